"""What the cores ask of the autopilot. The autopilot link (swarm_node.runtime) executes
each request with COMMAND_ACK handling, timeout and retry, and answers with an
`ApResult` carrying the same `request_id`."""

from __future__ import annotations

from enum import IntEnum

import msgspec

from .items import Waypoint


class MissionKind(IntEnum):
    """MAVLink MAV_MISSION_TYPE."""

    MISSION = 0
    FENCE = 1
    RALLY = 2


class ApRequest(msgspec.Struct, frozen=True, tag=True, kw_only=True):
    request_id: int = 0


class SetMode(ApRequest, frozen=True):
    mode: str  # ArduPilot mode name for the vehicle type, e.g. "GUIDED", "AUTO", "QLAND"


class Arm(ApRequest, frozen=True):
    force: bool = False


class Disarm(ApRequest, frozen=True):
    force: bool = False


class Takeoff(ApRequest, frozen=True):
    alt_rel_m: float


class Goto(ApRequest, frozen=True):
    lat_deg: float
    lon_deg: float
    alt_rel_m: float


class ChangeSpeed(ApRequest, frozen=True):
    speed_m_s: float
    airspeed: bool = True  # fixed-wing: airspeed; others: ground speed


class ChangeAltitude(ApRequest, frozen=True):
    alt_rel_m: float


class ReturnToLaunch(ApRequest, frozen=True):
    pass


class Land(ApRequest, frozen=True):
    pass


class Parachute(ApRequest, frozen=True):
    pass


class StartMission(ApRequest, frozen=True):
    first_item: int = 0


class UploadMission(ApRequest, frozen=True):
    items: tuple[Waypoint, ...] = ()


class UploadFence(ApRequest, frozen=True):
    """Inclusion/exclusion polygons and circles loaded as ArduPilot fence items (the
    backstop if the companion computer fails). Points are (lat_deg, lon_deg)."""

    exclusion_polygons: tuple[tuple[tuple[float, float], ...], ...] = ()
    exclusion_circles: tuple[tuple[float, float, float], ...] = ()  # lat, lon, radius_m
    inclusion_polygons: tuple[tuple[tuple[float, float], ...], ...] = ()


class UploadRally(ApRequest, frozen=True):
    points: tuple[tuple[float, float, float], ...] = ()  # lat, lon, alt_rel_m


class Calibrate(ApRequest, frozen=True):
    what: str  # "gyro", "baro", "airspeed", "accel", "compass"


class ApResult(msgspec.Struct, frozen=True):
    request_id: int
    ok: bool
    reason: str = ""  # e.g. "COMMAND_ACK DENIED", "timeout after 3 tries", "MISSION_ACK NO_SPACE"
    mav_result: int | None = None  # MAV_RESULT of the COMMAND_ACK, when there was one
