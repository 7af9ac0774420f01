"""Autopilot-neutral steps -> ArduPilot mission, fence and rally items, per vehicle type.

Mission (MAV_MISSION_TYPE_MISSION): item 0 is home (ArduPilot overwrites it with its
own home), then one or more items per `Waypoint`:

| ItemKind         | COPTER                 | PLANE                       | VTOL             | ROVER / BOAT            |
|------------------|------------------------|-----------------------------|------------------|-------------------------|
| WAYPOINT         | NAV_WAYPOINT           | NAV_WAYPOINT                | NAV_WAYPOINT     | NAV_WAYPOINT            |
| LOITER_TURNS     | NAV_LOITER_TURNS       | NAV_LOITER_TURNS            | NAV_LOITER_TURNS | NAV_WAYPOINT (no orbit) |
| LOITER_TIME      | NAV_LOITER_TIME        | NAV_LOITER_TIME             | NAV_LOITER_TIME  | NAV_LOITER_TIME         |
| LOITER_UNLIMITED | NAV_LOITER_UNLIM       | NAV_LOITER_UNLIM            | NAV_LOITER_UNLIM | NAV_LOITER_UNLIM        |
| TAKEOFF          | NAV_TAKEOFF            | NAV_TAKEOFF (15 deg pitch)  | NAV_VTOL_TAKEOFF | (nothing)               |
| LAND             | NAV_LAND               | DO_LAND_START + NAV_LAND    | NAV_VTOL_LAND    | NAV_WAYPOINT            |
| RTL              | NAV_RETURN_TO_LAUNCH   | NAV_RETURN_TO_LAUNCH        | same             | same                    |
| CHANGE_SPEED     | DO_CHANGE_SPEED ground | DO_CHANGE_SPEED airspeed    | airspeed         | ground                  |

A waypoint's own `speed_m_s` becomes a DO_CHANGE_SPEED before it. Loiter radius sign is
kept (ArduPilot: negative = counter-clockwise). Altitudes are above home
(MAV_FRAME_GLOBAL_RELATIVE_ALT).

Fence (MAV_MISSION_TYPE_FENCE, ArduPilot 4.0+): each polygon vertex is one item whose
param1 is the vertex count; circles are one item with param1 = radius.
Rally (MAV_MISSION_TYPE_RALLY): NAV_RALLY_POINT items.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

from swarm_proto import GeoPoint, VehicleType

from .items import ItemKind, Waypoint
from .mission_item import MavCmd, MavFrame, MissionItem
from .requests import MissionKind, UploadFence, UploadRally

SPEED_TYPE_AIRSPEED = 0
SPEED_TYPE_GROUNDSPEED = 1
PLANE_TAKEOFF_PITCH_DEG = 15.0
_FIXED_WING = (VehicleType.PLANE, VehicleType.VTOL)
_GROUND = (VehicleType.ROVER, VehicleType.BOAT)
_SUPPORTED = (VehicleType.PLANE, VehicleType.VTOL, VehicleType.COPTER, *_GROUND)


class ConversionError(ValueError):
    """Our own misuse: a step or shape the autopilot cannot be given."""


def _check_point(lat: float, lon: float, what: str) -> None:
    if not (math.isfinite(lat) and math.isfinite(lon)):
        raise ConversionError(f"{what}: position is not finite")
    if not (-90.0 <= lat <= 90.0 and -180.0 <= lon <= 180.0):
        raise ConversionError(f"{what}: position ({lat}, {lon}) out of range")


def _check_finite(what: str, *values: float | None) -> None:
    for v in values:
        if v is not None and not math.isfinite(v):
            raise ConversionError(f"{what}: value {v} is not finite")


def mission_items(
    waypoints: Sequence[Waypoint], vehicle_type: VehicleType, home: GeoPoint | None = None
) -> list[MissionItem]:
    """The MAVLink mission for `waypoints` (item 0 = home), seq numbered from 0."""
    return list(mission_items_with_index(waypoints, vehicle_type, home)[0])


def mission_items_with_index(
    waypoints: Sequence[Waypoint], vehicle_type: VehicleType, home: GeoPoint | None = None
) -> tuple[list[MissionItem], list[int]]:
    """The mission and, for each waypoint, the seq of the item that completes it (the
    previous item's seq when a waypoint produces nothing, e.g. a rover's TAKEOFF)."""
    if vehicle_type not in _SUPPORTED:
        raise ConversionError(f"no ArduPilot mission for vehicle type {vehicle_type.name}")
    items: list[MissionItem] = []

    def add(command: int, frame: int = MavFrame.GLOBAL_RELATIVE_ALT, **kw: Any) -> None:
        floats: dict[str, Any] = {k: float(v) for k, v in kw.items()}
        items.append(MissionItem(len(items), command, frame, **floats))

    if home is not None:
        add(
            MavCmd.NAV_WAYPOINT,
            frame=MavFrame.GLOBAL,
            lat_deg=home.lat_deg,
            lon_deg=home.lon_deg,
            alt_m=home.alt_msl_m,
        )
    else:
        add(MavCmd.NAV_WAYPOINT, frame=MavFrame.GLOBAL)
    fixed_wing = vehicle_type in _FIXED_WING
    ground = vehicle_type in _GROUND
    speed_type = SPEED_TYPE_AIRSPEED if fixed_wing else SPEED_TYPE_GROUNDSPEED
    index: list[int] = []
    for n, wp in enumerate(waypoints):
        what = f"waypoint {n} ({wp.kind.name})"
        _check_finite(
            what,
            wp.alt_rel_m,
            wp.speed_m_s,
            wp.loiter_radius_m,
            wp.turns,
            wp.hold_s,
            wp.acceptance_radius_m,
        )
        pos: dict[str, Any] = {
            "lat_deg": wp.lat_deg,
            "lon_deg": wp.lon_deg,
            "alt_m": wp.alt_rel_m,
        }
        radius = wp.loiter_radius_m or 0.0
        if wp.kind not in (ItemKind.RTL, ItemKind.CHANGE_SPEED, ItemKind.TAKEOFF):
            _check_point(wp.lat_deg, wp.lon_deg, what)
        if wp.speed_m_s is not None:
            if wp.speed_m_s <= 0:
                raise ConversionError(f"{what}: speed must be positive")
            add(
                MavCmd.DO_CHANGE_SPEED,
                frame=MavFrame.MISSION,
                param1=speed_type,
                param2=wp.speed_m_s,
                param3=-1.0,
            )
        if wp.kind == ItemKind.CHANGE_SPEED:
            if wp.speed_m_s is None:
                raise ConversionError(f"{what}: CHANGE_SPEED needs speed_m_s")
        elif wp.kind == ItemKind.WAYPOINT or (wp.kind == ItemKind.LOITER_TURNS and ground):
            add(MavCmd.NAV_WAYPOINT, param1=wp.hold_s, param2=wp.acceptance_radius_m, **pos)
        elif wp.kind == ItemKind.LOITER_TURNS:
            if wp.turns <= 0:
                raise ConversionError(f"{what}: needs turns > 0")
            add(MavCmd.NAV_LOITER_TURNS, param1=wp.turns, param3=radius, **pos)
        elif wp.kind == ItemKind.LOITER_TIME:
            if wp.hold_s < 0:
                raise ConversionError(f"{what}: negative hold_s")
            add(MavCmd.NAV_LOITER_TIME, param1=wp.hold_s, param3=radius, **pos)
        elif wp.kind == ItemKind.LOITER_UNLIMITED:
            add(MavCmd.NAV_LOITER_UNLIM, param3=radius, **pos)
        elif wp.kind == ItemKind.TAKEOFF:
            if wp.alt_rel_m <= 0 and not ground:
                raise ConversionError(f"{what}: take-off altitude must be positive")
            if vehicle_type == VehicleType.VTOL:
                add(MavCmd.NAV_VTOL_TAKEOFF, alt_m=wp.alt_rel_m)
            elif vehicle_type == VehicleType.PLANE:
                add(MavCmd.NAV_TAKEOFF, param1=PLANE_TAKEOFF_PITCH_DEG, alt_m=wp.alt_rel_m)
            elif vehicle_type == VehicleType.COPTER:
                add(MavCmd.NAV_TAKEOFF, alt_m=wp.alt_rel_m)
        elif wp.kind == ItemKind.LAND:
            if vehicle_type == VehicleType.VTOL:
                add(MavCmd.NAV_VTOL_LAND, **{**pos, "alt_m": 0.0})
            elif vehicle_type == VehicleType.PLANE:
                add(MavCmd.DO_LAND_START, **pos)
                add(MavCmd.NAV_LAND, **{**pos, "alt_m": 0.0})
            elif vehicle_type == VehicleType.COPTER:
                add(MavCmd.NAV_LAND, **{**pos, "alt_m": 0.0})
            else:
                add(MavCmd.NAV_WAYPOINT, param2=wp.acceptance_radius_m, **pos)
        elif wp.kind == ItemKind.RTL:
            add(
                MavCmd.NAV_RETURN_TO_LAUNCH
            )  # frame 3 as Mission Planner: RTL is a location command
        else:  # pragma: no cover - every ItemKind is handled above
            raise ConversionError(f"{what}: unknown kind")
        index.append(len(items) - 1)
    return items, index


def fence_items(fence: UploadFence) -> list[MissionItem]:
    """ArduPilot fence items: inclusion polygons and circles, exclusion polygons and circles."""
    items: list[MissionItem] = []

    def polygon(points: Sequence[tuple[float, float]], command: int, what: str) -> None:
        pts = list(points)
        if len(pts) >= 2 and pts[0] == pts[-1]:
            pts = pts[:-1]  # ArduPilot wants an open ring
        if len(pts) < 3:
            raise ConversionError(f"{what} needs at least 3 vertices, got {len(pts)}")
        for lat, lon in pts:
            _check_point(lat, lon, what)
        problem = _polygon_problem(pts)
        if problem:
            raise ConversionError(f"{what}: {problem}")
        for lat, lon in pts:
            items.append(
                MissionItem(
                    seq=len(items),
                    command=command,
                    frame=MavFrame.GLOBAL,
                    param1=float(len(pts)),
                    lat_deg=lat,
                    lon_deg=lon,
                    mission_type=MissionKind.FENCE,
                )
            )

    def circle(lat: float, lon: float, radius: float, command: int, what: str) -> None:
        _check_point(lat, lon, what)
        if not (math.isfinite(radius) and radius > 0):
            raise ConversionError(f"{what}: radius must be positive")
        items.append(
            MissionItem(
                seq=len(items),
                command=command,
                frame=MavFrame.GLOBAL,
                param1=radius,
                lat_deg=lat,
                lon_deg=lon,
                mission_type=MissionKind.FENCE,
            )
        )

    for n, poly in enumerate(fence.inclusion_polygons):
        polygon(poly, MavCmd.NAV_FENCE_POLYGON_VERTEX_INCLUSION, f"inclusion polygon {n}")
    for n, (lat, lon, radius) in enumerate(fence.inclusion_circles):
        circle(lat, lon, radius, MavCmd.NAV_FENCE_CIRCLE_INCLUSION, f"inclusion circle {n}")
    for n, poly in enumerate(fence.exclusion_polygons):
        polygon(poly, MavCmd.NAV_FENCE_POLYGON_VERTEX_EXCLUSION, f"exclusion polygon {n}")
    for n, (lat, lon, radius) in enumerate(fence.exclusion_circles):
        circle(lat, lon, radius, MavCmd.NAV_FENCE_CIRCLE_EXCLUSION, f"exclusion circle {n}")
    return items


def _polygon_problem(pts: Sequence[tuple[float, float]]) -> str | None:
    from shapely.geometry import Polygon
    from shapely.validation import explain_validity

    poly = Polygon([(lon, lat) for lat, lon in pts])
    if not poly.is_valid:
        return f"not a simple polygon ({explain_validity(poly)})"
    if poly.area <= 0:
        return "zero area"
    return None


def rally_items(rally: UploadRally) -> list[MissionItem]:
    items: list[MissionItem] = []
    for n, (lat, lon, alt) in enumerate(rally.points):
        _check_point(lat, lon, f"rally point {n}")
        _check_finite(f"rally point {n}", alt)
        items.append(
            MissionItem(
                seq=n,
                command=MavCmd.NAV_RALLY_POINT,
                frame=MavFrame.GLOBAL_RELATIVE_ALT,
                lat_deg=lat,
                lon_deg=lon,
                alt_m=alt,
                mission_type=MissionKind.RALLY,
            )
        )
    return items
