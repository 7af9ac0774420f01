"""Kinematic models: properties that must hold for any target and wind (hypothesis),
plus the VTOL transition sequence."""

from __future__ import annotations

import math

from hypothesis import given, settings
from hypothesis import strategies as st

from swarm_sim.core import (
    ALBATROSS_250_VTOL,
    GENERIC_BOAT,
    GENERIC_PLANE,
    GENERIC_QUADCOPTER,
    GENERIC_ROVER,
)
from swarm_sim.core.battery import Battery
from swarm_sim.core.geo import LocalFrame, point_in_polygon
from swarm_sim.core.kinematics import (
    G_M_S2,
    Body,
    EventKind,
    FixedWingModel,
    GroundModel,
    Guide,
    MultirotorModel,
    Target,
    VtolModel,
    VtolState,
)
from tests.conftest import examples

DT = 0.1
coords = st.floats(-3000, 3000)
winds = st.floats(0, 12)
directions = st.floats(0, 360)


def flying_body(airspeed: float, alt: float = 100.0) -> Body:
    return Body(alt=alt, ground_alt=0.0, airspeed=airspeed, vn=airspeed, on_ground=False)


@settings(max_examples=examples(40), deadline=None)
@given(
    coords,
    coords,
    st.floats(30, 300),
    winds,
    directions,
    st.sampled_from([GENERIC_PLANE, ALBATROSS_250_VTOL]),
)
def test_fixed_wing_never_below_min_airspeed_and_turns_within_bank_limit(
    n: float, e: float, alt: float, wind: float, wind_from: float, params: object
) -> None:
    p = params  # type: ignore[assignment]
    model = FixedWingModel(p)  # type: ignore[arg-type]
    b = flying_body(p.cruise_speed_m_s)  # type: ignore[attr-defined]
    b.wind_n = -wind * math.cos(math.radians(wind_from))
    b.wind_e = -wind * math.sin(math.radians(wind_from))
    target = Target(Guide.GOTO, n, e, alt)
    bank = math.radians(p.max_bank_deg)  # type: ignore[attr-defined]
    for _ in range(600):
        model.step(b, target, DT)
        assert b.airspeed >= p.min_airspeed_m_s - 1e-9  # type: ignore[attr-defined]
        max_rate = G_M_S2 * math.tan(bank) / b.airspeed
        assert abs(b.yaw_rate_rad_s) <= max_rate + 1e-9
        assert abs(b.roll_rad) <= bank + 1e-6
        assert -p.sink_rate_m_s - 1e-6 <= b.climb_rate <= p.climb_rate_m_s + 1e-6  # type: ignore[attr-defined]


def test_fixed_wing_turn_radius_is_bank_limited() -> None:
    p = GENERIC_PLANE
    model = FixedWingModel(p)
    b = flying_body(p.cruise_speed_m_s)
    # a target behind: the plane turns around at the tightest radius
    target = Target(Guide.GOTO, -5000.0, 1.0, 100.0)
    east = []
    for _ in range(400):
        model.step(b, target, DT)
        east.append(b.e)
    diameter = max(east) - min(east)
    r_min = p.cruise_speed_m_s**2 / (G_M_S2 * math.tan(math.radians(p.max_bank_deg)))
    assert diameter >= 2 * r_min * 0.95


@settings(max_examples=examples(40), deadline=None)
@given(coords, coords, st.floats(5, 120), winds, directions)
def test_multirotor_reaches_any_point_and_stops_there(
    n: float, e: float, alt: float, wind: float, frm: float
) -> None:
    p = GENERIC_QUADCOPTER
    model = MultirotorModel(p)
    b = Body(alt=20.0, ground_alt=0.0, on_ground=False)
    b.wind_n, b.wind_e = -wind * math.cos(math.radians(frm)), -wind * math.sin(math.radians(frm))
    target = Target(Guide.GOTO, n, e, alt)
    for _ in range(int(900 / DT)):
        model.step(b, target, DT)
        assert b.groundspeed <= p.cruise_speed_m_s + 1e-6
        assert -p.sink_rate_m_s - 1e-6 <= b.climb_rate <= p.climb_rate_m_s + 1e-6
        if math.hypot(b.n - n, b.e - e) < 0.5 and abs(b.alt - alt) < 0.5 and b.groundspeed < 0.2:
            break
    else:
        raise AssertionError(f"did not reach {n, e, alt}: {b}")


