"""Area coverage as a pipeline of plain functions over frozen types (paper section 2.3.5,
"rotation-optimized boustrophedon"; shape after Fields2Cover):

    decompose -> sweep_angle -> lanes -> order -> connect -> (waypoints: see plans.py)

- `decompose` turns the mission polygon (holes) and the no-fly zones into a `Region`:
  what must be seen (shell - holes - zones) and what must never be entered (the zones
  inflated by their margin).
- `lane_spacing_m` is the camera footprint width times (1 - side overlap).
- `sweep_angle` searches the region's edge directions, then refines the best ones by a
  shrinking local search (not a 1-degree brute force), minimizing a `SweepCost`.
- `lanes` cuts the region with parallel lines at the lane spacing, centred so the swaths
  tile the region's width; each lane is extended to cover its whole swath strip and is
  clipped so it never enters a zone.
- `order` finds a turn-radius-aware order of the lanes (each flown in either direction)
  with the vehicle's `TurnModel`: seeds of the boustrophedon and skip patterns (a lane
  is skipped when the spacing is < 2R and the U-turn to a farther lane is shorter)
  improved by or-opt and 2-opt moves over the exact transition-cost matrix.
- `connect` joins the ordered lanes with the turn model's transitions and reroutes a
  transition around the zones when it would cross one.
"""

from __future__ import annotations

import collections
import functools
import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt
import shapely
import shapely.affinity
import shapely.errors
from shapely.geometry import LineString, MultiPolygon, Polygon
from shapely.geometry.base import BaseGeometry

from .dubins import FloatArray, Pose, batch_lengths, shortest_path
from .errors import EmptyAreaError, FieldTooBigError, InvalidGeometryError, InvalidParameterError
from .geo import validated_polygon
from .turns import DubinsTurns, PointTurns, TurnModel
from .zones import ARC_STEP_M, Obstacles, ZoneSet

XY = tuple[float, float]

# --------------------------------------------------------------------------- types


@dataclass(frozen=True, slots=True)
class Region:
    """What to cover and what never to enter, in the local frame."""

    cover: Polygon | MultiPolygon  # shell - holes - zones
    keep_out: BaseGeometry  # zones inflated by their margin (may be empty)
    polygon: Polygon | MultiPolygon  # shell - holes (before zones)
    obstacles: Obstacles  # the keep-out with its visibility graph, for transitions
    target: Polygon | MultiPolygon  # what coverage is measured on: cover - keep-out


@dataclass(frozen=True, slots=True)
class Lane:
    """A straight sweep leg from `a` to `b` (it may be flown either way)."""

    line: int  # index of the sweep line (lanes on one line share it; a gap lane: the nearest)
    a: XY
    b: XY
    gap: bool = False  # a gap lane (`fill_gaps`): off the sweep grid, maybe across it

    @property
    def length_m(self) -> float:
        return math.hypot(self.b[0] - self.a[0], self.b[1] - self.a[1])

    @property
    def yaw(self) -> float:
        return math.atan2(self.b[1] - self.a[1], self.b[0] - self.a[0])

    def reversed(self) -> Lane:
        return Lane(self.line, self.b, self.a, self.gap)

    def start_pose(self) -> Pose:
        return Pose(self.a[0], self.a[1], self.yaw)

    def end_pose(self) -> Pose:
        return Pose(self.b[0], self.b[1], self.yaw)

    def cut(self, fraction: float) -> tuple[Lane, Lane]:
        """The lane split at `fraction` of its length (done part, remaining part)."""
        f = min(max(fraction, 0.0), 1.0)
        m = (self.a[0] + f * (self.b[0] - self.a[0]), self.a[1] + f * (self.b[1] - self.a[1]))
        return Lane(self.line, self.a, m, self.gap), Lane(self.line, m, self.b, self.gap)


@dataclass(frozen=True, slots=True)
class Leg:
    """A piece of a connected path: a lane (camera on) or a transition (camera off)."""

    points: tuple[XY, ...]
    length_m: float
    is_lane: bool


@dataclass(frozen=True, slots=True)
class CoveragePath:
    """Ordered lanes joined by transitions."""

    lanes: tuple[Lane, ...]  # in flight order and direction
    legs: tuple[Leg, ...]

    @property
    def length_m(self) -> float:
        return sum(leg.length_m for leg in self.legs)

    @property
    def lane_length_m(self) -> float:
        return sum(leg.length_m for leg in self.legs if leg.is_lane)

    def points(self) -> list[XY]:
        out: list[XY] = []
        for leg in self.legs:
            for p in leg.points:
                if not out or out[-1] != p:
                    out.append(p)
        return out


# --------------------------------------------------------------------------- stages


def lane_spacing_m(altitude_m: float, hfov_deg: float, side_overlap: float) -> float:
    """Distance between adjacent lanes: footprint width 2 h tan(HFOV/2) times (1 - overlap)."""
    if not (math.isfinite(altitude_m) and altitude_m > 0.0):
        raise InvalidParameterError(f"altitude must be > 0, got {altitude_m}")
    if not (math.isfinite(hfov_deg) and 0.0 < hfov_deg < 180.0):
        raise InvalidParameterError(f"camera HFOV must be in (0, 180) deg, got {hfov_deg}")
    if not (math.isfinite(side_overlap) and 0.0 <= side_overlap < 1.0):
        raise InvalidParameterError(f"side overlap must be in [0, 1), got {side_overlap}")
    footprint = 2.0 * altitude_m * math.tan(math.radians(hfov_deg) / 2.0)
    return footprint * (1.0 - side_overlap)


def decompose(
    polygon: Polygon | MultiPolygon, zones: ZoneSet | None = None, alt_m: float | None = None
) -> Region:
    """The region to cover: `polygon` (holes are not covered) minus the zones that apply
    at `alt_m`; the keep-out is those zones inflated by the zone set's margin."""
    poly = validated_polygon(polygon)
    zones = zones or ZoneSet()
    raw = zones.raw(alt_m)
    cover = poly.difference(raw) if not raw.is_empty else poly
    cover = _polygonal(cover)
    if cover.is_empty or cover.area < 1e-6 * max(poly.area, 1.0):
        raise EmptyAreaError("nothing to cover: the area is entirely inside no-fly zones")
    keep = zones.keep_out(alt_m)
    target = cover
    if zones.margin_m > 0.0 and not keep.is_empty:
        # the band within the margin of a zone is seen only incidentally: lanes stop at
        # the keep-out, and most of the band is out of reach of their swaths
        target = _polygonal(cover.difference(keep))
        if target.is_empty or target.area < 1e-6 * max(poly.area, 1.0):
            raise EmptyAreaError("nothing to cover outside the no-fly zones' margins")
    return Region(cover, keep, poly, Obstacles(keep, raw), target)


def _polygonal(g: BaseGeometry) -> Polygon | MultiPolygon:
    if isinstance(g, Polygon | MultiPolygon):
        return g
    polys = [p for p in getattr(g, "geoms", []) if isinstance(p, Polygon) and p.area > 0]
    return MultiPolygon(polys)


def _rings(g: BaseGeometry) -> list[FloatArray]:
    out: list[FloatArray] = []
    for p in getattr(g, "geoms", [g]):
        if isinstance(p, Polygon) and not p.is_empty:
            out.append(np.asarray(p.exterior.coords))
            out += [np.asarray(r.coords) for r in p.interiors]
    return out


def _edges(rings: Sequence[FloatArray]) -> FloatArray:
    if not rings:
        return np.zeros((0, 4))
    return np.concatenate([np.hstack([r[:-1], r[1:]]) for r in rings])


