"""Autoland ("swarm airport operations"): several vehicles land at one base, one after
the other, separated in time (`separation_s`) and, while they wait, in altitude (a
holding stack: each vehicle holds at its own level over a holding fix upwind of the
base, then flies the final approach along `heading_deg` and lands).

Order: a given priority first (e.g. lowest battery), then earliest possible landing.
Each vehicle's landing slot is the later of its earliest landing and the previous slot
plus the separation; it holds for the difference.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping
from dataclasses import dataclass

from shapely.geometry import Point
from shapely.ops import nearest_points

from swarm_node.core.autopilot.items import ItemKind, Waypoint
from swarm_proto import GeometryKind, VehicleType

from .context import PlanContext
from .endurance import LAND_FINAL_M, LAND_FINAL_M_S, VTOL_SINK_M_S
from .errors import InvalidGeometryError, InvalidParameterError, TargetInZoneError
from .geo import LocalFrame, heading_to_yaw
from .vehicles import PlanVehicle, VehiclePlan, require_vehicles
from .zones import XYZ, Track, ZoneSet, circle_points

DEFAULT_SEPARATION_S = 60.0
DEFAULT_STACK_STEP_M = 15.0
FINAL_APPROACH_M = 600.0  # holding fix / final approach start, from the base
FINAL_ALT_M = 40.0  # altitude at the start of the final approach
DEFAULT_SINK_M_S = 2.0
VTOL_BACK_TRANSITION_S = 13.0  # cruise to hover over the pad (Q_TRANS_DECEL 2 m/s/s from 26 m/s)


@dataclass(frozen=True, slots=True)
class LandingSlot:
    vehicle_id: int
    sequence: int  # 0 lands first
    hold_alt_rel_m: float
    hold_s: float
    land_at_s: float  # from now


@dataclass(frozen=True, slots=True)
class AutolandPlan:
    frame: LocalFrame
    base: tuple[float, float]
    approach_yaw_rad: float  # direction of the final approach (towards the base)
    slots: tuple[LandingSlot, ...]  # in landing order
    vehicles: tuple[VehiclePlan, ...]
    tracks: tuple[Track, ...] = ()  # every path flown, densely sampled (zone checks)


def _hold_radius(v: PlanVehicle, speed: float) -> float:
    """Radius of a vehicle's holding orbit: a fixed-wing's turn radius at its speed
    (never below its loiter radius); 0 for vehicles that hover."""
    return v.profile.turn_radius_m(speed) if v.profile.is_fixed_wing else 0.0


def _courses(heading_deg: float | None) -> list[float]:
    """Final approach courses (yaw) to try: the requested one only; by default north
    first, then every 15 degrees either side of it."""
    if heading_deg is not None:
        return [heading_to_yaw(heading_deg)]
    return [heading_to_yaw(d) for k in range(13) for d in sorted({15.0 * k, -15.0 * k})]


def _course_problem(
    zs: ZoneSet,
    base: tuple[float, float],
    yaw: float,
    hold_r: float,
    top_alt: float,
) -> str | None:
    """Why a final approach course does not work (None: it does): the holding fix, the
    holding stack's widest orbit (from the final altitude up to the top of the stack)
    and the final leg to the base must all be clear of the zones."""
    fix = (base[0] - FINAL_APPROACH_M * math.cos(yaw), base[1] - FINAL_APPROACH_M * math.sin(yaw))
    z = zs.zone_containing(*fix, FINAL_ALT_M)
    if z is not None:
        return f"the final approach starts inside no-fly zone {z.zone_id}"
    stack = circle_points(*fix, hold_r) if hold_r > 0 else (fix,)
    z = zs.entered(stack, FINAL_ALT_M, max(top_alt, FINAL_ALT_M))
    if z is not None:
        return f"the holding stack over the fix enters no-fly zone {z.zone_id}"
    z = zs.entered((fix, base), 0.0, FINAL_ALT_M)
    if z is not None:
        return f"the final approach crosses no-fly zone {z.zone_id}"
    return None


def plan_autoland(
    ctx: PlanContext,
    *,
    priority: Mapping[int, float] | None = None,
    max_alt_rel_m: float = 120.0,
    hold_until_released: bool = False,
    pad_spacing_m: float = 0.0,
) -> AutolandPlan:
    """`priority`: higher lands first (e.g. 100 - battery %); ties by earliest arrival.

    `hold_until_released`: every vehicle's hold over the fix is a LOITER_UNLIMITED (the
    mission manager releases it in turn: mission/landing.py) instead of a LOITER_TIME
    of the planned length. `pad_spacing_m`: each vehicle lands on its own pad, the pads
    in a row across the final approach through the base, this far apart in landing
    order (0: all at the base).

    Zones: the final approach course is `heading_deg`, or by default the first of north,
    15, -15, 30, ... degrees whose holding fix, holding stack (each fixed-wing orbit at
    its turn radius) and final leg are clear (else `TargetInZoneError`); each vehicle's
    transit to the fix climbs over or goes around zones (`ZoneSet.avoid`, up to
    `max_alt_rel_m`; a vehicle inside a zone first leaves it by the nearest way)."""
    geometry, vehicles, params = ctx.geometry, ctx.vehicles, ctx.params
    require_vehicles(vehicles)
    if geometry.kind != GeometryKind.POINT:
        raise InvalidGeometryError(f"a landing base is a POINT, got {geometry.kind.name}")
    sep = params.separation_s or DEFAULT_SEPARATION_S
    step = params.altitude_step_m or DEFAULT_STACK_STEP_M
    if sep <= 0 or step <= 0:
        raise InvalidParameterError("landing separation and altitude step must be > 0")
    frame = ctx.local_frame()
    base = frame.to_local(geometry.points[0].lat_deg, geometry.points[0].lon_deg)
    zs = ctx.zone_set(frame)
    if zs.zone_containing(*base, 0.0) is not None:
        raise TargetInZoneError("the landing base is inside a no-fly zone")
    speeds = {v.vehicle_id: v.speed(params) for v in vehicles}
    hold_r = max(_hold_radius(v, speeds[v.vehicle_id]) for v in vehicles)
    top_alt = params.altitude_rel_m + (len(vehicles) - 1) * step
    problems = []
    for yaw in _courses(params.heading_deg):
        problem = _course_problem(zs, base, yaw, hold_r, top_alt)
        if problem is None:
            break
        problems.append(problem)
    else:
        hint = ": change heading_deg" if params.heading_deg is not None else ""
        raise TargetInZoneError(f"{problems[0]}{hint}")
    fix = (base[0] - FINAL_APPROACH_M * math.cos(yaw), base[1] - FINAL_APPROACH_M * math.sin(yaw))
    prio = priority or {}
    transits = {
        v.vehicle_id: _transit(v, fix, params.altitude_rel_m, zs, frame, max_alt_rel_m)
        for v in vehicles
    }

    def reach_s(v: PlanVehicle) -> float:
        pts = transits[v.vehicle_id]
        return (
            sum(math.dist(a[:2], b[:2]) for a, b in itertools.pairwise(pts)) / speeds[v.vehicle_id]
        )

    def final_s(v: PlanVehicle) -> float:
        return final_approach_s(v, speeds[v.vehicle_id])

    seq = sorted(
        vehicles,
        key=lambda v: (-prio.get(v.vehicle_id, 0.0), reach_s(v) + final_s(v), v.vehicle_id),
    )
    slots: list[LandingSlot] = []
    plans: list[VehiclePlan] = []
    tracks: list[Track] = []
    last = -math.inf
    lat_b, lon_b = frame.to_geodetic(*base)
    lat_f, lon_f = frame.to_geodetic(*fix)
    for i, v in enumerate(seq):
        if pad_spacing_m > 0.0:  # its own pad across the final approach
            off = (i - (len(seq) - 1) / 2.0) * pad_spacing_m
            pad = (base[0] - off * math.sin(yaw), base[1] + off * math.cos(yaw))
            lat_b, lon_b = frame.to_geodetic(*pad)
        earliest = reach_s(v) + final_s(v)
        land = max(earliest, last + sep)
        last = land
        hold = land - earliest
        alt = params.altitude_rel_m + i * step
        slots.append(LandingSlot(v.vehicle_id, i, alt, hold, land))
        speed = speeds[v.vehicle_id]
        r = _hold_radius(v, speed)
        wps = [Waypoint(ItemKind.CHANGE_SPEED, speed_m_s=speed)]
        # the transit (planned at the bottom of the stack) flown at this vehicle's level
        transit = _transit(v, fix, alt, zs, frame, max_alt_rel_m)
        for a, b in itertools.pairwise(transit):
            kind = "exit" if a is transit[0] and zs.zone_containing(*a[:2], a[2]) else "transit"
            tracks.append(
                Track(v.vehicle_id, kind, (a[:2], b[:2]), min(a[2], b[2]), max(a[2], b[2]))
            )
        for x, y, z in transit[1:-1]:
            la, lo = frame.to_geodetic(x, y)
            wps.append(Waypoint(ItemKind.WAYPOINT, la, lo, z))
        wps.append(Waypoint(ItemKind.WAYPOINT, lat_f, lon_f, alt))
        if hold_until_released:
            wps.append(
                Waypoint(
                    ItemKind.LOITER_UNLIMITED,
                    lat_f,
                    lon_f,
                    alt,
                    loiter_radius_m=-r if r > 0 else None,
                )
            )
        elif hold > 0.0:
            wps.append(
                Waypoint(
                    ItemKind.LOITER_TIME,
                    lat_f,
                    lon_f,
                    alt,
                    hold_s=hold,
                    loiter_radius_m=-r if r > 0 else None,
                )
            )
        # hold (and descend) over the fix down to the final altitude, then the final leg
        stack = circle_points(*fix, r) if r > 0 else (fix,)
        tracks.append(Track(v.vehicle_id, "hold", stack, FINAL_ALT_M, max(alt, FINAL_ALT_M)))
        tracks.append(Track(v.vehicle_id, "final", (fix, base), 0.0, FINAL_ALT_M))
        wps.append(Waypoint(ItemKind.WAYPOINT, lat_f, lon_f, FINAL_ALT_M))
        wps.append(Waypoint(ItemKind.LAND, lat_b, lon_b, 0.0))
        length = sum(math.dist(a[:2], b[:2]) for a, b in itertools.pairwise(transit))
        plans.append(VehiclePlan(v.vehicle_id, tuple(wps), length + FINAL_APPROACH_M, land))
    return AutolandPlan(frame, base, yaw, tuple(slots), tuple(plans), tuple(tracks))


def final_approach_s(v: PlanVehicle, speed_m_s: float, from_alt_m: float = FINAL_ALT_M) -> float:
    """From leaving the holding fix at `from_alt_m` to touching down: the final leg at
    `speed_m_s`, then a plane glides down from FINAL_ALT_M at its sink rate; a VTOL
    slows down over the pad (VTOL_BACK_TRANSITION_S) and, like a multirotor, comes down
    vertically from its holding level at its sink rate and the last LAND_FINAL_M at
    LAND_FINAL_M_S (ArduPilot's LAND_SPEED)."""
    p = v.profile
    leg = FINAL_APPROACH_M / speed_m_s
    if p.vehicle_type not in (VehicleType.VTOL, VehicleType.COPTER):
        return leg + FINAL_ALT_M / (p.sink_rate_m_s or DEFAULT_SINK_M_S)
    vtol = p.vehicle_type == VehicleType.VTOL
    sink = VTOL_SINK_M_S if vtol else (p.sink_rate_m_s or VTOL_SINK_M_S)
    alt = max(from_alt_m, LAND_FINAL_M)
    down = (alt - LAND_FINAL_M) / sink + LAND_FINAL_M / LAND_FINAL_M_S
    return leg + (VTOL_BACK_TRANSITION_S if vtol else 0.0) + down


def _transit(
    v: PlanVehicle,
    fix: tuple[float, float],
    alt: float,
    zs: ZoneSet,
    frame: LocalFrame,
    max_alt_rel_m: float,
) -> list[XYZ]:
    """From where the vehicle is (its altitude) to the fix at `alt`, over or around the
    zones. A vehicle inside a zone first leaves it at the nearest point outside."""
    if v.pose is None:
        return [(*fix, alt), (*fix, alt)]
    x, y = frame.to_local(v.pose.lat_deg, v.pose.lon_deg)
    start: XYZ = (x, y, v.pose.alt_rel_m)
    out: list[XYZ] = [start]
    if zs.zone_containing(x, y, start[2]) is not None:
        keep = zs.keep_out(start[2], 1.0)
        edge = keep.exterior if hasattr(keep, "exterior") else keep.boundary
        q = nearest_points(edge, Point(x, y))[0]
        start = (float(q.x), float(q.y), start[2])
        out.append(start)
    if not zs.zones:
        return [*out, (*fix, alt)]
    return [*out, *zs.avoid([start, (*fix, alt)], max_alt_rel_m=max_alt_rel_m)[1:]]
