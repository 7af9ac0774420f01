"""PREMISSION: Dubins legs from where each vehicle is to its share's entry with airspeed
and waiting orbits so the fleet arrives together; the MISSION speed rule."""

from __future__ import annotations

import math
import random

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from swarm_node.core.autopilot.items import ItemKind
from swarm_node.core.planning import (
    InvalidParameterError,
    PlanVehicle,
    Pose,
    VehiclePose,
    path_length,
)
from swarm_node.core.planning.fleet_plan import FleetPlan, flyable, plan_fleet
from swarm_node.core.planning.premission import (
    entry_index,
    lateness_s,
    premission,
    premission_speed,
    sync_speed,
)
from swarm_proto import Geometry, Mission, MissionParams, MissionType
from tests.conftest import examples

from .conftest import ORIGIN

LA, LO = ORIGIN
AREA = Geometry.polygon(
    [(LA, LO), (LA, LO + 0.012), (LA + 0.006, LO + 0.014), (LA + 0.009, LO + 0.004)]
)


@pytest.fixture(scope="module")
def vtols(profiles: dict) -> tuple[list[PlanVehicle], FleetPlan]:
    from .conftest import make_fleet

    homes: list[VehiclePose | None] = [
        VehiclePose(LA - 0.002, LO - 0.002 + 0.0005 * i) for i in range(4)
    ]
    vs = make_fleet(profiles, ["fixed_wing"] * 4, homes)
    params = MissionParams(altitude_rel_m=100.0, altitude_step_m=5.0, side_overlap=0.2)
    mission = Mission(3, 900, MissionType.AREA, AREA, params)
    return vs, plan_fleet(mission, vs, zones=[], now_unix_s=0.0, home_alt_msl_m=0.0)


def _posed(vs: list[PlanVehicle], rnd: random.Random) -> list[PlanVehicle]:
    return [
        PlanVehicle(
            v.profile,
            VehiclePose(
                LA - 0.004 + 0.003 * rnd.random(),
                LO - 0.003 + 0.005 * rnd.random(),
                80.0,
                360.0 * rnd.random(),
            ),
        )
        for v in vs
    ]


@settings(
    max_examples=examples(12),
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture],
)
@given(st.integers(0, 10_000))
def test_the_fleet_arrives_at_its_entries_together_within_its_speed_ranges(
    vtols: tuple[list[PlanVehicle], FleetPlan], seed: int
) -> None:
    vs, plan = vtols
    posed = _posed(vs, random.Random(seed))
    pm = premission(plan, posed)
    assert pm.spread_s <= 2.0
    assert set(pm.legs) == {v.vehicle_id for v in vs}
    for v in posed:
        leg = pm.legs[v.vehicle_id]
        fv = PlanVehicle(flyable(v.profile), v.pose)
        r = flyable(v.profile).turn_radius_m(leg.speed_m_s)
        lo, hi = fv.speed_range()
        assert lo - 1e-6 <= leg.speed_m_s <= hi + 1e-6
        # at that speed the turn radius the path was planned with is flyable
        assert leg.speed_m_s <= fv.max_speed_on_radius(max(r, leg.orbit_m / (2 * math.pi))) + 1e-6
        assert leg.arrival_s == pytest.approx(pm.arrival_s, abs=1e-6)
        # the approach is the shortest Dubins path from the pose to the entry (no zones)
        assert v.pose is not None
        start = pm.frame.pose(v.pose)
        planned_r = flyable(v.profile).turn_radius_m(
            next(w.speed_m_s for w in plan.share(v.vehicle_id).waypoints if w.speed_m_s)
        )
        assert leg.path_m == pytest.approx(
            path_length(Pose(*start), leg.entry, planned_r), rel=1e-6
        )
        # what is uploaded: arrival speed first, ends with the mission speed, then the
        # share from just after its entry
        wps = pm.mission_waypoints(plan.share(v.vehicle_id))
        assert wps[0].kind == ItemKind.CHANGE_SPEED and wps[0].speed_m_s == leg.speed_m_s
        assert leg.waypoints[-1].kind == ItemKind.CHANGE_SPEED
        k = entry_index(plan, v.vehicle_id)
        assert wps[len(leg.waypoints) :] == plan.share(v.vehicle_id).waypoints[k + 1 :]
        if leg.orbits:
            assert any(w.kind == ItemKind.LOITER_TURNS for w in leg.waypoints)