# The edges of recent geometries (keyed by identity; the entry keeps the geometry alive):
# every lane set of a plan is cut from the same region's edges
_EDGES: collections.OrderedDict[int, tuple[BaseGeometry, FloatArray]] = collections.OrderedDict()


def _edges_of(g: BaseGeometry) -> FloatArray:
    got = _EDGES.get(id(g))
    if got is not None and got[0] is g:
        return got[1]
    edges = _edges(_rings(g))
    edges.flags.writeable = False
    _EDGES[id(g)] = (g, edges)
    while len(_EDGES) > 16:
        _EDGES.popitem(last=False)
    return edges


def _rotate(edges: FloatArray, angle: float) -> FloatArray:
    """Edges rotated by -angle (so the sweep direction becomes +x)."""
    c, s = math.cos(angle), math.sin(angle)
    x1, y1, x2, y2 = edges.T
    return np.column_stack([c * x1 + s * y1, -s * x1 + c * y1, c * x2 + s * y2, -s * x2 + c * y2])


def _scan(edges: FloatArray, ys: FloatArray) -> list[list[tuple[float, float]]]:
    """Inside intervals [x0, x1] of each horizontal line y (even-odd rule, half-open in y
    so a line through a vertex counts it once)."""
    if len(edges) == 0:
        return [[] for _ in ys]
    x1, y1, x2, y2 = (edges[:, i : i + 1] for i in range(4))
    y = ys[None, :]
    cross = ((y1 <= y) & (y < y2)) | ((y2 <= y) & (y < y1))
    with np.errstate(all="ignore"):
        xs = np.where(cross, x1 + (y - y1) * (x2 - x1) / (y2 - y1), np.inf)
    xs.sort(axis=0)
    counts = cross.sum(axis=0).tolist()
    cols = xs.T.tolist()
    return [
        [(col[i], col[i + 1]) for i in range(0, n - 1, 2)]
        for col, n in zip(cols, counts, strict=True)
    ]


def _merge(intervals: list[tuple[float, float]], gap: float = 0.0) -> list[tuple[float, float]]:
    out: list[tuple[float, float]] = []
    for lo, hi in sorted(intervals):
        if out and lo <= out[-1][1] + gap:
            out[-1] = (out[-1][0], max(out[-1][1], hi))
        else:
            out.append((lo, hi))
    return out


def _subtract(
    iv: tuple[float, float], cuts: list[tuple[float, float]]
) -> list[tuple[float, float]]:
    out = [iv]
    for c0, c1 in cuts:
        nxt: list[tuple[float, float]] = []
        for a, b in out:
            if c1 <= a or c0 >= b:
                nxt.append((a, b))
                continue
            if c0 > a:
                nxt.append((a, c0))
            if c1 < b:
                nxt.append((c1, b))
        out = nxt
    return out


_MIN_LANE_M = 1.0


def _lanes_rotated(
    cover_edges: FloatArray,
    keep_edges: FloatArray,
    spacing: float,
    merge_gaps: bool,
    extend: float = 0.5,
    shift: float = 0.5,
) -> list[tuple[int, float, float, float]]:
    """(line index, y, x0, x1) of each lane in the rotated frame. `extend` in [0, 0.5]:
    how far across its swath strip (in spacings) a lane is lengthened to cover the
    strip (0: clipped where the centre line leaves the region; 0.5: the whole strip).
    `shift` in [0, 1]: where the lane grid sits in its slack across the region."""
    ys_all = np.concatenate([cover_edges[:, 1], cover_edges[:, 3]])
    ymin, ymax = float(ys_all.min()), float(ys_all.max())
    width = ymax - ymin
    n = max(1, math.ceil(width / spacing - 1e-9))
    y0 = ymin - (n * spacing - width) * shift + spacing / 2.0
    centres: FloatArray = y0 + spacing * np.arange(n, dtype=np.float64)
    e = min(max(extend, 0.0), 0.5) * (1.0 - 1e-7)
    offsets = np.array([-e, -e / 2.0, 0.0, e / 2.0, e]) if e > 0 else np.zeros(1)
    sub: FloatArray = (centres[:, None] + spacing * offsets[None, :]).ravel().astype(np.float64)
    cover_iv = _scan(cover_edges, sub)
    keep_iv = _scan(keep_edges, centres) if len(keep_edges) else [[] for _ in centres]
    m = len(offsets)
    vx, vy = cover_edges[:, 0], cover_edges[:, 1]  # every ring vertex (edge starts)
    # vertices inside each lane's strip (tips between the sub-lines), all lines at once
    in_strip = (np.abs(vy[None, :] - centres[:, None]) <= e * spacing) if e > 0 else None
    out: list[tuple[int, float, float, float]] = []
    for k, y in enumerate(centres.tolist()):
        ivs = [iv for j in range(m) for iv in cover_iv[k * m + j]]
        if in_strip is not None and ivs:
            ivs += [(x, x) for x in vx[in_strip[k]].tolist()]
        groups = _merge(ivs)
        keep = _merge(keep_iv[k])
        if merge_gaps and len(groups) > 1:
            merged = [groups[0]]
            for g in groups[1:]:
                gap = (merged[-1][1], g[0])
                if any(c0 < gap[1] and c1 > gap[0] for c0, c1 in keep):
                    merged.append(g)
                else:
                    merged[-1] = (merged[-1][0], g[1])
            groups = merged
        for g in groups:
            for x0, x1 in _subtract(g, keep):
                if x1 - x0 >= _MIN_LANE_M:
                    out.append((k, y, x0, x1))
    return out


def lanes(
    region: Region,
    angle_rad: float,
    spacing_m: float,
    *,
    extend: float = 0.5,
    shift: float = 0.5,
    merge_gaps: bool = True,
) -> tuple[Lane, ...]:
    """Parallel lanes in direction `angle_rad` (CCW from east) at `spacing_m`.

    The lines sit across the region so the swaths (one spacing wide) tile it (`shift`
    places the grid in its slack: 0.5 centres it). A lane spans every part of the
    region within `extend` spacings of its centre line (0.5: its whole swath strip, so
    the swaths cover the region up to the zone margins). Pieces of one line separated
    only by a hole or by outside area are merged (flying over costs less than a turn);
    a line is cut wherever it would enter the keep-out.
    """
    if not (math.isfinite(spacing_m) and spacing_m > 0.0):
        raise InvalidParameterError(f"lane spacing must be > 0, got {spacing_m}")
    if not math.isfinite(angle_rad):
        raise InvalidParameterError("sweep angle must be finite")
    ce = _rotate(_edges_of(region.cover), angle_rad)
    ke = _rotate(_edges_of(region.keep_out), angle_rad)
    c, s = math.cos(angle_rad), math.sin(angle_rad)
    out: list[Lane] = []
    for k, y, x0, x1 in _lanes_rotated(ce, ke, spacing_m, merge_gaps, extend, shift):
        a = (c * x0 - s * y, s * x0 + c * y)
        b = (c * x1 - s * y, s * x1 + c * y)
        out.append(Lane(k, a, b))
    return _out_of_holes(out, region)


# The holes of recent polygons, unioned and prepared (keyed by the polygon's identity,
# which the entry keeps alive)
_HOLES: collections.OrderedDict[int, tuple[BaseGeometry, BaseGeometry | None]] = (
    collections.OrderedDict()
)


def _holes_of(polygon: BaseGeometry) -> BaseGeometry | None:
    """The polygon's holes as one prepared geometry (None without holes)."""
    got = _HOLES.get(id(polygon))
    if got is not None and got[0] is polygon:
        return got[1]
    holes = [Polygon(r) for p in _pieces(polygon) for r in p.interiors]
    inside = None
    if holes:
        inside = shapely.union_all(holes)
        shapely.prepare(inside)
    _HOLES[id(polygon)] = (polygon, inside)
    while len(_HOLES) > 8:
        _HOLES.popitem(last=False)
    return inside


