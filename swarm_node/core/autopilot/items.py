"""Autopilot-neutral mission steps. Planners output lists of `Waypoint`; the autopilot
link converts them into MAVLink mission items for the vehicle type (e.g. NAV_TAKEOFF or
NAV_VTOL_TAKEOFF, loiter radius sign conventions) and uploads them."""

from __future__ import annotations

from enum import IntEnum

import msgspec


class ItemKind(IntEnum):
    WAYPOINT = 1  # fly to (lat, lon, alt)
    LOITER_TURNS = 2  # circle `turns` times at `loiter_radius_m`
    LOITER_TIME = 3  # circle / hover for `hold_s`
    LOITER_UNLIMITED = 4  # circle / hover until told otherwise
    TAKEOFF = 5  # to alt_rel_m (VTOL: vertical take-off)
    LAND = 6  # at (lat, lon) (VTOL: vertical landing)
    RTL = 7  # return to launch
    CHANGE_SPEED = 8  # set speed_m_s from here on


class Waypoint(msgspec.Struct, frozen=True):
    """One step of a planned route, geodetic, altitude above home."""

    kind: ItemKind = ItemKind.WAYPOINT
    lat_deg: float = 0.0
    lon_deg: float = 0.0
    alt_rel_m: float = 0.0
    speed_m_s: float | None = None  # for CHANGE_SPEED, or a speed to hold from here
    loiter_radius_m: float | None = None  # > 0 clockwise, < 0 counter-clockwise
    turns: float = 0.0
    hold_s: float = 0.0
    acceptance_radius_m: float = 0.0  # 0: the autopilot's default
