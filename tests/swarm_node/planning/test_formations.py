"""Target, perimeter, objective, autoland and MUM-T planners."""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from shapely.geometry import LinearRing, Point, Polygon

from swarm_node.core.autopilot.items import ItemKind, Waypoint
from swarm_node.core.planning import (
    InvalidGeometryError,
    LeadState,
    NoVehiclesError,
    PlanVehicle,
    TargetInZoneError,
    VehiclePose,
    cyclic_slots,
    plan_autoland,
    plan_mumt,
    plan_objective,
    plan_perimeter,
    plan_target,
    respace_orbit,
    respace_perimeter,
    smooth_loop,
)
from swarm_node.core.planning.checks import arrival_spread_s
from swarm_node.core.planning.context import PlanContext
from swarm_node.core.profile import G_M_S2, VehicleProfile
from swarm_proto import Geometry, GeometryKind, LatLon, MissionParams, NoFlyZone
from tests.conftest import examples

from .conftest import ORIGIN, make_fleet

Fleet = Callable[..., list[PlanVehicle]]


def _around(n: int, dist_deg: float = 0.01) -> list[VehiclePose | None]:
    return [
        VehiclePose(
            ORIGIN[0] + dist_deg * math.sin(2 * math.pi * i / n + 0.3),
            ORIGIN[1] + dist_deg * math.cos(2 * math.pi * i / n + 0.3),
            0.0,
            10.0 * i,
        )
        for i in range(n)
    ]


def _gaps(angles: list[float]) -> list[float]:
    a = sorted(x % (2 * math.pi) for x in angles)
    if len(a) == 1:
        return [2 * math.pi]
    return [(b - c) % (2 * math.pi) for b, c in zip(a[1:] + a[:1], a, strict=True)]


# --------------------------------------------------------------------------- target


def test_hover_formation_equal_angles_radius_and_altitude_steps(fleet: Fleet) -> None:
    vs = fleet(["multirotor"] * 4, _around(4))
    params = MissionParams(altitude_rel_m=60, altitude_step_m=5, radius_m=40)
    plan = plan_target(PlanContext(Geometry.point(*ORIGIN), vs, params))
    assert all(s.radius_m == 40 and not s.orbit for s in plan.slots)
    assert _gaps([s.phase_rad for s in plan.slots]) == pytest.approx([math.pi / 2] * 4)
    assert sorted(s.alt_rel_m for s in plan.slots) == [60, 65, 70, 75]
    for s in plan.slots:
        assert math.hypot(s.x - plan.centre[0], s.y - plan.centre[1]) == pytest.approx(40)
    assert all(vp.waypoints[-1].kind == ItemKind.LOITER_UNLIMITED for vp in plan.vehicles)


def test_fixed_wing_orbit_radius_and_phase_spacing(fleet: Fleet) -> None:
    vs = fleet(["fixed_wing"] * 3, _around(3))
    params = MissionParams(altitude_rel_m=120, altitude_step_m=10, radius_m=20.0)
    plan = plan_target(PlanContext(Geometry.point(*ORIGIN), vs, params))
    p = vs[0].profile
    v = p.cruise_speed_m_s
    assert plan.orbit_radius_m >= v * v / (G_M_S2 * math.tan(math.radians(p.max_bank_deg))) - 1e-9
    assert plan.orbit_radius_m >= p.loiter_radius_m
    assert _gaps([s.phase_rad for s in plan.slots]) == pytest.approx([2 * math.pi / 3] * 3)
    # they reach their phase points at the same moment
    assert len({round(a.arrival_s, 6) for a in plan.arrivals}) == 1
    hold = plan.vehicles[0].waypoints[-1]
    assert hold.kind == ItemKind.LOITER_UNLIMITED and abs(
        hold.loiter_radius_m or 0
    ) == pytest.approx(plan.orbit_radius_m)


