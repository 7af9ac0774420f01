"""Avoidance along peers' published next legs (VehicleIntent): a fixed-wing turning at
a lane's end is seen as soon as its intent says so, where straight-line prediction sees
it only once it has turned; bad intents are counted and ignored; a stale one falls back
to straight on."""

from __future__ import annotations

import math

import numpy as np
import pymap3d

from swarm_node.core.safety.avoidance import (
    AvoidanceConfig,
    CollisionAvoider,
    Manoeuvre,
    ManoeuvreKind,
)
from swarm_node.core.safety.ttc import along_intent, along_route, legs_approach, straight
from swarm_proto import IntentPoint, VehicleInfo, VehicleIntent, VehicleStatus, VehicleType

LAT0, LON0, HOME = 40.4168, -3.7038, 650.0
T = 1_700_000_000.0
ALT = 60.0
SPEED, RADIUS = 20.0, 30.0
LANE_END = 200.0  # lane 1 runs north along x = 0 to here, lane 2 south along x = 60


def point(e: float, n: float, up: float = ALT) -> IntentPoint:
    lat, lon, _h = pymap3d.enu2geodetic(e, n, up, LAT0, LON0, HOME)
    return IntentPoint(float(lat), float(lon), HOME + up)


def status(vid: int, e: float, n: float, ve: float = 0.0, vn: float = 0.0, t: float = T):
    lat, lon, _h = pymap3d.enu2geodetic(e, n, ALT, LAT0, LON0, HOME)
    return VehicleStatus(
        vehicle_id=vid,
        time_unix_s=t,
        lat_deg=float(lat),
        lon_deg=float(lon),
        alt_msl_m=HOME + ALT,
        alt_rel_m=ALT,
        vel_north_m_s=vn,
        vel_east_m_s=ve,
        armed=True,
    )


def lane_end_turn(t: float) -> tuple[float, float, float, float, int]:
    """The contact's true flight: north up lane 1, a half circle of RADIUS at its end,
    south down lane 2 (position, velocity, and how many of its legs it has passed)."""
    straight_s = LANE_END / SPEED
    turn_s = math.pi * RADIUS / SPEED
    if t <= straight_s:
        return 0.0, SPEED * t, 0.0, SPEED, 0
    if t <= straight_s + turn_s:
        a = (t - straight_s) * SPEED / RADIUS  # swept angle, turning right
        e, n = RADIUS - RADIUS * math.cos(a), LANE_END + RADIUS * math.sin(a)
        return e, n, SPEED * math.sin(a), SPEED * math.cos(a), 1
    d = (t - straight_s - turn_s) * SPEED
    return 2 * RADIUS, LANE_END - d, 0.0, -SPEED, 2


LEGS = (point(0, LANE_END), point(2 * RADIUS, LANE_END), point(2 * RADIUS, -400))


def first_manoeuvre(intent: bool) -> float | None:
    """When a hovering VTOL on lane 2, 180 m south of its end, first gives way to the
    fixed-wing (it acts at once: the time the conflict is first seen)."""
    av = CollisionAvoider(AvoidanceConfig(2, VehicleType.VTOL, intent=intent))
    av.handle(VehicleInfo(1, VehicleType.PLANE, "plane", "p"), T)
    for step in range(150):
        now = T + 0.2 * step
        e, n, ve, vn, passed = lane_end_turn(now - T)
        av.handle(status(1, e, n, ve, vn, t=now), now)
        av.handle(status(2, 2 * RADIUS, LANE_END - 180.0, t=now), now)
        if step % 5 == 0 or step == 1:  # every second, and at once after the first status
            av.handle(VehicleIntent(1, now, SPEED, RADIUS, False, LEGS[passed:]), now)
        for o in av.on_timer(now):
            if isinstance(o, Manoeuvre) and o.kind is ManoeuvreKind.CLIMB:
                return now - T
    return None


def test_a_fixed_wing_turning_at_a_lane_end_is_seen_earlier_with_its_intent() -> None:
    with_intent = first_manoeuvre(True)
    without = first_manoeuvre(False)
    assert with_intent is not None and without is not None
    # its lane's end is 10 s ahead, the turn 4.7 s more: with its legs the conflict (about
    # 24 s ahead) is inside the 30 s horizon at once; straight on, it shows only in the turn
    assert with_intent <= 1.0
    assert without >= 10.0
    assert without - with_intent >= 9.0


