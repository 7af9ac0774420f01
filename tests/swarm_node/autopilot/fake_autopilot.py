"""A scripted MAVLink peer for the link's unit and property tests: real pymavlink bytes,
ArduPilot's answers to the subset the link uses (HEARTBEAT and a little telemetry,
COMMAND_ACK, PARAM_VALUE echo, the mission protocol server side with its own retries),
and no flight dynamics (the simulator, swarm_sim, flies). Pure and clocked by `now`.
"""

from __future__ import annotations

import random
from collections.abc import Callable
from dataclasses import dataclass, field

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from swarm_node.core.autopilot.framing import MavEncoder, MavFramer
from swarm_node.core.autopilot.link import LinkCore, Output, Transmit

MAV_TYPE = {"copter": 2, "plane": 1, "vtol": 1, "rover": 10, "boat": 11}


@dataclass
class _Server:
    """Mission protocol, autopilot side, for one mission type."""

    items: list = field(default_factory=list)
    receiving: int | None = None  # expected count while receiving
    incoming: list = field(default_factory=list)
    request_deadline: float | None = None
    request_tries: int = 0


class FakeAutopilot:
    def __init__(
        self,
        kind: str = "copter",
        *,
        sysid: int = 1,
        compid: int = 1,
        request_with_int: bool = False,
        ekf_ok: bool = True,
        start_unix_s: float = 1.8e9,
    ) -> None:
        self.kind = kind
        self.enc = MavEncoder(sysid, compid)
        self.framer = MavFramer()
        self.mav_type = MAV_TYPE[kind]
        self.custom_mode = 0
        self.armed = False
        self.ekf_ok = ekf_ok
        self.request_with_int = request_with_int
        self.start_unix_s = start_unix_s
        self.boot_s: float | None = None
        self.lat, self.lon, self.alt_rel = 37.4112, -5.9889, 0.0
        self.home_alt = 10.0
        self.params: dict[str, float] = {"TKOFF_ALT": 50.0}
        self.servers = {0: _Server(), 1: _Server(), 2: _Server()}
        #: command id -> results to answer with, consumed one per received command
        self.ack_script: dict[int, list[int]] = {}
        self.silent_commands: set[int] = set()  # never answered
        self.received: list = []
        self.statustexts: list[tuple[int, str]] = []  # to send before the next ACK
        # to send after it (ArduPilot: the ACK at once, texts from a queue after it)
        self.texts_after_ack: list[tuple[int, str]] = []
        self.answer_heartbeat = True  # REQUEST_MESSAGE(HEARTBEAT) answered
        self.modes_not_taken: set[int] = set()  # DO_SET_MODE accepted, the mode not taken
        self._next_hb = 0.0
        self._next_telemetry = 0.0
        self.telemetry_period_s = 0.1
        self.on_command: Callable[[object], None] | None = None
        self.report_current = True  # MISSION_CURRENT after DO_SET_MISSION_CURRENT

    # ---------------------------------------------------------------- output

    def _pack(self, msg: object) -> bytes:
        return self.enc.encode(msg)

    def _boot_ms(self, now: float) -> int:
        if self.boot_s is None:
            self.boot_s = now
        return int((now - self.boot_s) * 1000)

    def heartbeat(self) -> bytes:
        base = 1 | (128 if self.armed else 0)
        return self._pack(
            mavlink.MAVLink_heartbeat_message(
                self.mav_type, 3, base, self.custom_mode, 4 if self.armed else 3, 3
            )
        )

    def telemetry(self, now: float) -> list[bytes]:
        out = []
        boot = self._boot_ms(now)
        if now >= self._next_hb:
            self._next_hb = now + 1.0
            out.append(self.heartbeat())
        if now >= self._next_telemetry:
            self._next_telemetry = now + self.telemetry_period_s
            out.append(
                self._pack(
                    mavlink.MAVLink_global_position_int_message(
                        boot,
                        round(self.lat * 1e7),
                        round(self.lon * 1e7),
                        round((self.home_alt + self.alt_rel) * 1000),
                        round(self.alt_rel * 1000),
                        0,
                        0,
                        0,
                        9000,
                    )
                )
            )
            out.append(
                self._pack(
                    mavlink.MAVLink_system_time_message(
                        int((self.start_unix_s + boot / 1000) * 1e6), boot
                    )
                )
            )
            out.append(  # a 3-D fix (real ArduPilot has one before its EKF uses GPS)
                self._pack(
                    mavlink.MAVLink_gps_raw_int_message(
                        boot * 1000,
                        3,
                        round(self.lat * 1e7),
                        round(self.lon * 1e7),
                        0,
                        65535,
                        65535,
                        0,
                        0,
                        10,
                    )
                )
            )
            fence = (1 << 20) if self.servers[1].items else 0  # geofence present: loaded
            out.append(
                self._pack(
                    mavlink.MAVLink_sys_status_message(
                        fence, fence, fence, 0, 12000, -1, 80, 0, 0, 0, 0, 0, 0
                    )
                )
            )
            flags = 831 if self.ekf_ok else 1024
            out.append(
                self._pack(
                    mavlink.MAVLink_ekf_status_report_message(flags, 0.1, 0.1, 0.1, 0.1, 0.0)
                )
            )
        out += self._server_timers(now)
        return out

    def next_deadline(self) -> float:
        deadlines = [self._next_hb, self._next_telemetry]
        deadlines += [s.request_deadline for s in self.servers.values() if s.request_deadline]
        return min(deadlines)

    # ---------------------------------------------------------------- input

    def receive(self, data: bytes, now: float) -> list[bytes]:
        out: list[bytes] = []
        for msg in self.framer.feed(data):
            if not hasattr(msg, "get_type"):
                continue
            self.received.append(msg)
            handler = getattr(self, "_on_" + msg.get_type().lower(), None)
            if handler is not None:
                out += handler(msg, now)
        return out

    def _ack(self, command: int, result: int, src: object) -> bytes:
        return self._pack(
            mavlink.MAVLink_command_ack_message(
                command, result, 0, 0, src.get_srcSystem(), src.get_srcComponent()
            )
        )

    def _command(self, msg: object, now: float) -> list[bytes]:
        cmd = int(msg.command)
        if self.on_command is not None:
            self.on_command(msg)
        if cmd in self.silent_commands:
            return []
        script = self.ack_script.get(cmd)
        result = script.pop(0) if script else 0
        out = [
            self._pack(mavlink.MAVLink_statustext_message(sev, text.encode()))
            for sev, text in self.statustexts
        ]
        self.statustexts.clear()
        if result == 0:
            if cmd == 176 and int(msg.param2) not in self.modes_not_taken:
                self.custom_mode = int(msg.param2)
            elif cmd == 400:
                self.armed = msg.param1 == 1.0
            elif cmd == 22:
                self.alt_rel = float(msg.param7 if hasattr(msg, "param7") else msg.z)
            elif cmd == 192 and int(msg.param2) & 1:
                self.custom_mode = 4 if self.kind == "copter" else 15  # GUIDED
        out.append(self._ack(cmd, result, msg))
        out += [
            self._pack(mavlink.MAVLink_statustext_message(sev, text.encode()))
            for sev, text in self.texts_after_ack
        ]
        self.texts_after_ack.clear()
        if result == 0 and cmd == 512 and int(msg.param1) == 0 and self.answer_heartbeat:
            out.append(self.heartbeat())  # REQUEST_MESSAGE HEARTBEAT: at once, as ArduPilot
        if (
            result == 0 and cmd == 224 and self.report_current
        ):  # DO_SET_MISSION_CURRENT: ArduPilot reports it at once
            total = max(0, len(self.servers[0].items) - 1)
            out.append(
                self._pack(mavlink.MAVLink_mission_current_message(int(msg.param1), total, 3, 0))
            )
        return out

    _on_command_long = _command
    _on_command_int = _command

    def _on_param_set(self, msg: object, now: float) -> list[bytes]:
        name = msg.param_id if isinstance(msg.param_id, str) else msg.param_id.decode()
        self.params[name] = float(msg.param_value)
        return [
            self._pack(
                mavlink.MAVLink_param_value_message(
                    name.encode(), float(msg.param_value), 9, len(self.params), 0
                )
            )
        ]

    def _on_param_request_read(self, msg: object, now: float) -> list[bytes]:
        name = msg.param_id if isinstance(msg.param_id, str) else msg.param_id.decode()
        if name not in self.params:
            return []  # ArduPilot does not answer a name it does not have
        return [
            self._pack(
                mavlink.MAVLink_param_value_message(
                    name.encode(), float(self.params[name]), 9, len(self.params), 0
                )
            )
        ]

    # mission protocol, autopilot side
    def _request(self, mtype: int, seq: int, dst: tuple[int, int]) -> bytes:
        cls = (
            mavlink.MAVLink_mission_request_int_message
            if self.request_with_int
            else mavlink.MAVLink_mission_request_message
        )
        return self._pack(cls(dst[0], dst[1], seq, mtype))

    def _on_mission_count(self, msg: object, now: float) -> list[bytes]:
        s = self.servers[msg.mission_type]
        s.receiving = int(msg.count)
        s.incoming = []
        s.peer = (msg.get_srcSystem(), msg.get_srcComponent())  # type: ignore[attr-defined]
        if s.receiving == 0:
            s.items, s.receiving = [], None
            return [self._mission_ack(msg.mission_type, 0, s.peer)]  # type: ignore[attr-defined]
        s.request_deadline, s.request_tries = now + 1.0, 0
        return [self._request(msg.mission_type, 0, s.peer)]  # type: ignore[attr-defined]

    def _on_mission_item_int(self, msg: object, now: float) -> list[bytes]:
        s = self.servers[msg.mission_type]
        peer = (msg.get_srcSystem(), msg.get_srcComponent())
        if s.receiving is None:
            if s.items and msg.seq == len(s.items) - 1:
                return [self._mission_ack(msg.mission_type, 0, peer)]  # ACK lost: again
            return []
        if msg.seq != len(s.incoming):
            return [self._request(msg.mission_type, len(s.incoming), peer)]
        s.incoming.append(msg)
        if len(s.incoming) == s.receiving:
            s.items, s.receiving, s.request_deadline = list(s.incoming), None, None
            return [self._mission_ack(msg.mission_type, 0, peer)]
        s.request_deadline, s.request_tries = now + 1.0, 0
        return [self._request(msg.mission_type, len(s.incoming), peer)]

    def _server_timers(self, now: float) -> list[bytes]:
        out = []
        for mtype, s in self.servers.items():
            if s.request_deadline is not None and now >= s.request_deadline:
                s.request_tries += 1
                if s.request_tries > 5:
                    s.receiving, s.request_deadline = None, None
                    continue
                s.request_deadline = now + 1.0
                out.append(self._request(mtype, len(s.incoming), s.peer))  # type: ignore[attr-defined]
        return out

    def _mission_ack(self, mtype: int, code: int, dst: tuple[int, int]) -> bytes:
        return self._pack(mavlink.MAVLink_mission_ack_message(dst[0], dst[1], code, mtype))

    def _on_mission_clear_all(self, msg: object, now: float) -> list[bytes]:
        self.servers[msg.mission_type].items = []
        return [
            self._mission_ack(msg.mission_type, 0, (msg.get_srcSystem(), msg.get_srcComponent()))
        ]

    def _on_mission_request_list(self, msg: object, now: float) -> list[bytes]:
        s = self.servers[msg.mission_type]
        return [
            self._pack(
                mavlink.MAVLink_mission_count_message(
                    msg.get_srcSystem(), msg.get_srcComponent(), len(s.items), msg.mission_type
                )
            )
        ]

    def _on_mission_request_int(self, msg: object, now: float) -> list[bytes]:
        s = self.servers[msg.mission_type]
        if not 0 <= msg.seq < len(s.items):
            return []
        it = s.items[msg.seq]
        return [
            self._pack(
                mavlink.MAVLink_mission_item_int_message(
                    msg.get_srcSystem(),
                    msg.get_srcComponent(),
                    it.seq,
                    it.frame,
                    it.command,
                    it.current,
                    it.autocontinue,
                    it.param1,
                    it.param2,
                    it.param3,
                    it.param4,
                    it.x,
                    it.y,
                    it.z,
                    it.mission_type,
                )
            )
        ]

    _on_mission_request = _on_mission_request_int


