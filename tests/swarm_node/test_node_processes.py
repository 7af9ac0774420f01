"""Real node processes, each flying a simulated vehicle over MAVLink, on loopback Zenoh:
join, SIGKILL, SIGSTOP, restart, autopilot link loss, clean exit.

Times are asserted with slack (the machine is shared); the measured figures are in
`make bench BENCH=node`."""

from __future__ import annotations

import os
import queue
import signal
import time
from collections.abc import Iterator

import msgspec
import pytest

from swarm_proto import (
    Command,
    CommandArgs,
    CommandKind,
    FsmState,
    GeoPoint,
    SystemClock,
    VehicleInfo,
)
from swarm_sim.core import SITL_HOME
from swarm_sim.runtime import VehicleServer, VehicleSpec, spread_homes
from tests.conftest import free_tcp_port
from tests.swarm_node.processes import nodes, peers_of, plain_session, start_node, stop, wait_until

pytestmark = pytest.mark.network

LEASE_MS = 1000


@pytest.fixture
def swarm(request: pytest.FixtureRequest) -> str:
    return f"t{os.getpid()}{abs(hash(request.node.name)) % 10000}"


MODELS = ["vtol", "copter", "plane", "rover", "boat", "copter"]


@pytest.fixture
def six_vehicles() -> Iterator[dict[int, str]]:
    """Six simulated vehicles (one process thread, real TCP ports): node id -> MAVLink url."""
    specs = [
        VehicleSpec(m, instance=i, port=free_tcp_port(), home=h)
        for i, (m, h) in enumerate(zip(MODELS, spread_homes(SITL_HOME, 6, 30.0), strict=True))
    ]
    with VehicleServer(specs, SystemClock()) as server:
        yield {i + 1: f"tcp:127.0.0.1:{spec.tcp_port}" for i, spec in enumerate(specs)}
        server.close()


def test_nodes_join_lose_and_rejoin(
    zenoh_router: str, swarm: str, six_vehicles: dict[int, str]
) -> None:
    ids = [1, 2, 3, 4, 5, 6]
    args = ("--lease-ms", str(LEASE_MS))
    watcher = plain_session(zenoh_router)
    try:
        with nodes(ids, zenoh_router, swarm, *args, autopilots=six_vehicles) as procs:

            def everyone_sees(expected: dict[int, list[int]]) -> bool:
                return all(peers_of(watcher, swarm, i) == peers for i, peers in expected.items())

            full = {i: [j for j in ids if j != i] for i in ids}
            print("join", wait_until(lambda: everyone_sees(full), timeout=30))

            os.kill(procs[6].pid, signal.SIGKILL)
            after_kill = {i: [j for j in ids if j not in (i, 6)] for i in ids[:5]}
            print("kill", wait_until(lambda: everyone_sees(after_kill), timeout=10))

            os.kill(procs[5].pid, signal.SIGSTOP)
            after_stop = {i: [j for j in ids if j not in (i, 5, 6)] for i in ids[:4]}
            print("stop", wait_until(lambda: everyone_sees(after_stop), timeout=10))

            procs[6] = start_node(
                6, zenoh_router, swarm, "--autopilot", six_vehicles[6], *args
            )  # restarted
            rejoined = {i: [j for j in ids if j not in (i, 5)] for i in (1, 2, 3, 4, 6)}
            print("rejoin", wait_until(lambda: everyone_sees(rejoined), timeout=30))
            os.kill(procs[5].pid, signal.SIGCONT)
    finally:
        watcher.close()


def test_node_exits_cleanly_on_sigterm(zenoh_router: str, swarm: str) -> None:
    proc = start_node(9, zenoh_router, swarm)
    watcher = plain_session(zenoh_router)
    try:
        assert wait_until(lambda: peers_of(watcher, swarm, 9) is not None, timeout=30) is not None
        proc.send_signal(signal.SIGTERM)
        assert proc.wait(timeout=10) == 0
    finally:
        stop(proc)
        watcher.close()


def test_bad_configuration_is_a_clear_error(tmp_path: object) -> None:
    import subprocess
    import sys

    r = subprocess.run(
        [
            sys.executable,
            "-m",
            "swarm_node.cli",
            "run",
            "--id",
            "0",
            "--connect",
            f"tcp/127.0.0.1:{free_tcp_port()}",
        ],
        capture_output=True,
        timeout=60,
    )
    assert r.returncode == 2 and b"node_id must be 1..65534" in r.stderr


def test_autopilot_link_loss_drives_emergency(zenoh_router: str, swarm: str) -> None:
    spec = VehicleSpec("copter", port=free_tcp_port())
    server = VehicleServer([spec], SystemClock())
    server.start_thread()
    proc = start_node(1, zenoh_router, swarm, "--autopilot", f"tcp:127.0.0.1:{spec.tcp_port}")
    client = plain_session(zenoh_router)
    infos: queue.Queue[tuple[float, VehicleInfo]] = queue.Queue()
    sub = client.declare_subscriber(
        f"bandada/{swarm}/vehicle/1/info",
        lambda s: infos.put(
            (time.monotonic(), msgspec.msgpack.decode(s.payload.to_bytes(), type=VehicleInfo))
        ),
    )

    def wait_state(state: FsmState, timeout: float) -> float:
        t_end = time.monotonic() + timeout
        while time.monotonic() < t_end:
            try:
                t, info = infos.get(timeout=0.5)
            except queue.Empty:
                continue
            if info.fsm_state == state:
                return t
        pytest.fail(f"node never reached {state.name}")

    try:
        base = Command(
            900, 1, CommandKind.SET_BASE, args=CommandArgs(point=GeoPoint(37.4112, -5.9889, 10.0))
        )
        wait_until(lambda: peers_of(client, swarm, 1) is not None, timeout=30)
        client.put(f"bandada/{swarm}/cmd/900", msgspec.msgpack.encode(base))
        wait_state(FsmState.GO_MISSION, timeout=60)  # ready once the EKF has a position
        t_cut = time.monotonic()
        server.close()  # the autopilot falls silent
        t_emergency = wait_state(FsmState.EMERGENCY, timeout=20)
        print(
            f"link loss -> STATE_EMERGENCY seen after {t_emergency - t_cut:.2f} s (wall, loaded machine)"
        )
    finally:
        sub.undeclare()
        client.close()
        server.close()
        assert stop(proc) == 0
