"""Closest-approach geometry: against hand-computed cases and an independent ECEF sum."""

from __future__ import annotations

import math

import numpy as np
import pymap3d
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from swarm_node.core.safety.ttc import (
    EPS_SPEED2,
    BadTrackError,
    Track,
    along_route,
    approaches,
    closest_approach,
    entry_time,
    route_approach,
)
from tests.conftest import examples

LAT0, LON0, H0 = 40.4168, -3.7038, 650.0


def at(vid: int, e: float, n: float, up: float = 0.0, **kw: float) -> Track:
    lat, lon, h = pymap3d.enu2geodetic(e, n, up, LAT0, LON0, H0)
    return Track(vid, float(lat), float(lon), float(h), **kw)


def test_head_on_meets_halfway() -> None:
    own = at(1, 0, 0, vel_east_m_s=20.0)
    other = at(2, 1000, 0, vel_east_m_s=-20.0)
    a = approaches(own, [other], now=0.0, horizon_s=60.0)
    assert a.t_cpa_s[0] == pytest.approx(25.0, abs=0.01)
    assert a.miss_m[0] == pytest.approx(0.0, abs=0.2)  # curvature: 8 cm at 1 km
    assert a.range_m[0] == pytest.approx(1000.0, abs=0.01)


def test_lateral_and_vertical_offsets_are_the_miss() -> None:
    own = at(1, 0, 0, vel_east_m_s=20.0)
    other = at(2, 1000, 30, 40, vel_east_m_s=-20.0)
    a = approaches(own, [other], now=0.0, horizon_s=60.0)
    assert a.miss_m[0] == pytest.approx(50.0, abs=0.1)
    assert a.horizontal_m[0] == pytest.approx(30.0, abs=0.1)
    assert a.vertical_m[0] == pytest.approx(40.0, abs=0.1)


def test_diverging_and_still_pairs_have_their_cpa_now() -> None:
    own = at(1, 0, 0, vel_east_m_s=-20.0)
    away = at(2, 100, 0, vel_east_m_s=20.0)
    still = at(3, 0, 70)
    a = approaches(own, [away, still], now=0.0, horizon_s=60.0)
    assert list(a.t_cpa_s) == [0.0, 0.0] or a.t_cpa_s[1] > 0  # own moves: still one closes
    assert a.t_cpa_s[0] == 0.0 and a.miss_m[0] == pytest.approx(100.0, abs=0.01)
    parked = approaches(at(1, 0, 0), [still], now=0.0, horizon_s=60.0)
    assert parked.t_cpa_s[0] == 0.0 and parked.miss_m[0] == pytest.approx(70.0, abs=0.01)


def test_the_horizon_clips_the_look_ahead() -> None:
    own = at(1, 0, 0, vel_east_m_s=10.0)
    other = at(2, 2000, 0, vel_east_m_s=-10.0)  # CPA in 100 s
    a = approaches(own, [other], now=0.0, horizon_s=30.0)
    assert a.t_cpa_s[0] == 30.0
    assert a.miss_m[0] == pytest.approx(1400.0, abs=0.1)


def test_stale_report_is_extrapolated_and_widened_by_what_it_could_have_done() -> None:
    own = at(1, 0, 0, time_s=100.0)
    other = at(2, 500, 0, vel_east_m_s=-10.0, time_s=97.0, max_speed_m_s=35.0)
    a = approaches(own, [other], now=100.0, horizon_s=10.0)
    assert a.range_m[0] == pytest.approx(470.0, abs=0.01)  # 3 s at 10 m/s since
    assert a.margin_m[0] == pytest.approx(0.5 * 10.0 * 3.0**2)  # accelerating at 10 m/s^2
    slow = at(2, 500, 0, vel_east_m_s=-10.0, time_s=97.0, max_speed_m_s=35.0, max_accel_m_s2=100.0)
    a = approaches(own, [slow], now=100.0, horizon_s=10.0)
    assert a.margin_m[0] == pytest.approx(3.0 * (35.0 + 10.0))  # no faster than its top speed
    fresh = approaches(
        own, [at(2, 470, 0, vel_east_m_s=-10.0, time_s=100.0, max_speed_m_s=35.0)], 100.0, 10.0
    )
    assert fresh.margin_m[0] == 0.0


