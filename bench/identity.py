"""Identity and input on the LAN (docs/security.md), over real processes on loopback
Zenoh: two `swarm-node run` processes (vehicles 7 and 8), each linked over MAVLink to its
own simulated quadcopter, through a router; a plain zenoh-python session plays the
impostor and the garbage.

- `conflict_detect_ms`: from the impostor's first VehicleStatus in vehicle 7's name (no
  bandada attachment) to node 7's IDENTITY_CONFLICT alert, as a listener hears it;
  `untrusted_detect_ms`: to node 8 listing 7 as untrusted (its peers queryable, asked
  every 50 ms).
- The garbage run: `GARBAGE` payloads (undecodable bytes, wrong types, NaN, unknown
  fields only, keys that disagree with their payload, `BLOBS` blobs of 10 MB) on every
  topic a node subscribes to. `rss_growth_pct`: each node's resident memory 5 s after
  the run against just before it (the larger of the two); `malformed_alerts`: the
  MALFORMED_INPUT alerts each node raised (at most one per topic a minute);
  `dropped_by_reason`: what node 7's peers queryable counts (`dropped_by_zenoh`: the
  rest, refused by Zenoh before the node: the blobs); `status_hz_during`: the
  statuses each node published while the run lasted; `log_lines`: what each node logged
  meanwhile.
"""

from __future__ import annotations

import math
import multiprocessing as mp
import os
import random
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections import Counter
from pathlib import Path
from typing import Any

import msgspec

from swarm_proto import Alert, AlertCode, SwarmView, VehicleStatus, lan
from swarm_proto.session import ZenohSettings, open_session
from swarm_proto.topics import (
    ACK,
    COMMAND,
    FLEET,
    INFO,
    LINEAGE,
    MISSION,
    STATUS,
    TARGET,
    VOTE,
    ZONE,
    Topic,
)

SWARM = "identity"
IDS = (7, 8)
GARBAGE = 874  # payloads in the garbage run
BLOBS = 20  # of which 10 MB blobs
BLOB_BYTES = 10_000_000
SETTLE_S = 5.0
#: every topic a node subscribes to, with an example key
SUBSCRIBED: tuple[tuple[Topic, dict[str, int]], ...] = (
    (STATUS, {"vehicle_id": 7}),
    (INFO, {"vehicle_id": 8}),
    (COMMAND, {"issuer_id": 900}),
    (MISSION, {"mission_id": 41}),
    (ZONE, {"zone_id": 5}),
    (FLEET, {"fleet_id": 3}),
    (ACK, {"vehicle_id": 7}),
    (VOTE, {"mission_id": 41, "voter_id": 8}),
    (TARGET, {"source_id": 900, "target_id": 1}),
    (LINEAGE, {"mission_id": 41, "sender_id": 8}),
)


def garbage(swarm: str, n: int = GARBAGE, blobs: int = BLOBS) -> list[tuple[str, bytes]]:
    """`n` malformed payloads for the topics a node subscribes to, the same every time:
    undecodable bytes, wrong types, NaN, maps of unknown fields only, payloads whose key
    names another id, and `blobs` blobs of 10 MB (one shared bytes object)."""
    rng = random.Random(34)
    blob = bytes(BLOB_BYTES)
    nan = {"vehicle_id": 7, "time_unix_s": math.nan, "lat_deg": math.nan, "lon_deg": 0.0}
    kinds = [
        lambda: rng.randbytes(rng.randint(1, 300)),  # not MessagePack (mostly)
        lambda: msgspec.msgpack.encode({"vehicle_id": "seven", "issuer_id": [1, 2]}),
        lambda: msgspec.msgpack.encode({**nan, "alt_msl_m": math.nan, "alt_rel_m": 0.0}),
        lambda: msgspec.msgpack.encode({f"x{rng.randint(0, 99)}": rng.random() for _ in range(5)}),
        lambda: msgspec.msgpack.encode([1, 2, 3]),
    ]
    out: list[tuple[str, bytes]] = []
    for i in range(n - blobs):
        topic, params = SUBSCRIBED[i % len(SUBSCRIBED)]
        out.append((topic.key(swarm, **params), kinds[i % len(kinds)]()))
    # a valid status of vehicle 8 on vehicle 7's key: the key and the payload disagree
    wrong = lan.encode(VehicleStatus(8, time.time(), 37.41, -5.99, 110.0, 100.0))
    out[::50] = [(STATUS.key(swarm, vehicle_id=7), wrong)] * len(out[::50])
    for i in range(blobs):
        topic, params = SUBSCRIBED[i % len(SUBSCRIBED)]
        out.insert(rng.randrange(len(out)), (topic.key(swarm, **params), blob))
    return out


