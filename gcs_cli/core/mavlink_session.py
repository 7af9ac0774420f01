"""`gcs mavlink`, pure: one local MAVLink endpoint speaking for one vehicle's autopilot
(docs/ground-station.md, "MAVLink passthrough"). The shell (gcs_cli/mavlink.py) moves
bytes between the client (QGroundControl, MAVProxy, pymavlink) and Zenoh; this decides
what moves and when a session lives.

A session opens when the client first speaks (an endpoint that sends first, `udpout:`
towards a listening QGroundControl, opens at start and stays open), is announced to the
vehicle's node every `announce_s` (a `MavlinkSession`), and ends when the client has
been silent for `client_timeout_s` or the ground station stops (announced `closing`):
the node then stops relaying and nothing is sent to the vehicle. A client that speaks
again gets a new session.

Up: the client's bytes are cut into frames; whole valid frames go on as they came (one
Zenoh sample per read), bytes that are no frame are dropped and counted. Whether a
frame may reach the autopilot is the node's decision (swarm_node/core/passthrough.py:
foreign systems, read-only, the arbiter). Down: the node's bytes go to the client as
they are.

    actions: Up(data) -> the session's up key; Down(data) -> the client;
             Announce(msg) -> the session key; Listen(session_id | None) -> which down
             key the shell subscribes to

Pure: no I/O; `now` and the session ids (`new_id`) are given.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field

from swarm_node.core.autopilot.framing import BadFrame, MavFramer
from swarm_proto.messages import MavlinkSession

CLIENT_TIMEOUT_S = 10.0  # QGroundControl and MAVProxy send a HEARTBEAT every second
ANNOUNCE_S = 1.0  # the node ends a session it has not heard of for 5 s


@dataclass(frozen=True)
class Up:
    data: bytes


@dataclass(frozen=True)
class Down:
    data: bytes


@dataclass(frozen=True)
class Announce:
    msg: MavlinkSession


@dataclass(frozen=True)
class Listen:
    session_id: int | None  # the down key to subscribe to (None: none)


Action = Up | Down | Announce | Listen


@dataclass
class SessionCore:
    vehicle_id: int
    issuer_id: int
    new_id: Callable[[], int]  # a fresh random session id (1 .. 2^32 - 1)
    read_only: bool = False
    listens: bool = True  # the client speaks first (udp:, tcpin:); False: we do (udpout:)
    client_timeout_s: float = CLIENT_TIMEOUT_S
    announce_s: float = ANNOUNCE_S
    session_id: int | None = None
    counts: Counter[str] = field(default_factory=Counter)
    sessions: int = 0  # opened since start
    _framer: MavFramer = field(default_factory=MavFramer)
    _heard: float = float("-inf")  # the client's last bytes
    _announce_at: float = float("inf")

    def start(self, now: float) -> list[Action]:
        """An endpoint that speaks first opens its session now."""
        return [] if self.listens else self._open(now)

    # ------------------------------------------------------------------ bytes
    def on_client(self, data: bytes, now: float) -> list[Action]:
        """Bytes from the client: its valid frames to the vehicle."""
        frames: list[bytes] = []
        for item in self._framer.feed(data):
            if isinstance(item, BadFrame):
                self.counts["malformed"] += 1
                self.counts["malformed_bytes"] += item.n_bytes
            else:
                frames.append(bytes(item.get_msgbuf()))
        self._heard = now
        out = self._open(now) if self.session_id is None else []
        if frames:
            self.counts["frames_up"] += len(frames)
            out.append(Up(b"".join(frames)))
        return out

    def on_vehicle(self, session_id: int, data: bytes) -> list[Action]:
        """Bytes from the vehicle's node for `session_id`: to the client."""
        if session_id != self.session_id or not data:
            self.counts["stale_down"] += 1
            return []
        self.counts["bytes_down"] += len(data)
        return [Down(data)]

    # ------------------------------------------------------------------ time
    def on_timer(self, now: float) -> list[Action]:
        if self.session_id is None:
            return []
        if self.listens and now - self._heard >= self.client_timeout_s:
            self.counts["client_timeouts"] += 1
            return self._close()
        if now >= self._announce_at:
            self._announce_at = now + self.announce_s
            return [Announce(self._msg())]
        return []

    def next_deadline(self) -> float | None:
        if self.session_id is None:
            return None
        due = self._announce_at
        if self.listens:
            due = min(due, self._heard + self.client_timeout_s)
        return due

    def close(self) -> list[Action]:
        """The ground station stops: the session ends."""
        return self._close() if self.session_id is not None else []

    # ------------------------------------------------------------------ internals
    def _open(self, now: float) -> list[Action]:
        self.session_id = self.new_id()
        self.sessions += 1
        self._framer = MavFramer()
        self._announce_at = now + self.announce_s
        return [Listen(self.session_id), Announce(self._msg())]

    def _close(self) -> list[Action]:
        msg = self._msg(closing=True)
        self.session_id = None
        self._announce_at = float("inf")
        return [Announce(msg), Listen(None)]

    def _msg(self, *, closing: bool = False) -> MavlinkSession:
        assert self.session_id is not None
        return MavlinkSession(
            self.vehicle_id, self.session_id, self.issuer_id, self.read_only, closing
        )
