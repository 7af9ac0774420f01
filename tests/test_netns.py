"""The documented topologies on a lab network made of network namespaces (veth pairs
and bridges; addresses 10.77.x.y exist only inside the namespaces): the router, three
vehicles (a simulated vehicle and a `swarm-node run` each) and the ground station, each
in its own namespace, started with the command lines and the deploy/ files of
docs/deploy.md. Skipped where namespaces cannot be made (not root); CI runs as root.

Checks: discovery (the ground station sees the three vehicles alive), a command and its
three acks, across subnets joined only by the router; with mutual TLS and access
control, a client with a vehicle's certificate, or without the swarm's, cannot command a
vehicle, and the router's log shows the refused attempt.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from bench._netlab import VEHICLES, NetLab, SwarmLab, unavailable

pytestmark = pytest.mark.network

_REASON = unavailable()


@pytest.fixture
def env() -> dict[str, str]:
    return {**os.environ, "PYTHONUNBUFFERED": "1"}


def _lab(tmp_path: Path, topology: str, env: dict[str, str]) -> Iterator[SwarmLab]:
    if _REASON:
        pytest.skip(f"network namespaces unavailable: {_REASON}")
    with NetLab(tmp_path) as lab:
        yield SwarmLab(lab, topology, env)


# b, where only Zenoh crosses between the subnets, in make test; a in soak
@pytest.fixture(params=[pytest.param("a", marks=pytest.mark.soak), "b"])
def lab(request: pytest.FixtureRequest, tmp_path: Path, env: dict[str, str]) -> Iterator[SwarmLab]:
    yield from _lab(tmp_path, request.param, env)


@pytest.fixture
def tls_lab(tmp_path: Path, env: dict[str, str]) -> Iterator[SwarmLab]:
    yield from _lab(tmp_path, "tls", env)


def _fleet(s: SwarmLab, *, who: str = "gcs-900", want: int = len(VEHICLES)) -> list[dict]:
    """Ask `gcs status --json` until `want` vehicles are alive (the nodes take a few
    seconds to start); returns the last rows."""
    rows: list[dict] = []
    for _ in range(8):
        r = s.lab.run(s.gcs, s.gcs_argv("status", "--json", "--wait", "2", who=who), s.env)
        assert r.returncode == 0, r.stderr
        rows = json.loads(r.stdout)
        if sum(row["alive"] for row in rows) >= want:
            break
    return rows


def _set_fleet(
    s: SwarmLab, who: str = "gcs-900", timeout_s: float = 5.0
) -> subprocess.CompletedProcess[str]:
    ids = [a for v in VEHICLES for a in ("--id", str(v))]
    wait = ["--timeout", str(timeout_s)]
    return s.lab.run(
        s.gcs,
        s.gcs_argv("cmd", "set-fleet", "--fleet-id", "4", *ids, *wait, "--json", who=who),
        s.env,
    )


def _logs(s: SwarmLab) -> str:
    return "\n".join(
        f"--- {p.name}\n{p.read_text(errors='replace')[-3000:]}"
        for p in sorted(s.lab.logdir.glob("*.log"))
    )


_CONNECT = """
import socket, sys
try:
    socket.create_connection((sys.argv[1], int(sys.argv[2])), timeout=1).close()
    print("reached")
except OSError:
    print("unreachable")
