"""What is left of a silent member's share, for avoidance to predict it along
(mission/share.py `route_ahead`, sent as SilentShare when its share is held)."""

from __future__ import annotations

import msgspec

from swarm_node.core.autopilot.items import ItemKind
from swarm_node.core.mission.share import route_ahead
from swarm_node.database import seed_profiles
from swarm_proto import MissionType
from tests.swarm_node.planning.conftest import _ROLES, make_fleet
from tests.swarm_node.planning.test_fleet_plan import SMALL, _homes, _mission, _plan


def test_the_rest_of_a_share_from_where_its_progress_puts_it() -> None:
    seed = seed_profiles()
    model, base = _ROLES["multirotor"]
    roles = {"multirotor": msgspec.structs.replace(seed[model], vehicle_id=base)}
    vs = make_fleet(roles, ["multirotor"] * 4, _homes(4))
    plan = _plan(_mission(MissionType.AREA, SMALL, altitude_rel_m=60.0), vs)
    vid = vs[0].vehicle_id
    share = plan.share(vid)
    ahead = [w for w in share.waypoints if w.kind == ItemKind.WAYPOINT]
    half = share.length_m / 2
    points, speed = route_ahead(plan, vid, {vid: half})
    k, lat, lon = share.at(half)
    assert points[0][:2] == (lat, lon)  # from where its progress puts it
    assert [p[:2] for p in points[1:]] == [
        (w.lat_deg, w.lon_deg) for w in share.waypoints[k + 1 :] if w.kind == ItemKind.WAYPOINT
    ]
    assert all(p[2] == ahead[-1].alt_rel_m for p in points[1:])
    assert speed >= 0.0
    assert route_ahead(plan, 999, {}) == ((), 0.0)  # no share
    assert route_ahead(plan, vid, {vid: share.length_m}) == ((), 0.0)  # flown
