"""Autoland ("swarm airport operations"): several vehicles land at one base, one after
the other, separated in time (`separation_s`) and, while they wait, in altitude (a
holding stack: each vehicle holds at its own level over a holding fix upwind of the
base, then flies the final approach along `heading_deg` and lands).

Order: a given priority first (e.g. lowest battery), then earliest possible landing.
Each vehicle's landing slot is the later of its earliest landing and the previous slot
plus the separation; it holds for the difference.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

from swarm_node.core.autopilot.items import ItemKind, Waypoint
from swarm_proto import Geometry, GeometryKind, MissionParams, NoFlyZone

from .errors import InvalidGeometryError, InvalidParameterError, TargetInZoneError
from .geo import LocalFrame, heading_to_yaw
from .vehicles import DEFAULT_PARAMS, PlanVehicle, VehiclePlan, require_vehicles
from .zones import ZoneSet

DEFAULT_SEPARATION_S = 60.0
DEFAULT_STACK_STEP_M = 15.0
FINAL_APPROACH_M = 600.0  # holding fix / final approach start, from the base
FINAL_ALT_M = 40.0  # altitude at the start of the final approach
DEFAULT_SINK_M_S = 2.0


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


def plan_autoland(
    geometry: Geometry,
    vehicles: Sequence[PlanVehicle],
    params: MissionParams = DEFAULT_PARAMS,
    *,
    priority: Mapping[int, float] | None = None,
    zones: Sequence[NoFlyZone] = (),
    now_unix_s: float = 0.0,
    home_alt_msl_m: float = 0.0,
    frame: LocalFrame | None = None,
) -> AutolandPlan:
    """`priority`: higher lands first (e.g. 100 - battery %); ties by earliest arrival."""
    require_vehicles(vehicles)
    if geometry.kind != GeometryKind.POINT:
        raise InvalidGeometryError(f"a landing base is a POINT, got {geometry.kind.name}")
    sep = params.separation_s or DEFAULT_SEPARATION_S
    step = params.altitude_step_m or DEFAULT_STACK_STEP_M
    if sep <= 0 or step <= 0:
        raise InvalidParameterError("landing separation and altitude step must be > 0")
    frame = frame or LocalFrame.for_geometry(geometry)
    base = frame.to_local(geometry.points[0].lat_deg, geometry.points[0].lon_deg)
    zs = ZoneSet.from_messages(zones, frame, now_unix_s=now_unix_s, home_alt_msl_m=home_alt_msl_m)
    if zs.zone_containing(*base, 0.0) is not None:
        raise TargetInZoneError("the landing base is inside a no-fly zone")
    yaw = heading_to_yaw(params.heading_deg) if params.heading_deg is not None else math.pi / 2
    fix = (base[0] - FINAL_APPROACH_M * math.cos(yaw), base[1] - FINAL_APPROACH_M * math.sin(yaw))
    if zs.zone_containing(*fix, FINAL_ALT_M) is not None:
        raise TargetInZoneError(
            "the final approach starts inside a no-fly zone: change heading_deg"
        )
    prio = priority or {}

    def reach_s(v: PlanVehicle) -> float:
        if v.pose is None:
            return 0.0
        x, y = frame.to_local(v.pose.lat_deg, v.pose.lon_deg)
        return math.dist((x, y), fix) / v.speed(params)

    def final_s(v: PlanVehicle) -> float:
        sink = v.profile.sink_rate_m_s or DEFAULT_SINK_M_S
        return FINAL_APPROACH_M / v.speed(params) + FINAL_ALT_M / sink

    seq = sorted(
        vehicles,
        key=lambda v: (-prio.get(v.vehicle_id, 0.0), reach_s(v) + final_s(v), v.vehicle_id),
    )
    slots: list[LandingSlot] = []
    plans: list[VehiclePlan] = []
    last = -math.inf
    lat_b, lon_b = frame.to_geodetic(*base)
    lat_f, lon_f = frame.to_geodetic(*fix)
    for i, v in enumerate(seq):
        earliest = reach_s(v) + final_s(v)
        land = max(earliest, last + sep)
        last = land
        hold = land - earliest
        alt = params.altitude_rel_m + i * step
        slots.append(LandingSlot(v.vehicle_id, i, alt, hold, land))
        speed = v.speed(params)
        wps = [
            Waypoint(ItemKind.CHANGE_SPEED, speed_m_s=speed),
            Waypoint(ItemKind.WAYPOINT, lat_f, lon_f, alt),
        ]
        if hold > 0.0:
            wps.append(
                Waypoint(
                    ItemKind.LOITER_TIME,
                    lat_f,
                    lon_f,
                    alt,
                    hold_s=hold,
                    loiter_radius_m=-v.profile.loiter_radius_m or None,
                )
            )
        # leave the stack on the approach course, descending to the final altitude
        wps.append(Waypoint(ItemKind.WAYPOINT, lat_f, lon_f, FINAL_ALT_M))
        wps.append(Waypoint(ItemKind.LAND, lat_b, lon_b, 0.0))
        plans.append(VehiclePlan(v.vehicle_id, tuple(wps), 0.0, land))
    return AutolandPlan(frame, base, yaw, tuple(slots), tuple(plans))
