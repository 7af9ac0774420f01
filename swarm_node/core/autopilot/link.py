"""The whole autopilot link as one sans-I/O object: bytes and requests in, bytes, events
and results out. `swarm_node.runtime.autopilot_link.AutopilotLink` only moves bytes
and time; tests drive this directly (ManualClock, no sockets).

    core = LinkCore(LinkSettings(vehicle_type=VehicleType.VTOL), now)
    outputs = core.receive(data, now)        # bytes from the autopilot
    outputs += core.submit(token, Arm(), now)
    outputs += core.on_timer(now)            # call at core.next_deadline()
    # outputs: Transmit(data) to write, Emit(event) to report, Complete(token, result)

Inbound routing (reading this table says what happens to a message): the tracker
checks the source and validates; then

| message                                  | goes to                                  |
|------------------------------------------|------------------------------------------|
| telemetry (tracker.HANDLERS)             | the tracker -> AutopilotState, ApEvents  |
| COMMAND_ACK                              | request runner; stream requester (511)   |
| PARAM_VALUE, MISSION_* (tracker.PROTOCOL)| request runner (if addressed to us)      |
| STATUSTEXT                               | tracker (event) and request runner (quoted in refusals) |
| SYS_STATUS, MISSION_CURRENT              | tracker, then the request runner (fence enable waits, mission start check) |
| HEARTBEAT                                | tracker, then the request runner (a mode change confirmed) |
| tracker.IGNORED                          | nowhere (listed on purpose)              |
| anything else                            | counted as unhandled                     |

Passthrough (core/passthrough.py): while `tap` is set, every frame from the autopilot's
system that decoded, whatever the tracker made of it, is also kept as it came
(`take_tapped`), for the ground stations' sessions, unless it answers the node itself
(`for_passthrough`). `relay(data)` writes a session's frames as they are;
`RelayCommand` / `RelaySetting` requests (granted by the arbiter) too, answered at once.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from swarm_proto import VehicleType

from .events import ApEvent, AutopilotFound, AutopilotRebooted, LinkRestored
from .framing import BadFrame, MavEncoder, MavFramer, MAVLinkMessage
from .plans import PlanContext, check_request
from .requests import ApError, ApRequest, ApResult, MissionKind, ReadParam, RelayCommand
from .runner import Finished, RequestRunner, RunnerSettings, mission_kind_of
from .state import AutopilotState
from .streams import DEFAULT_RATES_HZ, StreamRequester
from .tracker import PROTOCOL, StateTracker, Verdict

MAV_TYPE_ONBOARD_CONTROLLER = 18
MAV_AUTOPILOT_INVALID = 8
MAV_STATE_ACTIVE = 4
#: Telemetry the request runner also sees (after the tracker applied it).
RUNNER_WATCHES = frozenset({"STATUSTEXT", "SYS_STATUS", "MISSION_CURRENT", "HEARTBEAT"})

#: The autopilot's own figures, read from its parameters when it is found (and after a
#: reboot), per vehicle type: what the node plans endurance and judges attitude with
#: (the swarm database's values are only a fallback; monitoring warns when they differ).
#: ArduPlane before 4.5 names its roll limit LIM_ROLL_CD (centidegrees): read if
#: ROLL_LIMIT_DEG is not answered.
_BATTERY = ("BATT_MONITOR", "BATT_CAPACITY")
FIGURES: dict[VehicleType, tuple[str, ...]] = {
    VehicleType.COPTER: (*_BATTERY, "ANGLE_MAX"),
    VehicleType.PLANE: (*_BATTERY, "ROLL_LIMIT_DEG"),
    VehicleType.VTOL: (*_BATTERY, "ROLL_LIMIT_DEG"),
    VehicleType.ROVER: _BATTERY,
    VehicleType.BOAT: _BATTERY,
}
FALLBACK = {"ROLL_LIMIT_DEG": "LIM_ROLL_CD"}


def figures_of(values: Mapping[str, float]) -> dict[str, float | None]:
    """AutopilotState's figure fields from the parameter values read so far."""
    out: dict[str, float | None] = {}
    monitor, capacity = values.get("BATT_MONITOR"), values.get("BATT_CAPACITY")
    if monitor is not None and monitor == 0:
        out["battery_capacity_mah"] = None  # no battery monitor: the autopilot does not know
    elif capacity is not None and capacity > 0:
        out["battery_capacity_mah"] = capacity
    for name, scale in (("ANGLE_MAX", 0.01), ("ROLL_LIMIT_DEG", 1.0), ("LIM_ROLL_CD", 0.01)):
        v = values.get(name)
        if v is not None and 0 < v * scale <= 90:
            out["max_bank_deg"] = v * scale
            break
    return out