def _out_of_holes(lanes_: Sequence[Lane], region: Region) -> tuple[Lane, ...]:
    """Lanes fly over holes but never start or end in one: an end inside a hole (where
    a zone cut the line, or where the strip's extension reaches over the hole) moves
    back along the lane to the hole's edge."""
    inside = _holes_of(region.polygon)
    if inside is None or not lanes_:
        return tuple(lanes_)
    ab = np.array([(*ln.a, *ln.b) for ln in lanes_], dtype=np.float64)
    in_a = shapely.contains_xy(inside, ab[:, 0], ab[:, 1])
    in_b = shapely.contains_xy(inside, ab[:, 2], ab[:, 3])
    out = []
    for ln, ia, ib in zip(lanes_, in_a.tolist(), in_b.tolist(), strict=True):
        if not (ia or ib):
            out.append(ln)
            continue
        line = LineString([ln.a, ln.b])
        rest = line.difference(inside)
        ends = [
            line.project(shapely.Point(c)) for g in getattr(rest, "geoms", [rest]) for c in g.coords
        ]
        if not ends or max(ends) - min(ends) < _MIN_LANE_M:
            continue
        a, b = line.interpolate(min(ends)), line.interpolate(max(ends))
        out.append(Lane(ln.line, (a.x, a.y), (b.x, b.y), ln.gap))
    return tuple(out)


@dataclass(frozen=True, slots=True)
class SweepCost:
    """Cost of a set of lanes for choosing the sweep direction: total lane length plus
    `turn_m` per lane (about one U-turn each). A separate object from the search."""

    turn_m: float
    stagger: float = 1.0  # weight of the lane ends' total variation along each side

    def __call__(self, lanes_: Sequence[Lane]) -> float:
        rows: list[tuple[int, float, float, float]] = []
        for ln in lanes_:
            c, s = math.cos(ln.yaw), math.sin(ln.yaw)
            u0, u1 = sorted((ln.a[0] * c + ln.a[1] * s, ln.b[0] * c + ln.b[1] * s))
            rows.append((ln.line, 0.0, u0, u1))
        return self.rotated(rows)

    def rotated(self, rows: Sequence[tuple[int, float, float, float]]) -> float:
        """Cost of lanes given as (line, y, x0, x1) in the sweep-aligned frame: length +
        turns + the stagger of the lane ends (each side's ends are passed twice by a
        skip pattern, so every step between neighbouring lines costs about twice)."""
        if not rows:
            return math.inf
        length = sum(x1 - x0 for _k, _y, x0, x1 in rows)
        lo: dict[int, float] = {}
        hi: dict[int, float] = {}
        for k, _y, x0, x1 in rows:
            lo[k] = min(lo.get(k, x0), x0)
            hi[k] = max(hi.get(k, x1), x1)
        ks = sorted(lo)
        tv = sum(abs(lo[a] - lo[b]) + abs(hi[a] - hi[b]) for a, b in itertools.pairwise(ks))
        return length + self.turn_m * len(rows) + self.stagger * tv

    @classmethod
    def for_turns(cls, turns: TurnModel, spacing_m: float) -> SweepCost:
        r = turns.radius_m
        if r <= 0.0:
            return cls(spacing_m)
        return cls(math.pi * r + max(spacing_m - 2.0 * r, 0.0) + 2.0 * r)


def _candidate_angles(region: Region) -> list[float]:
    angles: list[float] = []
    for g in (region.cover.convex_hull, region.cover):
        for ring in _rings(g):
            d = np.diff(ring, axis=0)
            length = np.hypot(d[:, 0], d[:, 1])
            for (dx, dy), ln in zip(d, length, strict=True):
                if ln > 1e-6:
                    angles.append(math.atan2(dy, dx) % math.pi)
    angles += [i * math.pi / 12 for i in range(12)]
    out: list[float] = []
    for a in sorted(angles):
        if not out or a - out[-1] > math.radians(0.25):
            out.append(a)
    if len(out) > 1 and out[0] + math.pi - out[-1] <= math.radians(0.25):
        out.pop()
    return out


def sweep_angles(
    region: Region, spacing_m: float, cost: SweepCost, *, top: int = 3
) -> list[tuple[float, float]]:
    """The `top` best sweep directions as (cost, angle), best first: every edge
    direction of the region and of its convex hull (plus a 15-degree net) is scored,
    then the best ones are refined by a local search with steps halving from 4 to 1/8
    degree (about 60 evaluations in all, not a 1-degree brute force)."""
    ce = _edges_of(region.cover)
    ke = _edges_of(region.keep_out)

    def score(a: float) -> float:
        return cost.rotated(_lanes_rotated(_rotate(ce, a), _rotate(ke, a), spacing_m, True, 0.0))

    scored = sorted((score(a), a) for a in _candidate_angles(region))
    out: list[tuple[float, float]] = []
    for c0, a0 in scored[:top]:
        c_cur, a_cur = c0, a0
        step = math.radians(4.0)
        while step >= math.radians(0.125):
            moved = True
            while moved:
                moved = False
                for a in (a_cur - step, a_cur + step):
                    c = score(a)
                    if c < c_cur - 1e-9:
                        c_cur, a_cur, moved = c, a, True
                        break
            step /= 2.0
        a_cur %= math.pi
        if all(abs(math.remainder(a_cur - b, math.pi)) > math.radians(0.1) for _c, b in out):
            out.append((c_cur, a_cur))
    return sorted(out)


def sweep_angle(region: Region, spacing_m: float, cost: SweepCost) -> float:
    """The best sweep direction (radians CCW from east, in [0, pi))."""
    return sweep_angles(region, spacing_m, cost, top=3)[0][1]


# --------------------------------------------------------------------------- order


def _poses(lanes_: Sequence[Lane]) -> tuple[FloatArray, FloatArray]:
    """Start and end poses of every lane in both directions: rows 2i (a->b), 2i+1 (b->a)."""
    n = len(lanes_)
    ab = np.array([(*ln.a, *ln.b) for ln in lanes_], dtype=np.float64).reshape(n, 4)
    yaw = np.array([ln.yaw for ln in lanes_], dtype=np.float64)
    back = np.array([math.remainder(y + math.pi, 2 * math.pi) for y in yaw.tolist()])
    st = np.empty((2 * n, 3))
    en = np.empty((2 * n, 3))
    st[0::2, :2], st[0::2, 2] = ab[:, :2], yaw
    en[0::2, :2], en[0::2, 2] = ab[:, 2:], yaw
    st[1::2, :2], st[1::2, 2] = ab[:, 2:], back
    en[1::2, :2], en[1::2, 2] = ab[:, :2], back
    return st, en


def _pair_costs(turns: TurnModel, ends: FloatArray, starts: FloatArray) -> FloatArray:
    """Transition lengths from each row of `ends` to the same row of `starts`."""
    if isinstance(turns, DubinsTurns):
        out = batch_lengths(ends, starts, turns.radius_m)
        assert isinstance(out, np.ndarray)
        return out
    if isinstance(turns, PointTurns):
        return np.hypot(starts[:, 0] - ends[:, 0], starts[:, 1] - ends[:, 1])
    return np.array(
        [
            turns.cost_matrix(e[None, :], s_[None, :])[0, 0]
            for e, s_ in zip(ends, starts, strict=True)
        ]
    )


