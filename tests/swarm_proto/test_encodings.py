"""Both encodings: round trips for every message (hypothesis), fuzzed decoders, the
radio's size, resolution, versioning and append-only evolution."""

from __future__ import annotations

import contextlib
import math
import typing
from typing import Any

import msgspec
import pytest
from hypothesis import assume, given
from hypothesis import strategies as st

from swarm_proto import (
    MESSAGE_TYPES,
    Ack,
    AckReason,
    AckRef,
    Alert,
    AlertCode,
    AlertFlag,
    DecodeError,
    DetailCode,
    EncodeError,
    Geometry,
    GpsFix,
    Mission,
    MissionParams,
    MissionType,
    NoFlyZone,
    ReasonDetail,
    Severity,
    SwarmView,
    VehicleStatus,
    lan,
    radio,
)
from swarm_proto import messages as swarm_proto_messages
from swarm_proto.testing import message_of, messages
from swarm_proto.units import Fixed, Saturate

NOW = 1.75e9


# --------------------------------------------------------------------------- LAN


@pytest.mark.parametrize("cls", MESSAGE_TYPES, ids=lambda c: c.__name__)
@given(data=st.data())
def test_lan_round_trip(cls: type, data: st.DataObject) -> None:
    msg = data.draw(message_of(cls))
    assert lan.decode(lan.encode(msg), cls) == msg


@pytest.mark.parametrize("cls", MESSAGE_TYPES, ids=lambda c: c.__name__)
@given(blob=st.binary(max_size=512))
def test_lan_decoder_survives_random_bytes(cls: type, blob: bytes) -> None:
    with contextlib.suppress(DecodeError):
        lan.decode(blob, cls)


@given(msg=messages(), data=st.data())
def test_lan_decoder_survives_mutated_payloads(msg: Any, data: st.DataObject) -> None:
    blob = bytearray(lan.encode(msg))
    for _ in range(data.draw(st.integers(1, 4))):
        i = data.draw(st.integers(0, len(blob) - 1))
        blob[i] = data.draw(st.integers(0, 255))
    cut = data.draw(st.integers(0, len(blob)))
    with contextlib.suppress(DecodeError):
        lan.decode(bytes(blob[:cut]), type(msg))


# --------------------------------------------------------------------------- radio


# LAN-only fields: a radio gateway's prediction of a radio peer (the 40-byte status
# carries the vehicle's own measurement, where both are 0)
LAN_ONLY = {VehicleStatus: ("position_error_m", "predicted_s")}


def _close(cls: type, a: Any, b: Any) -> None:
    """b (decoded from radio) equals a (sent) to within one step of each field's radio
    resolution (half a step, except next to a strict bound such as heading < 360)."""
    hints = typing.get_type_hints(cls, include_extras=True)
    for name in cls.__struct_fields__:
        if name in LAN_ONLY.get(cls, ()):
            assert getattr(b, name) == 0.0, name
            continue
        _close_value(hints[name], getattr(a, name), getattr(b, name), f"{cls.__name__}.{name}")


def _close_value(hint: Any, a: Any, b: Any, where: str) -> None:
    origin = typing.get_origin(hint)
    if origin is typing.Annotated:
        base, *extras = typing.get_args(hint)
        fixed = next((e for e in extras if isinstance(e, Fixed)), None)
        sat = next((e for e in extras if isinstance(e, Saturate)), None)
        if fixed is not None:
            assert math.isclose(a, b, abs_tol=fixed.resolution * (1 + 1e-6)), (where, a, b)
            return
        if sat is not None:
            assert b == min(a, sat.maximum), where
            return
        _close_value(base, a, b, where)
        return
    if origin in (typing.Union, __import__("types").UnionType):
        if a is None or b is None:
            assert a is None and b is None, where
            return
        (inner,) = [x for x in typing.get_args(hint) if x is not type(None)]
        _close_value(inner, a, b, where)
        return
    if origin is tuple:
        assert len(a) == len(b), where
        (inner, _) = typing.get_args(hint)
        for i, (x, y) in enumerate(zip(a, b, strict=True)):
            _close_value(inner, x, y, f"{where}[{i}]")
        return
    if isinstance(hint, type) and issubclass(hint, msgspec.Struct):
        _close(hint, a, b)
        return
    assert a == b, (where, a, b)


@pytest.mark.parametrize("cls", MESSAGE_TYPES, ids=lambda c: c.__name__)
@given(data=st.data())
def test_radio_round_trip_within_resolution(cls: type, data: st.DataObject) -> None:
    msg = data.draw(message_of(cls))
    now = getattr(msg, "time_unix_s", NOW)
    try:
        blob = radio.encode(msg)
    except EncodeError as exc:  # e.g. a 1 mm zone thickness: refused at the sender
        assert "radio resolution" in str(exc)
        assume(False)
        raise
    back = radio.decode(blob, now_unix_s=now + data.draw(st.floats(-86400, 86400)))
    assert type(back) is cls
    _close(cls, msg, back)
    assert radio.encode(back) == blob  # quantization is idempotent