@dataclass(frozen=True)
class LinkSettings:
    vehicle_type: VehicleType | None = None  # None: from the HEARTBEAT (QuadPlanes say PLANE)
    target_sysid: int | None = None  # None: the first autopilot heard
    target_compid: int | None = None
    source_sysid: int = 255  # ours; 255 is what ArduPilot's SYSID_MYGCS expects by default
    source_compid: int = 191  # MAV_COMP_ID_ONBOARD_COMPUTER
    link_timeout_s: float = 0.9  # silence that counts as a lost link (telemetry is 10 Hz)
    heartbeat_timeout_s: float = 2.5  # the same while only HEARTBEATs (1 Hz) arrive
    heartbeat_period_s: float = 1.0  # our HEARTBEAT (GCS failsafe; udpout peers learn us)
    stream_rates_hz: Mapping[str, float] = field(default_factory=lambda: dict(DEFAULT_RATES_HZ))
    runner: RunnerSettings = field(default_factory=RunnerSettings)
    read_figures: bool = True  # read FIGURES when the autopilot is found


@dataclass(frozen=True, slots=True)
class Transmit:
    data: bytes
    message: MAVLinkMessage  # None: a passthrough session's frames, written as they came


@dataclass(frozen=True, slots=True)
class Emit:
    event: ApEvent


@dataclass(frozen=True, slots=True)
class Complete:
    token: int
    result: ApResult


Output = Transmit | Emit | Complete


@dataclass(slots=True)
class LinkCounters:
    bytes_in: int = 0
    bytes_out: int = 0
    messages_in: int = 0
    messages_out: int = 0
    not_for_us: int = 0  # protocol replies addressed to another GCS
    relayed_out: int = 0  # passthrough bytes written to the autopilot
    tapped: int = 0  # frames from the autopilot kept for passthrough sessions


