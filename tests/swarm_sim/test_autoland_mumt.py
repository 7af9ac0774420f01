"""AUTOLAND and MUM-T missions flown by the mission manager (deliver 7), in
fast time over real MAVLink bytes (`swarm_sim.scenarios.autoland_flight`,
`mumt_flight`, which `make bench BENCH=mission` measures too): a fleet lands at one
base in turns, each on its own pad; followers hold their slots in a vee around a lead
node that flies its own mission."""

from __future__ import annotations

import itertools
import math

from swarm_node.core.planning import AutolandPlan
from swarm_proto import AckReason, Geometry, Mission, MissionParams, MissionType
from swarm_sim.core import SITL_HOME
from swarm_sim.scenarios import autoland_flight, mumt_flight
from tests.swarm_sim.test_mission_layer import GCS, ready_fleet


def test_a_fleet_lands_at_one_base_in_turns_each_on_its_own_pad(fleet_profiles: dict) -> None:
    """Three VTOLs orbiting a target get an AUTOLAND mission: each flies to the holding
    fix at its own stack level and holds; the first lands at once, each of the others
    leaves its hold when the one before has landed (its final approach, coming down
    vertically from its level, is longer than the 40 s asked: one vehicle on the final
    at a time), in the plan's order; each lands on its own pad, 15 m from the next; the
    landing completes the mission and deactivates the state machine."""
    got = autoland_flight(fleet_profiles, (1, 2, 3), separation_s=40.0)
    print(f"touchdowns {got.touchdowns} s, {[round(g) for g in got.gaps_s]} s apart")
    assert got.turns == got.order
    assert all(g >= 40.0 for g in got.gaps_s), got.gaps_s
    spots = [got.spots[v] for v in got.order]
    for a, b in itertools.pairwise(spots):
        assert 12.0 <= math.dist(a, b) <= 18.0, spots  # its own pad, 15 m from the next
    assert all(math.dist(p, (0.0, 0.0)) <= 20.0 for p in spots), spots
    assert got.completed == {1, 2, 3} and got.inactive


def test_autoland_plans_are_the_same_on_every_node(fleet_profiles: dict) -> None:
    """The landing order every node flies by comes from inputs they all have."""
    fleet = ready_fleet([1, 2, 3], fleet_profiles)
    pad = Geometry.point(SITL_HOME.lat_deg - 0.001, SITL_HOME.lon_deg)
    fleet.broadcast(Mission(22, GCS, MissionType.AUTOLAND, pad, MissionParams(altitude_rel_m=60.0)))
    assert fleet.run_until(
        lambda: all(v.node.manager.fleet_plan is not None for v in fleet.vehicles.values()), 30
    )
    plans = [v.node.manager.fleet_plan for v in fleet.vehicles.values()]
    assert all(p is not None and isinstance(p.detail, AutolandPlan) for p in plans)
    assert len({p.detail.slots for p in plans if p is not None}) == 1  # type: ignore[attr-defined]


def test_followers_hold_their_slots_around_a_lead_flying_its_own_mission(
    fleet_profiles: dict,
) -> None:
    """VTOL 4 flies a long route; a MUM-T mission sent to everyone makes 1 and 2 its
    followers (4, the lead, answers NOT_ADDRESSED and flies on): they take off, close
    on their slots of the vee behind the lead (assigned from their homes, the same on
    every node) and hold them within 10 m once converged; after the mission's duration
    they go home."""
    got = mumt_flight(fleet_profiles, 4, (1, 2))
    print(f"slot errors {got.slot_error_m} m, converged after {got.converged_after_s} s")
    assert got.answers == {1: AckReason.OK, 2: AckReason.OK, 4: AckReason.NOT_ADDRESSED}
    assert sorted(got.slots.values()) == [0, 1]
    assert all(e < 10.0 for e in got.slot_error_m.values()), got.slot_error_m
    assert got.lead_on_route
    assert got.completed == {1, 2}
