"""The ground station's round trip at swarm scale: `rtl_all_ms`, from the RTL command
to every vehicle's answer, for 10, 25 and 50 nodes on loopback Zenoh.

Six of the nodes are real `swarm-node run` processes (what two shared cores allow
beside everything else); the rest are NodeCores simulated in one helper process, each
with its own liveliness token, VehicleInfo and the node's own command path (`NodeCore.
handle(Received(cmd))`), all on one Zenoh session. No node has an autopilot here, so
every answer is the node's refusal (NOT_READY, "autopilot link down"): the figure is
the command/answer path (the ground station's exchange core, Zenoh, the node's
command manager), not an autopilot's mode change. The ground station discovers the
vehicles first (not timed), then `GroundStation.exchange` is timed from the first
copy sent to the last answer, 5 times per size.

Baseline in the same run (`raw_zenoh_ms`): a plain subscriber times the same command
published once to the last Ack, with no exchange core, no repeats, no membership.
"""

from __future__ import annotations

import multiprocessing as mp
import os
import signal
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from typing import Any

SWARM = "benchgcs"
SIZES = (10, 25, 50)
REAL = 6  # real node processes (ids 1..6); the rest simulated in-process (ids 101..)
RUNS = 5


def _free_port() -> int:
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _simulated_main(endpoint: str, ids: list[int], stop: Any, ready: Any) -> None:
    """NodeCores on one session: they answer commands as nodes do."""
    import msgspec

    from swarm_node.core.node import NodeCore, Publish, Received
    from swarm_node.database import seed_profiles
    from swarm_proto import Ack, Command
    from swarm_proto.session import SwarmBus, ZenohSettings
    from swarm_proto.topics import COMMAND

    base = seed_profiles()["Generic Quadcopter"]
    cores = {
        i: NodeCore(msgspec.structs.replace(base, vehicle_id=i, user_id=f"SIM{i}")) for i in ids
    }
    bus = SwarmBus.open(ZenohSettings(connect=(endpoint,)), SWARM)
    lock = threading.Lock()

    def on_command(cmd: Command, key: str) -> None:
        now = time.time()
        with lock:
            for core in cores.values():
                for o in core.handle(Received(cmd), now):
                    if isinstance(o, Publish) and isinstance(o.msg, Ack):
                        bus.publish(o.msg)

    bus.subscribe(COMMAND, on_command)
    for i in ids:
        bus.declare_alive(i)
    ready.set()
    try:
        while not stop.wait(1.0):
            with lock:
                for core in cores.values():
                    bus.publish(core.info())
    finally:
        bus.close()


def _start_real(endpoint: str, tmp: str) -> list[subprocess.Popen[bytes]]:
    env = {**os.environ, "PYTHONUNBUFFERED": "1", "BANDADA_DB": os.path.join(tmp, "swarm.db")}
    return [
        subprocess.Popen(
            [
                sys.executable,
                "-m",
                "swarm_node.cli",
                "run",
                "--id",
                str(i),
                "--swarm",
                SWARM,
                "--connect",
                endpoint,
                "--listen",
                "tcp/127.0.0.1:0",
            ],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
            env=env,
        )
        for i in range(1, REAL + 1)
    ]


def _raw_round_trip(endpoint: str, n: int, gcs_id: int) -> float:
    """A Command published once; milliseconds to the n-th Ack (a plain subscriber)."""
    from gcs_cli.ground import new_seq
    from swarm_proto import Ack, Command, CommandKind
    from swarm_proto.session import SwarmBus, ZenohSettings
    from swarm_proto.topics import ACK

    got: set[int] = set()
    done = threading.Event()
    seq = new_seq()
    with SwarmBus.open(ZenohSettings(connect=(endpoint,)), SWARM) as bus:

        def on_ack(a: Ack, key: str) -> None:
            if a.ref_id == seq and a.issuer_id == gcs_id:
                got.add(a.vehicle_id)
                if len(got) >= n:
                    done.set()

        bus.subscribe(ACK, on_ack)
        time.sleep(1.0)  # routes up
        t0 = time.perf_counter()
        bus.publish(Command(gcs_id, seq, CommandKind.RTL))
        done.wait(10.0)
        return (time.perf_counter() - t0) * 1000.0 if done.is_set() else float("nan")


def run() -> dict[str, Any]:
    from gcs_cli.core.exchange import Request
    from gcs_cli.ground import GroundStation, new_seq
    from swarm_proto import AckRef, Command, CommandKind, Selector
    from swarm_proto.session import ZenohSettings, open_session

    ctx = mp.get_context("spawn")
    endpoint = f"tcp/127.0.0.1:{_free_port()}"
    router = open_session(ZenohSettings(mode="router", listen=(endpoint,)))
    tmp = tempfile.mkdtemp(prefix="bandada-bench-gcs-")
    real = _start_real(endpoint, tmp)
    figures: dict[str, Any] = {
        "rtl_all_ms": {},
        "rtl_all_ms_max": {},
        "raw_zenoh_ms": {},
        "answers": {},
        "nodes": {},
    }
    try:
        time.sleep(4.0)  # the real nodes start (imports, Zenoh)
        for n in SIZES:
            sim_ids = list(range(101, 101 + n - REAL))
            stop, ready = ctx.Event(), ctx.Event()
            sim = ctx.Process(target=_simulated_main, args=(endpoint, sim_ids, stop, ready))
            sim.start()
            ready.wait(60)
            time.sleep(2.0)
            times, answers = [], []
            with GroundStation(ZenohSettings(connect=(endpoint,)), SWARM, 900) as gs:
                for _ in range(RUNS):
                    alive = gs.discover()
                    cmd = Command(
                        900, new_seq(), CommandKind.RTL, Selector(), time_unix_s=time.time()
                    )
                    req = Request(AckRef.COMMAND, cmd.seq, 900, Selector(), what="rtl")
                    t0 = time.perf_counter()
                    out = gs.exchange(cmd, req, timeout_s=10.0)
                    times.append((time.perf_counter() - t0) * 1000.0)
                    answers.append(len([r for r in out.rows if r.ack is not None]))
                    assert len(alive) >= n, f"discovered {len(alive)} of {n}"
                    time.sleep(0.3)
            raw = [_raw_round_trip(endpoint, n, 901) for _ in range(3)]
            stop.set()
            sim.join(30)
            figures["rtl_all_ms"][str(n)] = round(statistics.median(times), 1)
            figures["rtl_all_ms_max"][str(n)] = round(max(times), 1)
            figures["raw_zenoh_ms"][str(n)] = round(statistics.median(raw), 1)
            figures["answers"][str(n)] = min(answers)
            figures["nodes"][str(n)] = {"real_processes": REAL, "simulated_in_process": n - REAL}
    finally:
        for p in real:
            p.send_signal(signal.SIGINT)
        for p in real:
            try:
                p.wait(20)
            except subprocess.TimeoutExpired:
                p.kill()
        router.close()
    figures["how"] = (
        f"{REAL} real swarm-node processes plus NodeCores simulated in one process, loopback "
        "Zenoh through a router; no autopilot (every answer is the node's NOT_READY refusal); "
        f"median of {RUNS} exchanges after discovery, first copy sent to last answer"
    )
    return figures