@given(msg=message_of(VehicleStatus))
def test_radio_status_is_40_bytes(msg: VehicleStatus) -> None:
    assert len(radio.encode(msg)) == radio.STATUS_BYTES == 40


def test_a_predicted_status_is_lan_only() -> None:
    """A gateway's prediction keeps its error bound and horizon on the LAN;
    the radio layout has no room for them (statuses on air are measured: both 0)."""
    s = msgspec.structs.replace(_status(), position_error_m=7.25, predicted_s=0.8)
    assert lan.decode(lan.encode(s), VehicleStatus) == s
    back = radio.decode(radio.encode(s), now_unix_s=NOW)
    assert isinstance(back, VehicleStatus)
    assert back.position_error_m == 0.0 and back.predicted_s == 0.0
    older = {k: v for k, v in msgspec.to_builtins(s).items() if k not in LAN_ONLY[VehicleStatus]}
    assert lan.decode(msgspec.msgpack.encode(older), VehicleStatus).position_error_m == 0.0


@given(blob=st.binary(max_size=256))
def test_radio_decoder_survives_random_bytes(blob: bytes) -> None:
    with contextlib.suppress(DecodeError):
        radio.decode(blob, now_unix_s=NOW)


@given(blob=st.binary(max_size=256), tag=st.sampled_from(sorted(radio.TYPE_OF)))
def test_radio_decoder_survives_random_bodies(blob: bytes, tag: int) -> None:
    with contextlib.suppress(DecodeError):
        radio.decode(bytes((radio.RADIO_SCHEMA_VERSION, tag)) + blob, now_unix_s=NOW)


@given(msg=messages(), data=st.data())
def test_radio_decoder_survives_mutated_messages(msg: Any, data: st.DataObject) -> None:
    blob = bytearray(radio.encode(msg))
    for _ in range(data.draw(st.integers(1, 4))):
        i = data.draw(st.integers(0, len(blob) - 1))
        blob[i] ^= 1 << data.draw(st.integers(0, 7))
    cut = data.draw(st.integers(0, len(blob)))
    with contextlib.suppress(DecodeError):
        radio.decode(bytes(blob[:cut]), now_unix_s=NOW)


def _status(**kw: Any) -> VehicleStatus:
    base: dict[str, Any] = dict(
        vehicle_id=7,
        time_unix_s=NOW,
        lat_deg=37.4112,
        lon_deg=-5.9889,
        alt_msl_m=110.0,
        alt_rel_m=100.0,
    )
    base.update(kw)
    return VehicleStatus(**base)


def test_radio_header_errors_are_typed() -> None:
    blob = radio.encode(_status())
    with pytest.raises(DecodeError) as e:
        radio.decode(b"\x09" + blob[1:], now_unix_s=NOW)
    assert e.value.reason == "version"
    with pytest.raises(DecodeError) as e:
        radio.decode(blob[:1] + b"\xee" + blob[2:], now_unix_s=NOW)
    assert e.value.reason == "unknown-type"
    with pytest.raises(DecodeError) as e:
        radio.decode(blob[:20], now_unix_s=NOW)
    assert e.value.reason == "truncated"


def test_status_fields_survive_the_radio() -> None:
    s = _status(
        heading_deg=359.999,
        gps_sats=40,
        gps_fix=GpsFix.RTK_FIXED,
        battery_pct=-1,
        alerts=AlertFlag.GPS_LOSS | AlertFlag.BATTERY_LOW,
        vel_down_m_s=-2.5,
        armed=True,
    )
    back = radio.decode(radio.encode(s), now_unix_s=NOW + 3600)
    assert isinstance(back, VehicleStatus)
    assert back.heading_deg == pytest.approx(359.99)  # stays below 360
    assert back.gps_sats == 31  # saturates
    assert back.battery_pct == -1 and back.gps_fix == GpsFix.RTK_FIXED and back.armed
    assert back.alerts == AlertFlag.GPS_LOSS | AlertFlag.BATTERY_LOW
    assert back.vel_down_m_s == -2.5


@given(t=st.floats(0, 4e9), skew=st.floats(-20 * 86400, 20 * 86400))
def test_status_time_unwraps_near_now(t: float, skew: float) -> None:
    ms = round(t * 1000) % (1 << 32)
    assert radio.unwrap_time_ms(ms, t + skew) == pytest.approx(round(t * 1000) / 1000, abs=1e-3)


