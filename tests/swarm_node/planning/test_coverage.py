"""Coverage pipeline: properties, turn-aware order, sweep search, invalid input (the
reference polygons' targets: test_bench_targets.py)."""

from __future__ import annotations

import itertools
import math
from typing import Any

import pytest
import shapely
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from shapely.geometry import LineString, Point, Polygon

from swarm_node.core.planning import (
    DubinsTurns,
    EmptyAreaError,
    InvalidGeometryError,
    InvalidParameterError,
    PointTurns,
    SweepCost,
    Zone,
    ZoneSet,
    connect,
    coverage_ratio,
    decompose,
    lane_spacing_m,
    lanes,
    order,
    overlap_ratio,
    plan_lanes,
    shortest_path,
    sweep_angle,
)
from swarm_node.core.planning.checks import coverage_problems, path_problems
from swarm_node.core.planning.coverage import Leg
from swarm_node.core.planning.dubins import Pose
from swarm_node.core.planning.turns import TurnModel
from tests.conftest import examples

R_REF = 30.0


def test_lane_spacing_matches_reference(coverage_refs: dict[str, Any]) -> None:
    cam = coverage_refs["camera"]
    spacing = lane_spacing_m(cam["altitude_m"], cam["hfov_deg"], cam["side_overlap"])
    assert spacing == pytest.approx(cam["lane_spacing_m"], abs=0.01)


def test_turn_aware_order_beats_boustrophedon() -> None:
    # 10 lanes 34.6 m apart, turn radius 30 m: adjacent U-turns are CCC loops
    region = decompose(Polygon([(0, 0), (600, 0), (600, 346), (0, 346)]))
    spacing = 34.64
    ls = lanes(region, 0.0, spacing)
    turns = DubinsTurns(R_REF)
    boustro = [ln if i % 2 == 0 else ln.reversed() for i, ln in enumerate(ls)]
    smart = connect(order(ls, turns), turns)
    naive = connect(boustro, turns)
    assert smart.length_m < naive.length_m - 3 * 60
    # the better order skips lanes: fewer transitions between neighbouring lines
    steps = [abs(a.line - b.line) for a, b in zip(smart.lanes[:-1], smart.lanes[1:], strict=True)]
    assert sum(1 for s in steps if s == 1) <= 2
    # with point turns the plain boustrophedon is already optimal
    pt = connect(order(ls, PointTurns()), PointTurns())
    assert pt.length_m == pytest.approx(sum(ln.length_m for ln in ls) + spacing * (len(ls) - 1))


def test_sweep_search_finds_edge_direction_of_a_thin_rotated_strip() -> None:
    poly = shapely.affinity.rotate(
        Polygon([(0, 0), (1000, 0), (1000, 80), (0, 80)]), 17.3, origin=(0, 0)
    )
    region = decompose(poly)
    a = sweep_angle(region, 30.0, SweepCost.for_turns(DubinsTurns(30.0), 30.0))
    assert math.degrees(a) % 180 == pytest.approx(17.3, abs=0.05)


# --------------------------------------------------------------------------- properties


@st.composite
def star_polygons(draw: st.DrawFn) -> Polygon:
    """Random star-shaped polygons (simple by construction), 200-900 m across, with
    0-2 holes (16-gons well inside the shell, apart from each other)."""
    n = draw(st.integers(4, 9))
    cuts = sorted(draw(st.lists(st.floats(0, 2 * math.pi), min_size=n, max_size=n, unique=True)))
    radii = draw(st.lists(st.floats(150, 450), min_size=n, max_size=n))
    pts = [(r * math.cos(a), r * math.sin(a)) for a, r in zip(cuts, radii, strict=True)]
    poly = Polygon(pts)
    if not poly.is_valid or poly.area < 20_000:
        poly = poly.convex_hull
    holes: list[Polygon] = []
    for x, y, r in draw(
        st.lists(
            st.tuples(st.floats(-250, 250), st.floats(-250, 250), st.floats(20, 80)), max_size=2
        )
    ):
        hole = Point(x, y).buffer(r, quad_segs=4)
        if poly.buffer(-10).contains(hole) and all(hole.distance(h) > 5 for h in holes):
            holes.append(hole)
    return Polygon(poly.exterior, [h.exterior for h in holes])


zone_specs = st.one_of(
    st.none(),
    st.tuples(st.floats(-200, 200), st.floats(-200, 200), st.floats(30, 120)),
)


def _transition_samples(a: Pose, b: Pose, leg: Leg, turns: TurnModel) -> list[tuple[float, float]]:
    """The transition as flown: a Dubins one sampled along its arcs, a rerouted one (or
    a point turn) as its polyline."""
    if isinstance(turns, DubinsTurns) and abs(leg.length_m - turns.length(a, b)) < 1e-6:
        return [(p.x, p.y) for p in shortest_path(a, b, turns.radius_m).sample(1.0)]
    return list(leg.points)


