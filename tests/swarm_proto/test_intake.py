"""The input boundary's pure half (swarm_proto.intake): size caps from the topic registry,
decoding with a reason for every drop, keys checked against payloads, source
attachments, and the rate-limited MALFORMED_INPUT alarm."""

from __future__ import annotations

import math

import msgspec
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from swarm_proto import (
    Ack,
    AckReason,
    AckRef,
    Command,
    CommandKind,
    Geometry,
    GeoPoint,
    LatLon,
    Mission,
    MissionType,
    PlanLineage,
    TargetReport,
    TargetSource,
    VehicleInfo,
    VehicleStatus,
    VehicleType,
    Vote,
    VoteScore,
    lan,
)
from swarm_proto.errors import DecodeError
from swarm_proto.intake import (
    FOREIGN,
    INVALID,
    KEY_MISMATCH,
    MALFORMED,
    MAX_ATTACHMENT_BYTES,
    TOO_LARGE,
    InputAlarm,
    Source,
    decode,
    key_expr_of,
    max_message_bytes,
    parse_source,
    size_filters,
    source_tag,
    too_large,
)
from swarm_proto.topics import (
    ACK,
    COMMAND,
    INFO,
    LINEAGE,
    MISSION,
    STATUS,
    TARGET,
    TOPICS,
    VOTE,
    ZONE,
)

SWARM = "s"
NOW = 1.75e9


def status(vid: int = 7) -> VehicleStatus:
    return VehicleStatus(vid, NOW, 37.41, -5.99, 110.0, 100.0)


def polygon(n: int) -> Geometry:
    pts = tuple(
        LatLon(
            37.4 + 0.01 * math.sin(2 * math.pi * i / n), -5.9 + 0.01 * math.cos(2 * math.pi * i / n)
        )
        for i in range(n)
    )
    return Geometry.polygon([(p.lat_deg, p.lon_deg) for p in pts])


# ---------------------------------------------------------------- size caps


def test_the_largest_legal_telemetry_fits_its_cap() -> None:
    from bench.proto import SAMPLES  # one sample of every message, as the radio bench has

    for cls, msg in SAMPLES.items():
        topic = next(t for t in TOPICS if t.msg_type is cls)
        assert too_large(topic, len(lan.encode(msg))) is None, cls.__name__
    worst = VehicleStatus(
        65534,
        4e9,
        -89.123456789,
        -179.123456789,
        -1234.5678,
        -1234.5678,
        -123.456789,
        -123.456789,
        -123.456789,
        359.123456,
        123.456789,
        100,
        65.123456,
        position_error_m=12345.6789,
        predicted_s=12345.6789,
    )
    assert len(lan.encode(worst)) * 2 < (STATUS.max_bytes or 0)
    name = "x" * 48
    info = VehicleInfo(65534, VehicleType.VTOL, name, name, 255, name, name, name)
    assert len(lan.encode(info)) * 2 < (INFO.max_bytes or 0)


def test_a_4000_vertex_field_is_a_legal_mission_and_a_zone_as_large() -> None:
    mission = Mission(50, 900, MissionType.AREA, polygon(4000))
    data = lan.encode(mission)
    assert too_large(MISSION, len(data)) is None
    assert decode(MISSION, SWARM, f"bandada/{SWARM}/mission/50", data) == mission
    assert (ZONE.max_bytes or 0) == (MISSION.max_bytes or 0)
    assert (LINEAGE.max_bytes or 0) > (MISSION.max_bytes or 0)


def test_a_payload_over_its_cap_is_refused_before_decoding() -> None:
    problem = too_large(STATUS, 10_000_000)
    assert problem == "10000000 bytes, more than the 1024 status takes"
    with pytest.raises(DecodeError) as exc:
        decode(STATUS, SWARM, f"bandada/{SWARM}/vehicle/7/status", bytes(5000))
    assert exc.value.reason == TOO_LARGE


def test_zenoh_is_told_the_caps() -> None:
    rules = {r["id"]: r for r in size_filters()}
    status_rule = rules["bandada-status"]
    assert status_rule["key_exprs"] == ["bandada/*/vehicle/*/status"]
    assert status_rule["size_limit"] == (STATUS.max_bytes or 0) + MAX_ATTACHMENT_BYTES
    assert status_rule["flows"] == ["ingress"]
    assert rules["bandada-other"]["key_exprs"] == ["bandada/**"]
    assert max_message_bytes() > max(t.max_bytes or 0 for t in TOPICS)


# ---------------------------------------------------------------- decoding


def test_every_drop_has_its_reason() -> None:
    key = f"bandada/{SWARM}/vehicle/7/status"
    cases = {
        b"\xc1 not msgpack": MALFORMED,
        msgspec.msgpack.encode({"vehicle_id": "seven"}): INVALID,
        msgspec.msgpack.encode({"x1": 1.0, "x2": 2.0}): INVALID,  # unknown fields only
        msgspec.msgpack.encode({**msgspec.to_builtins(status()), "lat_deg": math.nan}): INVALID,
        lan.encode(status(8)): KEY_MISMATCH,
    }
    for data, reason in cases.items():
        with pytest.raises(DecodeError) as exc:
            decode(STATUS, SWARM, key, data)
        assert exc.value.reason == reason, data