def test_a_stale_intent_falls_back_to_straight_on() -> None:
    av = CollisionAvoider(AvoidanceConfig(2, VehicleType.VTOL, intent_stale_s=5.0))
    av.handle(VehicleInfo(1, VehicleType.PLANE, "plane", "p"), T)
    av.handle(status(1, 0, 0, vn=SPEED), T)
    av.handle(VehicleIntent(1, T, SPEED, RADIUS, False, LEGS), T)
    now = T + 6.0  # the intent was heard 6 s ago, the status is fresh
    av.handle(status(1, 0, 0, vn=SPEED, t=now), now)
    av.handle(status(2, 2 * RADIUS, LANE_END - 180.0, t=now), now)
    out = av.on_timer(now)
    assert not [o for o in out if isinstance(o, Manoeuvre)]
    assert av.counters.get("intent_stale") == 1
    assert not av.counters.get("intent_rows")


def test_bad_intents_are_counted_and_ignored() -> None:
    av = CollisionAvoider(AvoidanceConfig(2, VehicleType.VTOL))
    av.handle(VehicleIntent(9, T, SPEED, RADIUS, False, LEGS), T)  # never heard
    assert av.counters["intent_unknown"] == 1
    av.handle(status(1, 0, 0, vn=SPEED), T)
    four = (*LEGS, point(0, -400))
    av.handle(VehicleIntent(1, T, SPEED, RADIUS, False, four), T)  # too many legs
    nan = (IntentPoint(math.nan, LON0, HOME), *LEGS[1:])
    av.handle(VehicleIntent(1, T, SPEED, RADIUS, False, nan), T)
    av.handle(VehicleIntent(1, T, math.inf, RADIUS, False, LEGS), T)
    assert av.counters["intent_bad"] == 3
    av.handle(status(2, 2 * RADIUS, LANE_END - 180.0), T)
    assert not [o for o in av.on_timer(T) if isinstance(o, Manoeuvre)]  # straight on: clear
    # a good one, then one with no legs: back to straight on
    av.handle(VehicleIntent(1, T, SPEED, RADIUS, False, LEGS), T)
    av.handle(VehicleIntent(1, T, SPEED, RADIUS, False, ()), T)
    av.handle(status(1, 0, 0, vn=SPEED, t=T + 0.2), T + 0.2)
    av.handle(status(2, 2 * RADIUS, LANE_END - 180.0, t=T + 0.2), T + 0.2)
    assert not [o for o in av.on_timer(T + 0.2) if isinstance(o, Manoeuvre)]


def test_a_multirotor_intent_is_its_route_and_a_fixed_wing_loops_at_a_tight_lane_end() -> None:
    pts = np.array([[0.0, 100.0, 0.0], [20.0, 100.0, 0.0], [20.0, -100.0, 0.0]])
    start, vel = np.zeros(3), np.array([0.0, 10.0, 0.0])
    a = along_intent(start, vel, pts, 10.0, 0.0, 30.0, hold_at_end=True)
    b = along_route(start, pts, 10.0, 30.0)
    for x, y in zip(a, b, strict=True):
        assert np.allclose(x, y)
    # a fixed-wing with a 40 m turn radius cannot turn onto a lane 20 m over: it loops
    # out past it, then flies down the lane
    _times, starts, vels = along_intent(
        start, vel, pts * [1, 1, 0], 20.0, 40.0, 30.0, hold_at_end=False
    )
    assert np.allclose(np.linalg.norm(vels[:-1, :2], axis=1), 20.0)
    assert starts[:, 0].max() > 20.0 + 10.0  # overshoots lane 2 in its turn
    assert starts[-1, 1] < 0.0  # then flies down lane 2
    # a point passed (a newer intent not heard yet) is skipped, not turned back to
    c = along_intent(np.array([0.0, 110.0, 0.0]), vel, pts, 10.0, 0.0, 30.0, hold_at_end=True)
    assert np.allclose(c[2][0], np.array([20.0, -10.0, 0.0]) * 10.0 / math.hypot(20, 10))


