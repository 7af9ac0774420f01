"""The whole fleet's plan (`plan_fleet`), progress in metres along a share, and replanning
from that progress when a member drops out or one joins."""

from __future__ import annotations

import itertools
import math
import random
from collections.abc import Callable

import msgspec
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from swarm_node.core.autopilot.items import ItemKind, Waypoint
from swarm_node.core.mission_manager import Member, plan_share
from swarm_node.core.planning import (
    InvalidParameterError,
    PlanningError,
    PlanVehicle,
    VehiclePose,
    coverage_ratio,
    decompose,
    overlap_ratio,
)
from swarm_node.core.planning.area import AreaPlan
from swarm_node.core.planning.fleet_plan import (
    FleetPlan,
    Share,
    along_metres,
    flown_lanes,
    plan_fleet,
)
from swarm_node.core.planning.geo import LocalFrame
from swarm_node.core.planning.perimeter import PerimeterPlan
from swarm_node.core.planning.target import TargetPlan
from swarm_proto import (
    Geometry,
    GeometryKind,
    GeoPoint,
    LatLon,
    Mission,
    MissionParams,
    MissionType,
)
from tests.conftest import examples

from .conftest import ORIGIN

Fleet = Callable[..., list[PlanVehicle]]
LA, LO = ORIGIN
AREA = Geometry.polygon(
    [(LA, LO), (LA, LO + 0.012), (LA + 0.006, LO + 0.014), (LA + 0.009, LO + 0.004)]
)
#: about 180 m x 220 m: what quadcopters' batteries cover (the seed quad flies ~3 minutes)
SMALL = Geometry.polygon([(LA, LO), (LA, LO + 0.002), (LA + 0.002, LO + 0.0025), (LA + 0.002, LO)])
NO_ZONES: list = []


def _mission(kind: MissionType, geometry: Geometry, **params: object) -> Mission:
    return Mission(
        mission_id=7,
        issuer_id=900,
        mission_type=kind,
        geometry=geometry,
        params=MissionParams(**params),  # type: ignore[arg-type]
    )


def _plan(mission: Mission, vs: list[PlanVehicle]) -> FleetPlan:
    return plan_fleet(mission, vs, zones=NO_ZONES, now_unix_s=0.0, home_alt_msl_m=0.0)


def _homes(n: int) -> list[VehiclePose | None]:
    return [VehiclePose(LA - 0.002, LO - 0.002 + 0.0005 * i) for i in range(n)]


def _at(share: Share, fraction: float, vehicle: PlanVehicle) -> tuple[float, PlanVehicle]:
    """Progress and the vehicle posed `fraction` along its share (heading along it)."""
    k, lat, lon = share.at(fraction * share.length_m)
    _k2, lat2, lon2 = share.at(min(fraction * share.length_m + 5.0, share.length_m))
    frame = LocalFrame(lat, lon)
    x, y = frame.to_local(lat2, lon2)
    heading = (90.0 - math.degrees(math.atan2(y, x))) % 360.0 if (x or y) else 0.0
    return share.progress_m(k, lat, lon), PlanVehicle(
        vehicle.profile, VehiclePose(lat, lon, 100.0, heading)
    )


# --------------------------------------------------------------------------- share


def _line(n: int, step_deg: float = 0.001) -> tuple[Waypoint, ...]:
    out = [Waypoint(ItemKind.CHANGE_SPEED, speed_m_s=10.0)]
    for i in range(n):
        out.append(Waypoint(ItemKind.WAYPOINT, LA, LO + step_deg * i, 50.0))
    out.append(Waypoint(ItemKind.LOITER_UNLIMITED, LA, LO + step_deg * (n - 1), 50.0))
    return tuple(out)


def _share(wps: tuple[Waypoint, ...]) -> Share:
    along = along_metres(wps)
    return Share(1, wps, along, along[-1], 0.0)


def test_along_metres_counts_only_waypoint_legs() -> None:
    wps = _line(3)
    along = along_metres(wps)
    leg = LocalFrame(LA, LO).to_local(LA, LO + 0.001)[0]
    assert len(along) == len(wps)
    assert along[0] == 0.0 and along[1] == 0.0  # CHANGE_SPEED, then the first waypoint
    assert along[2] == pytest.approx(leg, rel=1e-6)
    assert along[3] == pytest.approx(2 * leg, rel=1e-6)
    assert along[4] == along[3]  # the loiter repeats the previous value


