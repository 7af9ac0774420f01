"""Telemetry stream scheduling: per-message intervals set by SET_MESSAGE_INTERVAL or by
REQUEST_DATA_STREAM (ArduPilot's stream groups), with defaults for a client that asks
for nothing. Pure: the caller passes `now` and asks what is due."""

from __future__ import annotations

import math

# message ids
HEARTBEAT = 0
SYS_STATUS = 1
SYSTEM_TIME = 2
GPS_RAW_INT = 24
ATTITUDE = 30
GLOBAL_POSITION_INT = 33
MISSION_CURRENT = 42
NAV_CONTROLLER_OUTPUT = 62
VFR_HUD = 74
TIMESYNC = 111
BATTERY_STATUS = 147
EKF_STATUS_REPORT = 193
HOME_POSITION = 242
EXTENDED_SYS_STATE = 245
GPS_GLOBAL_ORIGIN = 49
WIND = 168
FENCE_STATUS = 162

# What the simulator can stream.
STREAMABLE: frozenset[int] = frozenset(
    {
        HEARTBEAT,
        SYS_STATUS,
        SYSTEM_TIME,
        GPS_RAW_INT,
        ATTITUDE,
        GLOBAL_POSITION_INT,
        MISSION_CURRENT,
        NAV_CONTROLLER_OUTPUT,
        VFR_HUD,
        BATTERY_STATUS,
        EKF_STATUS_REPORT,
        HOME_POSITION,
        EXTENDED_SYS_STATE,
        GPS_GLOBAL_ORIGIN,
        WIND,
        TIMESYNC,
        FENCE_STATUS,
    }
)

# Intervals (s) before anyone asks. ArduPilot's defaults come from the SRn_ parameters
# (all 0 on a copter's SERIAL0); the simulator streams the core telemetry at modest rates
# so that a plain pymavlink client sees positions at once. HEARTBEAT is always 1 Hz.
DEFAULT_INTERVALS_S: dict[int, float] = {
    HEARTBEAT: 1.0,
    GLOBAL_POSITION_INT: 0.25,
    ATTITUDE: 0.25,
    VFR_HUD: 0.25,
    GPS_RAW_INT: 0.5,
    SYS_STATUS: 1.0,
    BATTERY_STATUS: 1.0,
    SYSTEM_TIME: 1.0,
    MISSION_CURRENT: 1.0,
    EKF_STATUS_REPORT: 1.0,
    EXTENDED_SYS_STATE: 1.0,
    FENCE_STATUS: 1.0,  # only while the fence is enabled, as ArduPilot
    TIMESYNC: 10.0,
}

# MAV_DATA_STREAM -> message ids (ArduPilot's GCS_MAVLINK stream groups, the subset the
# simulator produces)
STREAM_GROUPS: dict[int, tuple[int, ...]] = {
    1: (),  # RAW_SENSORS
    2: (
        SYS_STATUS,
        MISSION_CURRENT,
        GPS_RAW_INT,
        NAV_CONTROLLER_OUTPUT,
        EXTENDED_SYS_STATE,
        FENCE_STATUS,
    ),
    3: (),  # RC_CHANNELS
    4: (),  # RAW_CONTROLLER
    6: (GLOBAL_POSITION_INT,),  # POSITION
    10: (ATTITUDE,),  # EXTRA1
    11: (VFR_HUD,),  # EXTRA2
    12: (SYSTEM_TIME, BATTERY_STATUS, EKF_STATUS_REPORT, WIND),  # EXTRA3
}
MAV_DATA_STREAM_ALL = 0
MIN_INTERVAL_S = 0.02  # 50 Hz cap


class StreamScheduler:
    """Per-message intervals (seconds, sim time) and when each is next due."""

    def __init__(self, now: float, defaults: dict[int, float] | None = None) -> None:
        self.defaults = dict(DEFAULT_INTERVALS_S if defaults is None else defaults)
        self.intervals: dict[int, float] = dict(self.defaults)
        self._due: dict[int, float] = {mid: now for mid in self.intervals}
        self._next: float | None = now if self._due else None

    def set_interval(self, msg_id: int, interval_s: float | None, now: float) -> bool:
        """`interval_s`: None = the default, <= 0 or inf = off. False if `msg_id` cannot be
        streamed."""
        if msg_id not in STREAMABLE:
            return False
        if interval_s is None:
            interval_s = self.defaults.get(msg_id, 0.0)
        if interval_s <= 0 or not math.isfinite(interval_s):
            self.intervals.pop(msg_id, None)
            self._due.pop(msg_id, None)
            self._next = min(self._due.values()) if self._due else None
            return True
        interval_s = max(MIN_INTERVAL_S, interval_s)
        self.intervals[msg_id] = interval_s
        self._due[msg_id] = min(self._due.get(msg_id, now + interval_s), now + interval_s)
        self._next = min(self._due.values())
        return True

    def interval(self, msg_id: int) -> float:
        """Seconds, or 0 when off."""
        return self.intervals.get(msg_id, 0.0)

    def request_data_stream(self, stream_id: int, rate_hz: int, start: bool, now: float) -> None:
        groups = STREAM_GROUPS.keys() if stream_id == MAV_DATA_STREAM_ALL else (stream_id,)
        for group in groups:
            for mid in STREAM_GROUPS.get(group, ()):
                if start and rate_hz > 0:
                    self.set_interval(mid, 1.0 / rate_hz, now)
                else:
                    self.set_interval(mid, 0.0, now)

    def due(self, now: float) -> list[int]:
        """Message ids due at `now`; each is rescheduled one interval later (skipping
        missed slots rather than bursting)."""
        limit = now + 1e-9
        if self._next is None or self._next > limit:
            return []
        out = []
        due, intervals = self._due, self.intervals
        first = math.inf  # the next due time, found in the same pass
        for mid, t in due.items():
            if t <= limit:
                out.append(mid)
                t += intervals[mid]
                if t <= now:
                    t = now + intervals[mid]
                due[mid] = t
            if t < first:
                first = t
        self._next = first if due else None
        return out

    def next_deadline(self) -> float | None:
        return self._next
