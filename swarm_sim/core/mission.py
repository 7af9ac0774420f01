"""Mission, fence and rally storage and the MAVLink mission protocol, as ArduPilot runs it
(libraries/GCS_MAVLink/MissionItemProtocol*.cpp):

- Upload: MISSION_COUNT -> the vehicle asks for each item with MISSION_REQUEST (not
  _INT: that is what the recorded ArduPilot sent) -> MISSION_ITEM_INT or MISSION_ITEM ->
  MISSION_ACK. An item out of sequence gets MISSION_ACK INVALID_SEQUENCE and the
  transfer goes on; a bad item ends it with the error; a request unanswered for 1 s is
  sent again; 8 s without an item cancels the upload (OPERATION_CANCELLED). Another
  sender's MISSION_COUNT while receiving is DENIED. Mission and rally items are written
  as they arrive (a cancelled mission upload leaves a truncated mission, as in
  ArduPilot); fence items are committed only when complete.
- Download: MISSION_REQUEST_LIST -> MISSION_COUNT; MISSION_REQUEST_INT -> MISSION_ITEM_INT
  and MISSION_REQUEST -> MISSION_ITEM (with ArduPilot's one-off warning). Mission item 0
  is always the current home.
- MISSION_CLEAR_ALL, MISSION_WRITE_PARTIAL_LIST.

Pure: messages in, messages out, time passed in.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from .firmware import MISSION_CMD_NAMES, SEV_INFO, SEV_WARNING

MISSION, FENCE, RALLY, ALL_TYPES = 0, 1, 2, 255
TYPE_NAMES = {MISSION: "mission", FENCE: "fence", RALLY: "rally"}

# MAV_MISSION_RESULT
ACCEPTED, ERROR, UNSUPPORTED_FRAME, UNSUPPORTED, NO_SPACE = 0, 1, 2, 3, 4
INVALID_PARAM5_X, INVALID_PARAM6_Y = 10, 11
INVALID_SEQUENCE, DENIED, OPERATION_CANCELLED = 13, 14, 15

UPLOAD_TIMEOUT_S = 8.0  # MissionItemProtocol::upload_timeout_ms
REQUEST_RESEND_S = 1.0  # wp_recv_timeout_ms (plus the stream slow-down, 0 here)

MAX_ITEMS = {MISSION: 724, FENCE: 84, RALLY: 100}
MAX_ALT_M = 50_000.0

# MAV_FRAME values that carry a global position, and their altitude reference
FRAME_ABSOLUTE = {0, 5}  # GLOBAL, GLOBAL_INT
FRAME_RELATIVE = {3, 6}  # GLOBAL_RELATIVE_ALT(_INT)
FRAME_TERRAIN = {10, 11}  # GLOBAL_TERRAIN_ALT(_INT); flat terrain: same as relative
GLOBAL_FRAMES = FRAME_ABSOLUTE | FRAME_RELATIVE | FRAME_TERRAIN
FRAME_MISSION = 2

# Mission commands that carry a location (AP_Mission::stored_in_location)
LOCATION_COMMANDS = {16, 17, 18, 19, 20, 21, 22, 30, 31, 82, 84, 85, 92, 94, 179, 189, 201}
FENCE_COMMANDS = {5000, 5001, 5002, 5003, 5004}
RALLY_COMMANDS = {5100}


@dataclass(frozen=True, slots=True)
class MissionItem:
    """One stored item, in MISSION_ITEM_INT form (x, y: degE7 in global frames)."""

    seq: int
    frame: int
    command: int
    param1: float = 0.0
    param2: float = 0.0
    param3: float = 0.0
    param4: float = 0.0
    x: int = 0
    y: int = 0
    z: float = 0.0
    mission_type: int = MISSION
    current: int = 0
    autocontinue: int = 1

    @property
    def lat_deg(self) -> float:
        return self.x * 1e-7

    @property
    def lon_deg(self) -> float:
        return self.y * 1e-7

    @property
    def has_location(self) -> bool:
        return self.frame in GLOBAL_FRAMES and not (self.x == 0 and self.y == 0)

    @classmethod
    def from_message(cls, msg: Any) -> MissionItem:
        """From a decoded MISSION_ITEM_INT or MISSION_ITEM (float lat/lon converted)."""
        x, y = msg.x, msg.y
        if msg.get_type() == "MISSION_ITEM":
            if msg.frame in GLOBAL_FRAMES:
                x, y = _deg_e7(x), _deg_e7(y)
            else:
                x, y = _int32(x), _int32(y)
        return cls(
            seq=int(msg.seq),
            frame=int(msg.frame),
            command=int(msg.command),
            param1=float(msg.param1),
            param2=float(msg.param2),
            param3=float(msg.param3),
            param4=float(msg.param4),
            x=int(x),
            y=int(y),
            z=float(msg.z),
            mission_type=int(getattr(msg, "mission_type", 0)),
            current=int(msg.current),
            autocontinue=int(msg.autocontinue),
        )

    def to_int_message(self, target_system: int, target_component: int) -> Any:
        return mavlink.MAVLink_mission_item_int_message(
            target_system,
            target_component,
            self.seq,
            self.frame,
            self.command,
            self.current,
            self.autocontinue,
            self.param1,
            self.param2,
            self.param3,
            self.param4,
            self.x,
            self.y,
            self.z,
            self.mission_type,
        )

    def to_float_message(self, target_system: int, target_component: int) -> Any:
        if self.frame in GLOBAL_FRAMES:
            x, y = self.x * 1e-7, self.y * 1e-7
        else:
            x, y = float(self.x), float(self.y)
        return mavlink.MAVLink_mission_item_message(
            target_system,
            target_component,
            self.seq,
            self.frame,
            self.command,
            self.current,
            self.autocontinue,
            self.param1,
            self.param2,
            self.param3,
            self.param4,
            x,
            y,
            self.z,
            self.mission_type,
        )


def _deg_e7(value: float) -> int:
    if not math.isfinite(value):
        return 2**31 - 1  # fails the latitude check below
    return _int32(round(value * 1e7))


def _int32(value: float) -> int:
    if not math.isfinite(value):
        return 0
    return max(-(2**31), min(2**31 - 1, int(value)))


def validate_item(item: MissionItem) -> int:
    """MAV_MISSION_RESULT for storing `item` (AP_Mission::mavlink_int_to_mission_cmd and
    the fence/rally protocol checks, simplified)."""
    params = (item.param1, item.param2, item.param3, item.param4, item.z)
    if not all(math.isfinite(p) for p in params[:4]):
        return 6  # INVALID_PARAM1 (ArduPilot rejects NaN in most params)
    if item.mission_type == MISSION:
        if item.command not in MISSION_CMD_NAMES:
            return UNSUPPORTED
        if item.command in LOCATION_COMMANDS:
            if item.frame not in GLOBAL_FRAMES:
                return UNSUPPORTED_FRAME
            return _check_location(item)
        return ACCEPTED
    if item.mission_type == FENCE:
        if item.command not in FENCE_COMMANDS:
            return UNSUPPORTED
        if item.frame not in GLOBAL_FRAMES:
            return UNSUPPORTED_FRAME
        return _check_location(item)
    if item.mission_type == RALLY:
        if item.command not in RALLY_COMMANDS:
            return UNSUPPORTED
        if item.frame not in GLOBAL_FRAMES:
            return UNSUPPORTED_FRAME
        return _check_location(item)
    return UNSUPPORTED


def _check_location(item: MissionItem) -> int:
    if abs(item.x) > 900_000_000:
        return INVALID_PARAM5_X
    if abs(item.y) > 1_800_000_000:
        return INVALID_PARAM6_Y
    if not math.isfinite(item.z) or abs(item.z) > MAX_ALT_M:
        return 12  # INVALID_PARAM7
    return ACCEPTED


def validate_fence(items: list[MissionItem]) -> int:
    """Polygons must be runs of `param1` vertices (>= 3) with the same command."""
    i = 0
    while i < len(items):
        item = items[i]
        if item.command in (5001, 5002):
            count = int(item.param1)
            if count < 3 or i + count > len(items):
                return ERROR
            if any(
                it.command != item.command or int(it.param1) != count for it in items[i : i + count]
            ):
                return ERROR
            i += count
            continue
        if item.command in (5003, 5004) and not item.param1 > 0:
            return ERROR
        i += 1
    return ACCEPTED


@dataclass(frozen=True, slots=True)
class Peer:
    sysid: int
    compid: int


class ItemTransfer:
    """MissionItemProtocol for one mission type, over `items` (a list the caller owns)."""

    def __init__(
        self,
        mission_type: int,
        items: list[MissionItem],
        *,
        home_item: Callable[[], MissionItem] | None = None,
        current_seq: Callable[[], int] | None = None,
        on_change: Callable[[int], list[Any]] | None = None,
        statustext: Callable[[int, str], Any],
    ) -> None:
        self.mission_type = mission_type
        self.items = items
        self._home_item = home_item
        self._current_seq = current_seq
        self._on_change = on_change
        self._statustext = statustext
        self.receiving = False
        self._peer = Peer(0, 0)
        self._request_i = 0
        self._request_last = 0
        self._last_receive = 0.0
        self._last_request = 0.0
        self._buffer: list[MissionItem] | None = None  # fence: committed when complete
        self._request_warned = False
        self._item_warned = False
        self.uploads_completed = 0

    # upload ------------------------------------------------------------------

    def handle_count(self, peer: Peer, count: int, now: float) -> list[Any]:
        if self.receiving and peer != self._peer:
            return [self._ack(peer, DENIED)]
        self.receiving = False
        if count > MAX_ITEMS[self.mission_type]:
            return [
                self._ack(peer, NO_SPACE),
                self._statustext(
                    SEV_WARNING, f"Only {MAX_ITEMS[self.mission_type]} items are supported"
                ),
            ]
        self._item_warned = False
        if self.mission_type == FENCE:
            self._buffer = []
        else:
            del self.items[count:]
        if count == 0:
            return self._complete(peer)
        self.receiving = True
        self._peer = peer
        self._request_i = 0
        self._request_last = count - 1
        self._last_receive = now
        return [self._request(now)]

    def handle_partial_list(self, peer: Peer, start: int, end: int, now: float) -> list[Any]:
        count = len(self.items)
        if start > count or end > count or end < start or self.mission_type == FENCE:
            return [
                self._statustext(SEV_WARNING, "Flight plan update rejected"),
                self._ack(peer, ERROR),
            ]
        self.receiving = True
        self._peer = peer
        self._request_i = start
        self._request_last = end
        self._last_receive = now
        return [self._request(now)]

    def handle_item(
        self, peer: Peer, item: MissionItem, now: float, *, as_float: bool
    ) -> list[Any]:
        out: list[Any] = []
        if not self.receiving:
            return out  # ArduPilot ignores items when no upload is in progress
        if item.seq != self._request_i:
            return [self._ack(peer, INVALID_SEQUENCE)]
        if peer != self._peer:
            return [self._ack(peer, DENIED)]
        if as_float and not self._item_warned:
            self._item_warned = True
            out.append(
                self._statustext(SEV_WARNING, "got MISSION_ITEM; GCS should send MISSION_ITEM_INT")
            )
        result = validate_item(item)
        target = self._buffer if self._buffer is not None else self.items
        if result == ACCEPTED:
            stored = replace(item, current=0, autocontinue=1)
            if item.seq < len(target):
                target[item.seq] = stored
            elif item.seq == len(target):
                target.append(stored)
            else:
                result = ERROR
        if result != ACCEPTED:
            self.receiving = False
            self._buffer = None
            out.append(self._ack(peer, result))
            return out
        self._last_receive = now
        self._request_i += 1
        if self._request_i > self._request_last:
            out.extend(self._complete(peer))
            return out
        out.append(self._request(now))
        return out

    def _complete(self, peer: Peer) -> list[Any]:
        out: list[Any] = []
        result = ACCEPTED
        if self._buffer is not None:
            result = validate_fence(self._buffer)
            if result == ACCEPTED:
                self.items[:] = self._buffer
            self._buffer = None
        self.receiving = False
        if result == ACCEPTED:
            self.uploads_completed += 1
            if self.mission_type == MISSION:
                out.append(self._statustext(SEV_INFO, "Flight plan received"))
        out.append(self._ack(peer, result))
        if result == ACCEPTED and self.mission_type == FENCE:
            out.append(self._statustext(7, "Fence Indexed OK"))  # recorded, after the ACK
        if result == ACCEPTED and self._on_change is not None:
            out.extend(self._on_change(self.mission_type))
        return out

    def _request(self, now: float) -> Any:
        self._last_request = now
        return mavlink.MAVLink_mission_request_message(
            self._peer.sysid, self._peer.compid, self._request_i, self.mission_type
        )

    def update(self, now: float) -> list[Any]:
        if not self.receiving:
            return []
        if now - self._last_receive > UPLOAD_TIMEOUT_S:
            self.receiving = False
            self._buffer = None
            out = []
            if self.mission_type == MISSION:
                out.append(self._statustext(SEV_WARNING, "Mission upload timeout"))
            out.append(self._ack(self._peer, OPERATION_CANCELLED))
            return out
        if now - self._last_request > REQUEST_RESEND_S:
            return [self._request(now)]
        return []

    def next_deadline(self) -> float | None:
        if not self.receiving:
            return None
        return (
            min(self._last_receive + UPLOAD_TIMEOUT_S, self._last_request + REQUEST_RESEND_S) + 1e-6
        )

    # download ----------------------------------------------------------------

    def count(self) -> int:
        if self.mission_type == MISSION:
            return max(1, len(self.items))  # home is always item 0
        return len(self.items)

    def handle_request_list(self, peer: Peer) -> list[Any]:
        if self.receiving:
            return [self._ack(peer, DENIED)]
        self._request_warned = False
        return [
            mavlink.MAVLink_mission_count_message(
                peer.sysid, peer.compid, self.count(), self.mission_type
            )
        ]

    def handle_request(self, peer: Peer, seq: int, *, as_int: bool) -> list[Any]:
        if self.receiving:
            return [self._ack(peer, DENIED)]
        item = self._get(seq)
        if item is None:
            if self.mission_type == MISSION:
                return [
                    mavlink.MAVLink_mission_count_message(
                        peer.sysid, peer.compid, self.count(), MISSION
                    ),
                    self._ack(peer, ERROR),
                ]
            return [self._ack(peer, INVALID_SEQUENCE)]
        if as_int:
            return [item.to_int_message(peer.sysid, peer.compid)]
        out = []
        if not self._request_warned:
            self._request_warned = True
            out.append(
                self._statustext(SEV_WARNING, "got MISSION_REQUEST; use MISSION_REQUEST_INT!")
            )
        out.append(item.to_float_message(peer.sysid, peer.compid))
        return out

    def _get(self, seq: int) -> MissionItem | None:
        if self.mission_type == MISSION:
            if seq == 0 and self._home_item is not None:
                item = self._home_item()
            elif 0 < seq < len(self.items):
                item = self.items[seq]
            else:
                return None
            current = self._current_seq() if self._current_seq is not None else -1
            return replace(item, seq=seq, current=1 if seq == current and seq > 0 else 0)
        if 0 <= seq < len(self.items):
            return replace(self.items[seq], seq=seq)
        return None

    # clear ---------------------------------------------------------------------

    def handle_clear_all(self, peer: Peer) -> list[Any]:
        if self.receiving:
            return [self._ack(peer, ERROR)]
        if self.mission_type == MISSION:
            del self.items[1:]
        else:
            self.items.clear()
        out = [self._ack(peer, ACCEPTED)]
        if self._on_change is not None:
            out.extend(self._on_change(self.mission_type))
        return out

    def _ack(self, peer: Peer, result: int) -> Any:
        return mavlink.MAVLink_mission_ack_message(
            peer.sysid, peer.compid, result, self.mission_type
        )