def test_progress_is_the_last_reached_item_plus_the_projection_on_the_next_leg() -> None:
    s = _share(_line(3))
    leg = s.along_m[2]
    assert s.progress_m(-1, LA, LO) == 0.0
    assert s.progress_m(1, None, None) == 0.0
    # halfway along the first leg, 30 m off it to the north: the projection counts
    lat_off = LA + 30.0 / 111_000.0
    assert s.progress_m(1, lat_off, LO + 0.0005) == pytest.approx(leg / 2, rel=1e-3)
    # behind the leg's start, and beyond its end: clamped
    assert s.progress_m(1, LA, LO - 0.001) == 0.0
    assert s.progress_m(1, LA, LO + 0.005) == pytest.approx(leg)
    assert s.progress_m(2, LA, LO + 0.0015) == pytest.approx(1.5 * leg, rel=1e-3)
    assert s.progress_m(len(s.waypoints) - 1, LA, LO) == s.length_m
    assert s.progress_m(99, None, None) == s.length_m
    assert s.progress_m(1, math.nan, LO) == 0.0  # a bad fix counts nothing beyond the item


@settings(max_examples=examples(60), deadline=None)
@given(
    st.lists(
        st.tuples(st.floats(-0.003, 0.003), st.floats(-0.003, 0.003), st.booleans()),
        min_size=2,
        max_size=12,
    ),
    st.floats(-0.004, 0.004),
    st.floats(-0.004, 0.004),
    st.floats(0.0, 1.0),
)
def test_progress_is_monotone_bounded_and_inverts_at(
    pts: list[tuple[float, float, bool]], dlat: float, dlon: float, f: float
) -> None:
    wps: list[Waypoint] = []
    for a, b, loiter in pts:
        wps.append(Waypoint(ItemKind.WAYPOINT, LA + a, LO + b, 40.0))
        if loiter:
            wps.append(Waypoint(ItemKind.LOITER_TURNS, LA + a, LO + b, 40.0, turns=1.0))
    s = _share(tuple(wps))
    values = [s.progress_m(k, LA + dlat, LO + dlon) for k in range(-1, len(wps))]
    assert all(0.0 <= v <= s.length_m + 1e-9 for v in values)
    assert all(b >= a - 1e-6 for a, b in itertools.pairwise(values))
    k, lat, lon = s.at(f * s.length_m)
    assert s.progress_m(k, lat, lon) == pytest.approx(f * s.length_m, abs=0.05)


# --------------------------------------------------------------------------- plan_fleet


@pytest.fixture(scope="module")
def six_vtols(profiles: dict) -> tuple[list[PlanVehicle], FleetPlan]:
    from .conftest import make_fleet

    vs = make_fleet(profiles, ["fixed_wing"] * 6, _homes(6))
    mission = _mission(
        MissionType.AREA, AREA, altitude_rel_m=100.0, altitude_step_m=5.0, side_overlap=0.2
    )
    return vs, _plan(mission, vs)


def test_plan_fleet_gives_every_member_a_share_and_plan_share_is_its_wrapper(
    six_vtols: tuple[list[PlanVehicle], FleetPlan],
) -> None:
    vs, fp = six_vtols
    assert fp.roster == tuple(sorted(v.vehicle_id for v in vs))
    assert isinstance(fp.detail, AreaPlan)
    for vid in fp.roster:
        s = fp.share(vid)
        assert len(s.along_m) == len(s.waypoints)
        assert all(b >= a for a, b in itertools.pairwise(s.along_m))
        assert s.length_m == s.along_m[-1] > 0.0
        assert 0.0 < s.time_s <= fp.makespan_s + 1e-9
    members = [Member(v.profile, GeoPoint(v.pose.lat_deg, v.pose.lon_deg, 0.0)) for v in vs]
    v = vs[2].vehicle_id
    assert plan_share(fp.mission, members[::-1], v, [], 0.0, 0.0) == fp.share(v).waypoints
    with pytest.raises(PlanningError):
        fp.share(999)


def test_plan_fleet_is_the_same_whatever_the_order_of_the_vehicles(fleet: Fleet) -> None:
    vs = fleet(["multirotor", "fixed_wing", "multirotor"], _homes(3))
    mission = _mission(MissionType.AREA, SMALL, altitude_rel_m=60.0, side_overlap=0.2)
    a = _plan(mission, vs)
    b = _plan(mission, [vs[2], vs[0], vs[1]])
    assert a.roster == b.roster and a.shares == b.shares and a.makespan_s == b.makespan_s


