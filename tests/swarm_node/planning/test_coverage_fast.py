"""The fast paths of the area planner: coverage from the swaths' rectangles
equals the union's, the order's local search really moves, memoization does not
change plans, GIS fields with thousands of vertices are simplified first and their
plan still covers the original field, and a field too big to fly is refused up front.
Nothing here is timed (the times are in bench/results/planners.json)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
import shapely
from shapely.geometry import Polygon

from swarm_node.core.planning import DubinsTurns, decompose, lanes, plan_lanes
from swarm_node.core.planning import coverage as cov
from swarm_node.core.planning.context import PlanContext
from swarm_node.core.planning.errors import FieldTooBigError

SPACING = 34.64
TURNS = DubinsTurns(30.0)


def _union_coverage(lanes_: Any, area: Any, spacing: float) -> float:
    seen = shapely.union_all(cov.swaths(lanes_, spacing), grid_size=1e-6)
    return float(seen.intersection(area, grid_size=1e-6).area / area.area)


def test_coverage_from_rectangles_equals_the_union(coverage_refs: dict[str, Any]) -> None:
    for name, p in coverage_refs["polygons"].items():
        region = decompose(Polygon(p["shell"], p["holes"]))
        for angle in (0.1, 0.5, 1.3, 2.9):
            for extend in (0.0, 0.2, 0.5):
                ls = lanes(region, angle, SPACING, extend=extend)
                assert cov._disjoint_swaths(ls, SPACING), name
                fast = cov.coverage_ratio(ls, region.target, SPACING)
                assert fast == pytest.approx(_union_coverage(ls, region.target, SPACING), abs=1e-6)
                assert cov.overlap_ratio(ls, region.target, SPACING) == 0.0


def test_overlapping_swaths_are_unioned() -> None:
    a = cov.Lane(0, (0.0, 0.0), (100.0, 0.0))
    b = cov.Lane(1, (0.0, 10.0), (100.0, 10.0))  # closer than a spacing: overlapping
    area = shapely.box(0.0, -20.0, 100.0, 30.0)
    assert not cov._disjoint_swaths([a, b], 20.0)
    assert cov.coverage_ratio([a, b], area, 20.0) == pytest.approx(30.0 * 100.0 / 5000.0)


def test_order_local_search_improves_a_bad_tour() -> None:
    ls = [cov.Lane(k, (0.0, 40.0 * k), (500.0, 40.0 * k)) for k in range(8)]
    st, en = cov._poses(ls)
    c = cov._padded(TURNS.cost_matrix(en, st), None)
    m = 2 * len(ls)
    bad = np.array([m, *[2 * i for i in (3, 0, 6, 1, 5, 2, 7, 4)], m + 1], dtype=np.intp)
    better = cov._improve(bad, c)
    assert cov._cost(better, c) < cov._cost(bad, c) - 100.0


def test_memoized_plans_equal_cold_plans(coverage_refs: dict[str, Any]) -> None:
    p = coverage_refs["polygons"]["irregular6"]
    region = decompose(Polygon(p["shell"], p["holes"]))
    cov.clear_caches()
    cold = plan_lanes(region, SPACING, TURNS)
    warm = plan_lanes(region, SPACING, TURNS)
    assert cold.path == warm.path and cold.lanes == warm.lanes


def _gis_field(n: int = 4000, seed: int = 1) -> Polygon:
    """A digitized field: a lobed outline of n vertices with 1 m noise."""
    rng = np.random.default_rng(seed)
    th = np.linspace(0.0, 2.0 * math.pi, n, endpoint=False)
    r = 600.0 + 80.0 * np.sin(3.0 * th) + rng.normal(0.0, 1.0, n)
    return Polygon(np.column_stack([1.3 * r * np.cos(th), r * np.sin(th)]))


def test_a_4000_vertex_field_is_simplified_and_its_plan_covers_the_original() -> None:
    field = _gis_field()
    assert field.is_valid and len(field.exterior.coords) == 4001
    region = decompose(field)
    small = cov.simplified(region, SPACING)
    assert cov._vertex_count(small.cover) <= cov._MAX_VERTICES
    assert small.cover.contains(field)  # lanes planned on it see all of the field
    assert small.target is region.target  # coverage is measured on the field itself
    plan = plan_lanes(region, SPACING, TURNS)
    assert plan.coverage >= 0.99
    # independently of the planner's own figure: the swaths' union over the original
    assert _union_coverage(plan.lanes, field, SPACING) >= 0.99


def test_a_small_field_is_not_simplified(coverage_refs: dict[str, Any]) -> None:
    p = coverage_refs["polygons"]["irregular6"]
    region = decompose(Polygon(p["shell"], p["holes"]))
    assert cov.simplified(region, SPACING) is region


def test_a_field_too_big_to_fly_is_refused_with_its_estimate() -> None:
    region = decompose(shapely.box(0.0, 0.0, 20_000.0, 20_000.0))
    est = cov.estimated_flight_s(region, SPACING, TURNS, 48.0)
    # about area / spacing of lanes at 48 m/s: 4e8 / 34.64 / 48 s, plus the turns
    assert 4e8 / SPACING / 48.0 < est < 1.5 * 4e8 / SPACING / 48.0
    with pytest.raises(FieldTooBigError) as err:
        cov.check_flyable(region, SPACING, TURNS, 48.0, 4 * 3600.0)
    assert err.value.estimated_s == pytest.approx(est)
    assert "h of flight" in str(err.value)
    small = decompose(shapely.box(0.0, 0.0, 1000.0, 1000.0))
    assert cov.check_flyable(small, SPACING, TURNS, 48.0, 4 * 3600.0) < 4 * 3600.0


def test_plan_area_refuses_a_field_too_big_before_planning(fleet: Any) -> None:
    from swarm_node.core.planning import plan_area
    from swarm_proto import Geometry

    from .conftest import ORIGIN

    la, lo = ORIGIN[0], ORIGIN[1]
    huge = Geometry.polygon([(la, lo), (la + 0.5, lo), (la + 0.5, lo + 0.5), (la, lo + 0.5)])
    with pytest.raises(FieldTooBigError, match="too big to fly") as err:
        plan_area(PlanContext(huge, fleet(["fixed_wing", "fixed_wing"])))
    assert err.value.estimated_s > 4 * 3600.0