def test_arrival_order_follows_initial_bearings(fleet: Fleet) -> None:
    poses = _around(5, 0.02)
    vs = fleet(["multirotor"] * 5, poses)
    plan = plan_target(PlanContext(Geometry.point(*ORIGIN), vs, MissionParams(radius_m=60)))
    bearing = {}
    for v in vs:
        assert v.pose is not None
        x, y = plan.frame.to_local(v.pose.lat_deg, v.pose.lon_deg)
        bearing[v.vehicle_id] = math.atan2(y - plan.centre[1], x - plan.centre[0]) % (2 * math.pi)
    by_bearing = sorted(bearing, key=bearing.__getitem__)
    by_slot = sorted(bearing, key=lambda i: plan.slot_of(i).phase_rad % (2 * math.pi))
    k = by_slot.index(by_bearing[0])
    assert by_slot[k:] + by_slot[:k] == by_bearing  # same cyclic order: no crossing paths
    for i in bearing:  # each goes to the slot nearest its own bearing
        assert (
            abs(math.remainder(plan.slot_of(i).phase_rad - bearing[i], 2 * math.pi))
            <= math.pi / 5 + 1e-9
        )


def test_target_inside_a_zone_raises(fleet: Fleet) -> None:
    zone = NoFlyZone(4, Geometry.circle(*ORIGIN, 300.0))
    with pytest.raises(TargetInZoneError):
        plan_target(PlanContext(Geometry.point(*ORIGIN), fleet(["multirotor"]), zones=[zone]))


def _bank_radius(v: PlanVehicle, speed: float) -> float:
    """v^2 / (g tan(max bank)): the tightest turn a fixed-wing can fly at `speed`."""
    p = v.profile
    return speed * speed / (G_M_S2 * math.tan(math.radians(p.max_bank_deg)))


@pytest.mark.hypothesis  # a property inside: `make fuzz` explores it too
def test_respace_orbit_gives_equal_phases_and_speeds_the_orbit_allows(
    profiles: dict[str, VehicleProfile],
) -> None:
    albatross = profiles["fixed_wing"]
    r_min = albatross.turn_radius_m()  # the orbit at cruise speed

    @settings(max_examples=examples(60), deadline=None)
    @given(
        st.lists(st.floats(0, 2 * math.pi, exclude_max=True), min_size=1, max_size=8),
        st.floats(r_min, 3 * r_min),
    )
    def check(phase_list: list[float], radius: float) -> None:
        vs = make_fleet(profiles, ["fixed_wing"] * len(phase_list))
        phases = {v.vehicle_id: p for v, p in zip(vs, phase_list, strict=True)}
        speed = albatross.cruise_speed_m_s
        trims = respace_orbit(phases, radius, speed, vs)
        assert _gaps([t.target for t in trims.values()]) == pytest.approx(
            [2 * math.pi / len(phases)] * len(phases)
        )
        assert len({round(t.settle_s, 9) for t in trims.values()}) == 1
        for v in vs:
            t = trims[v.vehicle_id]
            lo, hi = v.speed_range()
            assert lo - 1e-9 <= t.speed_m_s <= hi + 1e-9
            # never faster than the orbit's radius allows at the max bank
            assert _bank_radius(v, t.speed_m_s) <= radius * (1 + 1e-9)
            # the trim closes the phase gap in the settle time
            assert (t.speed_m_s - speed) * t.settle_s == pytest.approx(t.move * radius, abs=1e-6)

    check()


def test_respace_on_the_tightest_orbit_only_slows_down(
    profiles: dict[str, VehicleProfile],
) -> None:
    # at cruise on the cruise-speed orbit a fixed-wing cannot speed up: the others wait
    vs = make_fleet(profiles, ["fixed_wing"] * 3)
    p = vs[0].profile
    r = p.turn_radius_m(p.cruise_speed_m_s)
    trims = respace_orbit({v.vehicle_id: 0.3 * i for i, v in enumerate(vs)}, r, 26.0, vs)
    assert max(t.speed_m_s for t in trims.values()) <= p.cruise_speed_m_s + 1e-9
    assert min(t.speed_m_s for t in trims.values()) < p.cruise_speed_m_s


