"""MAVLink passthrough (`gcs mavlink`, swarm_node/core/passthrough.py): a pymavlink
client through `gcs mavlink` -> Zenoh -> the vehicle's node -> a simulated vehicle, in
real time on this machine (the demo's harness: simulator, router, node), beside the
same client attached to the simulator directly. Round trips of a PARAM_REQUEST_READ and
of COMMAND_LONGs, a 100-item mission uploaded and downloaded, the node's CPU while a
client streams, and the radio mode's bytes per vehicle (fast time: FastFleet)."""

from __future__ import annotations

import os
import statistics
import tempfile
import time
from pathlib import Path
from typing import Any

from pymavlink.dialects.v20 import ardupilotmega as mavlink

N_ROUND_TRIPS = 40
MISSION_ITEMS = 100
CPU_WINDOW_S = 20.0


def _ms(xs: list[float]) -> dict[str, float]:
    xs = sorted(x * 1000.0 for x in xs)
    return {
        "median_ms": round(statistics.median(xs), 2),
        "p95_ms": round(xs[max(0, int(0.95 * len(xs)) - 1)], 2),
        "n": len(xs),
    }


def _cpu_s(pid: int) -> float:
    """User + system CPU seconds of a process (Linux /proc)."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def _upload(c: Any, n: int, timeout_s: float = 60.0) -> tuple[bool, float]:
    """A mission of `n` items (home + waypoints) through the client, as a ground station
    uploads it: MISSION_COUNT, then each MISSION_ITEM_INT asked for."""
    ts, tc = c.target
    conn = c.conn
    lat0, lon0 = 374112000, -59889000
    t0 = time.monotonic()
    end = t0 + timeout_s
    conn.mav.mission_count_send(ts, tc, n, 0)
    while time.monotonic() < end:
        m = conn.recv_match(
            type=["MISSION_REQUEST_INT", "MISSION_REQUEST", "MISSION_ACK"],
            blocking=True,
            timeout=1.0,
        )
        if m is None:
            conn.mav.mission_count_send(ts, tc, n, 0)
            continue
        if m.get_type() == "MISSION_ACK":
            return m.type == 0, time.monotonic() - t0
        seq = int(m.seq)
        frame = 0 if seq == 0 else 3
        conn.mav.mission_item_int_send(
            ts, tc, seq, frame, 16, 0, 1, 0, 0, 0, 0, lat0 + 200 * seq, lon0, 30.0, 0
        )
    return False, time.monotonic() - t0


def _round_trips(c: Any, direct: Any) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for label, client in (("passthrough", c), ("direct", direct)):
        reads = [r[1] for _ in range(N_ROUND_TRIPS) if (r := client.param_read("WPNAV_SPEED"))]
        servo = [r[1] for _ in range(N_ROUND_TRIPS) if (r := client.command(183, 9, 1500))]
        modes = []
        for i in range(N_ROUND_TRIPS // 2):  # GUIDED and LOITER in turn: always a change
            r = client.command(176, 1, 4 if i % 2 == 0 else 5)
            if r is not None:
                modes.append(r[1])
        out[label] = {
            "param_request_read": _ms(reads),
            "command_long_do_set_servo": _ms(servo),
            "command_long_do_set_mode": _ms(modes),
        }
    return out


def _stream_cpu(fleet: Any, c: Any, gcs_pid: int) -> dict[str, Any]:
    """The node's CPU over CPU_WINDOW_S with no session, then with a client streaming
    (MAVProxy's request: every stream group at 4 Hz; a HEARTBEAT a second)."""
    node_pid = fleet.nodes[7].pid
    a = _cpu_s(node_pid)
    time.sleep(CPU_WINDOW_S)
    idle = (_cpu_s(node_pid) - a) / CPU_WINDOW_S
    c.conn.mav.request_data_stream_send(*c.target, 0, 4, 1)
    a, g = _cpu_s(node_pid), _cpu_s(gcs_pid)
    frames = nbytes = 0
    t0 = beat = time.monotonic()
    while time.monotonic() - t0 < CPU_WINDOW_S:
        m = c.conn.recv_match(blocking=True, timeout=0.2)
        if m is not None:
            frames += 1
            nbytes += len(m.get_msgbuf())
        if time.monotonic() - beat >= 1.0:
            beat = time.monotonic()
            c.conn.mav.heartbeat_send(6, 8, 0, 0, 4)
    streaming = (_cpu_s(node_pid) - a) / CPU_WINDOW_S
    return {
        "node_cpu_pct_no_session": round(100 * idle, 2),
        "node_cpu_pct_streaming": round(100 * streaming, 2),
        "node_extra_cpu_pct": round(100 * (streaming - idle), 2),
        "gcs_mavlink_cpu_pct_streaming": round(100 * (_cpu_s(gcs_pid) - g) / CPU_WINDOW_S, 2),
        "frames_per_s_to_client": round(frames / CPU_WINDOW_S, 1),
        "bytes_per_s_to_client": round(nbytes / CPU_WINDOW_S),
    }


def lan() -> dict[str, Any]:
    from rich.console import Console

    from swarm_node.database import SwarmDatabase
    from swarm_sim.demo import start, stop
    from swarm_sim.passthrough_check import PassthroughClient, gcs_mavlink

    tmp = Path(tempfile.mkdtemp(prefix="bench-passthrough-"))
    os.environ["BANDADA_DB"] = str(tmp / "swarm.db")
    SwarmDatabase.open(tmp / "swarm.db").close()
    fleet = start((7,), 1.0, tmp, Console(file=open(os.devnull, "w")))  # noqa: SIM115
    try:
        port = next(a for a in fleet.nodes[7].args if str(a).startswith("tcp:"))  # type: ignore[union-attr]
        time.sleep(8.0)  # the vehicle boots, the node attaches
        with gcs_mavlink(fleet.endpoint, "default", 7, tmp / "gcs.log", mode="peer") as url:
            c = PassthroughClient(url)
            direct = PassthroughClient(str(port))
            assert c.attach() and direct.attach(), "no heartbeat"
            figures: dict[str, Any] = {"round_trips": _round_trips(c, direct)}
            ok, up_s = _upload(c, MISSION_ITEMS)
            items, down_s = c.download(0)
            ditems, ddown_s = direct.download(0)
            figures["mission_100"] = {
                "upload_ok": ok,
                "upload_s": round(up_s, 3),
                "download_items": len(items),
                "download_s": round(down_s, 3),
                "direct_download_s": round(ddown_s, 3),
                "same_as_direct": len(items) == len(ditems) == MISSION_ITEMS,
            }
            gcs_pid = _gcs_pid(tmp)
            figures["streaming"] = _stream_cpu(fleet, c, gcs_pid) if gcs_pid else {}
            c.close()
            direct.close()
        return figures
    finally:
        stop(fleet)


def _gcs_pid(tmp: Path) -> int | None:
    """The `gcs mavlink` process (the one child of ours running gcs_cli)."""
    me = os.getpid()
    for d in Path("/proc").iterdir():
        if not d.name.isdigit():
            continue
        try:
            stat = (d / "stat").read_text()
            cmd = (d / "cmdline").read_bytes()
        except OSError:
            continue
        ppid = int(stat.rsplit(")", 1)[1].split()[1])
        if ppid == me and b"gcs_cli.app" in cmd:
            return int(d.name)
    return None


def radio_mode() -> dict[str, Any]:
    """Bytes on the air per vehicle in the radio mode, from what a node publishes in
    fast time (one radio session, 10 minutes, a mode change a minute), each message as
    the radio encodes it plus its 2-byte record header."""
    from swarm_node.core.inputs import Received
    from swarm_node.database import seed_fleet
    from swarm_proto import radio
    from swarm_proto.messages import MavlinkAnswer, MavlinkCommand, MavlinkSummary
    from swarm_sim.fast_fleet import FastFleet

    profiles = {p.vehicle_id: p for p in seed_fleet()}
    fleet = FastFleet.build([7], profiles)
    v7 = fleet.vehicles[7]
    fleet.run_until(lambda: v7.link.state.ekf_has_position, 60)
    gcs = mavlink.MAVLink(None, srcSystem=255, srcComponent=190)
    t0, minutes = fleet.now, 10
    up = 0
    for minute in range(minutes):
        for k in range(3):  # the keep-alive every 20 s
            frame = b""
            if k == 0:
                mode = 4 if minute % 2 == 0 else 5
                frame = bytes(mavlink.MAVLink_set_mode_message(7, 1, mode).pack(gcs))
            cmd = MavlinkCommand(900, 7, frame)
            up += len(radio.encode(cmd)) + 2
            fleet.deliver(7, Received(cmd), fleet.now)
            fleet.run_for(20.0)
    span = fleet.now - t0
    sent = [(m, len(radio.encode(m)) + 2) for t, _, m in fleet.published if t >= t0]
    summaries = [b for m, b in sent if isinstance(m, MavlinkSummary)]
    answers = [b for m, b in sent if isinstance(m, MavlinkAnswer)]
    down = sum(summaries) + sum(answers)
    return {
        "seconds": round(span, 1),
        "summaries": len(summaries),
        "summary_bytes": summaries[0] if summaries else 0,
        "answers": len(answers),
        "vehicle_bytes_per_s": round(down / span, 2),
        "vehicle_bytes_per_cycle": round(down / span * 0.2, 2),
        "ground_station_bytes_per_s": round(up / span, 2),
        "slot_bytes_7_nodes_5ms_guard": 182,
        "note": "on air: radio encoding + 2-byte record header; acked messages also cost "
        "their 16-byte chunking and acknowledgements (radio.md). 182 bytes: one slot's "
        "payload budget with 7 nodes at 5 ms guard (`radio-gateway limits`).",
    }


def run() -> dict[str, Any]:
    return {"lan": lan(), "radio": radio_mode()}
