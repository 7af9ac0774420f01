"""CPU of one vehicle node as the swarm grows: a real `swarm-node run` process, linked
over MAVLink to a simulated quadcopter (in its own process) and on loopback Zenoh,
hears N synthetic peers (VehicleStatus at 5 Hz, VehicleInfo at 1 Hz, liveliness
tokens). Baseline in the same run: a plain zenoh-python process that only subscribes
to and decodes the same traffic.

Figures: cpu_s_per_sim_s for 10, 50 and 100 peers (`peers_10`, `peers_50`,
`peers_100`), the same for the baseline, and membership timings measured on the way
(join, SIGKILL and SIGSTOP detection)."""

from __future__ import annotations

import json
import math
import multiprocessing as mp
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from typing import Any

from swarm_proto import FsmState, GpsFix, VehicleInfo, VehicleStatus, VehicleType
from swarm_proto.session import SwarmBus, ZenohSettings, open_session

WINDOW_S = 8.0
PEER_COUNTS = (10, 50, 100)
SWARM = "bench"


def _free_port() -> int:
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _cpu_s(pid: int) -> float:
    with open(f"/proc/{pid}/stat") as f:
        fields = f.read().rsplit(")", 1)[1].split()
    ticks = os.sysconf("SC_CLK_TCK")
    return (int(fields[11]) + int(fields[12])) / ticks  # utime + stime


def _peers_main(endpoint: str, n: int, stop: Any, ready: Any) -> None:
    """A process that plays n peers."""
    bus = SwarmBus.open(ZenohSettings(connect=(endpoint,)), SWARM)
    try:
        for i in range(n):
            bus.declare_alive(1000 + i)
        ready.set()
        k = 0
        t0 = time.monotonic()
        while not stop.is_set():
            now = time.time()
            for i in range(n):
                vid = 1000 + i
                a = 2 * math.pi * i / max(n, 1) + 0.01 * k
                bus.publish(
                    VehicleStatus(
                        vid,
                        now,
                        37.41 + 0.01 * math.sin(a),
                        -5.99 + 0.01 * math.cos(a),
                        110.0,
                        100.0,
                        12.0,
                        3.0,
                        0.0,
                        45.0,
                        20.0,
                        80,
                        24.5,
                        GpsFix.FIX_3D,
                        14,
                        10,
                        True,
                        FsmState.GO_MISSION,
                    )
                )
                if k % 5 == 0:
                    bus.publish(
                        VehicleInfo(
                            vid, VehicleType.VTOL, "Albatross 250 VTOL", f"A{vid}", fleet_id=1
                        )
                    )
            k += 1
            time.sleep(max(0.0, t0 + k * 0.2 - time.monotonic()))
    finally:
        bus.close()


def _baseline_main(endpoint: str, stop: Any, ready: Any) -> None:
    """A plain subscriber that decodes everything the node would hear."""
    import msgspec
    import zenoh

    conf = zenoh.Config()
    conf.insert_json5("mode", '"peer"')
    conf.insert_json5("scouting/multicast/enabled", "false")
    conf.insert_json5("connect/endpoints", json.dumps([endpoint]))
    session = zenoh.open(conf)
    dec = msgspec.msgpack.Decoder()
    sub = session.declare_subscriber(
        f"bandada/{SWARM}/**", lambda s: dec.decode(s.payload.to_bytes())
    )
    ready.set()
    stop.wait()
    sub.undeclare()
    session.close()


def _vehicle_main(port: int, stop: Any) -> None:
    from swarm_proto import SystemClock
    from swarm_sim.runtime import VehicleServer, VehicleSpec

    with VehicleServer([VehicleSpec("copter", port=port, sysid=7)], SystemClock()):
        stop.wait()


