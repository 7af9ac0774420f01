"""The planner's battery model (swarm_node/core/planning/endurance.py) against what the
simulated vehicle drains flying the same sortie (swarm_sim.core: the quadcopter of the
seed database, in fast time, real MAVLink): the planner must never count a multirotor's
sortie cheaper than it flies, or it gives it more work than its battery flies with
reserve.

Measured (climb to 140 m, the mixed demo's quadcopter layers; 400 m out and back; RTL
and land): the simulator drains 646 mAh in the climb against the model's 467 (the model
climbs at hover current; the simulated lift motors draw 0.15 x hover more per m/s of
climb), and 2428 mAh for the sortie against the model's 2193: 7 % of the 3.3 Ah battery,
most of the planner's 10 % reserve. Counted at the climb current (and ArduCopter's 5 s
RTL loiter over home), the model came within 1 % (climb) and 2 % (sortie), but the
tighter budgets left a voted-out fleet's survivors 5 s short of their own rest
(tests/swarm_node/test_tasking_node.py: no replan, the winners' rest unflown): not
changed yet, a strict xfail until it is."""

from __future__ import annotations

import pytest

from swarm_node.core.planning.endurance import Endurance, leg_s
from swarm_node.database import seed_fleet
from tests.swarm_sim.conftest import make_pilot

WP, TAKEOFF, RTL, REL = 16, 22, 20, 3
ALT_M = 140.0  # the mixed demo's quadcopter layers are 140-160 m
OUT_M = 400.0


@pytest.mark.xfail(strict=True, reason="the model counts a multirotor's climb at hover current")
def test_a_quadcopter_sortie_costs_no_more_than_the_planner_counts() -> None:
    """Climb to 140 m, 400 m out and back at cruise, land: the model's climb and whole
    sortie cover the simulator's drain (within 1 % and 2 %: the autopilot's last metres
    of the climb slow down, each leg starts from a standstill)."""
    profile = next(p for p in seed_fleet() if p.model == "Generic Quadcopter")
    e = Endurance.of(profile, ALT_M)
    p = make_pilot("copter")
    p.wait_ready()
    p.upload(
        [
            (WP, 0, 0, 0, 0),
            (TAKEOFF, REL, 0, 0, ALT_M),
            (WP, REL, OUT_M, 0, ALT_M),
            (RTL, REL, 0, 0, 0),
        ]
    )
    assert p.set_mode("GUIDED") == 0 and p.arm() == 0
    assert p.command(22, 0, 0, 0, 0, 0, 0, ALT_M) == 0
    battery = p.ap.battery
    before = battery.consumed_mah
    assert p.h.run_until(lambda: p.ap.rel_alt_m > ALT_M - 0.5, 200)
    climbed = battery.consumed_mah - before
    assert p.set_mode("AUTO") == 0 and p.command(300) == 0
    assert p.h.run_until(lambda: not p.ap.armed, 900)
    total = battery.consumed_mah - before
    cruise_s = 2 * leg_s(OUT_M, profile.cruise_speed_m_s, profile.accel_m_s2)
    model_total = (
        e.used_pct(cruise_s, profile.battery_capacity_mah) * profile.battery_capacity_mah / 100.0
    )
    model_climb = e.hover_a * e.climb_s / 3.6
    assert 0.99 * climbed <= model_climb, (climbed, model_climb)
    assert 0.98 * total <= model_total, (total, model_total)
