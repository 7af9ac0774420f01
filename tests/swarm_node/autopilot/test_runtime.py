"""The AutopilotLink shell over real connections: connection strings, every transport,
link loss reported within 1 s and reconnection without a restart, close semantics."""

from __future__ import annotations

import queue
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from swarm_node.core.autopilot import requests as rq
from swarm_node.core.autopilot.events import ApEvent, LinkLost, LinkRestored
from swarm_node.runtime.autopilot_link import AutopilotLink, InvalidRequest
from swarm_node.runtime.mavlink_transport import Endpoint, check_address, parse_url
from swarm_proto import ScaledClock, SystemClock, VehicleType
from tests.conftest import free_tcp_port

from .fake_autopilot import FakeAutopilot
from .fake_endpoint import FakeEndpoint

WAIT_S = 20.0  # generous wall-clock waits: shared, noisy machine


def wait_for(pred: Callable[[], bool], timeout_s: float = WAIT_S) -> bool:
    end = time.monotonic() + timeout_s
    while time.monotonic() < end:
        if pred():
            return True
        time.sleep(0.01)
    return pred()


@pytest.mark.parametrize(
    ("url", "expected"),
    [
        ("udp:127.0.0.1:14550", Endpoint("udpin", "127.0.0.1", 14550)),
        ("udpin:0.0.0.0:14550", Endpoint("udpin", "0.0.0.0", 14550)),
        ("udp::14550", Endpoint("udpin", "0.0.0.0", 14550)),
        ("127.0.0.1:14550", Endpoint("udpin", "127.0.0.1", 14550)),
        ("udpout:10.0.0.2:14550", Endpoint("udpout", "10.0.0.2", 14550)),
        ("udpbcast:10.0.0.255:14550", Endpoint("udpbcast", "10.0.0.255", 14550)),
        ("tcp:127.0.0.1:5760", Endpoint("tcp", "127.0.0.1", 5760)),
        ("tcpin:0.0.0.0:5760", Endpoint("tcpin", "0.0.0.0", 5760)),
        ("/dev/ttyACM0", Endpoint("serial", device="/dev/ttyACM0", baud=57600)),
        ("/dev/ttyUSB0,921600", Endpoint("serial", device="/dev/ttyUSB0", baud=921600)),
        ("COM3", Endpoint("serial", device="COM3", baud=57600)),
        ("COM3,115200", Endpoint("serial", device="COM3", baud=115200)),
    ],
)
def test_connection_strings_as_mavproxy_writes_them(url: str, expected: Endpoint) -> None:
    assert parse_url(url) == expected


@pytest.mark.parametrize(
    "url", ["", "tcp:nohost", "udp:host:port", "tcp:1.2.3.4:99999", "/dev/x,fast"]
)
def test_bad_connection_strings_raise(url: str) -> None:
    with pytest.raises(ValueError):
        parse_url(url)


def test_udp_semantics_match_pymavlink() -> None:
    """mavutil: udp: and a bare HOST:PORT listen; udpout: sends."""
    from pymavlink import mavutil

    port = free_tcp_port()
    for url, listens in ((f"udp:127.0.0.1:{port}", True), (f"udpout:127.0.0.1:{port}", False)):
        conn = mavutil.mavlink_connection(url)
        try:
            assert conn.udp_server is listens
            assert (parse_url(url).kind == "udpin") is listens
        finally:
            conn.close()


class Events:
    def __init__(self) -> None:
        self.q: queue.Queue[ApEvent] = queue.Queue()
        self.seen: list[ApEvent] = []

    def __call__(self, e: ApEvent) -> None:
        self.q.put(e)
        self.seen.append(e)

    def wait(self, kind: type, timeout_s: float = WAIT_S) -> ApEvent:
        end = time.monotonic() + timeout_s
        while time.monotonic() < end:
            try:
                e = self.q.get(timeout=0.05)
            except queue.Empty:
                continue
            if isinstance(e, kind):
                return e
        raise AssertionError(f"no {kind.__name__} within {timeout_s} s; saw {self.seen[-10:]}")


@pytest.fixture
def clock() -> ScaledClock:
    return ScaledClock(1.0)


