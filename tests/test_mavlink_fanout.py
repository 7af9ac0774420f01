"""MAVLink fan-out as shipped (deploy/systemd/bandada-mavlink.service): MAVProxy owns the
autopilot and forwards to local UDP clients. The unit's own command line (its master
and ports swapped for a simulated vehicle and free ports on 127.0.0.1) serves the node's
autopilot link, which tracks and commands the vehicle through it, and at the same time
the radio gateway's GPS time source, which gets the autopilot's SYSTEM_TIME."""

from __future__ import annotations

import configparser
import os
import random
import shlex
import shutil
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import pytest

from tests.conftest import REPO

pytestmark = pytest.mark.network

BIN = Path(sys.executable).parent


def _free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _wait(cond: Callable[[], bool], timeout: float = 30.0) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if cond():
            return True
        time.sleep(0.1)
    return cond()


def _sim_port() -> tuple[int, int]:
    """A free instance for `swarm-sim vehicle` (port 5760 + 10 * instance)."""
    for _ in range(50):
        instance = random.randint(1000, 5900)
        port = 5760 + 10 * instance
        with socket.socket() as s:
            try:
                s.bind(("127.0.0.1", port))
            except OSError:
                continue
        return instance, port
    raise RuntimeError("no free port for the simulated vehicle")


def _stop(proc: subprocess.Popen[bytes]) -> None:
    if proc.poll() is None:
        os.killpg(proc.pid, signal.SIGINT)
        try:
            proc.wait(10)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait(5)


@pytest.mark.skipif(not (BIN / "mavproxy.py").exists(), reason="MAVProxy not installed")
def test_the_node_and_the_radio_gateway_share_the_autopilot(tmp_path: Path) -> None:
    from radio_gateway.runtime.timesource import GPS, time_source_from_spec
    from swarm_node.core.autopilot import requests as rq
    from swarm_node.runtime.autopilot_link import AutopilotLink
    from swarm_proto import SystemClock, VehicleType

    cp = configparser.ConfigParser(strict=False, interpolation=None)
    cp.read(REPO / "deploy" / "systemd" / "bandada-mavlink.service")
    argv = shlex.split(cp["Service"]["ExecStart"])
    instance, sim_port = _sim_port()
    ports = {p: _free_udp_port() for p in ("14550", "14551", "14552")}
    argv[0] = str(BIN / "mavproxy.py")
    for i, arg in enumerate(argv):
        if arg.startswith("--master="):
            argv[i] = f"--master=tcp:127.0.0.1:{sim_port}"
        elif arg.startswith("--state-basedir="):
            argv[i] = f"--state-basedir={tmp_path}"
        elif arg.startswith("--out=udpout:127.0.0.1:"):
            argv[i] = f"--out=udpout:127.0.0.1:{ports[arg.rsplit(':', 1)[1]]}"
    procs: list[subprocess.Popen[bytes]] = []
    link = gps = None
    try:
        log = (tmp_path / "sim.log").open("wb")
        sim = [
            str(BIN / "swarm-sim"),
            "vehicle",
            "--model",
            "copter",
            "--instance",
            str(instance),
            "--sysid",
            "1",
            "--speedup",
            "2",
        ]
        procs.append(
            subprocess.Popen(sim, stdout=log, stderr=subprocess.STDOUT, start_new_session=True)
        )

        def listening() -> bool:
            try:
                socket.create_connection(("127.0.0.1", sim_port), 0.5).close()
                return True
            except OSError:
                return False

        assert _wait(listening), (tmp_path / "sim.log").read_text()
        out = (tmp_path / "mavproxy.log").open("wb")
        procs.append(
            subprocess.Popen(
                argv, cwd=tmp_path, stdout=out, stderr=subprocess.STDOUT, start_new_session=True
            )
        )
        # the node's link (node.toml: autopilot = "udpin:127.0.0.1:14550")
        link = AutopilotLink(
            f"udpin:127.0.0.1:{ports['14550']}", SystemClock(), vehicle_type=VehicleType.COPTER
        )
        link.start()
        # the radio gateway's time source (radio.toml: mavlink:udpin:127.0.0.1:14551)
        gps = time_source_from_spec(f"mavlink:udpin:127.0.0.1:{ports['14551']}")
        assert _wait(lambda: link.state.link_ok and link.state.has_position, 60), (
            tmp_path / "mavproxy.log"
        ).read_text()[-2000:]
        assert link.state.sysid == 1
        assert link.request(rq.SetMode(mode="GUIDED"), timeout_s=20).ok
        assert _wait(lambda: link.state.mode_name == "GUIDED")
        assert _wait(lambda: gps.stratum == GPS, 60)  # GPS time while the node commands
        assert abs(gps.now() - time.time()) < 3600 * 24 * 365
    finally:
        if link is not None:
            link.close()
        if gps is not None:
            gps.close()
        for p in reversed(procs):
            _stop(p)
        shutil.rmtree(tmp_path / "logs", ignore_errors=True)
