"""What the cores ask of the autopilot. The autopilot link (swarm_node.runtime) executes
each request with COMMAND_ACK handling, timeout and retry, and answers with an
`ApResult` carrying the same `request_id`."""

from __future__ import annotations

from enum import IntEnum

import msgspec

from .items import Waypoint
from .mission_item import MissionItem


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
    enable: bool | None = None  # then MAV_CMD_DO_FENCE_ENABLE 1/0; None leaves it as is
    inclusion_circles: tuple[tuple[float, float, float], ...] = ()  # lat, lon, radius_m


class UploadRally(ApRequest, frozen=True):
    points: tuple[tuple[float, float, float], ...] = ()  # lat, lon, alt_rel_m


class Calibrate(ApRequest, frozen=True):
    what: str  # "gyro", "baro", "airspeed", "accel", "compass"


class UploadMissionItems(ApRequest, frozen=True):
    """Raw MAVLink items (already converted) for any mission type; seq is renumbered."""

    kind: MissionKind = MissionKind.MISSION
    items: tuple[MissionItem, ...] = ()


class DownloadMission(ApRequest, frozen=True):
    """Read the autopilot's mission, fence or rally items: ApResult.items."""

    kind: MissionKind = MissionKind.MISSION


class SetParam(ApRequest, frozen=True):
    """PARAM_SET, confirmed by the PARAM_VALUE echo."""

    name: str  # at most 16 characters, e.g. "TKOFF_ALT"
    value: float


class ReadParam(ApRequest, frozen=True):
    """PARAM_REQUEST_READ, answered by PARAM_VALUE: ApResult.value."""

    name: str  # at most 16 characters, e.g. "BATT_CAPACITY"


class RelayCommand(ApRequest, frozen=True):
    """MAVLink frames of a passthrough session's client (a ground station) that change
    what the vehicle does: written to the autopilot as they are, once the node's arbiter
    granted them (core/passthrough.py). The link answers at once: written (ok) or the
    link is down; the autopilot's own answer goes to the client."""

    data: bytes
    what: str = ""  # e.g. "SET_MODE LOITER", for logs and refusals


class RelaySetting(RelayCommand, frozen=True):
    """A passthrough frame that changes the vehicle without flying it (a parameter, a
    fence or rally upload, a calibration): never refused for precedence."""


class ApError(IntEnum):
    """Why a request failed, for code to branch on (ApResult.reason is for people)."""

    NONE = 0
    TIMEOUT = 1  # no answer after every attempt
    LINK_DOWN = 2  # no link to the autopilot when the request was due
    TEMPORARILY_REJECTED = 3  # MAV_RESULT_TEMPORARILY_REJECTED on the last attempt
    DENIED = 4  # MAV_RESULT_DENIED: invalid parameters
    UNSUPPORTED = 5  # MAV_RESULT_UNSUPPORTED
    FAILED = 6  # MAV_RESULT_FAILED (arming checks, wrong mode, ...)
    NO_POSITION = 7  # refused (MAV_RESULT_FAILED) while the EKF has no position yet
    CANCELLED = 8  # the link was closed, or the autopilot cancelled a transfer
    MISSION_ERROR = 9  # MISSION_ACK with an error (ApResult.reason names it)
    NOT_APPLICABLE = 10  # the vehicle type cannot do this (e.g. a rover's parachute)
    UNKNOWN_VEHICLE = 11  # vehicle type not configured and not known from a HEARTBEAT
    IN_PROGRESS = 12  # still MAV_RESULT_IN_PROGRESS when the time ran out
    NOT_STARTED = 13  # accepted, but the autopilot did not start the mission
    PREEMPTED = 14  # refused by the node's arbiter (a higher owner holds control), never sent
    MODE_NOT_CONFIRMED = 15  # a mode change accepted, but no HEARTBEAT showed the mode


class ApResult(msgspec.Struct, frozen=True):
    request_id: int
    ok: bool
    reason: str = ""  # e.g. "COMMAND_ACK DENIED", "timeout after 3 tries", "MISSION_ACK NO_SPACE"
    mav_result: int | None = None  # MAV_RESULT of the COMMAND_ACK, when there was one
    error: ApError = ApError.NONE
    items: tuple[MissionItem, ...] = ()  # DownloadMission: what the autopilot holds
    attempts: int = 0  # messages sent for the step that decided the result
    value: float | None = None  # ReadParam: the autopilot's value
