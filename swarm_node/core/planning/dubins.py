"""Exact Dubins paths (all six words) for one pair of poses, and a vectorized numpy batch
form for many pairs at once.

Poses are local ENU metres and yaw in radians, counter-clockwise from east (+x). The
formulas are those of Shkel & Lumelsky (2001), in the normalized form OMPL uses: the
distance `d` and the angles `alpha`, `beta` relative to the line joining the two
positions. Segment lengths `t, p, q` are in units of the turn radius; `DubinsPath`
exposes them in metres.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import IntEnum

import numpy as np
import numpy.typing as npt

from .errors import InvalidParameterError

TWO_PI = 2.0 * math.pi
_EPS = 1e-6  # below this, a start and goal pose are the same pose
_ZERO = -1e-7  # tiny negative angles are rounding, not a full turn

FloatArray = npt.NDArray[np.float64]


class Word(IntEnum):
    """The six Dubins words; L = left (counter-clockwise), R = right, S = straight."""

    LSL = 0
    RSR = 1
    RSL = 2
    LSR = 3
    RLR = 4
    LRL = 5

    @property
    def segments(self) -> str:
        return self.name


@dataclass(frozen=True, slots=True)
class Pose:
    """A local pose: x east, y north (metres), yaw counter-clockwise from east (rad)."""

    x: float
    y: float
    yaw: float

    def forward(self, dist_m: float) -> Pose:
        return Pose(
            self.x + dist_m * math.cos(self.yaw), self.y + dist_m * math.sin(self.yaw), self.yaw
        )


def mod2pi(x: float) -> float:
    """x in [0, 2 pi), with rounding noise next to 0 and 2 pi snapped to 0."""
    if _ZERO < x < 0.0:
        return 0.0
    xm = x - TWO_PI * math.floor(x / TWO_PI)
    if TWO_PI - xm < 0.5 * _EPS:
        return 0.0
    return xm


def _words(d: float, alpha: float, beta: float) -> list[tuple[Word, float, float, float]]:
    """Every feasible word with its normalized (t, p, q)."""
    ca, sa, cb, sb = math.cos(alpha), math.sin(alpha), math.cos(beta), math.sin(beta)
    cab = ca * cb + sa * sb
    out: list[tuple[Word, float, float, float]] = []
    tmp = 2.0 + d * d - 2.0 * (cab - d * (sa - sb))
    if tmp >= 0.0:
        theta = math.atan2(cb - ca, d + sa - sb)
        out.append((Word.LSL, mod2pi(-alpha + theta), math.sqrt(tmp), mod2pi(beta - theta)))
    tmp = 2.0 + d * d - 2.0 * (cab - d * (sb - sa))
    if tmp >= 0.0:
        theta = math.atan2(ca - cb, d - sa + sb)
        out.append((Word.RSR, mod2pi(alpha - theta), math.sqrt(tmp), mod2pi(-beta + theta)))
    tmp = d * d - 2.0 + 2.0 * (cab - d * (sa + sb))
    if tmp >= 0.0:
        p = math.sqrt(tmp)
        theta = math.atan2(ca + cb, d - sa - sb) - math.atan2(2.0, p)
        out.append((Word.RSL, mod2pi(alpha - theta), p, mod2pi(beta - theta)))
    tmp = -2.0 + d * d + 2.0 * (cab + d * (sa + sb))
    if tmp >= 0.0:
        p = math.sqrt(tmp)
        theta = math.atan2(-ca - cb, d + sa + sb) - math.atan2(-2.0, p)
        out.append((Word.LSR, mod2pi(-alpha + theta), p, mod2pi(-beta + theta)))
    tmp = 0.125 * (6.0 - d * d + 2.0 * (cab + d * (sa - sb)))
    if abs(tmp) < 1.0:
        p = TWO_PI - math.acos(tmp)
        theta = math.atan2(ca - cb, d - sa + sb)
        t = mod2pi(alpha - theta + 0.5 * p)
        out.append((Word.RLR, t, p, mod2pi(alpha - beta - t + p)))
    tmp = 0.125 * (6.0 - d * d + 2.0 * (cab - d * (sa - sb)))
    if abs(tmp) < 1.0:
        p = TWO_PI - math.acos(tmp)
        theta = math.atan2(-ca + cb, d + sa - sb)
        t = mod2pi(-alpha + theta + 0.5 * p)
        out.append((Word.LRL, t, p, mod2pi(beta - alpha - t + p)))
    return out


@dataclass(frozen=True, slots=True)
class DubinsPath:
    """The shortest path from `start` to a goal pose with turn radius `radius_m`."""

    start: Pose
    word: Word
    t: float  # normalized segment lengths (radians for turns, radius units for S)
    p: float
    q: float
    radius_m: float

    @property
    def segment_lengths_m(self) -> tuple[float, float, float]:
        r = self.radius_m
        return (self.t * r, self.p * r, self.q * r)

    @property
    def length_m(self) -> float:
        return (self.t + self.p + self.q) * self.radius_m

    def pose_at(self, s_m: float) -> Pose:
        """The pose `s_m` metres along the path (clamped to [0, length])."""
        r = self.radius_m
        seg = min(max(s_m, 0.0), self.length_m) / r if r > 0 else 0.0
        x, y, phi = 0.0, 0.0, self.start.yaw
        for kind, length in zip(self.word.segments, (self.t, self.p, self.q), strict=True):
            if seg <= 0.0:
                break
            v = min(seg, length)
            seg -= v
            if kind == "L":
                x, y, phi = (
                    x + math.sin(phi + v) - math.sin(phi),
                    y - math.cos(phi + v) + math.cos(phi),
                    phi + v,
                )
            elif kind == "R":
                x, y, phi = (
                    x - math.sin(phi - v) + math.sin(phi),
                    y + math.cos(phi - v) - math.cos(phi),
                    phi - v,
                )
            else:
                x, y = x + v * math.cos(phi), y + v * math.sin(phi)
        return Pose(self.start.x + x * r, self.start.y + y * r, math.remainder(phi, TWO_PI))

    @property
    def end(self) -> Pose:
        return self.pose_at(self.length_m)

    def sample(self, step_m: float) -> list[Pose]:
        """Poses every `step_m` metres, start and end included."""
        n = max(1, math.ceil(self.length_m / step_m))
        return [self.pose_at(self.length_m * i / n) for i in range(n + 1)]

    def sample_xy(self, step_m: float) -> FloatArray:
        """Positions every `step_m` metres, start and end included, as an (n, 2) array
        (vectorized: the same points as `sample`)."""
        r = self.radius_m
        n = max(1, math.ceil(self.length_m / step_m))
        s = np.linspace(0.0, self.length_m, n + 1) / r if r > 0 else np.zeros(n + 1)
        out = np.empty((n + 1, 2))
        x0, y0, phi = self.start.x, self.start.y, self.start.yaw
        lo = 0.0
        for i, (kind, length) in enumerate(
            zip(self.word.segments, (self.t, self.p, self.q), strict=True)
        ):
            hi = lo + length
            m = (s >= lo) & ((s < hi) | (i == 2))
            v = np.clip(s[m] - lo, 0.0, length)
            if kind == "L":
                out[m, 0] = x0 + r * (np.sin(phi + v) - math.sin(phi))
                out[m, 1] = y0 - r * (np.cos(phi + v) - math.cos(phi))
            elif kind == "R":
                out[m, 0] = x0 - r * (np.sin(phi - v) - math.sin(phi))
                out[m, 1] = y0 + r * (np.cos(phi - v) - math.cos(phi))
            else:
                out[m, 0] = x0 + r * v * math.cos(phi)
                out[m, 1] = y0 + r * v * math.sin(phi)
            end = self.pose_at(hi * r)
            x0, y0, phi = end.x, end.y, end.yaw
            lo = hi
        return out

    def waypoints(self, max_turn_rad: float = math.pi / 6) -> list[Pose]:
        """Poses a waypoint follower needs: segment joints plus points every
        `max_turn_rad` of each arc (start excluded, goal included)."""
        return [self.pose_at(s) for s in self.waypoint_s(max_turn_rad)]

    def waypoint_s(self, max_turn_rad: float = math.pi / 6) -> list[float]:
        """Distances along the path (m) of the `waypoints`."""
        r = self.radius_m
        out: list[float] = []
        s0 = 0.0
        for kind, length in zip(self.word.segments, (self.t, self.p, self.q), strict=True):
            if length <= 0.0:
                continue
            n = 1 if kind == "S" else max(1, math.ceil(length / max_turn_rad))
            out += [(s0 + length * i / n) * r for i in range(1, n + 1)]
            s0 += length
        return out


def _check_radius(radius_m: float) -> None:
    if not (math.isfinite(radius_m) and radius_m > 0.0):
        raise InvalidParameterError(f"Dubins turn radius must be finite and > 0, got {radius_m}")


def shortest_path(start: Pose, goal: Pose, radius_m: float) -> DubinsPath:
    """The exact shortest Dubins path from `start` to `goal` (all six words compared)."""
    _check_radius(radius_m)
    for v in (start.x, start.y, start.yaw, goal.x, goal.y, goal.yaw):
        if not math.isfinite(v):
            raise InvalidParameterError("Dubins poses must be finite")
    dx, dy = goal.x - start.x, goal.y - start.y
    d = math.hypot(dx, dy) / radius_m
    th = math.atan2(dy, dx)
    alpha, beta = mod2pi(start.yaw - th), mod2pi(goal.yaw - th)
    if d < _EPS and abs(alpha - beta) < _EPS:
        return DubinsPath(start, Word.LSL, 0.0, d, 0.0, radius_m)
    best = min(_words(d, alpha, beta), key=lambda w: w[1] + w[2] + w[3])
    return DubinsPath(start, best[0], best[1], best[2], best[3], radius_m)


def all_paths(start: Pose, goal: Pose, radius_m: float) -> list[DubinsPath]:
    """Every feasible Dubins word from `start` to `goal`, shortest first (for callers
    that must reject some, e.g. those crossing a no-fly zone)."""
    _check_radius(radius_m)
    dx, dy = goal.x - start.x, goal.y - start.y
    d = math.hypot(dx, dy) / radius_m
    th = math.atan2(dy, dx)
    alpha, beta = mod2pi(start.yaw - th), mod2pi(goal.yaw - th)
    words = sorted(_words(d, alpha, beta), key=lambda w: w[1] + w[2] + w[3])
    return [DubinsPath(start, w, t, p, q, radius_m) for w, t, p, q in words]


def path_length(start: Pose, goal: Pose, radius_m: float) -> float:
    return shortest_path(start, goal, radius_m).length_m


# --------------------------------------------------------------------------- batch


def _mod2pi_v(x: FloatArray) -> FloatArray:
    xm = x - TWO_PI * np.floor(x / TWO_PI)
    xm = np.where((x < 0.0) & (x > _ZERO), 0.0, xm)
    return np.where(TWO_PI - xm < 0.5 * _EPS, 0.0, xm)


def batch_lengths(
    start: npt.ArrayLike, goal: npt.ArrayLike, radius_m: float, *, words: bool = False
) -> FloatArray | tuple[FloatArray, npt.NDArray[np.int8]]:
    """Shortest Dubins lengths (metres) for many pairs at once.

    `start` and `goal` are (..., 3) arrays of (x, y, yaw); they broadcast against each
    other, so a (n, 1, 3) start and a (1, m, 3) goal give an n x m cost matrix. With
    `words=True` also returns the `Word` of each path as int8.
    """
    _check_radius(radius_m)
    s = np.asarray(start, dtype=np.float64)
    g = np.asarray(goal, dtype=np.float64)
    dx = g[..., 0] - s[..., 0]
    dy = g[..., 1] - s[..., 1]
    d = np.hypot(dx, dy) / radius_m
    th = np.arctan2(dy, dx)
    alpha = _mod2pi_v(s[..., 2] - th)
    beta = _mod2pi_v(g[..., 2] - th)
    ca, sa, cb, sb = np.cos(alpha), np.sin(alpha), np.cos(beta), np.sin(beta)
    cab = ca * cb + sa * sb
    d2 = d * d
    inf = np.inf
    cand = np.empty((6, *d.shape))
    with np.errstate(invalid="ignore"):
        # LSL
        tmp = 2.0 + d2 - 2.0 * (cab - d * (sa - sb))
        theta = np.arctan2(cb - ca, d + sa - sb)
        cand[0] = np.where(
            tmp >= 0.0, _mod2pi_v(theta - alpha) + np.sqrt(tmp) + _mod2pi_v(beta - theta), inf
        )
        # RSR
        tmp = 2.0 + d2 - 2.0 * (cab - d * (sb - sa))
        theta = np.arctan2(ca - cb, d - sa + sb)
        cand[1] = np.where(
            tmp >= 0.0, _mod2pi_v(alpha - theta) + np.sqrt(tmp) + _mod2pi_v(theta - beta), inf
        )
        # RSL
        tmp = d2 - 2.0 + 2.0 * (cab - d * (sa + sb))
        p = np.sqrt(tmp)
        theta = np.arctan2(ca + cb, d - sa - sb) - np.arctan2(2.0, p)
        cand[2] = np.where(tmp >= 0.0, _mod2pi_v(alpha - theta) + p + _mod2pi_v(beta - theta), inf)
        # LSR
        tmp = -2.0 + d2 + 2.0 * (cab + d * (sa + sb))
        p = np.sqrt(tmp)
        theta = np.arctan2(-ca - cb, d + sa + sb) - np.arctan2(-2.0, p)
        cand[3] = np.where(tmp >= 0.0, _mod2pi_v(theta - alpha) + p + _mod2pi_v(theta - beta), inf)
        # RLR
        tmp = 0.125 * (6.0 - d2 + 2.0 * (cab + d * (sa - sb)))
        p = TWO_PI - np.arccos(tmp)
        theta = np.arctan2(ca - cb, d - sa + sb)
        t = _mod2pi_v(alpha - theta + 0.5 * p)
        cand[4] = np.where(np.abs(tmp) < 1.0, t + p + _mod2pi_v(alpha - beta - t + p), inf)
        # LRL
        tmp = 0.125 * (6.0 - d2 + 2.0 * (cab - d * (sa - sb)))
        p = TWO_PI - np.arccos(tmp)
        theta = np.arctan2(cb - ca, d + sa - sb)
        t = _mod2pi_v(theta - alpha + 0.5 * p)
        cand[5] = np.where(np.abs(tmp) < 1.0, t + p + _mod2pi_v(beta - alpha - t + p), inf)
    best = np.argmin(cand, axis=0)
    length = np.take_along_axis(cand, best[None, ...], axis=0)[0]
    same = (d < _EPS) & (np.abs(alpha - beta) < _EPS)
    length = np.where(same, d, length) * radius_m
    if words:
        return length, np.where(same, 0, best).astype(np.int8)
    return length