def test_distances_are_exact_on_the_ellipsoid() -> None:
    """Ten kilometres apart: the range is the ECEF chord, computed here independently."""
    own = Track(1, 40.0, -3.0, 700.0)
    other = Track(2, 40.09, -2.95, 1200.0)
    a = approaches(own, [other], now=0.0, horizon_s=1.0)
    p = np.array(pymap3d.geodetic2ecef(40.0, -3.0, 700.0))
    q = np.array(pymap3d.geodetic2ecef(40.09, -2.95, 1200.0))
    assert a.range_m[0] == pytest.approx(float(np.linalg.norm(q - p)), abs=1e-3)


def test_velocities_are_rotated_between_tangent_planes() -> None:
    """Two aircraft 200 km apart flying due north at the same speed: in one frame
    their velocities differ (meridians converge), by what the rotation says."""
    own = Track(1, 40.0, -3.0, 700.0, vel_north_m_s=50.0)
    other = Track(2, 40.0, -0.65, 700.0, vel_north_m_s=50.0)
    a = approaches(own, [other], now=0.0, horizon_s=0.0)
    assert a.range_m[0] > 199_000
    same = approaches(own, [Track(2, 40.0, -3.0, 700.0, vel_north_m_s=50.0)], 0.0, 60.0)
    assert same.miss_m[0] == pytest.approx(0.0, abs=1e-6)


@pytest.mark.parametrize("bad", [math.nan, math.inf])
def test_non_finite_tracks_are_refused(bad: float) -> None:
    with pytest.raises(BadTrackError):
        Track(1, bad, 0.0, 0.0)
    with pytest.raises(BadTrackError):
        Track(1, 0.0, 0.0, 0.0, vel_down_m_s=bad)
    with pytest.raises(BadTrackError):
        Track(1, 91.0, 0.0, 0.0)


vec = st.tuples(*[st.floats(-2000, 2000, allow_nan=False)] * 3)
vel = st.tuples(*[st.floats(-60, 60, allow_nan=False)] * 3)


@settings(max_examples=examples(200), deadline=None)
@given(vec, vel, st.floats(0.0, 120.0))
def test_cpa_is_the_minimum_over_the_horizon(
    p: tuple[float, ...], v: tuple[float, ...], horizon: float
) -> None:
    rp, rv = np.array(p), np.array(v)
    a = closest_approach(rp, rv, horizon)
    assert 0.0 <= a.t_cpa_s <= horizon
    assert a.miss_m <= a.range_m + 1e-9
    ts = np.linspace(0.0, horizon, 241)
    sampled = np.linalg.norm(rp[None, :] + rv[None, :] * ts[:, None], axis=1)
    # relative speeds under sqrt(EPS_SPEED2) (3.2e-5 m/s) count as none: CPA now, which
    # can be that speed x the horizon longer than the sampled minimum (hypothesis found
    # 1e-5 m/s over 11 s)
    assert a.miss_m <= sampled.min() + math.sqrt(EPS_SPEED2) * horizon + 1e-9
    assert a.miss_m == pytest.approx(float(np.linalg.norm(rp + rv * a.t_cpa_s)), abs=1e-9)


@settings(max_examples=examples(100), deadline=None)
@given(
    st.floats(-1500, 1500),
    st.floats(-1500, 1500),
    st.floats(-50, 50),
    st.floats(-40, 40),
    st.floats(-40, 40),
    st.floats(0.0, 5.0),
    st.floats(0.0, 5.0),
)
def test_an_older_report_of_the_same_motion_never_looks_safer(
    e: float, n: float, up: float, ve: float, vn: float, age1: float, extra: float
) -> None:
    """The same motion reported earlier (so extrapolated to the same place now) only
    widens the protection volume: miss less margin never grows with age."""
    own = at(1, 0, 0, 0, vel_east_m_s=20.0, time_s=100.0)

    def report(age: float) -> Track:  # where it was `age` s before now
        return at(
            2,
            e - ve * age,
            n - vn * age,
            up,
            vel_east_m_s=ve,
            vel_north_m_s=vn,
            time_s=100.0 - age,
            max_speed_m_s=35.0,
        )

    young = approaches(own, [report(age1)], 100.0, 30.0)
    old = approaches(own, [report(age1 + extra)], 100.0, 30.0)
    assert old.miss_m[0] - old.margin_m[0] <= young.miss_m[0] - young.margin_m[0] + 0.05


