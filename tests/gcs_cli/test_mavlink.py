"""`gcs mavlink` (gcs_cli/mavlink.py, gcs_cli/core/mavlink_session.py): the session
core pure, and MAVProxy attached through it to a simulated vehicle flying a swarm
mission over real processes (the demo's harness: simulator, router and nodes, 5x)."""

from __future__ import annotations

import os
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import msgspec
import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink
from rich.console import Console

from gcs_cli.core.mavlink_session import (
    Announce,
    Command,
    Down,
    Listen,
    RadioSessionCore,
    SessionCore,
    Up,
)
from gcs_cli.ground import GroundStation
from swarm_proto import (
    AlertCode,
    CommandArgs,
    CommandKind,
    FsmState,
    Geometry,
    GeoPoint,
    Mission,
    MissionParams,
    MissionState,
    MissionType,
    NoFlyZone,
    Selector,
)
from swarm_proto.messages import MavlinkCommand, MavlinkSession
from swarm_proto.session import ZenohSettings
from swarm_sim.core import SITL_HOME
from swarm_sim.demo import start, stop
from tests.swarm_sim.test_fast_fleet import square
from tests.swarm_sim.test_mavproxy import mavproxy_path

CLIENT = mavlink.MAVLink(None, srcSystem=255, srcComponent=190)


def free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def heartbeat() -> bytes:
    return bytes(mavlink.MAVLink_heartbeat_message(6, 8, 0, 0, 4, 3).pack(CLIENT))


def core(**kw: object) -> SessionCore:
    ids = iter(range(1, 100))
    return SessionCore(7, 900, lambda: next(ids), **kw)  # type: ignore[arg-type]


# ----------------------------------------------------------------------- the core
def test_a_session_opens_when_the_client_speaks_and_ends_when_it_is_silent() -> None:
    c = core(client_timeout_s=10.0)
    assert c.start(0.0) == [] and c.next_deadline() is None
    out = c.on_client(heartbeat(), 1.0)
    assert out == [Listen(1), Announce(MavlinkSession(7, 1, 900)), Up(heartbeat())]
    assert c.on_vehicle(1, b"\xfdabc") == [Down(b"\xfdabc")]
    assert c.on_vehicle(2, b"\xfdold") == [] and c.counts["stale_down"] == 1
    assert c.on_timer(2.0) == [Announce(MavlinkSession(7, 1, 900))]  # every second
    assert c.next_deadline() == 3.0
    out = c.on_timer(11.0)  # 10 s without a byte from the client
    assert out == [Announce(MavlinkSession(7, 1, 900, closing=True)), Listen(None)]
    assert c.on_vehicle(1, b"\xfdlate") == []  # nothing for a session that ended
    assert c.on_client(heartbeat(), 12.0)[:2] == [Listen(2), Announce(MavlinkSession(7, 2, 900))]


def test_malformed_bytes_are_dropped_and_counted_and_whole_frames_go_on() -> None:
    c = core(read_only=True)
    out = c.on_client(b"\x00\x01junk" + heartbeat() + b"\xfd\x05", 0.0)
    assert out[-1] == Up(heartbeat())
    assert out[1] == Announce(MavlinkSession(7, 1, 900, read_only=True))
    assert c.counts["malformed"] == 1 and c.counts["frames_up"] == 1
    assert c.close() == [Announce(MavlinkSession(7, 1, 900, True, True)), Listen(None)]


def test_an_endpoint_that_speaks_first_is_open_from_the_start_and_never_times_out() -> None:
    c = core(listens=False)
    assert c.start(0.0) == [Listen(1), Announce(MavlinkSession(7, 1, 900))]
    assert c.on_timer(100.0) == [Announce(MavlinkSession(7, 1, 900))]


