"""The one geodesy (swarm_proto.geodesy) against pyproj's WGS84 geodesic (Karney), and
every safety module measuring with it (part 1)."""

from __future__ import annotations

import math

import pymap3d
import pyproj
import pytest
from hypothesis import given
from hypothesis import strategies as st

from swarm_node.core import fences, monitoring
from swarm_node.core.planning import transit
from swarm_proto import Geometry, geodesy

GEOD = pyproj.Geod(ellps="WGS84")

lat = st.floats(-80.0, 80.0)
lon = st.floats(-179.0, 179.0)
azimuth = st.floats(0.0, 360.0)


@given(lat, lon, azimuth, st.floats(0.0, 10_000.0))
def test_ground_distance_is_the_geodesic_to_10_micrometres_up_to_10_km(
    la: float, lo: float, az: float, d: float
) -> None:
    lo2, la2, _ = GEOD.fwd(lo, la, az, d)
    assert geodesy.distance_m(la, lo, la2, lo2) == pytest.approx(d, abs=1e-5)


@given(lat, lon, azimuth, st.floats(10_000.0, 50_000.0))
def test_ground_distance_is_the_geodesic_to_1_mm_up_to_50_km(
    la: float, lo: float, az: float, d: float
) -> None:
    lo2, la2, _ = GEOD.fwd(lo, la, az, d)
    assert geodesy.distance_m(la, lo, la2, lo2) == pytest.approx(d, abs=1e-3)


def test_the_old_flat_earth_formula_was_off_by_0_3_percent() -> None:
    """What the one geodesy replaced: 111,320 m per degree at 37.4 degrees north."""
    la, lo = 37.4, -6.0
    lo2, la2, _ = GEOD.fwd(lo, la, 0.0, 300.0)
    flat = (la2 - la) * 111_320.0
    assert 0.8 < flat - 300.0 < 1.0  # 0.9 m long over 300 m north-south
    assert geodesy.distance_m(la, lo, la2, lo2) == pytest.approx(300.0, abs=1e-6)


@given(lat, lon, st.floats(-5000, 5000), st.floats(-5000, 5000), st.floats(-50, 500))
def test_3d_distance_is_the_ecef_chord(la: float, lo: float, n: float, e: float, up: float) -> None:
    la2, lo2, h2 = pymap3d.enu2geodetic(e, n, up, la, lo, 10.0)
    d = geodesy.distance_3d_m(la, lo, 10.0, float(la2), float(lo2), float(h2))
    assert d == pytest.approx(math.sqrt(n * n + e * e + up * up), abs=1e-6)


@given(lat, lon, st.floats(-500, 5000), st.floats(-5000, 5000), st.floats(-5000, 5000))
def test_one_point_formulas_are_pymap3ds(
    la: float, lo: float, h: float, n: float, e: float
) -> None:
    """`ecef` and `enu_of`, on Python floats for speed, give pymap3d's answers."""
    want = pymap3d.geodetic2ecef(la, lo, h)
    assert geodesy.ecef(la, lo, h) == pytest.approx(tuple(map(float, want)), abs=1e-6)
    la2, lo2, h2 = (float(x) for x in pymap3d.enu2geodetic(e, n, 30.0, la, lo, h))
    want_enu = pymap3d.geodetic2enu(la2, lo2, h2, la, lo, h)
    got = geodesy.enu_of(la2, lo2, h2, la, lo, h)
    assert got == pytest.approx(tuple(map(float, want_enu)), abs=1e-6)


@given(lat, lon, st.floats(-10_000, 10_000), st.floats(-10_000, 10_000))
def test_offset_lands_at_the_distance_and_bearing_asked(
    la: float, lo: float, n: float, e: float
) -> None:
    la2, lo2 = geodesy.offset(la, lo, n, e)
    az, _back, d = GEOD.inv(lo, la, lo2, la2)
    r = math.hypot(n, e)
    assert d == pytest.approx(r, rel=3e-6, abs=1e-6)  # a tangent-plane offset: 2 cm at 14 km
    if r > 1.0:
        want = math.degrees(math.atan2(e, n)) % 360.0
        assert abs((az % 360.0 - want + 180.0) % 360.0 - 180.0) < 0.01
        assert abs((geodesy.bearing_deg(la, lo, la2, lo2) - want + 180.0) % 360.0 - 180.0) < 0.01


def test_every_safety_module_measures_with_it() -> None:
    """Monitoring (circle zones), the fence keeper, the mission manager's transit and
    the scenario tools give the same number for the same two points."""
    la, lo = 37.4, -6.0
    la2, lo2 = geodesy.offset(la, lo, 700.0, -300.0)
    d = geodesy.distance_m(la, lo, la2, lo2)
    assert transit.distance_m(la, lo, la2, lo2) == d
    assert fences._distance_m(la, lo, la2, lo2) == d
    circle = Geometry.circle(la, lo, d + 0.01)
    assert monitoring.inside(circle, la2, lo2)
    assert not monitoring.inside(Geometry.circle(la, lo, d - 0.01), la2, lo2)
