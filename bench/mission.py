"""Mission layer figures (issue 12) that the planning library and FastFleet measure,
each beside its baseline measured in the same run.

- `battery_min_pct_at_landing`, `makespan_planned_vs_flown`: the demo's survey (its
  300 x 260 m field, 35 m no-fly zone, 60 m, 60 % side overlap) flown in FastFleet by
  the fleet 1, 7, 8 (an Albatross VTOL, two quadcopters): the lowest battery any of
  them lands with, and the makespan flown (from each vehicle's AUTO start to its
  MISSION_COMPLETE) over the makespan planned (`FleetPlan.makespan_s`). Baseline: the
  split before issue 12 (`fleet_plan.BASELINE_SPLIT`: no endurance, every vehicle
  timed at constant speed, one split before the flyable stage).
- `inherit_coverage`, `double_flown_fraction`: six Albatross VTOLs plan an area; one
  is lost at 40 % of its share (the others at 40 % of theirs); the flown-before lanes
  plus the replanned split (`FleetPlan.replan`) cover this fraction of the area, and
  this fraction of it is seen twice (swaths at the lane spacing, counted with
  multiplicity). Baseline: no inheritance (the survivors finish their own shares).
- `premission_arrival_spread_s`: see `premission()`.

`survey(...)`, `inherit(...)` and `premission(...)` are what the tests run.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from typing import Any

from swarm_node.core.planning import (
    PlanVehicle,
    VehiclePose,
    coverage_ratio,
    decompose,
    overlap_ratio,
)
from swarm_node.core.planning import fleet_plan as fp_module
from swarm_node.core.planning.area import AreaPlan
from swarm_node.core.planning.fleet_plan import FleetPlan, flown_lanes, plan_fleet
from swarm_node.core.profile import VehicleProfile
from swarm_proto import (
    Alert,
    AlertCode,
    Command,
    CommandArgs,
    CommandKind,
    Geometry,
    GeoPoint,
    Mission,
    MissionParams,
    MissionType,
    Selector,
)

GCS = 900
SURVEY_FLEET = (1, 7, 8)
INHERIT_FLEET = (1, 2, 3, 4, 5, 6)


@contextmanager
def baseline_split(on: bool) -> Iterator[None]:
    """Plan areas with the split before issue 12 while inside (nodes included)."""
    old = fp_module.BASELINE_SPLIT
    fp_module.BASELINE_SPLIT = on
    try:
        yield
    finally:
        fp_module.BASELINE_SPLIT = old


def survey(
    profiles: Mapping[int, VehicleProfile],
    members: Sequence[int] = SURVEY_FLEET,
    *,
    baseline: bool = False,
    timeout_s: float = 1500.0,
) -> dict[str, Any]:
    """The demo's survey flown in FastFleet by `members`; per vehicle its planned and
    flown share time, the battery it lands with and its lowest, and the alerts."""
    from swarm_sim.core import SITL_HOME
    from swarm_sim.demo import demo_area
    from swarm_sim.fast_fleet import FastFleet

    with baseline_split(baseline):
        fleet = FastFleet.build(list(members), profiles)
        fleet.run_until(
            lambda: all(v.link.state.ekf_has_position for v in fleet.vehicles.values()), 60
        )
        base = GeoPoint(SITL_HOME.lat_deg, SITL_HOME.lon_deg, SITL_HOME.alt_m)
        fleet.broadcast(Command(GCS, 1, CommandKind.SET_BASE, args=CommandArgs(point=base)))
        fleet.run_for(2.0)
        area, zone = demo_area()
        fleet.broadcast(zone)
        params = MissionParams(altitude_rel_m=60.0, side_overlap=0.6)
        mission = Mission(7, GCS, MissionType.AREA, area, params, Selector.ids(*members))
        fleet.broadcast(mission)
        t_fly: dict[int, float] = {}
        t_done: dict[int, float] = {}
        lowest = {vid: 100 for vid in members}
        landed: dict[int, int] = {}
        seen = 0

        def step() -> bool:
            nonlocal seen
            for vid, v in fleet.vehicles.items():
                if v.node.manager.phase.value == "flying":
                    t_fly.setdefault(vid, fleet.now)
                s = v.link.state
                if s.battery_pct >= 0:
                    lowest[vid] = min(lowest[vid], s.battery_pct)
                if vid in t_fly and not s.armed and vid not in landed:
                    landed[vid] = s.battery_pct
            alerts = fleet.messages(Alert)
            for a in alerts[seen:]:
                if a.code == AlertCode.MISSION_COMPLETE:
                    t_done.setdefault(a.vehicle_id, fleet.now)
            seen = len(alerts)
            return len(landed) == len(members)

        finished = fleet.run_until(step, timeout_s)
        homes = {vid: fleet.vehicles[vid].link.state.home for vid in members}
        vehicles = [
            PlanVehicle(profiles[vid], VehiclePose(h.lat_deg, h.lon_deg) if h else None)
            for vid, h in homes.items()
        ]
        h0 = homes[members[0]]
        plan = plan_fleet(
            mission, vehicles, zones=[zone], now_unix_s=fleet.now,
            home_alt_msl_m=h0.alt_msl_m if h0 else 0.0,
        )  # fmt: skip
    alerts = fleet.messages(Alert)
    critical = sorted({a.vehicle_id for a in alerts if a.code == AlertCode.BATTERY_CRITICAL})
    flown = {vid: t_done[vid] - t_fly[vid] for vid in members if vid in t_done and vid in t_fly}
    return {
        "finished": finished,
        "vehicles": {
            str(vid): {
                "planned_s": round(plan.share(vid).time_s, 1),
                "flown_s": round(flown[vid], 1) if vid in flown else None,
                "battery_at_landing_pct": landed.get(vid),
                "battery_lowest_pct": lowest[vid],
                "critical_pct": profiles[vid].battery_critical_pct,
            }
            for vid in members
        },
        "battery_critical_alerts": critical,
        "makespan_planned_s": round(plan.makespan_s, 1),
        "makespan_flown_s": round(max(flown.values()), 1) if flown else None,
        "makespan_planned_vs_flown": (
            round(max(flown.values()) / plan.makespan_s, 3) if flown else None
        ),
        "battery_min_pct_at_landing": min(landed.values()) if landed else None,
    }


# --------------------------------------------------------------------------- inherit


def inherit_area() -> Geometry:
    la, lo = 40.4168, -3.7038
    return Geometry.polygon(
        [(la, lo), (la, lo + 0.012), (la + 0.006, lo + 0.014), (la + 0.009, lo + 0.004)]
    )


def inherit(
    profiles: Mapping[int, VehicleProfile],
    members: Sequence[int] = INHERIT_FLEET,
    *,
    lost: int | None = None,
    at: float = 0.4,
) -> dict[str, Any]:
    """Six VTOLs plan `inherit_area()`; `lost` (default the third) is lost when every
    vehicle is `at` of its share: coverage and double seeing of flown-before + the
    replanned split, and of flown-before + the survivors' own unflown shares."""
    area = inherit_area()
    la, lo = area.points[0].lat_deg, area.points[0].lon_deg
    homes = [VehiclePose(la - 0.002, lo - 0.002 + 0.0005 * i) for i in range(len(members))]
    vs = [PlanVehicle(profiles[m], h) for m, h in zip(members, homes, strict=True)]
    params = MissionParams(altitude_rel_m=100.0, altitude_step_m=5.0, side_overlap=0.2)
    mission = Mission(8, GCS, MissionType.AREA, area, params, Selector.ids(*members))
    plan = plan_fleet(mission, vs, zones=[], now_unix_s=0.0, home_alt_msl_m=0.0)
    lost = members[2] if lost is None else lost
    progress: dict[int, float] = {}
    posed: list[PlanVehicle] = []
    for v in vs:
        share = plan.share(v.vehicle_id)
        k, lat, lon = share.at(at * share.length_m)
        progress[v.vehicle_id] = share.progress_m(k, lat, lon)
        if v.vehicle_id != lost:
            posed.append(PlanVehicle(v.profile, VehiclePose(lat, lon, 100.0)))
    new = plan.replan(progress, posed, zones=[], now_unix_s=0.0, home_alt_msl_m=0.0)
    assert isinstance(plan.detail, AreaPlan) and isinstance(new.detail, AreaPlan)
    d = plan.detail
    target = decompose(d.frame.shape(area), d.zones).target
    spacing = d.lanes.spacing_m
    before = flown_lanes(plan, progress)
    after = [ln for a in new.detail.split.assignments for ln in a.path.lanes]
    # no inheritance: every survivor finishes its own share, the lost one's rest is lost
    own_rest = _rest_of_own_shares(plan, progress, exclude=lost)
    planned = [ln for a in d.split.assignments for ln in a.path.lanes]
    return {
        "planned_coverage": round(coverage_ratio(planned, target, spacing), 4),
        "inherit_coverage": round(coverage_ratio(before + after, target, spacing), 4),  # type: ignore[operator]
        "double_flown_fraction": round(overlap_ratio(before + after, target, spacing), 5),  # type: ignore[operator]
        "baseline_no_inherit_coverage": round(
            coverage_ratio(before + own_rest, target, spacing),  # type: ignore[operator]
            4,
        ),
        "replan_makespan_s": round(new.makespan_s, 1),
        "plan_makespan_s": round(plan.makespan_s, 1),
    }


