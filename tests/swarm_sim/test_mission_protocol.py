"""The mission protocol as ArduPilot runs it (MissionItemProtocol): uploads and
downloads of mission, fence and rally items, errors, timeouts, a second uploader, and
partial loss in both directions."""

from __future__ import annotations

import math

import pytest

from tests.swarm_sim.conftest import Pilot, make_pilot

REL = 3
MISSION, FENCE, RALLY = 0, 1, 2


@pytest.fixture
def p() -> Pilot:
    pilot = make_pilot("copter")
    pilot.wait_ready()
    pilot.c.clear()
    return pilot


def simple_mission(p: Pilot, n: int = 4) -> list[tuple[int, int, float, float, float]]:
    return [(16, 0, 0, 0, 0)] + [(16, REL, 50.0 * k, 10.0, 20) for k in range(1, n)]


def test_upload_asks_with_mission_request_for_every_type(p: Pilot) -> None:
    assert p.upload(simple_mission(p)).type == 0
    fence = [(5001, REL, 0, 0, 0), (5001, REL, 0, 0, 0), (5001, REL, 0, 0, 0)]
    raw = [
        (c, f, (3.0, 0, 0, 0), *p.latlon(n, e), z)
        for (c, f, n, e, z), (n, e) in zip(
            fence, [(-500, -500), (-500, 500), (500, 0)], strict=True
        )
    ]
    assert p.upload_raw(raw, FENCE).type == 0
    rally = [(5100, REL, (0, 0, 0, 0), *p.latlon(100, 100), 30)]
    assert p.upload_raw(rally, RALLY).type == 0
    types = {m.get_type() for _, m in p.c.history}
    assert "MISSION_REQUEST" in types and "MISSION_REQUEST_INT" not in types
    requests = [(m.mission_type, m.seq) for m in p.c.seen("MISSION_REQUEST")]
    assert requests == [(0, 0), (0, 1), (0, 2), (0, 3), (1, 0), (1, 1), (1, 2), (2, 0)]
    assert [m.mission_type for m in p.c.seen("MISSION_ACK")] == [0, 1, 2]
    assert (
        len(p.ap.mission_items) == 4 and len(p.ap.fence_items) == 3 and len(p.ap.rally_items) == 1
    )
    assert p.c.texts().count("Flight plan received") == 1  # mission uploads only
    total = p.c.seen("PARAM_VALUE")[-1]
    assert total.param_id == "MIS_TOTAL" and total.param_value == 3


def test_float_mission_item_accepted_with_arduPilot_warning(p: Pilot) -> None:
    p.c.mav.mission_count_send(1, 1, 2, 0)
    for seq in range(2):
        req = p.h.wait_for(p.c, "MISSION_REQUEST")
        assert req is not None and req.seq == seq
        lat, lon = p.frame.to_latlon(100.0 * seq, 0)
        p.c.mav.mission_item_send(1, 1, seq, REL, 16, 0, 1, 0, 0, 0, 0, lat, lon, 25, 0)
    ack = p.h.wait_for(p.c, "MISSION_ACK")
    assert ack is not None and ack.type == 0
    assert p.c.texts().count("got MISSION_ITEM; GCS should send MISSION_ITEM_INT") == 1
    item = p.ap.mission_items[1]
    assert abs(item.lat_deg - p.frame.to_latlon(100.0, 0)[0]) < 1e-5 and item.z == 25  # float32 lat


def test_download_count_home_and_out_of_range(p: Pilot) -> None:
    assert p.upload(simple_mission(p, 3)).type == 0
    p.c.mav.mission_request_list_send(1, 1, 0)
    assert p.h.wait_for(p.c, "MISSION_COUNT").count == 3
    p.c.mav.mission_request_int_send(1, 1, 7, 0)
    count = p.h.wait_for(p.c, "MISSION_COUNT")
    nak = p.h.wait_for(p.c, "MISSION_ACK")
    assert count.count == 3 and nak.type == 1  # ArduPilot educates the GCS, then ERROR
    for mtype in (FENCE, RALLY):
        p.c.mav.mission_request_list_send(1, 1, mtype)
        assert p.h.wait_for(p.c, "MISSION_COUNT").count == 0
        p.c.mav.mission_request_int_send(1, 1, 0, mtype)
        assert p.h.wait_for(p.c, "MISSION_ACK").type == 13  # INVALID_SEQUENCE


def test_out_of_sequence_item_is_nacked_and_the_transfer_goes_on(p: Pilot) -> None:
    p.c.mav.mission_count_send(1, 1, 2, 0)
    assert p.h.wait_for(p.c, "MISSION_REQUEST").seq == 0
    x, y = p.latlon(10, 10)
    p.c.mav.mission_item_int_send(1, 1, 1, REL, 16, 0, 1, 0, 0, 0, 0, x, y, 10, 0)
    assert p.h.wait_for(p.c, "MISSION_ACK").type == 13
    p.c.mav.mission_item_int_send(1, 1, 0, REL, 16, 0, 1, 0, 0, 0, 0, x, y, 10, 0)
    assert p.h.wait_for(p.c, "MISSION_REQUEST").seq == 1
    p.c.mav.mission_item_int_send(1, 1, 1, REL, 16, 0, 1, 0, 0, 0, 0, x, y, 10, 0)
    assert p.h.wait_for(p.c, "MISSION_ACK").type == 0