def test_multirotor_landing_speed_and_touchdown() -> None:
    p = GENERIC_QUADCOPTER
    model = MultirotorModel(p)
    b = Body(alt=40.0, ground_alt=0.0, on_ground=False)
    target = Target(Guide.LAND, 0.0, 0.0, 0.0)
    events = []
    while not b.on_ground:
        events += model.step(b, target, DT)
        if b.height < p.land_final_alt_m - 1.0:
            assert b.vd <= p.land_speed_m_s + 0.26  # final descent at LAND_SPEED
    assert [ev.kind for ev in events] == [EventKind.TOUCHDOWN]
    assert events[0].value <= p.land_speed_m_s + 0.01


@settings(max_examples=examples(30), deadline=None)
@given(st.floats(-500, 500), st.floats(-500, 500), st.sampled_from([GENERIC_ROVER, GENERIC_BOAT]))
def test_ground_vehicles_stay_on_the_ground(n: float, e: float, params: object) -> None:
    p = params  # type: ignore[assignment]
    model = GroundModel(p)  # type: ignore[arg-type]
    b = Body(alt=5.0, ground_alt=5.0)
    target = Target(Guide.GOTO, n, e, 500.0)
    for _ in range(int(900 / DT)):
        model.step(b, target, DT)
        assert b.alt == 5.0 and b.vd == 0.0 and b.on_ground
        assert b.groundspeed <= p.max_speed_m_s + 1e-9  # type: ignore[attr-defined]
        if math.hypot(b.n - n, b.e - e) < p.wp_radius_m and b.groundspeed < 0.2:  # type: ignore[attr-defined]
            return
    raise AssertionError("never arrived")


def test_vtol_transition_sequence_and_back() -> None:
    p = ALBATROSS_250_VTOL
    model = VtolModel(p)
    b = Body(alt=0.0, ground_alt=0.0, vtol_state=VtolState.MC)
    events = []
    while b.alt < 39.9:
        events += model.step(b, Target(Guide.TAKEOFF, 0, 0, 40.0, fixed_wing=False), DT)
    assert b.vtol_state == VtolState.MC and b.groundspeed < 0.5
    t = 0.0
    while b.vtol_state != VtolState.FW:
        events += model.step(b, Target(Guide.GOTO, 5000.0, 0.0, 40.0), DT)
        t += DT
    kinds = [ev.kind for ev in events]
    assert kinds == [
        EventKind.TRANSITION_STARTED,
        EventKind.TRANSITION_AIRSPEED,
        EventKind.TRANSITION_DONE,
    ]
    assert events[1].value >= p.min_airspeed_m_s
    expected = p.min_airspeed_m_s / p.transition_accel_m_s2 + p.transition_time_s
    assert abs(t - expected) < 0.5
    assert abs(b.alt - 40.0) < 1.0  # the lift motors hold the height
    while b.vtol_state != VtolState.MC:
        model.step(b, Target(Guide.LAND, b.n, b.e, 0.0, fixed_wing=False), DT)
    assert b.groundspeed <= p.vtol_speed_m_s + 0.5


def test_battery_voltage_falls_with_charge() -> None:
    bat = Battery(GENERIC_QUADCOPTER.battery)
    full = bat.resting_voltage
    assert abs(full - 3 * 4.2) < 0.01
    bat.step(30.0, 180.0)  # 3 min of hover
    assert bat.remaining_pct < 100 and bat.resting_voltage < full
    assert bat.voltage < bat.resting_voltage  # sag under load
    assert abs(bat.consumed_mah - 30.0 * 180.0 / 3.6) < 1e-6


@settings(max_examples=examples(50), deadline=None)
@given(st.floats(-60, 60), st.floats(-179, 179), coords, coords)
def test_local_frame_round_trip(lat: float, lon: float, n: float, e: float) -> None:
    frame = LocalFrame(lat, lon)
    back = frame.to_ne(*frame.to_latlon(n, e))
    assert abs(back[0] - n) < 1e-6 and abs(back[1] - e) < 1e-6


