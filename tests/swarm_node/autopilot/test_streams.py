"""Telemetry requests: SET_MESSAGE_INTERVAL for every tracked message when the link
comes up, REQUEST_DATA_STREAM when the autopilot refuses or ignores it, re-requests when
a message stops, and again after a link loss. Our own HEARTBEAT at 1 Hz."""

from __future__ import annotations

from swarm_node.core.autopilot.link import LinkCore, LinkSettings
from swarm_node.core.autopilot.streams import DEFAULT_RATES_HZ, FALLBACK_STREAMS_HZ, message_id
from swarm_proto import VehicleType

from .fake_autopilot import FakeAutopilot, Harness


def setup(**fake_kw: object) -> Harness:
    core = LinkCore(LinkSettings(vehicle_type=VehicleType.COPTER), 1000.0)
    fake = FakeAutopilot("copter")
    for k, v in fake_kw.items():
        setattr(fake, k, v)
    return Harness(core, fake)


def intervals(h: Harness) -> dict[int, float]:
    return {
        int(m.param1): m.param2
        for m in h.sent
        if m.get_type() == "COMMAND_LONG" and m.command == 511
    }


def data_streams(h: Harness) -> list[tuple[int, int]]:
    return [
        (m.req_stream_id, m.req_message_rate)
        for m in h.sent
        if m.get_type() == "REQUEST_DATA_STREAM"
    ]


def test_every_tracked_message_is_requested_at_its_rate() -> None:
    h = setup()
    h.run_until(lambda: h.core.state.link_ok, 5)
    got = intervals(h)
    assert got == {message_id(n): round(1e6 / hz) for n, hz in DEFAULT_RATES_HZ.items()}
    assert got[33] == 100_000  # GLOBAL_POSITION_INT at 10 Hz: link loss seen within 1 s
    h.run_until(lambda: False, 10)
    assert data_streams(h) == []
    heartbeats = [m for m in h.sent if m.get_type() == "HEARTBEAT"]
    assert 10 <= len(heartbeats) <= 12
    assert (heartbeats[0].type, heartbeats[0].autopilot) == (18, 8)  # onboard computer


def test_refused_intervals_fall_back_to_data_streams() -> None:
    h = setup(ack_script={511: [3] * 11})
    h.run_until(lambda: bool(data_streams(h)), 5)
    assert sorted(data_streams(h)) == sorted(FALLBACK_STREAMS_HZ.items())


def test_ignored_intervals_fall_back_too() -> None:
    """(An autopilot that ignores SET_MESSAGE_INTERVAL but streams anyway keeps its
    streams: the fallback is for silence.)"""
    h = setup(silent_commands={511}, _next_telemetry=1e12)  # heartbeats only, no answer
    h.run_until(lambda: bool(data_streams(h)), 10)
    assert len(data_streams(h)) == len(FALLBACK_STREAMS_HZ)


def test_a_message_that_stops_is_asked_for_again_and_all_after_a_link_loss() -> None:
    h = setup()
    h.run_until(lambda: h.core.state.link_ok, 5)
    first = len(intervals_list(h))
    h.run_until(lambda: False, 12)  # EXTENDED_SYS_STATE etc. never come from the fake
    again = intervals_list(h)[first:]
    assert again and all(int(m.param1) != 33 for m in again)  # position does flow
    assert {int(m.param1) for m in again} >= {message_id("VFR_HUD"), message_id("ATTITUDE")}
    before = len(intervals_list(h))
    h.down = True
    h.run_until(lambda: not h.core.state.link_ok, 5)
    h.down = False
    h.run_until(lambda: h.core.state.link_ok, 5)
    assert len(intervals_list(h)) - before >= len(DEFAULT_RATES_HZ)


def intervals_list(h: Harness) -> list:
    return [m for m in h.sent if m.get_type() == "COMMAND_LONG" and m.command == 511]