def test_cyclic_slots_keep_order() -> None:
    slots = cyclic_slots({1: 0.1, 2: 0.2, 3: 3.0}, 2 * math.pi)
    order = sorted(slots, key=slots.__getitem__)
    k = order.index(1)
    assert (order[k:] + order[:k]) == [1, 2, 3]


# --------------------------------------------------------------------------- perimeter


def _square(side_deg: float = 0.008) -> Geometry:
    la, lo = ORIGIN
    return Geometry.polygon(
        [(la, lo), (la, lo + side_deg), (la + side_deg, lo + side_deg), (la + side_deg, lo)]
    )


def _min_turn_radius(ring: list[tuple[float, float]]) -> float:
    pts = np.array(ring + ring[:2])
    best = math.inf
    for a, b, c in zip(pts[:-2], pts[1:-1], pts[2:], strict=True):
        ab, bc, ca = np.linalg.norm(b - a), np.linalg.norm(c - b), np.linalg.norm(a - c)
        cross = abs((b - a)[0] * (c - a)[1] - (b - a)[1] * (c - a)[0])
        if cross > 1e-9 and min(ab, bc) > 1e-6:
            best = min(best, ab * bc * ca / (2 * cross))
    return best


def test_perimeter_fixed_wing_smoothed_and_evenly_spaced(fleet: Fleet) -> None:
    vs = fleet(["fixed_wing"] * 3, _around(3))
    plan = plan_perimeter(PlanContext(_square(), vs, MissionParams(altitude_step_m=10)))
    r = max(v.profile.turn_radius_m(plan.speed_m_s) for v in vs)
    assert _min_turn_radius(list(plan.loop)) >= 0.98 * r
    offs = sorted(o for _v, o in plan.offsets_m)
    gaps = [(b - a) % plan.length_m for a, b in zip(offs, offs[1:] + offs[:1], strict=True)]
    assert gaps == pytest.approx([plan.length_m / 3] * 3)
    lo = max(v.speed_range()[0] for v in vs)
    hi = min(v.speed_range()[1] for v in vs)
    assert lo <= plan.speed_m_s <= hi
    for vp in plan.vehicles:  # closed loop: back where the timed entry brought it
        lap = _lap(vp.waypoints)
        assert lap[-1] == pytest.approx(_entry(vp.waypoints))


def _lap(waypoints: tuple[Waypoint, ...]) -> list[tuple[float, float]]:
    """The patrol laps: the positioned items after the last CHANGE_SPEED."""
    k = max(i for i, w in enumerate(waypoints) if w.kind == ItemKind.CHANGE_SPEED)
    return [(w.lat_deg, w.lon_deg) for w in waypoints[k + 1 :]]


def _entry(waypoints: tuple[Waypoint, ...]) -> tuple[float, float]:
    """Where the timed entry ends: the last item before the laps' CHANGE_SPEED."""
    k = max(i for i, w in enumerate(waypoints) if w.kind == ItemKind.CHANGE_SPEED)
    return waypoints[k - 1].lat_deg, waypoints[k - 1].lon_deg