def test_a_radio_session_sends_commands_only_and_makes_heartbeats_from_the_summary() -> None:
    from swarm_node.core.autopilot.framing import MavFramer
    from swarm_node.core.autopilot.state import AutopilotState
    from swarm_node.core.passthrough import high_latency2
    from swarm_proto import VehicleType

    r = RadioSessionCore(7, 900)
    assert r.start(0.0) == [Command(MavlinkCommand(900, 7))]  # the keep-alive
    assert r.next_deadline() == 20.0
    ap = AutopilotState(sysid=7, compid=1, vehicle_type=VehicleType.COPTER, mav_type=2)
    ap_mav = mavlink.MAVLink(None, srcSystem=7, srcComponent=1)
    armed = high_latency2(msgspec.structs.replace(ap, armed=True, mode_number=5))
    summary = bytes(armed.pack(ap_mav))
    out = r.on_summary(summary, 1.0)
    assert out[0] == Down(summary)
    (hb,) = MavFramer().feed(out[1].data)  # type: ignore[union-attr]
    assert hb.get_type() == "HEARTBEAT" and hb.custom_mode == 5 and hb.base_mode & 128
    assert hb.get_srcSystem() == 7  # from the autopilot's ids
    assert [type(a) for a in r.on_timer(2.0)] == [Down]  # a heartbeat every second
    mode = bytes(mavlink.MAVLink_set_mode_message(7, 1, 4).pack(CLIENT))
    assert r.on_client(heartbeat() + mode, 2.5) == [Command(MavlinkCommand(900, 7, mode))]
    (soon,) = r.on_client(mode, 3.0)  # one command per 2 s on the air
    ack, text = MavFramer().feed(soon.data)  # type: ignore[union-attr]
    assert ack.result == mavlink.MAV_RESULT_TEMPORARILY_REJECTED and "one command" in text.text
    params = bytes(mavlink.MAVLink_param_request_list_message(7, 1).pack(CLIENT))
    (told,) = r.on_client(params, 4.0)
    assert MavFramer().feed(told.data)[0].text == "bandada: not on the radio: PARAM_REQUEST_LIST"  # type: ignore[union-attr]
    assert r.on_client(params, 5.0) == []  # told once in 30 s
    assert r.counts["not_on_the_radio"] == 2 and r.counts["commands"] == 1


@pytest.mark.parametrize(
    "argv, named",
    [
        (["mavlink"], "--id"),
        (["mavlink", "--id", "7", "--all"], "--id"),
        (["mavlink", "--id", "7", "--serve", "nonsense:x"], "--serve"),
        (["mavlink", "--id", "7", "--serve", "/dev/ttyUSB0"], "--serve"),
        (["mavlink", "--id", "7", "--radio", "--read-only"], "--radio"),
        (["mavlink", "--id", "0"], "--id"),
    ],
)
def test_bad_options_are_one_line_and_nothing_is_opened(
    argv: list[str], named: str, capsys: pytest.CaptureFixture[str]
) -> None:
    from gcs_cli.app import run

    assert run(["--connect", "tcp/127.0.0.1:9", *argv]) == 2  # no router there: not asked
    err = capsys.readouterr().err
    assert named in err and err.count("\n") == 1, err


# ----------------------------------------------------------------------- real processes
class MavProxy:
    """MAVProxy on stdin/stdout, its lines collected."""

    def __init__(self, port: int, tmp: Path) -> None:
        tmp.mkdir(exist_ok=True)
        self.proc = subprocess.Popen(
            [
                *(sys.executable, mavproxy_path(), "--master", f"udpout:127.0.0.1:{port}"),
                *("--state-basedir", str(tmp)),
            ],
            cwd=tmp,
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
        )
        self.lines: list[str] = []
        out = self.proc.stdout
        assert out is not None
        self.reader = threading.Thread(
            target=lambda: self.lines.extend(iter(out.readline, "")), daemon=True
        )
        self.reader.start()

    def send(self, command: str) -> None:
        assert self.proc.stdin is not None
        self.proc.stdin.write(command + "\n")
        self.proc.stdin.flush()

    def saw(self, text: str, timeout: float) -> bool:
        return wait(lambda: any(text in ln for ln in self.lines), timeout)

    @property
    def out(self) -> str:
        return "".join(self.lines)

    def close(self) -> None:
        if self.proc.stdin is not None:
            self.proc.stdin.close()  # MAVProxy exits at the end of its input
        try:
            self.proc.wait(timeout=15)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
        self.reader.join(timeout=5)