class Harness:
    """Joins a LinkCore and a FakeAutopilot, drops packets at random both ways (seeded),
    and runs by jumping a manual time to the next deadline."""

    def __init__(
        self,
        core: LinkCore,
        fake: FakeAutopilot,
        *,
        loss: float = 0.0,
        seed: int = 0,
        now: float = 1000.0,
    ) -> None:
        self.core = core
        self.fake = fake
        self.loss = loss
        self.rng = random.Random(seed)
        self.now = now
        self.outputs: list[Output] = []
        self.sent: list = []  # what the link transmitted (decoded messages)
        self.down = False  # True: nothing crosses, both ways

    def _deliver_to_fake(self, outputs: list[Output]) -> list[bytes]:
        replies: list[bytes] = []
        for o in outputs:
            self.outputs.append(o)
            if isinstance(o, Transmit):
                self.sent.append(o.message)
                if self.down or self.rng.random() < self.loss:
                    continue
                replies += self.fake.receive(o.data, self.now)
        return replies

    def _deliver_to_core(self, packets: list[bytes]) -> None:
        while packets:
            back: list[Output] = []
            for p in packets:
                if self.down or self.rng.random() < self.loss:
                    continue
                back += self.core.receive(p, self.now)
            packets = self._deliver_to_fake(back)

    def submit(self, token: int, request: object) -> None:
        self._deliver_to_core(self._deliver_to_fake(self.core.submit(token, request, self.now)))

    def step(self) -> None:
        self.now = max(self.now, min(self.core.next_deadline(), self.fake.next_deadline()))
        self._deliver_to_core(self.fake.telemetry(self.now))
        if self.now >= self.core.next_deadline():
            self._deliver_to_core(self._deliver_to_fake(self.core.on_timer(self.now)))

    def run_until(self, predicate: Callable[[], bool], max_s: float = 600.0) -> bool:
        end = self.now + max_s
        while self.now < end:
            if predicate():
                return True
            self.step()
        return predicate()

    def results(self) -> dict:
        from swarm_node.core.autopilot.link import Complete

        return {o.token: o.result for o in self.outputs if isinstance(o, Complete)}

    def run_request(self, token: int, request: object, max_s: float = 600.0):
        self.submit(token, request)
        self.run_until(lambda: token in self.results(), max_s)
        return self.results().get(token)
