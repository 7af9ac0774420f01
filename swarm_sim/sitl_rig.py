"""What `make sitl-check` (sitl_check.py) and `make sitl-fleet` (sitl_fleet.py) share:
ArduPilot SITL (or swarm-sim) vehicles started from `ARDUPILOT_SITL_BIN` with the
ArduPilot tree's default parameter files, a Zenoh router, one `swarm-node run` per
vehicle, the ground station library, and what ArduPilot itself says on ports of its
own: an `Observer` on each SITL's SERIAL1 (tcp 5760+10*I+2: HEARTBEAT, GLOBAL_POSITION_INT
at 10 Hz, SYS_STATUS, STATUSTEXT) and a `Downloader` on SERIAL2 (+3: mission, fence and
rally items; parameters). Every figure the checks give comes from these, never from
the nodes' telemetry.

`--sim` runs the same against swarm-sim vehicles (the simulator accepts several
clients on one port, so the observer and downloader use the vehicle's port).
"""

from __future__ import annotations

import argparse
import contextlib
import os
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from rich.console import Console

from gcs_cli.ground import GroundStation
from swarm_proto import AlertCode, CommandArgs, CommandKind, Selector, VehicleType, geodesy
from swarm_proto.clock import Clock, SystemClock, clock_from_spec
from swarm_proto.session import ZenohSettings

HOME = (37.4112, -5.9889, 10.0, 0.0)  # lat, lon, alt MSL, heading: as the recordings
SWARM = "sitl"
GEOFENCE_BIT = 1 << 20  # MAV_SYS_STATUS_GEOFENCE

offset = geodesy.offset  # the one geodesy (swarm_proto.geodesy)
distance_m = geodesy.distance_m


def opt(x: float | None, fmt: str, none: str) -> str:
    return none if x is None else fmt.format(x)


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def wait_port_free(port: int, timeout_s: float = 90.0) -> None:
    """SITL binds its ports without SO_REUSEADDR: a port a previous run closed is in
    TIME_WAIT for up to a minute and SITL exits ("bind failed"). Wait for it."""
    end = time.monotonic() + timeout_s
    while True:
        with socket.socket() as s:
            try:
                s.bind(("0.0.0.0", port))
                return
            except OSError:
                if time.monotonic() >= end:
                    raise SystemExit(
                        f"tcp port {port} stays in use: another SITL? (--first-instance)"
                    ) from None
        time.sleep(1.0)


@dataclass(frozen=True)
class VehicleSpec:
    kind: str  # "copter" / "quadplane"
    node_id: int  # the seed database's system (7-9: quadcopters, 1-6: Albatross VTOLs)
    instance: int
    binary: str
    model: str
    parm: str
    vehicle_type: VehicleType
    sim_model: str
    home_east_m: float = 0.0
    home_north_m: float = 0.0
    # parameters beyond the default file (a user's own parm file would carry them)
    extra_params: Mapping[str, float] = field(default_factory=dict)

    @property
    def port(self) -> int:
        return 5760 + 10 * self.instance

    @property
    def name(self) -> str:
        return f"{self.kind} {self.node_id}"


# the copter's default 3.3 Ah battery drains in a few minutes of SITL (behaviours.md)
COPTER_EXTRA: Mapping[str, float] = {"BATT_CAPACITY": 20000}


def copter(node_id: int, instance: int, **kw: Any) -> VehicleSpec:
    kw.setdefault("extra_params", COPTER_EXTRA)
    return VehicleSpec(
        "copter",
        node_id,
        instance,
        "arducopter",
        "+",
        "copter.parm",
        VehicleType.COPTER,
        "copter",
        **kw,
    )


def quadplane(node_id: int, instance: int, **kw: Any) -> VehicleSpec:
    return VehicleSpec(
        "quadplane",
        node_id,
        instance,
        "arduplane",
        "quadplane",
        "quadplane.parm",
        VehicleType.VTOL,
        "vtol",
        **kw,
    )


# --------------------------------------------------------------------------- MAVLink


@dataclass
class Sample:
    t: float  # wall, monotonic
    lat: float
    lon: float
    alt_rel: float
    alt_msl: float = 0.0
    armed: bool = False


