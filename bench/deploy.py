"""Deployment figures on the namespace lab of bench/_netlab.py, topology b (ground
station and vehicles on different subnets, joined only by the router):

- `status_latency_ms_p50/p99`: a VehicleStatus published by a client in a vehicle's
  namespace (deploy/zenoh/client.json5) to a subscriber in the ground station's, through
  the router process; the send time travels in the message (one kernel clock for every
  namespace). 100 Hz for 5 s, the first second dropped. `tls`: the same with the mutual
  TLS and access-control configs of `swarm-node certs make`.
- `join_s`: from starting a vehicle (`swarm-sim vehicle` and `swarm-node run`, both
  Python processes starting cold) to the ground station's first sight of it (its
  liveliness token, and `join_status_s` its first VehicleStatus); median of 3 vehicles.

Without network namespaces (not root) the latencies are measured on 127.0.0.1 with the
same configs and the join figures are left out (null, with the reason).
"""

from __future__ import annotations

import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from bench._netlab import ROUTER_A, ROUTER_B, VEHICLES, NetLab, SwarmLab, unavailable

RATE_HZ = 100.0
SECONDS = 5.0

_COMMON = """
import sys, time, json
from swarm_proto.session import ZenohSettings, SwarmBus
from swarm_proto import VehicleStatus
from swarm_proto.topics import STATUS
cfg, endpoint = sys.argv[1], sys.argv[2]
bus = SwarmBus.open(ZenohSettings(connect=(endpoint,), config_file=cfg))
"""

SUBSCRIBER = (
    _COMMON
    + """
seen = []
bus.subscribe(STATUS, lambda m, k: seen.append((time.time(), m.time_unix_s)))
print("ready", flush=True)
deadline = time.time() + float(sys.argv[3])
while time.time() < deadline:
    time.sleep(0.1)
bus.close()
print(json.dumps([(r - s) * 1000 for r, s in seen]), flush=True)
"""
)

PUBLISHER = (
    _COMMON
    + """
time.sleep(1.0)  # routes through the router
n = int(float(sys.argv[3]) * float(sys.argv[4]))
period = 1 / float(sys.argv[4])
t = time.monotonic()
for i in range(n):
    bus.publish(VehicleStatus(vehicle_id=int(sys.argv[5]), time_unix_s=time.time(),
                              lat_deg=37.41, lon_deg=-5.99, alt_msl_m=60.0, alt_rel_m=50.0))
    t += period
    time.sleep(max(0.0, t - time.monotonic()))
bus.close()
"""
)

WATCHER = (
    _COMMON
    + """
first = {}
def alive(node_id, up):
    if up:
        print(json.dumps(["alive", node_id, time.time()]), flush=True)
bus.watch_alive(alive)
def status(m, k):
    if m.vehicle_id not in first:
        first[m.vehicle_id] = time.time()
        print(json.dumps(["status", m.vehicle_id, first[m.vehicle_id]]), flush=True)
bus.subscribe(STATUS, status)
print("ready", flush=True)
import signal, threading
stop = threading.Event()
signal.signal(signal.SIGINT, lambda *a: stop.set())
stop.wait(120)
bus.close()
"""
)