class LinkCore:
    def __init__(self, settings: LinkSettings | None = None, now: float = 0.0) -> None:
        self.settings = s = settings or LinkSettings()
        self.tracker = StateTracker(
            vehicle_type=s.vehicle_type,
            target_sysid=s.target_sysid,
            target_compid=s.target_compid,
            link_timeout_s=s.link_timeout_s,
            heartbeat_timeout_s=s.heartbeat_timeout_s,
        )
        self.framer = MavFramer()
        self.encoder = MavEncoder(s.source_sysid, s.source_compid)
        self.runner = RequestRunner(s.runner)
        self.streams = StreamRequester(s.stream_rates_hz)
        self.counters = LinkCounters()
        self._next_heartbeat = now
        self._figure_tokens: dict[int, str] = {}  # our own reads (negative tokens) -> name
        self._figure_values: dict[str, float] = {}
        self._next_figure_token = -1
        self.tap = False  # keep the autopilot's frames for passthrough sessions
        self._tapped: list[bytes] = []

    # ------------------------------------------------------------------ public

    @property
    def state(self) -> AutopilotState:
        return self.tracker.state

    def receive(self, data: bytes, now: float) -> list[Output]:
        """Bytes from the autopilot, in any chunking."""
        self.counters.bytes_in += len(data)
        out: list[Output] = []
        for item in self.framer.feed(data):
            out += self.receive_message(item, now)
        return out

    def receive_message(self, msg: MAVLinkMessage | BadFrame, now: float) -> list[Output]:
        """One decoded message (or BadFrame): what `receive` does per frame."""
        verdict, events = self.tracker.handle(msg, now)
        if self.tap and not isinstance(msg, BadFrame):
            self._keep(msg)
        out: list[Output] = [Emit(e) for e in events]
        for e in events:
            if isinstance(e, AutopilotFound | LinkRestored | AutopilotRebooted):
                force = not isinstance(e, LinkRestored)
                out += self._send(self.streams.on_link_up(self._target(), now, force))
            if isinstance(e, AutopilotFound | AutopilotRebooted) and self.settings.read_figures:
                self._figure_values.clear()
                names = FIGURES.get(self.state.vehicle_type, ())
                out += self._read_figures(names, now)
        if verdict is not Verdict.ACCEPTED or isinstance(msg, BadFrame):
            return out
        self.counters.messages_in += 1
        mtype = msg.get_type()
        self.streams.note(mtype, now)
        if mtype in PROTOCOL:
            if not self._addressed_to_us(msg):
                self.counters.not_for_us += 1
                return out
            if mtype == "COMMAND_ACK":
                out += self._send(self.streams.handle_ack(msg, now))
            sent, done = self.runner.handle(msg, self._context(), now)
            out += self._send(sent) + self._complete(done, now)
        elif mtype in RUNNER_WATCHES:
            sent, done = self.runner.handle(msg, self._context(), now)
            out += self._send(sent) + self._complete(done, now)
        return out

    def submit(self, token: int, request: ApRequest, now: float) -> list[Output]:
        """Queue a request; raises plans.InvalidRequest for a malformed one."""
        if isinstance(request, RelayCommand):  # a session's frames the arbiter granted
            if not self.state.link_ok:
                down = ApResult(
                    request.request_id, False, "autopilot link down", error=ApError.LINK_DOWN
                )
                return [Complete(token, down)]
            return [
                *self.relay(request.data),
                Complete(token, ApResult(request.request_id, True, "relayed")),
            ]
        vt = self.tracker.state.vehicle_type
        check_request(request, vt if vt != VehicleType.OTHER else None)
        sent, done = self.runner.submit(token, request, self._context(), now)
        return self._send(sent) + self._complete(done, now)

    def on_timer(self, now: float) -> list[Output]:
        out: list[Output] = []
        out += [Emit(e) for e in self.tracker.on_timer(now)]
        if now >= self._next_heartbeat:
            out += self._send([self._heartbeat()])
            period = self.settings.heartbeat_period_s
            self._next_heartbeat = max(self._next_heartbeat + period, now + period / 2)
        deadline = self.streams.next_deadline()
        if deadline is not None and now >= deadline:
            out += self._send(self.streams.on_timer(now, self.state.link_ok))
        sent, done = self.runner.on_timer(self._context(), now)
        out += self._send(sent) + self._complete(done, now)
        return out

    def next_deadline(self) -> float:
        t = self._next_heartbeat
        for d in (
            self.tracker.next_deadline(),
            self.streams.next_deadline(),
            self.runner.next_deadline(),
        ):
            if d is not None and d < t:
                t = d
        return t

    def close(self, reason: str = "link closed") -> list[Output]:
        """Cancel every pending request (results with ApError.CANCELLED)."""
        return self._complete(self.runner.cancel_all(reason))

    def pending_requests(self) -> int:
        return self.runner.pending()

    # ------------------------------------------------------------------ passthrough

    def relay(self, data: bytes) -> list[Output]:
        """A passthrough session's frames, written to the autopilot as they are."""
        if not data:
            return []
        self.counters.relayed_out += len(data)
        self.counters.bytes_out += len(data)
        return [Transmit(bytes(data), None)]

    def want_rates(self, wishes: Mapping[str, float], now: float) -> list[Output]:
        """Message rates passthrough sessions want (name -> Hz; streams.py `want`)."""
        return self._send(self.streams.want(wishes, now))

    def take_tapped(self) -> bytes:
        """The autopilot's frames kept since the last call (`tap`), as they came."""
        if not self._tapped:
            return b""
        data = b"".join(self._tapped)
        self._tapped.clear()
        return data

    def _keep(self, msg: MAVLinkMessage) -> None:
        sysid = self.state.sysid
        if not sysid or msg.get_srcSystem() != sysid:
            return  # before the autopilot is known, or another system on the link
        if not for_passthrough(msg, self.settings.source_sysid, self.settings.source_compid):
            return
        buf = msg.get_msgbuf()
        if buf:
            self.counters.tapped += 1
            self._tapped.append(bytes(buf))

    # ------------------------------------------------------------------ helpers

    def _target(self) -> tuple[int, int]:
        return (self.state.sysid, self.state.compid)

    def _context(self) -> PlanContext:
        return PlanContext(self.state, self.state.vehicle_type, self.runner.last_goto)

    def _addressed_to_us(self, msg: MAVLinkMessage) -> bool:
        ts = int(getattr(msg, "target_system", 0))
        tc = int(getattr(msg, "target_component", 0))
        return ts in (0, self.settings.source_sysid) and tc in (0, self.settings.source_compid)

    def _heartbeat(self) -> MAVLinkMessage:
        return mavlink.MAVLink_heartbeat_message(
            MAV_TYPE_ONBOARD_CONTROLLER, MAV_AUTOPILOT_INVALID, 0, 0, MAV_STATE_ACTIVE, 3
        )

    def _send(self, messages: list[MAVLinkMessage]) -> list[Output]:
        out: list[Output] = []
        for m in messages:
            data = self.encoder.encode(m)
            self.counters.bytes_out += len(data)
            self.counters.messages_out += 1
            out.append(Transmit(data, m))
        return out

    def _read_figures(self, names: tuple[str, ...], now: float) -> list[Output]:
        out: list[Output] = []
        for name in names:
            token = self._next_figure_token
            self._next_figure_token -= 1
            self._figure_tokens[token] = name
            sent, done = self.runner.submit(token, ReadParam(name=name), self._context(), now)
            out += self._send(sent) + self._complete(done, now)
        return out

    def _figure_read(self, name: str, result: ApResult, now: float | None) -> list[Output]:
        if result.ok and result.value is not None:
            self._figure_values[name] = result.value
            self.tracker.set_figures(**figures_of(self._figure_values))
            return []
        fallback = FALLBACK.get(name)
        if fallback is not None and now is not None and result.error != ApError.CANCELLED:
            return self._read_figures((fallback,), now)
        return []

    def _complete(self, done: list[Finished], now: float | None = None) -> list[Output]:
        out: list[Output] = []
        for f in done:
            name = self._figure_tokens.pop(f.token, None)
            if name is not None:
                out += self._figure_read(name, f.result, now)
                continue
            if f.result.ok and mission_kind_of(f.request) == MissionKind.MISSION:
                # uploads and downloads both carry the items the autopilot now holds
                self.tracker.set_mission_count(len(f.result.items))
            out.append(Complete(f.token, f.result))
        return out


def for_passthrough(msg: MAVLinkMessage, node_sysid: int, node_compid: int) -> bool:
    """Whether a frame from the autopilot goes to passthrough sessions: all but the
    answers to the node's own requests (a COMMAND_ACK, a MISSION_REQUEST of its upload:
    addressed to the node's component alone), which a client would take for its own."""
    ts = getattr(msg, "target_system", None)
    tc = getattr(msg, "target_component", None)
    if ts is None or tc is None:
        return True
    return not (int(ts) == node_sysid and int(tc) == node_compid)
