"""Area mission: the coverage pipeline in geodetic terms, split among the vehicles, and
replanned from completion percentages when vehicles drop out or join."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

from swarm_proto import GeometryKind, MissionParams

from .context import PlanContext
from .coverage import Lane, LanePlan, check_flyable, decompose, lane_spacing_m, plan_lanes
from .dubins import Pose, shortest_path
from .endurance import Endurance, accel_m_s2
from .errors import InvalidGeometryError, InvalidParameterError
from .geo import LocalFrame
from .split import (
    MakespanCost,
    SplitPlan,
    Worker,
    common_lanes,
    remaining_lanes,
    replan,
    split_lanes,
)
from .turns import DubinsTurns, TurnModel
from .vehicles import DEFAULT_PARAMS, PlanVehicle, VehiclePlan, require_vehicles, to_waypoints
from .zones import ARC_STEP_M, Obstacles, Track, ZoneSet

MAX_FLIGHT_S = 4 * 3600.0  # an area mission the swarm would fly longer than this is refused


@dataclass(frozen=True, slots=True)
class AreaPlan:
    frame: LocalFrame
    zones: ZoneSet
    obstacles: Obstacles
    lanes: LanePlan  # the region's lanes and a single-vehicle reference path
    split: SplitPlan
    vehicles: tuple[VehiclePlan, ...]
    altitudes_m: tuple[tuple[int, float], ...]  # vehicle id -> altitude above home
    tracks: tuple[Track, ...] = ()  # every path flown (lanes, transitions sampled along arcs)

    @property
    def makespan_s(self) -> float:
        return self.split.makespan_s

    def altitude_of(self, vehicle_id: int) -> float:
        return dict(self.altitudes_m)[vehicle_id]


def _hfov(vehicles: Sequence[PlanVehicle], hfov_deg: float | None) -> float:
    if hfov_deg is not None:
        return hfov_deg
    fovs = [v.profile.camera.hfov_deg for v in vehicles if v.profile.camera is not None]
    if not fovs:
        raise InvalidParameterError("area coverage needs a camera HFOV: no vehicle has a camera")
    return min(fovs)  # the narrowest camera sets the spacing


def _workers(
    vehicles: Sequence[PlanVehicle],
    params: MissionParams,
    frame: LocalFrame,
    *,
    altitudes: Mapping[int, float] | None = None,
    extra_s: Mapping[int, float] | None = None,
    stops: bool = True,
    battery_pct: Mapping[int, float] | None = None,
    homes: Mapping[int, tuple[float, float]] | None = None,
    launch_pct: Mapping[int, float] | None = None,
) -> list[Worker]:
    """Each vehicle as a split worker: its mission speed and turns, the time it loses
    stopping on waypoints, and with `altitudes` the time at cruise its battery allows
    for its block and the way home: a sortie from where it is (its home) with a full
    battery, or, for a vehicle in `battery_pct`, what that charge leaves in the air
    (the way home to `homes`, else to where it is)."""
    out = []
    for v in vehicles:
        speed = v.speed(params)
        start = Pose(*frame.pose(v.pose)) if v.pose is not None else None
        budget = math.inf
        if altitudes is not None:
            e = Endurance.of(v.profile, altitudes[v.vehicle_id])
            if battery_pct is None:
                launch = (launch_pct or {}).get(v.vehicle_id)
                budget = (
                    e.cruise_budget_s if launch is None else e.ground_budget_s(launch, v.profile)
                )
            elif v.vehicle_id in battery_pct:
                budget = e.airborne_budget_s(battery_pct[v.vehicle_id], v.profile)
        out.append(
            Worker(
                v.vehicle_id,
                speed,
                v.turns(speed),
                start,
                accel_m_s2=accel_m_s2(v.profile) if stops else 0.0,
                extra_s=(extra_s or {}).get(v.vehicle_id, 0.0),
                budget_s=budget,
                home=(homes or {}).get(v.vehicle_id),
            )
        )
    return out


def _reference_turns(workers: Sequence[Worker]) -> TurnModel:
    return max(workers, key=lambda w: w.turns.radius_m).turns


def _vehicle_plans(
    split: SplitPlan, frame: LocalFrame, altitudes: Mapping[int, float]
) -> tuple[VehiclePlan, ...]:
    out = []
    for a in split.assignments:
        pts = a.path.points()
        wps = to_waypoints(frame, pts, altitudes[a.vehicle_id], speed_m_s=a.speed_m_s)
        out.append(VehiclePlan(a.vehicle_id, wps, a.path.length_m, a.path_time_s))
    return tuple(out)


def _tracks(
    split: SplitPlan, workers: Sequence[Worker], altitudes: Mapping[int, float]
) -> tuple[Track, ...]:
    """Each vehicle's lanes and transitions as tracks (Dubins transitions sampled along
    their arcs, rerouted ones as their polylines)."""
    out: list[Track] = []
    by_id = {w.vehicle_id: w for w in workers}
    for a in split.assignments:
        w, alt = by_id[a.vehicle_id], altitudes[a.vehicle_id]
        prev, flown = w.start, 0
        for leg in a.path.legs:
            if leg.is_lane:
                ln = a.path.lanes[flown]
                out.append(Track(a.vehicle_id, "lane", (ln.a, ln.b), alt))
                prev, flown = ln.end_pose(), flown + 1
                continue
            pts = leg.points
            if isinstance(w.turns, DubinsTurns) and prev is not None and flown < len(a.path.lanes):
                goal = a.path.lanes[flown].start_pose()
                if abs(leg.length_m - w.turns.length(prev, goal)) < 1e-6:
                    xy = shortest_path(prev, goal, w.turns.radius_m).sample_xy(ARC_STEP_M)
                    pts = tuple((float(x), float(y)) for x, y in xy)
            out.append(Track(a.vehicle_id, "transition", pts, alt))
    return tuple(out)


def plan_area(
    ctx: PlanContext,
    *,
    hfov_deg: float | None = None,
    min_coverage: float = 0.99,
    endurance: bool = False,
    extra_s: Mapping[int, float] | None = None,
    legacy_split: bool = False,
    max_flight_s: float = MAX_FLIGHT_S,
    battery_pct: Mapping[int, float] | None = None,
) -> AreaPlan:
    """Cover a POLYGON (holes are not covered, zones are cut out and never entered) with
    `vehicles`: lane spacing from the altitude, the narrowest camera HFOV and the side
    overlap; sweep direction searched; lanes split to minimize the makespan (a vehicle
    that stops on its waypoints charged for each stop); each vehicle at
    `altitude_rel_m + i * altitude_step_m`. With `endurance` the vehicles are at their
    homes with a full battery (or, in `battery_pct`, what it has: one that flew before
    without a fresh battery), and no block and its way home take more than the battery
    allows (`endurance.Endurance`; `InfeasibleTimingError` if the fleet cannot
    cover the area). `extra_s`: seconds a vehicle's block is known to take beyond its
    path (the turns the flyable stage adds, see `fleet_plan`). `legacy_split`: the
    older split (every vehicle timed at constant speed, one turn allowance
    for all from the widest turn radius), the benchmark's baseline. A field the vehicles
    together would take over `max_flight_s` to fly (estimated before planning) is refused:
    FieldTooBigError with the estimate."""
    geometry, vehicles, params = ctx.geometry, ctx.vehicles, ctx.params
    require_vehicles(vehicles)
    if geometry.kind != GeometryKind.POLYGON:
        raise InvalidGeometryError(f"an area mission needs a POLYGON, got {geometry.kind.name}")
    frame = ctx.local_frame()
    poly = frame.shape(geometry)
    zs = ctx.zone_set(frame)
    alts = {
        v.vehicle_id: params.altitude_rel_m + i * params.altitude_step_m
        for i, v in enumerate(vehicles)
    }
    lo, hi = min(alts.values()), max(alts.values())
    zones_here = ZoneSet(zs.at(lo, hi), zs.margin_m, zs.vertical_margin_m)
    region = decompose(poly, zones_here)
    spacing = lane_spacing_m(lo, _hfov(vehicles, hfov_deg), params.side_overlap)
    workers = _workers(
        vehicles,
        params,
        frame,
        altitudes=alts if endurance else None,
        extra_s=extra_s,
        stops=not legacy_split,
        launch_pct=battery_pct,
    )
    turns = _reference_turns(workers)
    check_flyable(region, spacing, turns, sum(w.speed_m_s for w in workers), max_flight_s)
    lp = plan_lanes(region, spacing, turns, min_coverage=min_coverage)
    cost = None
    if legacy_split:
        r = max(w.turns.radius_m for w in workers)
        cost = MakespanCost(math.pi * r + 2.0 * r, region.obstacles)
    split = split_lanes(lp.lanes, workers, cost=cost, obstacles=region.obstacles)
    return AreaPlan(
        frame,
        zones_here,
        region.obstacles,
        lp,
        split,
        _vehicle_plans(split, frame, alts),
        tuple(alts.items()),
        _tracks(split, workers, alts),
    )


def replan_area(
    plan: AreaPlan,
    progress_pct: Mapping[int, float],
    vehicles: Sequence[PlanVehicle],
    params: MissionParams = DEFAULT_PARAMS,
    *,
    battery_pct: Mapping[int, float] | None = None,
    homes: Mapping[int, tuple[float, float]] | None = None,
) -> AreaPlan:
    """Share what is left of `plan` (from each vehicle's completion percentage) among
    `vehicles` from where they are now: the ones of the old plan missing here dropped
    out; new ones joined (they fly at the next free altitude step). A vehicle in
    `battery_pct` gets no more than that charge flies, with the way home to its
    `homes` entry (local metres in the plan's frame; else where it is now)."""
    require_vehicles(vehicles)
    for vid, pct in progress_pct.items():
        if not (math.isfinite(pct) and 0.0 <= pct <= 100.0):
            raise InvalidParameterError(f"vehicle {vid}: progress {pct} % is not in [0, 100]")
    alts = dict(plan.altitudes_m)
    top = max(alts.values())
    for v in vehicles:
        if v.vehicle_id not in alts:
            top += params.altitude_step_m
            alts[v.vehicle_id] = top
    workers = _workers(
        vehicles,
        params,
        plan.frame,
        altitudes=alts if battery_pct else None,
        battery_pct=battery_pct,
        homes=homes,
    )
    split = replan(plan.split, progress_pct, workers, obstacles=plan.obstacles)
    return _resplit(plan, split, workers, {v.vehicle_id: alts[v.vehicle_id] for v in vehicles})


def _resplit(
    plan: AreaPlan, split: SplitPlan, workers: Sequence[Worker], alts: dict[int, float]
) -> AreaPlan:
    """`plan`'s frame, zones, obstacles and lanes with a new split among `workers`."""
    return AreaPlan(
        plan.frame,
        plan.zones,
        plan.obstacles,
        plan.lanes,
        split,
        _vehicle_plans(split, plan.frame, alts),
        tuple(alts.items()),
        _tracks(split, workers, alts),
    )


def merge_area(
    plans: Sequence[tuple[AreaPlan, Mapping[int, float]]],
    vehicles: Sequence[PlanVehicle],
    params: MissionParams = DEFAULT_PARAMS,
) -> AreaPlan:
    """One plan again from the plans of a fleet split in parts (a partition, each part
    replanned from the same first plan without the others), each with its members'
    completion percentages: what none of them flew (the lanes left in every part's
    plan) shared among `vehicles` from where they are now. The result does not depend
    on the order of `plans`. Their frame, zones and lane grid are the first plan's."""
    require_vehicles(vehicles)
    first = plans[0][0]
    left: list[Lane] | None = None
    alts: dict[int, float] = {}
    for plan, pct in plans:
        for vid, p in pct.items():
            if not (math.isfinite(p) and 0.0 <= p <= 100.0):
                raise InvalidParameterError(f"vehicle {vid}: progress {p} % is not in [0, 100]")
        rest = remaining_lanes(plan.split, pct)
        left = rest if left is None else common_lanes(left, rest)
        for vid, alt in plan.altitudes_m:
            alts[vid] = max(alts.get(vid, alt), alt)  # the same whichever part came first
    top = max(alts.values(), default=params.altitude_rel_m)
    for v in sorted(vehicles, key=lambda v: v.vehicle_id):
        if v.vehicle_id not in alts:
            top += params.altitude_step_m
            alts[v.vehicle_id] = top
    workers = _workers(vehicles, params, first.frame)
    split = split_lanes(left or [], workers, obstacles=first.obstacles)
    return _resplit(first, split, workers, {v.vehicle_id: alts[v.vehicle_id] for v in vehicles})
