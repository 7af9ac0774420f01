"""The paper's score (section 2.3.6) as a pure object: terms, weights from the database,
the bounded time term, the reference point of each kind of mission."""

from __future__ import annotations

import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from swarm_node.core.mission.scoring import (
    Candidate,
    PaperScore,
    ScoreError,
    mission_terms,
    payload_wanted,
    reference_point,
)
from swarm_node.core.profile import PayloadClass
from swarm_node.database import SwarmDatabase, seed_payload_classes
from swarm_proto import Geometry, GeometryKind, LatLon, Mission, MissionType, Selector, SelectorKind

EO15 = "EO 1.5 Mpx 2-axis gimbal"
EO1080 = "EO 1080p 2-axis gimbal"
THERMAL = "Thermal 640 3-axis gimbal"
SDR = "SDR receiver"
REF = LatLon(40.0, -3.0)


@pytest.fixture(scope="module")
def classes() -> dict[str, PayloadClass]:
    return seed_payload_classes()


def test_payload_hierarchy_model_subtype_type_none(classes: dict[str, PayloadClass]) -> None:
    want = payload_wanted(EO15, classes)
    assert PaperScore.payload_term(classes[EO15], want) == 0.0
    assert PaperScore.payload_term(classes[EO1080], want) == 0.5  # visible camera
    assert PaperScore.payload_term(classes[THERMAL], want) == 0.75  # optical
    assert PaperScore.payload_term(classes[SDR], want) == 1.0
    assert PaperScore.payload_term(PayloadClass(), want) == 1.0  # no payload
    # a mission asking for no payload: every vehicle matches
    assert PaperScore.payload_term(classes[SDR], payload_wanted("", classes)) == 0.0


def test_unknown_payload_model_is_a_clear_error(classes: dict[str, PayloadClass]) -> None:
    with pytest.raises(ScoreError, match="unknown payload model 'EO 2000'"):
        payload_wanted("EO 2000", classes)


def test_weights_come_from_the_database_normalized() -> None:
    params = SwarmDatabase.memory().module_params("voting")
    s = PaperScore.from_params(params)
    assert (s.weight_payload, s.weight_time, s.weight_battery) == pytest.approx(
        (0.6 / 1.1, 0.2 / 1.1, 0.3 / 1.1)
    )
    assert s.weight_payload + s.weight_time + s.weight_battery == pytest.approx(1.0)
    assert s.time_scale_per_s == 0.01
    assert PaperScore.from_params(params) == PaperScore()  # the defaults are the seed's


@pytest.mark.parametrize(
    "params",
    [
        {"weight_payload": 0.0, "weight_time": 0.0, "weight_battery": 0.0},
        {"weight_payload": -1.0},
        {"weight_time": math.nan},
        {"time_scale_per_s": 0.0},
    ],
)
def test_bad_weights_are_refused(params: dict[str, float]) -> None:
    with pytest.raises(ScoreError):
        PaperScore.from_params(params)


def test_battery_is_linear() -> None:
    assert PaperScore.battery_term(100.0) == 0.0
    assert PaperScore.battery_term(0.0) == 1.0
    assert PaperScore.battery_term(25.0) == 0.75
    assert PaperScore.battery_term(None) == 1.0
    assert PaperScore.battery_term(150.0) == 0.0  # clamped


def test_time_term_is_bounded_where_the_papers_atanh_is_not() -> None:
    s = PaperScore()
    assert s.time_term(0.0) == 0.0
    # near 0, the same as the paper's atanh(0.01 t) (same slope)
    assert s.time_term(10.0) == pytest.approx(math.atanh(0.1), rel=0.01)
    for t in (99.0, 100.0, 101.0, 1000.0, 1e9):
        assert 0.0 <= s.time_term(t) <= 1.0
    assert s.time_term(200.0) < s.time_term(300.0)  # still ranks far vehicles
    assert s.time_term(None) == 1.0  # unknown position or speed


def test_arrival_time_is_distance_over_cruise_speed() -> None:
    one_km_north = LatLon(REF.lat_deg + 1000.0 / 111_000.0, REF.lon_deg)
    c = Candidate(1, PayloadClass(), one_km_north, 20.0, 100.0)
    assert PaperScore.arrival_s(c, REF) == pytest.approx(1000.0 / 20.0, rel=0.01)
    assert PaperScore.arrival_s(Candidate(1, PayloadClass(), None, 20.0, 100.0), REF) is None
    assert PaperScore.arrival_s(Candidate(1, PayloadClass(), REF, 0.0, 100.0), REF) is None