def test_unplanned_mission_types_and_bad_input_raise(fleet: Fleet) -> None:
    vs = fleet(["fixed_wing"], _homes(1))
    with pytest.raises(PlanningError):
        _plan(_mission(MissionType.MUMT, Geometry.point(LA, LO)), vs)
    with pytest.raises(InvalidParameterError):
        _plan(_mission(MissionType.AREA, SMALL), vs + vs)
    fp = _plan(_mission(MissionType.AREA, SMALL, altitude_rel_m=80.0), vs)
    with pytest.raises(InvalidParameterError):
        fp.replan({vs[0].vehicle_id: math.inf}, vs, zones=[], now_unix_s=0.0, home_alt_msl_m=0.0)


# --------------------------------------------------------------------------- area replan


def _coverage_after_loss(
    vs: list[PlanVehicle], fp: FleetPlan, lost: int, fractions: dict[int, float]
) -> tuple[FleetPlan, float, float, float]:
    progress, posed = {}, []
    for v in vs:
        m, pv = _at(fp.share(v.vehicle_id), fractions[v.vehicle_id], v)
        progress[v.vehicle_id] = m
        if v.vehicle_id != lost:
            posed.append(pv)
    new = fp.replan(progress, posed, zones=[], now_unix_s=0.0, home_alt_msl_m=0.0)
    assert isinstance(fp.detail, AreaPlan) and isinstance(new.detail, AreaPlan)
    d = fp.detail
    target = decompose(d.frame.shape(fp.mission.geometry), d.zones).target
    spacing = d.lanes.spacing_m
    flown = flown_lanes(fp, progress)
    after = [ln for a in new.detail.split.assignments for ln in a.path.lanes]
    planned = [ln for a in d.split.assignments for ln in a.path.lanes]
    union = flown + after
    return (
        new,
        coverage_ratio(union, target, spacing),  # type: ignore[arg-type]
        overlap_ratio(union, target, spacing),  # type: ignore[arg-type]
        coverage_ratio(planned, target, spacing),
    )


def test_a_vtol_lost_at_40_percent_leaves_its_lanes_to_the_others_flown_once(
    six_vtols: tuple[list[PlanVehicle], FleetPlan],
) -> None:
    vs, fp = six_vtols
    lost = vs[2].vehicle_id
    new, cov, double, planned = _coverage_after_loss(vs, fp, lost, {v.vehicle_id: 0.4 for v in vs})
    assert new.roster == tuple(v.vehicle_id for v in vs if v.vehicle_id != lost)
    assert lost not in new.shares
    assert cov >= 0.99 and cov >= planned - 1e-3
    assert double < 0.01
    # the lost vehicle's unflown lanes went to the others: their shares grew
    assert new.makespan_s > 0.6 * fp.makespan_s


@settings(
    max_examples=examples(4),
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture],
)
@given(st.integers(0, 5), st.lists(st.floats(0.05, 0.95), min_size=6, max_size=6), st.randoms())
def test_area_replan_covers_what_is_left_once_and_ignores_input_order(
    six_vtols: tuple[list[PlanVehicle], FleetPlan],
    lost_i: int,
    fractions: list[float],
    rnd: random.Random,
) -> None:
    vs, fp = six_vtols
    frac = {v.vehicle_id: f for v, f in zip(vs, fractions, strict=True)}
    new, cov, double, planned = _coverage_after_loss(vs, fp, vs[lost_i].vehicle_id, frac)
    assert cov >= 0.99 and cov >= planned - 1e-3
    assert double < 0.01
    # every survivor computes the same plan from the same inputs in any order
    progress = {}
    posed = []
    for v in vs:
        m, pv = _at(fp.share(v.vehicle_id), frac[v.vehicle_id], v)
        progress[v.vehicle_id] = m
        if v.vehicle_id != vs[lost_i].vehicle_id:
            posed.append(pv)
    items = list(progress.items())
    rnd.shuffle(items)
    rnd.shuffle(posed)
    again = fp.replan(dict(items), posed, zones=[], now_unix_s=0.0, home_alt_msl_m=0.0)
    assert again.roster == new.roster and again.shares == new.shares