@pytest.mark.hypothesis  # a property inside: `make fuzz` explores it too
@pytest.mark.parametrize("role", ["fixed_wing", "multirotor"])
def test_perimeter_entry_is_timed(profiles: dict[str, VehicleProfile], role: str) -> None:
    @settings(
        max_examples=examples(15), deadline=None, suppress_health_check=[HealthCheck.too_slow]
    )
    @given(
        st.lists(
            st.tuples(
                st.floats(-0.02, 0.02), st.floats(-0.02, 0.02), st.floats(0, 360, exclude_max=True)
            ),
            min_size=1,
            max_size=4,
        ),
    )
    def check(where: list[tuple[float, float, float]]) -> None:
        poses: list[VehiclePose | None] = [
            VehiclePose(ORIGIN[0] + a, ORIGIN[1] + b, 50.0, h) for a, b, h in where
        ]
        vs = make_fleet(profiles, [role] * len(where), poses)
        plan = plan_perimeter(PlanContext(_square(), vs, MissionParams(altitude_step_m=10)))
        # every vehicle is at its phase point at the same moment (within 1 s)...
        arrivals = {a.vehicle_id: a for a in plan.arrivals}
        assert len(plan.legs) == len(vs)
        assert arrival_spread_s(plan.legs, arrivals) <= 1.0
        for a in arrivals.values():
            assert a.arrival_s == pytest.approx(plan.arrival_s)
        # ... and that point is its offset along the loop, L / N from the next one
        ring = LinearRing(plan.loop)
        for vp in plan.vehicles:
            x, y = plan.frame.to_local(*_entry(vp.waypoints))
            assert (
                ring.project(Point(x, y)) == pytest.approx(plan.offset_of(vp.vehicle_id), abs=1.0)
                or abs(ring.project(Point(x, y)) - plan.offset_of(vp.vehicle_id)) > ring.length - 1
            )
            assert ring.distance(Point(x, y)) < 0.5
            assert vp.time_s == pytest.approx(plan.arrival_s + plan.lap_s * 1)

    check()


@pytest.mark.parametrize("role", ["multirotor", "fixed_wing"])
def test_perimeter_insertion_and_removal(fleet: Fleet, role: str) -> None:
    vs = fleet([role] * 4, _around(4))
    plan = plan_perimeter(PlanContext(_square(), vs[:3]))
    pos = {v: o for v, o in plan.offsets_m}
    pos.pop(vs[1].vehicle_id)  # one leaves
    pos[vs[3].vehicle_id] = pos[vs[0].vehicle_id] + 30.0  # one joins just ahead of another
    trims = respace_perimeter(plan, pos, [vs[0], vs[2], vs[3]])
    tg = sorted(t.target for t in trims.values())
    gaps = [(b - a) % plan.length_m for a, b in zip(tg, tg[1:] + tg[:1], strict=True)]
    assert gaps == pytest.approx([plan.length_m / 3] * 3)
    for v in (vs[0], vs[2], vs[3]):
        lo, hi = v.speed_range()
        t = trims[v.vehicle_id]
        assert lo - 1e-9 <= t.speed_m_s <= hi + 1e-9
        if v.profile.is_fixed_wing:  # the loop's tightest turn still holds at the trim
            assert _bank_radius(v, t.speed_m_s) <= plan.turn_radius_m * (1 + 1e-9)


def test_perimeter_circle_and_too_narrow(fleet: Fleet) -> None:
    vs = fleet(["fixed_wing"] * 2, _around(2))
    circle = Geometry.circle(*ORIGIN, 300.0)
    plan = plan_perimeter(PlanContext(circle, vs))
    assert plan.length_m == pytest.approx(2 * math.pi * 300.0, rel=0.01)
    with pytest.raises(InvalidGeometryError):
        plan_perimeter(PlanContext(Geometry.circle(*ORIGIN, 30.0), vs))
    with pytest.raises(InvalidGeometryError):
        smooth_loop(Polygon([(0, 0), (1000, 0), (1000, 50), (0, 50)]), 60.0)


# --------------------------------------------------------------------------- objective


def test_objective_distributes_evenly(fleet: Fleet) -> None:
    vs = fleet(["multirotor"] * 5, _around(5))
    la, lo = ORIGIN
    pts = Geometry(GeometryKind.POINTS, (LatLon(la + 0.01, lo), LatLon(la - 0.01, lo)))
    plan = plan_objective(PlanContext(pts, vs, MissionParams(radius_m=30)))
    sizes = sorted(len(g) for _p, g in plan.groups)
    assert sizes == [2, 3]
    assert sorted(v for _p, g in plan.groups for v in g) == sorted(v.vehicle_id for v in vs)
    three = Geometry(GeometryKind.POINTS, tuple(LatLon(la + 0.01 * k, lo) for k in range(3)))
    few = plan_objective(PlanContext(three, vs[:2]))
    assert len(few.unserved) == 1


# --------------------------------------------------------------------------- autoland