def wait(predicate: object, timeout: float) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():  # type: ignore[operator]
            return True
        time.sleep(0.1)
    return False


def gcs_mavlink(
    endpoint: str, vid: int, port: int, log: Path, clock: str, *extra: str
) -> subprocess.Popen[bytes]:
    cmd = [sys.executable, "-m", "gcs_cli.app", "--connect", endpoint, "mavlink"]
    cmd += ["--id", str(vid), "--serve", f"udp:127.0.0.1:{port}", *extra]
    env = {**os.environ, "BANDADA_CLOCK": clock}  # the swarm's clock: sessions timed on it
    return subprocess.Popen(cmd, stdout=open(log, "wb"), stderr=subprocess.STDOUT, env=env)


@pytest.mark.network
@pytest.mark.timeout(400)
def test_mavproxy_through_gcs_mavlink_reads_downloads_and_its_mode_change_leaves_the_fleet(
    tmp_path: Path, swarm_db: Path
) -> None:
    """Two quadcopters fly an area together behind a no-fly zone. MAVProxy, attached
    through `gcs mavlink` to 7, fetches the parameters, shows one, downloads the
    mission and the fence; its mode change takes 7 out of its fleet with an alert and 8
    replans alone. Then, attached read-only to 8, the same mode change is refused."""
    members = (7, 8)
    fleet = start(members, 5.0, tmp_path, Console(file=open(os.devnull, "w")))  # noqa: SIM115
    gs = GroundStation(ZenohSettings(connect=(fleet.endpoint,)), gcs_id=901)
    procs: list[subprocess.Popen[bytes]] = []
    proxies: list[MavProxy] = []
    try:
        assert gs.wait_for(
            lambda v: all(
                i in v.info
                and v.info[i].home is not None
                and i in v.status
                and v.status[i].gps_fix >= 3
                for i in members
            ),
            120,
        )
        lat, lon = SITL_HOME.lat_deg, SITL_HOME.lon_deg
        gs.zone(NoFlyZone(5, Geometry.circle(lat - 0.002, lon, 30.0), issuer_id=901))
        base = GeoPoint(lat, lon, SITL_HOME.alt_m)
        gs.command(CommandKind.SET_BASE, Selector(), CommandArgs(point=base), timeout_s=10.0)
        assert gs.wait_for(
            lambda v: all(v.fsm_state(i) == FsmState.GO_MISSION for i in members), 60
        )
        area = square(lat + 0.0012, lon, 60.0)
        acks = gs.mission(
            Mission(
                91,
                901,
                MissionType.AREA,
                area,
                MissionParams(altitude_rel_m=20.0),
                Selector.ids(*members),
            ),
            timeout_s=10.0,
        )
        assert sorted(a.vehicle_id for a in acks if a.accepted) == [7, 8]
        port = free_udp_port()
        procs.append(gcs_mavlink(fleet.endpoint, 7, port, tmp_path / "gcs-7.log", fleet.clock_spec))
        mp = MavProxy(port, tmp_path / "mavproxy-7")
        proxies.append(mp)
        assert mp.saw("online system 7", 60), mp.out
        assert mp.saw("Received", 60) and "parameters" in mp.out, mp.out
        mp.send("param show WPNAV_SPEED")
        assert mp.saw("WPNAV_SPEED", 20), mp.out
        assert gs.wait_for(
            lambda v: all(v.status[i].mission_state == MissionState.MISSION for i in members), 120
        )
        mp.send("wp list")
        assert mp.saw("waypoints to", 30), mp.out
        saved = next(ln for ln in mp.lines if "waypoints to" in ln and ln.startswith("Saved"))
        assert int(saved.split()[1]) > 2, saved  # the share 7 flies: home, take-off, its lanes
        mp.send("fence list")
        assert mp.saw("fence items", 30), mp.out
        requested = next(ln for ln in mp.lines if "fence items" in ln)
        assert "Requesting 1 fence items" in requested, requested  # the zone, a circle
        mp.send("mode LOITER")
        assert mp.saw("DO_SET_MODE: ACCEPTED", 30), mp.out
        assert gs.wait_for(
            lambda v: any(
                a.vehicle_id == 7
                and a.code == AlertCode.MISSION_FAILED
                and a.text == "left the mission: ground station 900: DO_SET_MODE LOITER"
                for a in v.alerts
            ),
            30,
        ), list(gs.snapshot().alerts)[-5:]
        assert gs.wait_for(lambda v: v.status[7].ap_mode == 5, 20)  # LOITER, out of the fleet
        assert wait(lambda: "replanning for [8]" in (tmp_path / "node-8.log").read_text(), 60)
        mp.close()
        # read-only on 8: the same mode change is refused, 8 flies on
        port = free_udp_port()
        procs.append(
            gcs_mavlink(
                fleet.endpoint, 8, port, tmp_path / "gcs-8.log", fleet.clock_spec, "--read-only"
            )
        )
        ro = MavProxy(port, tmp_path / "mavproxy-8")
        proxies.append(ro)
        assert ro.saw("online system 8", 60), ro.out
        ro.send("mode LOITER")
        assert ro.saw("DO_SET_MODE: DENIED", 30), ro.out
        assert ro.saw("bandada read-only: DO_SET_MODE LOITER refused", 10), ro.out
        view = gs.snapshot()
        assert view.status[8].ap_mode == 3 and view.status[8].mission_state == MissionState.MISSION
    finally:
        for p in proxies:
            p.close()
        for proc in procs:
            proc.terminate()
            try:
                proc.wait(15)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
        gs.close()
        stop(fleet)
    log = (tmp_path / "node-7.log").read_text()
    assert "passthrough ground station 900: DO_SET_MODE LOITER relayed" in log


