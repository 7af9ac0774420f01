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

from swarm_node.core.autopilot.items import ItemKind, Waypoint
from swarm_proto import Geometry, GeometryKind, MissionParams, NoFlyZone

from .dubins import Pose
from .errors import InfeasibleTimingError, InvalidGeometryError, InvalidParameterError
from .geo import LocalFrame, heading_to_yaw
from .turns import DubinsTurns
from .vehicles import DEFAULT_PARAMS, PlanVehicle, VehiclePlan, require_vehicles
from .zones import ZoneSet

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
    return Leg(v.vehicle_id, path_m, 0.0, lo, hi, cruise)


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
    if leg.orbit_m <= 0.0:  # can wait on the spot
        if leg.path_m <= 0.0:
            return 0, t, leg.cruise_speed_m_s
        v = min(max(leg.cruise_speed_m_s, leg.path_m / t), leg.max_speed_m_s)
        if leg.path_m / v > t + 1e-9:
            return None
        return 0, t - leg.path_m / v, v
    best: tuple[int, float, float] | None = None
    for k in range(_MAX_ORBITS + 1):
        dist = leg.path_m + k * leg.orbit_m
        v = dist / t  # grows with k
        if v < leg.min_speed_m_s - 1e-9:
            continue
        if v > leg.max_speed_m_s + 1e-9:
            break
        if best is None or abs(v - leg.cruise_speed_m_s) < abs(best[2] - leg.cruise_speed_m_s):
            best = (k, 0.0, v)
    return best


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
        if leg.orbit_m > 0.0:
            for k in range(_MAX_ORBITS + 1):
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
    vehicle_id: int
    points: tuple[tuple[float, float], ...]  # local, start excluded, goal included
    length_m: float
    leg: Leg
    loiter_centre: tuple[float, float] | None
    loiter_radius_m: float  # > 0 clockwise (ArduPilot sign)


def approach(
    v: PlanVehicle, start: Pose, goal: Pose, speed_m_s: float, zones: ZoneSet, alt_m: float
) -> Approach:
    """A vehicle's path from `start` to `goal` (Dubins for fixed-wing, straight
    otherwise; around the zones when the direct one would cross them)."""
    turns = v.turns(speed_m_s)
    pts = [(p.x, p.y) for p in turns.points(start, goal)]
    length = turns.length(start, goal)
    path = [(start.x, start.y), *pts]
    zs = zones.at(alt_m)
    if zs:
        from .zones import Obstacles

        obst = Obstacles(zones.keep_out(alt_m))
        if obst.crosses(path):
            around = obst.path((start.x, start.y), (goal.x, goal.y))
            pts = around[1:]
            length = sum(
                math.hypot(b[0] - a[0], b[1] - a[1]) for a, b in itertools.pairwise(around)
            )
    leg = leg_for(v, length, speed_m_s)
    if isinstance(turns, DubinsTurns):
        r = leg.radius_m
        # orbit beside the start, turning left (counter-clockwise): back to the start pose
        cx = start.x - r * math.sin(start.yaw)
        cy = start.y + r * math.cos(start.yaw)
        return Approach(v.vehicle_id, tuple(pts), length, leg, (cx, cy), -r)
    return Approach(v.vehicle_id, tuple(pts), length, leg, None, 0.0)


def arrival_waypoints(
    frame: LocalFrame, ap: Approach, arr: Arrival, alt_m: float, start: Pose
) -> list[Waypoint]:
    """CHANGE_SPEED, the loiter orbits or the hover wait, then the approach points."""
    out = [Waypoint(ItemKind.CHANGE_SPEED, speed_m_s=arr.speed_m_s)]
    if arr.orbits > 0 and ap.loiter_centre is not None:
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
    if arr.hold_s > 0.0:
        lat, lon = frame.to_geodetic(start.x, start.y)
        out.append(Waypoint(ItemKind.LOITER_TIME, lat, lon, alt_m, hold_s=arr.hold_s))
    if ap.points:
        ll = frame.to_geodetic_many(ap.points)
        out += [Waypoint(ItemKind.WAYPOINT, la, lo, alt_m) for la, lo in ll.tolist()]
    return out


# --------------------------------------------------------------------------- route mission


@dataclass(frozen=True, slots=True)
class RoutePlan:
    frame: LocalFrame
    arrival_s: float
    arrivals: tuple[Arrival, ...]
    vehicles: tuple[VehiclePlan, ...]
    legs: tuple[Leg, ...] = ()  # each vehicle's arrival leg (path, orbit, speed range)


def plan_route(
    geometry: Geometry,
    vehicles: Sequence[PlanVehicle],
    params: MissionParams = DEFAULT_PARAMS,
    *,
    zones: Sequence[NoFlyZone] = (),
    now_unix_s: float = 0.0,
    home_alt_msl_m: float = 0.0,
    zone_margin_m: float = 0.0,
    max_alt_rel_m: float = 120.0,
    frame: LocalFrame | None = None,
) -> RoutePlan:
    """All vehicles reach the route's first point at the same moment (heading along the
    first leg, or `heading_deg`), then fly the route; legs crossing a no-fly zone climb
    over it (ceiling + margin <= `max_alt_rel_m`) or go around it."""
    require_vehicles(vehicles)
    if geometry.kind not in (GeometryKind.POLYLINE, GeometryKind.POINT):
        raise InvalidGeometryError(f"a route needs a POLYLINE or POINT, got {geometry.kind.name}")
    if any(v.pose is None for v in vehicles):
        raise InvalidParameterError("a route plan needs every vehicle's current position")
    frame = frame or LocalFrame.for_geometry(geometry)
    zs = ZoneSet.from_messages(
        zones, frame, now_unix_s=now_unix_s, home_alt_msl_m=home_alt_msl_m, margin_m=zone_margin_m
    )
    pts = frame.ring(geometry.points)
    alts = [params.altitude_rel_m + i * params.altitude_step_m for i in range(len(vehicles))]
    from .errors import TargetInZoneError

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
    for v, ap, start, alt in zip(vehicles, aps, starts, alts, strict=True):
        a = arr[v.vehicle_id]
        wps = arrival_waypoints(frame, ap, a, alt, start)
        route3d = [(x, y, alt) for x, y in pts]
        safe = zs.avoid(route3d, max_alt_rel_m=max_alt_rel_m) if zs.zones else route3d
        cruise = v.speed(params)
        wps.append(Waypoint(ItemKind.CHANGE_SPEED, speed_m_s=cruise))
        if len(safe) > 1:
            ll = frame.to_geodetic_many([(p[0], p[1]) for p in safe[1:]]).tolist()
            for (la, lo), p in zip(ll, safe[1:], strict=True):
                wps.append(Waypoint(ItemKind.WAYPOINT, la, lo, p[2]))
        length = a.flown_m(ap.leg) + sum(
            math.hypot(b[0] - c[0], b[1] - c[1]) for c, b in itertools.pairwise(safe)
        )
        plans.append(VehiclePlan(v.vehicle_id, tuple(wps), length, a.arrival_s))
    t = next(iter(arr.values())).arrival_s
    return RoutePlan(
        frame,
        t,
        tuple(arr[v.vehicle_id] for v in vehicles),
        tuple(plans),
        tuple(a.leg for a in aps),
    )