def test_an_area_share_is_entered_at_its_first_lane(
    vtols: tuple[list[PlanVehicle], FleetPlan],
) -> None:
    _vs, plan = vtols
    for vid in plan.roster:
        k = entry_index(plan, vid)
        share = plan.share(vid)
        assert share.along_m[k] > 0.0  # after the approach from home planned with the share
        assert share.waypoints[k].kind == ItemKind.WAYPOINT


def test_premission_needs_poses(vtols: tuple[list[PlanVehicle], FleetPlan]) -> None:
    vs, plan = vtols
    with pytest.raises(InvalidParameterError):
        premission(plan, [PlanVehicle(vs[0].profile, None)])
    with pytest.raises(InvalidParameterError):
        premission(plan, [])


# --------------------------------------------------------------------------- MISSION


def test_a_vehicle_behind_the_fleet_speeds_up_and_one_ahead_slows_down() -> None:
    rng = (18.0, 30.0)
    others = {2: 0.0, 3: 0.0}
    behind = sync_speed(10.0, others, 26.0, rng)
    ahead = sync_speed(-10.0, others, 26.0, rng)
    assert behind.changed and behind.speed_m_s > 26.0
    assert ahead.changed and ahead.speed_m_s < 26.0
    # the whole fleet late together: nobody changes speed
    together = sync_speed(30.0, {2: 30.0, 3: 30.0}, 26.0, rng)
    assert not together.changed and together.speed_m_s == 26.0
    # inside the dead band: nominal; far out: clamped to the range
    assert not sync_speed(0.5, others, 26.0, rng).changed
    assert sync_speed(500.0, others, 26.0, rng).speed_m_s == 30.0
    assert sync_speed(-500.0, others, 26.0, rng).speed_m_s == 18.0
    with pytest.raises(InvalidParameterError):
        sync_speed(math.nan, others, 26.0, rng)


@settings(max_examples=examples(200))
@given(
    st.floats(-300, 300),
    st.dictionaries(st.integers(2, 9), st.floats(-300, 300), max_size=5),
    st.floats(1.0, 40.0),
)
def test_the_speed_rule_is_monotone_in_lateness_and_stays_in_range(
    own: float, others: dict[int, float], nominal: float
) -> None:
    rng = (0.5 * nominal, 1.3 * nominal)
    a = sync_speed(own, others, nominal, rng)
    b = sync_speed(own + 5.0, others, nominal, rng)
    assert rng[0] <= a.speed_m_s <= rng[1]
    if a.changed and b.changed:
        assert b.speed_m_s >= a.speed_m_s - 1e-9


def test_lateness_against_the_planned_schedule(
    vtols: tuple[list[PlanVehicle], FleetPlan],
) -> None:
    _vs, plan = vtols
    share = plan.share(plan.roster[0])
    half = share.length_m / 2
    assert lateness_s(share, half, share.time_s / 2) == pytest.approx(0.0)
    assert lateness_s(share, half, share.time_s / 2 + 7.0) == pytest.approx(7.0)
    assert share.planned_s_at(share.length_m * 2) == pytest.approx(share.time_s)