def test_request_is_repeated_then_the_upload_times_out(p: Pilot) -> None:
    assert p.upload(simple_mission(p, 5)).type == 0
    p.c.clear()
    t0 = p.h.now
    p.c.mav.mission_count_send(1, 1, 3, 0)
    assert p.h.wait_for(p.c, "MISSION_REQUEST").seq == 0
    ack = p.h.wait_for(p.c, "MISSION_ACK", 20)
    assert ack is not None and ack.type == 15  # OPERATION_CANCELLED
    assert 8.0 <= p.h.now - t0 <= 9.5
    repeats = [m for m in p.c.seen("MISSION_REQUEST") if m.seq == 0]
    assert len(repeats) >= 7  # once a second
    assert "Mission upload timeout" in p.c.texts()
    assert len(p.ap.mission_items) == 3  # truncated to the count, as ArduPilot does


def test_second_uploader_is_denied_first_one_completes(p: Pilot) -> None:
    gcs, other = p.c, p.link.add_client(sysid=200, compid=1)
    gcs.mav.mission_count_send(1, 1, 2, 0)
    assert p.h.wait_for(gcs, "MISSION_REQUEST").seq == 0
    other.mav.mission_count_send(1, 1, 5, 0)
    denied = p.h.wait_for(other, "MISSION_ACK", cond=lambda m: m.target_system == 200)
    assert denied is not None and denied.type == 14
    for seq in range(2):
        x, y = p.latlon(20.0 * (seq + 1), 0)
        gcs.mav.mission_item_int_send(1, 1, seq, REL, 16, 0, 1, 0, 0, 0, 0, x, y, 10, 0)
        p.h.run_for(0.1)
    assert p.h.wait_for(gcs, "MISSION_ACK", cond=lambda m: m.target_system == 255).type == 0
    assert len(p.ap.mission_items) == 2


def test_item_errors(p: Pilot) -> None:
    cases = [
        ((9999, REL, (0, 0, 0, 0), *p.latlon(1, 1), 10), 3),  # UNSUPPORTED command
        ((16, 1, (0, 0, 0, 0), *p.latlon(1, 1), 10), 2),  # UNSUPPORTED_FRAME (LOCAL_NED)
        ((16, REL, (0, 0, 0, 0), 910_000_000, 0, 10), 10),  # INVALID_PARAM5_X
    ]
    for item, result in cases:
        ack = p.upload_raw([(16, 0, (0, 0, 0, 0), 0, 0, 0), item])
        assert ack is not None and ack.type == result, (item, ack)
    p.c.mav.mission_count_send(1, 1, 5000, 0)
    assert p.h.wait_for(p.c, "MISSION_ACK").type == 4  # NO_SPACE
    assert "Only 724 items are supported" in p.c.texts()
    bad_fence = [
        (5001, REL, (4.0, 0, 0, 0), *p.latlon(n, e), 0) for n, e in [(0, 0), (0, 10), (10, 0)]
    ]
    assert p.upload_raw(bad_fence, FENCE).type == 1  # 3 vertices where 4 were announced
    assert p.ap.fence_items == []  # fence uploads commit only when complete and valid


def test_clear_all_per_type_and_all(p: Pilot) -> None:
    assert p.upload(simple_mission(p)).type == 0
    rally = [(5100, REL, (0, 0, 0, 0), *p.latlon(100, 100), 30)]
    assert p.upload_raw(rally, RALLY).type == 0
    p.c.mav.mission_clear_all_send(1, 1, RALLY)
    assert p.h.wait_for(p.c, "MISSION_ACK").mission_type == RALLY
    assert p.ap.rally_items == [] and len(p.ap.mission_items) == 4
    p.c.mav.mission_clear_all_send(1, 1, 255)
    ack = p.h.wait_for(p.c, "MISSION_ACK")
    assert ack.type == 0 and ack.mission_type == 255
    assert len(p.ap.mission_items) <= 1
    p.c.mav.mission_request_list_send(1, 1, 0)
    assert p.h.wait_for(p.c, "MISSION_COUNT").count == 1  # home only


def test_download_denied_during_upload_and_set_current(p: Pilot) -> None:
    assert p.upload(simple_mission(p)).type == 0
    p.c.mav.mission_set_current_send(1, 1, 2)
    mc = p.h.wait_for(p.c, "MISSION_CURRENT", cond=lambda m: m.seq == 2)
    assert mc is not None and mc.total == 3
    p.c.mav.mission_count_send(1, 1, 2, 0)
    p.h.wait_for(p.c, "MISSION_REQUEST")
    p.c.mav.mission_request_list_send(1, 1, 0)
    assert p.h.wait_for(p.c, "MISSION_ACK").type == 14


