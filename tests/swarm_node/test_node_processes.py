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


# node id (the seed database's system) -> the simulated model it flies
FLEET = {1: "vtol", 7: "copter", 2: "vtol", 10: "rover", 12: "boat", 8: "copter"}


@pytest.fixture
def six_vehicles() -> Iterator[dict[int, str]]:
    """Six simulated vehicles (one process thread, real TCP ports): node id -> MAVLink url."""
    homes = spread_homes(SITL_HOME, len(FLEET), 30.0)
    specs = {
        vid: VehicleSpec(model, instance=i, port=free_tcp_port(), home=homes[i], sysid=vid)
        for i, (vid, model) in enumerate(FLEET.items())
    }
    with VehicleServer(list(specs.values()), SystemClock()) as server:
        yield {vid: f"tcp:127.0.0.1:{spec.tcp_port}" for vid, spec in specs.items()}
        server.close()


def test_nodes_join_lose_and_rejoin(
    zenoh_router: str, swarm: str, six_vehicles: dict[int, str]
) -> None:
    ids = sorted(FLEET)
    killed, frozen = ids[-1], ids[-2]
    args = ("--lease-ms", str(LEASE_MS))
    watcher = plain_session(zenoh_router)

    def everyone_sees(alive: list[int]) -> bool:
        return all(peers_of(watcher, swarm, i) == [j for j in alive if j != i] for i in alive)

    try:
        with nodes(ids, zenoh_router, swarm, *args, autopilots=six_vehicles) as procs:
            assert wait_until(lambda: everyone_sees(ids), timeout=30) is not None, "join"

            os.kill(procs[killed].pid, signal.SIGKILL)
            alive = [i for i in ids if i != killed]
            assert wait_until(lambda: everyone_sees(alive), timeout=15) is not None, "SIGKILL"

            os.kill(procs[frozen].pid, signal.SIGSTOP)
            alive = [i for i in alive if i != frozen]
            assert wait_until(lambda: everyone_sees(alive), timeout=15) is not None, "SIGSTOP"

            procs[killed] = start_node(
                killed, zenoh_router, swarm, "--autopilot", six_vehicles[killed], *args
            )
            alive = sorted([*alive, killed])
            assert wait_until(lambda: everyone_sees(alive), timeout=30) is not None, "restart"
            os.kill(procs[frozen].pid, signal.SIGCONT)
    finally:
        watcher.close()


def test_node_exits_cleanly_on_sigterm(zenoh_router: str, swarm: str, swarm_db: object) -> None:
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


def test_autopilot_link_loss_drives_emergency(
    zenoh_router: str, swarm: str, swarm_db: object
) -> None:
    spec = VehicleSpec("copter", port=free_tcp_port(), sysid=7)
    server = VehicleServer([spec], SystemClock())
    server.start_thread()
    proc = start_node(7, zenoh_router, swarm, "--autopilot", f"tcp:127.0.0.1:{spec.tcp_port}")
    client = plain_session(zenoh_router)
    infos: queue.Queue[tuple[float, VehicleInfo]] = queue.Queue()
    sub = client.declare_subscriber(
        f"bandada/{swarm}/vehicle/7/info",
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
        wait_until(lambda: peers_of(client, swarm, 7) is not None, timeout=30)
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
