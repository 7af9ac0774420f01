"""The node's side of MAVLink passthrough sessions on Zenoh (the decisions are
`swarm_node.core.passthrough`'s; docs/autopilot-link.md, "Passthrough").

Up: a session's raw frames (`vehicle/<id>/mavlink/<session>/up`) and its announcements
(`.../session`) go to the node's inbox, like every other input. Down: while a session
is open the autopilot link hands over the autopilot's frames as they came, on its own
thread (`on_frames`), and they are put on each open session's `down` key at once,
without the node's loop: telemetry at the autopilot's rate never waits for it. The
node's answers for a session (`ToClient`) go on the same key.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable, Mapping
from typing import Any, Protocol

import zenoh

from swarm_proto.session import SwarmBus, put_options
from swarm_proto.topics import MAVLINK_DOWN, MAVLINK_SESSION, MAVLINK_UP

from ..core.inputs import BadInput, Input, MavlinkUp, Received

log = logging.getLogger("swarm_node.passthrough")


class RelayPort(Protocol):
    """What passthrough needs of the autopilot link (runtime/autopilot_link.py)."""

    on_frames: Callable[[bytes], None] | None

    def relay(self, data: bytes) -> None: ...

    def set_tap(self, on: bool) -> None: ...

    def want_rates(self, rates: Mapping[str, float]) -> None: ...


class PassthroughRelay:
    def __init__(
        self, bus: SwarmBus, vehicle_id: int, link: RelayPort, deliver: Callable[[Input], None]
    ) -> None:
        self.bus, self.vehicle_id, self.link, self.deliver = bus, vehicle_id, link, deliver
        self.swarm = bus.swarm
        self._up: zenoh.Subscriber | None = None
        self._lock = threading.Lock()
        # session id -> its down publisher; replaced whole (the link's thread reads it)
        self._down: dict[int, Any] = {}
        self.batches_down = 0
        self.bytes_down = 0

    def start(self) -> None:
        key = MAVLINK_UP.key(self.swarm, vehicle_id=self.vehicle_id)  # every session
        self._up = self.bus.session.declare_subscriber(key, self._on_up)
        self.bus.subscribe(
            MAVLINK_SESSION,
            lambda msg, _key: self.deliver(Received(msg)),
            key=MAVLINK_SESSION.key(self.swarm, vehicle_id=self.vehicle_id),
        )
        self.link.on_frames = self._on_frames

    def _on_up(self, sample: zenoh.Sample) -> None:
        key = str(sample.key_expr)
        params = MAVLINK_UP.parse(self.swarm, key)
        sid = params["session_id"] if params else ""
        if not sid.isdigit() or not 0 < int(sid) < 2**32:
            self.deliver(BadInput(key, "not a passthrough session key"))
            return
        self.deliver(MavlinkUp(int(sid), sample.payload.to_bytes()))

    # ------------------------------------------------------------------ the node's outputs
    def sessions(self, ids: tuple[int, ...]) -> None:
        """The sessions open now: a down publisher each; the link keeps the autopilot's
        frames only while there is one."""
        with self._lock:
            old = self._down
            new = {sid: old[sid] for sid in ids if sid in old}
            for sid in ids:
                if sid not in new:
                    key = MAVLINK_DOWN.key(self.swarm, vehicle_id=self.vehicle_id, session_id=sid)
                    new[sid] = self.bus.session.declare_publisher(key, **put_options(MAVLINK_DOWN))
            self._down = new
        for sid, pub in old.items():
            if sid not in new:
                _undeclare(pub)
        self.link.set_tap(bool(ids))

    def to_client(self, session_id: int, data: bytes) -> None:
        pub = self._down.get(session_id)
        if pub is not None:
            pub.put(data)

    def to_autopilot(self, data: bytes) -> None:
        self.link.relay(data)

    def wish(self, rates: tuple[tuple[str, float], ...]) -> None:
        self.link.want_rates(dict(rates))

    def _on_frames(self, data: bytes) -> None:
        """The autopilot's frames (the link's thread): to every open session."""
        for pub in self._down.values():
            try:
                pub.put(data)
            except Exception:  # that session is closing
                log.debug("passthrough put failed", exc_info=True)
                continue
            self.batches_down += 1
            self.bytes_down += len(data)

    def close(self) -> None:
        self.link.on_frames = None
        self.link.set_tap(False)
        if self._up is not None:
            _undeclare(self._up)
            self._up = None
        with self._lock:
            down, self._down = self._down, {}
        for pub in down.values():
            _undeclare(pub)


def _undeclare(entity: Any) -> None:
    try:
        entity.undeclare()
    except Exception:
        log.debug("undeclare failed", exc_info=True)
