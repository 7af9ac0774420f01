"""CPU of one vehicle node as the swarm grows, measured three ways in one run:

- `core_cpu_pct_at_peers`: the node core alone (NodeCore, pure, in this
  process) hearing 10, 100 and 1000 peers (VehicleStatus at 5 Hz, VehicleInfo at 1 Hz,
  liveliness tokens, spread over each period as real peers are), with its autopilot
  state polled at 5 Hz and its timers served as the runtime serves them, for 20
  simulated seconds: core CPU seconds per simulated second, in % of one core. Beside
  it, in the same run, `decode_cpu_pct_at_peers`: only decoding the same messages from
  their LAN bytes (what any subscriber pays), and `peer_visits_per_event`: peers the
  core looked at per input (flat).
- `real_processes_cpu_pct`: a real swarm of 10 `swarm-node run` processes,
  each linked over MAVLink to its own simulated quadcopter (one simulator process
  serving all ten) on loopback Zenoh through a router, every node hearing the nine
  others: each node process's CPU over the window, in % of one core (mean and max).
  Beside it `synthetic_peers_cpu_pct_10`: the one node hearing 10 synthetic peers
  played by one process (the older figure below), for the ratio between the two.
- `cpu_s_per_sim_s`: a real `swarm-node run` process with its autopilot link to a
  simulated quadcopter (in its own process), on loopback Zenoh at speed 1, hearing N
  synthetic peers played by one other process and one Zenoh session. Baseline in the
  same run: a plain zenoh-python process that only subscribes to and decodes the same
  traffic. And membership timings measured on the way (join, SIGKILL and SIGSTOP
  detection)."""

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
CORE_PEER_COUNTS = (10, 100, 1000)
CORE_SIM_S = 20.0
REAL_NODES = 10
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
    cmd = [
        sys.executable,
        "-m",
        "swarm_node.cli",
        "run",
        "--swarm",
        SWARM,
        "--connect",
        endpoint,
        "--lease-ms",
        str(lease_ms),
        "--log-level",
        "ERROR",
        "--id",
    ]
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


