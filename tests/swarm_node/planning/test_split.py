"""Heterogeneous lane split (makespan) and replanning from completion percentages."""

from __future__ import annotations

import functools
import math
from typing import Any

import pytest
import shapely
from hypothesis import given, settings
from hypothesis import strategies as st
from shapely.geometry import LineString, Polygon

from swarm_node.core.planning import (
    DubinsTurns,
    InvalidParameterError,
    NoVehiclesError,
    Pose,
    Worker,
    decompose,
    lane_spacing_m,
    plan_lanes,
    remaining_lanes,
    replan,
    split_lanes,
)
from tests.conftest import examples

R = 30.0
TURNS = DubinsTurns(R)


@pytest.fixture(scope="module")
def ref_lanes(coverage_refs: dict[str, Any]) -> dict[str, Any]:
    cam = coverage_refs["camera"]
    spacing = lane_spacing_m(cam["altitude_m"], cam["hfov_deg"], cam["side_overlap"])
    out = {}
    for name in ("irregular6", "square_with_hole"):
        ref = coverage_refs["polygons"][name]
        out[name] = plan_lanes(decompose(Polygon(ref["shell"], ref["holes"])), spacing, TURNS)
    return out


@pytest.mark.parametrize("name", ["irregular6", "square_with_hole"])
def test_split_makespan_within_8_percent_of_ideal(ref_lanes: dict[str, Any], name: str) -> None:
    lp = ref_lanes[name]
    speeds = (18.0, 18.0, 12.0)
    workers = [Worker(i + 1, v, TURNS) for i, v in enumerate(speeds)]
    plan = split_lanes(lp.lanes, workers)
    ideal = lp.path.length_m / sum(speeds)
    assert plan.makespan_s <= 1.08 * ideal
    # every lane is flown exactly once (a boundary lane may be cut between two vehicles)
    flown = [ln for a in plan.assignments for ln in a.path.lanes]
    assert _union_length(flown) == pytest.approx(lp.path.lane_length_m, abs=2.0)
    assert sum(ln.length_m for ln in flown) == pytest.approx(lp.path.lane_length_m, abs=2.0)
    # the slower vehicle gets less work
    slow = plan.of(3).path.lane_length_m
    assert slow < plan.of(1).path.lane_length_m and slow < plan.of(2).path.lane_length_m


def _union_length(lanes: Any) -> float:
    return float(shapely.union_all([LineString([ln.a, ln.b]) for ln in lanes]).length)


@functools.cache
def _base_plan() -> tuple[Any, Any]:
    region = decompose(Polygon([(0, 0), (700, 0), (700, 500), (0, 500)]))
    lp = plan_lanes(region, 40.0, TURNS, polish=False)
    workers = [Worker(1, 20.0, TURNS), Worker(2, 20.0, TURNS), Worker(3, 14.0, TURNS)]
    return lp, split_lanes(lp.lanes, workers)


@settings(max_examples=examples(12))
@given(
    st.dictionaries(st.sampled_from([1, 2, 3]), st.floats(0.0, 100.0), min_size=0, max_size=3),
    st.sampled_from([[1, 2], [2, 3], [1, 2, 3, 4], [4]]),
)
def test_replan_keeps_exactly_the_remaining_work(
    progress: dict[int, float], survivors: list[int]
) -> None:
    lp, plan = _base_plan()
    left = remaining_lanes(plan, progress)
    done_lane_m = 0.0
    for a in plan.assignments:
        pct = progress.get(a.vehicle_id, 0.0)
        total = a.path.length_m
        s, done = 0.0, 0.0
        for leg in a.path.legs:
            reach = min(max(pct / 100 * total - s, 0.0), leg.length_m)
            if leg.is_lane:
                done += reach
            s += leg.length_m
        done_lane_m += done
    assert _union_length(left) == pytest.approx(
        lp.path.lane_length_m - done_lane_m, abs=1.0 * len(lp.lanes)
    )
    # survivors (and a joiner, id 4, from the far corner) share what is left
    new = [Worker(v, 18.0, TURNS, Pose(700.0, 500.0, math.pi)) for v in survivors]
    after = replan(plan, progress, new)
    got = [ln for a in after.assignments for ln in a.path.lanes]
    # pieces under 1 m at a cut are not worth flying: at most 1 m lost per cut
    assert _union_length(got) == pytest.approx(_union_length(left), abs=1.0 * (len(new) + 3))
    assert {a.vehicle_id for a in after.assignments} == set(survivors)


def test_zero_vehicles_raise() -> None:
    with pytest.raises(NoVehiclesError):
        split_lanes([], [])


def test_bad_speed_raises() -> None:
    with pytest.raises(InvalidParameterError):
        Worker(1, 0.0, TURNS)
    with pytest.raises(InvalidParameterError):
        Worker(1, math.nan, TURNS)


def test_duplicate_ids_raise() -> None:
    with pytest.raises(InvalidParameterError):
        split_lanes([], [Worker(1, 10.0, TURNS), Worker(1, 12.0, TURNS)])