def test_the_loss_of_separation_comes_before_the_closest_approach() -> None:
    """Head-on at 40 m/s closing from 1000 m: the 20 m sphere is entered at 24.5 s, the
    closest point is at 25 s; inside already: 0; passing 30 m apart: never."""
    p, v = np.array([[1000.0, 0.0, 0.0]]), np.array([[-40.0, 0.0, 0.0]])
    assert entry_time(p, v, 20.0, 60.0)[0] == pytest.approx(24.5)
    assert entry_time(p, v, 20.0, 20.0)[0] == math.inf  # beyond the horizon
    assert entry_time(np.array([[10.0, 0.0, 0.0]]), v, 20.0, 60.0)[0] == 0.0
    assert entry_time(np.array([[1000.0, 30.0, 0.0]]), v, 20.0, 60.0)[0] == math.inf
    assert entry_time(p, -v, 20.0, 60.0)[0] == math.inf  # moving apart
    assert entry_time(p, np.zeros((1, 3)), 20.0, 60.0)[0] == math.inf  # no relative motion


vec = st.tuples(*[st.floats(-500, 500)] * 3)


@given(vec, st.tuples(*[st.floats(-50, 50)] * 3), st.floats(1.0, 60.0))
def test_the_entry_is_on_the_sphere_and_no_later_than_the_cpa(
    p: tuple[float, float, float], v: tuple[float, float, float], radius: float
) -> None:
    rel_p, rel_v = np.array([p]), np.array([v])
    t = float(entry_time(rel_p, rel_v, radius, 120.0)[0])
    a = closest_approach(rel_p, rel_v, 120.0)
    if math.isinf(t):
        assert a.miss_m[0] > radius - 1e-6
        return
    assert 0.0 <= t <= a.t_cpa_s[0] + 1e-9
    d = float(np.linalg.norm(rel_p[0] + rel_v[0] * t))
    if t > 0.0:
        assert d == pytest.approx(radius, rel=1e-6, abs=1e-6)
    else:
        assert d <= radius + 1e-9


def test_a_route_is_flown_leg_by_leg_then_held() -> None:
    legs = along_route(np.zeros(3), np.array([[30.0, 0, 0], [30.0, 50.0, 0]]), 10.0, 60.0)
    times, starts, vels = legs
    assert times.tolist() == pytest.approx([0.0, 3.0, 8.0])
    assert np.allclose(vels, [[10.0, 0, 0], [0, 10.0, 0], [0, 0, 0]])
    assert starts[2].tolist() == pytest.approx([30.0, 50.0, 0.0])


def test_a_route_that_turns_away_misses_what_the_straight_line_hits() -> None:
    """Flying east at 10 m/s to a lane's end 30 m ahead, then north: a vehicle hovering
    120 m east is 90 m away at the closest, never inside 20 m; straight on, it is hit
    at 12 s (inside 20 m at 10 s)."""
    legs = along_route(np.zeros(3), np.array([[30.0, 0, 0], [30.0, 300.0, 0]]), 10.0, 30.0)
    other, still = np.array([[120.0, 0, 0]]), np.zeros((1, 3))
    t, miss, entry = route_approach(legs, other, still, np.array([20.0]), 30.0)
    assert miss[0] == pytest.approx(90.0) and t[0] == pytest.approx(3.0) and entry[0] == math.inf
    straight = along_route(np.zeros(3), np.array([[300.0, 0, 0]]), 10.0, 30.0)
    t, miss, entry = route_approach(straight, other, still, np.array([20.0]), 30.0)
    assert miss[0] == pytest.approx(0.0) and t[0] == pytest.approx(12.0)
    assert entry[0] == pytest.approx(10.0)


@given(vec, st.tuples(*[st.floats(-50, 50)] * 3), st.tuples(*[st.floats(-20, 20)] * 3))
def test_one_long_leg_is_the_straight_line(
    p: tuple[float, float, float], v: tuple[float, float, float], u: tuple[float, float, float]
) -> None:
    """A route of one leg longer than the horizon is constant velocity: the same closest
    approach and loss of separation as `closest_approach` and `entry_time`."""
    own_v = np.array(u)
    speed = float(np.linalg.norm(own_v))
    if speed < 0.1:
        return
    legs = along_route(np.zeros(3), np.array([own_v * 100.0]), speed, 30.0)
    rel_p, rel_v = np.array([p]), np.array([v]) - own_v
    _t, miss, entry = route_approach(legs, np.array([p]), np.array([v]), np.array([20.0]), 30.0)
    a = closest_approach(rel_p, rel_v, 30.0)
    assert miss[0] == pytest.approx(a.miss_m[0], abs=1e-6)
    e = entry_time(rel_p, rel_v, 20.0, 30.0)[0]
    assert (math.isinf(e) and math.isinf(entry[0])) or entry[0] == pytest.approx(e, abs=1e-6)