class Observer:
    """What ArduPilot itself says, on a MAVLink port of its own: HEARTBEAT (mode, armed),
    GLOBAL_POSITION_INT at 10 Hz, SYS_STATUS (fence enabled), STATUSTEXT. It can also
    command the autopilot directly, as an operator's ground station would (`set_mode`)."""

    def __init__(self, url: str) -> None:
        from pymavlink import mavutil

        self.conn: Any = mavutil.mavlink_connection(
            url, source_system=250, source_component=191, retries=60
        )
        self.lock = threading.Lock()
        self.track: list[Sample] = []
        self.mode = -1
        self.modes: list[tuple[float, int]] = []  # (wall, custom_mode) at each change
        self.armed = False
        self.fence_enabled_at: float | None = None
        self.fence_enabled = False
        self.texts: list[tuple[float, str]] = []
        self.last_heard = 0.0
        self.version = ""
        self.boot_ms: list[tuple[float, int]] = []  # (wall, time_boot_ms): SITL's own rate
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True, name=f"observer-{url}")
        self._thread.start()

    def _run(self) -> None:
        asked = 0.0
        while not self._stop.is_set():
            try:
                msg = self.conn.recv_match(blocking=True, timeout=0.3)
            except Exception:  # SITL gone (or frozen and the socket reset)
                time.sleep(0.2)
                continue
            now = time.monotonic()
            if now - asked > 5.0 and getattr(self.conn, "target_system", None):
                asked = now
                with contextlib.suppress(Exception):
                    self._ask_streams()
            if msg is None:
                continue
            kind = msg.get_type()
            if msg.get_srcComponent() != 1:
                continue  # the autopilot's messages only
            with self.lock:
                self.last_heard = now
                if kind == "HEARTBEAT" and msg.type != 6:
                    if int(msg.custom_mode) != self.mode:
                        self.modes.append((now, int(msg.custom_mode)))
                    self.mode = int(msg.custom_mode)
                    self.armed = bool(msg.base_mode & 128)
                elif kind == "GLOBAL_POSITION_INT":
                    self.track.append(
                        Sample(
                            now,
                            msg.lat / 1e7,
                            msg.lon / 1e7,
                            msg.relative_alt / 1000.0,
                            msg.alt / 1000.0,
                            self.armed,
                        )
                    )
                    if not self.boot_ms or now - self.boot_ms[-1][0] >= 1.0:
                        self.boot_ms.append((now, int(msg.time_boot_ms)))
                elif kind == "SYS_STATUS":
                    on = bool(msg.onboard_control_sensors_enabled & GEOFENCE_BIT)
                    if on and not self.fence_enabled:
                        self.fence_enabled_at = now
                    self.fence_enabled = on
                elif kind == "AUTOPILOT_VERSION" and not self.version:
                    v = int(msg.flight_sw_version)
                    kinds = {0: "dev", 64: "alpha", 128: "beta", 192: "rc", 255: "official"}
                    raw = bytes(msg.flight_custom_version)
                    git = raw.decode("ascii") if raw.isascii() and raw.isalnum() else raw.hex()
                    self.version = (
                        f"{v >> 24 & 255}.{v >> 16 & 255}.{v >> 8 & 255}-"
                        f"{kinds.get(v & 255, v & 255)} ({git})"
                    )
                elif kind == "STATUSTEXT":
                    text = str(msg.text)
                    self.texts.append((now, text))
                    if text.startswith(("ArduCopter V", "ArduPlane V")) and not self.version:
                        self.version = text

    def _ask_streams(self) -> None:
        ts, tc = self.conn.target_system, 1
        if not self.version:  # MAV_CMD_REQUEST_MESSAGE AUTOPILOT_VERSION
            self.conn.mav.command_long_send(ts, tc, 512, 0, 148, 0, 0, 0, 0, 0, 0)
        for msg_id, hz in ((33, 10.0), (1, 2.0), (0, 1.0)):  # GLOBAL_POSITION_INT, SYS_STATUS, HB
            self.conn.mav.command_long_send(ts, tc, 511, 0, msg_id, 1e6 / hz, 0, 0, 0, 0, 0)
        self.conn.mav.heartbeat_send(6, 8, 0, 0, 0)

    def set_mode(self, number: int) -> None:
        """DO_SET_MODE straight to the autopilot (an operator's own ground station)."""
        ts = getattr(self.conn, "target_system", None) or 1
        self.conn.mav.command_long_send(ts, 1, 176, 0, 1, float(number), 0, 0, 0, 0, 0)

    def here(self) -> Sample | None:
        with self.lock:
            return self.track[-1] if self.track else None

    def since(self, t0: float) -> list[Sample]:
        with self.lock:
            return [s for s in self.track if s.t >= t0]

    def speedup(self) -> float | None:
        """SITL's own time against the wall clock, over what was observed (None: too
        little): whether it kept the speed-up it was asked for."""
        with self.lock:
            if len(self.boot_ms) < 10:
                return None
            (w0, b0), (w1, b1) = self.boot_ms[0], self.boot_ms[-1]
        return (b1 - b0) / 1000.0 / (w1 - w0) if w1 > w0 else None

    def close(self) -> None:
        self._stop.set()
        self._thread.join(2.0)
        with contextlib.suppress(Exception):
            self.conn.close()