@pytest.mark.soak
@pytest.mark.network
@pytest.mark.timeout(300)
def test_a_vehicle_behind_the_radio_through_gcs_mavlink_radio(
    tmp_path: Path, swarm_db: Path
) -> None:
    """The demo's radio harness in real time (emulated channel, one gateway per node and
    the ground station's): a pymavlink client through `gcs mavlink --radio` gets the
    HIGH_LATENCY2 and heartbeats made from it, a mode change acknowledged, and the rest
    refused at the ground station."""
    from swarm_sim.passthrough_check import PassthroughClient, gcs_mavlink

    fleet = start((7,), 1.0, tmp_path, Console(file=open(os.devnull, "w")), radio=True)  # noqa: SIM115
    try:
        host, port = fleet.endpoint.split("/", 1)[1].rsplit(":", 1)

        def gateway_up() -> bool:
            with socket.socket() as s:
                return s.connect_ex((host, int(port))) == 0

        assert wait(gateway_up, 60)
        log = tmp_path / "gcs-radio.log"
        # the ground station's own id: its radio gateway sends what it originates only
        radio = ("--radio",)
        with gcs_mavlink(fleet.endpoint, "default", 7, log, *radio, gcs_id=900, mode="peer") as url:
            c = PassthroughClient(url)
            try:
                assert c.attach(90), log.read_text()
                assert c.conn.recv_match(type="HIGH_LATENCY2", blocking=True, timeout=15)
                got = c.command(176, 1, 4, timeout_s=30)  # GUIDED, as a COMMAND_LONG
                assert got is not None and got[0] == mavlink.MAV_RESULT_ACCEPTED, got
                c.conn.mav.param_request_list_send(*c.target)
                text = c.conn.recv_match(type="STATUSTEXT", blocking=True, timeout=10)
                assert text is not None and "not on the radio" in text.text
            finally:
                c.close()
    finally:
        stop(fleet)
    assert (
        "radio passthrough session of ground station 900 open"
        in (tmp_path / "node-7.log").read_text()
    )
