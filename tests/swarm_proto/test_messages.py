"""Cross-field rules and constraints of the message contract."""

from __future__ import annotations

import math

import msgspec
import pytest

from swarm_proto import (
    AlertFlag,
    DecodeError,
    EncodeError,
    Geometry,
    GeometryKind,
    LatLon,
    Mission,
    MissionType,
    NoFlyZone,
    Selector,
    SelectorKind,
    VehicleStatus,
    lan,
    validate,
)


def status(**kw: object) -> VehicleStatus:
    base: dict[str, object] = dict(
        vehicle_id=1,
        time_unix_s=1.7e9,
        lat_deg=37.41,
        lon_deg=-5.98,
        alt_msl_m=110.0,
        alt_rel_m=100.0,
    )
    base.update(kw)
    return VehicleStatus(**base)  # type: ignore[arg-type]


SQUARE = [(37.0, -6.0), (37.0, -5.99), (37.01, -5.99), (37.01, -6.0)]


def test_self_intersecting_polygon_is_refused_with_a_clear_error() -> None:
    bowtie = [(37.0, -6.0), (37.01, -5.99), (37.0, -5.99), (37.01, -6.0)]
    with pytest.raises(ValueError, match="not simple: Self-intersection"):
        Geometry.polygon(bowtie)


@pytest.mark.parametrize(
    ("shell", "holes", "match"),
    [
        (SQUARE[:2], [], "at least 3 vertices"),
        ([*SQUARE, SQUARE[0]], [], "open ring"),
        ([(37.0, -6.0), (37.0, -5.99), (37.0, -5.98)], [], "not simple|zero area"),
        ([(0.0, -179.0), (0.0, 179.0), (1.0, 179.0)], [], "antimeridian"),
        (SQUARE, [[(38.0, -6.0), (38.0, -5.99), (38.01, -5.99)]], "not simple"),
    ],
)
def test_invalid_polygons(shell: list, holes: list, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        Geometry.polygon(shell, holes)


def test_geometry_kind_rules() -> None:
    with pytest.raises(ValueError, match="exactly 1 point"):
        Geometry(GeometryKind.POINT, ())
    with pytest.raises(ValueError, match="positive radius"):
        Geometry(GeometryKind.CIRCLE, (LatLon(1, 1),), radius_m=0.0)
    with pytest.raises(ValueError, match="only a POLYGON may have holes"):
        Geometry(GeometryKind.POINTS, (LatLon(1, 1),), holes=((LatLon(1, 1),),))


def test_invalid_geometry_is_a_decode_error_on_the_wire() -> None:
    good = lan.encode(Geometry.polygon(SQUARE))
    raw = msgspec.msgpack.decode(good)
    raw["points"] = [[37.0, -6.0], [37.01, -5.99], [37.0, -5.99], [37.01, -6.0]]
    with pytest.raises(DecodeError, match="Self-intersection"):
        lan.decode(msgspec.msgpack.encode(raw), Geometry)


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("lat_deg", math.nan),
        ("lat_deg", 90.5),
        ("lon_deg", -180.01),
        ("alt_msl_m", math.inf),
        ("vel_north_m_s", math.nan),
        ("heading_deg", 360.0),
        ("battery_pct", 101),
        ("gps_fix", 42),
        ("fsm_state", 9),
        ("vehicle_id", 0),
    ],
)
def test_out_of_range_and_nan_are_rejected_at_decode(field: str, value: object) -> None:
    raw = msgspec.to_builtins(status())
    raw[field] = value
    with pytest.raises(DecodeError) as err:
        lan.decode(msgspec.msgpack.encode(raw), VehicleStatus)
    assert field in str(err.value)


def test_validate_checks_what_construction_does_not() -> None:
    bad = status(lat_deg=math.nan)  # msgspec does not check constraints on construction
    with pytest.raises(EncodeError, match="lat_deg"):
        validate(bad)
    validate(status())


def test_alert_flags_must_fit_16_bits() -> None:
    with pytest.raises(ValueError, match="16 bits"):
        status(alerts=AlertFlag(1 << 17))


def test_selector_rules_and_addressing() -> None:
    with pytest.raises(ValueError):
        Selector(SelectorKind.IDS)
    with pytest.raises(ValueError):
        Selector(SelectorKind.FLEET)
    with pytest.raises(ValueError):
        Selector(SelectorKind.QUANTITY)
    assert Selector.ids(3, 4).addresses(3, 0)
    assert not Selector.ids(3, 4).addresses(5, 0)
    assert Selector.fleet(2).addresses(9, 2)
    assert not Selector.fleet(2).addresses(9, 1)
    assert Selector().addresses(77, 0)
    assert Selector(SelectorKind.QUANTITY, quantity=2, fleet_id=1).addresses(5, 1)


def test_zone_rules() -> None:
    poly = Geometry.polygon(SQUARE)
    with pytest.raises(ValueError, match="floor"):
        NoFlyZone(1, poly, floor_alt_msl_m=100.0, ceiling_alt_msl_m=50.0)
    with pytest.raises(ValueError, match="POLYGON or a CIRCLE"):
        NoFlyZone(1, Geometry.point(37.0, -6.0))
    with pytest.raises(ValueError, match="ends before"):
        NoFlyZone(1, poly, valid_from_unix_s=10.0, valid_until_unix_s=5.0)
    z = NoFlyZone(1, poly, valid_from_unix_s=10.0, valid_until_unix_s=20.0)
    assert not z.in_force(5.0) and z.in_force(15.0) and not z.in_force(20.0)


def test_mission_id_zero_is_reserved() -> None:
    with pytest.raises(ValueError, match="reserved"):
        Mission(0, 1, MissionType.TARGET, Geometry.point(37.0, -6.0))


def test_derived_groundspeed_and_course() -> None:
    s = status(vel_north_m_s=3.0, vel_east_m_s=4.0)
    assert s.groundspeed_m_s == pytest.approx(5.0)
    assert s.course_deg == pytest.approx(math.degrees(math.atan2(4, 3)))
