"""`gcs watch` in a pseudo-terminal, its screen read back with a terminal emulator
(pyte): a vehicle's line with its position and packets per second, and an alert with
its full meaning as it arrives."""

from __future__ import annotations

import contextlib
import os
import pty
import select
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable

import pyte
import pytest

from swarm_proto import (
    Alert,
    AlertCode,
    GpsFix,
    Severity,
    VehicleInfo,
    VehicleStatus,
    VehicleType,
)
from swarm_proto.session import SwarmBus, ZenohSettings

pytestmark = pytest.mark.network
COLS, ROWS = 110, 30


def test_watch_on_a_terminal(zenoh_router: str) -> None:
    screen = pyte.Screen(COLS, ROWS)
    stream = pyte.ByteStream(screen)
    master, slave = pty.openpty()
    env = {
        **os.environ,
        "COLUMNS": str(COLS),
        "LINES": str(ROWS),
        "TERM": "xterm-256color",
        "PYTHONUNBUFFERED": "1",
        "PYTHONFAULTHANDLER": "1",  # SIGABRT prints every thread's stack: a hang shows where
    }
    import fcntl
    import struct
    import termios

    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", ROWS, COLS, 0, 0))
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "gcs_cli.app",
            "--connect",
            zenoh_router,
            "--swarm",
            "watch",
            "watch",
            "--duration",
            "300",
            "--period",
            "0.3",
        ],
        stdin=slave,
        stdout=slave,
        stderr=slave,
        env=env,
        close_fds=True,
    )
    os.close(slave)
    # The terminal is drained all along, so `gcs watch` never blocks writing to it; the
    # read ends when the process (its last holder) exits and the terminal reads EIO.
    lock = threading.Lock()
    raw: list[bytes] = []

    def drain() -> None:
        while True:
            try:
                data = os.read(master, 65536)
            except OSError:
                return
            if not data:
                return
            with lock:
                raw.append(data)
                stream.feed(data)

    reader = threading.Thread(target=drain, daemon=True)
    reader.start()

    def text() -> str:
        with lock:
            return "\n".join(screen.display)

    def shown(pred: Callable[[], bool], timeout: float) -> bool:
        end = time.monotonic() + timeout
        while not pred():
            if time.monotonic() > end or proc.poll() is not None:
                return pred()
            time.sleep(0.05)
        return True

    stop = threading.Event()
    alert = threading.Event()
    bus = SwarmBus.open(ZenohSettings(mode="client", connect=(zenoh_router,)), "watch")

    def vehicle() -> None:  # vehicle 4 at 5 Hz, and one alert when told
        alerted = False
        bus.declare_alive(4)
        while not stop.wait(0.2):
            now = time.time()
            bus.publish(
                VehicleStatus(
                    4,
                    now,
                    37.4123456,
                    -5.9876543,
                    150.0,
                    120.0,
                    battery_pct=77,
                    gps_fix=GpsFix.FIX_3D,
                    gps_sats=14,
                )
            )
            if int(now * 5) % 5 == 0:
                bus.publish(VehicleInfo(4, VehicleType.PLANE, "Plane", "P4"))
            if alert.is_set() and not alerted:
                bus.publish(
                    Alert(
                        4, now, Severity.CRITICAL, AlertCode.BATTERY_CRITICAL, "battery 12% 13.1 V"
                    )
                )
                alerted = True

    t = threading.Thread(target=vehicle, daemon=True)
    t.start()
    hung = ""
    try:
        # the vehicle on the screen (its status and info): `gcs watch` is subscribed, so
        # the one alert sent from now on reaches it (sent at a fixed time, it was lost
        # while a loaded host was still starting the process). 60 s: Python and its
        # imports on a loaded host
        listening = shown(lambda: "37.41235" in text() and "PLN" in text(), 60.0)
        alert.set()
        seen = listening and shown(lambda: "battery critical" in text(), 30.0)
        shot = text()
        rows_then = shot.splitlines()
    finally:
        stop.set()
        t.join(2)
        bus.close()
        proc.send_signal(signal.SIGINT)  # Ctrl-C quits
        try:
            # it exits within a second; 60 s is what a loaded 2-core host may add
            proc.wait(60)
        except subprocess.TimeoutExpired:
            proc.send_signal(signal.SIGABRT)
            with contextlib.suppress(subprocess.TimeoutExpired):
                proc.wait(10)
            reader.join(5)
            with lock:
                hung = b"".join(raw)[-8000:].decode(errors="replace")
            proc.kill()
            proc.wait(10)
        reader.join(10)
        os.close(master)
    assert not hung, f"gcs watch did not exit within 60 s of Ctrl-C:\n{hung}"
    assert seen, shot
    line = next(row for row in rows_then if row.lstrip().startswith("4 "))
    assert "PLN" in line and "37.41235,-5.98765" in line and "77" in line and "3D/14" in line
    pkt = float(line.split()[-1])
    assert 0.0 < pkt <= 8.0, line  # status at 5 Hz (and info at 1 Hz), as heard
    assert "battery critical: the vehicle returns or lands: battery 12% 13.1 V" in shot, shot
    assert float(line.split()[-3]) < 5.0  # link age: heard lately (a loaded host is slow)
    assert proc.returncode == 0