def _free_port() -> int:
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def rss_mb(pid: int) -> float:
    with open(f"/proc/{pid}/status") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024.0
    return 0.0


def _vehicles_main(ports: dict[int, int], stop: Any) -> None:
    from swarm_proto import SystemClock
    from swarm_sim.core import SITL_HOME
    from swarm_sim.runtime import VehicleServer, VehicleSpec, spread_homes

    homes = spread_homes(SITL_HOME, len(ports), 30.0)
    specs = [
        VehicleSpec("copter", home=homes[i], port=p, sysid=vid)
        for i, (vid, p) in enumerate(ports.items())
    ]
    with VehicleServer(specs, SystemClock()):
        stop.wait()


def _plain(endpoint: str) -> Any:
    import json

    import zenoh

    conf = zenoh.Config()
    conf.insert_json5("mode", '"peer"')
    conf.insert_json5("scouting/multicast/enabled", "false")
    conf.insert_json5("connect/endpoints", json.dumps([endpoint]))
    return zenoh.open(conf)


def _view(session: Any, node: int) -> SwarmView | None:
    for reply in session.get(f"bandada/{SWARM}/vehicle/{node}/peers", timeout=1.0):
        if reply.ok is not None:
            return msgspec.msgpack.decode(reply.ok.payload.to_bytes(), type=SwarmView)
    return None


def _until(pred: Any, timeout: float, period: float = 0.05) -> float | None:
    t0 = time.monotonic()
    while time.monotonic() - t0 < timeout:
        if pred():
            return time.monotonic() - t0
        time.sleep(period)
    return None


def _lines(path: Path) -> int:
    return len(path.read_bytes().splitlines()) if path.exists() else 0


