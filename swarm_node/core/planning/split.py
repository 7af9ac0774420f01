"""Splitting coverage lanes among heterogeneous vehicles, and replanning the remaining
lanes when vehicles drop out or join.

The lanes (in sweep order) are cut into contiguous blocks, one per vehicle, so that
vehicles work side by side rather than interleaved. The objective (`MakespanCost`, a
separate object) is the mission makespan: the largest (approach + block path) / speed.
The split is searched in two steps: for each arrangement of the vehicles across the
sweep (distinct speed/turn classes only), a binary search on the makespan with a greedy
prefix fill over estimated block costs; then the best arrangements are evaluated
exactly (each block ordered and connected with its vehicle's turn model) and the block
boundaries are moved lane by lane while the exact makespan improves. Optionally the
lane at each block boundary is cut so the two vehicles meet mid-lane.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

from .coverage import CoveragePath, Lane, connect, order
from .dubins import Pose
from .errors import InvalidParameterError, NoVehiclesError
from .turns import TurnModel
from .zones import Obstacles

_MAX_ARRANGEMENTS = 720


@dataclass(frozen=True, slots=True)
class Worker:
    """A vehicle taking part in a coverage split."""

    vehicle_id: int
    speed_m_s: float
    turns: TurnModel
    start: Pose | None = None  # where it is now (None: approach not counted)

    def __post_init__(self) -> None:
        if not (math.isfinite(self.speed_m_s) and self.speed_m_s > 0.0):
            raise InvalidParameterError(
                f"vehicle {self.vehicle_id}: speed must be > 0, got {self.speed_m_s}"
            )


@dataclass(frozen=True, slots=True)
class Assignment:
    vehicle_id: int
    speed_m_s: float
    path: CoveragePath  # approach (if a start was given) + its lanes

    @property
    def time_s(self) -> float:
        return self.path.length_m / self.speed_m_s


@dataclass(frozen=True, slots=True)
class SplitPlan:
    assignments: tuple[Assignment, ...]

    @property
    def makespan_s(self) -> float:
        return max((a.time_s for a in self.assignments), default=0.0)

    def of(self, vehicle_id: int) -> Assignment:
        for a in self.assignments:
            if a.vehicle_id == vehicle_id:
                return a
        raise NoVehiclesError(f"vehicle {vehicle_id} has no assignment")


@dataclass(frozen=True, slots=True)
class MakespanCost:
    """Time of a block of lanes for a worker. `estimate` is cheap (lane lengths plus one
    turn allowance per lane plus a straight approach); `exact` orders and connects."""

    turn_allowance_m: float
    obstacles: Obstacles | None = None  # transitions are rerouted around them

    def estimate(self, block: Sequence[Lane], w: Worker) -> float:
        if not block:
            return 0.0
        length = sum(ln.length_m for ln in block) + self.turn_allowance_m * (len(block) - 1)
        if w.start is not None:
            mid = block[0].a
            length += math.hypot(mid[0] - w.start.x, mid[1] - w.start.y)
        return length / w.speed_m_s

    def path(self, block: Sequence[Lane], w: Worker) -> CoveragePath:
        return connect(order(block, w.turns, w.start), w.turns, self.obstacles, w.start)

    def exact(self, block: Sequence[Lane], w: Worker) -> float:
        return self.path(block, w).length_m / w.speed_m_s if block else 0.0


def sweep_sorted(lanes: Sequence[Lane]) -> list[Lane]:
    """Lanes in sweep order: by line, then along the line."""

    def key(ln: Lane) -> tuple[int, float]:
        c, s = math.cos(ln.yaw), math.sin(ln.yaw)
        return ln.line, min(ln.a[0] * c + ln.a[1] * s, ln.b[0] * c + ln.b[1] * s)

    return sorted(lanes, key=key)


def _greedy(
    lanes: Sequence[Lane], ws: Sequence[Worker], cost: MakespanCost, limit: float
) -> list[int] | None:
    """Block boundaries filling each worker up to `limit` seconds, or None."""
    bounds = [0]
    i = 0
    for k, w in enumerate(ws):
        j = i
        if k == len(ws) - 1:
            j = len(lanes)
            if cost.estimate(lanes[i:j], w) > limit:
                return None
        else:
            while j < len(lanes) and cost.estimate(lanes[i : j + 1], w) <= limit:
                j += 1
        bounds.append(j)
        i = j
    return bounds


def _partition(
    lanes: Sequence[Lane], ws: Sequence[Worker], cost: MakespanCost
) -> tuple[float, list[int]]:
    hi = max(cost.estimate(lanes, w) for w in ws)
    lo = 0.0
    best = _greedy(lanes, ws, cost, hi)
    assert best is not None
    for _ in range(40):
        mid = (lo + hi) / 2.0
        got = _greedy(lanes, ws, cost, mid)
        if got is None:
            lo = mid
        else:
            hi, best = mid, got
    return hi, best


def _arrangements(workers: Sequence[Worker]) -> list[tuple[Worker, ...]]:
    if len(workers) <= 6 and all(w.start is None for w in workers):
        # only distinct classes matter when nobody has a position
        seen: dict[tuple[tuple[float, float], ...], tuple[Worker, ...]] = {}
        for p in itertools.permutations(workers):
            key = tuple((w.speed_m_s, w.turns.radius_m) for w in p)
            seen.setdefault(key, p)
        return list(seen.values())
    if len(workers) <= 6:
        return list(itertools.permutations(workers))[:_MAX_ARRANGEMENTS]
    by_speed = sorted(workers, key=lambda w: -w.speed_m_s)
    return [tuple(by_speed), tuple(reversed(by_speed))]


def split_lanes(
    lanes: Sequence[Lane],
    workers: Sequence[Worker],
    *,
    cost: MakespanCost | None = None,
    cut_lanes: bool = True,
    obstacles: Obstacles | None = None,
) -> SplitPlan:
    """Contiguous blocks of the lanes (in sweep order), one per worker, minimizing the
    makespan. Workers may get an empty block when there are fewer lanes than workers."""
    if not workers:
        raise NoVehiclesError("cannot split coverage among zero vehicles")
    ids = [w.vehicle_id for w in workers]
    if len(set(ids)) != len(ids):
        raise InvalidParameterError(f"duplicate vehicle ids in {ids}")
    ordered = sweep_sorted(lanes)
    if cost is None:
        r = max(w.turns.radius_m for w in workers)
        allowance = math.pi * r + 2.0 * r if r > 0 else 0.0
        cost = MakespanCost(allowance, obstacles)
    if not ordered:
        return SplitPlan(
            tuple(Assignment(w.vehicle_id, w.speed_m_s, CoveragePath((), ())) for w in workers)
        )
    scored = sorted(
        ((*_partition(ordered, arr, cost), arr) for arr in _arrangements(workers)),
        key=lambda t: t[0],
    )
    best_plan: tuple[float, list[int], tuple[Worker, ...]] | None = None
    for _est, bounds, arr in scored[:3]:
        bounds, span = _refine(ordered, arr, cost, bounds)
        if best_plan is None or span < best_plan[0]:
            best_plan = (span, bounds, arr)
    assert best_plan is not None
    _span, bounds, arr = best_plan
    blocks = [list(ordered[bounds[k] : bounds[k + 1]]) for k in range(len(arr))]
    if cut_lanes:
        blocks = _cut_boundaries(blocks, arr, cost)
    assigned = {
        w.vehicle_id: Assignment(
            w.vehicle_id, w.speed_m_s, cost.path(b, w) if b else CoveragePath((), ())
        )
        for w, b in zip(arr, blocks, strict=True)
    }
    return SplitPlan(tuple(assigned[w.vehicle_id] for w in workers))


def _refine(
    lanes: Sequence[Lane], ws: Sequence[Worker], cost: MakespanCost, bounds: list[int]
) -> tuple[list[int], float]:
    """Move block boundaries one lane at a time while the exact makespan drops."""
    memo: dict[tuple[int, int, int], float] = {}

    def t(k: int, b: list[int]) -> float:
        key = (k, b[k], b[k + 1])
        if key not in memo:
            memo[key] = cost.exact(lanes[b[k] : b[k + 1]], ws[k])
        return memo[key]

    def span(b: list[int]) -> float:
        return max(t(k, b) for k in range(len(ws)))

    cur = span(bounds)
    for _ in range(4 * len(lanes) + 10):
        best_move: tuple[float, list[int]] | None = None
        for k in range(1, len(ws)):
            for step in (-1, 1):
                b = list(bounds)
                b[k] += step
                if not b[k - 1] <= b[k] <= b[k + 1]:
                    continue
                s = span(b)
                if s < cur - 1e-9 and (best_move is None or s < best_move[0]):
                    best_move = (s, b)
        if best_move is None:
            break
        cur, bounds = best_move
    return bounds, cur


def _cut_boundaries(
    blocks: list[list[Lane]], ws: Sequence[Worker], cost: MakespanCost
) -> list[list[Lane]]:
    """Balance neighbours further by cutting the lane at each boundary: the busier side's
    boundary lane is cut and its far part handed over, the cut point found by
    bisection on the two exact times."""
    for k in range(len(blocks) - 1):
        left, right = blocks[k], blocks[k + 1]
        if not left or not right:
            continue
        tl0, tr0 = cost.exact(left, ws[k]), cost.exact(right, ws[k + 1])
        give_right = tl0 > tr0
        shared = left[-1] if give_right else right[0]
        keep_l = left[:-1] if give_right else left
        keep_r = right if give_right else right[1:]

        def split_at(
            f: float,
            shared: Lane = shared,
            keep_l: list[Lane] = keep_l,
            keep_r: list[Lane] = keep_r,
        ) -> tuple[list[Lane], list[Lane]]:
            a, b = shared.cut(f)  # a: the left part (towards the left block)
            # a part under 1 m is not worth a turn: the other side flies the whole lane
            # (dropping it would leave its strip unseen)
            if a.length_m <= 1.0:
                return list(keep_l), [shared, *keep_r]
            if b.length_m <= 1.0:
                return [*keep_l, shared], list(keep_r)
            return [*keep_l, a], [b, *keep_r]

        lo, hi = 0.0, 1.0
        best = (max(tl0, tr0), left, right)
        for _ in range(12):
            mid = (lo + hi) / 2.0
            lb, rb = split_at(mid)
            tl, tr = cost.exact(lb, ws[k]), cost.exact(rb, ws[k + 1])
            if max(tl, tr) < best[0]:
                best = (max(tl, tr), lb, rb)
            if tl < tr:
                lo = mid
            else:
                hi = mid
        blocks[k], blocks[k + 1] = best[1], best[2]
    return blocks


# --------------------------------------------------------------------------- replan


def remaining_lanes(plan: SplitPlan, progress_pct: Mapping[int, float]) -> list[Lane]:
    """The lanes (and parts of lanes) not flown yet, from each vehicle's completion
    percentage of its own path. A vehicle missing from `progress_pct` has done 0 %."""
    out: list[Lane] = []
    for a in plan.assignments:
        pct = progress_pct.get(a.vehicle_id, 0.0)
        if not math.isfinite(pct):
            raise InvalidParameterError(f"vehicle {a.vehicle_id}: progress is not finite")
        done_m = min(max(pct, 0.0), 100.0) / 100.0 * a.path.length_m
        s = 0.0
        lane_iter = iter(a.path.lanes)
        for leg in a.path.legs:
            if not leg.is_lane:
                s += leg.length_m
                continue
            lane = next(lane_iter)
            if s + leg.length_m <= done_m:
                s += leg.length_m
                continue
            if s < done_m:
                _done, rest = lane.cut((done_m - s) / leg.length_m)
                if rest.length_m > 1.0:
                    out.append(rest)
            else:
                out.append(lane)
            s += leg.length_m
    return out


def replan(
    plan: SplitPlan,
    progress_pct: Mapping[int, float],
    workers: Sequence[Worker],
    *,
    cost: MakespanCost | None = None,
    cut_lanes: bool = True,
    obstacles: Obstacles | None = None,
) -> SplitPlan:
    """Split what remains of `plan` among `workers` (those still flying plus any that
    joined, each from its current `start`): vehicles of the old plan that are not in
    `workers` dropped out and their remaining lanes are shared out."""
    left = remaining_lanes(plan, progress_pct)
    return split_lanes(left, workers, cost=cost, cut_lanes=cut_lanes, obstacles=obstacles)
