"""Perimeter mission: cyclic patrol of a closed polygon or a circle (paper: "phase-offset
starting points, smoothed paths respecting minimum turn radii, loop continuity,
insertion/removal, consistent spacing through time- or angle-based offsets").

- The loop is the polygon's outline (or the circle). For fixed-wing aircraft it is
  smoothed with the largest turn radius R: a morphological opening then closing by R
  rounds every corner to an arc of radius >= R (a shape narrower than 2R is an error).
- All vehicles fly the loop in the same direction at one common speed (inside every
  vehicle's range), starting L/N apart along it: equal spacing in distance and time.
- Entry is timed like a target orbit's: each vehicle flies a Dubins path (or a straight
  line) to its start point, tangent to the loop, and all arrive together
  (`route.synchronize`: whole waiting orbits or a hover wait, plus a speed trim).
- Slots keep the vehicles' order along the loop; `respace_perimeter` re-spaces them
  with speed trims when one joins or leaves.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

from shapely.geometry import LinearRing, LineString, Point, Polygon

from swarm_proto import Geometry, GeometryKind

from .context import PlanContext
from .dubins import Pose
from .errors import InvalidGeometryError, NoSafeRouteError
from .formation import Trim, cyclic_slots, respace, speed_ranges_on
from .geo import LocalFrame
from .route import Arrival, Leg, approach, arrival_waypoints, synchronize
from .vehicles import (
    PlanVehicle,
    VehiclePlan,
    common_speed,
    require_vehicles,
    to_waypoints,
)
from .zones import Track, ZoneSet


@dataclass(frozen=True, slots=True)
class PerimeterPlan:
    frame: LocalFrame
    loop: tuple[tuple[float, float], ...]  # closed ring (first point not repeated), CCW
    length_m: float
    speed_m_s: float  # common speed
    offsets_m: tuple[tuple[int, float], ...]  # vehicle id -> start position along loop
    vehicles: tuple[VehiclePlan, ...]
    turn_radius_m: float = 0.0  # the loop's tightest turn (smoothing radius, circle radius)
    arrival_s: float = 0.0  # when every positioned vehicle is at its start point
    arrivals: tuple[Arrival, ...] = ()  # how each positioned vehicle gets there on time
    legs: tuple[Leg, ...] = ()  # their arrival legs
    tracks: tuple[Track, ...] = ()  # every path flown, densely sampled (zone checks)

    @property
    def lap_s(self) -> float:
        return self.length_m / self.speed_m_s

    def offset_of(self, vehicle_id: int) -> float:
        return dict(self.offsets_m)[vehicle_id]


def smooth_loop(polygon: Polygon, radius_m: float) -> Polygon:
    """`polygon`'s outline with every corner rounded to a radius >= `radius_m`."""
    if radius_m <= 0.0:
        return Polygon(polygon.exterior)
    shell = Polygon(polygon.exterior)
    opened = shell.buffer(-radius_m, quad_segs=16).buffer(radius_m, quad_segs=16)
    if opened.is_empty or not isinstance(opened, Polygon):
        raise InvalidGeometryError(
            f"the perimeter is too narrow for a {radius_m:.0f} m turn radius"
        )
    closed = opened.buffer(radius_m, quad_segs=16).buffer(-radius_m, quad_segs=16)
    if not isinstance(closed, Polygon):
        raise InvalidGeometryError("smoothing split the perimeter")
    return closed


def _loop(geometry: Geometry, frame: LocalFrame, radius: float) -> LinearRing:
    shape = frame.shape(geometry)
    if not isinstance(shape, Polygon):
        raise InvalidGeometryError(f"a perimeter is a POLYGON or CIRCLE, got {geometry.kind.name}")
    if geometry.kind == GeometryKind.CIRCLE:
        assert geometry.radius_m is not None
        if geometry.radius_m < radius:
            raise InvalidGeometryError(
                f"circle radius {geometry.radius_m:.0f} m is below the turn radius {radius:.0f} m"
            )
        ring = shape.exterior
    else:
        ring = smooth_loop(shape, radius).exterior.simplify(0.5)
    if not ring.is_ccw:
        ring = LinearRing(list(ring.coords)[::-1])
    return LinearRing(ring.coords)