def _percentiles(samples: list[float]) -> dict[str, float]:
    s = sorted(samples[int(RATE_HZ) :])  # the first second: routes settling
    if not s:
        raise RuntimeError("no status samples arrived")
    return {
        "p50": round(s[len(s) // 2], 3),
        "p99": round(s[min(len(s) - 1, int(len(s) * 0.99))], 3),
        "samples": len(s),
    }


def _wait_line(path: Path, text: str, timeout: float = 60.0) -> None:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if path.exists() and text in path.read_text():
            return
        time.sleep(0.1)
    raise RuntimeError(f"{path.name}: no {text!r}: {path.read_text()[-2000:]}")


def _lab_latency(topology: str, env: dict[str, str]) -> dict[str, float]:
    with tempfile.TemporaryDirectory() as tmp, NetLab(Path(tmp)) as lab:
        s = SwarmLab(lab, topology, env)
        s.start_router()
        gcs_cfg, v_cfg = _configs(s)
        proto = "tls" if topology == "tls" else "tcp"
        sub = lab.popen(
            s.gcs,
            [s.py, "-c", SUBSCRIBER, gcs_cfg, f"{proto}/{ROUTER_A}:7447", str(SECONDS + 4)],
            "sub.log",
            env,
        )
        _wait_line(lab.logdir / "sub.log", "ready")
        r = lab.run(
            s.vehicles[1],
            [
                s.py,
                "-c",
                PUBLISHER,
                v_cfg,
                f"{proto}/{ROUTER_B}:7447",
                str(SECONDS),
                str(RATE_HZ),
                "1",
            ],
            env,
        )
        if r.returncode != 0:
            raise RuntimeError(r.stderr[-2000:])
        sub.wait(30)
        lines = (lab.logdir / "sub.log").read_text().strip().splitlines()
        return _percentiles(json.loads(lines[-1]))


def _configs(s: SwarmLab) -> tuple[str, str]:
    if s.topology == "tls":
        return str(s.certs / "gcs-900.json5"), str(s.certs / "vehicle-1.json5")
    client = str(Path(__file__).resolve().parents[1] / "deploy" / "zenoh" / "client.json5")
    return client, client


def _join(env: dict[str, str]) -> dict[str, Any]:
    with tempfile.TemporaryDirectory() as tmp, NetLab(Path(tmp)) as lab:
        s = SwarmLab(lab, "b", env)
        s.start_router()
        cfg, _ = _configs(s)
        w = lab.popen(s.gcs, [s.py, "-c", WATCHER, cfg, f"tcp/{ROUTER_A}:7447"], "watch.log", env)
        _wait_line(lab.logdir / "watch.log", "ready")
        alive_s, status_s = [], []
        for v in VEHICLES:
            t0 = time.time()
            s.start_vehicle(v)
            _wait_line(lab.logdir / "watch.log", f'["status", {v},', 90)
            seen: dict[str, float] = {}
            for line in (lab.logdir / "watch.log").read_text().splitlines():
                if line.startswith("["):
                    kind, vid, t = json.loads(line)
                    if vid == v:
                        seen.setdefault(kind, t)
            alive_s.append(seen["alive"] - t0)
            status_s.append(seen["status"] - t0)
        lab.stop(w)
        return {
            "join_s": round(statistics.median(alive_s), 2),
            "join_status_s": round(statistics.median(status_s), 2),
            "join_s_each": [round(x, 2) for x in alive_s],
        }


def _loopback_latency(tls: bool) -> dict[str, float]:
    """The fallback: router, publisher and subscriber processes on 127.0.0.1."""
    from swarm_node.certs import make_swarm_certs
    from swarm_proto.session import ZenohSettings, open_session
    from tests.conftest import free_tcp_port

    with tempfile.TemporaryDirectory() as tmp:
        certs = Path(tmp) / "certs"
        proto = "tls" if tls else "tcp"
        endpoint = f"{proto}/127.0.0.1:{free_tcp_port()}"
        if tls:
            make_swarm_certs(certs, "default", [1], [900], ["127.0.0.1"])
            rcfg, gcfg, vcfg = (
                str(certs / f"{n}.json5") for n in ("router", "gcs-900", "vehicle-1")
            )
        else:
            client = str(Path(__file__).resolve().parents[1] / "deploy" / "zenoh" / "client.json5")
            rcfg, gcfg, vcfg = None, client, client
        router = open_session(ZenohSettings(mode="router", listen=(endpoint,), config_file=rcfg))
        try:
            log = Path(tmp) / "sub.log"
            with log.open("w") as out:
                sub = subprocess.Popen(
                    [sys.executable, "-c", SUBSCRIBER, gcfg, endpoint, str(SECONDS + 4)],
                    stdout=out,
                )
                _wait_line(log, "ready")
                subprocess.run(
                    [
                        sys.executable,
                        "-c",
                        PUBLISHER,
                        vcfg,
                        endpoint,
                        str(SECONDS),
                        str(RATE_HZ),
                        "1",
                    ],
                    check=True,
                )
                sub.wait(30)
            return _percentiles(json.loads(log.read_text().strip().splitlines()[-1]))
        finally:
            router.close()


def run() -> dict[str, Any]:
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    reason = unavailable()
    if reason is None:
        plain, tls = _lab_latency("b", env), _lab_latency("tls", env)
        join = _join(env)
        network = "network namespaces, topology b (docs/deploy.md)"
    else:
        plain, tls = _loopback_latency(False), _loopback_latency(True)
        join = {"join_s": None, "join_status_s": None, "join_unavailable": reason}
        network = "127.0.0.1"
    return {
        "network": network,
        "rate_hz": RATE_HZ,
        "status_latency_ms_p50": plain["p50"],
        "status_latency_ms_p99": plain["p99"],
        "tls": {
            "status_latency_ms_p50": tls["p50"],
            "status_latency_ms_p99": tls["p99"],
        },
        "samples": plain["samples"],
        **join,
    }