def run(*, blobs: int = BLOBS) -> dict[str, Any]:
    endpoint = f"tcp/127.0.0.1:{_free_port()}"
    router = open_session(ZenohSettings(mode="router", listen=(endpoint,)))
    ctx = mp.get_context("spawn")
    ports = {vid: _free_port() for vid in IDS}
    stop = ctx.Event()
    sim = ctx.Process(target=_vehicles_main, args=(ports, stop))
    sim.start()
    tmp = Path(tempfile.mkdtemp(prefix="bandada-identity-"))
    env = {**os.environ, "PYTHONUNBUFFERED": "1", "BANDADA_DB": str(tmp / "swarm.db")}
    plain = _plain(endpoint)
    alerts: list[tuple[float, Alert]] = []
    statuses: list[tuple[float, int]] = []
    lock = threading.Lock()

    def on_alert(s: Any) -> None:
        with lock:
            alerts.append(
                (time.monotonic(), msgspec.msgpack.decode(s.payload.to_bytes(), type=Alert))
            )

    def on_status(s: Any) -> None:
        if s.attachment is not None:  # the nodes' own (the impostor's has none)
            with lock:
                statuses.append((time.monotonic(), int(str(s.key_expr).split("/")[3])))

    subs = [
        plain.declare_subscriber(f"bandada/{SWARM}/vehicle/*/alert", on_alert),
        plain.declare_subscriber(f"bandada/{SWARM}/vehicle/*/status", on_status),
    ]
    procs: dict[int, subprocess.Popen[bytes]] = {}
    logs = {vid: tmp / f"node{vid}.log" for vid in IDS}
    try:
        time.sleep(2.0)  # the simulator's ports open
        for vid in IDS:
            cmd = [sys.executable, "-m", "swarm_node.cli", "run", "--id", str(vid)]
            cmd += ["--swarm", SWARM, "--connect", endpoint, "--listen", "tcp/127.0.0.1:0"]
            cmd += ["--autopilot", f"tcp:127.0.0.1:{ports[vid]}", "--log-level", "WARNING"]
            procs[vid] = subprocess.Popen(
                cmd, env=env, stdout=logs[vid].open("wb"), stderr=subprocess.STDOUT
            )

        def listed() -> bool:
            views = {vid: _view(plain, vid) for vid in IDS}
            return all(
                v is not None and [p.node_id for p in v.peers] == [o for o in IDS if o != vid]
                for vid, v in views.items()
            )

        assert _until(listed, 120, 0.5) is not None, "the nodes never listed each other"
        time.sleep(3.0)

        # ---- an impostor in vehicle 7's name
        fake = lan.encode(VehicleStatus(7, time.time(), 37.5, -5.9, 110.0, 100.0, fsm_state=3))
        t0 = time.monotonic()
        seen_conflict: float | None = None
        seen_untrusted: float | None = None
        while time.monotonic() - t0 < 10.0 and (seen_conflict is None or seen_untrusted is None):
            plain.put(f"bandada/{SWARM}/vehicle/7/status", fake)
            with lock:
                hit = [
                    t
                    for t, a in alerts
                    if a.vehicle_id == 7 and a.code == AlertCode.IDENTITY_CONFLICT and t >= t0
                ]
            if hit and seen_conflict is None:
                seen_conflict = hit[0] - t0
            view = _view(plain, 8)
            if (
                seen_untrusted is None
                and view is not None
                and any(p.node_id == 7 and p.untrusted for p in view.peers)
            ):
                seen_untrusted = time.monotonic() - t0
            time.sleep(0.05)
        time.sleep(12.0)  # the conflict clears (10 s without the impostor)

        # ---- the garbage run
        payloads = garbage(SWARM, blobs=blobs)
        rss0 = {vid: rss_mb(p.pid) for vid, p in procs.items()}
        lines0 = {vid: _lines(path) for vid, path in logs.items()}
        with lock:
            n_alerts0 = len(alerts)
        g0 = time.monotonic()
        for key, data in payloads:
            plain.put(key, data)
            time.sleep(0.002)
        g1 = time.monotonic()
        time.sleep(SETTLE_S)
        rss1 = {vid: rss_mb(p.pid) for vid, p in procs.items()}
        alive = {vid: p.poll() is None for vid, p in procs.items()}
        with lock:
            malformed = Counter(
                a.vehicle_id for _, a in alerts[n_alerts0:] if a.code == AlertCode.MALFORMED_INPUT
            )
            during = Counter(v for t, v in statuses if g0 <= t <= g1 + 1.0)
        view7 = _view(plain, 7)
        dropped: Counter[str] = Counter()
        for d in view7.dropped if view7 is not None else ():
            dropped[d.reason] += d.count
        growth = {vid: 100.0 * (rss1[vid] - rss0[vid]) / rss0[vid] for vid in IDS}
        return {
            "conflict_detect_ms": round(1000 * seen_conflict, 1) if seen_conflict else None,
            "untrusted_detect_ms": round(1000 * seen_untrusted, 1) if seen_untrusted else None,
            "rss_growth_pct": round(max(growth.values()), 1),
            "rss_mb": {
                f"node_{vid}": {"before": round(rss0[vid], 1), "after": round(rss1[vid], 1)}
                for vid in IDS
            },
            "malformed_alerts": {f"node_{vid}": malformed.get(vid, 0) for vid in IDS},
            "dropped_by_reason": dict(sorted(dropped.items())),
            # larger than any cap: Zenoh refuses them before the node sees them
            "dropped_by_zenoh": len(payloads) - sum(dropped.values()),
            "status_hz_during": {
                f"node_{vid}": round(during.get(vid, 0) / (g1 - g0 + 1.0), 2) for vid in IDS
            },
            "log_lines": {f"node_{vid}": _lines(logs[vid]) - lines0[vid] for vid in IDS},
            "nodes_up": all(alive.values()),
            "garbage": {
                "payloads": len(payloads),
                "blobs_10mb": blobs,
                "topics": len(SUBSCRIBED),
                "seconds": round(g1 - g0, 2),
            },
        }
    finally:
        for p in procs.values():
            if p.poll() is None:
                p.send_signal(signal.SIGINT)
        for p in procs.values():
            try:
                p.wait(20)
            except subprocess.TimeoutExpired:
                p.kill()
        for s in subs:
            s.undeclare()
        plain.close()
        stop.set()
        sim.join(20)
        router.close()
        shutil.rmtree(tmp, ignore_errors=True)
