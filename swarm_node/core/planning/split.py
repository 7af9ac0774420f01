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

import dataclasses
import itertools
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

from swarm_proto import DetailCode, ReasonDetail

from .coverage import LOCAL_SEARCH, CoveragePath, Lane, connect, order, order_cost
from .dubins import Pose
from .endurance import leg_s, stop_and_go_s
from .errors import InfeasibleTimingError, InvalidParameterError, NoVehiclesError
from .turns import PointTurns, TurnModel
from .zones import Obstacles

_MAX_ARRANGEMENTS = 720


@dataclass(frozen=True, slots=True)
class Worker:
    """A vehicle taking part in a coverage split."""

    vehicle_id: int
    speed_m_s: float
    turns: TurnModel
    start: Pose | None = None  # where it is now (None: approach not counted)
    accel_m_s2: float = 0.0  # it stops on every waypoint, braking at this (0: it does not)
    extra_s: float = 0.0  # seconds its block is known to take beyond the path (turns added)
    budget_s: float = math.inf  # the most its block plus the way home may take
    home: tuple[float, float] | None = None  # where the way home goes (default: start)

    def __post_init__(self) -> None:
        if not (math.isfinite(self.speed_m_s) and self.speed_m_s > 0.0):
            raise InvalidParameterError(
                f"vehicle {self.vehicle_id}: speed must be > 0, got {self.speed_m_s}"
            )
        for name in ("accel_m_s2", "extra_s"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0.0):
                raise InvalidParameterError(f"vehicle {self.vehicle_id}: {name} must be >= 0")
        if not (self.budget_s >= 0.0):
            raise InvalidParameterError(f"vehicle {self.vehicle_id}: budget_s must be >= 0")

    @property
    def back_to(self) -> tuple[float, float] | None:
        if self.home is not None:
            return self.home
        return (self.start.x, self.start.y) if self.start is not None else None

    def return_s(self, end: tuple[float, float]) -> float:
        """Straight way home from `end` at the worker's speed (0 with nowhere to go)."""
        h = self.back_to
        return math.dist(end, h) / self.speed_m_s if h is not None else 0.0


