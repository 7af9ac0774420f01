"""Separation analysis of a trajectory log, as the paper does it (section 4, tables 2
and 3): for every pair of vehicles, the 3-D distance at each time step, its minimum
and when, and how many samples fell in each band:

    risk        danger_m <= d < risk_m     (paper: 10-40 m)
    danger      near_m   <= d < danger_m   (paper: 5-10 m)
    near        d < near_m                 (paper: < 5 m, near-collision)

Distances are exact on the WGS84 ellipsoid: positions go to ECEF (pymap3d) and the
distance is the straight chord between them; altitudes are taken as heights.

Time steps: by default every distinct `time_s` of the file (a simulator writes every
vehicle at each step, so these are its steps); with `step_s`, a uniform grid. A vehicle
with no sample at a step is interpolated linearly (in ECEF) between its samples on
either side if they are at most `max_gap_s` apart; otherwise the pair has no sample
at that step. Pure: no I/O (the command in `analyze.py` reads and prints).
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from swarm_proto.geodesy import ecef_many
from swarm_proto.trajectory import Trajectory

FloatArray = npt.NDArray[np.float64]


class AnalysisError(ValueError):
    """The log cannot be analysed as asked (one line, for people)."""


@dataclass(frozen=True, slots=True)
class Thresholds:
    risk_m: float = 40.0
    danger_m: float = 10.0
    near_m: float = 5.0

    def __post_init__(self) -> None:
        if not (0.0 < self.near_m <= self.danger_m <= self.risk_m):
            raise AnalysisError(
                f"thresholds must be 0 < near <= danger <= risk, got near {self.near_m}, "
                f"danger {self.danger_m}, risk {self.risk_m}"
            )


@dataclass(frozen=True)
class PairSeparation:
    a: int
    b: int
    times_s: FloatArray  # the steps where both are known
    distances_m: FloatArray
    min_m: float
    min_time_s: float
    risk: int
    danger: int
    near: int

    @property
    def samples(self) -> int:
        return len(self.times_s)

    def as_dict(self) -> dict[str, Any]:
        return {
            "pair": f"{self.a}-{self.b}",
            "a": self.a,
            "b": self.b,
            "min_m": round(self.min_m, 3),
            "min_time_s": round(self.min_time_s, 3),
            "risk": self.risk,
            "danger": self.danger,
            "near": self.near,
            "samples": self.samples,
        }


@dataclass(frozen=True)
class SeparationReport:
    thresholds: Thresholds
    vehicles: tuple[int, ...]
    pairs: tuple[PairSeparation, ...] = field(default_factory=tuple)

    @property
    def min_sep_m(self) -> float:
        known = [p.min_m for p in self.pairs if p.samples]
        return min(known) if known else float("nan")

    def totals(self) -> dict[str, int]:
        return {
            "risk": sum(p.risk for p in self.pairs),
            "danger": sum(p.danger for p in self.pairs),
            "near": sum(p.near for p in self.pairs),
            "samples": sum(p.samples for p in self.pairs),
        }

    def as_dict(self) -> dict[str, Any]:
        closest = min((p for p in self.pairs if p.samples), key=lambda p: p.min_m, default=None)
        return {
            "thresholds": {
                "risk_m": self.thresholds.risk_m,
                "danger_m": self.thresholds.danger_m,
                "near_m": self.thresholds.near_m,
            },
            "vehicles": list(self.vehicles),
            "pairs": [p.as_dict() for p in self.pairs],
            "totals": self.totals(),
            "min_sep_m": None if closest is None else round(closest.min_m, 3),
            "min_pair": None if closest is None else f"{closest.a}-{closest.b}",
            "min_time_s": None if closest is None else round(closest.min_time_s, 3),
        }


def classify(d: FloatArray, th: Thresholds) -> tuple[int, int, int]:
    """(risk, danger, near) sample counts."""
    near = int(np.count_nonzero(d < th.near_m))
    danger = int(np.count_nonzero((d >= th.near_m) & (d < th.danger_m)))
    risk = int(np.count_nonzero((d >= th.danger_m) & (d < th.risk_m)))
    return risk, danger, near


def _ecef_at(
    tr: Trajectory, vehicle: int, grid: FloatArray, max_gap_s: float
) -> tuple[FloatArray, npt.NDArray[np.bool_]]:
    sel = tr.vehicle == vehicle
    t = tr.time_s[sel]
    order = np.argsort(t, kind="stable")
    t = t[order]
    xyz = ecef_many(tr.lat[sel][order], tr.lon[sel][order], tr.alt_m[sel][order])
    # one sample per time: the last one written
    keep = np.append(t[1:] != t[:-1], True)
    t, xyz = t[keep], xyz[keep]
    out = np.stack([np.interp(grid, t, xyz[:, k]) for k in range(3)], -1)
    hi = np.searchsorted(t, grid, side="left")
    exact = (hi < len(t)) & (t[np.minimum(hi, len(t) - 1)] == grid)
    inside = (grid >= t[0]) & (grid <= t[-1])
    lo = np.clip(hi - 1, 0, len(t) - 1)
    gap = t[np.clip(hi, 0, len(t) - 1)] - t[lo]
    valid = exact | (inside & (gap <= max_gap_s))
    return out, valid


def analyze(
    tr: Trajectory,
    thresholds: Thresholds | None = None,
    *,
    vehicles: Sequence[int] | None = None,
    step_s: float | None = None,
    max_gap_s: float = 2.0,
) -> SeparationReport:
    th = thresholds or Thresholds()
    present = tr.vehicles
    if vehicles:
        unknown = sorted(set(vehicles) - set(present))
        if unknown:
            raise AnalysisError(
                f"vehicle(s) {', '.join(map(str, unknown))} not in the log "
                f"(it has {', '.join(map(str, present))})"
            )
        chosen = sorted(set(vehicles))
    else:
        chosen = present
    if len(chosen) < 2:
        raise AnalysisError(f"need two vehicles or more, the log has {len(chosen)}")
    if step_s is not None:
        if not step_s > 0:
            raise AnalysisError(f"step must be positive, got {step_s}")
        t0, t1 = float(tr.time_s.min()), float(tr.time_s.max())
        grid = (t0 + step_s * np.arange(int(np.floor((t1 - t0) / step_s + 1e-9)) + 1)).astype(
            np.float64
        )
    else:
        grid = np.unique(tr.time_s[np.isin(tr.vehicle, chosen)]).astype(np.float64)
    states = {v: _ecef_at(tr, v, grid, max_gap_s) for v in chosen}
    pairs = []
    for a, b in itertools.combinations(chosen, 2):
        (pa, va), (pb, vb) = states[a], states[b]
        both = va & vb
        d = np.linalg.norm(pa[both] - pb[both], axis=1)
        times = grid[both]
        if len(d):
            i = int(np.argmin(d))
            mn, when = float(d[i]), float(times[i])
        else:
            mn, when = float("nan"), float("nan")
        risk, danger, near = classify(d, th)
        pairs.append(PairSeparation(a, b, times, d, mn, when, risk, danger, near))
    return SeparationReport(th, tuple(chosen), tuple(pairs))
