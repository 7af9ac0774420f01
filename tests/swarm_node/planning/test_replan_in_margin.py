"""A replan from where the survivors are, when one of them is in a no-fly zone's margin.

Found flying the paper's experiment 1 (`make demo`): six VTOLs surveying a field with a
60 m zone in it, two voted out to a target; the four stayers' replan failed on every
node ("route end point is inside an inflated no-fly zone") because one of them, turning
at the end of a lane next to the zone, was inside the zone's margin (the keep-out the
planner grows by the turn radius): the transition from its position was routed with the
visibility graph, which refuses an end inside the keep-out. The survivors then flew on
with their old shares and the voted-out pair's lanes were never flown. Now a vehicle in
a margin leaves it the shortest way first (`Obstacles.path_from`)."""

from __future__ import annotations

import math
from collections.abc import Callable

from shapely.geometry import LineString, Point, Polygon

from swarm_node.core.planning import PlanVehicle, VehiclePose
from swarm_node.core.planning.area import AreaPlan
from swarm_node.core.planning.dubins import Pose
from swarm_node.core.planning.fleet_plan import plan_fleet
from swarm_node.core.planning.geo import LocalFrame
from swarm_node.core.planning.zones import Obstacles
from swarm_proto import Geometry, Mission, MissionParams, MissionType, NoFlyZone

from .conftest import ORIGIN

Fleet = Callable[..., list[PlanVehicle]]
FRAME = LocalFrame(*ORIGIN)


def _poly(*pts: tuple[float, float]) -> Geometry:
    return Geometry.polygon([FRAME.to_geodetic(e, n) for e, n in pts])


def test_the_way_out_of_a_margin_leaves_it_straight_away_from_the_zone() -> None:
    zone = Point(0.0, 0.0).buffer(60.0)
    obstacles = Obstacles(zone.buffer(90.0), zone)
    start = (0.0, 110.0)  # 50 m outside the zone, inside its 90 m margin
    path = obstacles.path_from(start, (0.0, -400.0))
    assert path[0] == start and path[-1] == (0.0, -400.0)
    assert path[1][1] > 110.0  # out first, away from the zone
    assert not LineString(path).intersects(zone)
    # an end outside the margin: the plain path
    assert obstacles.path_from((0.0, 400.0), (0.0, -400.0)) == obstacles.path(
        (0.0, 400.0), (0.0, -400.0)
    )


def test_stayers_replan_when_one_of_them_is_in_the_zone_margin(fleet: Fleet) -> None:
    area = _poly((-500, -350), (500, -350), (500, 350), (-500, 350))
    zone = NoFlyZone(
        1,
        Geometry.circle(*FRAME.to_geodetic(175.0, 50.0), 60.0),
        floor_alt_msl_m=-100.0,
        ceiling_alt_msl_m=1000.0,
    )
    homes = [VehiclePose(*FRAME.to_geodetic(30.0 * i, -1000.0)) for i in range(6)]
    vs = fleet(["fixed_wing"] * 6, homes)
    mission = Mission(
        101, 900, MissionType.AREA, area, MissionParams(altitude_rel_m=80.0, side_overlap=0.5)
    )
    fp = plan_fleet(mission, vs, zones=[zone], now_unix_s=0.0, home_alt_msl_m=0.0)
    assert isinstance(fp.detail, AreaPlan)
    progress = {v.vehicle_id: 0.3 * fp.share(v.vehicle_id).length_m for v in vs}
    # the stayers: where their shares put them, one of them 50 m from the zone (its
    # margin is the turn radius and more), heading away from the field's centre
    stayers = []
    for v in vs[:4]:
        _k, lat, lon = fp.share(v.vehicle_id).at(progress[v.vehicle_id])
        stayers.append(PlanVehicle(v.profile, VehiclePose(lat, lon, 80.0, 90.0)))
    in_margin = VehiclePose(*FRAME.to_geodetic(175.0, 50.0 - 110.0), 80.0, 90.0)
    stayers[0] = PlanVehicle(stayers[0].profile, in_margin)
    keep = fp.detail.obstacles
    x, y = fp.detail.frame.to_local(in_margin.lat_deg, in_margin.lon_deg)
    assert keep.inner.contains(Point(x, y))  # the case: inside the keep-out, outside the zone
    new = fp.replan(progress, stayers, zones=[zone], now_unix_s=0.0, home_alt_msl_m=0.0)
    assert isinstance(new.detail, AreaPlan)
    assert set(new.shares) == {v.vehicle_id for v in stayers}
    raw = fp.detail.zones.raw(80.0)
    for a in new.detail.split.assignments:
        pts = a.path.points()
        assert not LineString(pts).intersects(raw.buffer(-1e-6)), a.vehicle_id


