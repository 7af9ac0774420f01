"""Target mission: a formation around a point (paper: "symmetric formations adapted to
rotary-wing (hover) and fixed-wing (fly-through) platforms, altitude steps, angle
spacing, initial positions used to optimize arrival").

- Hover-capable vehicles hover on a circle of `radius_m` at equal angles.
- Fixed-wing vehicles orbit the point at a radius >= v^2 / (g tan(max bank)) of the
  widest-turning one, with phases 2 pi / N apart, all in the same direction; they enter
  the orbit at their phase point at the same moment (route.synchronize), so the spacing
  holds from the start.
- Slots are handed out in the vehicles' angular order around the target (paths do not
  cross) and the pattern is rotated to shorten the largest approach.
- Every vehicle has its own altitude: altitude_rel_m + i * altitude_step_m.
- `respace_orbit` re-spaces the orbiters when one joins or leaves (speed trims).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

from shapely.geometry import Point

from swarm_node.core.autopilot.items import ItemKind, Waypoint
from swarm_proto import GeometryKind, MissionParams

from .context import PlanContext
from .dubins import Pose
from .errors import InvalidGeometryError, InvalidParameterError, TargetInZoneError
from .formation import Trim, cyclic_slots, respace, speed_ranges_on
from .geo import LocalFrame
from .route import Arrival, Leg, approach, arrival_waypoints, synchronize
from .vehicles import PlanVehicle, VehiclePlan, common_speed, require_vehicles
from .zones import Track, Zone, ZoneSet, circle_points

DEFAULT_HOVER_RADIUS_M = 50.0


@dataclass(frozen=True, slots=True)
class Slot:
    vehicle_id: int
    x: float
    y: float
    alt_rel_m: float
    phase_rad: float  # angle around the target, CCW from east
    radius_m: float
    orbit: bool  # True: orbiting (fixed-wing), False: hovering


@dataclass(frozen=True, slots=True)
class TargetPlan:
    frame: LocalFrame
    centre: tuple[float, float]
    orbit_radius_m: float  # 0 when nobody orbits
    clockwise: bool
    slots: tuple[Slot, ...]
    arrivals: tuple[Arrival, ...]
    vehicles: tuple[VehiclePlan, ...]
    orbit_speed_m_s: float = 0.0  # the orbiters' common speed on the orbit
    legs: tuple[Leg, ...] = ()  # each positioned vehicle's arrival leg
    tracks: tuple[Track, ...] = ()  # every path flown, densely sampled (zone checks)

    def slot_of(self, vehicle_id: int) -> Slot:
        return next(s for s in self.slots if s.vehicle_id == vehicle_id)


def orbit_radius_m(
    vehicles: Sequence[PlanVehicle], params: MissionParams, orbit_speed_m_s: float
) -> float:
    """The common orbit radius: the requested one, never below any orbiter's minimum
    turn radius (v^2 / (g tan(max bank)), and its loiter radius) at the faster of its
    mission speed (it arrives on the orbit at that speed) and the common orbit speed."""
    need = max(
        (v.profile.turn_radius_m(max(v.speed(params), orbit_speed_m_s)) for v in vehicles),
        default=0.0,
    )
    return max(params.radius_m or 0.0, need)


def _phases(
    vehicles: Sequence[PlanVehicle], centre: tuple[float, float], frame: LocalFrame
) -> dict[int, float]:
    """Each vehicle's bearing from the centre (CCW from east); without a position, an
    arbitrary distinct one."""
    out = {}
    for i, v in enumerate(vehicles):
        if v.pose is None:
            out[v.vehicle_id] = 2 * math.pi * i / len(vehicles)
        else:
            x, y = frame.to_local(v.pose.lat_deg, v.pose.lon_deg)
            out[v.vehicle_id] = math.atan2(y - centre[1], x - centre[0]) % (2 * math.pi)
    return out


def plan_target(ctx: PlanContext, *, clockwise: bool = False) -> TargetPlan:
    geometry, vehicles, params = ctx.geometry, ctx.vehicles, ctx.params
    require_vehicles(vehicles)
    if geometry.kind not in (GeometryKind.POINT, GeometryKind.CIRCLE):
        raise InvalidGeometryError(f"a target is a POINT or CIRCLE, got {geometry.kind.name}")
    frame = ctx.local_frame()
    centre = frame.to_local(geometry.points[0].lat_deg, geometry.points[0].lon_deg)
    zs = ctx.zone_set(frame)
    alts = {
        v.vehicle_id: params.altitude_rel_m + i * params.altitude_step_m
        for i, v in enumerate(vehicles)
    }
    for alt in alts.values():
        z = zs.zone_containing(*centre, alt)
        if z is not None:
            raise TargetInZoneError(f"the target is inside no-fly zone {z.zone_id}")
    if geometry.kind == GeometryKind.CIRCLE and params.radius_m is None:
        params = _with_radius(params, geometry.radius_m)
    orbiters = [v for v in vehicles if v.profile.is_fixed_wing]
    hoverers = [v for v in vehicles if not v.profile.is_fixed_wing]
    # orbiters share one speed on the orbit, or the phase spacing would drift
    orbit_speed = common_speed(orbiters, params) if orbiters else 0.0
    r_orbit = orbit_radius_m(orbiters, params, orbit_speed) if orbiters else 0.0
    r_hover = params.radius_m if params.radius_m is not None else DEFAULT_HOVER_RADIUS_M
    bearings = _phases(vehicles, centre, frame)
    slots: list[Slot] = []
    for group, r, orbit in ((orbiters, r_orbit, True), (hoverers, r_hover, False)):
        if not group:
            continue
        phase = cyclic_slots({v.vehicle_id: bearings[v.vehicle_id] for v in group}, 2 * math.pi)
        for v in group:
            a = phase[v.vehicle_id]
            slots.append(
                Slot(
                    v.vehicle_id,
                    centre[0] + r * math.cos(a),
                    centre[1] + r * math.sin(a),
                    alts[v.vehicle_id],
                    a,
                    r,
                    orbit,
                )
            )
    for s in slots:
        z = zs.zone_containing(s.x, s.y, s.alt_rel_m)
        if z is not None:
            raise TargetInZoneError(
                f"vehicle {s.vehicle_id}'s slot around the target is inside no-fly zone {z.zone_id}"
            )
    orbit_ring = circle_points(*centre, r_orbit) if orbiters else ()
    for s in slots:
        z = zs.entered(orbit_ring, s.alt_rel_m) if s.orbit else None
        if z is not None:
            raise TargetInZoneError(
                f"the {r_orbit:.0f} m orbit around the target crosses no-fly zone {z.zone_id} "
                f"at {s.alt_rel_m:.0f} m: {_clear_radii(zs, z, centre)}"
            )
    by_id = {s.vehicle_id: s for s in slots}
    # orbiters arrive at their phase points together, tangent to the orbit
    sign = -1.0 if clockwise else 1.0
    aps = {}
    for v in vehicles:
        s = by_id[v.vehicle_id]
        if v.pose is None:
            continue
        start = Pose(*frame.pose(v.pose))
        goal_yaw = (
            s.phase_rad + sign * math.pi / 2
            if s.orbit
            else math.atan2(s.y - start.y, s.x - start.x)
        )
        aps[v.vehicle_id] = (
            start,
            approach(v, start, Pose(s.x, s.y, goal_yaw), v.speed(params), zs, s.alt_rel_m),
        )
    sync = synchronize([aps[v.vehicle_id][1].leg for v in orbiters if v.vehicle_id in aps])
    plans = []
    arrivals: list[Arrival] = []
    tracks: list[Track] = []
    for v in vehicles:
        s = by_id[v.vehicle_id]
        wps: list[Waypoint] = []
        length, t = 0.0, 0.0
        if s.orbit:
            tracks.append(Track(v.vehicle_id, "orbit", orbit_ring, s.alt_rel_m))
        if v.vehicle_id in aps:
            start, ap = aps[v.vehicle_id]
            arr = sync.get(v.vehicle_id) or Arrival(
                v.vehicle_id, 0, 0.0, v.speed(params), ap.length_m / v.speed(params)
            )
            arrivals.append(arr)
            wps += arrival_waypoints(frame, ap, arr, s.alt_rel_m, start)
            tracks += ap.tracks(arr, s.alt_rel_m)
            length, t = arr.flown_m(ap.leg), arr.arrival_s
        else:
            lat, lon = frame.to_geodetic(s.x, s.y)
            wps.append(Waypoint(ItemKind.WAYPOINT, lat, lon, s.alt_rel_m))
            tracks.append(Track(v.vehicle_id, "slot", ((s.x, s.y),), s.alt_rel_m))
        hold_speed = orbit_speed if s.orbit else v.speed(params)
        wps.append(_hold(frame, centre, s, params, clockwise, hold_speed))
        plans.append(VehiclePlan(v.vehicle_id, tuple(wps), length, t))
    return TargetPlan(
        frame,
        centre,
        r_orbit,
        clockwise,
        tuple(slots),
        tuple(arrivals),
        tuple(plans),
        orbit_speed,
        tuple(aps[v.vehicle_id][1].leg for v in vehicles if v.vehicle_id in aps),
        tuple(tracks),
    )


def _clear_radii(zs: ZoneSet, zone: Zone, centre: tuple[float, float]) -> str:
    """Which orbit radii clear `zone` (inflated by the margin): a circle around `centre`
    misses it below its nearest distance or beyond its farthest."""
    poly = zone.polygon.buffer(zs.margin_m, join_style="mitre") if zs.margin_m else zone.polygon
    near = poly.distance(Point(centre))
    far = max(math.dist(centre, c) for c in poly.exterior.coords)
    return f"an orbit clears it below {near:.0f} m or beyond {far:.0f} m radius"


def _with_radius(params: MissionParams, radius: float | None) -> MissionParams:
    import msgspec

    return msgspec.structs.replace(params, radius_m=radius)


def _hold(
    frame: LocalFrame,
    centre: tuple[float, float],
    s: Slot,
    params: MissionParams,
    clockwise: bool,
    speed: float,
) -> Waypoint:
    if s.orbit:
        lat, lon = frame.to_geodetic(*centre)
        r = s.radius_m if clockwise else -s.radius_m
        if params.loops > 0:
            return Waypoint(
                ItemKind.LOITER_TURNS,
                lat,
                lon,
                s.alt_rel_m,
                speed_m_s=speed,
                loiter_radius_m=r,
                turns=float(params.loops),
            )
        return Waypoint(
            ItemKind.LOITER_UNLIMITED, lat, lon, s.alt_rel_m, speed_m_s=speed, loiter_radius_m=r
        )
    lat, lon = frame.to_geodetic(s.x, s.y)
    if params.duration_s:
        return Waypoint(ItemKind.LOITER_TIME, lat, lon, s.alt_rel_m, hold_s=params.duration_s)
    return Waypoint(ItemKind.LOITER_UNLIMITED, lat, lon, s.alt_rel_m)


def respace_orbit(
    phases_rad: Mapping[int, float],
    radius_m: float,
    speed_m_s: float,
    vehicles: Sequence[PlanVehicle],
) -> dict[int, Trim]:
    """After a vehicle joined or left an orbit: new equal phases (2 pi / N apart, order
    kept) and each orbiter's speed trim; `Trim.target`/`move` are in radians. A trim
    stays within the vehicle's speed range on this orbit (`speed_range_on(radius_m)`:
    a fixed-wing never flies faster than the orbit's radius allows at its max bank)."""
    if not (math.isfinite(radius_m) and radius_m > 0.0):
        raise InvalidParameterError(f"orbit radius must be > 0, got {radius_m}")
    period = 2 * math.pi * radius_m
    trims = respace(
        {v: p * radius_m for v, p in phases_rad.items()},
        period,
        speed_m_s,
        speed_ranges_on(vehicles, phases_rad, radius_m),
    )
    return {
        v: Trim(v, t.target / radius_m, t.move / radius_m, t.speed_m_s, t.settle_s)
        for v, t in trims.items()
    }
