"""Route missions and simultaneous arrival.

`synchronize` makes several vehicles arrive at one point at the same time: each flies
its own path (Dubins for fixed-wing, straight for the others) plus a whole number of
loiter orbits, at a speed trimmed within its range; hover-capable vehicles may instead
wait. The turn radius is never inflated to stretch a path: the Dubins length is not
monotone in the radius, and a wider turn changes the path, not just its length.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass

from shapely.geometry import LineString
from shapely.geometry.base import BaseGeometry

from swarm_node.core.autopilot.items import ItemKind, Waypoint
from swarm_proto import GeometryKind

from .context import PlanContext
from .dubins import Pose, all_paths
from .errors import (
    InfeasibleTimingError,
    InvalidGeometryError,
    InvalidParameterError,
    NoSafeRouteError,
    TargetInZoneError,
)
from .geo import LocalFrame, heading_to_yaw
from .turns import DubinsTurns
from .vehicles import PlanVehicle, VehiclePlan, require_vehicles
from .zones import ARC_STEP_M, Obstacles, Track, ZoneSet, circle_points

_MAX_ORBITS = 60


@dataclass(frozen=True, slots=True)
class Leg:
    """One vehicle's approach to the meeting point."""

    vehicle_id: int
    path_m: float  # length of its path to the point
    orbit_m: float  # circumference of one loiter orbit (0: it can hover instead)
    min_speed_m_s: float
    max_speed_m_s: float  # for a fixed-wing, already capped by what `radius_m` allows
    cruise_speed_m_s: float
    radius_m: float = 0.0  # the turn radius its path and orbit were planned with (0: none)
    hover: bool = False  # it can wait on the spot (hover-capable) instead of orbiting

    def __post_init__(self) -> None:
        vals = (self.path_m, self.orbit_m, self.min_speed_m_s, self.max_speed_m_s, self.radius_m)
        if not all(math.isfinite(v) and v >= 0.0 for v in vals) or self.max_speed_m_s <= 0:
            raise InvalidParameterError(f"vehicle {self.vehicle_id}: bad arrival leg {vals}")
        if self.min_speed_m_s > self.max_speed_m_s:
            raise InvalidParameterError(f"vehicle {self.vehicle_id}: min speed > max speed")


def leg_for(v: PlanVehicle, path_m: float, speed_m_s: float) -> Leg:
    """A vehicle's arrival leg for a path of `path_m` planned at mission speed
    `speed_m_s`: a fixed-wing's path and loiter orbit use the turn radius R of that speed
    (never below its loiter radius), so its usable speeds are capped at
    sqrt(R g tan(max bank)); hover-capable vehicles wait on the spot instead."""
    turns = v.turns(speed_m_s)
    r = turns.radius_m
    lo, hi = v.speed_range_on(r)
    cruise = min(max(speed_m_s, lo), hi)
    if r > 0.0:
        return Leg(v.vehicle_id, path_m, 2 * math.pi * r, lo, hi, cruise, r)
    return Leg(v.vehicle_id, path_m, 0.0, lo, hi, cruise, hover=True)


@dataclass(frozen=True, slots=True)
class Arrival:
    vehicle_id: int
    orbits: int  # whole loiter orbits flown before the path
    hold_s: float  # time spent hovering before the path (hover-capable only)
    speed_m_s: float
    arrival_s: float  # from now

    def flown_m(self, leg: Leg) -> float:
        return leg.path_m + self.orbits * leg.orbit_m


