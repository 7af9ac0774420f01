"""Where a silent member's aircraft is, from its last report: along its held share until
its failsafe's timeout, then its RTL to its rally point, its error bound growing with
time (`safety/silent.py`: what the ground station and the map show of a LOST vehicle).
Pure, injected time."""

from __future__ import annotations

import math

import pymap3d
import pytest

from swarm_node.core.failsafe import COMPANION_TIMEOUT_S
from swarm_node.core.safety.silent import SilentAircraft, failsafe_after_s
from swarm_node.core.safety.ttc import Track
from swarm_proto import VehicleType
from tests.swarm_node.safety.test_avoidance import HOME, LAT0, LON0, T, status

ALT = 40.0


def geo(e: float, n: float, up: float = ALT) -> tuple[float, float, float]:
    lat, lon, _h = pymap3d.enu2geodetic(e, n, up, LAT0, LON0, HOME)
    return float(lat), float(lon), up


def enu(t: Track) -> tuple[float, float, float]:
    e, n, u = pymap3d.geodetic2enu(t.lat_deg, t.lon_deg, t.alt_msl_m, LAT0, LON0, HOME)
    return float(e), float(n), float(u)


def copter(route: bool = True) -> SilentAircraft:
    last = Track.from_status(status(3, 0.0, 0.0, ALT, ve=10.0), max_speed_m_s=20.0)
    a = SilentAircraft(
        last,
        VehicleType.COPTER,
        HOME,
        speed_m_s=10.0,
        rally=(*geo(0.0, -200.0)[:2], HOME + 30.0),
        home=(LAT0, LON0),
        failsafe_s=failsafe_after_s(VehicleType.COPTER),
    )
    # its share: 50 m east, then a lane 100 m north
    return a.with_route([geo(50.0, 0.0), geo(50.0, 100.0)], 10.0) if route else a


def test_along_its_share_until_the_failsafe_then_home_and_landed() -> None:
    a = copter()
    p = a.predict(T + 3.0)
    assert p.phase == "route"
    assert enu(p.track) == pytest.approx((30.0, 0.0, ALT), abs=0.5)
    assert (p.track.vel_east_m_s, p.track.vel_north_m_s) == pytest.approx((10.0, 0.0), abs=1e-6)
    p = a.predict(T + 8.0)  # round the lane's corner
    assert enu(p.track) == pytest.approx((50.0, 30.0, ALT), abs=0.5)
    assert p.track.vel_north_m_s == pytest.approx(10.0)
    # 10 s on: the failsafe; RTL from (50, 50) to the rally point at (0, -200), 40 m
    p = a.predict(T + COMPANION_TIMEOUT_S + 5.0)
    assert p.phase == "rtl"
    e, n, u = enu(p.track)
    assert u == pytest.approx(ALT, abs=0.5)
    assert math.hypot(e - 50.0, n - 50.0) == pytest.approx(50.0, abs=1.0)
    assert p.track.vel_north_m_s < -9.0  # heading south, home
    # 255 m home at 10 m/s, then a 1 m/s descent of 40 m
    p = a.predict(T + COMPANION_TIMEOUT_S + 26.0 + 10.0)
    assert p.phase == "landing" and enu(p.track)[2] == pytest.approx(30.0, abs=1.5)
    assert a.predict(T + COMPANION_TIMEOUT_S + 26.0 + 45.0).phase == "landed"


def test_its_error_bound_grows_with_time_up_to_a_cap() -> None:
    a = copter()
    errors = [a.predict(T + dt).track.error_m for dt in (0.0, 5.0, 15.0, 60.0, 600.0)]
    assert errors == sorted(errors)
    assert errors[0] == pytest.approx(a.model.base_error_m)
    assert errors[-1] == pytest.approx(a.model.max_error_m)


def test_no_route_straight_on_then_rtl_and_a_plane_circles_its_rally_point() -> None:
    last = Track.from_status(status(4, 0.0, 0.0, 100.0, vn=20.0), max_speed_m_s=35.0)
    plane = SilentAircraft(
        last, VehicleType.PLANE, HOME, speed_m_s=20.0, rally=(*geo(0.0, -200.0, 0.0)[:2], HOME)
    )
    p = plane.predict(T + 5.0)
    assert p.phase == "straight" and enu(p.track)[1] == pytest.approx(100.0, abs=0.5)
    p = plane.predict(T + 600.0)
    assert p.phase == "circling"
    assert enu(p.track)[:2] == pytest.approx((0.0, -200.0), abs=1.0)
    assert enu(p.track)[2] == pytest.approx(100.0, abs=0.5)  # at its altitude, over it
    assert p.track.error_m > 60.0  # its circle's radius on top of the cap


def test_rovers_and_boats_have_no_failsafe() -> None:
    assert failsafe_after_s(VehicleType.ROVER) is None
    assert failsafe_after_s(VehicleType.PLANE) == COMPANION_TIMEOUT_S


def test_a_quadplane_lands_at_its_rally_point_where_a_plane_would_circle() -> None:
    """The node sets Q_RTL_MODE 1 on a QuadPlane (failsafe.py): its failsafe's RTL
    switches to QRTL at its rally point and lands there."""
    last = Track.from_status(status(4, 0.0, 0.0, 100.0, vn=20.0), max_speed_m_s=35.0)
    vtol = SilentAircraft(
        last, VehicleType.VTOL, HOME, speed_m_s=20.0, rally=(*geo(0.0, -200.0, 0.0)[:2], HOME)
    )
    assert vtol.predict(T + 3600.0).phase == "landed"
    assert enu(vtol.predict(T + 3600.0).track)[:2] == pytest.approx((0.0, -200.0), abs=1.0)


def test_its_rtl_ends_at_its_own_landing_point_on_every_node_and_the_ground_station() -> None:
    """rally_point: where its node put its autopilot's rally point (landing_point.py):
    its pad when based near the base, else its slot there; no base, no rally point."""
    from swarm_node.core.landing_point import assigned_slot
    from swarm_node.core.safety.silent import rally_point
    from swarm_proto import GeoPoint, VehicleInfo

    base = GeoPoint(*geo(0.0, -200.0)[:2], HOME + 30.0)
    pad = GeoPoint(*geo(300.0, 0.0)[:2], HOME)
    near = VehicleInfo(3, VehicleType.COPTER, "m", "u", home=pad, base=base)
    assert rally_point(near) == (pad.lat_deg, pad.lon_deg, base.alt_msl_m)
    far = GeoPoint(*geo(5000.0, 0.0)[:2], HOME)
    away = VehicleInfo(3, VehicleType.COPTER, "m", "u", home=far, base=base)
    assert rally_point(away) == (*assigned_slot(3, base), base.alt_msl_m)
    assert rally_point(VehicleInfo(3, VehicleType.COPTER, "m", "u", home=pad)) is None