@dataclass(frozen=True, slots=True)
class Assignment:
    vehicle_id: int
    speed_m_s: float
    path: CoveragePath  # approach (if a start was given) + its lanes
    accel_m_s2: float = 0.0  # the worker's: it stops on every point of its path
    extra_s: float = 0.0  # the worker's known extra time (counted only with lanes)

    @property
    def path_time_s(self) -> float:
        """Flying time of the path: length / speed, or stopping on every point of it."""
        if self.accel_m_s2 <= 0.0:
            return self.path.length_m / self.speed_m_s
        return stop_and_go_s(self.path.points(), self.speed_m_s, self.accel_m_s2)

    @property
    def time_s(self) -> float:
        """What the split balanced: the path time plus the known extra."""
        return self.path_time_s + (self.extra_s if self.path.lanes else 0.0)


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

    turn_allowance_m: float | None = None  # None: each worker's own (pi R + 2 R)
    obstacles: Obstacles | None = None  # transitions are rerouted around them
    budget_cut: tuple[tuple[int, float], ...] = ()  # vehicle id -> seconds off its budget

    def allowance_m(self, w: Worker) -> float:
        if self.turn_allowance_m is not None:
            return self.turn_allowance_m
        r = w.turns.radius_m
        return math.pi * r + 2.0 * r

    def estimate(self, block: Sequence[Lane], w: Worker) -> float:
        if not block:
            return 0.0
        a, v = w.accel_m_s2, w.speed_m_s
        t = (
            sum(leg_s(ln.length_m, v, a) for ln in block)
            + self.allowance_m(w) * (len(block) - 1) / v
        )
        if w.start is not None:
            mid = block[0].a
            t += leg_s(math.hypot(mid[0] - w.start.x, mid[1] - w.start.y), v, a)
        return t + w.extra_s

    @staticmethod
    def _end(w: Worker) -> tuple[float, float] | None:
        """Where a worker with a battery budget goes after its block (the local search
        counts its way home); None for the others."""
        return w.back_to if math.isfinite(w.budget_s) else None

    def path(self, block: Sequence[Lane], w: Worker, *, improve: bool = False) -> CoveragePath:
        """The block connected in its cheapest seed pattern's order (the order the
        split times), or with `improve` that order improved by the local search, the
        way home counted."""
        if improve:
            seq = order(block, w.turns, w.start, end=self._end(w), improve=True)
        else:
            seq = order(block, w.turns, w.start, improve=False)
        return connect(seq, w.turns, self.obstacles, w.start)

    def assignment(self, block: Sequence[Lane], w: Worker) -> Assignment:
        """The block ordered by its cheapest seed pattern (what the split times)."""
        path = self.path(block, w) if block else CoveragePath((), ())
        return Assignment(w.vehicle_id, w.speed_m_s, path, w.accel_m_s2, w.extra_s)

    def final(self, block: Sequence[Lane], w: Worker) -> Assignment:
        """The block as it is flown: its order improved by the local search
        (`coverage.LOCAL_SEARCH`), kept only if that overruns the budget less and,
        then, takes less time than the seed pattern the split timed."""
        a = self.assignment(block, w)
        if not block or not LOCAL_SEARCH:
            return a
        b = Assignment(
            w.vehicle_id, w.speed_m_s, self.path(block, w, improve=True), w.accel_m_s2, w.extra_s
        )
        return b if (self.overrun_s(b, w), b.time_s) < (self.overrun_s(a, w), a.time_s) else a

    def exact(self, block: Sequence[Lane], w: Worker) -> float:
        return self.timed(block, w)[1]

    def timed(self, block: Sequence[Lane], w: Worker) -> tuple[float, float]:
        """(`overrun_s`, `time_s`) of the block's assignment. Without obstacles the
        path's length is the lanes plus the order's transition costs, and for a vehicle
        at constant speed, or one with point turns, its time follows from them: the
        path is not connected (the split asks this for many blocks)."""
        if not block:
            return 0.0, 0.0
        plain = type(self) is MakespanCost and (self.obstacles is None or self.obstacles.is_empty)
        if plain and (w.accel_m_s2 <= 0.0 or isinstance(w.turns, PointTurns)):
            lanes, transitions_m = order_cost(block, w.turns, w.start)
            if w.accel_m_s2 <= 0.0:
                t = (sum(ln.length_m for ln in lanes) + transitions_m) / w.speed_m_s
            else:  # point turns: the path's points are the start and the lanes' ends
                pts = [] if w.start is None else [(w.start.x, w.start.y)]
                for ln in lanes:
                    pts += [ln.a, ln.b]
                t = stop_and_go_s(pts, w.speed_m_s, w.accel_m_s2)
            t += w.extra_s
            over = 0.0
            if not math.isinf(w.budget_s):
                over = max(t + w.return_s(lanes[-1].b) - w.budget_s, 0.0)
            return over, t
        a = self.assignment(block, w)
        return self.overrun_s(a, w), a.time_s

    def fits(self, block: Sequence[Lane], w: Worker) -> bool:
        """Whether the block and the way home (from the farther end of its first and
        last lanes) fit in the worker's budget, by the estimate."""
        if not block or math.isinf(w.budget_s):
            return True
        ends = (block[0].a, block[0].b, block[-1].a, block[-1].b)
        back = max(w.return_s(p) for p in ends)
        budget = w.budget_s - dict(self.budget_cut).get(w.vehicle_id, 0.0)
        return self.estimate(block, w) + back <= budget

    def overrun_s(self, a: Assignment, w: Worker) -> float:
        """By how much an assignment and its way home overrun the worker's budget."""
        if not a.path.lanes or math.isinf(w.budget_s):
            return 0.0
        end = a.path.lanes[-1].b
        return max(a.time_s + w.return_s(end) - w.budget_s, 0.0)

    def fits_exact(self, a: Assignment, w: Worker) -> bool:
        """Whether an assignment and its way home fit in the worker's budget."""
        return self.overrun_s(a, w) <= 1e-9