def _options(leg: Leg, t: float) -> tuple[int, float, float] | None:
    """(orbits, hold, speed) letting `leg` arrive exactly at `t`, closest to cruise."""
    if leg.hover:  # can wait on the spot
        if leg.path_m <= 0.0:
            return 0, t, leg.cruise_speed_m_s
        v = min(max(leg.cruise_speed_m_s, leg.path_m / t), leg.max_speed_m_s)
        if leg.path_m / v > t + 1e-9:
            return None
        return 0, t - leg.path_m / v, v
    best: tuple[int, float, float] | None = None
    for k in _orbit_counts(leg):
        dist = leg.path_m + k * leg.orbit_m
        v = dist / t  # grows with k
        if v < leg.min_speed_m_s - 1e-9:
            continue
        if v > leg.max_speed_m_s + 1e-9:
            break
        # `t` may be another leg's candidate time, a rounding error short of what this leg
        # needs at its limit: within the tolerance, fly the limit itself (arriving a
        # nanosecond late) rather than a speed a hair outside the range, whose turn would
        # be wider than the radius the path was planned with
        v = min(max(v, leg.min_speed_m_s), leg.max_speed_m_s)
        if best is None or abs(v - leg.cruise_speed_m_s) < abs(best[2] - leg.cruise_speed_m_s):
            best = (k, 0.0, v)
    return best


def _orbit_counts(leg: Leg) -> range:
    """The whole orbits a leg may fly: none when it has no room for an orbit."""
    return range(_MAX_ORBITS + 1) if leg.orbit_m > 0.0 else range(1)


def synchronize(legs: Sequence[Leg], *, not_before_s: float = 0.0) -> dict[int, Arrival]:
    """The earliest common arrival time (>= `not_before_s`) every leg can meet, and how
    each vehicle meets it. Raises `InfeasibleTimingError` if none within the orbit cap."""
    if not legs:
        return {}
    if all(leg.path_m < 1e-6 for leg in legs) and not_before_s <= 0.0:
        return {
            leg.vehicle_id: Arrival(leg.vehicle_id, 0, 0.0, leg.cruise_speed_m_s, 0.0)
            for leg in legs
        }
    earliest = max([not_before_s, 1e-9, *(leg.path_m / leg.max_speed_m_s for leg in legs)])
    cands = {earliest}
    for leg in legs:
        if not leg.hover:
            for k in _orbit_counts(leg):
                for v in (leg.max_speed_m_s, leg.min_speed_m_s):
                    if v > 0:
                        t = (leg.path_m + k * leg.orbit_m) / v
                        if t >= earliest:
                            cands.add(t)
    for t in sorted(cands):
        got = [_options(leg, t) for leg in legs]
        if all(g is not None for g in got):
            return {
                leg.vehicle_id: Arrival(leg.vehicle_id, g[0], g[1], g[2], t)
                for leg, g in zip(legs, got, strict=True)
                if g is not None
            }
    raise InfeasibleTimingError(
        f"no common arrival time within the speed ranges and {_MAX_ORBITS} loiter orbits"
    )


# --------------------------------------------------------------------------- approach


@dataclass(frozen=True, slots=True)
class Approach:
    """A vehicle's planned way to a meeting point, and where it may wait on the way."""

    vehicle_id: int
    points: tuple[tuple[float, float], ...]  # waypoints: local, start excluded, goal included
    length_m: float
    leg: Leg
    loiter_centre: tuple[float, float] | None  # None: no waiting orbit (or no room for one)
    loiter_radius_m: float  # > 0 clockwise (ArduPilot sign)
    trace: tuple[tuple[float, float], ...] = ()  # the path sampled densely, start included
    loiter_after: int = 0  # the orbit is flown after points[:loiter_after] ...
    loiter_entry: tuple[float, float] | None = None  # ... from this tangent point (None: start)

    def tracks(self, arr: Arrival, alt_m: float) -> list[Track]:
        """The approach as flown, and its waiting orbit if the arrival flies one."""
        out = [Track(self.vehicle_id, "approach", self.trace, alt_m)]
        if arr.orbits > 0 and self.loiter_centre is not None:
            circle = circle_points(*self.loiter_centre, abs(self.loiter_radius_m))
            out.append(Track(self.vehicle_id, "wait", circle, alt_m))
        return out