def test_radio_is_append_only() -> None:
    m = Mission(
        5, 1, MissionType.TARGET, Geometry.point(37.4, -5.9), MissionParams(radius_m=80.0), name="t"
    )
    raw = msgspec.msgpack.decode(radio.encode(m)[2:])
    header = bytes((radio.RADIO_SCHEMA_VERSION, radio.TAG_OF[Mission]))
    # an older sender without the trailing optional fields
    older = radio.decode(header + msgspec.msgpack.encode(raw[:-2]), now_unix_s=NOW)
    assert isinstance(older, Mission) and older.name == "" and older.geometry == m.geometry
    # a newer sender with fields we do not know yet
    newer = radio.decode(header + msgspec.msgpack.encode([*raw, 42, "future"]), now_unix_s=NOW)
    assert newer == m
    # but required fields cannot be dropped
    with pytest.raises(DecodeError, match="missing"):
        radio.decode(header + msgspec.msgpack.encode(raw[:2]), now_unix_s=NOW)


def test_an_operating_area_survives_both_encodings_and_older_senders() -> None:
    area = NoFlyZone(8, Geometry.circle(37.41, -5.99, 900.0), name="field", operating_area=True)
    assert lan.decode(lan.encode(area), NoFlyZone) == area
    back = radio.decode(radio.encode(area), now_unix_s=NOW)
    assert isinstance(back, NoFlyZone) and back.operating_area and back.zone_id == 8
    # a sender from before the field existed: its zones are no-fly zones
    raw = msgspec.msgpack.decode(radio.encode(area)[2:])
    header = bytes((radio.RADIO_SCHEMA_VERSION, radio.TAG_OF[NoFlyZone]))
    # (operating_area was the last field until issuer_id was appended, and later
    # time_unix_s after it)
    older = radio.decode(header + msgspec.msgpack.encode(raw[:-3]), now_unix_s=NOW)
    assert isinstance(older, NoFlyZone) and not older.operating_area and older.name == "field"
    assert older.issuer_id == 0  # and nobody to acknowledge it to
    # a sender from before zones were stamped: stamp 0, the receiver stamps it
    unstamped = radio.decode(header + msgspec.msgpack.encode(raw[:-1]), now_unix_s=NOW)
    assert isinstance(unstamped, NoFlyZone) and unstamped.operating_area
    assert unstamped.time_unix_s == 0.0
    lan_older = msgspec.msgpack.encode(
        {k: v for k, v in msgspec.to_builtins(area).items() if k != "operating_area"}
    )
    assert lan.decode(lan_older, NoFlyZone).operating_area is False


def test_a_reason_detail_crosses_both_encodings_and_older_nodes() -> None:
    """An Ack and an Alert carry their reason's numbers (appended: an older node's
    Ack decodes with none, and an older node reads ours without them); on the radio an
    Ack without them costs one byte more than before."""
    detail = ReasonDetail(DetailCode.ENDURANCE, 0, needed_s=410.0, available_s=148.0)
    ack = Ack(7, 900, AckRef.MISSION, 42, False, AckReason.INVALID, "endurance", detail)
    alert = Alert(8, NOW, Severity.WARNING, AlertCode.COLLISION_RISK, "avoid: climb", None)
    for msg in (ack, alert):
        assert lan.decode(lan.encode(msg), type(msg)) == msg
        assert radio.decode(radio.encode(msg), now_unix_s=NOW) == msg
    raw = msgspec.msgpack.decode(radio.encode(ack)[2:])
    header = bytes((radio.RADIO_SCHEMA_VERSION, radio.TAG_OF[Ack]))
    older = radio.decode(header + msgspec.msgpack.encode(raw[:-1]), now_unix_s=NOW)
    assert isinstance(older, Ack) and older.detail is None and older.text == "endurance"
    plain = Ack(7, 900, AckRef.COMMAND, 3, True)
    before = msgspec.msgpack.encode(msgspec.msgpack.decode(radio.encode(plain)[2:])[:-1])
    assert len(radio.encode(plain)) == 2 + len(before) + 1
    # an older node's LAN map has no "detail" key
    lan_older = msgspec.msgpack.encode(
        {k: v for k, v in msgspec.to_builtins(ack).items() if k != "detail"}
    )
    assert lan.decode(lan_older, Ack).detail is None


def test_radio_refuses_values_it_cannot_carry() -> None:
    with pytest.raises(EncodeError):
        radio.encode(_status(lat_deg=math.nan))
    with pytest.raises(EncodeError):
        radio.encode(_status(ap_mode=999))
    with pytest.raises(EncodeError, match="no radio type tag"):
        radio.encode(MissionParams())