def test_legs_approach_matches_the_straight_line_closest_approach() -> None:
    a = straight(np.zeros(3), np.array([10.0, 0.0, 0.0]))
    b = straight(np.array([400.0, 5.0, 0.0]), np.array([-10.0, 0.0, 0.0]))
    t, miss, entry = legs_approach(a, b, 20.0, 30.0)
    assert math.isclose(t, 20.0) and math.isclose(miss, 5.0)
    assert math.isclose(entry, 20.0 - math.sqrt(400 - 25) / 20.0)


def test_the_module_publishes_its_next_legs_on_change_and_every_2_s() -> None:
    """A VTOL in its mission publishes the items ahead (three at most, MSL, its turn
    radius), again only when they change or 2 s on, and none while it gives way."""
    import msgspec

    from swarm_node.core.autopilot.items import ItemKind, Waypoint
    from swarm_node.core.autopilot.state import AutopilotState
    from swarm_node.core.outputs import Publish
    from swarm_node.core.safety.module import AvoidanceModule
    from swarm_node.database import seed_profiles
    from swarm_proto import GeoPoint, geodesy

    lat, lon, home_msl = 37.41, -5.99, 10.0
    vtol = msgspec.structs.replace(seed_profiles()["Albatross 250 VTOL"], vehicle_id=2)
    items = tuple(
        Waypoint(ItemKind.WAYPOINT, *geodesy.offset(lat, lon, 0.0, 300.0 * k), 60.0)
        for k in range(1, 6)
    )
    m = AvoidanceModule(vtol, items=items)

    def state(current: int, mode: str = "AUTO") -> AutopilotState:
        return AutopilotState(
            sysid=2,
            link_ok=True,
            armed=True,
            lat_deg=lat,
            lon_deg=lon,
            alt_msl_m=home_msl + 60.0,
            alt_rel_m=60.0,
            home=GeoPoint(lat, lon, home_msl),
            mode_name=mode,
            mission_current=current,
            groundspeed_m_s=25.0,
            vel_east_m_s=25.0,
        )

    def own(now: float) -> VehicleStatus:
        return VehicleStatus(2, now, lat, lon, home_msl + 60.0, 60.0, vel_east_m_s=25.0, armed=True)

    def intents(now: float, current: int, mode: str = "AUTO") -> list[VehicleIntent]:
        out = m.tick(now, own(now), state(current, mode))
        return [o.msg for o in out if isinstance(o, Publish) and isinstance(o.msg, VehicleIntent)]

    (first,) = intents(T, 2)
    assert [(p.lat_deg, p.lon_deg) for p in first.legs] == [
        (w.lat_deg, w.lon_deg) for w in items[1:4]
    ]
    assert all(p.alt_msl_m == home_msl + 60.0 for p in first.legs)
    assert first.turn_radius_m == round(vtol.turn_radius_m(), 1) > 0 and not first.hold_at_end
    assert intents(T + 0.2, 2) == []  # unchanged: not again before 2 s
    (moved,) = intents(T + 0.4, 3)  # the next item: at once
    assert [(p.lat_deg, p.lon_deg) for p in moved.legs] == [
        (w.lat_deg, w.lon_deg) for w in items[2:5]
    ]
    assert intents(T + 0.6, 3) == []
    assert len(intents(T + 2.5, 3)) == 1  # every 2 s
    (gone,) = intents(T + 2.7, 3, "LOITER")  # off its legs: once, empty
    assert gone.legs == ()
    assert intents(T + 5.0, 3, "LOITER") == []


def test_a_contact_beyond_reach_on_any_path_costs_no_intent_prediction() -> None:
    av = CollisionAvoider(AvoidanceConfig(2, VehicleType.VTOL))
    av.handle(VehicleInfo(1, VehicleType.PLANE, "plane", "p"), T)
    av.handle(status(1, 0, 3000.0, vn=SPEED), T)  # 3 km off: 30 s at 20 m/s is 600 m
    av.handle(VehicleIntent(1, T, SPEED, RADIUS, False, LEGS), T)
    av.handle(status(2, 0, 0), T)
    av.on_timer(T)
    assert not av.counters.get("intent_rows")
    av.handle(status(1, 0, 500.0, vn=SPEED, t=T + 0.2), T + 0.2)
    av.handle(status(2, 0, 0, t=T + 0.2), T + 0.2)
    av.on_timer(T + 0.2)
    assert av.counters["intent_rows"] == 1
