"""A fixed-wing's approach to its share is flown clear of the no-fly zones with the
autopilot's real turns, not only as planned (a `make demo` run's VTOL 4 flew
into the field zone right after the vote replan, GEOFENCE_BREACH).

The breach, reconstructed from its logs (the fleet plan cc65b4c7 made again from the
declared mission and the pads; the replan from the logged progress): vehicle 4 was in
its lane-end turn at 29.6 m/s (the PREMISSION catch-up speed, never slowed: the share's
CHANGE_SPEED 26 m/s came after the approach) when its replanned share was uploaded; the
share began behind it. The approach's Dubins entry was planned at the 69 m minimum
radius of 26 m/s, and the flyable check at the 89.6 m of 26 m/s with the planners'
1.3 margin, which at 29.6 m/s is the aircraft's minimum (89.3 m): predicted 2 m clear
of the zone, the aircraft flew the entry arc wide (turning 65 m east of its planned
eastmost point) and the leg after it crossed the zone.
Now the share's speed is set before the approach, and the entry is planned at 1.3 times
the minimum radius of the faster of the speed flown now and the share's."""

from __future__ import annotations

import math

import pytest

from swarm_node.core.autopilot.items import ItemKind, Waypoint
from swarm_node.core.autopilot.requests import UploadMission
from swarm_node.core.mission_manager import MissionManager
from swarm_node.core.outputs import Submit
from swarm_node.core.planning.fleet_plan import TURN_RADIUS_MARGIN
from swarm_node.core.planning.flight import FIXED_WING_ACCEPT_M
from swarm_node.core.planning.geo import LocalFrame
from swarm_node.core.planning.transit import flown_speed_m_s, flown_turn_radius_m
from swarm_proto import Geometry, GeoPoint, NoFlyZone
from swarm_sim.core.airframes import ALBATROSS_250_VTOL
from swarm_sim.core.kinematics import Body, FixedWingModel
from swarm_sim.core.navigation import FlyTo
from tests.swarm_node.test_node_core import flying, profile

VTOL = "Albatross 250 VTOL"
ZONE_AT = (37.42066066542333, -5.986075745002986)  # the demo's field zone (story.py)
ZONE_R_M = 60.0
HOME_ALT_MSL_M = 10.0
NOW = 1795682506.0
#: vehicle 4's replanned share, metres east/north of the zone's centre: the end of its
#: lane-end turn (where its progress put it), then the next lane west (the first 15
#: waypoints of the 83; 110 m above home)
SHARE_XY = (
    (-234.9, 126.8),
    (-222.2, 171.2),
    (-189.1, 203.4),
    (-144.3, 214.8),
    (-99.8, 202.4),
    (-67.4, 169.5),
    (-55.7, 124.7),
    (-67.9, 80.1),
    (-100.7, 47.6),
    (-145.3, 35.6),
    (-675.0, 35.6),
    (-718.7, 47.0),
    (-751.3, 78.2),
    (-764.5, 121.4),
    (-755.1, 165.5),
)
#: where the vehicle was when the approach was planned (east, north, heading), and where
#: the autopilot started flying it (0.4 s later, still turning right at 19 deg/s)
PLANNED_AT = (-122.0, 223.3, 101.8)
STARTED_AT = (-110.6, 220.2, 106.0)
FLOWN_M_S = 29.6


def _frame() -> LocalFrame:
    return LocalFrame(*ZONE_AT)


def _zone() -> NoFlyZone:
    return NoFlyZone(
        1,
        Geometry.circle(*ZONE_AT, ZONE_R_M),
        floor_alt_msl_m=-100.0,
        ceiling_alt_msl_m=1000.0,
        name="field zone",
    )


def _share() -> tuple[Waypoint, ...]:
    f = _frame()
    return (
        Waypoint(ItemKind.CHANGE_SPEED, speed_m_s=26.0),
        *(Waypoint(ItemKind.WAYPOINT, *f.to_geodetic(x, y), 110.0) for x, y in SHARE_XY),
    )


def _uploaded(speed_m_s: float = FLOWN_M_S) -> tuple[Waypoint, ...]:
    """The items the mission manager uploads for the share from the breach's pose."""
    lat, lon = _frame().to_geodetic(PLANNED_AT[0], PLANNED_AT[1])
    ap = flying(
        lat_deg=lat,
        lon_deg=lon,
        heading_deg=PLANNED_AT[2],
        airspeed_m_s=speed_m_s,
        groundspeed_m_s=speed_m_s,
        home=GeoPoint(37.4112, -5.98788, HOME_ALT_MSL_M),
    )
    manager = MissionManager(profile(4, VTOL))
    t = manager.transit
    return t.tight(t.with_approach(_share(), ap, [_zone()], NOW, HOME_ALT_MSL_M))


