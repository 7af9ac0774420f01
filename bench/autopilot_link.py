"""Autopilot link: how fast the link core digests real ArduPilot telemetry (the SITL
QuadPlane recording), beside pymavlink's own stream parser on the same bytes in the
same run, and what a 100-item mission upload costs under loss (simulated seconds)."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

from pymavlink import mavutil
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from swarm_node.core.autopilot.link import LinkCore, LinkSettings
from swarm_proto import VehicleType

SHARED = Path(__file__).resolve().parents[2] / "shared" / "data" / "ardupilot-sitl"
TLOG = SHARED / "arduplane-quadplane-sortie.tlog"


def _recording() -> tuple[bytes, int, float]:
    conn = mavutil.mavlink_connection(str(TLOG))
    chunks: list[bytes] = []
    first = last = 0.0
    try:
        while True:
            msg = conn.recv_match()
            if msg is None:
                break
            if not chunks:
                first = msg._timestamp
            last = msg._timestamp
            chunks.append(bytes(msg.get_msgbuf()))
    finally:
        conn.close()
    return b"".join(chunks), len(chunks), last - first


def _best_of(fn: Any, repeat: int = 3) -> float:
    best = float("inf")
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def _upload_under_loss(n: int, loss: float, seed: int) -> tuple[float, int, bool]:
    from swarm_node.core.autopilot import requests as rq
    from swarm_node.core.autopilot.mission_item import MavCmd, MissionItem
    from tests.swarm_node.autopilot.fake_autopilot import FakeAutopilot, Harness

    core = LinkCore(LinkSettings(vehicle_type=VehicleType.COPTER), 1000.0)
    h = Harness(core, FakeAutopilot("copter"), seed=seed)
    h.run_until(lambda: core.state.link_ok, 10)
    h.loss = loss
    items = tuple(
        MissionItem(
            seq=i, command=MavCmd.NAV_WAYPOINT, lat_deg=37.4 + i * 1e-4, lon_deg=-5.98, alt_m=30
        )
        for i in range(n)
    )
    start, sent0 = h.now, len(h.sent)
    result = h.run_request(1, rq.UploadMissionItems(items=items), max_s=3600)
    mission_msgs = sum(1 for m in h.sent[sent0:] if m.get_type().startswith("MISSION"))
    return h.now - start, mission_msgs, bool(result and result.ok)


def run() -> dict:
    data, count, duration_s = _recording()

    def ours() -> None:
        core = LinkCore(LinkSettings(vehicle_type=VehicleType.VTOL), 0.0)
        for i in range(0, len(data), 4096):
            core.receive(data[i : i + 4096], float(i))

    def pymavlink_parser() -> None:
        parser = mavlink.MAVLink(None)
        parser.robust_parsing = True
        for i in range(0, len(data), 4096):
            parser.parse_buffer(data[i : i + 4096])

    t_ours = _best_of(ours)
    t_theirs = _best_of(pymavlink_parser)
    rate_in = count / duration_s
    figures: dict[str, Any] = {
        "recording_messages": count,
        "recording_msgs_per_s": round(rate_in, 1),
        "link_core_msgs_per_s": round(count / t_ours),
        "pymavlink_parse_msgs_per_s": round(count / t_theirs),
        "link_core_cpu_pct_at_recorded_rate": round(100 * rate_in * t_ours / count, 2),
    }
    for loss in (0.0, 0.2):
        sim_s, msgs, ok = _upload_under_loss(100, loss, seed=1)
        key = f"upload_100_items_loss{int(loss * 100)}"
        figures[f"{key}_sim_s"] = round(sim_s, 1)
        figures[f"{key}_mission_msgs"] = msgs
        figures[f"{key}_ok"] = ok
    return figures