def _node_with_vehicle(ctx: Any, endpoint: str) -> tuple[subprocess.Popen[bytes], Any, Any, str]:
    """A simulated quadcopter in its own process and node 7 flying it (a fresh seeded
    database in a temporary directory)."""
    port = _free_port()
    stop_vehicle = ctx.Event()
    vehicle = ctx.Process(target=_vehicle_main, args=(port, stop_vehicle))
    vehicle.start()
    tmp = tempfile.mkdtemp(prefix="bandada-bench-")
    env = {**os.environ, "PYTHONUNBUFFERED": "1", "BANDADA_DB": os.path.join(tmp, "swarm.db")}
    node = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "swarm_node.cli",
            "run",
            "--id",
            "7",
            "--swarm",
            SWARM,
            "--connect",
            endpoint,
            "--autopilot",
            f"tcp:127.0.0.1:{port}",
            "--log-level",
            "ERROR",
        ],
        env=env,
    )
    return node, vehicle, stop_vehicle, tmp


def _measure(pid: int) -> float:
    c0, t0 = _cpu_s(pid), time.monotonic()
    time.sleep(WINDOW_S)
    return (_cpu_s(pid) - c0) / (time.monotonic() - t0)


def _peers(session: Any, node: int) -> list[int] | None:
    import msgspec

    from swarm_proto import SwarmView

    for reply in session.get(f"bandada/{SWARM}/vehicle/{node}/peers", timeout=1.0):
        if reply.ok is not None:
            view = msgspec.msgpack.decode(reply.ok.payload.to_bytes(), type=SwarmView)
            return sorted(p.node_id for p in view.peers)
    return None


def _until(pred: Any, timeout: float) -> float | None:
    t0 = time.monotonic()
    while time.monotonic() - t0 < timeout:
        if pred():
            return round(time.monotonic() - t0, 3)
        time.sleep(0.02)
    return None


def membership_timings(endpoint: str, lease_ms: int = 2000) -> dict[str, Any]:
    """Six node processes: how long until every node lists every other, and until a
    SIGKILLed and a SIGSTOPped node are marked lost by all the others."""
    ids = [1, 2, 3, 7, 8, 9]
    tmp = tempfile.mkdtemp(prefix="bandada-bench-")
    env = {**os.environ, "BANDADA_DB": os.path.join(tmp, "swarm.db")}
    cmd = [sys.executable, "-m", "swarm_node.cli", "run", "--swarm", SWARM, "--connect", endpoint,
           "--lease-ms", str(lease_ms), "--log-level", "ERROR", "--id"]  # fmt: skip
    watcher = SwarmBus.open(ZenohSettings(connect=(endpoint,)), SWARM)
    t_launch = time.monotonic()
    procs = {i: subprocess.Popen([*cmd, str(i)], env=env) for i in ids}

    def all_see(alive: list[int]) -> bool:
        return all(_peers(watcher.session, i) == [j for j in alive if j != i] for i in alive)

    try:
        # from launching six processes (Python start-up included) to every node listing
        # every other
        _until(lambda: all_see(ids), 120)
        join = round(time.monotonic() - t_launch, 3)
        os.kill(procs[9].pid, signal.SIGKILL)
        alive = ids[:-1]
        killed = _until(lambda: all_see(alive), 60)
        os.kill(procs[8].pid, signal.SIGSTOP)
        alive = ids[:-2]
        frozen = _until(lambda: all_see(alive), 60)
        os.kill(procs[8].pid, signal.SIGCONT)
    finally:
        for p in procs.values():
            if p.poll() is None:
                p.send_signal(signal.SIGINT)
        for p in procs.values():
            try:
                p.wait(20)
            except subprocess.TimeoutExpired:
                p.kill()
        watcher.close()
        shutil.rmtree(tmp, ignore_errors=True)
    return {
        "nodes": len(ids),
        "lease_ms": lease_ms,
        "all_listed_after_launch_s": join,
        "sigkill_marked_lost_s": killed,
        "sigstop_marked_lost_s": frozen,
    }