@dataclass(slots=True)
class _CostSet:
    """Transition costs among the lanes of one lane set (rows 2i a->b, 2i+1 b->a, as
    `_poses`), each computed the first time it is asked for (NaN until then)."""

    turns: TurnModel
    index: dict[Lane, int]
    st: FloatArray
    en: FloatArray
    m: FloatArray

    @classmethod
    def of(cls, lanes_: Sequence[Lane], turns: TurnModel) -> _CostSet:
        st, en = _poses(lanes_)
        n2 = 2 * len(lanes_)
        index = {ln: i for i, ln in enumerate(lanes_)}
        return cls(turns, index, st, en, np.full((n2, n2), np.nan))

    def get(self, gu: npt.NDArray[np.intp], gv: npt.NDArray[np.intp]) -> FloatArray:
        vals = self.m[gu, gv]
        miss = np.isnan(vals)
        if miss.any():
            mu, mv = gu[miss], gv[miss]
            got = _pair_costs(self.turns, self.en[mu], self.st[mv])
            self.m[mu, mv] = got
            vals[miss] = got
        return vals


# Transition costs of recent lane sets: the plan's candidates and the split's many blocks
# of one plan's lanes share them (a pure function of immutable arguments; bounded).
_COST_SETS: collections.OrderedDict[tuple[Any, ...], _CostSet] = collections.OrderedDict()
_COST_SETS_MAX = 8
_MAX_UNKNOWN = 2  # lanes of a block outside a known set (the split's cut lanes)


class _Costs:
    """Transition costs among the lanes of one `order`, asked for sparsely (only the
    links the seed patterns use, unless the local search needs them all): looked up in
    and added to a recent lane set that holds all but at most two of the lanes (those:
    computed each time), or to a new set of these lanes."""

    def __init__(self, lanes_: Sequence[Lane], turns: TurnModel) -> None:
        self.turns = turns
        self.st, self.en = _poses(lanes_)
        self.memo: _CostSet | None = None
        k = len(lanes_)
        rows: list[int] = [-1] * k
        try:
            hash(turns)
        except TypeError:
            self.g = np.full(2 * k, -1, dtype=np.intp)  # no memo: every cost computed
            return
        for key in reversed(_COST_SETS):
            cs = _COST_SETS[key]
            if cs.turns != turns:
                continue
            unknown = 0
            for i, ln in enumerate(lanes_):
                r = cs.index.get(ln)
                if r is None:
                    unknown += 1
                    if unknown > _MAX_UNKNOWN:
                        break
                    r = -1
                rows[i] = r
            if unknown <= _MAX_UNKNOWN:
                self.memo = cs
                _COST_SETS.move_to_end(key)  # the most recently used, found first
                break
        if self.memo is None:
            self.memo = _CostSet.of(lanes_, turns)
            _COST_SETS[(turns, tuple(lanes_))] = self.memo
            while len(_COST_SETS) > _COST_SETS_MAX:
                _COST_SETS.popitem(last=False)
            rows = list(range(k))
        at = np.array(rows, dtype=np.intp)
        self.g = np.where(np.repeat(at, 2) >= 0, np.repeat(2 * at, 2) + np.tile([0, 1], k), -1)

    def pairs(self, u: npt.NDArray[np.intp], v: npt.NDArray[np.intp]) -> FloatArray:
        """Costs from the end of node u to the start of node v (nodes 2i a->b, 2i+1 b->a
        of this call's lanes), element by element."""
        gu, gv = self.g[u], self.g[v]
        known = (gu >= 0) & (gv >= 0)
        if self.memo is not None and known.all():
            return self.memo.get(gu, gv)
        out = np.empty(len(u))
        if self.memo is not None and known.any():
            out[known] = self.memo.get(gu[known], gv[known])
        other = ~known if self.memo is not None else np.ones(len(u), dtype=bool)
        out[other] = _pair_costs(self.turns, self.en[u[other]], self.st[v[other]])
        return out

    def matrix(self) -> FloatArray:
        n2 = len(self.g)
        u, v = np.divmod(np.arange(n2 * n2, dtype=np.intp), n2)
        return self.pairs(u, v).reshape(n2, n2)


def clear_caches() -> None:
    """Forget the memoized transitions and cost matrices (benchmarks time cold plans)."""
    _COST_SETS.clear()
    _HOLES.clear()
    _EDGES.clear()
    _cached_transition.cache_clear()


def _padded(cm: FloatArray, first: FloatArray | None, last: FloatArray | None = None) -> FloatArray:
    """The transition matrix with a virtual start S (row 2n: the start pose, or free)
    and a virtual end E (column 2n+1: the way on from each lane end, or free), so every
    move is an interior one."""
    m = cm.shape[0]
    c = np.full((m + 2, m + 2), np.inf)
    c[:m, :m] = cm
    c[m, :m] = first if first is not None else 0.0
    c[:m, m + 1] = last if last is not None else 0.0
    return c


def _cost(t: npt.NDArray[np.intp], c: FloatArray) -> float:
    return float(c[t[:-1], t[1:]].sum())


def _flip(t: npt.NDArray[np.intp], m: int) -> npt.NDArray[np.intp]:
    return np.where(t < m, t ^ 1, t)


@functools.lru_cache(maxsize=256)
def _moves(n: int) -> tuple[npt.NDArray[np.intp], ...]:
    """Every move of `_improve` on a tour of n lanes, as flat index arrays (read-only):
    2-opt reversals of t[i..j] (i <= j), then or-opt moves of t[i..e] (1-3 lanes)
    between t[p] and t[p+1] (p outside the run)."""
    pos = np.arange(1, n + 1)
    i2, j2 = np.meshgrid(pos, pos, indexing="ij")
    up = j2 >= i2
    ri, rj = i2[up], j2[up]
    ii_, ee_, pp_ = [], [], []
    for k in (1, 2, 3):
        if k > n:
            break
        ii = np.arange(1, n - k + 2)  # run t[i..i+k-1]
        p = np.arange(0, n + 1)  # insert between t[p] and t[p+1]
        ig, pg = np.meshgrid(ii, p, indexing="ij")
        eg = ig + k - 1
        ok = (pg < ig - 1) | (pg > eg)
        ii_.append(ig[ok])
        ee_.append(eg[ok])
        pp_.append(pg[ok])
    out = (ri, rj, np.concatenate(ii_), np.concatenate(ee_), np.concatenate(pp_))
    for a in out:
        a.flags.writeable = False
    return out


