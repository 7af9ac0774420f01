"""Mission layer figures that the planning library and FastFleet measure,
each beside its baseline measured in the same run.

- `battery_min_pct_at_landing`: the demo's survey (its 300 x 260 m field, 35 m no-fly
  zone, 60 m, 60 % side overlap) flown in FastFleet by the fleet 1, 7, 8 (an Albatross
  VTOL, two quadcopters): the lowest battery any of them lands with. Baseline: the
  older split (`fleet_plan.BASELINE_SPLIT`: no endurance, every vehicle timed
  at constant speed, one split before the flyable stage).
- `makespan_planned_vs_flown`: from the plan to the last MISSION_COMPLETE (arming,
  take-off, climb, the approach or the PREMISSION the node flies, the share) over the
  plan's makespan (`FleetPlan.makespan_s`, launch included), the worst of the bench's
  fleets: the survey 1, 7, 8 and three VTOLs flying a route and an area with their
  PREMISSION (`makespan_planned_vs_flown_by_fleet`; the shares alone, from the
  mission's start in AUTO, in `survey_1_7_8/makespan_share_planned_vs_flown`).
- `inherit_coverage`, `double_flown_fraction`, `replan_agree_ms`: the node's mission
  inheritance flown end to end in FastFleet (`swarm_sim.scenarios.inheritance`): six
  VTOLs fly an area mission sent to ALL, one is killed at 40 % of its share; coverage
  from the flown tracks (swath: camera footprint), double flying from the runs each
  vehicle flew on its own lanes, loss noticed -> every survivor flying its new share,
  in simulated milliseconds (`replan_loss_to_flying_ms` from the kill, the stale
  timeout included). The same for two quadcopters and a rover (`inherit_quads_rover`,
  a quadcopter or the rover killed).
- `inherit.planning_coverage` (planning only, under `inherit`): six Albatross VTOLs plan
  an area; one is lost at 40 % of its share (the others at 40 % of theirs); the flown-before lanes
  plus the replanned split (`FleetPlan.replan`) cover this fraction of the area, and
  this fraction of it is seen twice (swaths at the lane spacing, counted with
  multiplicity). Baseline: no inheritance (the survivors finish their own shares).
- `premission_arrival_spread_s`: three VTOLs on the ground get a route mission to ALL
  and fly it with the nodes' PREMISSION (`swarm_sim.scenarios.premission_meet`): the
  spread of their arrivals at their entries, from the autopilots' positions; the same
  for an area mission (`premission_area_arrival_spread_s`), the MISSION speed rule's
  lateness spread, and the baselines without the meet and without the rule.
  `premission_planner`: the planner's legs flown by a driver from scattered poses
  (before the node flew them).
- `autoland`: three VTOLs in the air land at one base in turns (touchdown gaps, the
  order); `mumt`: two VTOLs follow a lead flying its own route (largest distance from
  their slots once converged).

`survey(...)`, `inherit(...)` and `premission_flight(...)` are what the tests run.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from typing import Any

import msgspec

from swarm_node.core.autopilot.items import ItemKind
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
    """Plan areas with the older split while inside (nodes included)."""
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
    from swarm_node.core.node import NodeSettings
    from swarm_sim.core import SITL_HOME
    from swarm_sim.demo import demo_area
    from swarm_sim.fast_fleet import FastFleet

    with baseline_split(baseline):
        # the planner's figures: collision avoidance off (its climbs and the landing
        # holds cost the 3.3 Ah quadcopters their reserve: docs/avoidance.md)
        settings = NodeSettings(avoidance=False)
        fleet = FastFleet.build(list(members), profiles, settings=settings)
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
        t_start: dict[int, float] = {}  # the plan is released: arming, take-off, climb
        t_done: dict[int, float] = {}
        lowest = {vid: 100 for vid in members}
        landed: dict[int, int] = {}
        seen = 0

        def step() -> bool:
            nonlocal seen
            for vid, v in fleet.vehicles.items():
                if v.node.manager.phase.value != "idle":
                    t_start.setdefault(vid, fleet.now)
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
            # every member landed, or completed on the ground (the plan gave it nothing)
            return all(v in landed or (v in t_done and v not in t_fly) for v in members)

        finished = fleet.run_until(step, timeout_s)
        homes = {vid: fleet.vehicles[vid].link.state.home for vid in members}
        vehicles = [
            PlanVehicle(profiles[vid], VehiclePose(h.lat_deg, h.lon_deg) if h else None)
            for vid, h in homes.items()
        ]
        h0 = homes[members[0]]
        plan = plan_fleet(
            mission,
            vehicles,
            zones=[zone],
            now_unix_s=fleet.now,
            home_alt_msl_m=h0.alt_msl_m if h0 else 0.0,
        )
    alerts = fleet.messages(Alert)
    critical = sorted({a.vehicle_id for a in alerts if a.code == AlertCode.BATTERY_CRITICAL})
    flown = {vid: t_done[vid] - t_fly[vid] for vid in members if vid in t_done and vid in t_fly}
    sortie = {
        vid: t_done[vid] - t_start[vid] for vid in members if vid in t_done and vid in t_start
    }
    share_span = max(plan.share(vid).time_s for vid in members)
    return {
        "finished": finished,
        "vehicles": {
            str(vid): {
                "planned_s": round(plan.share(vid).sortie_s, 1),
                "flown_s": round(sortie[vid], 1) if vid in sortie else None,
                "share_planned_s": round(plan.share(vid).time_s, 1),
                "share_flown_s": round(flown[vid], 1) if vid in flown else None,
                "battery_at_landing_pct": landed.get(vid),
                "battery_lowest_pct": lowest[vid],
                "critical_pct": profiles[vid].battery_critical_pct,
            }
            for vid in members
        },
        "battery_critical_alerts": critical,
        # from the plan (arming, take-off, climb, the approach, the share) to the last
        # MISSION_COMPLETE, against the plan's makespan (launch included)
        "makespan_planned_s": round(plan.makespan_s, 1),
        "makespan_flown_s": round(max(sortie.values()), 1) if sortie else None,
        "makespan_planned_vs_flown": (
            round(max(sortie.values()) / plan.makespan_s, 3) if sortie else None
        ),
        # the shares alone (from the mission start in AUTO), as the older split's end
        "makespan_share_planned_vs_flown": (
            round(max(flown.values()) / share_span, 3) if flown else None
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


# --------------------------------------------------------------------------- premission

PREMISSION_FLEET = (1, 2, 3)
_DRIVER_FIRST_ID = 7_000_000  # request ids of this driver (results kept from the nodes)


def premission_flight(
    profiles: Mapping[int, VehicleProfile],
    members: Sequence[int] = PREMISSION_FLEET,
    *,
    timeout_s: float = 600.0,
    closed_loop: bool = True,
    trace: list[tuple[float, int, float, float, int, float]] | None = None,
) -> dict[str, Any]:
    """Three Albatross VTOLs in FastFleet (simulated ArduPilot, real MAVLink through the
    node's autopilot link, driven here directly: the node does not wire PREMISSION yet)
    take off and fly to scattered points; then, from where each is and its heading,
    `premission` plans their legs to their shares of an area plan, each uploads its
    approach and share and starts it at once. Measured: when each reaches its entry
    item (MISSION_ITEM_REACHED) after the start; the spread of those times, against the
    predicted arrival. With `closed_loop`, once past its waiting orbit each vehicle's
    airspeed is set every second to what brings it to its entry at the predicted time
    (`premission_speed` on `PremissionLeg.remaining_m`), as the node is to do.
    Baseline (same legs): flying the Dubins legs at cruise without the synchronizing
    speeds and orbits (`path / cruise`)."""
    from swarm_node.core.autopilot.requests import (
        ApRequest,
        Arm,
        ChangeSpeed,
        Goto,
        SetMode,
        StartMission,
        Takeoff,
        UploadMission,
    )
    from swarm_node.core.node import AutopilotResult
    from swarm_node.core.planning.fleet_plan import flyable
    from swarm_node.core.planning.flight import FIXED_WING_ACCEPT_M
    from swarm_node.core.planning.premission import premission, premission_speed
    from swarm_sim.core import SITL_HOME
    from swarm_sim.fast_fleet import FastFleet

    fleet = FastFleet.build(list(members), profiles, spacing_m=60.0)
    fleet.run_until(lambda: all(v.link.state.ekf_has_position for v in fleet.vehicles.values()), 60)
    ids = iter(range(_DRIVER_FIRST_ID, _DRIVER_FIRST_ID + 10_000))
    results: dict[int, bool] = {}
    deliver = fleet._deliver

    def keep_ours(vid: int, event: Any, at: float) -> None:
        if isinstance(event, AutopilotResult) and event.result.request_id >= _DRIVER_FIRST_ID:
            results[event.result.request_id] = event.result.ok
            return
        deliver(vid, event, at)

    fleet._deliver = keep_ours  # type: ignore[method-assign]

    def run_steps(vid: int, steps: Sequence[ApRequest]) -> None:
        v = fleet.vehicles[vid]
        for step in steps:
            rid = next(ids)
            req = msgspec.structs.replace(step, request_id=rid)
            fleet._link_out(vid, v.link.submit(rid, req, fleet.now))
            if not fleet.run_until(lambda rid=rid: rid in results, 60):
                raise RuntimeError(f"vehicle {vid}: {type(step).__name__} got no result")
            if not results[rid]:
                raise RuntimeError(f"vehicle {vid}: {type(step).__name__} failed")

    for vid in members:
        run_steps(vid, [SetMode(mode="GUIDED"), Arm(), Takeoff(alt_rel_m=80.0)])
    fleet.run_until(
        lambda: all((v.link.state.alt_rel_m or 0.0) > 70.0 for v in fleet.vehicles.values()), 300
    )
    # scatter: each to its own point around the field, where it circles in GUIDED
    la, lo = SITL_HOME.lat_deg, SITL_HOME.lon_deg
    spots = [(la + 0.004, lo - 0.006), (la - 0.004, lo + 0.002), (la + 0.001, lo + 0.008)]
    for vid, (sla, slo) in zip(members, spots, strict=False):
        run_steps(vid, [Goto(lat_deg=sla, lon_deg=slo, alt_rel_m=80.0)])
    fleet.run_for(90.0)
    # the fleet's area plan, made at the homes (as every member makes it)
    area = Geometry.polygon(
        [
            (la + 0.006, lo - 0.004),
            (la + 0.006, lo + 0.004),
            (la + 0.010, lo + 0.004),
            (la + 0.010, lo - 0.004),
        ]
    )
    homes = {vid: fleet.vehicles[vid].link.state.home for vid in members}
    vs = [
        PlanVehicle(profiles[vid], VehiclePose(h.lat_deg, h.lon_deg) if h else None)
        for vid, h in homes.items()
    ]
    params = MissionParams(altitude_rel_m=80.0, side_overlap=0.2)
    mission = Mission(9, GCS, MissionType.AREA, area, params, Selector.ids(*members))
    plan = plan_fleet(mission, vs, zones=[], now_unix_s=fleet.now, home_alt_msl_m=0.0)
    posed = []
    for vid in members:
        s = fleet.vehicles[vid].link.state
        assert s.lat_deg is not None and s.lon_deg is not None
        posed.append(
            PlanVehicle(
                profiles[vid],
                VehiclePose(
                    s.lat_deg, s.lon_deg, s.alt_rel_m or 0.0, s.heading_deg, s.airspeed_m_s
                ),
            )
        )
    pm = premission(plan, posed)
    entry_seq = {}
    for vid in members:
        wps = [
            msgspec.structs.replace(w, acceptance_radius_m=FIXED_WING_ACCEPT_M)
            if w.kind == ItemKind.WAYPOINT
            else w
            for w in pm.mission_waypoints(plan.share(vid))
        ]
        leg = pm.legs[vid]
        last_wp = max(k for k, w in enumerate(leg.waypoints) if w.kind == ItemKind.WAYPOINT)
        entry_seq[vid] = last_wp + 1  # item 0 is home
        run_steps(vid, [UploadMission(items=tuple(wps))])
    t0: dict[int, float] = {}
    for vid in members:
        t0[vid] = fleet.now
        run_steps(vid, [StartMission()])
    reached: dict[int, float] = {}
    # arrival: the closest pass by the entry point while its item is being flown
    frame = pm.frame
    closest: dict[int, tuple[float, float]] = {}
    next_control = dict.fromkeys(members, fleet.now + 1.0)
    commanded = {vid: pm.legs[vid].speed_m_s for vid in members}
    ranges = {}
    for vid in members:
        fv = PlanVehicle(flyable(profiles[vid]))
        r = max(pm.legs[vid].orbit_m / (2 * math.pi), fv.profile.turn_radius_m())
        ranges[vid] = fv.speed_range_on(r)

    def control(vid: int) -> None:
        s = fleet.vehicles[vid].link.state
        assert s.lat_deg is not None and s.lon_deg is not None
        left = pm.legs[vid].remaining_m(s.mission_reached - 1, s.lat_deg, s.lon_deg)
        if left is None:
            return
        v = premission_speed(left, pm.arrival_s - (fleet.now - t0[vid]), ranges[vid])
        if abs(v - commanded[vid]) >= 0.2:
            commanded[vid] = v
            rid = next(ids)
            req = ChangeSpeed(request_id=rid, speed_m_s=v)
            fleet._link_out(vid, fleet.vehicles[vid].link.submit(rid, req, fleet.now))

    def step() -> bool:
        for vid in members:
            s = fleet.vehicles[vid].link.state
            if vid in reached or s.lat_deg is None or s.lon_deg is None:
                continue
            if closed_loop and fleet.now >= next_control[vid]:
                next_control[vid] = fleet.now + 1.0
                control(vid)
            e = pm.legs[vid].entry
            d = math.dist(frame.to_local(s.lat_deg, s.lon_deg), (e.x, e.y))
            if s.mission_reached >= entry_seq[vid] - 1 and d < closest.get(vid, (math.inf, 0))[0]:
                closest[vid] = (d, fleet.now - t0[vid])
            if s.mission_reached >= entry_seq[vid] and (d > 40.0 or vid not in closest):
                reached[vid] = closest.get(vid, (0.0, fleet.now - t0[vid]))[1]
            if trace is not None and s.lat_deg is not None and s.lon_deg is not None:
                trace.append(
                    (
                        fleet.now - t0[vid],
                        vid,
                        s.lat_deg,
                        s.lon_deg,
                        s.mission_reached,
                        s.airspeed_m_s,
                    )
                )
        return len(reached) == len(members)

    fleet.run_until(step, timeout_s)
    cruise = {vid: pm.legs[vid].path_m / profiles[vid].cruise_speed_m_s for vid in members}
    flown = list(reached.values())
    return {
        "finished": len(reached) == len(members),
        "predicted_arrival_s": round(pm.arrival_s, 1),
        "predicted_spread_s": round(pm.spread_s, 3),
        "arrivals_s": {str(vid): round(t, 1) for vid, t in reached.items()},
        "legs": {
            str(vid): {
                "path_m": round(leg.path_m),
                "orbits": leg.orbits,
                "hold_s": round(leg.hold_s, 1),
                "speed_m_s": round(leg.speed_m_s, 2),
            }
            for vid, leg in pm.legs.items()
        },
        "premission_arrival_spread_s": round(max(flown) - min(flown), 2) if flown else None,
        "baseline_unsynchronized_spread_s": round(max(cruise.values()) - min(cruise.values()), 2),
    }


# --------------------------------------------------------------------------- run


def _meet(profiles: Mapping[int, VehicleProfile], kind: MissionType) -> dict[str, Any]:
    """The nodes' PREMISSION (three VTOLs on the ground, a mission to ALL) flown to the
    end, and the same flight without the meet (the baseline)."""
    from swarm_node.core.mission import fleet_sync
    from swarm_sim.scenarios import premission_meet

    got = premission_meet(profiles, PREMISSION_FLEET, kind, to_the_end=True)
    fleet_sync.PREMISSION = False
    try:
        old = premission_meet(profiles, PREMISSION_FLEET, kind, to_the_end=True)
    finally:
        fleet_sync.PREMISSION = True
    fleet_sync.SPEED_RULE = False
    try:
        no_rule = premission_meet(profiles, PREMISSION_FLEET, kind, to_the_end=True)
    finally:
        fleet_sync.SPEED_RULE = True

    def ratio(m: Any) -> float | None:
        return round(m.makespan_flown_s / m.makespan_planned_s, 3) if m.makespan_flown_s else None

    return {
        "arrival_spread_s": round(got.spread_s, 2),
        "arrivals_s": {str(v): round(t, 1) for v, t in sorted(got.arrivals.items())},
        "meet_s": round(got.meet_s, 1) if got.meet_s is not None else None,
        "entry_miss_m": {str(v): round(d, 1) for v, d in sorted(got.entry_miss_m.items())},
        "speed_commands": {str(v): n for v, n in sorted(got.speed_commands.items())},
        "lateness_spread_s": round(got.lateness_spread_s, 2),
        "completed": sorted(got.completed),
        "makespan_planned_s": round(got.makespan_planned_s, 1),
        "makespan_flown_s": round(got.makespan_flown_s, 1) if got.makespan_flown_s else None,
        "makespan_planned_vs_flown": ratio(got),
        "baseline_no_meet": {
            "arrival_spread_s": round(old.spread_s, 2),
            "makespan_planned_vs_flown": ratio(old),
        },
        "baseline_no_speed_rule": {
            "lateness_spread_s": round(no_rule.lateness_spread_s, 2),
            "makespan_planned_vs_flown": ratio(no_rule),
        },
    }


def _inherited(r: Any) -> dict[str, Any]:
    return {
        "coverage": round(r.coverage, 4),
        "double_flown_fraction": round(r.double_flown, 4),
        "double_flown_by_pair": {f"{a}-{b}": round(x, 4) for (a, b), x in r.pairs.items() if x},
        "lanes_cover": round(r.lanes_cover, 3),
        "loss_to_flying_ms": round(r.agree_s * 1000.0),
        "noticed_ms": round(r.noticed_s * 1000.0),
        "agree_ms": round((r.agree_s - r.noticed_s) * 1000.0),
        "survivors_completed": sorted(r.completed),
        "same_plan": r.same_plan,
        "battery_critical": list(r.battery_critical),
    }


def run() -> dict[str, Any]:
    from swarm_node.database import seed_fleet
    from swarm_sim.scenarios import autoland_flight, inheritance, mumt_flight

    profiles = {p.vehicle_id: p for p in seed_fleet()}
    new = survey(profiles)
    old = survey(profiles, baseline=True)
    inh = inherit(profiles)
    flown = inheritance(profiles, INHERIT_FLEET, victim=3, at_fraction=0.4)
    quads_rover = {
        f"victim_{v}": _inherited(
            inheritance(
                profiles,
                (7, 8, 10),
                victim=v,
                at_fraction=0.4,
                half_m=80.0,
                alt_m=40.0,
                north_m=150.0,
            )
        )
        for v in (8, 10)
    }
    route = _meet(profiles, MissionType.ROUTE)
    area = _meet(profiles, MissionType.AREA)
    pre = premission_flight(profiles)
    open_loop = premission_flight(profiles, closed_loop=False)
    landings = autoland_flight(profiles, (1, 2, 3), separation_s=40.0)
    follow = mumt_flight(profiles, 4, (1, 2))
    spans = {
        "survey_1_7_8": new["makespan_planned_vs_flown"],
        "premission_route_1_2_3": route["makespan_planned_vs_flown"],
        "premission_area_1_2_3": area["makespan_planned_vs_flown"],
    }
    out: dict[str, Any] = {
        # PREMISSION flown by the nodes: the spread of the three VTOLs' arrivals at their
        # entries (route mission; the area mission's under "premission_area")
        "premission_arrival_spread_s": route["arrival_spread_s"],
        "premission_area_arrival_spread_s": area["arrival_spread_s"],
        "battery_min_pct_at_landing": new["battery_min_pct_at_landing"],
        # plan -> last MISSION_COMPLETE (take-off, climb, approach or PREMISSION, share)
        # over the plan's makespan; the worst of the bench's fleets, each below
        "makespan_planned_vs_flown": max(v for v in spans.values() if v is not None),
        "makespan_planned_vs_flown_by_fleet": spans,
        "inherit_coverage": round(flown.coverage, 4),
        "double_flown_fraction": round(flown.double_flown, 4),
        # loss noticed (the stale timeout) -> every survivor flying its new share
        "replan_agree_ms": round((flown.agree_s - flown.noticed_s) * 1000.0),
        "replan_loss_to_flying_ms": round(flown.agree_s * 1000.0),
        "survivors_completed": sorted(flown.completed),
        "inherit_quads_rover": quads_rover,
        "autoland": {
            "touchdowns_s": {str(v): round(t, 1) for v, t in sorted(landings.touchdowns.items())},
            "touchdown_gaps_s": [round(g, 1) for g in landings.gaps_s],
            "separation_s": 40.0,
            "order_as_planned": landings.turns == landings.order,
            "completed": sorted(landings.completed),
        },
        "mumt": {
            "slot_error_max_m": {
                str(v): round(e, 2) for v, e in sorted(follow.slot_error_m.items())
            },
            "converged_after_s": {
                str(v): round(t, 1) for v, t in sorted(follow.converged_after_s.items())
            },
            "completed": sorted(follow.completed),
        },
        "baseline": {
            "battery_min_pct_at_landing": old["battery_min_pct_at_landing"],
            "makespan_planned_vs_flown": old["makespan_planned_vs_flown"],
            "battery_critical_alerts": old["battery_critical_alerts"],
            "inherit_coverage": inh["baseline_no_inherit_coverage"],
            "premission_arrival_spread_s": route["baseline_no_meet"]["arrival_spread_s"],
            "premission_area_arrival_spread_s": area["baseline_no_meet"]["arrival_spread_s"],
        },
        "premission_route": route,
        "premission_area": area,
        # the planner's legs flown by a driver (not the node), from scattered poses
        "premission_planner": {
            **pre,
            "open_loop_spread_s": open_loop["premission_arrival_spread_s"],
        },
        "survey_1_7_8": new,
        "survey_1_7_8_baseline": old,
        "inherit": inh,
    }
    if math.isnan(out["inherit_coverage"]):
        raise RuntimeError("inherit coverage is not a number")
    return out