class _Blocks:
    """`MakespanCost.estimate` and `fits` of the contiguous blocks lanes[i:j] of one lane
    list in O(1) each (prefix sums per worker, built once): the partition search asks
    for them hundreds of thousands of times. The same arithmetic as the cost's own
    methods, which a subclass of MakespanCost may override: then those are called."""

    def __init__(self, lanes: Sequence[Lane], cost: MakespanCost) -> None:
        self.lanes = lanes
        self.cost = cost
        self.fast = type(cost) is MakespanCost
        self._cut = dict(cost.budget_cut)
        self._until: dict[tuple[int, int], int] = {}
        self._tables: dict[int, tuple[list[float], list[float], list[float], list[float]]] = {}

    def _table(self, w: Worker) -> tuple[list[float], list[float], list[float], list[float]]:
        t = self._tables.get(w.vehicle_id)
        if t is None:
            a, v = w.accel_m_s2, w.speed_m_s
            prefix = [0.0, *itertools.accumulate(leg_s(ln.length_m, v, a) for ln in self.lanes)]
            approach = [0.0] * len(self.lanes)
            if w.start is not None:
                sx, sy = w.start.x, w.start.y
                approach = [
                    leg_s(math.hypot(ln.a[0] - sx, ln.a[1] - sy), v, a) for ln in self.lanes
                ]
            back_a = [w.return_s(ln.a) for ln in self.lanes]
            back_b = [w.return_s(ln.b) for ln in self.lanes]
            t = self._tables[w.vehicle_id] = (prefix, approach, back_a, back_b)
        return t

    def estimate(self, i: int, j: int, w: Worker) -> float:
        if not self.fast:
            return self.cost.estimate(self.lanes[i:j], w)
        if j <= i:
            return 0.0
        prefix, approach, _ba, _bb = self._table(w)
        t = (prefix[j] - prefix[i]) + self.cost.allowance_m(w) * (j - i - 1) / w.speed_m_s
        return t + approach[i] + w.extra_s

    def fill(self, i: int, w: Worker, limit: float) -> int:
        """The greedy fill from lane i: the largest j >= i such that every block
        lanes[i:j'] with i < j' <= j is within `limit` by the estimate and fits the
        budget (the first j' that fails stops it)."""
        n = len(self.lanes)
        if not self.fast:
            j = i
            while j < n and self.estimate(i, j + 1, w) <= limit and self.fits(i, j + 1, w):
                j += 1
            return j
        # the estimate grows with j: bisect; the budget check does not depend on the
        # limit: its first failure from i is found once
        if i >= n:
            return i
        prefix, approach, _ba, _bb = self._table(w)
        allow, v, pi, ap, ex = (
            self.cost.allowance_m(w),
            w.speed_m_s,
            prefix[i],
            approach[i],
            w.extra_s,
        )
        lo, hi = i, n  # est(i, lo) <= limit (lo == i: the empty block)
        while lo < hi:
            mid = (lo + hi + 1) // 2
            # `estimate(i, mid, w)`, inlined (the same arithmetic)
            if (prefix[mid] - pi) + allow * (mid - i - 1) / v + ap + ex <= limit:
                lo = mid
            else:
                hi = mid - 1
        return min(lo, self._fits_until(i, w))

    def _fits_until(self, i: int, w: Worker) -> int:
        """The largest j such that every block lanes[i:j'] with i < j' <= j fits."""
        key = (w.vehicle_id, i)
        got = self._until.get(key)
        if got is None:
            n = len(self.lanes)
            got = i
            if math.isinf(w.budget_s):
                got = n
            else:
                while got < n and self.fits(i, got + 1, w):
                    got += 1
            self._until[key] = got
        return got

    def fits(self, i: int, j: int, w: Worker) -> bool:
        if not self.fast:
            return self.cost.fits(self.lanes[i:j], w)
        if j <= i or math.isinf(w.budget_s):
            return True
        _p, _a, back_a, back_b = self._table(w)
        back = max(back_a[i], back_b[i], back_a[j - 1], back_b[j - 1])
        budget = w.budget_s - self._cut.get(w.vehicle_id, 0.0)
        return self.estimate(i, j, w) + back <= budget


def sweep_sorted(lanes: Sequence[Lane]) -> list[Lane]:
    """Lanes in sweep order: by line, then along the line."""

    def key(ln: Lane) -> tuple[int, float]:
        c, s = math.cos(ln.yaw), math.sin(ln.yaw)
        return ln.line, min(ln.a[0] * c + ln.a[1] * s, ln.b[0] * c + ln.b[1] * s)

    return sorted(lanes, key=key)


def _greedy(blocks: _Blocks, ws: Sequence[Worker], limit: float) -> list[int] | None:
    """Block boundaries filling each worker up to `limit` seconds, or None."""
    n = len(blocks.lanes)
    bounds = [0]
    i = 0
    for k, w in enumerate(ws):
        j = i
        if k == len(ws) - 1:
            j = n
            if blocks.estimate(i, j, w) > limit or not blocks.fits(i, j, w):
                return None
        else:
            j = blocks.fill(i, w, limit)
        bounds.append(j)
        i = j
    return bounds


def _partition(
    blocks: _Blocks, ws: Sequence[Worker], cost: MakespanCost
) -> tuple[float, list[int]] | None:
    """The least makespan limit (by the estimate) the greedy fill meets, and its block
    boundaries; None when the budgets leave lanes over at any limit."""
    hi = max(blocks.estimate(0, len(blocks.lanes), w) for w in ws)
    lo = 0.0
    best = _greedy(blocks, ws, hi)
    if best is None:
        return None
    for _ in range(40):
        mid = (lo + hi) / 2.0
        got = _greedy(blocks, ws, mid)
        if got is None:
            lo = mid
        else:
            hi, best = mid, got
    return hi, best


