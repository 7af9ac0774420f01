"""Autopilot link loss is judged from the autopilot's own data (its time since
boot in GLOBAL_POSITION_INT, ATTITUDE, SYSTEM_TIME), apart from the node's own stalls.
A timer served late (the node stopped, a loaded host) does not declare the link lost
while what the autopilot sent meanwhile waits to be read; a burst read late shows the
stall in the autopilot's timestamps; a real gap shows in them too."""

from __future__ import annotations

import pytest

from swarm_node.core.autopilot.events import HostStalled, LinkLost, LinkRestored
from swarm_node.core.autopilot.tracker import DRAIN_S, LATE_TOLERANCE_S
from tests.swarm_node.autopilot.test_tracker import T0, gpi, tracker, wire


def feed(t: object, start_s: float, boot_ms: int, n: int, period_s: float = 0.1) -> None:
    for k in range(n):
        t.handle(wire(gpi(boot_ms=boot_ms + round(k * period_s * 1000))), start_s + k * period_s)  # type: ignore[attr-defined]


def test_a_late_timer_waits_for_what_is_in_the_socket() -> None:
    """The node stopped 2 s: its link timer runs first on resume, then the bytes that
    waited are read. Before the timer declared the link lost (a WARNING, and an
    EMERGENCY had the node's tick also run late); now it defers and nothing is lost."""
    t = tracker(link_timeout_s=0.6)
    feed(t, T0, 10_000, 5)  # up to T0 + 0.4, boot 10.4 s
    resume = T0 + 0.4 + 2.0
    events = t.on_timer(resume)  # the timer first, 1.4 s past its deadline
    assert [type(e) for e in events] == [HostStalled]
    assert events[0].stall_s == pytest.approx(2.0 - 0.6)
    assert t.state.link_ok and t.state.host_stalls == 1
    # then what the autopilot sent during the stall: its clock ran on, ours did not read
    _, events = t.handle(wire(gpi(boot_ms=10_500)), resume)
    assert [type(e) for e in events] == [HostStalled]  # seen in its timestamps too
    assert events[0].stall_s == pytest.approx(2.0 - 0.1, abs=0.01)
    for k in range(1, 20):
        t.handle(wire(gpi(boot_ms=10_500 + 100 * k)), resume + 0.001 * k)
    assert t.state.link_ok and t.state.link_losses == 0
    assert t.on_timer(resume + 0.1) == []


def test_a_late_timer_with_nothing_waiting_is_a_loss_a_moment_later() -> None:
    t = tracker(link_timeout_s=0.6)
    feed(t, T0, 10_000, 5)
    resume = T0 + 0.4 + 2.0
    assert [type(e) for e in t.on_timer(resume)] == [HostStalled]
    assert t.next_deadline() == pytest.approx(resume + DRAIN_S)
    assert t.on_timer(resume + DRAIN_S / 2) == []
    (lost,) = t.on_timer(resume + DRAIN_S)
    assert isinstance(lost, LinkLost) and not t.state.link_ok


def test_a_timer_on_time_is_not_a_stall() -> None:
    t = tracker(link_timeout_s=0.6)
    feed(t, T0, 10_000, 5)
    (lost,) = t.on_timer(T0 + 0.4 + 0.6 + LATE_TOLERANCE_S / 2)
    assert isinstance(lost, LinkLost) and t.state.host_stalls == 0


def test_a_real_gap_is_measured_in_the_autopilots_own_time() -> None:
    """A radio that lost 3 s of telemetry: the autopilot's clock jumped as ours did."""
    t = tracker(link_timeout_s=0.6)
    feed(t, T0, 10_000, 5)  # last: boot 10.4 s at T0 + 0.4
    (lost,) = t.on_timer(T0 + 1.0)
    assert isinstance(lost, LinkLost)
    _, events = t.handle(wire(gpi(boot_ms=13_400)), T0 + 3.4)
    assert isinstance(events[0], LinkRestored)
    assert events[0].autopilot_gap_s == pytest.approx(3.0)
    assert events[0].down_s == pytest.approx(3.0)
    assert not any(isinstance(e, HostStalled) for e in events)
    assert t.state.link_gap_s == pytest.approx(3.0) and t.state.host_stalls == 0


def test_a_restoring_heartbeat_leaves_the_gap_to_the_next_timed_message() -> None:
    from tests.swarm_node.autopilot.test_tracker import hb

    t = tracker(link_timeout_s=0.6)
    feed(t, T0, 10_000, 5)
    t.on_timer(T0 + 1.0)
    _, events = t.handle(wire(hb()), T0 + 2.4)
    assert isinstance(events[0], LinkRestored) and events[0].autopilot_gap_s == -1.0
    t.handle(wire(gpi(boot_ms=12_500)), T0 + 2.5)
    assert t.state.link_gap_s == pytest.approx(2.1)


def test_a_reboot_is_counted_and_is_no_stall() -> None:
    t = tracker(link_timeout_s=0.6)
    feed(t, T0, 60_000, 5)
    t.handle(wire(gpi(boot_ms=1_000)), T0 + 0.5)  # time since boot went back
    assert t.state.reboots == 1 and t.state.host_stalls == 0
    feed(t, T0 + 0.6, 1_100, 3)
    assert t.state.host_stalls == 0


def test_an_autopilot_that_paused_is_a_loss_not_our_stall() -> None:
    """SITL stopped (SIGSTOP) 3 s: its clock paused with it. The link was judged lost on
    time; what comes after it is no late read of ours."""
    t = tracker(link_timeout_s=0.6)
    feed(t, T0, 10_000, 5)
    (lost,) = t.on_timer(T0 + 1.0)
    assert isinstance(lost, LinkLost)
    _, events = t.handle(wire(gpi(boot_ms=10_500)), T0 + 3.4)  # its clock went on 0.1 s
    assert isinstance(events[0], LinkRestored) and events[0].autopilot_gap_s == pytest.approx(0.1)
    assert not any(isinstance(e, HostStalled) for e in events) and t.state.host_stalls == 0
