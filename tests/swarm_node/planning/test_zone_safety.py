"""No planned path enters a no-fly zone: approaches, waiting orbits, target orbits,
landing legs and holding stacks, MUM-T transits, each sampled along its arcs (the
plans' `tracks`), and the tracks are what is uploaded."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from swarm_node.core.autopilot.items import ItemKind
from swarm_node.core.planning import (
    InfeasibleTimingError,
    LeadState,
    LocalFrame,
    NoSafeRouteError,
    PlanVehicle,
    TargetInZoneError,
    VehiclePose,
    ZoneSet,
    plan_autoland,
    plan_mumt,
    plan_perimeter,
    plan_route,
    plan_target,
)
from swarm_node.core.planning.checks import track_cover_problems, track_zone_problems
from swarm_node.core.planning.context import PlanContext
from swarm_node.core.profile import VehicleProfile
from swarm_proto import Geometry, GeometryKind, LatLon, MissionParams, NoFlyZone

from .conftest import ORIGIN, make_fleet

Fleet = Callable[..., list[PlanVehicle]]
FRAME = LocalFrame(*ORIGIN)
PARAMS = MissionParams(altitude_rel_m=100.0, altitude_step_m=10.0)


def _ll(x: float, y: float) -> tuple[float, float]:
    return FRAME.to_geodetic(x, y)


def _pose(x: float, y: float, heading: float, alt: float = 100.0) -> VehiclePose:
    return VehiclePose(*_ll(x, y), alt, heading)


def _zone(zid: int, x: float, y: float, r: float, ceiling: float = 10_000.0) -> NoFlyZone:
    return NoFlyZone(zid, Geometry.circle(*_ll(x, y), r), ceiling_alt_msl_m=ceiling)


def _check(plan: Any, zones: list[NoFlyZone], *, skip: tuple[str, ...] = ()) -> None:
    zs = ZoneSet.from_messages(zones, plan.frame, now_unix_s=0.0)
    tracks = [t for t in plan.tracks if t.kind not in skip]
    assert track_zone_problems(tracks, zs) == []
    for vp in plan.vehicles:
        assert track_cover_problems(vp.vehicle_id, vp.waypoints, plan.tracks, plan.frame) == []


# --------------------------------------------------------------------------- examples


def test_target_orbit_through_a_zone_between_two_slots_raises(fleet: Fleet) -> None:
    # the audit's case: two orbiters on a 200 m orbit, slots east and west, and a 60 m
    # zone on the orbit due north: neither slot is in it, the orbit is
    vs = fleet(["fixed_wing"] * 2, [_pose(-2000, 0, 90), _pose(2000, 0, 270)])
    zone = _zone(7, 0, 200, 60)
    params = MissionParams(altitude_rel_m=100, radius_m=200)
    with pytest.raises(TargetInZoneError, match=r"orbit .* zone 7.*below 1[34]\d m or beyond"):
        plan_target(PlanContext(Geometry.point(*ORIGIN), vs, params, zones=[zone]))
    # a zone that applies only above the orbiters' altitudes does not matter
    high = NoFlyZone(7, zone.geometry, floor_alt_msl_m=500.0)
    _check(plan_target(PlanContext(Geometry.point(*ORIGIN), vs, params, zones=[high])), [high])


def test_waiting_orbit_moves_along_the_approach_away_from_a_zone(fleet: Fleet) -> None:
    # the near Albatross must wait; a zone just left of its start (where the orbit used
    # to go) pushes the orbit to the right side or further along
    near, far = fleet(["fixed_wing"] * 2, [_pose(-600, 0, 90), _pose(-4000, 200, 90)])
    zone = _zone(3, -600, 120, 40)
    plan = plan_target(PlanContext(Geometry.point(*ORIGIN), [near, far], PARAMS, zones=[zone]))
    arr = {a.vehicle_id: a for a in plan.arrivals}
    assert arr[near.vehicle_id].orbits > 0
    waits = [t for t in plan.tracks if t.kind == "wait"]
    assert waits and all(t.vehicle_id == near.vehicle_id for t in waits)
    _check(plan, [zone])
    (loiter,) = [
        w
        for vp in plan.vehicles
        if vp.vehicle_id == near.vehicle_id
        for w in vp.waypoints
        if w.kind == ItemKind.LOITER_TURNS
    ]
    x, y = FRAME.to_local(loiter.lat_deg, loiter.lon_deg)
    assert y < 0 or x > -600 + 1.0  # not beside the start on the left (north)


def test_autoland_picks_a_clear_approach_course(fleet: Fleet) -> None:
    vs = fleet(["fixed_wing", "multirotor"], [_pose(-1500, -1500, 0), _pose(1500, 800, 0)])
    # a zone around the default holding fix (600 m south of the base)
    zone = _zone(5, 0, -600, 150)
    plan = plan_autoland(PlanContext(Geometry.point(*ORIGIN), vs, PARAMS, zones=[zone]))
    assert plan.approach_yaw_rad != pytest.approx(math.pi / 2)
    _check(plan, [zone])
    # the fixed-wing holds on an orbit it can fly: its turn radius, not its loiter radius
    p = vs[0].profile
    holds = [
        w
        for vp in plan.vehicles
        for w in vp.waypoints
        if w.kind == ItemKind.LOITER_TIME and w.loiter_radius_m
    ]
    for w in holds:
        assert abs(w.loiter_radius_m or 0) == pytest.approx(p.turn_radius_m(p.cruise_speed_m_s))
    with pytest.raises(TargetInZoneError, match="heading_deg"):
        plan_autoland(
            PlanContext(
                Geometry.point(*ORIGIN),
                vs,
                MissionParams(altitude_rel_m=100, heading_deg=0.0),
                zones=[zone],
            )
        )


def test_autoland_transit_goes_around_a_zone(fleet: Fleet) -> None:
    vs = fleet(["multirotor"], [_pose(0, -2500, 0, 20.0)])
    zone = _zone(6, 0, -1500, 200)  # between the vehicle and the holding fix
    plan = plan_autoland(PlanContext(Geometry.point(*ORIGIN), vs, PARAMS, zones=[zone]))
    _check(plan, [zone])
    assert len([w for w in plan.vehicles[0].waypoints if w.kind == ItemKind.WAYPOINT]) > 2


def test_mumt_follower_goes_around_a_zone_to_its_slot(fleet: Fleet) -> None:
    vs = fleet(["multirotor"], [_pose(-900, 0, 90)])
    lead = LeadState(*_ll(0, 0), 100.0, course_deg=90.0, speed_m_s=0.0)
    zone = _zone(2, -500, -30, 80)  # on the straight way to the slot behind the lead
    plan = plan_mumt(lead, vs, PARAMS, zones=[zone], frame=FRAME)
    _check(plan, [zone])
    assert len(plan.vehicles[0].waypoints) > 2


# --------------------------------------------------------------------------- property


@st.composite
def scenes(
    draw: st.DrawFn, profiles: dict[str, VehicleProfile], mixed: bool = True
) -> tuple[list[PlanVehicle], list[NoFlyZone]]:
    """1-3 vehicles of one kind (or mixed, unless a common speed is needed) within
    2.5 km of the origin, and 1-3 zones near it, some only up to the lowest level."""
    kinds = [
        st.lists(st.just("fixed_wing"), min_size=1, max_size=3),
        st.lists(st.just("multirotor"), min_size=1, max_size=3),
    ]
    if mixed:
        kinds.append(
            st.lists(st.sampled_from(["fixed_wing", "multirotor"]), min_size=2, max_size=3)
        )
    roles = draw(st.one_of(*kinds))
    poses: list[VehiclePose | None] = [
        _pose(
            draw(st.floats(-2500, 2500)),
            draw(st.floats(-2500, 2500)),
            draw(st.floats(0, 360, exclude_max=True)),
        )
        for _ in roles
    ]
    zones = [
        _zone(
            i,
            draw(st.floats(-1500, 1500)),
            draw(st.floats(-1500, 1500)),
            draw(st.floats(30, 300)),
            draw(st.sampled_from([10_000.0, 105.0])),  # some apply only to the lowest
        )
        for i in range(draw(st.integers(1, 3)))
    ]
    return make_fleet(profiles, roles, poses), zones


ALLOWED = (TargetInZoneError, NoSafeRouteError, InfeasibleTimingError)
SQUARE = Geometry.polygon([_ll(-700, -700), _ll(700, -700), _ll(700, 700), _ll(-700, 700)])


@pytest.mark.parametrize("kind", ["target", "route", "autoland", "mumt", "perimeter"])
def test_no_planned_path_enters_a_zone(profiles: dict[str, VehicleProfile], kind: str) -> None:
    line = Geometry(
        GeometryKind.POLYLINE, (LatLon(*_ll(0, 0)), LatLon(*_ll(800, 600)), LatLon(*_ll(0, 1500)))
    )
    seen: dict[str, int] = {}

    # derandomized: the same 30 scenes every run, so that "most can be planned" below is
    # a property of the planners, not of which scenes a run happened to draw
    @settings(
        max_examples=30,
        deadline=None,
        derandomize=True,
        suppress_health_check=[HealthCheck.too_slow],
    )
    @given(scenes(profiles, mixed=kind != "perimeter"))  # a patrol needs one common speed
    def check(scene: tuple[list[PlanVehicle], list[NoFlyZone]]) -> None:
        vs, zones = scene
        try:
            if kind == "target":
                plan: Any = plan_target(
                    PlanContext(Geometry.point(*ORIGIN), vs, PARAMS, zones=zones, frame=FRAME)
                )
            elif kind == "route":
                plan = plan_route(
                    PlanContext(line, vs, PARAMS, zones=zones, frame=FRAME), max_alt_rel_m=200
                )
            elif kind == "autoland":
                plan = plan_autoland(
                    PlanContext(Geometry.point(*ORIGIN), vs, PARAMS, zones=zones, frame=FRAME)
                )
            elif kind == "perimeter":
                plan = plan_perimeter(PlanContext(SQUARE, vs, PARAMS, zones=zones, frame=FRAME))
            else:
                lead = LeadState(*_ll(0, 0), 100.0, course_deg=30.0, speed_m_s=20.0)
                plan = plan_mumt(lead, vs, PARAMS, zones=zones, frame=FRAME)
        except ALLOWED as e:
            seen[type(e).__name__] = seen.get(type(e).__name__, 0) + 1
            return
        seen["planned"] = seen.get("planned", 0) + 1
        _check(plan, zones, skip=("exit",))

    check()
    assert seen.get("planned", 0) >= 10, seen  # most scenes can be planned