def test_a_command_shows_its_progress_on_a_terminal(zenoh_router: str) -> None:
    """While a command waits, the terminal shows who is awaited (stderr, a status line)."""
    screen = pyte.Screen(COLS, ROWS)
    stream = pyte.ByteStream(screen)
    master, slave = pty.openpty()
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "gcs_cli.app",
            "--connect",
            zenoh_router,
            "--swarm",
            "prog",
            "cmd",
            "set-base",
            "--point",
            "37.41,-5.98",
            "--id",
            "99",
            "--timeout",
            "4",
        ],
        stdin=slave,
        stdout=slave,
        stderr=slave,
        close_fds=True,
        env={**os.environ, "COLUMNS": str(COLS), "TERM": "xterm-256color"},
    )
    os.close(slave)
    seen = ""
    end = time.monotonic() + 30
    while time.monotonic() < end and proc.poll() is None:
        r, _, _ = select.select([master], [], [], 0.2)
        if r:
            try:
                stream.feed(os.read(master, 65536))
            except OSError:
                break
            text = "\n".join(screen.display)
            if "waiting for 99" in text:
                seen = text
    try:
        while True:  # the rest, once it exited
            r, _, _ = select.select([master], [], [], 0.2)
            if not r:
                break
            stream.feed(os.read(master, 65536))
    except OSError:
        pass
    proc.wait(10)
    os.close(master)
    final = "\n".join(screen.display)
    assert "set-base: 0 answered, waiting for 99" in seen, seen
    assert proc.returncode == 1 and "no answer in" in final, final


def test_record_writes_the_flight_csv(zenoh_router: str, tmp_path: object) -> None:
    """`gcs record`: one row per status heard (a repeated sample once), in the flight
    recorder's format, readable by `gcs plot --track` and `gcs analyze separation`."""
    from pathlib import Path

    from gcs_cli.app import run
    from swarm_proto.trajectory import read_trajectory

    out = Path(str(tmp_path)) / "flight.csv"
    stop = threading.Event()
    bus = SwarmBus.open(ZenohSettings(mode="client", connect=(zenoh_router,)), "rec")

    def vehicles() -> None:
        k = 0
        bus.declare_alive(5)
        while not stop.wait(0.2):
            k += 1
            t = 1.8e9 + k * 0.2
            for vid in (5, 6):
                bus.publish(
                    VehicleStatus(
                        vid,
                        t,
                        37.41 + 1e-5 * k,
                        -5.98,
                        100.0 + vid,
                        90.0,
                        battery_pct=80,
                        fleet_id=vid - 4,
                    )
                )
            bus.publish(
                VehicleStatus(5, t, 37.41 + 1e-5 * k, -5.98, 105.0, 90.0, fleet_id=1)
            )  # again

    t = threading.Thread(target=vehicles, daemon=True)
    t.start()
    try:
        code = run(
            [
                "--connect",
                zenoh_router,
                "--swarm",
                "rec",
                "record",
                str(out),
                "--duration",
                "3",
                "--fleet",
                "1",
            ]
        )
    finally:
        stop.set()
        t.join(2)
        bus.close()
    assert code == 0
    traj = read_trajectory(out)
    assert traj.vehicles == [5]  # --fleet 1 only
    assert len(set(traj.time_s.tolist())) == len(traj.time_s) >= 5  # each sample once
    header = out.read_text().splitlines()[0]
    assert header == (
        "time_s,vehicle,lat,lon,alt_m,alt_rel_m,groundspeed_m_s,heading_deg,"
        "battery_pct,fsm,mission,progress_pct,armed"
    )
