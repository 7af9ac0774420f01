"""over a real node process flying a simulated quadcopter (MAVLink on TCP,
Zenoh on 127.0.0.1):

- the node's process is stopped (SIGSTOP) for 3 s while ArduPilot flies on:
  no link loss is judged, no emergency, the vehicle is not landed; the node reports
  its own stall apart;
- the autopilot reboots (its stores empty, the TCP link dropped): the node reconnects,
  puts the fence and the rally point back and verifies them by download.

Times are not asserted (the machine is shared); the fault campaign measures them
(`make faults`, docs/reliability.md)."""

from __future__ import annotations

import os
import queue
import signal
import time
from collections.abc import Iterator
from pathlib import Path

import msgspec
import pytest

from gcs_cli.ground import GroundStation
from swarm_proto import (
    Alert,
    AlertCode,
    CommandArgs,
    CommandKind,
    FsmState,
    Geometry,
    GeoPoint,
    NoFlyZone,
    Selector,
    SelectorKind,
    SystemClock,
    VehicleInfo,
)
from swarm_proto.session import ZenohSettings
from swarm_sim.core import SITL_HOME
from swarm_sim.runtime import VehicleServer, VehicleSpec
from tests.conftest import free_tcp_port
from tests.swarm_node.processes import peers_of, plain_session, start_node, stop, wait_until

pytestmark = pytest.mark.network
BASE = GeoPoint(SITL_HOME.lat_deg, SITL_HOME.lon_deg, SITL_HOME.alt_m)
SEVEN = Selector(SelectorKind.IDS, (7,))


class Rig:
    """Node 7 on a simulated quadcopter, a ground station, and what the node says."""

    def __init__(self, router: str, swarm: str, log: Path) -> None:
        self.spec = VehicleSpec("copter", port=free_tcp_port(), sysid=7)
        self.server = VehicleServer([self.spec], SystemClock())
        self.server.start_thread()
        self.proc = start_node(
            7, router, swarm, "--autopilot", f"tcp:127.0.0.1:{self.spec.tcp_port}", log=log
        )
        self.log = log
        self.watch = plain_session(router)
        self.alerts: queue.SimpleQueue[Alert] = queue.SimpleQueue()
        self.states: list[FsmState] = []
        self.subs = [
            self.watch.declare_subscriber(
                f"bandada/{swarm}/vehicle/7/alert",
                lambda s: self.alerts.put(msgspec.msgpack.decode(s.payload.to_bytes(), type=Alert)),
            ),
            self.watch.declare_subscriber(
                f"bandada/{swarm}/vehicle/7/info",
                lambda s: self.states.append(
                    msgspec.msgpack.decode(s.payload.to_bytes(), type=VehicleInfo).fsm_state
                ),
            ),
        ]
        assert wait_until(lambda: peers_of(self.watch, swarm, 7) is not None, 40) is not None
        self.gs = GroundStation(ZenohSettings(connect=(router,)), swarm)

    @property
    def sim(self):  # type: ignore[no-untyped-def]
        return self.server.endpoints[0].autopilot

    def command(self, kind: CommandKind, **args: object) -> None:
        acks = self.gs.command(kind, SEVEN, CommandArgs(**args), timeout_s=15)  # type: ignore[arg-type]
        assert [a.accepted for a in acks] == [True], acks

    def drain(self) -> list[Alert]:
        out = []
        while True:
            try:
                out.append(self.alerts.get_nowait())
            except queue.Empty:
                return out

    def close(self) -> int:
        self.gs.close()
        for s in self.subs:
            s.undeclare()
        self.watch.close()
        code = stop(self.proc)
        self.server.close()
        print(self.log.read_text(errors="replace")[-6000:])
        return code


@pytest.fixture
def rig(zenoh_router: str, swarm_db: Path, tmp_path: Path) -> Iterator[Rig]:
    r = Rig(zenoh_router, f"r{os.getpid()}", tmp_path / "node7.log")
    try:
        yield r
    finally:
        assert r.close() == 0


@pytest.mark.soak  # in fast time: test_busy_host.py; a stopped node process: test_node_processes.py
def test_a_stopped_node_does_not_land_its_flying_vehicle(rig: Rig) -> None:
    rig.command(CommandKind.SET_BASE, point=BASE)
    assert wait_until(lambda: rig.states[-1:] == [FsmState.GO_MISSION], 60) is not None
    rig.command(CommandKind.SET_MODE, text="GUIDED")
    rig.command(CommandKind.ARM)
    rig.command(CommandKind.TAKEOFF, value=30.0)
    assert wait_until(lambda: rig.sim.rel_alt_m > 25.0, 60) is not None
    rig.drain()
    os.kill(rig.proc.pid, signal.SIGSTOP)  # 2 s and 3 s in fast time: test_busy_host.py
    time.sleep(3.0)
    os.kill(rig.proc.pid, signal.SIGCONT)
    time.sleep(3.0)
    alerts = rig.drain()
    assert not [a for a in alerts if a.code == AlertCode.AUTOPILOT_LINK_LOSS], alerts
    assert [a for a in alerts if a.code == AlertCode.GENERIC and "stalled" in a.text], alerts
    assert FsmState.EMERGENCY not in rig.states
    assert rig.sim.mode_name == "GUIDED" and rig.sim.armed and rig.sim.rel_alt_m > 25.0
    assert "(this host stalled, not the link)" in rig.log.read_text()


@pytest.mark.soak  # fast time: tests/swarm_sim/test_backstop.py; the campaign's process row
def test_after_an_autopilot_reboot_its_fence_and_rally_point_are_back(rig: Rig) -> None:
    rig.command(CommandKind.SET_BASE, point=BASE)
    zone = NoFlyZone(3, Geometry.circle(SITL_HOME.lat_deg + 0.0015, SITL_HOME.lon_deg, 40.0))
    assert rig.gs.declare_zone(zone, timeout_s=15) == {7}
    assert (
        wait_until(
            lambda: (
                rig.sim.fence_items
                and rig.sim.rally_items
                and rig.sim.params["FENCE_ENABLE"][0] == 1.0
            ),
            30,
        )
        is not None
    )
    time.sleep(2.5)  # the backstop's own check of the new base's rally point done
    fence = [(i.command, i.x, i.y, i.param1) for i in rig.sim.fence_items]
    rally = [(i.x, i.y, i.z) for i in rig.sim.rally_items]
    rig.drain()
    rig.server.reboot(7)  # the stores come back empty, the TCP link drops
    assert wait_until(lambda: rig.server.counters["reboots"] == 1, 5) is not None
    assert (
        wait_until(
            lambda: (
                [(i.command, i.x, i.y, i.param1) for i in rig.sim.fence_items] == fence
                and [(i.x, i.y, i.z) for i in rig.sim.rally_items] == rally
            ),
            60,
        )
        is not None
    )
    assert wait_until(lambda: rig.sim.fence_present(), 10) is not None
    texts = []
    assert (
        wait_until(
            lambda: (
                texts.extend(a.text for a in rig.drain())
                or {
                    "fence restored and verified (autopilot rebooted)",
                    "rally point restored and verified (autopilot rebooted)",
                }
                <= set(texts)
            ),
            30,
        )
        is not None
    ), texts