def test_area_percent_converts_metres_along_the_share_to_the_coverage_path(
    six_vtols: tuple[list[PlanVehicle], FleetPlan],
) -> None:
    _vs, fp = six_vtols
    assert isinstance(fp.detail, AreaPlan)
    vid = fp.roster[1]
    path = fp.detail.split.of(vid).path
    share = fp.share(vid)
    frame = fp.detail.frame
    # at each lane's end the path metres are the lane's end exactly
    s = 0.0
    lanes = iter(path.lanes)
    xy = [
        frame.to_local(w.lat_deg, w.lon_deg) if w.kind == ItemKind.WAYPOINT else None
        for w in share.waypoints
    ]
    for leg in path.legs:
        s += leg.length_m
        if not leg.is_lane:
            continue
        end = next(lanes).b
        k = next(i for i, p in enumerate(xy) if p is not None and math.dist(p, end) < 0.05)
        pct = fp.area_percent(vid, share.along_m[k])
        assert pct / 100.0 * path.length_m == pytest.approx(s, abs=1e-6)
    assert fp.area_percent(vid, 0.0) == 0.0
    assert fp.area_percent(vid, share.length_m) == pytest.approx(100.0)
    assert fp.area_percent(999, 50.0) == 0.0


def test_area_replan_takes_a_joiner(fleet: Fleet, profiles: dict) -> None:
    vs = fleet(["multirotor", "multirotor"], _homes(2))
    mission = _mission(
        MissionType.AREA, SMALL, altitude_rel_m=80.0, altitude_step_m=5.0, side_overlap=0.2
    )
    fp = _plan(mission, vs)
    joiner = PlanVehicle(
        msgspec.structs.replace(profiles["multirotor"], vehicle_id=150), VehiclePose(LA, LO)
    )
    progress = {v.vehicle_id: 0.5 * fp.share(v.vehicle_id).length_m for v in vs}
    posed = [_at(fp.share(v.vehicle_id), 0.5, v)[1] for v in vs]
    new = fp.replan(progress, [*posed, joiner], zones=[], now_unix_s=0.0, home_alt_msl_m=0.0)
    assert new.roster == (*fp.roster, 150)
    assert new.share(150).length_m > 0.0


# --------------------------------------------------------------------------- other types


def _around(n: int, r_deg: float = 0.006) -> list[VehiclePose | None]:
    return [
        VehiclePose(
            LA + 0.004 + r_deg * math.sin(2 * math.pi * i / n),
            LO + 0.004 + r_deg * math.cos(2 * math.pi * i / n),
            80.0,
            0.0,
        )
        for i in range(n)
    ]


def test_perimeter_replan_rephases_the_patrol_among_the_survivors(fleet: Fleet) -> None:
    square = Geometry.polygon(
        [(LA, LO), (LA, LO + 0.008), (LA + 0.008, LO + 0.008), (LA + 0.008, LO)]
    )
    vs = fleet(["fixed_wing"] * 4, _around(4))
    fp = _plan(_mission(MissionType.PERIMETER, square, altitude_step_m=10.0, loops=3), vs)
    assert isinstance(fp.detail, PerimeterPlan)
    progress, posed = {}, []
    for v in vs:
        m, pv = _at(fp.share(v.vehicle_id), 0.5, v)
        progress[v.vehicle_id] = m
        posed.append(pv)
    survivors = posed[:1] + posed[2:]
    new = fp.replan(progress, survivors, zones=[], now_unix_s=0.0, home_alt_msl_m=0.0)
    assert isinstance(new.detail, PerimeterPlan)
    assert new.roster == tuple(sorted(v.vehicle_id for v in survivors))
    offs = sorted(o for _v, o in new.detail.offsets_m)
    gaps = [(b - a) for a, b in zip(offs, [*offs[1:], offs[0] + new.detail.length_m], strict=True)]
    assert gaps == pytest.approx([new.detail.length_m / 3] * 3, rel=1e-6)
    assert new.mission.params.loops == 2  # half of 3 laps flown: 1.5 left, rounded up
    assert new.detail.arrivals  # a synchronized entry onto the loop