def _polyline_poses(pts: Sequence[tuple[float, float]], step_m: float) -> list[tuple[float, Pose]]:
    """(distance along, pose) every `step_m` along a polyline, heading along each leg."""
    out: list[tuple[float, Pose]] = []
    s0 = 0.0
    for a, b in itertools.pairwise(pts):
        d = math.hypot(b[0] - a[0], b[1] - a[1])
        if d <= 1e-9:
            continue
        yaw = math.atan2(b[1] - a[1], b[0] - a[0])
        n = max(1, math.ceil(d / step_m))
        for i in range(n):
            f = i / n
            out.append((s0 + f * d, Pose(a[0] + f * (b[0] - a[0]), a[1] + f * (b[1] - a[1]), yaw)))
        s0 += d
    return out


def ahead_of(
    start: Pose, around: Sequence[tuple[float, float]], raw: BaseGeometry
) -> list[tuple[float, float]]:
    """A polyline from a fixed-wing's position without its first corners that lie
    behind it (more than 90 degrees off its heading) while the straight way to the next
    one stays out of the zones (`raw`): the autopilot flies to a corner behind it in a
    loop whose side is its own choice, and the turn onto the next leg after it may face
    the zone. Measured: a VTOL voted out at a survey lane's end 35 m from a zone got a
    way around the zone's margin starting 55 m behind it, looped to it and turned into
    the zone (GEOFENCE_BREACH)."""
    out = list(around)
    hx, hy = math.cos(start.yaw), math.sin(start.yaw)
    while len(out) > 2:
        x, y = out[1]
        behind = (x - start.x) * hx + (y - start.y) * hy < 0.0
        if not behind or (not raw.is_empty and LineString([out[0], out[2]]).intersects(raw)):
            break
        del out[1]
    return out


def approach(
    v: PlanVehicle, start: Pose, goal: Pose, speed_m_s: float, zones: ZoneSet, alt_m: float
) -> Approach:
    """A vehicle's path from `start` to `goal`, clear of the (inflated) zones at `alt_m`.

    Fixed-wing: the shortest Dubins word at the turn radius of `speed_m_s` whose arcs
    (sampled every couple of metres) stay clear; else the shortest polyline around the
    zones (visibility graph). The waiting orbit (for `synchronize`) is tangent to the
    path, at the first place along it (the start first, each side) where the whole
    circle is clear; with no such place the leg gets no orbit and must make up time
    with its speed alone. Other vehicles: a straight line (or around the zones), and
    they wait on the spot."""
    turns = v.turns(speed_m_s)
    keep = zones.keep_out(alt_m) if zones.at(alt_m) else None
    obst = Obstacles(keep, zones.raw(alt_m)) if keep is not None and not keep.is_empty else None
    start_xy = (start.x, start.y)
    path_poses: list[tuple[float, Pose]] = []  # candidate places for the waiting orbit
    pts: list[tuple[float, float]] = []
    pts_s: list[float] = []
    trace: list[tuple[float, float]] = []
    length = math.nan
    if isinstance(turns, DubinsTurns):
        r = turns.radius_m
        for path in all_paths(start, goal, r):
            xy = [(float(x), float(y)) for x, y in path.sample_xy(ARC_STEP_M)]
            if obst is None or not obst.crosses(xy):
                pts_s = path.waypoint_s()
                pts = [(q.x, q.y) for q in (path.pose_at(x) for x in pts_s)]
                trace, length = xy, path.length_m
                step = max(r / 2.0, 10.0)
                n = max(1, math.ceil(path.length_m / step))
                path_poses = [
                    (path.length_m * i / n, path.pose_at(path.length_m * i / n)) for i in range(n)
                ]
                break
    else:
        trace = [start_xy, (goal.x, goal.y)]
        if obst is None or not obst.crosses(trace):
            pts, pts_s = [(goal.x, goal.y)], [math.hypot(goal.x - start.x, goal.y - start.y)]
            length = pts_s[0]
    if math.isnan(length):  # around the zones
        assert obst is not None
        around = obst.path_from(start_xy, (goal.x, goal.y))  # it may be in a margin
        if isinstance(turns, DubinsTurns):
            around = ahead_of(start, around, zones.raw(alt_m))
        pts = list(around[1:])
        pts_s = list(itertools.accumulate(math.dist(a, b) for a, b in itertools.pairwise(around)))
        trace, length = list(around), pts_s[-1] if pts_s else 0.0
        path_poses = _polyline_poses(around, max(turns.radius_m / 2.0, 10.0))
    leg = leg_for(v, length, speed_m_s)
    if not isinstance(turns, DubinsTurns):
        return Approach(v.vehicle_id, tuple(pts), length, leg, None, 0.0, tuple(trace))
    r = leg.radius_m
    for s_at, pose in path_poses or [(0.0, start)]:
        for side in (1.0, -1.0):  # left of the path (counter-clockwise), then right
            cx = pose.x - side * r * math.sin(pose.yaw)
            cy = pose.y + side * r * math.cos(pose.yaw)
            if keep is None or zones.entered(circle_points(cx, cy, r), alt_m) is None:
                after = sum(1 for x in pts_s if x <= s_at + 1e-9) if s_at > 0 else 0
                entry = (pose.x, pose.y) if s_at > 0 else None
                return Approach(
                    v.vehicle_id,
                    tuple(pts),
                    length,
                    leg,
                    (cx, cy),
                    -side * r,
                    tuple(trace),
                    after,
                    entry,
                )
    no_orbit = Leg(
        v.vehicle_id, length, 0.0, leg.min_speed_m_s, leg.max_speed_m_s, leg.cruise_speed_m_s, r
    )
    return Approach(v.vehicle_id, tuple(pts), length, no_orbit, None, 0.0, tuple(trace))