"""


def test_discovery_and_a_command_with_its_acks(lab: SwarmLab) -> None:
    lab.start_router()
    for v in VEHICLES:
        lab.start_vehicle(v)
    rows = _fleet(lab)
    assert sorted(r["id"] for r in rows if r["alive"]) == list(VEHICLES), _logs(lab)
    r = _set_fleet(lab)
    assert r.returncode == 0, r.stdout + r.stderr + _logs(lab)
    answered = [v["id"] for v in json.loads(r.stdout)["vehicles"] if v["reason"] == "OK"]
    assert sorted(answered) == list(VEHICLES), r.stdout
    router_log = (lab.lab.logdir / "router.log").read_text()
    # the router keeps the multicast scouting router.json5 enables
    assert "multicast scouting on" in router_log
    if lab.topology == "b":  # only Zenoh crosses: no IP route between the subnets
        probe = lab.lab.run(lab.gcs, [lab.py, "-c", _CONNECT, "10.77.2.11", "5760"], lab.env)
        assert probe.stdout.strip() == "unreachable", probe.stdout + probe.stderr


@pytest.mark.soak  # the same certificates and ACL on 127.0.0.1: test_security.py
def test_tls_only_the_ground_station_commands(tls_lab: SwarmLab) -> None:
    s = tls_lab
    s.start_router(log_denied=True)
    for v in VEHICLES:
        s.start_vehicle(v)
    rows = _fleet(s)
    assert sorted(r["id"] for r in rows if r["alive"]) == list(VEHICLES), _logs(s)
    r = _set_fleet(s)
    assert r.returncode == 0, r.stdout + r.stderr + _logs(s)
    # a vehicle's certificate (used from the ground station's host): it connects, but
    # its command is not delivered: no vehicle answers (waited for 2 s, not the default 5)
    r = _set_fleet(s, who="vehicle-2", timeout_s=2.0)
    assert r.returncode == 1, r.stdout + r.stderr
    assert {v["answer"] for v in json.loads(r.stdout)["vehicles"]} == {"no answer"}, r.stdout
    # certificates of another CA (even one named gcs-900): no connection at all
    from swarm_node.certs import make_swarm_certs

    other = s.lab.logdir / "other"
    make_swarm_certs(other, "default", [1], [900], ["10.77.1.1"])
    argv = [
        str(s.bin / "gcs"),
        "--zenoh-config",
        str(other / "gcs-900.json5"),
        "--connect",
        "tls/10.77.1.1:7447",
        "cmd",
        "set-fleet",
        "--fleet-id",
        "5",
        "--id",
        "1",
    ]
    r = s.lab.run(s.gcs, argv, s.env)
    assert r.returncode == 2 and "cannot open Zenoh" in r.stderr, r.stdout + r.stderr
    time.sleep(0.5)
    log = (s.lab.logdir / "router.log").read_text()
    assert "CertCommonName(vehicle-2)" in log
    assert "unauthorized to Put (ingress) on bandada/default/cmd/900" in log


_RADIO_PAIR = """
import sys, time, queue
from pathlib import Path
from radio_gateway.runtime.gateway import load_config as gateway_config
from swarm_node.runtime.config import load_config as node_config
from swarm_proto import VehicleStatus
from swarm_proto.session import SwarmBus
from swarm_proto.topics import STATUS
deploy = Path(sys.argv[1])
node = SwarmBus.open(node_config(deploy / "node-radio.toml").zenoh)
gateway = SwarmBus.open(gateway_config(deploy / "radio.toml", {}).zenoh)
got = queue.Queue()
gateway.subscribe(STATUS, lambda m, k: got.put(m.vehicle_id))
for _ in range(50):
    node.publish(VehicleStatus(vehicle_id=1, time_unix_s=time.time(), lat_deg=37.4,
                               lon_deg=-6.0, alt_msl_m=50.0, alt_rel_m=40.0))
    try:
        print("gateway got status of", got.get(timeout=0.2))
        break
    except queue.Empty:
        pass
gateway.close()
node.close()
"""


def test_vehicle_behind_a_radio_gateway_configs_join(tmp_path: Path, env: dict[str, str]) -> None:
    """Topology c: on the companion computer (its own namespace, so port 7447 is ours),
    the node with deploy/config/node-radio.toml and the gateway with the shipped
    deploy/config/radio.toml share one Zenoh network as they are. (The radio link
    itself: tests/radio_gateway/test_gateway_e2e.py and `swarm-sim demo --radio`.)"""
    if _REASON:
        pytest.skip(f"network namespaces unavailable: {_REASON}")
    from bench._netlab import REPO

    with NetLab(tmp_path) as lab:
        ns = lab.host("companion", {})
        r = lab.run(ns, [sys.executable, "-c", _RADIO_PAIR, str(REPO / "deploy" / "config")], env)
        assert "gateway got status of 1" in r.stdout, r.stdout + r.stderr