def test_fields_a_receiver_does_not_know_are_accepted() -> None:
    data = msgspec.msgpack.encode({**msgspec.to_builtins(status()), "appended_later": 3})
    assert decode(STATUS, SWARM, f"bandada/{SWARM}/vehicle/7/status", data) == status()


@pytest.mark.parametrize(
    ("topic", "key", "msg"),
    [
        (STATUS, "vehicle/8/status", status(7)),
        (ACK, "vehicle/8/ack", Ack(7, 900, AckRef.COMMAND, 1, True, AckReason.OK)),
        (COMMAND, "cmd/555", Command(901, 1, CommandKind.RTL)),
        (VOTE, "vote/41/8", Vote(41, 7, (VoteScore(7, 0.5),))),
        (VOTE, "vote/42/7", Vote(41, 7, (VoteScore(7, 0.5),))),
        (
            TARGET,
            "target/900/1",
            TargetReport(1, 901, TargetSource.OPERATOR, NOW, GeoPoint(37.4, -5.9, 10.0)),
        ),
        (
            LINEAGE,
            "lineage/41/9",
            PlanLineage(Mission(41, 900, MissionType.AREA, polygon(8)), 8, ()),
        ),
        (MISSION, "mission/42", Mission(41, 900, MissionType.AREA, polygon(8))),
    ],
)
def test_a_key_that_names_another_sender_than_its_payload_is_dropped(
    topic: object, key: str, msg: msgspec.Struct
) -> None:
    with pytest.raises(DecodeError) as exc:
        decode(topic, SWARM, f"bandada/{SWARM}/{key}", lan.encode(msg))  # type: ignore[arg-type]
    assert exc.value.reason == KEY_MISMATCH


def test_the_key_a_message_is_published_on_passes() -> None:
    for msg in (Command(900, 1, CommandKind.RTL), Vote(41, 7, (VoteScore(7, 0.5),))):
        topic = next(t for t in TOPICS if t.msg_type is type(msg))
        assert decode(topic, SWARM, topic.key_of(SWARM, msg), lan.encode(msg)) == msg


@settings(derandomize=True, max_examples=300)
@given(st.binary(max_size=400))
def test_any_bytes_are_a_message_or_a_decode_error(data: bytes) -> None:
    for topic in (STATUS, INFO, COMMAND, MISSION, VOTE):
        try:
            decode(topic, SWARM, topic.key(SWARM, **dict.fromkeys(topic.params, 7)), data)
        except DecodeError as exc:
            assert exc.reason in (MALFORMED, INVALID, KEY_MISMATCH)


# ---------------------------------------------------------------- sources


def test_a_source_tag_names_the_session_and_its_autopilot() -> None:
    tag = source_tag("3f2a9c1d00112233445566778899aabb", 10)
    assert parse_source(tag) == Source("3f2a9c1d00112233445566778899aabb", 10)
    assert parse_source(b"bandada-radio:3") == Source(relay=3)
    assert parse_source(b"bandada-radio:3").key == "radio"
    for junk in (None, b"", b"hello", b"bandada-src:ZZZ:1", b"bandada-src:abc:999", b"x" * 500):
        assert parse_source(junk) == FOREIGN
    assert FOREIGN.key == "foreign" and FOREIGN.describe() == "a foreign publisher"


# ---------------------------------------------------------------- the alarm


def test_at_most_one_alarm_a_minute_per_topic_with_the_count_and_the_first() -> None:
    alarm = InputAlarm(SWARM)
    key7, key8 = f"bandada/{SWARM}/vehicle/7/status", f"bandada/{SWARM}/vehicle/8/status"
    first = alarm.dropped(key7, TOO_LARGE, "10000000 bytes", 0.0)
    assert first is not None and first.count == 1 and first.key_expr == "vehicle/*/status"
    assert first.text.startswith("1 dropped, first vehicle/7/status: too_large")
    for i in range(1, 40):  # the same topic, any vehicle: counted, not alarmed
        assert alarm.dropped(key8 if i % 2 else key7, INVALID, "bad", i * 0.5) is None
    assert alarm.dropped(f"bandada/{SWARM}/cmd/555", KEY_MISMATCH, "x", 1.0) is not None
    assert alarm.next_deadline() == 60.0
    assert alarm.on_timer(59.9) == []
    (summary,) = alarm.on_timer(60.0)
    assert summary.count == 39 and summary.first.startswith("vehicle/8/status: invalid")
    assert alarm.dropped(key7, INVALID, "bad", 61.0) is None  # within the next minute
    assert alarm.on_timer(120.0)[0].count == 1
    assert alarm.on_timer(200.0) == []
    assert alarm.dropped(key7, INVALID, "bad", 250.0) is not None  # quiet a minute: at once
    assert alarm.by_reason() == {TOO_LARGE: 1, INVALID: 41, KEY_MISMATCH: 1}


def test_the_alarm_keeps_one_window_per_topic_whatever_the_keys() -> None:
    alarm = InputAlarm(SWARM)
    for i in range(5000):
        alarm.dropped(f"bandada/{SWARM}/vehicle/{i}/status", INVALID, "x", i * 0.001)
        alarm.dropped(f"bandada/{SWARM}/junk/{i}", MALFORMED, "x", i * 0.001)
    assert len(alarm._windows) == 2 and len(alarm.counts) == 2
    assert key_expr_of(SWARM, f"bandada/{SWARM}/junk/1") == "other"