def _arrangements(workers: Sequence[Worker]) -> list[tuple[Worker, ...]]:
    if len(workers) <= 6 and all(w.start is None for w in workers):
        # only distinct classes matter when nobody has a position
        seen: dict[tuple[tuple[float, ...], ...], tuple[Worker, ...]] = {}
        for p in itertools.permutations(workers):
            key = tuple(
                (w.speed_m_s, w.turns.radius_m, w.accel_m_s2, w.extra_s, w.budget_s) for w in p
            )
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
        cost = MakespanCost(None, obstacles)
    if not ordered:
        return SplitPlan(
            tuple(Assignment(w.vehicle_id, w.speed_m_s, CoveragePath((), ())) for w in workers)
        )
    bounds, arr = _best_bounds(ordered, workers, cost)
    blocks = [list(ordered[bounds[k] : bounds[k + 1]]) for k in range(len(arr))]
    if cut_lanes:
        blocks = _cut_boundaries(blocks, arr, cost)
    assigned = {w.vehicle_id: cost.final(b, w) for w, b in zip(arr, blocks, strict=True)}
    return SplitPlan(tuple(assigned[w.vehicle_id] for w in workers))


#: partitions made again with the budgets the estimate overran tightened
_BUDGET_ROUNDS = 4


def _best_bounds(
    ordered: Sequence[Lane], workers: Sequence[Worker], cost: MakespanCost
) -> tuple[list[int], tuple[Worker, ...]]:
    """The block boundaries and arrangement of the least makespan with every block and
    its way home within its worker's budget. The greedy fill checks budgets on the
    estimate; where the exact time overruns one, that worker's budget is tightened by
    the overrun for the estimate and the partition made again."""
    cut: dict[int, float] = {}
    worst = 0.0
    for _ in range(_BUDGET_ROUNDS):
        c = dataclasses.replace(cost, budget_cut=tuple(sorted(cut.items())))
        blocks = _Blocks(ordered, c)
        parts = [(_partition(blocks, arr, c), arr) for arr in _arrangements(workers)]
        scored = sorted(
            ((p[0], p[1], arr) for p, arr in parts if p is not None), key=lambda t: t[0]
        )
        if not scored:
            break
        best: tuple[tuple[float, float], list[int], tuple[Worker, ...]] | None = None
        for _est, bounds, arr in scored[:3]:
            bounds, span = _refine(ordered, arr, cost, bounds)
            if best is None or span < best[0]:
                best = (span, bounds, arr)
        assert best is not None
        (worst, _span), bounds, arr = best
        if worst <= 0.0:
            return bounds, arr
        for k, w in enumerate(arr):
            a = cost.assignment(ordered[bounds[k] : bounds[k + 1]], w)
            over = cost.overrun_s(a, w)
            if over > 0.0:
                cut[w.vehicle_id] = cut.get(w.vehicle_id, 0.0) + over + 1.0
    budgets = ", ".join(
        f"vehicle {w.vehicle_id} {w.budget_s:.0f} s" for w in workers if math.isfinite(w.budget_s)
    )
    short = f" (short by {worst:.0f} s)" if worst > 0.0 else ""
    exc = InfeasibleTimingError(
        f"the vehicles' endurance does not cover the area{short}: at cruise, {budgets}"
    )
    exc.detail = _shortfall(ordered, workers, cost)
    raise exc


def _shortfall(
    ordered: Sequence[Lane], workers: Sequence[Worker], cost: MakespanCost
) -> ReasonDetail:
    """What the area asks of each vehicle against what it has, for people: an even
    split of the lanes (in sweep order), each block with the way home by the estimate,
    against the battery's budget, both averaged over the vehicles with a budget (one
    vehicle: its own figures)."""
    limited = [w for w in workers if math.isfinite(w.budget_s)]
    n, k = len(workers), len(ordered)
    needs, budgets = [], []
    for idx, w in enumerate(workers):
        if not math.isfinite(w.budget_s):
            continue
        block = ordered[round(idx * k / n) : round((idx + 1) * k / n)] or ordered[-1:]
        back = max(w.return_s(p) for p in (block[0].a, block[0].b, block[-1].a, block[-1].b))
        needs.append(cost.estimate(block, w) + back)
        budgets.append(w.budget_s)
    if not needs:
        return ReasonDetail(DetailCode.ENDURANCE)
    one = limited[0].vehicle_id if len(workers) == 1 else 0
    return ReasonDetail(
        DetailCode.ENDURANCE,
        one if one <= 65534 else 0,
        needed_s=min(sum(needs) / len(needs), 1.0e7),
        available_s=min(sum(budgets) / len(budgets), 1.0e7),
    )