def _rest_of_own_shares(plan: FleetPlan, progress: Mapping[int, float], exclude: int) -> list:
    """The unflown lanes of every share but `exclude`'s (what nobody replans)."""
    from swarm_node.core.planning import remaining_lanes
    from swarm_node.core.planning.split import SplitPlan

    assert isinstance(plan.detail, AreaPlan)
    split = plan.detail.split
    keep = SplitPlan(tuple(a for a in split.assignments if a.vehicle_id != exclude))
    pct = {vid: plan.area_percent(vid, m) for vid, m in progress.items()}
    return list(remaining_lanes(keep, pct))


# --------------------------------------------------------------------------- run


def run() -> dict[str, Any]:
    from swarm_node.database import seed_fleet

    profiles = {p.vehicle_id: p for p in seed_fleet()}
    new = survey(profiles)
    old = survey(profiles, baseline=True)
    inh = inherit(profiles)
    out: dict[str, Any] = {
        "battery_min_pct_at_landing": new["battery_min_pct_at_landing"],
        "makespan_planned_vs_flown": new["makespan_planned_vs_flown"],
        "inherit_coverage": inh["inherit_coverage"],
        "double_flown_fraction": inh["double_flown_fraction"],
        "baseline": {
            "battery_min_pct_at_landing": old["battery_min_pct_at_landing"],
            "makespan_planned_vs_flown": old["makespan_planned_vs_flown"],
            "battery_critical_alerts": old["battery_critical_alerts"],
            "inherit_coverage": inh["baseline_no_inherit_coverage"],
        },
        "survey_1_7_8": new,
        "survey_1_7_8_baseline": old,
        "inherit": inh,
    }
    if math.isnan(out["inherit_coverage"]):
        raise RuntimeError("inherit coverage is not a number")
    return out