def test_point_in_polygon() -> None:
    square = [(0.0, 0.0), (0.0, 10.0), (10.0, 10.0), (10.0, 0.0)]
    assert point_in_polygon(5, 5, square)
    assert not point_in_polygon(15, 5, square)
    assert not point_in_polygon(5, 5, square[:2])


def test_the_albatross_defaults_are_the_papers_and_the_databases() -> None:
    p = ALBATROSS_250_VTOL
    assert p.name == "Albatross 250 VTOL" and p.can_hover and p.is_fixed_wing
    assert (p.cruise_speed_m_s, p.stall_speed_m_s, p.mass_kg) == (26.0, 15.5, 12.5)
    assert p.stall_speed_m_s < p.min_airspeed_m_s < p.cruise_speed_m_s < p.max_speed_m_s
    assert p.camera is not None and p.camera.gimbal_axes == 2
    w, h = p.camera.resolution_px
    assert 1.4e6 <= w * h <= 1.6e6  # 1.5 Mpx
    # the swarm database seeds the same aircraft: planners and simulator agree
    from swarm_node.database import ALBATROSS, seed_profiles

    seeded = seed_profiles()[ALBATROSS]
    assert seeded.cruise_speed_m_s == p.cruise_speed_m_s
    assert seeded.min_speed_m_s == p.stall_speed_m_s
    assert seeded.max_speed_m_s == p.max_speed_m_s
    assert seeded.camera is not None and seeded.camera.hfov_deg == p.camera.hfov_deg


def test_the_albatross_cruises_at_26_m_s_in_the_simulator() -> None:
    model = VtolModel(ALBATROSS_250_VTOL)
    b = flying_body(ALBATROSS_250_VTOL.cruise_speed_m_s)
    b.vtol_state = VtolState.FW
    target = Target(Guide.GOTO, 20_000.0, 0.0, 100.0)
    for _ in range(300):
        model.step(b, target, DT)
    assert math.isclose(b.airspeed, 26.0, abs_tol=0.5)


def test_a_vtol_leaning_on_its_lift_motors_stays_within_30_degrees() -> None:
    """Found flying the paper's experiment 1 with landing on the pads (`make demo`): a
    VTOL circling its pad at 28 m/s was sent its landing item; on the lift motors the
    simulator reported pitch -88 degrees (the hover model's last speed was from the
    take-off) and then -65 for ten seconds (a copter's drag at wing speed), which the
    node's monitoring took for an abnormal attitude: an emergency and a parachute over
    the pad. A QuadPlane on its lift motors leans within Q_ANGLE_MAX (30 degrees by
    default), as a copter within ANGLE_MAX."""
    p = ALBATROSS_250_VTOL
    model = VtolModel(p)
    b = Body(alt=0.0, ground_alt=0.0, vtol_state=VtolState.MC)
    while b.alt < 39.9:
        model.step(b, Target(Guide.TAKEOFF, 0, 0, 40.0, fixed_wing=False), DT)
    while b.vtol_state != VtolState.FW:
        model.step(b, Target(Guide.GOTO, 5000.0, 0.0, 40.0), DT)
    for _ in range(100):
        model.step(b, Target(Guide.GOTO, 5000.0, 0.0, 40.0), DT)
    assert b.groundspeed > 20.0
    worst = 0.0
    for _ in range(600):
        model.step(b, Target(Guide.LAND, b.n, b.e, 0.0, fixed_wing=False), DT)
        worst = max(worst, abs(math.degrees(b.pitch_rad)), abs(math.degrees(b.roll_rad)))
    assert worst <= 30.0 + 1e-9
    copter = MultirotorModel(GENERIC_QUADCOPTER)
    c = flying_body(0.0, 30.0)
    for _ in range(300):
        copter.step(c, Target(Guide.GOTO, 2000.0, 0.0, 30.0), DT)
        worst = max(worst, abs(math.degrees(c.pitch_rad)), abs(math.degrees(c.roll_rad)))
    assert worst <= 30.0 + 1e-9
