"""The mission layer in fast time (issue 12): mission inheritance and flown-as-planned.

- `inherit_coverage`, `double_flown_fraction`, `replan_agree_ms`: six VTOLs fly an
  area mission sent to ALL, one is killed at 40 % of its share
  (`swarm_sim.scenarios.inheritance`); coverage from the flown tracks (swath: camera
  footprint), double flying from the lane runs, loss -> every survivor flying its new
  share in simulated milliseconds.
- `makespan_planned_vs_flown`, `battery_min_pct_at_landing`: the demo survey flown by
  the fleet 1, 7, 8 (an Albatross and two quadcopters) until all have landed.
- `premission_arrival_spread_s`: not measured (PREMISSION legs are not flown yet).
"""

from __future__ import annotations

from typing import Any

from swarm_node.database import seed_fleet
from swarm_proto import (
    Alert,
    AlertCode,
    Command,
    CommandArgs,
    CommandKind,
    FsmState,
    GeoPoint,
    Mission,
    MissionParams,
    MissionType,
    Selector,
)
from swarm_sim.core import SITL_HOME
from swarm_sim.fast_fleet import FastFleet
from swarm_sim.scenarios import inheritance


def survey_178(profiles: dict) -> dict[str, Any]:
    from swarm_sim.demo import demo_area

    members = [1, 7, 8]
    fleet = FastFleet.build(members, profiles)
    fleet.run_until(lambda: all(v.link.state.ekf_has_position for v in fleet.vehicles.values()), 60)
    base = GeoPoint(SITL_HOME.lat_deg, SITL_HOME.lon_deg, SITL_HOME.alt_m)
    fleet.broadcast(Command(900, 1, CommandKind.SET_BASE, args=CommandArgs(point=base)))
    fleet.run_for(2.0)
    area, zone = demo_area()
    fleet.broadcast(zone)
    fleet.broadcast(Mission(7, 900, MissionType.AREA, area,
                            MissionParams(altitude_rel_m=60.0, side_overlap=0.6),
                            Selector.ids(*members)))  # fmt: skip
    t0 = fleet.now
    battery: dict[int, int] = {}

    def landed() -> bool:
        for vid, v in fleet.vehicles.items():
            s = v.link.state
            if vid not in battery and fleet.now > t0 + 60 and not s.armed and (s.alt_rel_m or 0.0) < 1.0:
                battery[vid] = s.battery_pct
        return len(battery) == len(members)

    fleet.run_until(landed, 1800)
    plan = fleet.vehicles[1].node.manager.fleet_plan
    done = [
        t for t, _vid, m in fleet.published
        if isinstance(m, Alert) and m.code == AlertCode.MISSION_COMPLETE
    ]  # fmt: skip
    flown_s = (max(done) - t0) if done else float("nan")
    planned_s = plan.makespan_s if plan is not None else float("nan")
    return {
        "makespan_planned_s": round(planned_s, 1),
        "makespan_flown_s": round(flown_s, 1),
        "makespan_planned_vs_flown": round(flown_s / planned_s, 3) if planned_s else None,
        "battery_min_pct_at_landing": min(battery.values()) if battery else None,
        "battery_pct_at_landing": battery,
        "all_inactive": all(v.node.fsm.state == FsmState.INACTIVE for v in fleet.vehicles.values()),
    }


def run() -> dict[str, Any]:
    profiles = {p.vehicle_id: p for p in seed_fleet()}
    r = inheritance(profiles, (1, 2, 3, 4, 5, 6), victim=3, at_fraction=0.4)
    return {
        "inherit_coverage": round(r.coverage, 4),
        "double_flown_fraction": round(r.double_flown, 4),
        "replan_agree_ms": round(r.agree_s * 1000.0),
        "survivors_completed": sorted(r.completed),
        "premission_arrival_spread_s": None,
        **survey_178(profiles),
    }
