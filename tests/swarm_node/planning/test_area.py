"""Area missions end to end in geodetic terms: split, zones, replan, invalid input."""

from __future__ import annotations

import math
from collections.abc import Callable

import msgspec
import pytest

from swarm_node.core.autopilot.items import ItemKind
from swarm_node.core.planning import (
    InvalidGeometryError,
    InvalidParameterError,
    NoVehiclesError,
    PlanVehicle,
    VehiclePose,
    ZoneSet,
    coverage_ratio,
    lane_spacing_m,
    plan_area,
    replan_area,
)
from swarm_node.core.planning.checks import waypoint_zone_problems
from swarm_node.core.planning.context import PlanContext
from swarm_proto import Geometry, MissionParams, NoFlyZone

from .conftest import ORIGIN

Fleet = Callable[..., list[PlanVehicle]]

LA, LO = ORIGIN
AREA = Geometry.polygon(
    [(LA, LO), (LA, LO + 0.012), (LA + 0.006, LO + 0.014), (LA + 0.009, LO + 0.004)],
    holes=[[(LA + 0.003, LO + 0.005), (LA + 0.003, LO + 0.007), (LA + 0.004, LO + 0.006)]],
)
ZONE = NoFlyZone(5, Geometry.circle(LA + 0.005, LO + 0.010, 150.0), ceiling_alt_msl_m=5000.0)
PARAMS = MissionParams(altitude_rel_m=100.0, altitude_step_m=10.0, side_overlap=0.6)


def _poses(n: int) -> list[VehiclePose | None]:
    return [VehiclePose(LA - 0.002, LO - 0.002 + 0.001 * i, 50.0, 45.0) for i in range(n)]


@pytest.fixture(scope="module")
def plan(profiles: dict) -> object:
    from .conftest import make_fleet

    vs = make_fleet(profiles, ["fixed_wing", "fixed_wing", "multirotor"], _poses(3))
    return vs, plan_area(PlanContext(AREA, vs, PARAMS, zones=[ZONE], zone_margin_m=20.0))


def test_area_plan_covers_and_never_enters_zones(plan: object) -> None:
    vs, p = plan  # type: ignore[misc]
    spacing = lane_spacing_m(100.0, min(v.profile.camera.hfov_deg for v in vs), 0.6)
    assert p.lanes.spacing_m == pytest.approx(spacing)
    lanes = [ln for a in p.split.assignments for ln in a.path.lanes]
    assert coverage_ratio(lanes, _cover(p), spacing) >= 0.99
    zs = ZoneSet.from_messages([ZONE], p.frame, now_unix_s=0.0)
    for v, vp in zip(vs, p.vehicles, strict=True):
        start = (*p.frame.to_local(v.pose.lat_deg, v.pose.lon_deg), p.altitude_of(v.vehicle_id))
        assert waypoint_zone_problems(vp.waypoints, zs, p.frame, start=start) == []
        assert vp.waypoints[0].kind == ItemKind.CHANGE_SPEED
        assert {w.alt_rel_m for w in vp.waypoints[1:]} == {p.altitude_of(v.vehicle_id)}
    assert sorted(p.altitude_of(v.vehicle_id) for v in vs) == [100.0, 110.0, 120.0]


def _cover(p: object) -> object:
    from swarm_node.core.planning import decompose

    # the area minus its hole minus the zone inflated by the margin
    return decompose(p.frame.shape(AREA), p.zones).target  # type: ignore[attr-defined]


def test_replan_after_dropout_and_join(plan: object, fleet: Fleet) -> None:
    vs, p = plan  # type: ignore[misc]
    joiner = fleet(["multirotor"], [VehiclePose(LA + 0.009, LO + 0.004, 80.0, 0.0)])[0]
    joiner = PlanVehicle(msgspec.structs.replace(joiner.profile, vehicle_id=77), joiner.pose)
    survivors = [vs[0], vs[2], joiner]
    progress = {v.vehicle_id: 40.0 for v in vs}
    r = replan_area(p, progress, survivors, PARAMS)
    assert {vp.vehicle_id for vp in r.vehicles} == {vs[0].vehicle_id, vs[2].vehicle_id, 77}
    assert r.altitude_of(77) not in {
        r.altitude_of(vs[0].vehicle_id),
        r.altitude_of(vs[2].vehicle_id),
    }
    left = sum(a.path.lane_length_m for a in r.split.assignments)
    before = sum(a.path.lane_length_m for a in p.split.assignments)
    assert 0.45 * before < left < 0.75 * before  # about 60 % left
    zs = ZoneSet.from_messages([ZONE], p.frame, now_unix_s=0.0)
    for v, vp in zip(survivors, r.vehicles, strict=True):
        start = (*p.frame.to_local(v.pose.lat_deg, v.pose.lon_deg), r.altitude_of(v.vehicle_id))
        assert waypoint_zone_problems(vp.waypoints, zs, p.frame, start=start) == []
    with pytest.raises(InvalidParameterError):
        replan_area(p, {vs[0].vehicle_id: math.nan}, survivors)


def test_invalid_area_input(fleet: Fleet) -> None:
    vs = fleet(["fixed_wing"])
    with pytest.raises(NoVehiclesError):
        plan_area(PlanContext(AREA, []))
    with pytest.raises(InvalidGeometryError):
        plan_area(PlanContext(Geometry.point(LA, LO), vs))
    with pytest.raises(ValueError, match="not simple"):  # rejected already by the message type
        Geometry.polygon([(LA, LO), (LA + 0.01, LO + 0.01), (LA + 0.01, LO), (LA, LO + 0.01)])
    no_camera = [PlanVehicle(msgspec.structs.replace(vs[0].profile, camera=None))]
    with pytest.raises(InvalidParameterError, match="camera"):
        plan_area(PlanContext(AREA, no_camera))
    with pytest.raises(InvalidParameterError, match="duplicate"):
        plan_area(PlanContext(AREA, vs + vs))