def _improve(t: npt.NDArray[np.intp], c: FloatArray, max_moves: int = 2000) -> npt.NDArray[np.intp]:
    """Steepest descent over 2-opt (reverse a run, which flips each lane's direction) and
    or-opt (move a run of 1-3 lanes elsewhere, either way round) moves, all evaluated at
    once with numpy over the padded matrix; t = [S, lanes..., E]."""
    m = c.shape[0] - 2
    n = len(t) - 2
    if n < 2:
        return t
    ri, rj, oi, oe, op = _moves(n)
    inf = np.inf
    for _ in range(max_moves):
        f = _flip(t, m)
        link = c[t[:-1], t[1:]]  # link[k]: t[k] -> t[k+1]
        pf = np.concatenate([[0.0], np.cumsum(link)])
        rl = c[f[1:], f[:-1]]  # reversed link between positions k and k+1
        # (S and E are never inside a reversed run: their links, infinite reversed,
        # must not poison the prefix sums of the others)
        rl[0] = rl[-1] = 0.0
        pr = np.concatenate([[0.0], np.cumsum(rl)])
        with np.errstate(invalid="ignore"):
            d2 = (
                c[t[ri - 1], f[rj]]
                + c[f[ri], t[rj + 1]]
                + (pr[rj] - pr[ri])
                - link[ri - 1]
                - link[rj]
                - (pf[rj] - pf[ri])
            )
            lp = link[op]
            fwd = c[t[op], t[oi]] + c[t[oe], t[op + 1]] - lp
            bwd = (
                c[t[op], f[oe]] + c[f[oi], t[op + 1]] - lp + ((pr[oe] - pr[oi]) - (pf[oe] - pf[oi]))
            )
            gain = link[oi - 1] + link[oe] - c[t[oi - 1], t[oe + 1]]
            do = np.fmin(fwd, bwd) - gain
        d2[np.isnan(d2)] = inf
        do[np.isnan(do)] = inf
        k2, ko = int(d2.argmin()), int(do.argmin())
        b2, bo = float(d2[k2]), float(do[ko])
        if min(b2, bo) >= -1e-9:
            return t
        if b2 <= bo + 1e-9:
            i, j = int(ri[k2]), int(rj[k2])
            t = np.concatenate([t[:i], f[i : j + 1][::-1], t[j + 1 :]])
        else:
            i, j, q = int(oi[ko]), int(oe[ko]), int(op[ko])
            piece = f[i : j + 1][::-1] if bwd[ko] < fwd[ko] else t[i : j + 1]
            rest = np.concatenate([t[:i], t[j + 1 :]])
            at = q + 1 if q < i else q + 1 - (j - i + 1)
            t = np.concatenate([rest[:at], piece, rest[at:]])
    return t


@functools.lru_cache(maxsize=256)
def _patterns(n: int) -> tuple[npt.NDArray[np.intp], npt.NDArray[np.intp]]:
    """The seed patterns over n lanes in sweep order: (positions, direction bits), one
    row per pattern (read-only)."""
    pos: list[list[int]] = []
    bit: list[list[int]] = []
    for k in range(1, min(n, 6) + 1):
        # every k-th lane outward, then the skipped ones back, and so on
        seq: list[int] = []
        for r in range(k):
            part = list(range(n))[r::k]
            seq += part if r % 2 == 0 else part[::-1]
        for flip in (0, 1):
            pos.append(seq)
            bit.append([(j + flip) % 2 for j in range(n)])
    out = (np.array(pos, dtype=np.intp), np.array(bit, dtype=np.intp))
    for a in out:
        a.flags.writeable = False
    return out


def _seeds(lanes_: Sequence[Lane]) -> npt.NDArray[np.intp]:
    """Boustrophedon and skip-k patterns over the lanes sorted across the sweep, as
    nodes (2i: lane i a->b, 2i+1: b->a), one row per pattern."""
    ab = np.array([(*ln.a, *ln.b) for ln in lanes_], dtype=np.float64).reshape(-1, 4)
    yaw = np.array([ln.yaw for ln in lanes_], dtype=np.float64)
    c, s = np.cos(yaw), np.sin(yaw)
    along = np.minimum(ab[:, 0] * c + ab[:, 1] * s, ab[:, 2] * c + ab[:, 3] * s)  # `_along`
    line = np.array([ln.line for ln in lanes_], dtype=np.int64)
    idx = np.lexsort((along, line))
    pos, bit = _patterns(len(lanes_))
    return 2 * idx[pos] + bit


def _along(ln: Lane) -> float:
    c, s = math.cos(ln.yaw), math.sin(ln.yaw)
    return min(ln.a[0] * c + ln.a[1] * s, ln.b[0] * c + ln.b[1] * s)


def order(
    lanes_: Sequence[Lane],
    turns: TurnModel,
    start: Pose | None = None,
    *,
    restarts: int = 2,
    end: XY | None = None,
    improve: bool | None = None,
) -> tuple[Lane, ...]:
    """The lanes in a short flight order and direction for this turn model (from
    `start` if given; with `end`, counting the straight way there from the last lane,
    e.g. home): the cheapest seed pattern, or with `improve` (default: the module's
    `LOCAL_SEARCH`) the `restarts` cheapest improved to a local optimum, best kept."""
    search = LOCAL_SEARCH if improve is None else improve
    return _order(lanes_, turns, start, restarts, end=end, improve=search)[0]


def order_cost(
    lanes_: Sequence[Lane],
    turns: TurnModel,
    start: Pose | None = None,
    *,
    end: XY | None = None,
) -> tuple[tuple[Lane, ...], float]:
    """The cheapest seed pattern (no local search) and the total length of the
    transitions the connected path will have (from `start` when given) with no obstacle
    to go around: the split times blocks by it without connecting them. With `end`, the
    pattern is chosen counting the way there (not included in the length)."""
    lanes, cost = _order(lanes_, turns, start, 0, end=end, improve=False)
    if end is not None and lanes:
        cost -= math.hypot(end[0] - lanes[-1].b[0], end[1] - lanes[-1].b[1])
    return lanes, cost


# The order's local search (`_improve`, 2-opt and or-opt moves over all transitions)
# never moved before (the virtual start's and end's reversed links made every
# move NaN). Fixed, it shortens paths (irregular6: 24312 -> 24208 m) and runs where its
# cost is paid once: the single-vehicle path of `plan_lanes` and each vehicle's final
# share (`split_lanes`), each kept only if it is better than the seed pattern it starts
# from (a share: by its time and, for a vehicle with a battery budget, its way home).
# Ranking candidates and timing blocks use the seed patterns alone.
LOCAL_SEARCH = True