class Downloader:
    """Reads ArduPilot's mission, fence or rally items on a MAVLink port of its own."""

    def __init__(self, url: str) -> None:
        from pymavlink import mavutil

        self.conn: Any = mavutil.mavlink_connection(
            url, source_system=251, source_component=191, retries=60
        )

    def download(self, mission_type: int, timeout_s: float = 15.0) -> list[Any] | None:
        c = self.conn
        if not getattr(c, "target_system", None) and c.wait_heartbeat(timeout=timeout_s) is None:
            return None
        ts = c.target_system
        end = time.monotonic() + timeout_s
        while c.recv_match(blocking=False) is not None:  # drain
            pass
        count = None
        while count is None and time.monotonic() < end:
            c.mav.mission_request_list_send(ts, 1, mission_type)
            m = c.recv_match(type="MISSION_COUNT", blocking=True, timeout=1.0)
            if m is not None and m.mission_type == mission_type:
                count = m.count
        if count is None:
            return None
        items: list[Any] = []
        while len(items) < count and time.monotonic() < end:
            c.mav.mission_request_int_send(ts, 1, len(items), mission_type)
            m = c.recv_match(type="MISSION_ITEM_INT", blocking=True, timeout=1.0)
            if m is not None and m.mission_type == mission_type and m.seq == len(items):
                items.append(m)
        c.mav.mission_ack_send(ts, 1, 0, mission_type)
        return items if len(items) == count else None

    def set_param(self, name: str, value: float, timeout_s: float = 15.0) -> bool:
        c = self.conn
        if not getattr(c, "target_system", None) and c.wait_heartbeat(timeout=timeout_s) is None:
            return False
        end = time.monotonic() + timeout_s
        while time.monotonic() < end:
            c.mav.param_set_send(c.target_system, 1, name.encode(), float(value), 9)
            m = c.recv_match(type="PARAM_VALUE", blocking=True, timeout=1.0)
            if m is not None and m.param_id == name and abs(m.param_value - value) < 1e-3:
                return True
        return False

    def close(self) -> None:
        with contextlib.suppress(Exception):
            self.conn.close()


# --------------------------------------------------------------------------- processes


@dataclass
class Vehicle:
    """One vehicle of the rig: its SITL (or swarm-sim) process, its node, the ports of
    its own ArduPilot is read on."""

    spec: VehicleSpec
    proc: subprocess.Popen[bytes]
    home: tuple[float, float]
    node: subprocess.Popen[bytes] | None = None
    observer: Observer | None = None
    downloader: Downloader | None = None


