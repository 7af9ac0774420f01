"""A ground station's program attached to a vehicle through `gcs mavlink` (MAVLink
passthrough, docs/ground-station.md), as pymavlink scripts attach to an autopilot:
`make sitl-check`'s passthrough row (against real ArduPilot SITL) and `make bench
BENCH=passthrough` use it.

    with gcs_mavlink(endpoint, swarm, vehicle_id, logs) as url:
        c = PassthroughClient(url)
        c.param_read("RTL_ALT")              # (value, round trip in seconds)
        c.download(0)                         # the mission's items
"""

from __future__ import annotations

import contextlib
import os
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any


def free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@contextlib.contextmanager
def gcs_mavlink(
    endpoint: str,
    swarm: str,
    vehicle_id: int,
    log: Path,
    *extra: str,
    gcs_id: int = 902,
    mode: str = "client",
) -> Iterator[str]:
    """`gcs mavlink --id VEHICLE` in its own process, serving one local UDP port: yields
    the pymavlink URL to attach to (`udpout:`: the client speaks first)."""
    port = free_udp_port()
    cmd = [sys.executable, "-m", "gcs_cli.app", "--connect", endpoint, "--mode", mode]
    cmd += ["--swarm", swarm, "--gcs-id", str(gcs_id), "mavlink", "--id", str(vehicle_id)]
    cmd += ["--serve", f"udp:127.0.0.1:{port}", *extra]
    with open(log, "ab") as out:
        proc = subprocess.Popen(cmd, stdout=out, stderr=subprocess.STDOUT, env=dict(os.environ))
    try:
        yield f"udpout:127.0.0.1:{port}"
    finally:
        proc.terminate()
        try:
            proc.wait(10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


class PassthroughClient:
    """A pymavlink client (QGroundControl's ids: 255/190) with timed requests."""

    def __init__(self, url: str) -> None:
        from pymavlink import mavutil

        self.conn: Any = mavutil.mavlink_connection(url, source_system=255, source_component=190)
        self.target = (0, 0)

    def attach(self, timeout_s: float = 30.0) -> bool:
        """Heartbeats until the autopilot's comes back (the session opens on ours)."""
        end = time.monotonic() + timeout_s
        while time.monotonic() < end:
            self.conn.mav.heartbeat_send(6, 8, 0, 0, 4)
            m = self.conn.recv_match(type="HEARTBEAT", blocking=True, timeout=0.5)
            if m is not None and m.type != 6:
                self.target = (m.get_srcSystem(), m.get_srcComponent())
                return True
        return False

    def _drain(self) -> None:
        while self.conn.recv_match(blocking=False) is not None:
            pass

    def param_read(self, name: str, timeout_s: float = 5.0) -> tuple[float, float] | None:
        """(value, round-trip seconds) of one PARAM_REQUEST_READ, or None."""
        self._drain()
        t0 = time.monotonic()
        self.conn.mav.param_request_read_send(*self.target, name.encode(), -1)
        end = t0 + timeout_s
        while time.monotonic() < end:
            m = self.conn.recv_match(type="PARAM_VALUE", blocking=True, timeout=0.2)
            if m is not None and m.param_id == name:
                return float(m.param_value), time.monotonic() - t0
        return None

    def param_list(self, timeout_s: float = 60.0) -> tuple[dict[str, float], int, float]:
        """(every parameter received by name, how many the autopilot has, seconds): one
        PARAM_REQUEST_LIST, then the missing ones asked for by index, as QGroundControl
        does."""
        self._drain()
        t0 = time.monotonic()
        self.conn.mav.param_request_list_send(*self.target)
        got: dict[int, tuple[str, float]] = {}
        count = -1
        end = t0 + timeout_s
        quiet_since = time.monotonic()
        while time.monotonic() < end and (count < 0 or len(got) < count):
            m = self.conn.recv_match(type="PARAM_VALUE", blocking=True, timeout=0.2)
            if m is not None and 0 <= m.param_index < m.param_count:
                count = int(m.param_count)
                got[int(m.param_index)] = (m.param_id, float(m.param_value))
                quiet_since = time.monotonic()
            elif count > 0 and time.monotonic() - quiet_since > 1.0:
                for i in sorted(set(range(count)) - set(got))[:20]:
                    self.conn.mav.param_request_read_send(*self.target, b"", i)
                quiet_since = time.monotonic()
        return dict(got[i] for i in sorted(got)), count, time.monotonic() - t0

    def download(self, mission_type: int = 0, timeout_s: float = 30.0) -> tuple[list[Any], float]:
        """The items of a store (0 mission, 1 fence, 2 rally), item by item, and the
        seconds it took; items [] when it did not complete."""
        c, (ts, tc) = self.conn, self.target
        self._drain()
        t0 = time.monotonic()
        end = t0 + timeout_s
        count = None
        while count is None and time.monotonic() < end:
            c.mav.mission_request_list_send(ts, tc, mission_type)
            m = c.recv_match(type="MISSION_COUNT", blocking=True, timeout=1.0)
            if m is not None and m.mission_type == mission_type:
                count = int(m.count)
        items: list[Any] = []
        while count is not None and len(items) < count and time.monotonic() < end:
            c.mav.mission_request_int_send(ts, tc, len(items), mission_type)
            m = c.recv_match(type="MISSION_ITEM_INT", blocking=True, timeout=1.0)
            if m is not None and m.mission_type == mission_type and m.seq == len(items):
                items.append(m)
        c.mav.mission_ack_send(ts, tc, 0, mission_type)
        done = count is not None and len(items) == count
        return (items if done else []), time.monotonic() - t0

    def command(
        self, command: int, *params: float, timeout_s: float = 5.0
    ) -> tuple[int, float] | None:
        """(MAV_RESULT, round-trip seconds) of one COMMAND_LONG, or None."""
        self._drain()
        p = [*params, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0][:7]
        t0 = time.monotonic()
        self.conn.mav.command_long_send(*self.target, command, 0, *p)
        end = t0 + timeout_s
        while time.monotonic() < end:
            m = self.conn.recv_match(type="COMMAND_ACK", blocking=True, timeout=0.2)
            if m is not None and m.command == command:
                return int(m.result), time.monotonic() - t0
        return None

    def close(self) -> None:
        with contextlib.suppress(Exception):
            self.conn.close()


def same_items(a: list[Any], b: list[Any]) -> bool:
    """Two downloads of one store hold the same items (command, frame, position)."""
    key = lambda m: (m.seq, m.command, m.frame, m.x, m.y, round(m.z, 2))  # noqa: E731
    return [key(m) for m in a] == [key(m) for m in b]


def check(endpoint: str, swarm: str, vehicle_id: int, log: Path, direct: Any) -> tuple[bool, str]:
    """`make sitl-check`'s passthrough row: attached through `gcs mavlink`, a parameter
    read, every parameter listed, and the mission downloaded as ArduPilot itself gives
    it on a port of its own (`direct`: sitl_check.Downloader)."""
    with gcs_mavlink(endpoint, swarm, vehicle_id, log) as url:
        c = PassthroughClient(url)
        try:
            if not c.attach():
                return False, "no HEARTBEAT through gcs mavlink"
            params, count, list_s = c.param_list()
            if not params:
                return False, "PARAM_REQUEST_LIST unanswered"
            name = next(iter(params))  # index 0 (a format version): read back by name
            one = c.param_read(name)
            items, dl_s = c.download(0)
            want = direct.download(0) if direct is not None else None
            ok = (
                one is not None
                and one[0] == params[name]
                and len(params) == count
                and bool(items)
                and (want is None or same_items(items, want))
            )
            read = "unanswered" if one is None else f"{one[1] * 1000:.0f} ms"
            detail = (
                f"{len(params)}/{count} params in {list_s:.1f} s, {name} read {read}; "
                f"mission {len(items)} items in {dl_s:.2f} s"
                + ("" if want is None else f" ({'=' if same_items(items, want) else '!='} direct)")
            )
            return ok, detail
        finally:
            c.close()
