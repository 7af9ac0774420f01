"""The order's local search: on where its cost is paid once (a plan's single
path, each vehicle's final share), never making an order worse, and counting the way
home of a vehicle with a battery budget (without it the search moved the 1,7,8 demo
survey's shares' ends away from home and the endurance-aware split refused the survey)."""

from __future__ import annotations

import math
from typing import Any

from shapely.geometry import Polygon

from swarm_node.core.planning import DubinsTurns, Worker, decompose, plan_lanes, split_lanes
from swarm_node.core.planning import coverage as cov
from swarm_node.core.planning.dubins import Pose
from swarm_node.core.planning.split import MakespanCost

SPACING = 34.64
TURNS = DubinsTurns(30.0)


def _length(lanes: Any, turns: Any = TURNS, start: Pose | None = None) -> float:
    return cov.connect(lanes, turns, None, start).length_m


def test_the_search_never_lengthens_an_order(coverage_refs: dict[str, Any]) -> None:
    assert cov.LOCAL_SEARCH
    for name, p in coverage_refs["polygons"].items():
        lanes = plan_lanes(decompose(Polygon(p["shell"], p["holes"])), SPACING, TURNS).lanes
        for start in (None, Pose(-500.0, -500.0, 0.3)):
            seed = cov.order(lanes, TURNS, start, improve=False)
            searched = cov.order(lanes, TURNS, start, restarts=4, improve=True)
            assert _length(searched, start=start) <= _length(seed, start=start) + 1e-6, name


def test_the_way_home_counts_in_the_order() -> None:
    """Lanes north of home: without the way home the order may end at the far side;
    with it, path plus way home is never longer."""
    lanes = [cov.Lane(k, (0.0, 200.0 + 40.0 * k), (600.0, 200.0 + 40.0 * k)) for k in range(9)]
    home = (0.0, 0.0)
    for improve in (False, True):
        free = cov.order(lanes, TURNS, improve=improve)
        homing = cov.order(lanes, TURNS, end=home, improve=improve)

        def total(seq: Any) -> float:
            end = seq[-1].b
            return _length(seq) + math.hypot(end[0] - home[0], end[1] - home[1])

        assert total(homing) <= total(free) + 1e-6
    # order_cost: the transitions only (the way home chooses, it is not counted in)
    seq, cost = cov.order_cost(lanes, TURNS, end=home)
    assert math.isclose(_length(seq), sum(ln.length_m for ln in seq) + cost, rel_tol=1e-9)


def test_a_final_share_is_never_worse_than_the_share_the_split_timed(
    coverage_refs: dict[str, Any],
) -> None:
    p = coverage_refs["polygons"]["irregular6"]
    lanes = plan_lanes(decompose(Polygon(p["shell"], p["holes"])), SPACING, TURNS).lanes
    homes = [(-900.0, -900.0), (-800.0, -900.0), (-700.0, -900.0)]
    workers = [
        Worker(i + 1, v, TURNS, Pose(*h, 0.0), budget_s=900.0, home=h)
        for i, (v, h) in enumerate(zip((18.0, 18.0, 12.0), homes, strict=True))
    ]
    plan = split_lanes(lanes, workers)
    cost = MakespanCost()
    for a, w in zip(plan.assignments, workers, strict=True):
        seed = cost.assignment(a.path.lanes, w)
        assert (cost.overrun_s(a, w), a.time_s) <= (cost.overrun_s(seed, w), seed.time_s + 1e-9)
