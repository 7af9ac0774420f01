"""A real third-party ground station attaches: MAVProxy (from PyPI, in .venv) connects
to a simulated vehicle over TCP exactly as it would to ArduPilot SITL, prints the
vehicle's position and switches its mode."""

from __future__ import annotations

import shutil
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from swarm_proto.clock import ScaledClock
from swarm_sim.core import SITL_HOME
from swarm_sim.runtime import VehicleServer, VehicleSpec
from tests.conftest import free_tcp_port


def mavproxy_path() -> str:
    local = Path(sys.executable).parent / "mavproxy.py"
    if local.exists():
        return str(local)
    found = shutil.which("mavproxy.py")
    if found is None:
        pytest.skip("MAVProxy is not installed (pip install MAVProxy)")
    return found


def wait(predicate: object, timeout: float) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():  # type: ignore[operator]
            return True
        time.sleep(0.1)
    return False


def test_mavproxy_reads_position_and_switches_mode(tmp_path: Path) -> None:
    exe = mavproxy_path()
    port = free_tcp_port()
    server = VehicleServer(
        [VehicleSpec("copter", instance=0, home=SITL_HOME, port=port)], ScaledClock(5.0)
    )
    server.start_thread()
    ap = server.endpoints[0].autopilot
    lines: list[str] = []
    proc = subprocess.Popen(
        [
            sys.executable,
            exe,
            "--master",
            f"tcp:127.0.0.1:{port}",
            "--state-basedir",
            str(tmp_path),
        ],
        cwd=tmp_path,
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )
    assert proc.stdin is not None and proc.stdout is not None
    reader = threading.Thread(
        target=lambda: lines.extend(iter(proc.stdout.readline, "")), daemon=True
    )  # type: ignore[union-attr]
    reader.start()
    try:
        if not wait(
            lambda: any("Detected vehicle" in ln or "online system 1" in ln for ln in lines), 30
        ):
            if proc.poll() is not None:
                pytest.skip(f"MAVProxy cannot run here: {''.join(lines)[-500:]}")
            raise AssertionError(f"MAVProxy never saw the vehicle:\n{''.join(lines)}")
        assert wait(lambda: ap.ekf_position, 30)
        time.sleep(1.0)  # let MAVProxy's stream requests and a few positions arrive
        proc.stdin.write("status GLOBAL_POSITION_INT\n")
        proc.stdin.flush()
        assert wait(lambda: any("GLOBAL_POSITION_INT {" in ln for ln in lines), 20), "".join(lines)
        proc.stdin.write("mode GUIDED\n")
        proc.stdin.flush()
        assert wait(lambda: ap.mode_name == "GUIDED", 20), "".join(lines)
        assert wait(lambda: any("GUIDED>" in ln or "Mode GUIDED" in ln for ln in lines), 20), (
            "".join(lines)
        )
        assert wait(lambda: any("Received" in ln and "parameters" in ln for ln in lines), 30)
        proc.stdin.close()  # MAVProxy exits at the end of its input
    finally:
        try:
            proc.wait(timeout=15)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
        reader.join(timeout=5)
        server.close()
    out = "".join(lines)
    position = next(ln for ln in lines if "GLOBAL_POSITION_INT {" in ln)
    assert "lat : 37411" in position and "lon : -5988" in position, position
    assert "DO_SET_MODE: ACCEPTED" in out
    # MAVProxy fetched the parameters (MAVLink FTP is NAKed, so it fell back at once to
    # PARAM_REQUEST_LIST) and saw no fence breach (SYS_STATUS geofence health bit)
    assert ap.counters["rx:PARAM_REQUEST_LIST"] > 0, ap.counters
    assert "fence breach" not in out