def _endpoint_and_url(
    kind: str, clock: ScaledClock, fake: FakeAutopilot
) -> tuple[FakeEndpoint, str]:
    if kind == "tcp":
        ep = FakeEndpoint(fake, clock, "tcp")
        return ep, f"tcp:127.0.0.1:{ep.port}"
    if kind == "tcpin":
        port = free_tcp_port()
        ep = FakeEndpoint(fake, clock, "tcpout", port)
        return ep, f"tcpin:127.0.0.1:{port}"
    if kind == "udpout":
        ep = FakeEndpoint(fake, clock, "udp")
        return ep, f"udpout:127.0.0.1:{ep.port}"
    if kind == "udpin":
        port = free_tcp_port()
        ep = FakeEndpoint(fake, clock, "udpout", port)
        return ep, f"udpin:127.0.0.1:{port}"
    if kind == "serial":
        ep = FakeEndpoint(fake, clock, "pty")
        return ep, f"{ep.device},115200"
    raise ValueError(kind)


@pytest.fixture(params=["tcp", "tcpin", "udpout", "udpin", "serial"])
def running(
    request: pytest.FixtureRequest, clock: ScaledClock
) -> Iterator[tuple[AutopilotLink, FakeEndpoint, Events]]:
    fake = FakeAutopilot("copter")
    ep, url = _endpoint_and_url(request.param, clock, fake)
    ep.start()
    events = Events()
    link = AutopilotLink(url, clock, vehicle_type=VehicleType.COPTER, on_event=events)
    link.start()
    try:
        yield link, ep, events
    finally:
        link.close()
        ep.close()


def test_every_transport_tracks_and_commands(
    running: tuple[AutopilotLink, FakeEndpoint, Events],
) -> None:
    link, ep, _ = running
    assert wait_for(lambda: link.state.link_ok and link.state.has_position)
    assert link.state.sysid == 1 and link.state.mode_name == "STABILIZE"
    result = link.request(rq.SetMode(mode="GUIDED"), timeout_s=WAIT_S)
    assert result.ok, result
    assert link.request(rq.Arm(), timeout_s=WAIT_S).ok
    assert wait_for(lambda: link.state.armed and link.state.mode_name == "GUIDED")
    status = link.vehicle_status(7)
    assert status is not None and status.vehicle_id == 7 and status.armed
    # SET_MESSAGE_INTERVAL was asked for every tracked message
    intervals = [m for m in ep.fake.received if m.get_type() == "COMMAND_LONG" and m.command == 511]
    assert len(intervals) >= 11
    assert any(m.get_type() == "HEARTBEAT" for m in ep.fake.received)


def test_link_loss_within_one_second_and_restoration_without_restart(clock: ScaledClock) -> None:
    fake = FakeAutopilot("copter")
    ep = FakeEndpoint(fake, clock, "tcp").start()
    events = Events()
    link = AutopilotLink(f"tcp:127.0.0.1:{ep.port}", clock, on_event=events)
    try:
        link.start()
        assert wait_for(lambda: link.state.link_ok)
        # the autopilot goes silent (a radio fade): LinkLost. That it comes 0.9 s after the
        # last message is checked on the pure core with a manual clock (test_link_core);
        # here, on a shared machine, only that it is not early and not absurdly late.
        ep.paused = True
        lost = events.wait(LinkLost)
        assert isinstance(lost, LinkLost) and 0.9 <= lost.silent_s < 5.0
        ep.paused = False
        restored = events.wait(LinkRestored)
        assert isinstance(restored, LinkRestored)
        # the TCP connection drops (SITL restarted): the link reconnects by itself
        ep.drop_client()
        assert wait_for(lambda: link.stats()["reconnects"] >= 1)
        assert wait_for(lambda: link.state.link_ok)
        assert link.request(rq.SetMode(mode="LOITER"), timeout_s=WAIT_S).ok
    finally:
        link.close()
        ep.close()


@pytest.mark.parametrize(
    ("url", "problem"),
    [
        ("garbage", "no such device 'garbage'"),
        ("/dev/nonexistent", "no such device '/dev/nonexistent'"),
        ("tcp:999.0.0.1:5760", "'999.0.0.1' is not an IP address"),
        ("tcp:no-such-host.invalid:5760", "cannot resolve host 'no-such-host.invalid'"),
        ("udp:127.0.0.1:x", "expected HOST:PORT"),
    ],
)
def test_an_address_that_cannot_work_is_refused_before_opening(url: str, problem: str) -> None:
    with pytest.raises(ValueError, match=problem):
        check_address(url)


def test_addresses_that_may_work_pass(tmp_path: Path) -> None:
    device = tmp_path / "ttyACM0"
    device.touch()
    for url in ("tcp:127.0.0.1:5760", "tcp:localhost:5760", "udpin:0.0.0.0:14550", "COM3"):
        check_address(url)
    assert check_address(f"{device},921600").baud == 921600