def _order(
    lanes_: Sequence[Lane],
    turns: TurnModel,
    start: Pose | None,
    restarts: int,
    *,
    end: XY | None = None,
    improve: bool = False,
) -> tuple[tuple[Lane, ...], float]:
    """The order and the sum of its transitions' lengths (from the cost matrix), plus
    the straight way to `end` from the last lane when given."""
    if not lanes_:
        return (), 0.0
    n = len(lanes_)
    costs = _Costs(lanes_, turns)
    seeds = _seeds(lanes_)  # (patterns, n) nodes
    first = None
    if start is not None:
        first = turns.cost_matrix(np.array([[start.x, start.y, start.yaw]]), costs.st)[0]
    last = None
    if end is not None:
        last = np.hypot(costs.en[:, 0] - end[0], costs.en[:, 1] - end[1])
    # every seed's cost from the links it uses only (no full matrix)
    u, v = seeds[:, :-1], seeds[:, 1:]
    links = costs.pairs(u.ravel(), v.ravel()).reshape(u.shape)
    head = first[seeds[:, 0]] if first is not None else np.zeros(len(seeds))
    tail = last[seeds[:, -1]] if last is not None else np.zeros(len(seeds))
    total = np.concatenate([head[:, None], links, tail[:, None]], axis=1).sum(axis=1)
    rank = np.argsort(total, kind="stable")
    if restarts <= 0 or not improve:
        best_seq, best_cost = seeds[rank[0]], float(total[rank[0]])  # the cheapest seed
    else:
        cm = costs.matrix()
        idx = np.arange(n)
        cm[2 * idx, 2 * idx] = cm[2 * idx + 1, 2 * idx + 1] = np.inf
        cm[2 * idx, 2 * idx + 1] = cm[2 * idx + 1, 2 * idx] = np.inf
        c = _padded(cm, first, last)
        m = 2 * n
        tours = [np.array([m, *seeds[r], m + 1], dtype=np.intp) for r in rank[:restarts]]
        best = min((_improve(t, c) for t in tours), key=lambda t: _cost(t, c))
        best_seq, best_cost = best[1:-1], _cost(best, c)
    return tuple(
        lanes_[x // 2] if x % 2 == 0 else lanes_[x // 2].reversed() for x in best_seq.tolist()
    ), best_cost


# --------------------------------------------------------------------------- connect


def connect(
    ordered: Sequence[Lane],
    turns: TurnModel,
    obstacles: Obstacles | None = None,
    start: Pose | None = None,
) -> CoveragePath:
    """Lanes joined by the turn model's transitions (from `start` if given). A transition
    whose curve would cross the obstacles is replaced by the shortest polyline around
    them (visibility graph)."""
    legs: list[Leg] = []
    prev = start
    for ln in ordered:
        nxt = ln.start_pose()
        if prev is not None:
            legs.append(_transition(prev, nxt, turns, obstacles))
        legs.append(Leg((ln.a, ln.b), ln.length_m, True))
        prev = ln.end_pose()
    return CoveragePath(tuple(ordered), tuple(legs))


def _transition(a: Pose, b: Pose, turns: TurnModel, obstacles: Obstacles | None) -> Leg:
    try:
        return _cached_transition(a, b, turns, obstacles)  # type: ignore[arg-type]
    except TypeError:  # a turn model that cannot be hashed
        return _transition_uncached(a, b, turns, obstacles)


# The split evaluates many blocks sharing most of their transitions (a pure function
# of its arguments, all immutable: memoized, bounded).
@functools.lru_cache(maxsize=16384)
def _cached_transition(a: Pose, b: Pose, turns: TurnModel, obstacles: Obstacles | None) -> Leg:
    return _transition_uncached(a, b, turns, obstacles)


def _transition_uncached(a: Pose, b: Pose, turns: TurnModel, obstacles: Obstacles | None) -> Leg:
    pts = [(a.x, a.y)] + [(p.x, p.y) for p in turns.points(a, b)]
    length = turns.length(a, b)
    if obstacles is None or obstacles.is_empty:
        return Leg(tuple(pts), length, False)
    # the arcs between the waypoints (30 degrees apart) bulge out of their chords by up
    # to R (1 - cos 15 deg) < 0.035 R: farther than that from the obstacles the arcs are
    # clear too, nearer they are checked sampled
    trace: Sequence[XY] | FloatArray = pts
    if isinstance(turns, DubinsTurns):
        # the curve stays within 0.035 R of the waypoints' hull: far from the obstacles'
        # bounding box it is clear (most transitions of a plan, at the field's edges)
        xs, ys = [p[0] for p in pts], [p[1] for p in pts]
        bx0, by0, bx1, by1 = obstacles.blocked.bounds
        pad = 0.035 * turns.radius_m
        if min(xs) - pad > bx1 or max(xs) + pad < bx0 or min(ys) - pad > by1 or max(ys) + pad < by0:
            return Leg(tuple(pts), length, False)
        if obstacles.clearance(pts) > 0.035 * turns.radius_m:
            return Leg(tuple(pts), length, False)
        trace = shortest_path(a, b, turns.radius_m).sample_xy(ARC_STEP_M)  # (n, 2) array
    if not obstacles.crosses(trace):
        return Leg(tuple(pts), length, False)
    # a vehicle's start (a replan from where it is) may be in a zone's margin
    around = obstacles.path_from((a.x, a.y), (b.x, b.y))
    return Leg(tuple(around), LineString(around).length, False)


# --------------------------------------------------------------------------- metrics


# Swaths of neighbouring lanes share an edge; GEOS unions of such nearly coincident
# edges can silently drop a whole polygon unless snapped to a precision grid.
_GRID_M = 1e-6


def swaths(lanes_: Sequence[Lane], spacing_m: float) -> list[BaseGeometry]:
    """Each lane's swath at the lane spacing (flat-ended rectangle)."""
    return [LineString([ln.a, ln.b]).buffer(spacing_m / 2.0, cap_style="flat") for ln in lanes_]


def _disjoint_swaths(lanes_: Sequence[Lane], spacing_m: float) -> bool:
    """True when the lanes' swaths cannot overlap (their areas simply add up): sweep
    lanes (no gap lanes), all parallel, lanes on one line disjoint along it and lines
    at least a spacing apart across. What `lanes` makes; anything else is unioned."""
    if any(ln.gap for ln in lanes_):
        return False
    ab = np.array([(*ln.a, *ln.b) for ln in lanes_], dtype=np.float64)
    dx, dy = ab[:, 2] - ab[:, 0], ab[:, 3] - ab[:, 1]
    if not (np.hypot(dx, dy) > 0.0).all():
        return False
    yaw = lanes_[0].yaw
    c, s = math.cos(yaw), math.sin(yaw)
    if (np.abs(np.sin(np.arctan2(dy, dx) - yaw)) > 1e-9).any():
        return False  # not all parallel
    u0, u1 = ab[:, 0] * c + ab[:, 1] * s, ab[:, 2] * c + ab[:, 3] * s
    v = -ab[:, 0] * s + ab[:, 1] * c
    lo, hi = np.minimum(u0, u1), np.maximum(u0, u1)
    line = np.array([ln.line for ln in lanes_])
    tol = 1e-6 * max(spacing_m, 1.0)
    by = np.lexsort((lo, line))  # by line, then along it
    line, lo, hi, v = line[by], lo[by], hi[by], v[by]
    same = line[1:] == line[:-1]
    if (same & (np.abs(v[1:] - v[:-1]) > tol)).any():
        return False  # one line's lanes are not on one line
    if (same & (hi[:-1] > lo[1:] + tol)).any():
        return False  # lanes of one line overlap along it
    across = np.sort(v[np.concatenate([[True], ~same])])
    return bool((np.diff(across) >= spacing_m - tol).all())


def coverage_ratio(lanes_: Sequence[Lane], area: BaseGeometry, spacing_m: float) -> float:
    """Fraction of `area` inside the union of the lanes' swaths at the lane spacing.

    Sweep lanes' swaths tile the area without overlapping (`_disjoint_swaths`): then
    the covered area is the sum of each swath's intersection with the area (one
    vectorized GEOS call, no union); otherwise the swaths are unioned."""
    if area.is_empty or area.area <= 0:
        raise EmptyAreaError("coverage of an empty area")
    if not lanes_:
        return 0.0
    if _disjoint_swaths(lanes_, spacing_m):
        try:
            return _tiled_coverage(lanes_, area, spacing_m)
        except shapely.errors.GEOSException:
            pass  # a degenerate area the rectangle clipping cannot take: unioned
    seen = shapely.union_all(swaths(lanes_, spacing_m), grid_size=_GRID_M)
    return float(seen.intersection(area, grid_size=_GRID_M).area / area.area)


def _tiled_coverage(lanes_: Sequence[Lane], area: BaseGeometry, spacing_m: float) -> float:
    """Coverage of swaths that tile without overlapping: the sum of each swath's
    intersection with the area. In the frame where the lanes run along x each swath is
    an axis-aligned box: GEOS's rectangle clipping, not a general overlay."""
    yaw = lanes_[0].yaw
    c, s = math.cos(yaw), math.sin(yaw)
    rot = np.array([[c, -s], [s, c]])  # row vectors: (x, y) @ rot = rotated by -yaw
    local = shapely.transform(area, lambda xy: xy @ rot)
    ab = np.array([(*ln.a, *ln.b) for ln in lanes_], dtype=np.float64)
    u0, v0 = (ab[:, :2] @ rot).T
    u1 = (ab[:, 2:] @ rot)[:, 0]
    lo, hi = np.minimum(u0, u1).tolist(), np.maximum(u0, u1).tolist()
    h = spacing_m / 2.0
    seen_area = 0.0
    for x0, x1, v in zip(lo, hi, v0.tolist(), strict=True):
        seen_area += float(shapely.clip_by_rect(local, x0, v - h, x1, v + h).area)
    return min(seen_area / area.area, 1.0)


def overlap_ratio(lanes_: Sequence[Lane], area: BaseGeometry, spacing_m: float) -> float:
    """Fraction of `area` seen by two or more swaths, counted with multiplicity
    (sum of swath areas inside `area` minus the area of their union, over `area`)."""
    if not lanes_ or _disjoint_swaths(lanes_, spacing_m):
        return 0.0
    sw = swaths(lanes_, spacing_m)
    total = sum(s.intersection(area).area for s in sw)
    union = shapely.union_all(sw, grid_size=_GRID_M).intersection(area, grid_size=_GRID_M).area
    return float(max(total - union, 0.0) / area.area)


_GAP_ROUNDS = 4
_GAP_CANDIDATES = 3  # lane plans (of the sweep candidates) that get gap lanes
_GAP_OFFSETS = 7  # candidate line offsets across a gap, per direction


def _pieces(g: BaseGeometry) -> list[Polygon]:
    return [p for p in getattr(g, "geoms", [g]) if isinstance(p, Polygon) and not p.is_empty]


def _gap_lane(
    piece: Polygon,
    missing: BaseGeometry,
    region: Region,
    angle: float,
    spacing_m: float,
    line_of: Any,
) -> Lane | None:
    """The straight lane, along the sweep or across it, that sees most of the unseen
    ground (`missing`) at a few offsets across the uncovered `piece`: on each
    candidate line, the stretch outside the keep-out that reaches the piece, spanning
    all the unseen ground its swath can take in (so one lane tangent to a zone's front
    sees the slivers left at several cut lanes). None if none sees anything."""
    best: tuple[float, float, Lane] | None = None
    keep = region.keep_out
    for a in (angle, angle + math.pi / 2):
        c, s = math.cos(a), math.sin(a)
        rot = shapely.affinity.rotate(missing, -a, origin=(0.0, 0.0), use_radians=True)
        xy = np.asarray(piece.exterior.coords)
        u = xy[:, 0] * c + xy[:, 1] * s  # along the direction
        v = -xy[:, 0] * s + xy[:, 1] * c  # across it
        u0, u1, v0, v1 = float(u.min()), float(u.max()), float(v.min()), float(v.max())
        ke = _rotate(_edges(_rings(keep)), a) if not keep.is_empty else np.zeros((0, 4))
        for off in np.linspace(v0, v1, _GAP_OFFSETS).tolist():
            band = rot.intersection(
                shapely.box(-1e9, off - spacing_m / 2, 1e9, off + spacing_m / 2)
            )
            if band.is_empty:
                continue
            b0, _bv0, b1, _bv1 = band.bounds
            blocked = _merge(_scan(ke, np.array([off]))[0]) if len(ke) else []
            for x0, x1 in _subtract((min(b0, u0), max(b1, u1)), blocked):
                if x1 - x0 < _MIN_LANE_M or x1 < u0 or x0 > u1:
                    continue  # too short, or does not reach the piece
                seen = float(
                    shapely.box(x0, off - spacing_m / 2, x1, off + spacing_m / 2)
                    .intersection(band)
                    .area
                )
                lane_a = (c * x0 - s * off, s * x0 + c * off)
                lane_b = (c * x1 - s * off, s * x1 + c * off)
                mid = ((lane_a[0] + lane_b[0]) / 2, (lane_a[1] + lane_b[1]) / 2)
                lane = Lane(line_of(mid), lane_a, lane_b, gap=True)
                if best is None or (seen, -(x1 - x0)) > (best[0], best[1]):
                    best = (seen, -(x1 - x0), lane)
    if best is None or best[0] <= 1e-9:
        return None
    return best[2]


def fill_gaps(
    region: Region,
    lanes_: Sequence[Lane],
    angle_rad: float,
    spacing_m: float,
    min_coverage: float,
) -> tuple[tuple[Lane, ...], float]:
    """Lanes added where the sweep lanes leave ground unseen, until `min_coverage` of
    the region is seen at the lane spacing: (all lanes, coverage).

    Where a sweep lane is cut at the keep-out, its swath stops at the cut: the ground
    beside a zone's curved edge (and, with a margin, in front of it) is left unseen.
    Each uncovered piece, largest first, gets the straight lane (along the sweep, or
    across it, tangent to the zone) at one of a few offsets across the piece, spanning
    it, cut at the keep-out, whose swath sees most of it; a few rounds. Ground within
    the keep-out deeper than half a spacing cannot be seen from outside it at all."""
    out = list(lanes_)
    total = float(region.target.area)
    main = next((ln for ln in out if not ln.gap), None)
    c, s = math.cos(angle_rad), math.sin(angle_rad)

    def across(p: XY) -> float:
        return -p[0] * s + p[1] * c

    def line_of(p: XY) -> int:
        if main is None:
            return 0
        return main.line + round((across(p) - across(main.a)) / spacing_m)

    seen = shapely.union_all(swaths(out, spacing_m), grid_size=_GRID_M) if out else Polygon()
    missing = _polygonal(region.target.difference(seen, grid_size=_GRID_M))
    cov = 1.0 - float(missing.area) / total
    for _ in range(_GAP_ROUNDS):
        if cov >= min_coverage:
            break
        added = 0
        for piece in sorted(_pieces(missing), key=lambda p: -p.area):
            if cov >= min_coverage or piece.area < max(0.5, 1e-7 * total):
                break
            got = _gap_lane(piece, missing, region, angle_rad, spacing_m, line_of)
            trimmed = _out_of_holes([got], region) if got is not None else ()
            if not trimmed:
                continue
            (lane,) = trimmed
            out.append(lane)
            added += 1
            sw = swaths([lane], spacing_m)[0]
            missing = _polygonal(missing.difference(sw, grid_size=_GRID_M))
            cov = 1.0 - float(missing.area) / total
        if not added:
            break
    return tuple(out), cov


def check_region(polygon: BaseGeometry) -> None:
    if not isinstance(polygon, Polygon | MultiPolygon):
        raise InvalidGeometryError(f"area coverage needs a polygon, got {polygon.geom_type}")


# --------------------------------------------------------------------------- whole pipeline

_EXTEND_LEVELS = (0.0, 0.05, 0.1, 0.15, 0.2, 0.3, 0.4, 0.5)
_SHIFTS = (0.5, 0.0, 1.0)
_NUDGES_DEG = (-1.0, -0.5, -0.25, 0.25, 0.5, 1.0)


@dataclass(frozen=True, slots=True)
class LanePlan:
    """The chosen lanes of a region and one vehicle's path over all of them."""

    angle_rad: float
    spacing_m: float
    extend: float
    lanes: tuple[Lane, ...]  # across the sweep (line order)
    path: CoveragePath  # ordered, connected
    coverage: float  # of the region's target (area - holes - inflated zones) at the lane spacing
    overlap: float  # of the same target


def _least_extension(
    region: Region, angle: float, spacing_m: float, shift: float, min_coverage: float
) -> tuple[tuple[Lane, ...], float, float]:
    """(lanes, coverage, extend) with the least lane extension reaching min_coverage
    (binary search over the levels; the full extension if none reaches it)."""
    got: dict[int, tuple[tuple[Lane, ...], float]] = {}

    def at(i: int) -> tuple[tuple[Lane, ...], float]:
        if i not in got:
            ls = lanes(region, angle, spacing_m, extend=_EXTEND_LEVELS[i], shift=shift)
            got[i] = (ls, coverage_ratio(ls, region.target, spacing_m) if ls else 0.0)
        return got[i]

    lo, hi = 0, len(_EXTEND_LEVELS) - 1
    if at(lo)[1] >= min_coverage:  # the usual case: no extension needed
        hi = lo
    elif at(hi)[1] >= min_coverage:
        while lo < hi:
            mid = (lo + hi) // 2
            if at(mid)[1] >= min_coverage:
                hi = mid
            else:
                lo = mid + 1
    ls, cov = at(hi)
    return ls, cov, _EXTEND_LEVELS[hi]


# GIS fields come with thousands of vertices: above this many the lanes are planned on
# the field simplified within a tolerance tied to the lane spacing (coverage is still
# measured on the field itself)
_MAX_VERTICES = 256
_SIMPLIFY_SPACINGS = 0.05  # simplification tolerance, in lane spacings


def _vertex_count(g: BaseGeometry) -> int:
    return int(shapely.get_num_coordinates(g))


def simplified(region: Region, spacing_m: float) -> Region:
    """The region whose cover has at most about `_MAX_VERTICES` vertices: the cover
    simplified within a tolerance (Douglas-Peucker) then grown by it, so it contains the
    original cover and lanes planned on it see all of it. The tolerance starts at 5 %
    of the lane spacing and doubles, up to half a spacing, until the cover is small
    enough. The keep-out, obstacles, polygon and coverage target stay exact. Unchanged
    when already small."""
    if _vertex_count(region.cover) <= _MAX_VERTICES:
        return region
    tol = _SIMPLIFY_SPACINGS * spacing_m
    best = region
    while tol <= 0.5 * spacing_m + 1e-9:
        # every vertex dropped is within tol of the simplified boundary: grown by tol
        # (mitred corners, a few vertices each) it contains the original
        thin = region.cover.simplify(tol, preserve_topology=True)
        cover = _polygonal(thin.buffer(tol, join_style="mitre", mitre_limit=2.0))
        if not cover.is_empty and cover.is_valid:
            best = Region(cover, region.keep_out, region.polygon, region.obstacles, region.target)
            if _vertex_count(cover) <= _MAX_VERTICES:
                break
        tol *= 2.0
    return best


def estimated_flight_s(
    region: Region, spacing_m: float, turns: TurnModel, speed_m_s: float
) -> float:
    """A quick estimate of the time to fly the whole region at `speed_m_s` (before any
    planning): lane length (area / spacing) plus one turn per lane across the region's
    extent, for the sweep along its longer side."""
    if not (math.isfinite(speed_m_s) and speed_m_s > 0.0):
        raise InvalidParameterError(f"speed must be > 0, got {speed_m_s}")
    x0, y0, x1, y1 = region.cover.bounds
    n_lanes = math.ceil(min(x1 - x0, y1 - y0) / spacing_m)
    turn = SweepCost.for_turns(turns, spacing_m).turn_m
    return (region.cover.area / spacing_m + n_lanes * turn) / speed_m_s


def check_flyable(
    region: Region, spacing_m: float, turns: TurnModel, speed_m_s: float, max_flight_s: float
) -> float:
    """The estimated flight time (s) of the region, or FieldTooBigError when it is over
    `max_flight_s`: a field too big to fly is refused before it is planned."""
    est = estimated_flight_s(region, spacing_m, turns, speed_m_s)
    if est > max_flight_s:
        raise FieldTooBigError(
            f"field too big to fly: about {est / 3600.0:.1f} h of flight "
            f"(limit {max_flight_s / 3600.0:.1f} h) at {speed_m_s:.1f} m/s",
            est,
        )
    return est


def plan_lanes(
    region: Region,
    spacing_m: float,
    turns: TurnModel,
    *,
    min_coverage: float = 0.99,
    start: Pose | None = None,
    top: int = 3,
    polish: bool = True,
) -> LanePlan:
    """decompose's region -> lanes -> order -> connect, choosing among the `top` sweep
    directions (and small nudges of the best one) and three lane-grid placements the
    one with the shortest path, each with the least lane extension that reaches
    `min_coverage` at the lane spacing. `polish=False` keeps only the best direction
    and the centred grid (about ten times faster)."""
    if not 0.0 < min_coverage <= 1.0:
        raise InvalidParameterError(f"min_coverage must be in (0, 1], got {min_coverage}")
    region = simplified(region, spacing_m)
    cands = [
        a
        for _c, a in sweep_angles(region, spacing_m, SweepCost.for_turns(turns, spacing_m), top=top)
    ]
    if polish:
        cands += [cands[0] + math.radians(n) for n in _NUDGES_DEG]
    else:
        cands = cands[:1]
    plans: list[LanePlan] = []
    # without obstacles no transition is rerouted: a path's length is its lanes plus
    # the order's transition costs, and only the chosen order needs connecting
    lazy = region.obstacles.is_empty
    unconnected: list[tuple[bool, float, int, LanePlan, tuple[Lane, ...]]] = []
    seen: set[tuple[Lane, ...]] = set()
    for angle in cands:
        for shift in _SHIFTS if polish else _SHIFTS[:1]:
            ls, cov, ext = _least_extension(region, angle, spacing_m, shift, min_coverage)
            if not ls:
                continue
            if lazy:
                if ls in seen:  # the same lanes as another placement (no slack): same path
                    continue
                seen.add(ls)
                seq, cost = _order(ls, turns, start, 0)  # its cheapest seed pattern
                length = sum(ln.length_m for ln in ls) + cost
                stub = LanePlan(angle, spacing_m, ext, ls, CoveragePath((), ()), cov, 0.0)
                unconnected.append((cov >= min_coverage, -length, -len(unconnected), stub, seq))
                continue
            path = connect(order(ls, turns, start, improve=False), turns, region.obstacles, start)
            plans.append(LanePlan(angle, spacing_m, ext, ls, path, cov, 0.0))
    if unconnected:
        *_k, stub, _seq = max(unconnected, key=lambda u: u[:3])
        seq = order(stub.lanes, turns, start, improve=False)
        path = connect(seq, turns, region.obstacles, start)
        plans.append(
            LanePlan(stub.angle_rad, spacing_m, stub.extend, stub.lanes, path, stub.coverage, 0.0)
        )

    def rank(p: LanePlan) -> tuple[bool, float]:
        return p.coverage >= min_coverage, -p.path.length_m

    plans.sort(key=rank, reverse=True)
    if plans and plans[0].coverage < min_coverage:
        # ground left unseen beside the zones: gap lanes for the shortest few, then
        # the shortest again (filling every candidate costs ten times more)
        filled = []
        for p in plans[:_GAP_CANDIDATES]:
            ls, cov = fill_gaps(region, p.lanes, p.angle_rad, spacing_m, min_coverage)
            path = connect(order(ls, turns, start, improve=False), turns, region.obstacles, start)
            filled.append(LanePlan(p.angle_rad, spacing_m, p.extend, ls, path, cov, 0.0))
        plans = sorted(filled + plans, key=rank, reverse=True)
    best = plans[0] if plans else None
    if best is None:
        raise EmptyAreaError("no lane fits in the area")
    path = best.path
    if LOCAL_SEARCH:
        # the chosen lanes' order improved, kept if shorter as connected (improving every
        # candidate's would find irregular6's 24231 m path, 80 m shorter, for some 20 ms
        # more of a 50-80 ms plan; the planning budget is 100 ms)
        better = connect(
            order(best.lanes, turns, start, restarts=4, improve=True),
            turns,
            region.obstacles,
            start,
        )
        if better.length_m < path.length_m - 1e-9:
            path = better
    return LanePlan(
        best.angle_rad,
        spacing_m,
        best.extend,
        best.lanes,
        path,
        best.coverage,
        overlap_ratio(best.lanes, region.target, spacing_m),
    )