def test_the_papers_formula(classes: dict[str, PayloadClass]) -> None:
    s = PaperScore()
    pos = LatLon(REF.lat_deg + 0.01, REF.lon_deg)
    c = Candidate(7, classes[EO1080], pos, 10.0, 80.0)
    t = s.terms(c, classes[EO15], REF)
    expected = (
        1.0
        - 0.6 / 1.1 * 0.5
        - 0.2 / 1.1 * math.tanh(0.01 * PaperScore.arrival_s(c, REF))  # type: ignore[operator]
        - 0.3 / 1.1 * 0.2
    )
    assert t.score == pytest.approx(expected)
    # the best possible vehicle scores 1: the model, on the spot, full battery
    best = Candidate(1, classes[EO15], REF, 26.0, 100.0)
    assert s.score(best, classes[EO15], REF) == 1.0


@given(
    pct=st.floats(-50, 150) | st.none(),
    dist_deg=st.floats(0, 5),
    speed=st.floats(0, 60),
    model=st.sampled_from([EO15, EO1080, THERMAL, SDR, ""]),
)
def test_score_is_always_in_0_1(
    pct: float | None, dist_deg: float, speed: float, model: str
) -> None:
    classes = seed_payload_classes()
    have = classes[model] if model else PayloadClass()
    c = Candidate(1, have, LatLon(REF.lat_deg + dist_deg, REF.lon_deg), speed, pct)
    v = PaperScore().score(c, classes[EO15], REF)
    assert 0.0 <= v <= 1.0 and math.isfinite(v)


def test_reference_points() -> None:
    square = Geometry(
        GeometryKind.POLYGON,
        (LatLon(40.0, -3.0), LatLon(40.0, -2.99), LatLon(40.01, -2.99), LatLon(40.01, -3.0)),
    )
    for kind in (MissionType.AREA, MissionType.PERIMETER):
        c = reference_point(kind, square)
        assert c.lat_deg == pytest.approx(40.005, abs=1e-6)
        assert c.lon_deg == pytest.approx(-2.995, abs=1e-6)
    route = Geometry(GeometryKind.POLYLINE, (LatLon(41.0, -3.0), LatLon(41.1, -3.0)))
    assert reference_point(MissionType.ROUTE, route) == LatLon(41.0, -3.0)
    target = Geometry(GeometryKind.POINT, (LatLon(42.0, -3.0),))
    assert reference_point(MissionType.TARGET, target) == LatLon(42.0, -3.0)
    lead = LatLon(43.0, -3.0)
    assert reference_point(MissionType.MUMT, target, lead) == lead
    assert reference_point(MissionType.MUMT, target) == LatLon(42.0, -3.0)  # lead unknown


def test_candidate_of_a_profile(fleet_profiles: dict) -> None:
    c = Candidate.of(fleet_profiles[7], REF, 90.0)
    assert c.payload.model == EO1080 and c.cruise_speed_m_s == 10.0 and c.battery_pct == 90.0


def test_a_vehicles_own_score_for_a_quantity_mission(fleet_profiles: dict) -> None:
    """The six-VTOL scenario of the issue: a target 2 km north, two cameras asked for;
    the formula computed by hand here."""
    classes = seed_payload_classes()
    target = LatLon(REF.lat_deg + 2000.0 / 111_000.0, REF.lon_deg)
    m = Mission(
        9,
        900,
        MissionType.TARGET,
        Geometry(GeometryKind.POINT, (target,)),
        selection=Selector(SelectorKind.QUANTITY, quantity=2, payload_model=EO15),
    )
    vtol = Candidate.of(fleet_profiles[1], REF, 60.0)  # EO 1.5 Mpx: the model
    t = mission_terms(PaperScore(), m, vtol, classes)
    arrival = PaperScore.arrival_s(vtol, target)
    assert arrival == pytest.approx(2000.0 / 26.0, rel=0.01)
    hand = 1 - 0.6 / 1.1 * 0 - 0.2 / 1.1 * math.tanh(0.01 * arrival) - 0.3 / 1.1 * 0.4  # type: ignore[operator]
    assert (t.payload, t.battery) == (0.0, pytest.approx(0.4)) and t.score == pytest.approx(hand)
    quad = Candidate.of(fleet_profiles[7], REF, 60.0)  # EO 1080p: same subtype
    assert mission_terms(PaperScore(), m, quad, classes).payload == 0.5
