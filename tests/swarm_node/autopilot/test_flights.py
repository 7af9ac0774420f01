"""The autopilot link flies simulated vehicles (swarm_sim, the MAVLink vehicle
simulator) through arm -> take-off -> uploaded mission -> RTL -> land, checking the
MAVLink the link sends.

Fast time without sockets: the link core and the simulator's endpoint exchange real
MAVLink bytes while time jumps to the next deadline (a 10-minute sortie in seconds).
`test_copter_sortie_through_tcp_in_scaled_time` runs the real stack: AutopilotLink
thread, the simulator's TCP server, a shared ScaledClock.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from typing import Any

import pytest

from swarm_node.core.autopilot import requests as rq
from swarm_node.core.autopilot.events import (
    ApEvent,
    LinkLost,
    MissionItemReached,
    ModeChanged,
)
from swarm_node.core.autopilot.items import ItemKind, Waypoint
from swarm_node.core.autopilot.link import Complete, Emit, LinkCore, LinkSettings, Output, Transmit
from swarm_node.core.autopilot.requests import ApError, ApResult
from swarm_node.core.autopilot.status import to_vehicle_status
from swarm_proto import VehicleType, validate

sim = pytest.importorskip("swarm_sim.core")
HOME = sim.SITL_HOME
M_PER_DEG = 111_320.0


def offset(north_m: float, east_m: float) -> tuple[float, float]:
    return (
        HOME.lat_deg + north_m / M_PER_DEG,
        HOME.lon_deg + east_m / (M_PER_DEG * math.cos(math.radians(HOME.lat_deg))),
    )


def distance_m(lat: float, lon: float, lat2: float, lon2: float) -> float:
    dn = (lat2 - lat) * M_PER_DEG
    de = (lon2 - lon) * M_PER_DEG * math.cos(math.radians(lat))
    return math.hypot(dn, de)


class SimFlight:
    """LinkCore <-> simulated vehicle, real MAVLink bytes, time jumping to deadlines."""

    def __init__(self, model: str, vtype: VehicleType, now: float = 1.8e9) -> None:
        self.ep = sim.VehicleEndpoint.create(model, home=HOME, now=now)
        self.core = LinkCore(LinkSettings(vehicle_type=vtype), now)
        self.now = now
        self.sent: list[Any] = []
        self.events: list[ApEvent] = []
        self.results: dict[int, ApResult] = {}
        self._token = 0

    def _outputs(self, outputs: list[Output]) -> bytes:
        data = bytearray()
        for o in outputs:
            if isinstance(o, Transmit):
                self.sent.append(o.message)
                data += o.data
            elif isinstance(o, Emit):
                self.events.append(o.event)
            elif isinstance(o, Complete):
                self.results[o.token] = o.result
        return bytes(data)

    def _exchange(self, to_vehicle: bytes) -> None:
        while to_vehicle:
            back = self.ep.receive(to_vehicle, self.now)
            to_vehicle = self._outputs(self.core.receive(back, self.now)) if back else b""

    def step(self) -> None:
        ep_deadline = self.ep.next_deadline()
        t = self.core.next_deadline()
        if ep_deadline is not None:
            t = min(t, ep_deadline)
        self.now = max(self.now, t)
        if ep_deadline is not None and ep_deadline <= self.now:
            data = self.ep.on_timer(self.now)
            if data:
                self._exchange(self._outputs(self.core.receive(data, self.now)))
        if self.core.next_deadline() <= self.now:
            self._exchange(self._outputs(self.core.on_timer(self.now)))

    def wait(self, pred: Callable[[], bool], max_s: float, what: str) -> None:
        end = self.now + max_s
        while not pred():
            assert self.now < end, f"{what}: not within {max_s} s (state {self.core.state})"
            self.step()

    def do(self, request: rq.ApRequest, max_s: float = 120.0) -> ApResult:
        self._token += 1
        token = self._token
        self._exchange(self._outputs(self.core.submit(token, request, self.now)))
        self.wait(lambda: token in self.results, max_s, type(request).__name__)
        return self.results[token]

    @property
    def state(self) -> Any:
        return self.core.state

    def commands(self) -> list[tuple[str, int | str]]:
        """What the link sent, as (message, command or mode) in order, without the
        stream requests, heartbeats and the requests for one (a mode confirmed)."""
        out: list[tuple[str, int | str]] = []
        for m in self.sent:
            t = m.get_type()
            if t == "COMMAND_LONG" and m.command == 176:
                out.append(("MODE", int(m.param2)))
            elif t in ("COMMAND_LONG", "COMMAND_INT") and m.command not in (511, 512):
                out.append((t, int(m.command)))
            elif t in ("MISSION_COUNT", "PARAM_SET"):
                out.append((t, int(m.count) if t == "MISSION_COUNT" else m.param_id))
        return out


def route(n: int, spacing_m: float, alt: float) -> list[Waypoint]:
    return [
        Waypoint(lat_deg=p[0], lon_deg=p[1], alt_rel_m=alt)
        for p in (offset(spacing_m * (i + 1), spacing_m * (i % 2)) for i in range(n))
    ]


def fly_mission(f: SimFlight, waypoints: list[Waypoint], max_s: float) -> ApResult:
    """Upload has happened; start the mission and wait until its last item is reached."""
    last = f.state.mission_count - 1
    started = f.do(rq.StartMission())
    assert started.ok, started
    f.wait(lambda: f.state.mission_reached >= last, max_s, "mission")
    reached = [e.seq for e in f.events if isinstance(e, MissionItemReached)]
    assert reached[-len(waypoints) :] == list(range(last - len(waypoints) + 1, last + 1))
    return started


def check_statuses(f: SimFlight) -> None:
    status = to_vehicle_status(f.state, vehicle_id=3, now_unix_s=f.now)
    assert status is not None
    validate(status)
    assert status.time_unix_s == pytest.approx(f.now, abs=1.0)  # GPS time = sim clock


def ready(f: SimFlight) -> None:
    f.wait(
        lambda: f.state.link_ok and f.state.ekf_has_position and f.state.home is not None, 60, "EKF"
    )


def test_copter_sortie() -> None:
    f = SimFlight("copter", VehicleType.COPTER)
    # before the EKF has a position, ArduPilot (and the simulator) refuse GUIDED
    f.wait(lambda: f.state.link_ok, 10, "link")
    early = f.do(rq.SetMode(mode="GUIDED"))
    assert not early.ok and early.error == ApError.NO_POSITION, early
    ready(f)
    wps = route(3, 60.0, 30.0)
    assert f.do(rq.UploadMission(items=tuple(wps))).ok
    assert f.do(rq.SetMode(mode="GUIDED")).ok
    assert f.do(rq.Arm()).ok
    assert f.do(rq.Takeoff(alt_rel_m=30.0)).ok
    f.wait(lambda: (f.state.alt_rel_m or 0) > 28.0, 60, "climb")
    check_statuses(f)
    target = offset(-40.0, 30.0)
    assert f.do(rq.Goto(lat_deg=target[0], lon_deg=target[1], alt_rel_m=30.0)).ok
    assert f.do(rq.ChangeSpeed(speed_m_s=4.0)).ok
    f.wait(lambda: distance_m(f.state.lat_deg, f.state.lon_deg, *target) < 3, 120, "goto")
    assert f.do(rq.ChangeAltitude(alt_rel_m=45.0)).ok
    f.wait(lambda: (f.state.alt_rel_m or 0) > 44.0, 60, "climb to 45 m")
    assert distance_m(f.state.lat_deg, f.state.lon_deg, *target) < 3  # stayed over the target
    fly_mission(f, wps, 300)
    assert f.do(rq.ReturnToLaunch()).ok
    f.wait(
        lambda: distance_m(f.state.lat_deg, f.state.lon_deg, HOME.lat_deg, HOME.lon_deg) < 5,
        300,
        "home",
    )
    assert f.do(rq.Land()).ok
    f.wait(lambda: not f.state.armed, 300, "landed and disarmed")
    assert (f.state.alt_rel_m or 0) < 1.0
    assert f.commands() == [
        ("MODE", 4),  # the early refusal
        ("MISSION_COUNT", 4),
        ("MODE", 4),
        ("COMMAND_LONG", 400),
        ("COMMAND_LONG", 22),
        ("COMMAND_INT", 192),  # Goto
        ("COMMAND_LONG", 178),
        ("COMMAND_INT", 192),  # ChangeAltitude: reposition to the Goto target, higher
        ("COMMAND_LONG", 224),  # DO_SET_MISSION_CURRENT 1
        ("MODE", 3),
        ("COMMAND_LONG", 300),
        ("MODE", 6),
        ("MODE", 9),
    ]
    assert not any(isinstance(e, LinkLost) for e in f.events)
    modes = [e.mode for e in f.events if isinstance(e, ModeChanged)]
    assert modes[-4:] == ["GUIDED", "AUTO", "RTL", "LAND"]


def test_vtol_sortie() -> None:
    f = SimFlight("vtol", VehicleType.VTOL)
    ready(f)
    wps = route(3, 500.0, 60.0)
    assert f.do(rq.UploadMission(items=tuple(wps))).ok
    assert f.do(rq.SetMode(mode="GUIDED")).ok
    assert f.do(rq.Arm()).ok
    assert f.do(rq.Takeoff(alt_rel_m=40.0)).ok
    f.wait(lambda: (f.state.alt_rel_m or 0) > 38.0, 120, "vertical climb")
    check_statuses(f)
    assert f.do(rq.StartMission()).ok
    f.wait(lambda: f.state.mission_reached >= 1, 300, "first waypoint")
    assert f.do(rq.ChangeSpeed(speed_m_s=24.0)).ok  # airspeed, in AUTO
    assert f.do(rq.ChangeAltitude(alt_rel_m=90.0)).ok
    f.wait(lambda: (f.state.alt_rel_m or 0) > 85.0, 120, "climb to 90 m")
    f.wait(lambda: f.state.mission_reached >= 3, 600, "mission")
    assert f.do(rq.ReturnToLaunch()).ok
    f.wait(
        lambda: distance_m(f.state.lat_deg, f.state.lon_deg, HOME.lat_deg, HOME.lon_deg) < 250,
        600,
        "home",
    )
    assert f.do(rq.Land()).ok  # QLAND
    f.wait(lambda: not f.state.armed, 600, "landed and disarmed")
    assert f.commands() == [
        ("MISSION_COUNT", 4),
        ("MODE", 15),
        ("COMMAND_LONG", 224),  # ArduPlane: out of a landing sequence before arming
        ("COMMAND_LONG", 400),
        ("COMMAND_LONG", 22),
        ("COMMAND_LONG", 224),  # DO_SET_MISSION_CURRENT 1
        ("MODE", 10),
        ("COMMAND_LONG", 300),
        ("COMMAND_LONG", 178),
        ("COMMAND_INT", 186),
        ("MODE", 11),
        ("MODE", 20),
    ]
    speed = next(m for m in f.sent if m.get_type() == "COMMAND_LONG" and m.command == 178)
    assert (speed.param1, speed.param2) == (0.0, 24.0)  # airspeed
    assert f.state.mode_name == "QLAND"


def test_plane_sortie() -> None:
    f = SimFlight("plane", VehicleType.PLANE)
    ready(f)
    wps = route(3, 500.0, 80.0)
    landing = [Waypoint(ItemKind.LAND, lat_deg=HOME.lat_deg, lon_deg=HOME.lon_deg)]
    up = f.do(rq.UploadMission(items=(*wps, Waypoint(ItemKind.RTL), *landing)))
    assert up.ok
    assert any(i.command == 189 for i in up.items)  # DO_LAND_START marks the landing sequence
    assert f.do(rq.Arm()).ok
    assert f.do(rq.Takeoff(alt_rel_m=60.0)).ok
    f.wait(lambda: (f.state.alt_rel_m or 0) > 55.0, 180, "climb in TAKEOFF mode")
    check_statuses(f)
    last_wp = len(wps)
    assert f.do(rq.StartMission()).ok
    f.wait(lambda: f.state.mission_reached >= last_wp, 600, "mission")
    assert f.do(rq.ReturnToLaunch()).ok
    f.wait(
        lambda: distance_m(f.state.lat_deg, f.state.lon_deg, HOME.lat_deg, HOME.lon_deg) < 400,
        600,
        "home",
    )
    land = f.do(rq.Land())
    # The link sends DO_LAND_START, which ArduPlane (and the simulator) answer by
    # jumping to the mission's landing sequence.
    assert land.ok, land
    f.wait(lambda: not f.state.armed or (f.state.alt_rel_m or 99) < 1.0, 900, "landing")
    sent = f.commands()
    assert sent[:8] == [
        ("MISSION_COUNT", 7),
        ("COMMAND_LONG", 224),  # ArduPlane: out of a landing sequence before arming
        ("COMMAND_LONG", 400),
        ("PARAM_SET", "TKOFF_ALT"),
        ("MODE", 13),
        ("COMMAND_LONG", 224),  # DO_SET_MISSION_CURRENT 1
        ("MODE", 10),
        ("COMMAND_LONG", 300),
    ]
    assert sent[8:10] == [("MODE", 11), ("COMMAND_LONG", 189)]


@pytest.mark.parametrize("model", ["rover", "boat"])
def test_ground_vehicle_sortie(model: str) -> None:
    vt = VehicleType.ROVER if model == "rover" else VehicleType.BOAT
    f = SimFlight(model, vt)
    ready(f)
    wps = route(3, 40.0, 0.0)
    assert f.do(rq.UploadMission(items=tuple(wps))).ok
    assert f.do(rq.Arm()).ok
    takeoff = f.do(rq.Takeoff(alt_rel_m=10))
    assert takeoff.ok and "nothing to do" in takeoff.reason
    fly_mission(f, wps, 600)
    assert f.do(rq.ReturnToLaunch()).ok
    f.wait(
        lambda: distance_m(f.state.lat_deg, f.state.lon_deg, HOME.lat_deg, HOME.lon_deg) < 10,
        600,
        "home",
    )
    assert f.do(rq.Land()).ok  # HOLD
    assert f.do(rq.Disarm()).ok
    f.wait(lambda: not f.state.armed, 10, "disarmed")
    assert f.commands() == [
        ("MISSION_COUNT", 4),
        ("COMMAND_LONG", 400),
        ("COMMAND_LONG", 224),  # DO_SET_MISSION_CURRENT 1
        ("MODE", 10),
        ("COMMAND_LONG", 300),
        ("MODE", 11),
        ("MODE", 4),
        ("COMMAND_LONG", 400),
    ]


def test_fence_rally_and_mission_round_trip_with_the_simulator() -> None:
    f = SimFlight("copter", VehicleType.COPTER)
    ready(f)
    box = [offset(-500, -500), offset(500, -500), offset(500, 500), offset(-500, 500)]
    nfz = [offset(100, 100), offset(150, 100), offset(150, 150)]
    fence = rq.UploadFence(
        inclusion_polygons=(tuple(box),),
        exclusion_polygons=(tuple(nfz),),
        exclusion_circles=((*offset(-200, 0), 40.0),),
        enable=True,
    )
    assert f.do(fence).ok
    assert f.do(rq.UploadRally(points=((*offset(50, 0), 30.0),))).ok
    up = f.do(rq.UploadMission(items=tuple(route(4, 30, 20))))
    assert up.ok
    for kind, n in (
        (rq.MissionKind.FENCE, 8),
        (rq.MissionKind.RALLY, 1),
        (rq.MissionKind.MISSION, 5),
    ):
        down = f.do(rq.DownloadMission(kind=kind))
        assert down.ok and len(down.items) == n, down
    down = f.do(rq.DownloadMission(kind=rq.MissionKind.MISSION))
    assert all(a.same_as(b) for a, b in zip(down.items[1:], up.items[1:], strict=True))
    assert f.ep.autopilot.params["FENCE_ENABLE"][0] == 1.0


def test_copter_sortie_through_tcp_in_scaled_time() -> None:
    """The whole stack: AutopilotLink (thread, TCP client) and the simulator's TCP
    server share one ScaledClock running 5x faster than the wall clock."""
    from swarm_node.runtime.autopilot_link import AutopilotLink
    from swarm_proto import ScaledClock
    from swarm_sim.runtime import VehicleServer, VehicleSpec
    from tests.conftest import free_tcp_port

    clock = ScaledClock(5.0)
    port = free_tcp_port()
    server = VehicleServer([VehicleSpec("copter", instance=0, port=port)], clock)
    sent: list[Any] = []
    with server:
        link = AutopilotLink(
            f"tcp:127.0.0.1:{port}", clock, vehicle_type=VehicleType.COPTER, on_send=sent.append
        )
        with link:
            deadline = time.monotonic() + 120

            def until(pred: Callable[[], bool], what: str) -> None:
                while not pred():
                    assert time.monotonic() < deadline, what
                    time.sleep(0.02)

            def do(req: rq.ApRequest) -> ApResult:
                for _ in range(5):  # a noisy machine may starve the thread past a timeout
                    res = link.request(req, timeout_s=30)
                    if res.ok or res.error not in (ApError.LINK_DOWN, ApError.TIMEOUT):
                        return res
                return res

            until(lambda: link.state.ekf_has_position, "EKF")
            assert do(rq.UploadMission(items=tuple(route(2, 30, 15)))).ok
            assert do(rq.SetMode(mode="GUIDED")).ok
            assert do(rq.Arm()).ok
            assert do(rq.Takeoff(alt_rel_m=15)).ok
            until(lambda: (link.state.alt_rel_m or 0) > 13, "climb")
            assert do(rq.StartMission()).ok
            until(lambda: link.state.mission_reached >= 2, "mission")
            assert do(rq.Land()).ok
            until(lambda: not link.state.armed, "landed")
    kinds = [m.get_type() for m in sent]
    assert "HEARTBEAT" in kinds and "MISSION_ITEM_INT" in kinds
    assert [int(m.param2) for m in sent if m.get_type() == "COMMAND_LONG" and m.command == 176][
        -3:
    ] == [4, 3, 9]
