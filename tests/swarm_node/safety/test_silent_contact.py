"""A silent member is still an aircraft for avoidance: kept as a contact at its
predicted position (along its held share, then its RTL to its rally point), its error
bound growing with time, until heard again, seen landed or forgotten. Pure, injected
time."""

from __future__ import annotations

import math

import pymap3d
import pytest

from swarm_node.core.failsafe import COMPANION_TIMEOUT_S
from swarm_node.core.safety.avoidance import (
    Forget,
    Manoeuvre,
    ManoeuvreKind,
    Silent,
    SilentRoute,
)
from swarm_node.core.safety.silent import SilentAircraft, failsafe_after_s
from swarm_node.core.safety.ttc import Track
from swarm_proto import GeoPoint, VehicleInfo, VehicleType
from tests.swarm_node.safety.test_avoidance import HOME, LAT0, LON0, T, avoider, status

ALT = 40.0


def geo(e: float, n: float, up: float = ALT) -> tuple[float, float, float]:
    lat, lon, _h = pymap3d.enu2geodetic(e, n, up, LAT0, LON0, HOME)
    return float(lat), float(lon), up


def enu(t: Track) -> tuple[float, float, float]:
    e, n, u = pymap3d.geodetic2enu(t.lat_deg, t.lon_deg, t.alt_msl_m, LAT0, LON0, HOME)
    return float(e), float(n), float(u)


def info(vid: int, vtype: VehicleType = VehicleType.COPTER, base: bool = True) -> VehicleInfo:
    lat, lon, _ = geo(0.0, -200.0)
    home = GeoPoint(lat, lon, HOME)  # its pad, by the base: its RTL's rally point
    return VehicleInfo(
        vid,
        vtype,
        "m",
        "u",
        cruise_speed_m_s=10.0,
        home=home,
        base=GeoPoint(lat, lon, HOME + 30.0) if base else None,
    )


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


def _own_and_silent(vtype: VehicleType = VehicleType.COPTER):  # type: ignore[no-untyped-def]
    """Own copter 1 hovering at (60, 60, 40); copter 3 flying east at (0, 0, 40)."""
    av = avoider(1, VehicleType.COPTER)
    av.handle(info(3), T)
    av.handle(status(1, 60.0, 60.0, ALT), T)
    av.handle(status(3, 0.0, 0.0, ALT, ve=10.0), T)
    assert not av.on_timer(T)
    av.handle(Silent(3), T + 2.0)
    av.handle(SilentRoute(3, (geo(50.0, 0.0), geo(50.0, 100.0)), 10.0), T + 2.0)
    return av


def test_a_silent_member_on_its_lanes_is_given_way_to() -> None:
    av = _own_and_silent()
    assert av.silent == (3,)
    out: list[object] = []
    for k in range(1, 60):  # 12 s at 5 Hz, nothing heard of 3 since T
        now = T + 2.0 + 0.2 * k
        av.handle(status(1, 60.0, 60.0, ALT, t=now), now)
        out += av.on_timer(now)
    m = [o for o in out if isinstance(o, Manoeuvre)]
    assert m and m[0].kind is ManoeuvreKind.CLIMB and m[0].against == (3,)
    # without the route, straight on east it passes 60 m south: nothing to do
    av2 = avoider(1, VehicleType.COPTER)
    av2.handle(info(3), T)
    av2.handle(status(1, 60.0, 60.0, ALT), T)
    av2.handle(status(3, 0.0, 0.0, ALT, ve=10.0), T)
    av2.on_timer(T)
    av2.handle(Forget(3), T + 2.0)  # the old rule: forgotten when lost
    for k in range(1, 60):
        now = T + 2.0 + 0.2 * k
        av2.handle(status(1, 60.0, 60.0, ALT, t=now), now)
        assert not [o for o in av2.on_timer(now) if isinstance(o, Manoeuvre)]


def test_kept_well_past_the_old_ten_seconds_until_heard_again() -> None:
    av = _own_and_silent()
    now = T + 120.0
    av.handle(status(1, 60.0, 60.0, ALT, t=now), now)
    av.on_timer(now)
    assert av.silent == (3,)
    p = av.predicted(3, now)
    assert p is not None and enu(p)[1] < -150.0  # on its way home or there
    av.handle(status(3, 10.0, -190.0, 20.0, t=now + 0.2), now + 0.2)  # heard again
    av.handle(status(1, 60.0, 60.0, ALT, t=now + 0.2), now + 0.2)
    av.on_timer(now + 0.2)
    assert av.silent == () and av.predicted(3, now + 0.2) is None


def test_seen_landed_or_forgotten_it_is_dropped() -> None:
    av = _own_and_silent()
    now = T + 30.0
    av.handle(status(3, 0.0, -200.0, 0.0, t=now, armed=False), now)  # parked: seen landed
    av.handle(status(1, 60.0, 60.0, ALT, t=now), now)
    av.on_timer(now)
    assert av.silent == ()
    av = _own_and_silent()
    av.handle(Forget(3), T + 30.0)  # dismissed
    assert av.silent == ()


def test_a_member_lost_on_the_ground_or_never_heard_is_not_predicted() -> None:
    av = avoider(1, VehicleType.COPTER)
    av.handle(status(1, 60.0, 60.0, ALT), T)
    av.handle(status(3, 0.0, 0.0, 0.5), T)  # armed on its pad
    av.on_timer(T)
    av.handle(Silent(3), T + 2.0)
    av.handle(Silent(9), T + 2.0)
    assert av.silent == ()


def test_a_bad_route_is_counted_not_taken() -> None:
    av = _own_and_silent()
    before = av.predicted(3, T + 5.0)
    av.handle(SilentRoute(3, ((math.nan, 0.0, 40.0),), 10.0), T + 2.0)
    assert av.counters.get("bad_track") == 1
    assert av.predicted(3, T + 5.0) == before


def test_its_way_home_ends_on_its_own_pad_not_at_the_base() -> None:
    """Its autopilot's rally point is its own landing point (landing_point.py): the pad
    it took off from, 300 m from the base here, not the base."""
    av = avoider(1, VehicleType.COPTER)
    pad_lat, pad_lon, _ = geo(300.0, 0.0)
    base_lat, base_lon, _ = geo(0.0, -200.0)
    av.handle(
        VehicleInfo(
            3,
            VehicleType.COPTER,
            "m",
            "u",
            cruise_speed_m_s=10.0,
            home=GeoPoint(pad_lat, pad_lon, HOME),
            base=GeoPoint(base_lat, base_lon, HOME + 30.0),
        ),
        T,
    )
    av.handle(status(1, 60.0, 60.0, ALT), T)
    av.handle(status(3, 0.0, 0.0, ALT, ve=10.0), T)
    av.on_timer(T)
    av.handle(Silent(3), T + 2.0)
    p = av.predicted(3, T + 600.0)
    assert p is not None
    assert enu(p)[:2] == pytest.approx((300.0, 0.0), abs=2.0)
