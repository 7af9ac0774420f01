"""Real node processes on loopback Zenoh: join, SIGKILL, SIGSTOP, restart, clean exit.

Times are asserted with slack (the machine is shared); the measured figures are in
`make bench BENCH=node`."""

from __future__ import annotations

import os
import signal

import pytest

from tests.conftest import free_tcp_port
from tests.swarm_node.processes import nodes, peers_of, plain_session, start_node, stop, wait_until

pytestmark = pytest.mark.network

LEASE_MS = 1000


@pytest.fixture
def swarm(request: pytest.FixtureRequest) -> str:
    return f"t{os.getpid()}{abs(hash(request.node.name)) % 10000}"


def test_nodes_join_lose_and_rejoin(zenoh_router: str, swarm: str) -> None:
    ids = [1, 2, 3, 4, 5, 6]
    args = ("--lease-ms", str(LEASE_MS))
    watcher = plain_session(zenoh_router)
    try:
        with nodes(ids, zenoh_router, swarm, *args) as procs:

            def everyone_sees(expected: dict[int, list[int]]) -> bool:
                return all(peers_of(watcher, swarm, i) == peers for i, peers in expected.items())

            full = {i: [j for j in ids if j != i] for i in ids}
            assert wait_until(lambda: everyone_sees(full), timeout=30) is not None

            os.kill(procs[6].pid, signal.SIGKILL)
            after_kill = {i: [j for j in ids if j not in (i, 6)] for i in ids[:5]}
            assert wait_until(lambda: everyone_sees(after_kill), timeout=10) is not None

            os.kill(procs[5].pid, signal.SIGSTOP)
            after_stop = {i: [j for j in ids if j not in (i, 5, 6)] for i in ids[:4]}
            assert wait_until(lambda: everyone_sees(after_stop), timeout=10) is not None

            procs[6] = start_node(6, zenoh_router, swarm, *args)  # restarted: rejoins
            rejoined = {i: [j for j in ids if j not in (i, 5)] for i in (1, 2, 3, 4, 6)}
            assert wait_until(lambda: everyone_sees(rejoined), timeout=30) is not None
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