def test_autoland_separates_in_time_and_altitude(fleet: Fleet) -> None:
    vs = fleet(["fixed_wing", "fixed_wing", "multirotor"], _around(3, 0.005))
    params = MissionParams(altitude_rel_m=80, altitude_step_m=20, separation_s=90, heading_deg=270)
    plan = plan_autoland(
        PlanContext(Geometry.point(*ORIGIN), vs, params), priority={vs[2].vehicle_id: 50}
    )
    assert plan.slots[0].vehicle_id == vs[2].vehicle_id  # priority lands first
    times = [s.land_at_s for s in plan.slots]
    assert all(b - a >= 90 - 1e-9 for a, b in itertools.pairwise(times))
    alts = [s.hold_alt_rel_m for s in plan.slots]
    assert alts == [80, 100, 120]
    for vp in plan.vehicles:
        assert vp.waypoints[-1].kind == ItemKind.LAND


def test_autoland_base_in_zone_raises(fleet: Fleet) -> None:
    with pytest.raises(TargetInZoneError):
        plan_autoland(
            PlanContext(
                Geometry.point(*ORIGIN),
                fleet(["multirotor"]),
                zones=[NoFlyZone(1, Geometry.circle(*ORIGIN, 50))],
            )
        )


# --------------------------------------------------------------------------- MUM-T


def test_mumt_slots_follow_the_moving_lead(fleet: Fleet) -> None:
    vs = fleet(["fixed_wing", "fixed_wing", "multirotor"], _around(3, 0.003))
    lead = LeadState(ORIGIN[0], ORIGIN[1], 300.0, course_deg=90.0, speed_m_s=40.0, time_s=100.0)
    p1 = plan_mumt(lead, vs, now_s=100.0, lookahead_s=0.0)
    spacing = max(60.0, 2 * max(v.profile.turn_radius_m() for v in vs))
    for s in p1.slots:  # behind (west of) the lead heading east, above it
        assert s.x < p1.lead_xy[0] - spacing + 1e-6 and s.alt_rel_m > 300.0
    # the lead moves 400 m east: every slot moves with it, followers keep their slots
    lead2 = LeadState(
        ORIGIN[0],
        ORIGIN[1] + 400 / (111_320 * math.cos(math.radians(ORIGIN[0]))),
        300.0,
        90.0,
        40.0,
        110.0,
    )
    p2 = plan_mumt(
        lead2,
        vs,
        now_s=110.0,
        lookahead_s=0.0,
        frame=p1.frame,
        previous={s.vehicle_id: s.index for s in p1.slots},
    )
    for s1, s2 in zip(p1.slots, p2.slots, strict=True):
        assert s2.index == s1.index
        assert s2.x - s1.x == pytest.approx(400.0, abs=1.0)
        assert s2.y == pytest.approx(s1.y, abs=1.0)
    # prediction: a 5 s old report is extrapolated along the course
    p3 = plan_mumt(lead, vs, now_s=105.0, lookahead_s=0.0, frame=p1.frame)
    assert p3.lead_xy[0] - p1.lead_xy[0] == pytest.approx(200.0, abs=0.5)
    for v, s in zip(vs, p1.slots, strict=True):
        lo, hi = v.speed_range()
        assert lo <= s.speed_m_s <= hi


def test_zero_vehicles_raise() -> None:
    with pytest.raises(NoVehiclesError):
        plan_target(PlanContext(Geometry.point(*ORIGIN), []))
    with pytest.raises(NoVehiclesError):
        plan_mumt(LeadState(*ORIGIN, 100.0, 0.0, 30.0), [])


def test_nan_positions_raise(fleet: Fleet) -> None:
    bad = fleet(["multirotor"], [VehiclePose(math.nan, ORIGIN[1])])
    with pytest.raises(InvalidGeometryError, match="finite"):
        plan_target(PlanContext(Geometry.point(*ORIGIN), bad))
    with pytest.raises(InvalidGeometryError, match="finite"):
        plan_mumt(LeadState(*ORIGIN, 100.0, 0.0, 30.0), bad)
