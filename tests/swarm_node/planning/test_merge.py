"""A fleet split by a partition merges back (swarm/heal.py): two parts replanned the
same first plan apart, each flew some of its plan; `FleetPlan.merged` makes one plan
of what neither flew, the same whichever part computes it, with no lane of it flown
before and nothing left out."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable

import msgspec
import pytest

from swarm_node.core.planning import PlanningError, PlanVehicle
from swarm_node.core.planning.area import AreaPlan
from swarm_node.core.planning.coverage import Lane
from swarm_node.core.planning.fleet_plan import FleetPlan, flown_lanes
from swarm_node.core.planning.split import common_lanes
from swarm_proto import MissionType

from .test_fleet_plan import SMALL, _at, _homes, _mission, _plan

Fleet = Callable[..., list[PlanVehicle]]


def _lanes(plan: FleetPlan) -> list[Lane]:
    assert isinstance(plan.detail, AreaPlan)
    return [ln for a in plan.detail.split.assignments for ln in a.path.lanes]


def _length(lanes: list[Lane]) -> float:
    return sum(ln.length_m for ln in lanes)


def _flown(plan: FleetPlan, fraction: float, vs: list[PlanVehicle]) -> tuple[dict, list]:
    """Each of `vs` `fraction` along its share of `plan`: progress, and posed there."""
    progress, posed = {}, []
    for v in vs:
        m, pv = _at(plan.share(v.vehicle_id), fraction, v)
        progress[v.vehicle_id] = m
        posed.append(pv)
    return progress, posed


def _replan(plan: FleetPlan, progress: dict, survivors: list[PlanVehicle]) -> FleetPlan:
    return plan.replan(progress, survivors, zones=[], now_unix_s=0.0, home_alt_msl_m=0.0)


def test_two_parts_merge_into_one_plan_of_what_neither_flew(fleet: Fleet) -> None:
    vs = fleet(["multirotor"] * 4, _homes(4))
    p0 = _plan(_mission(MissionType.AREA, SMALL, altitude_rel_m=60.0), vs)
    prog0, posed0 = _flown(p0, 0.3, vs)  # the cut: every member 30 % along its share
    a, b = posed0[:2], posed0[2:]
    pa, pb = _replan(p0, prog0, a), _replan(p0, prog0, b)  # each part replans alone
    assert set(pa.roster) == {v.vehicle_id for v in a}
    prog_a, posed_a = _flown(pa, 0.4, a)
    prog_b, posed_b = _flown(pb, 0.4, b)
    everyone = posed_a + posed_b
    kw = {"zones": [], "now_unix_s": 0.0, "home_alt_msl_m": 0.0}
    on_a = pa.merged(prog_a, [(pb, prog_b)], everyone, **kw)
    on_b = pb.merged(prog_b, [(pa, prog_a)], list(reversed(everyone)), **kw)
    assert on_a.shares == on_b.shares and on_a.digest() == on_b.digest()  # every node alike
    assert on_a.roster == tuple(sorted(v.vehicle_id for v in vs))
    merged = _lanes(on_a)
    flown = flown_lanes(p0, prog0) + flown_lanes(pa, prog_a) + flown_lanes(pb, prog_b)
    assert _length(common_lanes(merged, flown)) < 1.0  # no lane flown twice
    # nothing left out: what was flown (by either part: both flew the same rest) and
    # what is merged make the whole area's lanes
    whole = _lanes(p0)
    assert _length(merged) + _length(common_lanes(whole, flown)) == pytest.approx(
        _length(whole), rel=0.02
    )
    # each part alone would fly the other's rest again: the merge does not
    assert _length(common_lanes(_lanes(pa), flown_lanes(pb, prog_b))) > 50.0
    assert _length(merged) < _length(_lanes(pa))


def test_only_area_plans_of_one_mission_merge(fleet: Fleet) -> None:
    vs = fleet(["multirotor"] * 4, _homes(4))
    p0 = _plan(_mission(MissionType.AREA, SMALL, altitude_rel_m=60.0), vs)
    kw = {"zones": [], "now_unix_s": 0.0, "home_alt_msl_m": 0.0}
    with pytest.raises(ValueError, match="not finite"):
        p0.merged({vs[0].vehicle_id: math.nan}, [], vs, **kw)
    perimeter = dataclasses.replace(p0, mission=_mission(MissionType.PERIMETER, SMALL))
    with pytest.raises(PlanningError, match="PERIMETER plans are not merged"):
        perimeter.merged({}, [(p0, {})], vs, **kw)
    other = dataclasses.replace(p0, mission=msgspec.structs.replace(p0.mission, mission_id=8))
    with pytest.raises(PlanningError, match="another mission"):
        p0.merged({}, [(other, {})], vs, **kw)


def test_common_lanes_is_the_overlap_on_one_line() -> None:
    a = [Lane(0, (0.0, 0.0), (100.0, 0.0)), Lane(1, (0.0, 10.0), (100.0, 10.0))]
    b = [Lane(0, (80.0, 0.0), (20.0, 0.0)), Lane(1, (0.0, 30.0), (100.0, 30.0))]
    (got,) = common_lanes(a, b)
    assert (
        got.line == 0
        and got.a == pytest.approx((20.0, 0.0))
        and got.b == pytest.approx((80.0, 0.0))
    )
    assert common_lanes(a, []) == []
