"""Simultaneous arrival and route missions."""

from __future__ import annotations

import math
from collections.abc import Callable

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from swarm_node.core.autopilot.items import ItemKind
from swarm_node.core.planning import (
    InfeasibleTimingError,
    Leg,
    PlanVehicle,
    TargetInZoneError,
    VehiclePose,
    ZoneSet,
    plan_route,
    synchronize,
)
from swarm_node.core.planning.checks import arrival_spread_s, waypoint_zone_problems
from swarm_node.core.profile import VehicleProfile
from swarm_proto import Geometry, MissionParams, NoFlyZone

from .conftest import ORIGIN

Fleet = Callable[..., list[PlanVehicle]]


@st.composite
def legs(draw: st.DrawFn, profiles: dict[str, VehicleProfile]) -> list[Leg]:
    n = draw(st.integers(1, 6))
    out = []
    for i in range(n):
        role = draw(st.sampled_from(["fixed_wing", "multirotor"]))
        p = profiles[role]
        path = draw(st.floats(0.0, 8000.0))
        if p.is_fixed_wing:
            r = max(p.turn_radius_m(), p.loiter_radius_m)
            lo, hi = p.min_speed_m_s * 1.1, p.max_speed_m_s
            out.append(Leg(i, path, 2 * math.pi * r, lo, hi, p.cruise_speed_m_s))
        else:
            out.append(Leg(i, path, 0.0, 0.0, p.max_speed_m_s, p.cruise_speed_m_s))
    return out


def test_simultaneous_arrivals_within_one_second(profiles: dict[str, VehicleProfile]) -> None:
    @settings(max_examples=200)
    @given(legs(profiles))
    def check(ls: list[Leg]) -> None:
        arr = synchronize(ls)
        assert arrival_spread_s(ls, arr) <= 1.0
        for leg in ls:
            a = arr[leg.vehicle_id]
            assert leg.min_speed_m_s - 1e-9 <= a.speed_m_s <= leg.max_speed_m_s + 1e-9
            assert a.orbits == int(a.orbits) and a.orbits >= 0
            assert a.hold_s == 0.0 or leg.orbit_m == 0.0  # only hover-capable vehicles wait

    check()


def test_no_radius_inflation_orbits_are_whole() -> None:
    # two fixed-wing, one far: the near one orbits, both at speeds within range
    c = 2 * math.pi * 80.0
    arr = synchronize([Leg(1, 500.0, c, 17.0, 30.0, 26.0), Leg(2, 3000.0, c, 17.0, 30.0, 26.0)])
    assert arr[1].orbits >= 1 and arr[2].orbits == 0
    assert arr[1].arrival_s == pytest.approx(arr[2].arrival_s)


def test_infeasible_when_a_slow_vehicle_cannot_wait() -> None:
    # a fixed-wing with a zero-length orbit model and no speed margin cannot lose time
    with pytest.raises(InfeasibleTimingError):
        synchronize(
            [Leg(1, 1000.0, 1e-6, 30.0, 30.0, 30.0), Leg(2, 1001.0, 1e-6, 10.0, 10.0, 10.0)]
        )


def _poses(n: int) -> list[VehiclePose | None]:
    return [
        VehiclePose(ORIGIN[0] - 0.01 - 0.004 * i, ORIGIN[1] - 0.01 + 0.006 * i, 50.0, 45.0 * i)
        for i in range(n)
    ]


def test_route_plan_arrives_together_and_avoids_zones(fleet: Fleet) -> None:
    vs = fleet(["fixed_wing", "fixed_wing", "multirotor"], _poses(3))
    route = Geometry(
        kind=Geometry.point(0, 0).kind.__class__.POLYLINE,
        points=tuple(
            Geometry.point(ORIGIN[0] + 0.002 * k, ORIGIN[1] + 0.01 * k).points[0] for k in range(3)
        ),
    )
    mid = route.points[1]
    zone = NoFlyZone(
        9,
        Geometry.circle(mid.lat_deg - 0.0007, mid.lon_deg - 0.004, 120.0),
        ceiling_alt_msl_m=10_000.0,
    )
    plan = plan_route(
        route, vs, MissionParams(altitude_rel_m=100, altitude_step_m=10), zones=[zone]
    )
    assert len({round(a.arrival_s, 6) for a in plan.arrivals}) == 1
    zs = ZoneSet.from_messages([zone], plan.frame, now_unix_s=0.0)
    for v, vp in zip(vs, plan.vehicles, strict=True):
        assert v.pose is not None
        start = (*plan.frame.to_local(v.pose.lat_deg, v.pose.lon_deg), 100.0)
        assert waypoint_zone_problems(vp.waypoints, zs, plan.frame, start=start) == []
        assert vp.waypoints[0].kind == ItemKind.CHANGE_SPEED


def test_route_point_inside_a_zone_raises(fleet: Fleet) -> None:
    vs = fleet(["multirotor"], _poses(1))
    route = Geometry.point(*ORIGIN)
    zone = NoFlyZone(1, Geometry.circle(*ORIGIN, 200.0))
    with pytest.raises(TargetInZoneError):
        plan_route(route, vs, zones=[zone])