def arrival_waypoints(
    frame: LocalFrame, ap: Approach, arr: Arrival, alt_m: float, start: Pose
) -> list[Waypoint]:
    """CHANGE_SPEED, the hover wait, the approach points with the loiter orbits where
    the approach put them (a WAYPOINT at the orbit's tangent point, then LOITER_TURNS)."""
    out = [Waypoint(ItemKind.CHANGE_SPEED, speed_m_s=arr.speed_m_s)]
    if arr.hold_s > 0.0:
        lat, lon = frame.to_geodetic(start.x, start.y)
        out.append(Waypoint(ItemKind.LOITER_TIME, lat, lon, alt_m, hold_s=arr.hold_s))
    before: tuple[tuple[float, float], ...] = ap.points
    after: tuple[tuple[float, float], ...] = ()
    if arr.orbits > 0:
        if ap.loiter_centre is None:
            raise NoSafeRouteError(f"vehicle {ap.vehicle_id} has no room for a waiting orbit")
        before, after = ap.points[: ap.loiter_after], ap.points[ap.loiter_after :]
        if ap.loiter_entry is not None:
            before = (*before, ap.loiter_entry)
    out += _waypoints(frame, before, alt_m)
    if arr.orbits > 0:
        assert ap.loiter_centre is not None
        lat, lon = frame.to_geodetic(*ap.loiter_centre)
        out.append(
            Waypoint(
                ItemKind.LOITER_TURNS,
                lat,
                lon,
                alt_m,
                loiter_radius_m=ap.loiter_radius_m,
                turns=float(arr.orbits),
            )
        )
        out += _waypoints(frame, after, alt_m)
    return out


def _waypoints(
    frame: LocalFrame, pts: Sequence[tuple[float, float]], alt_m: float
) -> list[Waypoint]:
    if not pts:
        return []
    ll = frame.to_geodetic_many(pts)
    return [Waypoint(ItemKind.WAYPOINT, la, lo, alt_m) for la, lo in ll.tolist()]


# --------------------------------------------------------------------------- route mission


