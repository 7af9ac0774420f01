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

Over the 900 MHz radio (`RadioSessionCore`) a session is budgeted: the vehicle's
HIGH_LATENCY2 every 5 s and commands only (docs/radio.md, "MAVLink passthrough on the
air").

Pure: no I/O; `now` and the session ids (`new_id`) are given.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from swarm_node.core.autopilot.framing import BadFrame, MavEncoder, MavFramer, MAVLinkMessage
from swarm_proto.messages import MavlinkCommand, MavlinkSession

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


# ----------------------------------------------------------------------- the radio
KEEPALIVE_S = 20.0  # the node ends a radio session it has not heard of for 60 s
COMMAND_GAP_S = 2.0  # at most one command every 2 s on the air, per vehicle
REFUSAL_REPEAT_S = 30.0  # a client asking again and again is told once in this long
RADIO_COMMANDS = frozenset({"COMMAND_LONG", "COMMAND_INT", "SET_MODE"})


@dataclass(frozen=True)
class Command:
    msg: MavlinkCommand  # to publish: the radio carries it (acknowledged, lowest class)


RadioAction = Down | Command


@dataclass
class RadioSessionCore:
    """`gcs mavlink --radio`: a vehicle behind the 900 MHz radio, budgeted. The client
    gets the vehicle's HIGH_LATENCY2 (every 5 s) and a HEARTBEAT made from it every
    second (clients find a vehicle by its heartbeat; `custom0` says armed), and sends
    commands only (COMMAND_LONG, COMMAND_INT, SET_MODE), one per `command_gap_s`; what
    it asks beyond that is answered here (COMMAND_ACK TEMPORARILY_REJECTED for a
    command too soon, a STATUSTEXT for what does not go on the radio), from the
    autopilot's ids."""

    vehicle_id: int
    issuer_id: int
    command_gap_s: float = COMMAND_GAP_S
    keepalive_s: float = KEEPALIVE_S
    counts: Counter[str] = field(default_factory=Counter)
    _framer: MavFramer = field(default_factory=MavFramer)
    _summary: MAVLinkMessage | None = None
    _encoder: MavEncoder | None = None
    _beat_at: float = float("inf")
    _keep_at: float = float("-inf")
    _command_at: float = float("-inf")
    _refused: dict[str, float] = field(default_factory=dict)

    def start(self, now: float) -> list[RadioAction]:
        return self.on_timer(now)

    def on_client(self, data: bytes, now: float) -> list[RadioAction]:
        out: list[RadioAction] = []
        for item in self._framer.feed(data):
            if isinstance(item, BadFrame):
                self.counts["malformed"] += 1
                continue
            name = item.get_type()
            if name == "HEARTBEAT":
                continue
            if name not in RADIO_COMMANDS:
                out += self._refuse(name, now)
            elif now - self._command_at < self.command_gap_s:
                self.counts["too_soon"] += 1
                command = int(item.command) if name != "SET_MODE" else 11
                ack = mavlink.MAVLink_command_ack_message(
                    command,
                    mavlink.MAV_RESULT_TEMPORARILY_REJECTED,
                    0,
                    0,
                    item.get_srcSystem(),
                    item.get_srcComponent(),
                )
                out.append(self._down(ack, _text("bandada: radio: one command per 2 s")))
            else:
                self._command_at = now
                self.counts["commands"] += 1
                frame = bytes(item.get_msgbuf())
                out.append(Command(MavlinkCommand(self.issuer_id, self.vehicle_id, frame)))
        return out

    def on_summary(self, frame: bytes, now: float) -> list[RadioAction]:
        """The vehicle's HIGH_LATENCY2: to the client, and the heartbeats made from it."""
        items = [m for m in MavFramer().feed(frame) if not isinstance(m, BadFrame)]
        if not items or items[0].get_type() != "HIGH_LATENCY2":
            self.counts["bad_summary"] += 1
            return []
        first = self._summary is None
        self._summary = items[0]
        ids = (items[0].get_srcSystem(), items[0].get_srcComponent())
        if self._encoder is None or (self._encoder.sysid, self._encoder.compid) != ids:
            self._encoder = MavEncoder(*ids)
        self.counts["summaries"] += 1
        out: list[RadioAction] = [Down(frame)]
        if first:
            self._beat_at = now
            out += self.on_timer(now)
        return out

    def on_answer(self, frame: bytes) -> list[RadioAction]:
        self.counts["answers"] += 1
        return [Down(frame)]

    def on_timer(self, now: float) -> list[RadioAction]:
        out: list[RadioAction] = []
        if now >= self._keep_at:
            self._keep_at = now + self.keepalive_s
            out.append(Command(MavlinkCommand(self.issuer_id, self.vehicle_id)))
        if self._summary is not None and now >= self._beat_at:
            self._beat_at = now + 1.0
            out.append(self._down(heartbeat_of(self._summary)))
        return out

    def next_deadline(self) -> float:
        return min(self._keep_at, self._beat_at)

    def close(self) -> list[RadioAction]:
        return []  # the node ends the session once the keep-alives stop

    def _refuse(self, name: str, now: float) -> list[RadioAction]:
        self.counts["not_on_the_radio"] += 1
        if now - self._refused.get(name, float("-inf")) < REFUSAL_REPEAT_S:
            return []
        self._refused[name] = now
        return [self._down(_text(f"bandada: not on the radio: {name}"))]

    def _down(self, *msgs: MAVLinkMessage) -> Down:
        enc = self._encoder or MavEncoder(self.vehicle_id % 256 or 1, 1)
        self._encoder = enc
        return Down(b"".join(enc.encode(m) for m in msgs))


def heartbeat_of(hl2: MAVLinkMessage) -> MAVLinkMessage:
    """The HEARTBEAT a client expects, from a HIGH_LATENCY2 (custom0 bit 0: armed)."""
    base = mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
    if int(hl2.custom0) & 1:
        base |= mavlink.MAV_MODE_FLAG_SAFETY_ARMED
    return mavlink.MAVLink_heartbeat_message(
        int(hl2.type), int(hl2.autopilot), base, int(hl2.custom_mode), mavlink.MAV_STATE_ACTIVE, 3
    )


def _text(text: str) -> MAVLinkMessage:
    return mavlink.MAVLink_statustext_message(
        mavlink.MAV_SEVERITY_WARNING, text[:50].encode("ascii", "replace")
    )
