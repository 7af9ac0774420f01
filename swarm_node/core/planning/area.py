"""Area mission: the coverage pipeline in geodetic terms, split among the vehicles, and
replanned from completion percentages when vehicles drop out or join."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

from swarm_proto import Geometry, GeometryKind, MissionParams, NoFlyZone

from .coverage import LanePlan, check_flyable, decompose, lane_spacing_m, plan_lanes
from .dubins import Pose, shortest_path
from .errors import InvalidGeometryError, InvalidParameterError
from .geo import LocalFrame
from .split import SplitPlan, Worker, replan, split_lanes
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
    vehicles: Sequence[PlanVehicle], params: MissionParams, frame: LocalFrame
) -> list[Worker]:
    out = []
    for v in vehicles:
        speed = v.speed(params)
        start = Pose(*frame.pose(v.pose)) if v.pose is not None else None
        out.append(Worker(v.vehicle_id, speed, v.turns(speed), start))
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
        out.append(VehiclePlan(a.vehicle_id, wps, a.path.length_m, a.time_s))
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
    geometry: Geometry,
    vehicles: Sequence[PlanVehicle],
    params: MissionParams = DEFAULT_PARAMS,
    *,
    zones: Sequence[NoFlyZone] = (),
    now_unix_s: float = 0.0,
    home_alt_msl_m: float = 0.0,
    zone_margin_m: float = 0.0,
    hfov_deg: float | None = None,
    min_coverage: float = 0.99,
    frame: LocalFrame | None = None,
    max_flight_s: float = MAX_FLIGHT_S,
) -> AreaPlan:
    """Cover a POLYGON (holes are not covered, zones are cut out and never entered) with
    `vehicles`: lane spacing from the altitude, the narrowest camera HFOV and the side
    overlap; sweep direction searched; lanes split to minimize the makespan; each
    vehicle at `altitude_rel_m + i * altitude_step_m`. A field the vehicles together
    would take over `max_flight_s` to fly (estimated before planning) is refused:
    FieldTooBigError with the estimate."""
    require_vehicles(vehicles)
    if geometry.kind != GeometryKind.POLYGON:
        raise InvalidGeometryError(f"an area mission needs a POLYGON, got {geometry.kind.name}")
    frame = frame or LocalFrame.for_geometry(geometry)
    poly = frame.shape(geometry)
    zs = ZoneSet.from_messages(
        zones, frame, now_unix_s=now_unix_s, home_alt_msl_m=home_alt_msl_m, margin_m=zone_margin_m
    )
    alts = {
        v.vehicle_id: params.altitude_rel_m + i * params.altitude_step_m
        for i, v in enumerate(vehicles)
    }
    lo, hi = min(alts.values()), max(alts.values())
    zones_here = ZoneSet(zs.at(lo, hi), zs.margin_m, zs.vertical_margin_m)
    region = decompose(poly, zones_here)
    spacing = lane_spacing_m(lo, _hfov(vehicles, hfov_deg), params.side_overlap)
    workers = _workers(vehicles, params, frame)
    turns = _reference_turns(workers)
    check_flyable(region, spacing, turns, sum(w.speed_m_s for w in workers), max_flight_s)
    lp = plan_lanes(region, spacing, turns, min_coverage=min_coverage)
    split = split_lanes(lp.lanes, workers, obstacles=region.obstacles)
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
) -> AreaPlan:
    """Share what is left of `plan` (from each vehicle's completion percentage) among
    `vehicles` from where they are now: the ones of the old plan missing here dropped
    out; new ones joined (they fly at the next free altitude step)."""
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
    workers = _workers(vehicles, params, plan.frame)
    split = replan(plan.split, progress_pct, workers, obstacles=plan.obstacles)
    alts = {v.vehicle_id: alts[v.vehicle_id] for v in vehicles}
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