def test_a_coverage_connection_from_inside_a_margin_is_clear_of_the_zone() -> None:
    from swarm_node.core.planning.coverage import connect, decompose, plan_lanes
    from swarm_node.core.planning.turns import DubinsTurns
    from swarm_node.core.planning.zones import Zone, ZoneSet

    square = Polygon([(-400, -400), (400, -400), (400, 400), (-400, 400)])
    zones = ZoneSet((Zone(1, Point(0.0, 0.0).buffer(60.0)),), margin_m=90.0)
    region = decompose(square, zones)
    turns = DubinsTurns(69.0)
    lanes = plan_lanes(region, 48.0, turns).lanes
    start = Pose(0.0, -110.0, math.pi / 2)  # heading at the zone, in its margin
    path = connect(lanes[:3], turns, region.obstacles, start)
    assert path.points()[0] == (0.0, -110.0)
    assert not LineString(path.points()).intersects(Point(0.0, 0.0).buffer(59.9))


def test_a_vehicle_inside_the_zone_itself_is_not_led_through_it() -> None:
    import pytest

    from swarm_node.core.planning.errors import NoSafeRouteError

    zone = Point(0.0, 0.0).buffer(60.0)
    with pytest.raises(NoSafeRouteError):
        Obstacles(zone.buffer(90.0), zone).path_from((0.0, 20.0), (0.0, -400.0))
    with pytest.raises(NoSafeRouteError):  # margins unknown: as `path`
        Obstacles(zone.buffer(90.0)).path_from((0.0, 110.0), (0.0, -400.0))


def test_a_replan_heads_each_survivor_along_its_share(fleet: Fleet) -> None:
    """The survivors of a replan are posed where their progress puts them on their
    shares (the same on every node); they were all headed north. A VTOL flying west
    past the demo's field zone was planned as if it flew north, into the zone: its new
    share turned round next to the zone (8.6 m from it) and the next replan found no
    flyable turn there. Each is now headed along the leg it is on."""
    from swarm_node.core.mission.share import Member, _vehicles, heading_on, pose_on
    from swarm_proto import GeoPoint

    area = _poly((-300, -200), (300, -200), (300, 200), (-300, 200))
    homes = [VehiclePose(*FRAME.to_geodetic(30.0 * i, -800.0)) for i in range(3)]
    vs = fleet(["fixed_wing"] * 3, homes)
    mission = Mission(101, 900, MissionType.AREA, area, MissionParams(altitude_rel_m=80.0))
    fp = plan_fleet(mission, vs, zones=[], now_unix_s=0.0, home_alt_msl_m=0.0)
    for v in vs:
        share = fp.share(v.vehicle_id)
        progress = {v.vehicle_id: 0.5 * share.length_m}
        k, lat, lon = share.at(progress[v.vehicle_id])
        ahead = next(w for w in share.waypoints[k + 1 :] if w.lat_deg)
        x, y = LocalFrame(lat, lon).to_local(ahead.lat_deg, ahead.lon_deg)
        want = math.degrees(math.atan2(x, y)) % 360.0
        got = heading_on(fp, v.vehicle_id, progress)
        assert got is not None and abs((got - want + 180.0) % 360.0 - 180.0) < 1e-6
        at = pose_on(fp, v.vehicle_id, progress)
        assert isinstance(at, GeoPoint)
        (pv,) = _vehicles([Member(v.profile, at, heading_deg=got)])
        assert pv.pose is not None and pv.pose.heading_deg == got
    assert heading_on(fp, 99, {}) is None  # no share
