"""What the autopilot link reports as it happens (besides the `AutopilotState` snapshot):
link lost and restored, the autopilot found or rebooted, mode and arming changes,
STATUSTEXT, mission progress, home, EKF and landed-state changes.

`time_s` is the link clock's time when the event was noticed (simulated time in a
simulation). Events are msgspec Structs tagged by class name, so a node can log or
forward them as they are.
"""

from __future__ import annotations

import msgspec

from swarm_proto import GeoPoint, VehicleType


class ApEvent(msgspec.Struct, frozen=True, tag=True, kw_only=True):
    time_s: float


class LinkLost(ApEvent, frozen=True):
    """No valid message from the autopilot for `silent_s` (the link timeout)."""

    silent_s: float


class LinkRestored(ApEvent, frozen=True):
    """Valid messages flow again after a LinkLost; `down_s` since the last message (on
    the node's clock), `autopilot_gap_s` as the autopilot's own time since boot shows
    it (-1: no timed message yet): a short autopilot gap with a long `down_s` was the
    node reading late, not the link."""

    down_s: float
    autopilot_gap_s: float = -1.0


class AutopilotFound(ApEvent, frozen=True):
    """The first HEARTBEAT of the autopilot the link follows."""

    sysid: int
    compid: int
    mav_type: int
    vehicle_type: VehicleType  # configured, else from mav_type


class AutopilotRebooted(ApEvent, frozen=True):
    """Its time since boot went backwards: streams are requested again."""

    boot_time_ms: int


class HostStalled(ApEvent, frozen=True):
    """The node read the link `stall_s` late: the autopilot's messages carry times
    since boot spread over a gap the node saw as silence (its own stall, not the
    link's), or the link's timer ran that late."""

    stall_s: float


class ModeChanged(ApEvent, frozen=True):
    old_mode: str  # "" before the first HEARTBEAT
    mode: str
    mode_number: int


class ArmedChanged(ApEvent, frozen=True):
    armed: bool


class StatusText(ApEvent, frozen=True):
    """STATUSTEXT (chunked texts joined). severity is MAV_SEVERITY: 0 emergency .. 7 debug."""

    severity: int
    text: str


class MissionItemReached(ApEvent, frozen=True):
    seq: int


class MissionCurrentChanged(ApEvent, frozen=True):
    seq: int


class HomeChanged(ApEvent, frozen=True):
    home: GeoPoint


class EkfChanged(ApEvent, frozen=True):
    """EKF_STATUS_REPORT: whether attitude, velocity and absolute position are good."""

    ok: bool
    flags: int


class LandedChanged(ApEvent, frozen=True):
    """EXTENDED_SYS_STATE landed_state (only when the autopilot sends it)."""

    landed: bool


EVENT_TYPES: tuple[type[ApEvent], ...] = (
    LinkLost,
    LinkRestored,
    AutopilotFound,
    AutopilotRebooted,
    HostStalled,
    ModeChanged,
    ArmedChanged,
    StatusText,
    MissionItemReached,
    MissionCurrentChanged,
    HomeChanged,
    EkfChanged,
    LandedChanged,
)