def test_closed_loop_premission_speed_and_what_is_left_of_a_leg(
    vtols: tuple[list[PlanVehicle], FleetPlan],
) -> None:
    assert premission_speed(600.0, 30.0, (18.0, 30.0)) == pytest.approx(20.0)
    assert premission_speed(600.0, 10.0, (18.0, 30.0)) == 30.0
    assert premission_speed(100.0, 30.0, (18.0, 30.0)) == 18.0
    assert premission_speed(100.0, 0.0, (18.0, 30.0)) == 30.0
    with pytest.raises(InvalidParameterError):
        premission_speed(math.inf, 3.0, (18.0, 30.0))
    vs, plan = vtols
    pm = premission(plan, _posed(vs, random.Random(4)))
    for leg in pm.legs.values():
        loiter = [k for k, w in enumerate(leg.waypoints) if w.kind == ItemKind.LOITER_TURNS]
        first = next(k for k, w in enumerate(leg.waypoints) if w.kind == ItemKind.WAYPOINT)
        w = leg.waypoints[first]
        left = leg.remaining_m(first, w.lat_deg, w.lon_deg)
        if loiter and loiter[0] > first:
            assert left is None  # the orbit is still to come
            continue
        assert left is not None and 0.0 <= left <= leg.path_m + 1.0
        last = max(k for k, w in enumerate(leg.waypoints) if w.kind == ItemKind.WAYPOINT)
        e = leg.waypoints[last]
        assert leg.remaining_m(last, e.lat_deg, e.lon_deg) == pytest.approx(0.0, abs=1e-6)


def test_a_fixed_wing_route_fleet_meets_at_the_routes_first_point(profiles: dict) -> None:
    """A route planned from the homes; airborne elsewhere, the fleet's PREMISSION legs
    all end at the route's first point (each at its altitude), heading along the
    route, predicted together."""
    from swarm_proto import GeometryKind, LatLon

    from .conftest import make_fleet

    homes: list[VehiclePose | None] = [VehiclePose(LA - 0.003, LO + 0.001 * i) for i in range(3)]
    vs = make_fleet(profiles, ["fixed_wing"] * 3, homes)
    route = Geometry(
        GeometryKind.POLYLINE,
        (LatLon(LA + 0.004, LO), LatLon(LA + 0.008, LO + 0.004), LatLon(LA + 0.012, LO)),
    )
    mission = Mission(4, 900, MissionType.ROUTE, route, MissionParams(altitude_step_m=10.0))
    plan = plan_fleet(mission, vs, zones=[], now_unix_s=0.0, home_alt_msl_m=0.0)
    pm = premission(plan, _posed(vs, random.Random(9)))
    first = pm.frame.to_local(LA + 0.004, LO)
    second = pm.frame.to_local(LA + 0.008, LO + 0.004)
    yaw = math.atan2(second[1] - first[1], second[0] - first[0])
    for leg in pm.legs.values():
        assert math.dist((leg.entry.x, leg.entry.y), first) < 0.5
        assert abs(math.remainder(leg.entry.yaw - yaw, 2 * math.pi)) < 1e-3
    assert pm.spread_s <= 2.0


def test_target_and_perimeter_shares_are_entered_past_their_planned_approach(
    profiles: dict,
) -> None:
    from .conftest import make_fleet

    homes: list[VehiclePose | None] = [VehiclePose(LA - 0.003, LO + 0.001 * i) for i in range(3)]
    vs = make_fleet(profiles, ["fixed_wing"] * 3, homes)
    centre = (LA + 0.006, LO + 0.003)
    target = Mission(
        5, 900, MissionType.TARGET, Geometry.point(*centre), MissionParams(radius_m=150.0)
    )
    square = Geometry.polygon(
        [(LA + 0.004, LO), (LA + 0.004, LO + 0.008), (LA + 0.012, LO + 0.008), (LA + 0.012, LO)]
    )
    patrol = Mission(6, 900, MissionType.PERIMETER, square, MissionParams(altitude_step_m=10.0))
    for mission in (target, patrol):
        plan = plan_fleet(mission, vs, zones=[], now_unix_s=0.0, home_alt_msl_m=0.0)
        pm = premission(plan, _posed(vs, random.Random(2)))
        assert pm.spread_s <= 2.0
        for vid in plan.roster:
            k = entry_index(plan, vid)
            share = plan.share(vid)
            assert share.along_m[k] > 0.0  # past the approach planned from home
            if mission is target:
                assert k == len(share.waypoints) - 2  # the slot, before the hold
                e = pm.legs[vid].entry
                c = pm.frame.to_local(*centre)
                assert math.dist((e.x, e.y), c) == pytest.approx(
                    plan.detail.slot_of(vid).radius_m,
                    rel=0.01,  # type: ignore[attr-defined]
                )
