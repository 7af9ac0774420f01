"""Helpers to run real bandada processes in tests (spawned, never forked)."""

from __future__ import annotations

import contextlib
import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import msgspec
import zenoh

from swarm_proto import SwarmView, SystemClock
from swarm_sim.runtime import VehicleServer, VehicleSpec


@contextlib.contextmanager
def served(specs: dict[int, VehicleSpec]) -> Iterator[dict[int, int]]:
    """Simulated vehicles served on 127.0.0.1 by one thread: node id -> the TCP port
    each listens on. Give the specs port 0: the kernel picks each port as it binds
    (ports picked free one after another beforehand came out equal: "two vehicles on
    one port")."""
    with VehicleServer(list(specs.values()), SystemClock()) as server:
        yield dict(zip(specs, server.ports, strict=True))


def start_node(
    node_id: int, router: str, swarm: str, *args: str, log: Path | None = None
) -> subprocess.Popen[bytes]:
    cmd = [
        sys.executable,
        "-m",
        "swarm_node.cli",
        "run",
        "--id",
        str(node_id),
        "--swarm",
        swarm,
        "--connect",
        router,
        "--listen",
        "tcp/127.0.0.1:0",
        *args,
    ]
    out = open(log, "ab") if log else subprocess.DEVNULL  # noqa: SIM115
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}  # BANDADA_DB: the test's database
    return subprocess.Popen(cmd, stdout=out, stderr=subprocess.STDOUT, env=env)


def stop(proc: subprocess.Popen[bytes], timeout: float = 10.0) -> int:
    """SIGINT, then SIGKILL if it does not exit (a hang at exit is a bug we want to see)."""
    if proc.poll() is None:
        with contextlib.suppress(ProcessLookupError):
            os.kill(proc.pid, signal.SIGCONT)
            proc.send_signal(signal.SIGINT)
        try:
            return proc.wait(timeout)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
            return -999
    return proc.returncode


def plain_session(endpoint: str) -> zenoh.Session:
    conf = zenoh.Config()
    conf.insert_json5("mode", '"peer"')
    conf.insert_json5("scouting/multicast/enabled", "false")
    conf.insert_json5("connect/endpoints", json.dumps([endpoint]))
    return zenoh.open(conf)


def peers_of(
    session: zenoh.Session, swarm: str, node_id: int, timeout: float = 1.0
) -> list[int] | None:
    """Ask a node who it sees (its SwarmView queryable); None if it does not answer."""
    key = f"bandada/{swarm}/vehicle/{node_id}/peers"
    for reply in session.get(key, timeout=timeout):
        if reply.ok is not None:
            view = msgspec.msgpack.decode(reply.ok.payload.to_bytes(), type=SwarmView)
            return sorted(p.node_id for p in view.peers)
    return None


def wait_until(predicate: object, timeout: float, period: float = 0.1) -> float | None:
    """Seconds until predicate() is true, or None after timeout."""
    t0 = time.monotonic()
    while time.monotonic() - t0 < timeout:
        if predicate():  # type: ignore[operator]
            return time.monotonic() - t0
        time.sleep(period)
    return None


@contextlib.contextmanager
def nodes(
    ids: list[int], router: str, swarm: str, *args: str, autopilots: dict[int, str] | None = None
) -> Iterator[dict[int, subprocess.Popen[bytes]]]:
    ap = autopilots or {}
    procs = {
        i: start_node(i, router, swarm, *(("--autopilot", ap[i]) if i in ap else ()), *args)
        for i in ids
    }
    try:
        yield procs
    finally:
        codes = {i: stop(p) for i, p in procs.items()}
        assert all(c != -999 for c in codes.values()), f"a node hung at exit: {codes}"