# fields of STATUS_LAYOUT, by position (version, tag, vehicle_id, time_ms, lat, lon, ...)
_LAT_I, _VID_I, _FLAGS_I, _ALERTS_I, _PROG_I = 4, 2, 17, 20, 18


def _raw_status(**at: int) -> bytes:
    """A radio status with some positional fields replaced by raw integers."""
    values = list(radio.STATUS_LAYOUT.unpack(radio.encode(_status())))
    for index, value in at.items():
        values[int(index.lstrip("_"))] = value
    return radio.STATUS_LAYOUT.pack(*values)


@pytest.mark.parametrize(
    ("raw", "field"),
    [
        ({f"_{_LAT_I}": 91 * 10_000_000}, "lat_deg"),  # 1e-7 degree resolution
        ({f"_{_LAT_I}": -91 * 10_000_000}, "lat_deg"),
        ({f"_{_VID_I}": 0}, "vehicle_id"),
        ({f"_{_PROG_I}": 101}, "mission_progress_pct"),
    ],
)
def test_radio_status_out_of_range_is_rejected(raw: dict[str, int], field: str) -> None:
    with pytest.raises(DecodeError) as err:
        radio.decode(_raw_status(**raw), now_unix_s=NOW)
    assert field in str(err.value)


def test_radio_status_unknown_enum_is_rejected() -> None:
    base = radio.STATUS_LAYOUT.unpack(radio.encode(_status()))[_FLAGS_I]
    bad_mission_state = (base & ~(0xF << 3)) | (15 << 3)  # no MissionState 15
    with pytest.raises(DecodeError, match=r"MissionState|mission_state|15"):
        radio.decode(_raw_status(**{f"_{_FLAGS_I}": bad_mission_state}), now_unix_s=NOW)


def test_radio_status_is_forward_compatible() -> None:
    """Append-only evolution: a newer node may set alert bits this version does not name,
    and may append bytes to the status. An older receiver keeps the bits it cannot name
    and ignores the tail rather than drop the whole status (docs/radio-encoding.md)."""
    future_bit = 1 << 15
    s = radio.decode(_raw_status(**{f"_{_ALERTS_I}": future_bit | 1}), now_unix_s=NOW)
    assert isinstance(s, VehicleStatus)
    assert int(s.alerts) == future_bit | 1 and AlertFlag.BATTERY_LOW in s.alerts
    longer = radio.encode(_status()) + b"\x07\x00future"
    assert radio.decode(longer, now_unix_s=NOW) == radio.decode(longer[:40], now_unix_s=NOW)


@pytest.mark.parametrize(
    "kw",
    [{"lat_deg": 90.5}, {"lon_deg": -180.5}, {"battery_pct": 101}, {"vehicle_id": 0}],
)
def test_lan_and_radio_agree_on_what_is_invalid(kw: dict[str, Any]) -> None:
    bad = msgspec.to_builtins(_status())
    bad.update(kw)
    with pytest.raises(DecodeError):
        lan.decode(msgspec.msgpack.encode(bad), VehicleStatus)
    with pytest.raises(EncodeError):  # never produced on the radio in the first place
        radio.encode(msgspec.structs.replace(_status(), **kw))


@given(view=message_of(SwarmView))
def test_swarm_view_round_trips_on_the_lan(view: SwarmView) -> None:
    assert lan.decode(lan.encode(view), SwarmView) == view


@given(msg=message_of(swarm_proto_messages.VehicleInfo))
def test_a_field_on_air_is_what_receivers_decode_and_stays_there(msg: Any) -> None:
    """`radio.on_air` gives a field as the radio's receivers decode it, to the bit, and
    a value already on air is unchanged (a sender publishing it and computing with it
    computes what its receivers do: mission/published.py)."""
    heard = radio.quantized(msg)
    for name in ("mission_progress_m", "mission_path_m", "home", "battery_pct"):
        mine = radio.on_air(type(msg), name, getattr(msg, name))
        assert mine == getattr(heard, name)
        assert radio.on_air(type(msg), name, mine) == mine
    again = radio.quantized(
        msgspec.structs.replace(msg, mission_progress_m=heard.mission_progress_m, home=heard.home)
    )
    assert again.mission_progress_m == heard.mission_progress_m and again.home == heard.home


def test_on_air_refuses_what_the_field_cannot_carry() -> None:
    vi = swarm_proto_messages.VehicleInfo
    for bad in (math.nan, -1.0, 2.0e6):
        with pytest.raises(EncodeError):
            radio.on_air(vi, "mission_progress_m", bad)
    with pytest.raises(EncodeError):
        radio.on_air(vi, "no_such_field", 1.0)
