"""A fresh `gcs` process against node processes already running (defects 5
and 6), over real Zenoh on 127.0.0.1: a mission for one listed vehicle waits for that
vehicle, and zones are durable (every vehicle confirms, a node started later learns
them)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
from collections.abc import Iterator
from pathlib import Path

import msgspec
import pytest

from swarm_proto import NoFlyZone
from tests.swarm_node.processes import peers_of, plain_session, start_node, stop, wait_until

pytestmark = pytest.mark.network


@pytest.fixture
def swarm(request: pytest.FixtureRequest) -> str:
    return f"f{os.getpid()}{abs(hash(request.node.name)) % 10000}"


def gcs(
    router: str, swarm: str, *args: str, timeout: float = 60.0
) -> subprocess.CompletedProcess[str]:
    """The ground station as an operator runs it: a new process each time."""
    cmd = [sys.executable, "-m", "gcs_cli.app", "--connect", router, "--swarm", swarm, *args]
    env = {**os.environ, "PYTHONUNBUFFERED": "1", "COLUMNS": "200"}
    return subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, env=env)


@pytest.fixture
def two_nodes(
    zenoh_router: str, swarm: str, swarm_db: Path, tmp_path: Path
) -> Iterator[dict[int, subprocess.Popen[bytes]]]:
    """Nodes 1 and 7 (no autopilot: they answer missions and hold zones)."""
    procs = {i: start_node(i, zenoh_router, swarm, log=tmp_path / f"node{i}.log") for i in (1, 7)}
    watcher = plain_session(zenoh_router)
    try:
        for i in procs:
            assert wait_until(lambda i=i: peers_of(watcher, swarm, i) is not None, 30) is not None
        yield procs
    finally:
        watcher.close()
        codes = {i: stop(p) for i, p in procs.items()}
        for i in procs:
            print(f"--- node {i}\n" + (tmp_path / f"node{i}.log").read_text(errors="replace"))
        assert all(c == 0 for c in codes.values()), codes


@pytest.mark.soak  # test_ground_repeats.py and test_exchange.py wait for the addressed the same way
def test_mission_for_one_id_waits_for_that_vehicle(
    zenoh_router: str, swarm: str, two_nodes: dict[int, subprocess.Popen[bytes]]
) -> None:
    """Defect 6: node 7 is silent while the fresh ground station starts (frozen, so it
    is heard neither by status nor by its answer); node 1 answers NOT_ADDRESSED at once.
    The ground station must keep waiting for vehicle 7, not conclude from vehicle 1."""
    seven = two_nodes[7]
    os.kill(seven.pid, signal.SIGSTOP)
    resume = threading.Timer(3.0, lambda: os.kill(seven.pid, signal.SIGCONT))
    resume.start()
    try:
        r = gcs(
            zenoh_router,
            swarm,
            "mission",
            "target",
            "--point",
            "37.4125,-5.9889",
            "--id",
            "7",
            "--timeout",
            "20",
            "--yes",
        )
    finally:
        resume.join()
        os.kill(seven.pid, signal.SIGCONT)
    out = r.stdout + r.stderr
    assert "addresses none" not in out, out
    assert "no answer" not in out, out
    # node 7 answered (without an autopilot it refuses, with its reason, in the table)
    assert " 7 " in out or "│ 7" in out, out


# a node restarted learns from its peer what was declared while it was down, over real
# processes: test_declared_processes.py; `gcs zone add` and `remove` confirmed by a
# running node: test_gcs_commands.py's test_status_commands_missions_and_zones
@pytest.mark.soak
def test_zone_confirmed_and_learned_by_a_node_started_later(
    zenoh_router: str,
    swarm: str,
    swarm_db: Path,
    tmp_path: Path,
    two_nodes: dict[int, subprocess.Popen[bytes]],
) -> None:
    """Defect 5: `gcs zone add` says which vehicles hold the zone; a node started after
    the zone was declared holds it too (it asks its peers' zones queryables)."""
    r = gcs(
        zenoh_router,
        swarm,
        "zone",
        "add",
        "3",
        "--circle",
        "37.43,-5.98,50",
        "--floor",
        "0",
        "--ceiling",
        "300",
    )
    assert r.returncode == 0, r.stdout + r.stderr
    assert "zone 3: 2 accepted of 2 addressed" in r.stdout, r.stdout

    late = start_node(2, zenoh_router, swarm, log=tmp_path / "node2.log")
    watcher = plain_session(zenoh_router)
    try:

        def zone_of_2() -> NoFlyZone | None:
            key = f"bandada/{swarm}/vehicle/2/zones/3"
            for reply in watcher.get(key, timeout=1.0):
                if reply.ok is not None:
                    return msgspec.msgpack.decode(reply.ok.payload.to_bytes(), type=NoFlyZone)
            return None

        assert wait_until(lambda: zone_of_2() is not None, 30) is not None
        zone = zone_of_2()
        assert zone is not None and zone.geometry.radius_m == 50.0 and zone.active
        # withdrawn: each vehicle, the late one too, confirms it dropped it
        r = gcs(zenoh_router, swarm, "zone", "remove", "3")
        assert r.returncode == 0, r.stdout + r.stderr
        assert "zone 3: 3 accepted of 3 addressed" in r.stdout, r.stdout
        assert r.stdout.count("withdrawn") == 3, r.stdout  # each vehicle's answer
    finally:
        watcher.close()
        code = stop(late)
        print((tmp_path / "node2.log").read_text(errors="replace"))
        assert code == 0


def test_zone_add_with_no_vehicle_says_so(zenoh_router: str, swarm: str) -> None:
    r = gcs(zenoh_router, swarm, "zone", "add", "4", "--circle", "37.43,-5.98,50", "--timeout", "1")
    assert r.returncode == 1
    assert "zone 4: no vehicle addressed answered or is alive" in r.stdout, r.stdout