class Rig:
    """Starts and stops the processes; the ground station; helpers the checks share.
    `args`: `bin`, `sim`, `speedup`; `clock`: a BANDADA_CLOCK spec the nodes (and
    swarm-sim vehicles) run on ("" = the system clock)."""

    prefix = "bandada-sitl-"

    def __init__(self, args: argparse.Namespace, console: Console, clock: str = "") -> None:
        self.args = args
        self.console = console
        self.clock = clock
        self.node_clock: Clock = clock_from_spec(clock) if clock else SystemClock()
        self.tmp = Path(tempfile.mkdtemp(prefix=self.prefix))
        self.procs: list[subprocess.Popen[bytes]] = []
        self.router_port = free_port()
        self.gs: GroundStation | None = None

    def log(self, text: str) -> None:
        self.console.print(f"[bold cyan]>[/] {text}")

    def spawn(self, cmd: list[str], name: str, cwd: Path | None = None) -> subprocess.Popen[bytes]:
        out = open(self.tmp / f"{name}.log", "ab")  # noqa: SIM115
        env = {**os.environ, "PYTHONUNBUFFERED": "1"}
        env.pop("BANDADA_CLOCK", None)
        if self.clock:
            env["BANDADA_CLOCK"] = self.clock
        p = subprocess.Popen(
            cmd,
            stdout=out,
            stderr=subprocess.STDOUT,
            cwd=cwd or self.tmp,
            env=env,
            start_new_session=True,
        )
        self.procs.append(p)
        return p

    def defaults_dir(self) -> Path:
        home = os.environ.get("ARDUPILOT_HOME")
        if home:
            return Path(home) / "Tools" / "autotest" / "default_params"
        return Path(self.args.bin).resolve().parent.parent.parent / "Tools/autotest/default_params"

    def start_router(self) -> None:
        self.log(f"router on tcp/127.0.0.1:{self.router_port}; logs in {self.tmp}")
        self.spawn(
            [
                sys.executable,
                "-m",
                "swarm_node.cli",
                "router",
                "--listen",
                f"tcp/127.0.0.1:{self.router_port}",
            ],
            "router",
        )

    def start_vehicle(self, spec: VehicleSpec, what: str = "") -> Vehicle:
        lat, lon = offset(HOME[0], HOME[1], spec.home_north_m, spec.home_east_m)
        home = f"{lat:.7f},{lon:.7f},{HOME[2]:g},{HOME[3]:g}"
        name = what or spec.kind
        if self.args.sim:
            cmd = [
                sys.executable,
                "-c",
                "from swarm_sim.cli import main; main()",
                "vehicle",
                "--model",
                spec.sim_model,
                "--instance",
                str(spec.instance),
                "--sysid",  # the database's mav_sysid: the node checks it
                str(spec.node_id),
                "--speedup",
                str(self.args.speedup),
                "--home",
                home,
            ]
            self.log(f"swarm-sim {spec.sim_model} -I{spec.instance} on tcp:127.0.0.1:{spec.port}")
            proc = self.spawn(cmd, f"sim-{name}")
        else:
            binary = Path(self.args.bin) / spec.binary
            if not binary.is_file():
                raise SystemExit(f"{binary} not found (ARDUPILOT_SITL_BIN)")
            parm = self.defaults_dir() / spec.parm
            if not parm.is_file():
                raise SystemExit(f"{parm} not found (set ARDUPILOT_HOME)")
            defaults = [str(parm)]
            if spec.extra_params:
                path = self.tmp / f"{name}-extra.parm"
                path.write_text("".join(f"{k} {v}\n" for k, v in spec.extra_params.items()))
                defaults.append(str(path))
            for port in (spec.port, spec.port + 2, spec.port + 3):
                wait_port_free(port)
            wd = self.tmp / f"sitl-{name}"
            wd.mkdir(exist_ok=True)
            cmd = [
                str(binary),
                "--model",
                spec.model,
                "--speedup",
                str(self.args.speedup),
                f"-I{spec.instance}",
                # the node's id as the autopilot's MAVLink system id (MAV_SYSID on
                # master, SYSID_THISMAV before), which the node checks
                "--sysid",
                str(spec.node_id),
                "-w",
                "--defaults",
                ",".join(defaults),
                "--home",
                home,
            ]
            self.log(f"SITL {spec.binary} -I{spec.instance} on tcp:127.0.0.1:{spec.port}")
            proc = self.spawn(cmd, f"sitl-{name}", cwd=wd)
        return Vehicle(spec, proc, home=(lat, lon))

    def attach(self, v: Vehicle) -> None:
        """The observer (SERIAL1) and the downloader (SERIAL2) of a started vehicle; in
        the simulator its extra parameters are set here (SITL reads them from a file)."""
        p = v.spec.port
        obs, dl = (p, p) if self.args.sim else (p + 2, p + 3)
        v.observer = Observer(f"tcp:127.0.0.1:{obs}")
        v.downloader = Downloader(f"tcp:127.0.0.1:{dl}")
        if self.args.sim:
            for name, value in v.spec.extra_params.items():
                v.downloader.set_param(name, value)

    def start_node(self, v: Vehicle) -> None:
        s = v.spec
        v.node = self.spawn(
            [
                sys.executable,
                "-m",
                "swarm_node.cli",
                "run",
                "--id",
                str(s.node_id),
                "--autopilot",
                f"tcp:127.0.0.1:{s.port}",
                "--swarm",
                SWARM,
                "--db",
                str(self.tmp / f"node{s.node_id}.db"),
                "--connect",
                f"tcp/127.0.0.1:{self.router_port}",
                "--mode",
                "client",
            ],
            f"node{s.node_id}",
        )

    def connect_ground(self) -> None:
        # nodes and ground station are clients of the router, as in the demo
        self.gs = GroundStation(
            ZenohSettings(mode="client", connect=(f"tcp/127.0.0.1:{self.router_port}",)), SWARM
        )

    def close_vehicles(self, vehicles: list[Vehicle]) -> None:
        if self.gs is not None:
            self.gs.close()
            self.gs = None
        for v in vehicles:
            if v.observer is not None:
                v.observer.close()
                self.save_observed(v)
            if v.downloader is not None:
                v.downloader.close()
        for p in reversed(self.procs):  # nodes before SITL, the router last
            if p.poll() is None:
                with contextlib.suppress(ProcessLookupError):
                    os.kill(p.pid, signal.SIGCONT)
                    p.send_signal(signal.SIGINT)
        for p in reversed(self.procs):
            try:
                p.wait(10)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()

    def save_observed(self, v: Vehicle) -> None:
        """What ArduPilot said, into the logs directory: its track (CSV: wall seconds,
        lat, lon, alt above home, alt MSL, armed) and its STATUSTEXTs."""
        obs = v.observer
        if obs is None:
            return
        name = f"{v.spec.kind}{v.spec.node_id}"
        with obs.lock:
            track, texts = list(obs.track), list(obs.texts)
        rows = [
            f"{s.t:.2f},{s.lat:.7f},{s.lon:.7f},{s.alt_rel:.2f},{s.alt_msl:.2f},{int(s.armed)}"
            for s in track
        ]
        (self.tmp / f"track-{name}.csv").write_text(
            "t,lat,lon,alt_rel,alt_msl,armed\n" + "\n".join(rows) + "\n"
        )
        (self.tmp / f"texts-{name}.log").write_text("".join(f"{t:.2f} {x}\n" for t, x in texts))

    # ----------------------------------------------------------------- helpers
    @property
    def ground(self) -> GroundStation:
        assert self.gs is not None
        return self.gs

    def wait(self, pred: Callable[[], bool], timeout_s: float, period: float = 0.2) -> bool:
        end = time.monotonic() + timeout_s
        while time.monotonic() < end:
            if pred():
                return True
            time.sleep(period)
        return pred()

    def node_now(self) -> float:
        """The nodes' clock now (what their alerts are stamped with)."""
        return self.node_clock.now()

    def alerts(self, vid: int, code: AlertCode, since_unix: float) -> list[Any]:
        view = self.ground.snapshot()
        return [
            a
            for a in view.alerts
            if a.vehicle_id == vid and a.code == code and a.time_unix_s >= since_unix
        ]

    def command_ids(self, kind: CommandKind, vid: int, **args: Any) -> tuple[bool, str]:
        acks = self.ground.command(kind, Selector.ids(vid), CommandArgs(**args), timeout_s=15.0)
        if not acks:
            return False, f"{kind.name}: no answer"
        a = acks[0]
        return a.accepted, f"{kind.name}: {a.reason.name} {a.text}".strip()
