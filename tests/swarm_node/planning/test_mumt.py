"""MUM-T lead state: from the lead's telemetry (VehicleStatus) and from ADS-B
(MAVLink ADSB_VEHICLE, encoded and decoded by pymavlink here; the core takes the
decoded fields and never imports pymavlink)."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pymavlink.dialects.v20 import common as mavlink

from swarm_node.core.planning import (
    InvalidParameterError,
    LeadState,
    PlanVehicle,
    plan_mumt,
)
from swarm_proto import VehicleStatus
from tests.conftest import examples

from .conftest import ORIGIN

Fleet = Callable[..., list[PlanVehicle]]

VALID = (
    mavlink.ADSB_FLAGS_VALID_COORDS
    | mavlink.ADSB_FLAGS_VALID_ALTITUDE
    | mavlink.ADSB_FLAGS_VALID_HEADING
    | mavlink.ADSB_FLAGS_VALID_VELOCITY
    | mavlink.ADSB_FLAGS_VALID_CALLSIGN
)
ICAO = 0x3443C1
HOME_MSL = 650.0


def adsb_fields(**over: Any) -> dict[str, Any]:
    """An ADSB_VEHICLE message packed to bytes by pymavlink and decoded back: the
    fields exactly as a MAVLink reader hands them over."""
    f: dict[str, Any] = {
        "ICAO_address": ICAO,
        "lat": round(ORIGIN[0] * 1e7),
        "lon": round(ORIGIN[1] * 1e7),
        "altitude_type": mavlink.ADSB_ALTITUDE_TYPE_GEOMETRIC,
        "altitude": 950_000,  # mm MSL: 300 m above a 650 m home
        "heading": 9_000,  # cdeg: east
        "hor_velocity": 4_000,  # cm/s
        "ver_velocity": -150,
        "callsign": b"EC-MUM",
        "emitter_type": mavlink.ADSB_EMITTER_TYPE_LIGHT,
        "tslc": 2,
        "flags": VALID,
        "squawk": 7000,
    }
    f.update(over)
    mav = mavlink.MAVLink(None, srcSystem=200, srcComponent=1)
    buf = mav.adsb_vehicle_encode(**f).pack(mav)
    msg = mavlink.MAVLink(None).decode(bytearray(buf))
    assert msg.get_type() == "ADSB_VEHICLE"
    out: dict[str, Any] = msg.to_dict()
    return out


def test_from_adsb_decodes_a_real_adsb_vehicle_message(fleet: Fleet) -> None:
    lead = LeadState.from_adsb(
        adsb_fields(), received_s=1000.0, home_alt_msl_m=HOME_MSL, icao_address=ICAO
    )
    assert (lead.lat_deg, lead.lon_deg) == pytest.approx(ORIGIN, abs=1e-7)
    assert lead.alt_rel_m == pytest.approx(300.0)
    assert lead.course_deg == pytest.approx(90.0)
    assert lead.speed_m_s == pytest.approx(40.0)
    assert lead.time_s == pytest.approx(998.0)  # heard 2 s before it was received
    # QNH pressure altitude is taken as MSL too
    qnh = LeadState.from_adsb(
        adsb_fields(altitude_type=mavlink.ADSB_ALTITUDE_TYPE_PRESSURE_QNH),
        received_s=1000.0,
        home_alt_msl_m=HOME_MSL,
    )
    assert qnh.alt_rel_m == pytest.approx(300.0)
    # the report drives a plan: the 2 s age is extrapolated along the course (east)
    vs = fleet(["multirotor", "fixed_wing"])
    fresh = plan_mumt(lead, vs, now_s=998.0, lookahead_s=0.0)
    aged = plan_mumt(lead, vs, now_s=1000.0, lookahead_s=0.0, frame=fresh.frame)
    assert aged.lead_xy[0] - fresh.lead_xy[0] == pytest.approx(80.0, abs=0.1)
    assert all(s.alt_rel_m > 300.0 for s in aged.slots)


@settings(max_examples=examples(50), deadline=None)
@given(
    st.integers(-900_000_000, 900_000_000),
    st.integers(-1_800_000_000, 1_800_000_000),
    st.integers(-500_000, 20_000_000),
    st.integers(0, 35_999),
    st.integers(0, 30_000),
    st.integers(0, 255),
)
def test_from_adsb_round_trips_any_valid_report(
    lat: int, lon: int, alt_mm: int, hdg: int, vel: int, tslc: int
) -> None:
    f = adsb_fields(lat=lat, lon=lon, altitude=alt_mm, heading=hdg, hor_velocity=vel, tslc=tslc)
    lead = LeadState.from_adsb(f, received_s=5000.0, home_alt_msl_m=HOME_MSL)
    assert lead.lat_deg == pytest.approx(lat / 1e7, abs=1e-12)
    assert lead.lon_deg == pytest.approx(lon / 1e7, abs=1e-12)
    assert lead.alt_rel_m == pytest.approx(alt_mm / 1000.0 - HOME_MSL)
    assert lead.course_deg == pytest.approx(hdg / 100.0)
    assert lead.speed_m_s == pytest.approx(vel / 100.0)
    assert lead.time_s == pytest.approx(5000.0 - tslc)


@pytest.mark.parametrize(
    ("over", "match"),
    [
        ({"flags": VALID & ~mavlink.ADSB_FLAGS_VALID_COORDS}, "valid position"),
        ({"flags": VALID & ~mavlink.ADSB_FLAGS_VALID_ALTITUDE}, "valid altitude"),
        ({"flags": VALID & ~mavlink.ADSB_FLAGS_VALID_HEADING}, "valid heading"),
        ({"flags": VALID & ~mavlink.ADSB_FLAGS_VALID_VELOCITY}, "valid velocity"),
        ({"flags": 0}, "position, altitude, heading, velocity"),
        ({"flags": VALID | mavlink.ADSB_FLAGS_SIMULATED}, "SIMULATED"),
        ({"ICAO_address": 0x3443C2}, "ICAO 3443C2"),
        ({"lat": 910_000_000}, "lat"),
        ({"lon": -1_800_000_001}, "lon"),
        ({"heading": 36_000}, "heading"),
        ({"hor_velocity": 65_535}, "hor_velocity"),
        ({"altitude_type": 2}, "altitude_type"),
    ],
)
def test_from_adsb_rejects_invalid_reports(over: dict[str, Any], match: str) -> None:
    with pytest.raises(InvalidParameterError, match=match):
        LeadState.from_adsb(
            adsb_fields(**over), received_s=1000.0, home_alt_msl_m=HOME_MSL, icao_address=ICAO
        )


@pytest.mark.parametrize(
    ("field", "value", "match"),
    [
        ("lat", math.nan, "lat"),
        ("hor_velocity", math.inf, "hor_velocity"),
        ("altitude", "950000", "number"),
        ("tslc", True, "number"),
        ("heading", None, "number"),
    ],
)
def test_from_adsb_rejects_non_numbers(field: str, value: Any, match: str) -> None:
    f = adsb_fields()
    f[field] = value
    with pytest.raises(InvalidParameterError, match=match):
        LeadState.from_adsb(f, received_s=1000.0, home_alt_msl_m=HOME_MSL)
    del f[field]
    with pytest.raises(InvalidParameterError, match=f"no '{field}' field"):
        LeadState.from_adsb(f, received_s=1000.0, home_alt_msl_m=HOME_MSL)
    with pytest.raises(InvalidParameterError, match="received_s"):
        LeadState.from_adsb(adsb_fields(), received_s=math.nan, home_alt_msl_m=HOME_MSL)


def test_from_status_uses_course_over_ground_or_heading_when_stopped() -> None:
    moving = VehicleStatus(
        vehicle_id=9,
        time_unix_s=1234.5,
        lat_deg=ORIGIN[0],
        lon_deg=ORIGIN[1],
        alt_msl_m=950.0,
        alt_rel_m=300.0,
        vel_north_m_s=-30.0,
        vel_east_m_s=30.0,
        heading_deg=120.0,  # crabbing: yaw differs from the course
    )
    lead = LeadState.from_status(moving)
    assert (lead.lat_deg, lead.lon_deg, lead.alt_rel_m) == (ORIGIN[0], ORIGIN[1], 300.0)
    assert lead.course_deg == pytest.approx(135.0)
    assert lead.speed_m_s == pytest.approx(30.0 * math.sqrt(2))
    assert lead.time_s == 1234.5
    # a stopped ground vehicle's velocity has no direction: its heading orients the slots
    stopped = VehicleStatus(
        vehicle_id=9,
        time_unix_s=1234.5,
        lat_deg=ORIGIN[0],
        lon_deg=ORIGIN[1],
        alt_msl_m=650.0,
        alt_rel_m=0.0,
        heading_deg=250.0,
    )
    parked = LeadState.from_status(stopped)
    assert parked.course_deg == pytest.approx(250.0) and parked.speed_m_s == 0.0