@settings(max_examples=examples(20), deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    star_polygons(),
    zone_specs,
    st.floats(20.0, 60.0),
    st.sampled_from([0.0, 30.0]),
    st.sampled_from([0.0, 5.0]),
    st.booleans(),
)
def test_coverage_covers_area_minus_holes_and_zones_and_never_enters_them(
    poly: Polygon,
    zone: tuple[float, float, float] | None,
    spacing: float,
    radius: float,
    margin: float,
    polish: bool,
) -> None:
    zones = ZoneSet()
    if zone is not None:
        zones = ZoneSet((Zone(1, Point(zone[0], zone[1]).buffer(zone[2])),), margin_m=margin)
    try:
        region = decompose(poly, zones)
    except EmptyAreaError:
        return
    turns = DubinsTurns(radius) if radius > 0 else PointTurns()
    lp = plan_lanes(region, spacing, turns, polish=polish)
    # the area minus its holes minus the zones is seen at the lane spacing (zones with
    # their margin: the band within the margin is not flown over, see docs/planners.md)
    target = poly.difference(zones.keep_out()) if zones.zones else poly
    assert coverage_problems(lp.lanes, target, spacing, 0.99) == []
    # no lane, transition (sampled along its arcs) or waypoint inside a zone; no lane
    # starts or ends inside a hole (holes are ground not to see, not no-fly areas: a
    # lane or a turn may pass over one, see docs/planners.md)
    raw = zones.raw()
    inner = raw.buffer(-1e-6) if zones.zones else None
    assert path_problems(lp.path, raw if zones.zones else None) == []
    lanes_flown = lp.path.lanes
    for k, leg in enumerate(lp.path.legs):
        if leg.is_lane or inner is None:
            continue
        a, b = lanes_flown[(k - 1) // 2].end_pose(), lanes_flown[(k + 1) // 2].start_pose()
        assert not LineString(_transition_samples(a, b, leg, turns)).intersects(inner)
    holes = [Polygon(h) for h in poly.interiors]
    for p in lp.path.points():
        assert inner is None or not inner.contains(Point(p))
    for ln in lp.path.lanes:
        for p in (ln.a, ln.b):
            assert not any(h.buffer(-1e-6).contains(Point(p)) for h in holes), p
    # the sweep lanes are parallel and spacing apart; gap lanes (beside zones) are extra
    sweep = [ln for ln in lp.lanes if not ln.gap]
    ys = sorted(
        {
            round(-math.sin(lp.angle_rad) * ln.a[0] + math.cos(lp.angle_rad) * ln.a[1], 6)
            for ln in sweep
        }
    )
    for a, b in itertools.pairwise(ys):
        assert (b - a) / spacing == pytest.approx(round((b - a) / spacing), abs=1e-6)


# --------------------------------------------------------------------------- invalid input


def test_self_intersecting_polygon_raises() -> None:
    with pytest.raises(InvalidGeometryError, match="not simple"):
        decompose(Polygon([(0, 0), (100, 100), (100, 0), (0, 100)]))


def test_empty_area_raises() -> None:
    with pytest.raises(EmptyAreaError):
        decompose(Polygon([(0, 0), (0, 0), (0, 0)]))
    square = Polygon([(0, 0), (100, 0), (100, 100), (0, 100)])
    covered = ZoneSet((Zone(1, square.buffer(10)),))
    with pytest.raises(EmptyAreaError):
        decompose(square, covered)


@pytest.mark.filterwarnings("ignore::RuntimeWarning")
def test_nan_polygon_raises() -> None:
    with pytest.raises(InvalidGeometryError, match="finite"):
        decompose(Polygon([(0, 0), (math.nan, 0), (100, 100)]))


@pytest.mark.parametrize(
    "args", [(0.0, 60.0, 0.7), (100.0, 0.0, 0.7), (100.0, 60.0, 1.0), (math.nan, 60, 0.5)]
)
def test_bad_camera_parameters_raise(args: tuple[float, float, float]) -> None:
    with pytest.raises(InvalidParameterError):
        lane_spacing_m(*args)


def test_metrics_on_a_known_layout() -> None:
    area = Polygon([(0, 0), (100, 0), (100, 40), (0, 40)])
    region = decompose(area)
    ls = lanes(region, 0.0, 20.0)
    assert len(ls) == 2
    assert coverage_ratio(ls, area, 20.0) == pytest.approx(1.0)
    assert overlap_ratio(ls, area, 20.0) == pytest.approx(0.0)
    assert overlap_ratio(ls, area, 30.0) == pytest.approx(10 * 100 / 4000)