def link_loss_to_emergency_s(endpoint: str) -> float | None:
    """A node flying a simulated quadcopter is made ready and active; then the vehicle
    process is killed: how long until the node's VehicleInfo says EMERGENCY."""
    import queue as q

    from swarm_proto import Command, CommandArgs, CommandKind, FsmState, GeoPoint

    ctx = mp.get_context("spawn")
    node, vehicle, _stop, tmp = _node_with_vehicle(ctx, endpoint)
    infos: q.Queue[tuple[float, VehicleInfo]] = q.Queue()
    bus = SwarmBus.open(ZenohSettings(connect=(endpoint,)), SWARM)
    from swarm_proto.topics import INFO

    bus.subscribe(
        INFO, lambda m, k: infos.put((time.monotonic(), m)) if m.vehicle_id == 7 else None
    )

    def wait_state(state: FsmState, timeout: float) -> float | None:
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            try:
                t, info = infos.get(timeout=0.2)
            except q.Empty:
                continue
            if info.fsm_state == state:
                return t
        return None

    try:
        base = Command(
            900, 1, CommandKind.SET_BASE, args=CommandArgs(point=GeoPoint(37.4112, -5.9889, 10.0))
        )
        t_ready = None
        for _ in range(60):
            bus.publish(base)
            t_ready = wait_state(FsmState.GO_MISSION, 1.0)
            if t_ready is not None:
                break
        if t_ready is None:
            return None
        t_cut = time.monotonic()
        vehicle.kill()
        t_em = wait_state(FsmState.EMERGENCY, 20.0)
        return None if t_em is None else round(t_em - t_cut, 3)
    finally:
        bus.close()
        node.send_signal(signal.SIGINT)
        node.wait(20)
        vehicle.join(5)
        shutil.rmtree(tmp, ignore_errors=True)


def run() -> dict[str, Any]:
    ctx = mp.get_context("spawn")
    endpoint = f"tcp/127.0.0.1:{_free_port()}"
    router = open_session(ZenohSettings(mode="router", listen=(endpoint,)))
    node, vehicle, stop_vehicle, tmp = _node_with_vehicle(ctx, endpoint)
    stop_base, base_ready = ctx.Event(), ctx.Event()
    baseline = ctx.Process(target=_baseline_main, args=(endpoint, stop_base, base_ready))
    baseline.start()
    base_ready.wait(30)
    node_fig: dict[str, float] = {}
    base_fig: dict[str, float] = {}
    try:
        time.sleep(2.0)
        node_fig["peers_0"] = round(_measure(node.pid), 4)
        for n in PEER_COUNTS:
            stop, ready = ctx.Event(), ctx.Event()
            peers = ctx.Process(target=_peers_main, args=(endpoint, n, stop, ready))
            peers.start()
            ready.wait(60)
            time.sleep(2.0)  # let discovery settle
            c_node0, c_base0, t0 = _cpu_s(node.pid), _cpu_s(baseline.pid or 0), time.monotonic()
            time.sleep(WINDOW_S)
            dt = time.monotonic() - t0
            node_fig[f"peers_{n}"] = round((_cpu_s(node.pid) - c_node0) / dt, 4)
            base_fig[f"peers_{n}"] = round((_cpu_s(baseline.pid or 0) - c_base0) / dt, 4)
            stop.set()
            peers.join(30)
    finally:
        node.send_signal(signal.SIGINT)
        node.wait(20)
        stop_base.set()
        baseline.join(20)
        stop_vehicle.set()
        vehicle.join(20)
        router.close()
        shutil.rmtree(tmp, ignore_errors=True)
    router = open_session(ZenohSettings(mode="router", listen=(endpoint,)))
    try:
        membership = membership_timings(endpoint)
        membership["link_loss_to_emergency_s"] = link_loss_to_emergency_s(endpoint)
    finally:
        router.close()
    return {
        "membership": membership,
        "cpu_s_per_sim_s": node_fig,
        "baseline_plain_subscriber_cpu_s_per_sim_s": base_fig,
        "window_s": WINDOW_S,
        "note": (
            "One swarm-node process with its autopilot link to a simulated quadcopter, at speed 1 "
            "(simulated s = wall s); peers_0 is the node alone with its autopilot; "
            "peers publish VehicleStatus at 5 Hz and VehicleInfo at 1 Hz each. Baseline: a plain "
            "zenoh-python subscriber decoding the same traffic in its own process."
        ),
    }