@dataclass(frozen=True, slots=True)
class RoutePlan:
    frame: LocalFrame
    arrival_s: float
    arrivals: tuple[Arrival, ...]
    vehicles: tuple[VehiclePlan, ...]
    legs: tuple[Leg, ...] = ()  # each vehicle's arrival leg (path, orbit, speed range)
    tracks: tuple[Track, ...] = ()  # every path flown, densely sampled (zone checks)


def plan_route(
    ctx: PlanContext,
    *,
    max_alt_rel_m: float = 120.0,
) -> RoutePlan:
    """All vehicles reach the route's first point at the same moment (heading along the
    first leg, or `heading_deg`), then fly the route; legs crossing a no-fly zone climb
    over it (ceiling + margin <= `max_alt_rel_m`) or go around it."""
    geometry, vehicles, params = ctx.geometry, ctx.vehicles, ctx.params
    require_vehicles(vehicles)
    if geometry.kind not in (GeometryKind.POLYLINE, GeometryKind.POINT):
        raise InvalidGeometryError(f"a route needs a POLYLINE or POINT, got {geometry.kind.name}")
    if any(v.pose is None for v in vehicles):
        raise InvalidParameterError("a route plan needs every vehicle's current position")
    frame = ctx.local_frame()
    zs = ctx.zone_set(frame)
    pts = frame.ring(geometry.points)
    alts = [params.altitude_rel_m + i * params.altitude_step_m for i in range(len(vehicles))]
    for x, y in pts:
        for alt in alts:
            z = zs.zone_containing(x, y, alt)
            if z is not None:
                raise TargetInZoneError(
                    f"route point ({x:.0f}, {y:.0f}) is in no-fly zone {z.zone_id}"
                )
    if params.heading_deg is not None:
        yaw = heading_to_yaw(params.heading_deg)
    elif len(pts) > 1:
        yaw = math.atan2(pts[1][1] - pts[0][1], pts[1][0] - pts[0][0])
    else:
        yaw = 0.0
    goal = Pose(pts[0][0], pts[0][1], yaw)
    aps = []
    starts = []
    for v, alt in zip(vehicles, alts, strict=True):
        assert v.pose is not None
        start = Pose(*frame.pose(v.pose))
        starts.append(start)
        aps.append(approach(v, start, goal, v.speed(params), zs, alt))
    arr = synchronize([a.leg for a in aps])
    plans = []
    tracks: list[Track] = []
    for v, ap, start, alt in zip(vehicles, aps, starts, alts, strict=True):
        a = arr[v.vehicle_id]
        wps = arrival_waypoints(frame, ap, a, alt, start)
        tracks += ap.tracks(a, alt)
        route3d = [(x, y, alt) for x, y in pts]
        safe = zs.avoid(route3d, max_alt_rel_m=max_alt_rel_m) if zs.zones else route3d
        tracks += [
            Track(v.vehicle_id, "route", (p[:2], q[:2]), min(p[2], q[2]), max(p[2], q[2]))
            for p, q in itertools.pairwise(safe)
        ]
        cruise = v.speed(params)
        wps.append(Waypoint(ItemKind.CHANGE_SPEED, speed_m_s=cruise))
        if len(safe) > 1:
            ll = frame.to_geodetic_many([(p[0], p[1]) for p in safe[1:]]).tolist()
            for (la, lo), p in zip(ll, safe[1:], strict=True):
                wps.append(Waypoint(ItemKind.WAYPOINT, la, lo, p[2]))
        route_m = sum(math.hypot(b[0] - c[0], b[1] - c[1]) for c, b in itertools.pairwise(safe))
        length = a.flown_m(ap.leg) + route_m
        # the share's time: the synchronized arrival, then the route at the mission speed
        plans.append(VehiclePlan(v.vehicle_id, tuple(wps), length, a.arrival_s + route_m / cruise))
    t = next(iter(arr.values())).arrival_s
    return RoutePlan(
        frame,
        t,
        tuple(arr[v.vehicle_id] for v in vehicles),
        tuple(plans),
        tuple(a.leg for a in aps),
        tuple(tracks),
    )
