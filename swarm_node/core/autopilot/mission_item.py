"""One MAVLink mission item as plain data: the fields of MISSION_ITEM_INT, with lat/lon
as degrees. What the mission protocol uploads and downloads for the mission, fence and
rally types. `items.Waypoint` is the autopilot-neutral step planners produce; the
conversion per vehicle type lives in `conversion`."""

from __future__ import annotations

import math
from enum import IntEnum

import msgspec


class MavCmd(IntEnum):
    """The MAV_CMD values the autopilot link uses (common.xml)."""

    NAV_WAYPOINT = 16
    NAV_LOITER_UNLIM = 17
    NAV_LOITER_TURNS = 18
    NAV_LOITER_TIME = 19
    NAV_RETURN_TO_LAUNCH = 20
    NAV_LAND = 21
    NAV_TAKEOFF = 22
    NAV_VTOL_TAKEOFF = 84
    NAV_VTOL_LAND = 85
    DO_SET_MODE = 176
    DO_CHANGE_SPEED = 178
    DO_LAND_START = 189
    DO_REPOSITION = 192
    DO_CHANGE_ALTITUDE = 186
    DO_FENCE_ENABLE = 207
    DO_PARACHUTE = 208
    DO_SET_MISSION_CURRENT = 224
    PREFLIGHT_CALIBRATION = 241
    MISSION_START = 300
    COMPONENT_ARM_DISARM = 400
    SET_MESSAGE_INTERVAL = 511
    REQUEST_MESSAGE = 512
    NAV_FENCE_RETURN_POINT = 5000
    NAV_FENCE_POLYGON_VERTEX_INCLUSION = 5001
    NAV_FENCE_POLYGON_VERTEX_EXCLUSION = 5002
    NAV_FENCE_CIRCLE_INCLUSION = 5003
    NAV_FENCE_CIRCLE_EXCLUSION = 5004
    NAV_RALLY_POINT = 5100
    DO_START_MAG_CAL = 42424


class MavFrame(IntEnum):
    GLOBAL = 0  # altitude above mean sea level
    MISSION = 2  # not a position
    GLOBAL_RELATIVE_ALT = 3  # altitude above home


#: MAV_FRAME values whose x/y are latitude/longitude
GLOBAL_FRAMES = frozenset({0, 3, 5, 6, 10, 11})


class MissionItem(msgspec.Struct, frozen=True):
    """A MISSION_ITEM_INT without its addressing. x/y are degrees here (1e7 on the wire);
    `mission_type` is MAV_MISSION_TYPE (0 mission, 1 fence, 2 rally)."""

    seq: int
    command: int
    frame: int = MavFrame.GLOBAL_RELATIVE_ALT
    param1: float = 0.0
    param2: float = 0.0
    param3: float = 0.0
    param4: float = 0.0
    lat_deg: float = 0.0
    lon_deg: float = 0.0
    alt_m: float = 0.0
    current: int = 0
    autocontinue: int = 1
    mission_type: int = 0

    def problem(self) -> str | None:
        """Why this item cannot be sent or was received corrupt, or None."""
        if not 0 <= self.seq <= 65535:
            return f"seq {self.seq} out of range"
        if not 0 <= self.command <= 65535:
            return f"command {self.command} out of range"
        if not 0 <= self.frame <= 255:
            return f"frame {self.frame} out of range"
        if not all(math.isfinite(v) for v in (self.lat_deg, self.lon_deg, self.alt_m)):
            return "position is not finite"
        if self.frame in GLOBAL_FRAMES and not (
            -90.0 <= self.lat_deg <= 90.0 and -180.0 <= self.lon_deg <= 180.0
        ):
            return f"position ({self.lat_deg}, {self.lon_deg}) out of range"
        if not (abs(self.lat_deg) < 214.0 and abs(self.lon_deg) < 214.0):
            return "x/y do not fit int32 at 1e7"
        return None

    def same_as(self, other: MissionItem, tolerance_deg: float = 1.5e-7) -> bool:
        """Equal as the autopilot stores it (lat/lon to 1e-7 degrees, floats as float32,
        NaN equal to NaN); the sequence number and `current` flag are not compared."""

        def close(a: float, b: float, tol: float) -> bool:
            if math.isnan(a) or math.isnan(b):
                return math.isnan(a) and math.isnan(b)
            return abs(a - b) <= tol * max(1.0, abs(a), abs(b))

        return (
            self.command == other.command
            and self.frame == other.frame
            and self.mission_type == other.mission_type
            and self.autocontinue == other.autocontinue
            and all(
                close(a, b, 1e-6)
                for a, b in (
                    (self.param1, other.param1),
                    (self.param2, other.param2),
                    (self.param3, other.param3),
                    (self.param4, other.param4),
                    (self.alt_m, other.alt_m),
                )
            )
            and abs(self.lat_deg - other.lat_deg) <= tolerance_deg
            and abs(self.lon_deg - other.lon_deg) <= tolerance_deg
        )
