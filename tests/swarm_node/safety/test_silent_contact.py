"""A silent member is still an aircraft for avoidance: kept as a contact at its
predicted position (along its held share, then its RTL to its rally point), its error
bound growing with time, until heard again, seen landed or forgotten. Pure, injected
time. The prediction itself: test_silent_prediction.py."""

from __future__ import annotations

import math

import pytest

from swarm_node.core.safety.avoidance import (
    Forget,
    Manoeuvre,
    ManoeuvreKind,
    Silent,
    SilentRoute,
)
from swarm_proto import GeoPoint, VehicleInfo, VehicleType
from tests.swarm_node.safety.test_avoidance import HOME, T, avoider, status
from tests.swarm_node.safety.test_silent_prediction import ALT, enu, geo


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