def _fly(
    items: tuple[Waypoint, ...],
    speed_m_s: float,
    t_max_s: float = 150.0,
    start: tuple[float, float, float] = STARTED_AT,
) -> list[tuple[float, float]]:
    """The path (east, north) the simulator's fixed-wing model and AUTO waypoint task (what
    the demo's vehicles fly: an L1-style track, turns at the 45 degree bank limit, the
    yaw rate built up at 1 rad/s^2) flies through `items`' waypoints from STARTED_AT,
    turning right at its bank limit as the breach's vehicle was. The speed stays
    `speed_m_s` (the slower CHANGE_SPEED is not applied: the wider turns)."""
    f = _frame()
    pts = [f.to_local(w.lat_deg, w.lon_deg) for w in items if w.kind == ItemKind.WAYPOINT]
    x, y, hdg = start
    body = Body(n=y, e=x, alt=120.0, airspeed=speed_m_s, heading_deg=hdg, on_ground=False)
    body.vn = speed_m_s * math.cos(math.radians(hdg))
    body.ve = speed_m_s * math.sin(math.radians(hdg))
    model = FixedWingModel(ALBATROSS_250_VTOL)
    body.yaw_rate_rad_s = model.turn_rate_max_rad_s(speed_m_s)

    class Ctx:
        hover_capable, fixed_wing, wp_accel, loiter_radius = False, True, 1.0, 60.0

        def __init__(self) -> None:
            self.body, self.wp_speed = body, speed_m_s

    ctx, dt, t = Ctx(), 0.05, 0.0
    path: list[tuple[float, float]] = []
    origin: tuple[float, float] | None = None
    for e, n in pts:
        task = FlyTo(n, e, 120.0, accept_m=FIXED_WING_ACCEPT_M, stop=False, origin=origin)
        while t < t_max_s and not task.update(ctx, dt):
            model.step(body, task.target(ctx), dt)
            path.append((body.e, body.n))
            t += dt
        origin = (n, e)
    return path


def _clearance_m(path: list[tuple[float, float]]) -> float:
    return min(math.hypot(x, y) for x, y in path) - ZONE_R_M


def test_the_replanned_approach_of_the_demo_breach_is_flown_clear_of_the_field_zone() -> None:
    items = _uploaded()
    path = _fly(items, FLOWN_M_S)
    assert min(x for x, _y in path) < -600.0  # it flew the approach and down the lane west
    assert _clearance_m(path) > 20.0  # before the fix: -16 m, in the zone
    # the share's speed first: the approach is flown at the speed its turns are planned for
    assert items[0].kind == ItemKind.CHANGE_SPEED and items[0].speed_m_s == 26.0


def test_the_approach_at_cruise_speed_is_flown_clear_too() -> None:
    items = _uploaded(26.0)
    assert _clearance_m(_fly(items, 26.0)) > 20.0


def test_legs_off_the_plan_keep_the_turn_margin_at_the_speed_flown() -> None:
    p = profile(4, VTOL)
    cruise = TURN_RADIUS_MARGIN * p.turn_radius_m()
    assert flown_turn_radius_m(p) == pytest.approx(cruise)
    assert flown_turn_radius_m(p, 20.0) == pytest.approx(cruise)  # slower: still cruise's
    fast = flown_turn_radius_m(p, FLOWN_M_S)
    assert fast == pytest.approx(TURN_RADIUS_MARGIN * p.turn_radius_m(FLOWN_M_S))
    assert fast > 1.25 * p.turn_radius_m(FLOWN_M_S)  # the margin kept at 29.6 m/s
    assert flown_turn_radius_m(p, 500.0) == pytest.approx(flown_turn_radius_m(p, p.max_speed_m_s))
    for bad in (math.nan, math.inf, -3.0, 0.0):
        assert flown_turn_radius_m(p, bad) == pytest.approx(cruise)


def test_the_speed_flown_is_the_faster_of_air_and_ground_speed_and_never_nan() -> None:
    assert flown_speed_m_s(flying(airspeed_m_s=26.0, groundspeed_m_s=31.0)) == 31.0
    assert flown_speed_m_s(flying(airspeed_m_s=math.nan, groundspeed_m_s=math.nan)) == 0.0
    assert flown_speed_m_s(flying(airspeed_m_s=math.inf, groundspeed_m_s=0.0)) == 0.0


@pytest.mark.parametrize("pose", [(-43.0, 188.0, 331.0, 30.3), (69.0, 210.0, 41.0, 29.3)])
def test_the_way_home_of_a_fixed_wing_faster_than_cruise_is_flown_clear_of_the_zone(
    pose: tuple[float, float, float, float],
) -> None:
    """North of the field zone heading away from home (south of it), at a catch-up
    speed: the way home's entry turns back past the zone (before the fix: planned at
    the 69 m cruise minimum and flown 32 m and 20 m into the zone)."""
    x, y, hdg, speed = pose
    lat, lon = _frame().to_geodetic(x, y)
    ap = flying(
        lat_deg=lat,
        lon_deg=lon,
        heading_deg=hdg,
        airspeed_m_s=speed,
        groundspeed_m_s=speed,
        alt_rel_m=110.0,
        home=GeoPoint(37.4112, -5.98788, HOME_ALT_MSL_M),
    )
    outs = MissionManager(profile(4, VTOL)).start_return(ap, [_zone()], NOW)
    (up,) = [
        o.request for o in outs if isinstance(o, Submit) and isinstance(o.request, UploadMission)
    ]
    path = _fly(up.items, speed, t_max_s=80.0, start=(x, y, hdg))
    assert min(y for _x, y in path) < -300.0  # past the zone, on its way home
    assert _clearance_m(path) > 20.0
