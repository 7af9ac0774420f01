"""The TCP shell: real sockets on 127.0.0.1, pymavlink's own mavutil client, several
vehicles in one process on a shared scaled clock, and the `swarm-sim vehicle` command."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from pymavlink import mavutil

from swarm_proto.clock import ScaledClock
from swarm_sim.core import SITL_HOME, sitl_port
from swarm_sim.runtime import VehicleServer, VehicleSpec, spread_homes
from tests.conftest import REPO, free_tcp_port

SPEEDUP = 20.0


def connect(port: int) -> mavutil.mavfile:
    deadline = time.monotonic() + 20
    while True:
        try:
            return mavutil.mavlink_connection(f"tcp:127.0.0.1:{port}", source_system=255, retries=0)
        except OSError:
            if time.monotonic() > deadline:
                raise
            time.sleep(0.2)


@pytest.fixture
def two_vehicles() -> Iterator[tuple[VehicleServer, list[int]]]:
    ports = [free_tcp_port(), free_tcp_port()]
    homes = spread_homes(SITL_HOME, 2, 10.0)
    specs = [
        VehicleSpec("copter", instance=0, home=homes[0], port=ports[0]),
        VehicleSpec("vtol", instance=1, home=homes[1], port=ports[1]),
    ]
    server = VehicleServer(specs, ScaledClock(SPEEDUP))
    server.start_thread()
    try:
        yield server, ports
    finally:
        server.close()


def wait_position(m: mavutil.mavfile, timeout: float = 20.0) -> object:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        msg = m.recv_match(type="GLOBAL_POSITION_INT", blocking=True, timeout=1.0)
        if msg is not None and msg.lat != 0:
            return msg
    raise AssertionError("no position")


def test_sitl_ports() -> None:
    assert [sitl_port(i) for i in range(3)] == [5760, 5770, 5780]


def test_vehicles_on_port_0_get_free_ports_and_say_which() -> None:
    """The demo's simulator binds free ports itself and reports them (ports picked free
    by the demo and bound later by the simulator process were a race on a busy host)."""
    specs = [VehicleSpec("copter", instance=i, port=0, sysid=i + 1) for i in range(3)]
    server = VehicleServer(specs, ScaledClock(SPEEDUP))
    server.start_thread()
    try:
        ports = server.ports
        assert len(set(ports)) == 3 and all(p > 0 for p in ports), ports
        m = mavutil.mavlink_connection(f"tcp:127.0.0.1:{ports[2]}", source_system=250)
        try:
            hb = m.wait_heartbeat(timeout=20)
            assert hb is not None and m.target_system == 3
        finally:
            m.close()
    finally:
        server.close()
    with pytest.raises(ValueError, match="one port"):
        VehicleServer(
            [VehicleSpec("copter", port=7), VehicleSpec("vtol", port=7)], ScaledClock(SPEEDUP)
        )


def test_pymavlink_client_sees_two_vehicles_in_one_process(
    two_vehicles: tuple[VehicleServer, list[int]],
) -> None:
    server, ports = two_vehicles
    links = [connect(port) for port in ports]
    try:
        beats = [m.wait_heartbeat(timeout=10) for m in links]
        assert [(b.get_srcSystem(), b.type, b.autopilot) for b in beats] == [(1, 2, 3), (2, 1, 3)]
        positions = [wait_position(m) for m in links]
        lats = {round(p.lat / 1e7, 5) for p in positions}  # type: ignore[attr-defined]
        assert lats == {round(SITL_HOME.lat_deg, 5)}
        assert positions[0].lon != positions[1].lon  # type: ignore[attr-defined]
        # switch the copter's mode through pymavlink's own helper
        links[0].mav.command_long_send(1, 1, 176, 0, 1, 4, 0, 0, 0, 0, 0)
        ack = links[0].recv_match(type="COMMAND_ACK", blocking=True, timeout=10)
        assert ack is not None and ack.command == 176 and ack.result == 0
        assert server.endpoints[0].autopilot.mode_name == "GUIDED"
        assert server.endpoints[1].autopilot.mode_name != "GUIDED"
    finally:
        for m in links:
            m.close()


def test_two_clients_on_one_port_and_disconnects(
    two_vehicles: tuple[VehicleServer, list[int]],
) -> None:
    _server, ports = two_vehicles
    a, b = connect(ports[0]), connect(ports[0])
    try:
        assert a.wait_heartbeat(timeout=10) is not None
        assert b.wait_heartbeat(timeout=10) is not None
        a.close()
        assert b.recv_match(type="HEARTBEAT", blocking=True, timeout=10) is not None
    finally:
        b.close()
    c = connect(ports[0])  # the port still accepts clients
    try:
        assert c.wait_heartbeat(timeout=10) is not None
    finally:
        c.close()


def test_a_vehicle_removed_is_gone_and_the_other_flies_on(
    two_vehicles: tuple[VehicleServer, list[int]],
) -> None:
    """`remove` (the demo's crash): the vehicle's clients are cut off and its port
    closes; the other vehicle is served as before."""
    server, ports = two_vehicles
    a, b = connect(ports[0]), connect(ports[1])
    try:
        assert a.wait_heartbeat(timeout=10) is not None
        server.remove(1)
        deadline = time.monotonic() + 10
        while len(server.vehicles) != 1 and time.monotonic() < deadline:
            time.sleep(0.05)
        assert [v.spec.system_id for v in server.vehicles] == [2]
        assert b.recv_match(type="HEARTBEAT", blocking=True, timeout=10) is not None
        with pytest.raises(OSError):
            mavutil.mavlink_connection(f"tcp:127.0.0.1:{ports[0]}", retries=0)
    finally:
        a.close()
        b.close()


def test_cli_vehicle_uses_the_shared_clock_from_the_environment() -> None:
    instance = 40 + os.getpid() % 40  # a SITL-style port unlikely to be taken: 6160..6550
    port = sitl_port(instance)
    clock = ScaledClock(SPEEDUP, start_unix_s=1_800_000_000.0)
    env = {**os.environ, "BANDADA_CLOCK": clock.spec()}
    proc = subprocess.Popen(
        [
            str(Path(sys.executable).parent / "swarm-sim"),
            "vehicle",
            "--model",
            "rover,boat",
            "--instance",
            str(instance),
            "--count",
            "2",
        ],
        cwd=REPO,
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        m = connect(port)
        try:
            hb = m.wait_heartbeat(timeout=15)
            assert hb is not None and hb.type == 10 and hb.get_srcSystem() == instance + 1
            wait_position(m)
            st = None
            deadline = time.monotonic() + 20
            while time.monotonic() < deadline:
                st = m.recv_match(type="SYSTEM_TIME", blocking=True, timeout=1.0)
                if st is not None and st.time_unix_usec:
                    break
            assert st is not None and st.time_unix_usec
            # GPS time is the shared simulated clock, not the wall clock
            assert abs(st.time_unix_usec / 1e6 - clock.now()) < 5 * SPEEDUP
            assert abs(st.time_unix_usec / 1e6 - time.time()) > 1e6
        finally:
            m.close()
        boat = connect(sitl_port(instance + 1))
        try:
            hb = boat.wait_heartbeat(timeout=15)
            assert hb is not None and hb.type == 11 and hb.get_srcSystem() == instance + 2
        finally:
            boat.close()
    finally:
        proc.terminate()
        try:
            _out, err = proc.communicate(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
            _out, err = proc.communicate()
    assert f"rover instance {instance} sysid {instance + 1} on tcp:127.0.0.1:{port}" in err


def test_cli_vehicle_home_and_speedup() -> None:
    """`swarm-sim vehicle --home LAT,LON,ALT,HDG --speedup K`, as SITL takes --home: the
    vehicle starts there, facing HDG, and its clock runs K times faster than the wall."""
    instance = 80 + os.getpid() % 40  # 6560..6950, apart from the test above
    port = sitl_port(instance)
    env = {k: v for k, v in os.environ.items() if k != "BANDADA_CLOCK"}
    proc = subprocess.Popen(
        [
            str(Path(sys.executable).parent / "swarm-sim"),
            "vehicle",
            "--model",
            "copter",
            "--instance",
            str(instance),
            "--home",
            "-35.363261,149.165230,584,270",
            "--speedup",
            "4",
        ],
        cwd=REPO,
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        m = connect(port)
        try:
            hb = m.wait_heartbeat(timeout=15)
            assert hb is not None and hb.get_srcSystem() == instance + 1
            pos = wait_position(m)
            assert abs(pos.lat / 1e7 + 35.363261) < 1e-5  # type: ignore[attr-defined]
            assert abs(pos.lon / 1e7 - 149.165230) < 1e-5  # type: ignore[attr-defined]
            assert abs(pos.alt / 1000 - 584) < 1.0  # type: ignore[attr-defined]
            assert abs(pos.hdg / 100 - 270) < 1.0  # type: ignore[attr-defined]
            # read everything for 3 s of wall time; every SYSTEM_TIME read while draining
            # gives (wall, simulated boot time)
            samples = []
            end = time.monotonic() + 3.0
            while time.monotonic() < end:
                msg = m.recv_match(blocking=True, timeout=0.5)
                if msg is not None and msg.get_type() == "SYSTEM_TIME":
                    samples.append((time.monotonic(), msg.time_boot_ms / 1000))
            assert len(samples) >= 3
            (w0, s0), (w1, s1) = samples[0], samples[-1]
            ratio = (s1 - s0) / (w1 - w0)
            assert 2.0 < ratio < 8.0, ratio  # 4x, with a loaded machine's slack
        finally:
            m.close()
    finally:
        proc.terminate()
        try:
            proc.communicate(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.communicate()


def test_the_demo_picks_listening_ports_below_the_ephemeral_range(tmp_path: Path) -> None:
    """Outgoing connections on a busy host draw from the kernel's ephemeral range, so a
    port picked there may be gone before a gateway or router listens on it."""
    import random
    import socket

    from swarm_sim import demo

    low = demo._ephemeral_low()
    ports = {demo.free_tcp_port(random.Random(seed)) for seed in range(20)}
    assert all(1024 <= p < low for p in ports) and len(ports) > 15, ports
    for p in list(ports)[:3]:
        with socket.socket() as s:
            s.bind(("127.0.0.1", p))
    bad = tmp_path / "range"
    bad.write_text("garbage\n")
    assert demo._ephemeral_low(str(bad)) == 32768
    assert demo._ephemeral_low(str(tmp_path / "missing")) == 32768
