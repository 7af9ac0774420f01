"""Shared pieces of the formation planners (target, perimeter, objective, MUM-T):
equal spacing on a cycle, order-preserving slot assignment, and re-spacing when the
number of vehicles changes."""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from .errors import InfeasibleTimingError, InvalidParameterError, NoVehiclesError
from .vehicles import PlanVehicle


def cyclic_slots(positions: Mapping[int, float], period: float) -> dict[int, float]:
    """Equally spaced targets on a cycle of length `period` for the vehicles at
    `positions` (each in [0, period)), keeping their cyclic order (so their paths do
    not cross) and rotating the pattern to minimize the largest move."""
    if not positions:
        return {}
    if not (math.isfinite(period) and period > 0.0):
        raise InvalidParameterError(f"cycle length must be > 0, got {period}")
    ids = sorted(positions, key=lambda v: positions[v] % period)
    n = len(ids)
    gap = period / n
    pos = np.array([positions[v] % period for v in ids])
    best: tuple[float, float] | None = None
    for shift in range(n):
        k = (np.arange(n) + shift) % n
        base = pos - k * gap  # the offset each vehicle would like
        # circular mean of the wanted offsets, on the cycle of length gap
        ang = 2 * math.pi * base / gap
        off = (math.atan2(np.sin(ang).mean(), np.cos(ang).mean()) * gap / (2 * math.pi)) % gap
        moves = np.abs(np.remainder(pos - (off + k * gap) + period / 2, period) - period / 2)
        cost = float(moves.max())
        if best is None or cost < best[0] - 1e-9:
            best = (cost, off, shift)  # type: ignore[assignment]
    assert best is not None
    _c, off, shift = best  # type: ignore[misc]
    return {v: (off + ((i + shift) % n) * gap) % period for i, v in enumerate(ids)}


@dataclass(frozen=True, slots=True)
class Trim:
    """How a vehicle on a cycle reaches its new slot: fly at `speed_m_s` for `settle_s`
    (then back to the common speed)."""

    vehicle_id: int
    target: float  # new position on the cycle
    move: float  # signed distance along the cycle (+ = ahead)
    speed_m_s: float
    settle_s: float


def respace(
    positions: Mapping[int, float],
    period: float,
    speed_m_s: float,
    speed_ranges: Mapping[int, tuple[float, float]],
) -> dict[int, Trim]:
    """Re-space vehicles moving along a cycle at a common `speed_m_s` after one joined or
    left: equal spacing, order kept, and a speed trim per vehicle so all reach their
    new slots together, as soon as their speed ranges allow.

    The equally spaced pattern (`cyclic_slots`) may be rotated by some delta: each
    vehicle v then moves m_v = d_v + delta relative to the common speed, which takes
    T >= m_v / (hi_v - speed) ahead or |m_v| / (speed - lo_v) behind. The least T for
    which some delta fits every vehicle is max over pairs (u, w) of
    (d_w - d_u) / (room ahead of w + room behind u); delta is the one nearest 0 (the
    pattern that needs the least move) that fits. So a fixed-wing already at the top
    of its range on this cycle is never asked to speed up: the others slow down."""
    slots = cyclic_slots(positions, period)
    for v in slots:
        lo, hi = speed_ranges[v]
        if not lo - 1e-9 <= speed_m_s <= hi + 1e-9:
            raise InfeasibleTimingError(
                f"vehicle {v} cannot fly the common {speed_m_s:.1f} m/s "
                f"(its range here is {lo:.1f}-{hi:.1f} m/s)"
            )
    d = {
        v: float(np.remainder(slots[v] - positions[v] % period + period / 2, period) - period / 2)
        for v in slots
    }
    up = {v: max(speed_ranges[v][1] - speed_m_s, 0.0) for v in slots}
    down = {v: max(speed_m_s - speed_ranges[v][0], 0.0) for v in slots}
    settle = 0.0
    for u in slots:
        for w in slots:
            gap = d[w] - d[u]
            if gap <= 1e-9:
                continue
            room = up[w] + down[u]
            if room <= 1e-12:
                raise InfeasibleTimingError(
                    f"vehicles {u} and {w} cannot change speed from {speed_m_s:.1f} m/s to re-space"
                )
            settle = max(settle, gap / room)
    if settle <= 0.0:  # everyone is already in place (up to a common rotation)
        delta = -next(iter(d.values())) if d else 0.0
        return {v: Trim(v, (slots[v] + delta) % period, 0.0, speed_m_s, 0.0) for v in slots}
    lo_d = max(-down[v] * settle - d[v] for v in slots)
    hi_d = min(up[v] * settle - d[v] for v in slots)
    delta = min(max(0.0, lo_d), max(lo_d, hi_d))
    out = {}
    for v in slots:
        move = d[v] + delta
        out[v] = Trim(v, (slots[v] + delta) % period, move, speed_m_s + move / settle, settle)
    return out


def speed_ranges_on(
    vehicles: Sequence[PlanVehicle], ids: Iterable[int], radius_m: float
) -> dict[int, tuple[float, float]]:
    """Speed range of each vehicle in `ids` on a cycle whose tightest turn has
    `radius_m` (`PlanVehicle.speed_range_on`); `NoVehiclesError` for an unknown id."""
    by_id = {v.vehicle_id: v for v in vehicles}
    out = {}
    for i in ids:
        if i not in by_id:
            raise NoVehiclesError(f"vehicle {i} is on the cycle but not among the vehicles")
        out[i] = by_id[i].speed_range_on(radius_m)
    return out


def assign_min_cost(cost: np.ndarray) -> list[int]:
    """Row -> column assignment with the least total cost (rows <= columns): exact for
    up to 7 rows, greedy plus pairwise swaps beyond."""
    n, m = cost.shape
    if n > m:
        raise InvalidParameterError("more vehicles than slots")
    if n <= 7 and m <= 8:
        best: tuple[float, tuple[int, ...]] | None = None
        for cols in itertools.permutations(range(m), n):
            c = float(sum(cost[i, j] for i, j in enumerate(cols)))
            if best is None or c < best[0]:
                best = (c, cols)
        assert best is not None
        return list(best[1])
    out = [-1] * n
    used: set[int] = set()
    for flat in np.argsort(cost, axis=None):
        i, j = divmod(int(flat), m)
        if out[i] < 0 and j not in used:
            out[i] = j
            used.add(j)
    improved = True
    while improved:
        improved = False
        for a in range(n):
            for b in range(a + 1, n):
                if cost[a, out[b]] + cost[b, out[a]] < cost[a, out[a]] + cost[b, out[b]] - 1e-9:
                    out[a], out[b] = out[b], out[a]
                    improved = True
    return out