def test_partial_write_list(p: Pilot) -> None:
    assert p.upload(simple_mission(p, 4)).type == 0
    p.c.mav.mission_write_partial_list_send(1, 1, 2, 2, 0)
    req = p.h.wait_for(p.c, "MISSION_REQUEST")
    assert req.seq == 2
    x, y = p.latlon(999, 0)
    p.c.mav.mission_item_int_send(1, 1, 2, REL, 16, 0, 1, 0, 0, 0, 0, x, y, 44, 0)
    assert p.h.wait_for(p.c, "MISSION_ACK").type == 0
    assert p.ap.mission_items[2].z == 44 and len(p.ap.mission_items) == 4


def robust_upload(
    p: Pilot, items: list[tuple[int, int, float, float, float]], timeout: float = 120
) -> object:
    """A client that answers every (repeated) request and re-sends MISSION_COUNT if the
    vehicle goes quiet: what the autopilot link must do on a lossy radio."""
    end = p.h.now + timeout
    last_activity = p.h.now
    p.c.mav.mission_count_send(1, 1, len(items), 0)
    while p.h.now < end:
        msg = p.c.pop(("MISSION_REQUEST", "MISSION_ACK"))
        if msg is None:
            p.h.run_for(0.2)
            if p.h.now - last_activity > 3.0:
                p.c.mav.mission_count_send(1, 1, len(items), 0)
                last_activity = p.h.now
            continue
        last_activity = p.h.now
        if msg.get_type() == "MISSION_ACK":
            if msg.type == 0:
                return msg
            continue  # e.g. INVALID_SEQUENCE for a duplicate: keep going
        cmd, frame, n, e, z = items[msg.seq]
        x, y = p.latlon(n, e) if (n or e) else (0, 0)
        p.c.mav.mission_item_int_send(1, 1, msg.seq, frame, cmd, 0, 1, 0, 0, 0, 0, x, y, z, 0)
    return None


@pytest.mark.parametrize("loss", [0.2, 0.4])
def test_upload_and_download_survive_partial_loss(loss: float) -> None:
    p = make_pilot("copter")
    p.wait_ready()
    p.link.loss_to_vehicle = p.link.loss_to_client = loss
    items = [(16, 0, 0, 0, 0)] + [(16, REL, 30.0 * k, -20.0 * k, 15 + k) for k in range(1, 12)]
    ack = robust_upload(p, items)
    assert ack is not None, "upload never completed"
    assert p.link.dropped > 0
    stored = p.ap.mission_items
    assert len(stored) == 12
    for k in range(1, 12):
        lat, lon = p.frame.to_latlon(30.0 * k, -20.0 * k)
        assert abs(stored[k].lat_deg - lat) < 1e-6 and abs(stored[k].lon_deg - lon) < 1e-6
        assert stored[k].z == 15 + k
    # download everything back, re-asking for what got lost
    got: dict[int, object] = {}
    deadline = p.h.now + 120
    while len(got) < 12 and p.h.now < deadline:
        for seq in range(12):
            if seq not in got:
                p.c.mav.mission_request_int_send(1, 1, seq, 0)
        p.h.run_for(0.5)
        while (item := p.c.pop("MISSION_ITEM_INT")) is not None:
            got[item.seq] = item
    assert len(got) == 12
    assert got[5].z == 20  # type: ignore[attr-defined]


def test_rtl_goes_to_a_closer_rally_point() -> None:
    p = make_pilot("copter")
    p.wait_ready()
    rally = [(5100, REL, (0, 0, 0, 0), *p.latlon(300, 0), 20)]
    assert p.upload_raw(rally, RALLY).type == 0
    assert p.set_mode("GUIDED") == 0 and p.arm() == 0
    assert p.command(22, 0, 0, 0, 0, 0, 0, 20) == 0
    assert p.h.run_until(lambda: p.ap.rel_alt_m > 19, 60)
    x, y = p.latlon(280, 0)
    assert p.command_int(192, 6, -1, 0, 0, 0, x=x, y=y, z=20) == 0
    assert p.h.run_until(lambda: math.hypot(p.ap.body.n - 280, p.ap.body.e) < 3, 120)
    assert p.set_mode("RTL") == 0
    assert p.h.run_until(lambda: not p.ap.armed, 300)
    assert math.hypot(p.ap.body.n - 300, p.ap.body.e) < 3


def test_link_latency_delays_both_directions() -> None:
    p = make_pilot("copter")
    p.wait_ready()
    p.link.latency_s = 0.3
    t0 = p.h.now
    p.c.mav.command_long_send(1, 1, 176, 0, 1, 4, 0, 0, 0, 0, 0)
    ack = p.h.wait_for(p.c, "COMMAND_ACK", 5)
    assert ack is not None and ack.result == 0
    assert 0.6 - 1e-6 <= p.h.now - t0 < 0.7  # there and back
    ack_time = next(t for t, m in reversed(p.c.history) if m.get_type() == "COMMAND_ACK")
    assert ack_time >= t0 + 0.6 - 1e-6
    assert robust_upload(p, simple_mission(p, 6)) is not None  # the protocol copes