def _refine(
    lanes: Sequence[Lane], ws: Sequence[Worker], cost: MakespanCost, bounds: list[int]
) -> tuple[list[int], tuple[float, float]]:
    """Move block boundaries one lane at a time while the exact makespan drops."""
    memo: dict[tuple[int, int, int], tuple[float, float]] = {}

    def t(k: int, b: list[int]) -> tuple[float, float]:
        """By how much the block and the way home overrun the worker's budget, and the
        block's exact time."""
        key = (k, b[k], b[k + 1])
        if key not in memo:
            memo[key] = cost.timed(lanes[b[k] : b[k + 1]], ws[k])
        return memo[key]

    def span(b: list[int]) -> tuple[float, float]:
        """First the total overrun of the budgets, then the makespan."""
        ts = [t(k, b) for k in range(len(ws))]
        return round(sum(o for o, _ in ts), 6), max(x for _, x in ts)

    cur = span(bounds)
    for _ in range(4 * len(lanes) + 10):
        best_move: tuple[tuple[float, float], list[int]] | None = None
        for k in range(1, len(ws)):
            for step in (-1, 1):
                b = list(bounds)
                b[k] += step
                if not b[k - 1] <= b[k] <= b[k + 1]:
                    continue
                s = span(b)
                better = s[0] < cur[0] or (s[0] == cur[0] and s[1] < cur[1] - 1e-9)
                if better and (best_move is None or s < best_move[0]):
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
        tl0, tr0 = _timed(cost, left, ws[k]), _timed(cost, right, ws[k + 1])
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
            tl, tr = _timed(cost, lb, ws[k]), _timed(cost, rb, ws[k + 1])
            if max(tl, tr) < best[0]:
                best = (max(tl, tr), lb, rb)
            if tl < tr:
                lo = mid
            else:
                hi = mid
        blocks[k], blocks[k + 1] = best[1], best[2]
    return blocks


def _timed(cost: MakespanCost, block: Sequence[Lane], w: Worker) -> float:
    """The block's exact time, inf if it and the way home overrun the worker's budget."""
    over, t = cost.timed(block, w)
    return t if over <= 1e-9 else math.inf


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


def common_lanes(a: Sequence[Lane], b: Sequence[Lane], tol_m: float = 0.5) -> list[Lane]:
    """The parts of the lanes of `a` that `b` holds too (each a piece of the same sweep
    line): what neither of two partial records says was flown, when `a` and `b` are
    what is left of one area by two of them (pieces under 1 m dropped, as
    `remaining_lanes` drops them)."""
    out: list[Lane] = []
    for la in a:
        n = la.length_m
        if n <= 1e-9:
            continue
        ux, uy = (la.b[0] - la.a[0]) / n, (la.b[1] - la.a[1]) / n
        spans: list[tuple[float, float]] = []
        for lb in b:
            if lb.line != la.line or lb.gap != la.gap:
                continue
            # the same straight line: both ends of lb within tol of la's line
            off = [(p[0] - la.a[0]) * -uy + (p[1] - la.a[1]) * ux for p in (lb.a, lb.b)]
            if max(abs(off[0]), abs(off[1])) > tol_m:
                continue
            s0 = (lb.a[0] - la.a[0]) * ux + (lb.a[1] - la.a[1]) * uy
            s1 = (lb.b[0] - la.a[0]) * ux + (lb.b[1] - la.a[1]) * uy
            lo, hi = max(min(s0, s1), 0.0), min(max(s0, s1), n)
            if hi - lo > 1.0:
                spans.append((lo, hi))
        for lo, hi in _union(spans):
            start, end = la.cut(lo / n)[1], la.cut(hi / n)[0]
            out.append(Lane(la.line, start.a, end.b, la.gap))
    return out


def _union(spans: list[tuple[float, float]]) -> list[tuple[float, float]]:
    merged: list[tuple[float, float]] = []
    for lo, hi in sorted(spans):
        if merged and lo <= merged[-1][1]:
            merged[-1] = (merged[-1][0], max(merged[-1][1], hi))
        else:
            merged.append((lo, hi))
    return merged


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