def test_the_link_says_why_nothing_is_heard(clock: ScaledClock) -> None:
    """Refused, then open and silent: what the node's "no autopilot yet" alert says."""
    import socket

    port = free_tcp_port()
    link = AutopilotLink(f"tcp:127.0.0.1:{port}", clock, reopen_interval_s=0.1)
    link.start()
    try:
        assert wait_for(lambda: "refused" in link.state.link_problem), link.state.link_problem
        with socket.socket() as server:  # a listener that never speaks
            server.bind(("127.0.0.1", port))
            server.listen()
            assert wait_for(lambda: link.state.link_problem.endswith("open, nothing heard"))
        assert link.state.link_problem.startswith(f"tcp:127.0.0.1:{port}")
    finally:
        link.close()


def test_the_autopilot_may_start_after_the_link(clock: ScaledClock) -> None:
    port = free_tcp_port()
    events = Events()
    link = AutopilotLink(f"tcp:127.0.0.1:{port}", clock, on_event=events, reopen_interval_s=0.1)
    link.start()
    try:
        time.sleep(0.3)  # nobody listening yet: connection refused, retried
        assert not link.state.link_ok
        ep = FakeEndpoint(FakeAutopilot("rover"), clock, "tcp", port).start()
        try:
            assert wait_for(lambda: link.state.link_ok)
            assert link.state.vehicle_type == VehicleType.ROVER
            assert link.state.link_problem == ""  # heard: nothing to explain
        finally:
            ep.close()
    finally:
        link.close()


def test_serial_device_that_disappears_is_reopened(clock: ScaledClock, tmp_path: Path) -> None:
    """Like a USB radio unplugged and plugged back: the node opens a stable udev-style
    name (here a symlink to a pseudo-terminal) that points to a new device later."""
    device = tmp_path / "ttyAUTOPILOT"
    ep = FakeEndpoint(FakeAutopilot("boat"), clock, "pty").start()
    device.symlink_to(ep.device)
    events = Events()
    link = AutopilotLink(str(device), clock, baud=57600, on_event=events, reopen_interval_s=0.1)
    link.start()
    try:
        assert wait_for(lambda: link.state.link_ok)
        ep.close()  # unplugged
        device.unlink()
        events.wait(LinkLost)
        ep = FakeEndpoint(FakeAutopilot("boat"), clock, "pty").start()
        device.symlink_to(ep.device)  # plugged back in
        events.wait(LinkRestored)
        assert link.stats()["reconnects"] >= 1
        assert link.request(rq.SetMode(mode="HOLD"), timeout_s=WAIT_S).ok
    finally:
        link.close()
        ep.close()


def test_requests_end_cancelled_on_close_and_invalid_ones_raise(clock: ScaledClock) -> None:
    fake = FakeAutopilot("plane")
    fake.silent_commands.add(176)
    ep = FakeEndpoint(fake, clock, "tcp").start()
    link = AutopilotLink(f"tcp:127.0.0.1:{ep.port}", clock, vehicle_type=VehicleType.VTOL)
    link.start()
    try:
        assert wait_for(lambda: link.state.link_ok)
        with pytest.raises(InvalidRequest):
            link.submit(rq.SetMode(mode="LAND"))  # a copter mode: not a QuadPlane one
        with pytest.raises(InvalidRequest):
            link.submit(rq.Goto(lat_deg=float("nan"), lon_deg=0.0, alt_rel_m=10))
        pending = link.submit(rq.SetMode(mode="QLOITER"))
    finally:
        link.close()
        ep.close()
    result = pending.result(timeout=WAIT_S)
    assert not result.ok and result.error == rq.ApError.CANCELLED
    with pytest.raises(RuntimeError):
        link.submit(rq.Arm())


def test_events_go_to_a_queue_without_a_callback() -> None:
    clock = SystemClock()
    fake = FakeAutopilot("copter")
    ep = FakeEndpoint(fake, clock, "tcp").start()
    with AutopilotLink(f"tcp:127.0.0.1:{ep.port}", clock) as link:
        first = link.events.get(timeout=WAIT_S)
        assert type(first).__name__ == "AutopilotFound"
    ep.close()


def test_tcpin_accepts_a_new_client_when_the_old_one_is_gone(clock: ScaledClock) -> None:
    port = free_tcp_port()
    link = AutopilotLink(f"tcpin:127.0.0.1:{port}", clock)
    link.start()
    ep = FakeEndpoint(FakeAutopilot("copter"), clock, "tcpout", port).start()
    try:
        assert wait_for(lambda: link.state.link_ok)
        ep.drop_client()  # the autopilot side reconnects
        assert wait_for(lambda: link.request(rq.SetMode(mode="LOITER"), timeout_s=WAIT_S).ok)
    finally:
        ep.close()
        link.close()
