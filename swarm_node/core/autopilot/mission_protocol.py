"""The MAVLink mission protocol, client side, for the mission, fence and rally types, as
two pure state machines: `MissionUpload` and `MissionDownload`.

Upload:   -> MISSION_COUNT(n)                 (empty: -> MISSION_CLEAR_ALL, <- MISSION_ACK)
          <- MISSION_REQUEST_INT(i) or MISSION_REQUEST(i)   -> MISSION_ITEM_INT(i)
          ... <- MISSION_ACK(ACCEPTED) after the last item
Download: -> MISSION_REQUEST_LIST   <- MISSION_COUNT(n)
          -> MISSION_REQUEST_INT(i) <- MISSION_ITEM_INT(i) or MISSION_ITEM(i)   ...
          -> MISSION_ACK(ACCEPTED)

Real ArduPilot answers MISSION_COUNT with MISSION_REQUEST (not _INT) — both are
answered with MISSION_ITEM_INT, which ArduPilot accepts either way and which keeps
1e-7 degree precision (MISSION_ITEM's float32 latitude loses ~0.4 m).

Loss handling (as the MAVLink mission protocol specifies): whoever waits for an answer
resends its last message after `timeout_s`; the autopilot re-requests items it lost.
Duplicated requests are answered again. Every new step restores `retries` resends; an
overall deadline (`overall_timeout_s`, default grows with the item count) bounds a
transfer no matter what the autopilot does, so a transfer always ends: ok, or failed
with a reason (and a MISSION_ACK OPERATION_CANCELLED sent so the autopilot stops too).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from .framing import MAVLinkMessage
from .mission_item import GLOBAL_FRAMES, MissionItem
from .requests import ApError, MissionKind

MAV_MISSION_ACCEPTED = 0
MAV_MISSION_INVALID_SEQUENCE = 13
MAV_MISSION_OPERATION_CANCELLED = 15


def mission_result_name(code: int) -> str:
    entry = mavlink.enums["MAV_MISSION_RESULT"].get(code)
    return entry.name.removeprefix("MAV_") if entry else f"MISSION_RESULT({code})"


@dataclass(frozen=True, slots=True)
class TransferResult:
    ok: bool
    reason: str = ""
    error: ApError = ApError.NONE
    items: tuple[MissionItem, ...] = ()
    attempts: int = 0


def item_to_message(item: MissionItem, target: tuple[int, int]) -> MAVLinkMessage:
    return mavlink.MAVLink_mission_item_int_message(
        target[0],
        target[1],
        item.seq,
        item.frame,
        item.command,
        item.current,
        item.autocontinue,
        item.param1,
        item.param2,
        item.param3,
        item.param4,
        round(item.lat_deg * 1e7),
        round(item.lon_deg * 1e7),
        item.alt_m,
        item.mission_type,
    )


def item_from_message(msg: MAVLinkMessage) -> MissionItem:
    """MISSION_ITEM_INT or MISSION_ITEM -> MissionItem (ValueError if malformed)."""
    scale = 1e7 if msg.get_type() == "MISSION_ITEM_INT" else 1.0
    item = MissionItem(
        seq=int(msg.seq),
        command=int(msg.command),
        frame=int(msg.frame),
        param1=float(msg.param1),
        param2=float(msg.param2),
        param3=float(msg.param3),
        param4=float(msg.param4),
        lat_deg=msg.x / scale,
        lon_deg=msg.y / scale,
        alt_m=float(msg.z),
        current=int(msg.current),
        autocontinue=int(msg.autocontinue),
        mission_type=int(getattr(msg, "mission_type", 0)),
    )
    if scale == 1.0 and item.frame in GLOBAL_FRAMES:
        # float32 degrees: keep them as sent, rounded to the 1e-7 grid the autopilot uses
        item = _rounded(item)
    problem = item.problem()
    if problem:
        raise ValueError(problem)
    return item


def _rounded(item: MissionItem) -> MissionItem:
    import msgspec

    return msgspec.structs.replace(
        item, lat_deg=round(item.lat_deg * 1e7) / 1e7, lon_deg=round(item.lon_deg * 1e7) / 1e7
    )


class _Transfer:
    def __init__(
        self,
        kind: MissionKind,
        target: tuple[int, int],
        *,
        timeout_s: float,
        retries: int,
        overall_timeout_s: float,
    ) -> None:
        if not (timeout_s > 0 and retries >= 0 and overall_timeout_s > 0):
            raise ValueError("timeouts must be positive and retries >= 0")
        self.kind = MissionKind(kind)
        self.target = target
        self.timeout_s = timeout_s
        self.retries = retries
        self.overall_timeout_s = overall_timeout_s
        self.result: TransferResult | None = None
        self.invalid = 0  # messages for this transfer we rejected
        self.out_of_sequence = 0  # INVALID_SEQUENCE acks to a late item of ours (ignored)
        self.sent = 0
        self._last: MAVLinkMessage | None = None
        self._deadline: float | None = None
        self._give_up_at = math.inf
        self._retries_left = retries
        self._attempts = 0

    @property
    def done(self) -> bool:
        return self.result is not None

    def next_deadline(self) -> float | None:
        if self.done or self._deadline is None:
            return None
        return min(self._deadline, self._give_up_at)

    def _send(self, msg: MAVLinkMessage, now: float, progress: bool) -> list[MAVLinkMessage]:
        if progress:
            self._retries_left = self.retries
            self._attempts = 0
        self._last = msg
        self._deadline = now + self.timeout_s
        self._attempts += 1
        self.sent += 1
        return [msg]

    def _finish(self, result: TransferResult) -> None:
        self.result = result
        self._deadline = None

    def _fail(
        self, reason: str, error: ApError, now: float, cancel: bool = True
    ) -> list[MAVLinkMessage]:
        self._finish(TransferResult(False, reason, error, attempts=self._attempts))
        if not cancel:
            return []
        self.sent += 1
        return [self._ack(MAV_MISSION_OPERATION_CANCELLED)]

    def _ack(self, code: int) -> MAVLinkMessage:
        return mavlink.MAVLink_mission_ack_message(self.target[0], self.target[1], code, self.kind)

    def _waiting_for(self) -> str:
        raise NotImplementedError

    def on_timer(self, now: float) -> list[MAVLinkMessage]:
        if self.done or self._deadline is None:
            return []
        if now >= self._give_up_at:
            return self._fail(
                f"{self.kind.name.lower()} transfer took longer than {self.overall_timeout_s:g} s",
                ApError.TIMEOUT,
                now,
            )
        if now < self._deadline:
            return []
        if self._retries_left <= 0 or self._last is None:
            return self._fail(
                f"no {self._waiting_for()} after {self._attempts} tries", ApError.TIMEOUT, now
            )
        self._retries_left -= 1
        return self._send(self._last, now, progress=False)

    def _mine(self, msg: MAVLinkMessage) -> bool:
        return int(getattr(msg, "mission_type", 0)) == self.kind


class MissionUpload(_Transfer):
    """Writes `items` (seq renumbered 0..n-1, mission_type set to `kind`)."""

    def __init__(
        self,
        kind: MissionKind,
        items: tuple[MissionItem, ...] | list[MissionItem],
        target: tuple[int, int],
        *,
        timeout_s: float = 1.5,
        retries: int = 5,
        overall_timeout_s: float | None = None,
    ) -> None:
        n = len(items)
        super().__init__(
            kind,
            target,
            timeout_s=timeout_s,
            retries=retries,
            overall_timeout_s=overall_timeout_s or (20.0 + 2.0 * n * timeout_s),
        )
        import msgspec

        self.items = tuple(
            msgspec.structs.replace(it, seq=i, mission_type=int(kind)) for i, it in enumerate(items)
        )
        for it in self.items:
            problem = it.problem()
            if problem:
                raise ValueError(f"item {it.seq}: {problem}")
        self._requested: set[int] = set()

    def start(self, now: float) -> list[MAVLinkMessage]:
        self._give_up_at = now + self.overall_timeout_s
        t = self.target
        if not self.items:
            return self._send(
                mavlink.MAVLink_mission_clear_all_message(t[0], t[1], self.kind), now, True
            )
        return self._send(
            mavlink.MAVLink_mission_count_message(t[0], t[1], len(self.items), self.kind), now, True
        )

    def _waiting_for(self) -> str:
        if not self.items:
            return "MISSION_ACK to MISSION_CLEAR_ALL"
        if len(self._requested) == len(self.items):
            return "MISSION_ACK after the last item (the upload may have succeeded)"
        if not self._requested:
            return "MISSION_REQUEST for the first item"
        return f"MISSION_REQUEST after item {max(self._requested)}"

    def handle(self, msg: MAVLinkMessage, now: float) -> list[MAVLinkMessage]:
        if self.done or not self._mine(msg):
            return []
        mtype = msg.get_type()
        if mtype in ("MISSION_REQUEST_INT", "MISSION_REQUEST"):
            seq = int(msg.seq)
            if not 0 <= seq < len(self.items):
                self.invalid += 1
                return []
            new = seq not in self._requested
            self._requested.add(seq)
            return self._send(item_to_message(self.items[seq], self.target), now, progress=new)
        if mtype == "MISSION_ACK":
            code = int(msg.type)
            if code == MAV_MISSION_ACCEPTED:
                if self.items and len(self._requested) < len(self.items):
                    return []  # a stale ACK from an earlier transfer: not ours yet
                self._finish(TransferResult(True, items=self.items, attempts=self._attempts))
                return []
            if code == MAV_MISSION_INVALID_SEQUENCE:
                # an item it did not ask for (our late answer to a request it sent again:
                # a loaded host, a slow link): ArduPilot says so and keeps waiting for the
                # one it asked for (MissionItemProtocol::handle_mission_item); the upload
                # goes on, its timeouts still end one that never completes
                self.out_of_sequence += 1
                return []
            return self._fail(
                f"MISSION_ACK {mission_result_name(code)}",
                ApError.CANCELLED
                if code == MAV_MISSION_OPERATION_CANCELLED
                else ApError.MISSION_ERROR,
                now,
                cancel=False,
            )
        return []


class MissionDownload(_Transfer):
    """Reads the autopilot's items of `kind`; result.items in seq order."""

    def __init__(
        self,
        kind: MissionKind,
        target: tuple[int, int],
        *,
        timeout_s: float = 1.5,
        retries: int = 5,
        overall_timeout_s: float | None = None,
    ) -> None:
        super().__init__(
            kind,
            target,
            timeout_s=timeout_s,
            retries=retries,
            overall_timeout_s=overall_timeout_s or 20.0,
        )
        self._fixed_overall = overall_timeout_s
        self._count: int | None = None
        self._items: list[MissionItem] = []

    def start(self, now: float) -> list[MAVLinkMessage]:
        self._give_up_at = now + self.overall_timeout_s
        t = self.target
        return self._send(
            mavlink.MAVLink_mission_request_list_message(t[0], t[1], self.kind), now, True
        )

    def _waiting_for(self) -> str:
        if self._count is None:
            return "MISSION_COUNT"
        return f"MISSION_ITEM {len(self._items)}"

    def _request_next(self, now: float) -> list[MAVLinkMessage]:
        t = self.target
        seq = len(self._items)
        return self._send(
            mavlink.MAVLink_mission_request_int_message(t[0], t[1], seq, self.kind), now, True
        )

    def handle(self, msg: MAVLinkMessage, now: float) -> list[MAVLinkMessage]:
        if self.done or not self._mine(msg):
            return []
        mtype = msg.get_type()
        if mtype == "MISSION_COUNT":
            count = int(msg.count)
            if self._count is not None:
                if count != self._count:
                    self.invalid += 1
                return []
            if not 0 <= count <= 65535:
                self.invalid += 1
                return []
            self._count = count
            if self._fixed_overall is None:  # grows with the count now that it is known
                self.overall_timeout_s = 20.0 + 2.0 * count * self.timeout_s
                self._give_up_at = now + self.overall_timeout_s
            if count == 0:
                return self._complete()
            return self._request_next(now)
        if mtype in ("MISSION_ITEM_INT", "MISSION_ITEM"):
            if self._count is None or int(msg.seq) != len(self._items):
                return []  # a duplicate or out-of-order item: the request stands
            try:
                item = item_from_message(msg)
            except (ValueError, TypeError, OverflowError):
                self.invalid += 1
                return []
            self._items.append(item)
            if len(self._items) == self._count:
                return self._complete()
            return self._request_next(now)
        if mtype == "MISSION_ACK" and int(msg.type) != MAV_MISSION_ACCEPTED:
            code = int(msg.type)
            return self._fail(
                f"MISSION_ACK {mission_result_name(code)}", ApError.MISSION_ERROR, now, cancel=False
            )
        return []

    def _complete(self) -> list[MAVLinkMessage]:
        self._finish(TransferResult(True, items=tuple(self._items), attempts=self._attempts))
        self.sent += 1
        return [self._ack(MAV_MISSION_ACCEPTED)]