def _peer_traffic(peers: int, sim_s: float) -> list[tuple[float, bytes, type]]:
    """What `peers` peers publish for `sim_s` seconds, in time order, as LAN bytes."""
    from swarm_proto import lan

    out: list[tuple[float, bytes, type]] = []
    for k in range(round(sim_s / 0.2)):
        for i in range(peers):
            vid = 1000 + i
            at = 0.2 * k + 0.2 * i / peers  # spread over the period
            a = 2 * math.pi * i / peers + 0.01 * k
            st = VehicleStatus(
                vid,
                at,
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
            out.append((at, lan.encode(st), VehicleStatus))
            if k % 5 == 0:
                info = VehicleInfo(
                    vid, VehicleType.VTOL, "Albatross 250 VTOL", f"A{vid}", fleet_id=1
                )
                out.append((at, lan.encode(info), VehicleInfo))
    return out


def core_at_peers(
    peers: int, sim_s: float = CORE_SIM_S, *, liveliness: bool = True
) -> dict[str, float]:
    """The node core alone hearing `peers` peers for `sim_s` simulated seconds: CPU %
    of one core (core only, messages decoded beforehand), the same traffic only decoded,
    and the peers the core looked at per input. With `liveliness` the peers hold tokens
    (a LAN swarm); without, they are known by telemetry only and go stale by deadline
    (peers behind a radio)."""
    from swarm_node.core.node import AutopilotUpdate, NodeCore, NodeSettings, PeerAlive, Received
    from swarm_node.database import seed_fleet
    from swarm_proto import lan

    profiles = {p.vehicle_id: p for p in seed_fleet()}
    traffic = _peer_traffic(peers, sim_s)
    t0 = time.process_time()
    msgs = [(at, lan.decode(raw, cls)) for at, raw, cls in traffic]
    decode_s = time.process_time() - t0
    core = NodeCore(profiles[7], NodeSettings(), now=0.0, fleet_profiles=profiles)
    if liveliness:
        for i in range(peers):
            core.handle(PeerAlive(1000 + i, True), 0.0)
    events = 0
    next_ap = 0.0
    t0 = time.process_time()
    for at, msg in msgs:
        deadline = core.next_deadline()
        while min(deadline, next_ap) <= at:  # the runtime's loop: timers and the 5 Hz poll
            now = min(deadline, next_ap)
            if now >= next_ap:
                next_ap += 0.2
                core.handle(AutopilotUpdate(core.autopilot), now)
            if now >= core.next_deadline():
                core.on_timer(now)
            events += 1
            deadline = core.next_deadline()
        core.handle(Received(msg), at)
        events += 1
    core_s = time.process_time() - t0
    assert len(core.members.live()) == peers
    return {
        "core_cpu_pct": round(100.0 * core_s / sim_s, 3),
        "decode_cpu_pct": round(100.0 * decode_s / sim_s, 3),
        "peer_visits_per_event": round(core.members.visits / events, 3),
        "events_per_sim_s": round(events / sim_s, 1),
    }


def _vehicles_main(ports: list[int], stop: Any) -> None:
    from swarm_proto import SystemClock
    from swarm_sim.core import SITL_HOME
    from swarm_sim.runtime import VehicleServer, VehicleSpec, spread_homes

    homes = spread_homes(SITL_HOME, len(ports), 40.0)
    specs = [
        VehicleSpec("copter", home=h, port=p, sysid=i + 1)
        for i, (h, p) in enumerate(zip(homes, ports, strict=True))
    ]
    with VehicleServer(specs, SystemClock()):
        stop.wait()


def real_swarm(endpoint: str, n: int = REAL_NODES) -> dict[str, Any]:
    """`n` real node processes, each with its own simulated quadcopter (one simulator
    process serving them all), on loopback Zenoh: every node's CPU % over the window,
    once every node lists every other."""
    ctx = mp.get_context("spawn")
    ids = list(range(1, n + 1))
    ports = [_free_port() for _ in ids]
    stop = ctx.Event()
    sim = ctx.Process(target=_vehicles_main, args=(ports, stop))
    sim.start()
    tmp = tempfile.mkdtemp(prefix="bandada-bench-")
    env = {**os.environ, "PYTHONUNBUFFERED": "1", "BANDADA_DB": os.path.join(tmp, "swarm.db")}
    watcher = SwarmBus.open(ZenohSettings(connect=(endpoint,)), SWARM)
    procs: dict[int, subprocess.Popen[bytes]] = {}
    try:
        time.sleep(2.0)  # the simulator's ports open
        for vid, port in zip(ids, ports, strict=True):
            procs[vid] = subprocess.Popen(
                [
                    sys.executable,
                    "-m",
                    "swarm_node.cli",
                    "run",
                    "--id",
                    str(vid),
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
        listed = _until(
            lambda: all(_peers(watcher.session, i) == [j for j in ids if j != i] for i in ids), 120
        )
        time.sleep(3.0)  # past start-up
        c0 = {vid: _cpu_s(p.pid) for vid, p in procs.items()}
        t0 = time.monotonic()
        time.sleep(WINDOW_S)
        dt = time.monotonic() - t0
        pct = {vid: 100.0 * (_cpu_s(p.pid) - c0[vid]) / dt for vid, p in procs.items()}
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
        stop.set()
        sim.join(20)
        shutil.rmtree(tmp, ignore_errors=True)
    return {
        "nodes": n,
        "all_listed_s": listed,
        "node_cpu_pct_mean": round(sum(pct.values()) / len(pct), 2),
        "node_cpu_pct_max": round(max(pct.values()), 2),
    }


def run() -> dict[str, Any]:
    core = {f"peers_{n}": core_at_peers(n) for n in CORE_PEER_COUNTS}
    radio = {f"peers_{n}": core_at_peers(n, liveliness=False) for n in CORE_PEER_COUNTS}
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
    router = open_session(ZenohSettings(mode="router", listen=(endpoint,)))
    try:
        real = real_swarm(endpoint)
    finally:
        router.close()
    synthetic_10 = round(100.0 * node_fig["peers_10"], 2)
    return {
        "core_cpu_pct_at_peers": {k: v["core_cpu_pct"] for k, v in core.items()},
        "decode_cpu_pct_at_peers": {k: v["decode_cpu_pct"] for k, v in core.items()},
        "core_cpu_pct_at_peers_telemetry_only": {k: v["core_cpu_pct"] for k, v in radio.items()},
        "peer_visits_per_event_telemetry_only": {
            k: v["peer_visits_per_event"] for k, v in radio.items()
        },
        "core": core,
        "core_telemetry_only": radio,
        "real_processes_cpu_pct": {"nodes_10": real["node_cpu_pct_mean"]},
        "real_processes": real,
        "synthetic_peers_cpu_pct_10": synthetic_10,
        "real_vs_synthetic_10": round(real["node_cpu_pct_mean"] / synthetic_10, 2)
        if synthetic_10 > 0
        else None,
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