def plan_perimeter(ctx: PlanContext) -> PerimeterPlan:
    geometry, vehicles, params = ctx.geometry, ctx.vehicles, ctx.params
    require_vehicles(vehicles)
    if geometry.kind not in (GeometryKind.POLYGON, GeometryKind.CIRCLE):
        raise InvalidGeometryError(f"a perimeter is a POLYGON or CIRCLE, got {geometry.kind.name}")
    frame = ctx.local_frame()
    speed = common_speed(vehicles, params)
    radius = max(
        max(
            v.profile.turn_radius_m(speed),
            v.profile.loiter_radius_m if v.profile.is_fixed_wing else 0.0,
        )
        for v in vehicles
    )
    ring = _loop(geometry, frame, radius)
    loop_radius = (geometry.radius_m or radius) if geometry.kind == GeometryKind.CIRCLE else radius
    zs = ctx.zone_set(frame)
    alts = {
        v.vehicle_id: params.altitude_rel_m + i * params.altitude_step_m
        for i, v in enumerate(vehicles)
    }
    lo, hi = min(alts.values()), max(alts.values())
    band = ZoneSet(zs.at(lo, hi), zs.margin_m, zs.vertical_margin_m)
    if band.zones and LineString(ring.coords).intersects(band.keep_out(None)):
        raise NoSafeRouteError("the perimeter loop crosses a no-fly zone: replan the mission")
    length = ring.length
    pos = {}
    for i, v in enumerate(vehicles):
        if v.pose is None:
            pos[v.vehicle_id] = length * i / len(vehicles)
        else:
            pos[v.vehicle_id] = ring.project(Point(frame.to_local(v.pose.lat_deg, v.pose.lon_deg)))
    offsets = cyclic_slots(pos, length)
    loops = max(params.loops, 1)
    # timed entry: every vehicle reaches its start point, heading along the loop, at the
    # same moment (route.synchronize), so the spacing in time holds from the first lap
    aps = {}
    for v in vehicles:
        if v.pose is not None:
            start = Pose(*frame.pose(v.pose))
            goal = _loop_pose(ring, offsets[v.vehicle_id])
            aps[v.vehicle_id] = (
                start,
                approach(v, start, goal, v.speed(params), zs, alts[v.vehicle_id]),
            )
    sync = synchronize([ap.leg for _start, ap in aps.values()])
    arrival_s = next(iter(sync.values())).arrival_s if sync else 0.0
    loop_xy = tuple((float(x), float(y)) for x, y in ring.coords)
    plans = []
    tracks: list[Track] = []
    for v in vehicles:
        alt = alts[v.vehicle_id]
        pts = lap_points(ring, offsets[v.vehicle_id], loops)
        tracks.append(Track(v.vehicle_id, "loop", loop_xy, alt))
        lap_m = length * loops
        if v.vehicle_id in aps:
            start, ap = aps[v.vehicle_id]
            arr = sync[v.vehicle_id]
            wps = arrival_waypoints(frame, ap, arr, alt, start)
            wps += to_waypoints(frame, pts[1:], alt, speed_m_s=speed)
            tracks += ap.tracks(arr, alt)
            flown, t0 = arr.flown_m(ap.leg), arr.arrival_s
        else:
            wps = list(to_waypoints(frame, pts, alt, speed_m_s=speed))
            flown, t0 = 0.0, 0.0
        plans.append(VehiclePlan(v.vehicle_id, tuple(wps), flown + lap_m, t0 + lap_m / speed))
    coords = tuple((float(x), float(y)) for x, y in list(ring.coords)[:-1])
    return PerimeterPlan(
        frame,
        coords,
        length,
        speed,
        tuple((v.vehicle_id, offsets[v.vehicle_id]) for v in vehicles),
        tuple(plans),
        loop_radius,
        arrival_s,
        tuple(sync[v.vehicle_id] for v in vehicles if v.vehicle_id in sync),
        tuple(ap.leg for _start, ap in aps.values()),
        tuple(tracks),
    )


def _loop_pose(ring: LinearRing, at_m: float) -> Pose:
    """The pose on the (counter-clockwise) loop `at_m` along it, heading along it."""
    n = ring.length
    p = ring.interpolate(at_m % n)
    a = ring.interpolate((at_m - 0.5) % n)
    b = ring.interpolate((at_m + 0.5) % n)
    return Pose(float(p.x), float(p.y), math.atan2(b.y - a.y, b.x - a.x))


def lap_points(ring: LinearRing, start_m: float, laps: int = 1) -> list[tuple[float, float]]:
    """The loop's vertices starting at `start_m` along it, `laps` times round, closed."""
    coords = list(ring.coords)[:-1]
    dist = [ring.project(Point(c)) for c in coords]
    first = ring.interpolate(start_m % ring.length)
    s0 = start_m % ring.length
    after = sorted(range(len(coords)), key=lambda i: (dist[i] - s0) % ring.length)
    one = [(float(coords[i][0]), float(coords[i][1])) for i in after]
    start = (float(first.x), float(first.y))
    out = [start]
    for _ in range(laps):
        out += [p for p in one if math.dist(p, out[-1]) > 1e-6]
        out.append(start)
    return out


def respace_perimeter(
    plan: PerimeterPlan,
    positions_m: Mapping[int, float],
    vehicles: Sequence[PlanVehicle],
) -> dict[int, Trim]:
    """Vehicles at `positions_m` along the loop (some joined, some left): new equal
    offsets (order kept) and the speed trims that bring everyone there together, each
    within the vehicle's speed range on the loop (a fixed-wing never faster than the
    loop's tightest turn allows at its max bank)."""
    ranges = speed_ranges_on(vehicles, positions_m, plan.turn_radius_m)
    return respace(positions_m, plan.length_m, plan.speed_m_s, ranges)