def test_target_replan_respaces_the_orbit(fleet: Fleet) -> None:
    vs = fleet(["fixed_wing"] * 4, _around(4, 0.01))
    mission = _mission(MissionType.TARGET, Geometry.point(LA + 0.004, LO + 0.004), radius_m=200.0)
    fp = _plan(mission, vs)
    assert isinstance(fp.detail, TargetPlan)
    posed = [_at(fp.share(v.vehicle_id), 0.7, v)[1] for v in vs]
    new = fp.replan({}, posed[1:], zones=[], now_unix_s=0.0, home_alt_msl_m=0.0)
    assert isinstance(new.detail, TargetPlan)
    phases = sorted(s.phase_rad for s in new.detail.slots)
    gaps = [b - a for a, b in zip(phases, [*phases[1:], phases[0] + 2 * math.pi], strict=True)]
    assert gaps == pytest.approx([2 * math.pi / 3] * 3, rel=1e-6)


def test_route_replan_keeps_the_survivors_shares_and_plans_a_joiner(
    fleet: Fleet, profiles: dict
) -> None:
    route = Geometry(
        GeometryKind.POLYLINE,
        (LatLon(LA, LO), LatLon(LA + 0.004, LO + 0.004), LatLon(LA + 0.008, LO)),
    )
    vs = fleet(["fixed_wing"] * 3, _around(3, 0.01))
    fp = _plan(_mission(MissionType.ROUTE, route, altitude_step_m=10.0), vs)
    joiner = PlanVehicle(
        msgspec.structs.replace(profiles["fixed_wing"], vehicle_id=60), VehiclePose(LA, LO, 80.0)
    )
    new = fp.replan({}, [vs[0], vs[2], joiner], zones=[], now_unix_s=0.0, home_alt_msl_m=0.0)
    assert new.roster == (vs[0].vehicle_id, vs[2].vehicle_id, 60)
    assert new.share(vs[0].vehicle_id) is fp.share(vs[0].vehicle_id)
    assert new.share(60).length_m > 0.0


def test_objective_replan_spreads_the_survivors_over_the_points(fleet: Fleet) -> None:
    pts = Geometry(GeometryKind.POINTS, (LatLon(LA, LO), LatLon(LA + 0.006, LO + 0.006)))
    vs = fleet(["multirotor"] * 4, _around(4))
    fp = _plan(_mission(MissionType.OBJECTIVE, pts, radius_m=30.0), vs)
    new = fp.replan({}, vs[1:], zones=[], now_unix_s=0.0, home_alt_msl_m=0.0)
    groups = dict(new.detail.groups)  # type: ignore[attr-defined]
    assert sorted(len(g) for g in groups.values()) == [1, 2]
    assert new.roster == tuple(v.vehicle_id for v in vs[1:])


def test_area_replan_keeps_each_survivor_within_its_battery(fleet: Fleet) -> None:
    from swarm_node.core.planning import InfeasibleTimingError
    from swarm_node.core.planning.endurance import Endurance

    vs = fleet(["multirotor"] * 3, _homes(3))
    mission = _mission(
        MissionType.AREA, SMALL, altitude_rel_m=80.0, altitude_step_m=5.0, side_overlap=0.2
    )
    fp = _plan(mission, vs)
    assert set(fp.homes) == set(fp.roster)
    progress, posed = {}, []
    for v in vs:
        m, pv = _at(fp.share(v.vehicle_id), 0.3, v)
        progress[v.vehicle_id] = m
        posed.append(pv)
    survivors = posed[:2]
    battery = {v.vehicle_id: 95.0 for v in survivors}
    new = fp.replan(
        progress, survivors, zones=[], now_unix_s=0.0, home_alt_msl_m=0.0, battery_pct=battery
    )
    assert new.homes == fp.homes  # the way home still goes where they took off
    assert isinstance(new.detail, AreaPlan)
    frame = new.detail.frame
    for v in survivors:
        a = new.detail.split.of(v.vehicle_id)
        if not a.path.lanes:
            continue
        home = frame.to_local(fp.homes[v.vehicle_id].lat_deg, fp.homes[v.vehicle_id].lon_deg)
        back = math.dist(a.path.lanes[-1].b, home) / a.speed_m_s
        budget = Endurance.of(v.profile, 80.0).airborne_budget_s(95.0, v.profile)
        assert a.time_s + back <= budget + 1e-6
    with pytest.raises(InfeasibleTimingError):
        fp.replan(
            progress,
            survivors,
            zones=[],
            now_unix_s=0.0,
            home_alt_msl_m=0.0,
            battery_pct={v.vehicle_id: 27.0 for v in survivors},
        )
