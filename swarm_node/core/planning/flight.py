"""Flyable fixed-wing waypoint sequences: what an ArduPlane-like autopilot flies, and a
stage that makes every corner of a plan one it can fly as planned.

An autopilot in AUTO accepts a waypoint once within its acceptance radius (or past
the line through it square to the leg), then turns at its turn radius towards the
next waypoint, to the side of the smaller heading change. At a corner sharper than
that turn can follow within the acceptance radius the flown path leaves the planned
one, by up to two turn radii at a reversal, and to whichever side is shorter: into a
no-fly zone, if one is there. The planners sample their own turns (Dubins arcs every
30 degrees) but some corners come from polylines that know nothing of headings:
detours around zones (visibility graph), a route's points, the join between an
approach and the plan, the way home.

`flyable_course` finds every corner the aircraft cannot make within `CORNER_TOL_M` of
the planned path and replaces the connection by an explicit Dubins path, sampled into
waypoints, from the pose at the corner to a later pose of the plan: the shortest of
the six words (and of the later waypoints it may rejoin at, passing every waypoint the
plan must pass) whose sampled path keeps `TURN_CLEARANCE_M` clear of the zones, less
clearance only where an end of it is nearer a zone than that. Straight legs that must
be flown as they are (coverage lanes) are entered aligned. With no clear connection it
raises `NoSafeRouteError`; it never returns a corner it could not make flyable.
`predict_flight` is the autopilot model; `flight_problems` checks a sequence with it.
`flyable_plan` applies the stage to every fixed-wing share of a plan and keeps the
plan's `tracks` what is uploaded.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt
import shapely
from shapely.geometry import LineString
from shapely.geometry.base import BaseGeometry

from swarm_node.core.autopilot.items import ItemKind, Waypoint
from swarm_proto import NoFlyZone

from ..margins import FIXED_WING_KEEP_M
from .dubins import DubinsPath, FloatArray, Pose, Word, all_paths
from .errors import InvalidParameterError, NoSafeRouteError
from .geo import LocalFrame
from .vehicles import PlanVehicle
from .zones import ARC_STEP_M, Track, ZoneSet

XY = tuple[float, float]

#: Fixed-wing waypoint acceptance the mission manager asks for on every plain waypoint.
#: ArduPlane's WP_RADIUS default (90 m) makes a plane count the closely spaced
#: waypoints of a planned turn as reached at once and head for one behind it, looping
#: wide; the autopilot also accepts a waypoint it has flown past.
FIXED_WING_ACCEPT_M = 15.0
#: Least clearance from a zone of the turns this stage adds. ArduPlane does not fly
#: them as planned: a SITL QuadPlane (quadplane.parm, NAVL1_PERIOD 14) passed their
#: sampled waypoints 24-37 m on their inside ("Passed waypoint #92 dist 26m") and,
#: with 20 m here, entered a 35 m zone by 4.9 m (`make sitl-check`): what ArduPlane
#: cuts, plus the clearance it must keep as flown (margins.FIXED_WING_KEEP_M).
TURN_CLEARANCE_M = FIXED_WING_KEEP_M
#: How far the flown path may leave the planned one at a corner it keeps.
CORNER_TOL_M = 6.0
#: The zone clearance the flown path (as `predict_flight` predicts it) is checked for.
FLOWN_CLEARANCE_M = 0.0
MAX_TURN_SAMPLE_RAD = math.pi / 6  # arcs become waypoints at most this far apart

_MERGE_M = 0.5  # consecutive waypoints this close are one
_HEADING_VARIANTS = (0.0, math.pi / 4, -math.pi / 4, math.pi / 2, -math.pi / 2)
_MAX_REJOIN = 80  # later waypoints a connection may rejoin the plan at
_VIA_ARCS = tuple(
    (left, math.radians(a)) for left in (True, False) for a in (90.0, 180.0, 270.0)
)  # arcs a blocked turn may start or end with


# --------------------------------------------------------------------------- corners


def corner_overshoot_m(turn_rad: float, radius_m: float, accept_m: float) -> float:
    """How far outside the planned corner an aircraft flies that starts turning, at
    `radius_m`, `accept_m` before the corner: (R tan(t/2) - a) sin t for turns up to 90
    degrees (the turn starts that late and carries it across the outgoing leg), the
    lateness itself beyond; 0 when the turn fits within the acceptance radius."""
    t = abs(turn_rad)
    if t < 1e-9:
        return 0.0
    if t >= math.pi - 1e-9:
        return math.inf
    late = radius_m * math.tan(t / 2.0) - accept_m
    if late <= 0.0:
        return 0.0
    return late * (math.sin(t) if t < math.pi / 2 else 1.0)


def max_corner_rad(radius_m: float, accept_m: float, tol_m: float = CORNER_TOL_M) -> float:
    """The sharpest corner an aircraft turning at `radius_m` flies within `tol_m` of
    the plan (`corner_overshoot_m`), at most 90 degrees."""
    lo, hi = 0.0, math.pi / 2
    if corner_overshoot_m(hi, radius_m, accept_m) <= tol_m:
        return hi
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if corner_overshoot_m(mid, radius_m, accept_m) <= tol_m:
            lo = mid
        else:
            hi = mid
    return lo


def _arc(start: Pose, left: bool, angle_rad: float, radius_m: float) -> DubinsPath:
    """A plain arc from `start`, to the left or right."""
    return DubinsPath(start, Word.LSL if left else Word.RSR, angle_rad, 0.0, 0.0, radius_m)


def _arc_into(goal: Pose, left: bool, angle_rad: float, radius_m: float) -> DubinsPath:
    """The arc to the left or right that ends at `goal`."""
    back = _arc(Pose(goal.x, goal.y, goal.yaw + math.pi), not left, angle_rad, radius_m).end
    return _arc(Pose(back.x, back.y, back.yaw + math.pi), left, angle_rad, radius_m)


def _yaw(a: XY, b: XY) -> float:
    return math.atan2(b[1] - a[1], b[0] - a[0])


def _turn(a: float, b: float) -> float:
    """Signed heading change from yaw `a` to yaw `b`, in (-pi, pi]."""
    return math.remainder(b - a, 2.0 * math.pi)


# --------------------------------------------------------------------------- predictor


@dataclass(frozen=True, slots=True)
class FlownPath:
    """What `predict_flight` predicts: positions every step, and for each the index of
    the waypoint being flown to (len(waypoints) once all are reached)."""

    points: FloatArray  # (n, 2)
    target: npt.NDArray[np.intp]  # (n,)
    reached: int  # waypoints reached, in order

    def leg(self, k: int) -> FloatArray:
        """The positions flown towards waypoint `k` (the one before included)."""
        idx = np.flatnonzero(self.target == k)
        if len(idx) == 0:
            return np.zeros((0, 2))
        return self.points[max(idx[0] - 1, 0) : idx[-1] + 1]


def predict_flight(
    waypoints: Sequence[XY],
    *,
    radius_m: float,
    accept_m: float = FIXED_WING_ACCEPT_M,
    start: Pose | None = None,
    step_m: float = 1.0,
) -> FlownPath:
    """The path an ArduPlane-like autopilot flies through `waypoints` (local metres):
    from `start` (default: the first waypoint, heading at the second, which counts as
    reached), it flies at each waypoint in turn, turning at `radius_m` towards it (to
    the side of the smaller heading change) and flying straight once it points at it;
    a waypoint is reached within `accept_m` or once past the line through it square
    to the leg from the previous one, and the aircraft turns at once for the next.
    A waypoint not reached after flying its distance plus two full circles ends the
    prediction there (`reached` tells how far it got)."""
    if not (math.isfinite(radius_m) and radius_m > 0.0):
        raise InvalidParameterError(f"turn radius must be > 0, got {radius_m}")
    if not (math.isfinite(step_m) and step_m > 0.0):
        raise InvalidParameterError(f"step must be > 0, got {step_m}")
    wps = [(float(x), float(y)) for x, y in waypoints]
    if start is None:
        if len(wps) < 2:
            pts = np.asarray(wps, dtype=np.float64).reshape(-1, 2)
            return FlownPath(pts, np.full(len(pts), len(wps), dtype=np.intp), len(wps))
        x, y = wps[0]
        yaw = _yaw(wps[0], wps[1])
        k = 1
    else:
        x, y, yaw = start.x, start.y, start.yaw
        k = 0
    ox, oy = x, y  # where the current leg started (the previous waypoint)
    max_turn = step_m / radius_m
    xs, ys, tg = [x], [y], [k]
    budget = 0
    steps = 0
    while k < len(wps):
        tx, ty = wps[k]
        dx, dy = tx - x, ty - y
        d = math.hypot(dx, dy)
        if steps == 0:
            budget = math.ceil((d + 4.0 * math.pi * radius_m) / step_m) + 10
        ln, le = tx - ox, ty - oy
        passed = math.hypot(ln, le) >= 1.0 and (x - tx) * ln + (y - ty) * le > 0.0
        if d <= accept_m or passed:
            ox, oy = tx, ty
            k += 1
            steps = 0
            tg[-1] = k
            continue
        if steps >= budget:
            break
        err = math.remainder(math.atan2(dy, dx) - yaw, 2.0 * math.pi)
        yaw += min(max(err, -max_turn), max_turn)
        x += step_m * math.cos(yaw)
        y += step_m * math.sin(yaw)
        xs.append(x)
        ys.append(y)
        tg.append(k)
        steps += 1
    return FlownPath(
        np.column_stack([np.asarray(xs), np.asarray(ys)]), np.asarray(tg, dtype=np.intp), k
    )


# --------------------------------------------------------------------------- the stage


@dataclass(frozen=True, slots=True)
class Piece:
    """A stretch of the flown course: a kept straight leg (two points) or an added
    turn (sampled every couple of metres), with its altitude band."""

    points: tuple[XY, ...]
    alt_lo_m: float
    alt_hi_m: float
    turn: bool


@dataclass(frozen=True, slots=True)
class Course:
    """A flyable waypoint sequence: `points` (local) with their altitudes, `source` the
    input index of each (-1: a point of an added turn), and the pieces it is flown as
    (from the start pose, when there is one)."""

    points: tuple[XY, ...]
    alts: tuple[float, ...]
    source: tuple[int, ...]
    pieces: tuple[Piece, ...]
    added_m: float  # length added to the planned polyline


class _Blocked:
    """The zones inflated by a clearance, per altitude band (cached)."""

    def __init__(self, zones: ZoneSet, clearance_m: float) -> None:
        self.zones = zones
        self.clearance_m = clearance_m
        self._cache: dict[tuple[float, float], BaseGeometry | None] = {}

    def at(self, lo: float, hi: float) -> BaseGeometry | None:
        key = (round(lo, 3), round(hi, 3))
        if key not in self._cache:
            zs = self.zones.at(lo, hi)
            if not zs:
                self._cache[key] = None
            else:
                g = ZoneSet(zs, self.clearance_m).keep_out(None).buffer(-1e-6)
                shapely.prepare(g)
                self._cache[key] = g
        return self._cache[key]

    def clear(self, xy: FloatArray, lo: float, hi: float) -> bool:
        g = self.at(lo, hi)
        if g is None or len(xy) == 0:
            return True
        geom = LineString(xy) if len(xy) > 1 else shapely.Point(xy[0])
        return not bool(g.intersects(geom))

    def contains(self, p: XY, lo: float, hi: float) -> bool:
        g = self.at(lo, hi)
        return g is not None and bool(g.intersects(shapely.Point(p)))


def flyable_course(
    points: Sequence[XY],
    alts: Sequence[float],
    zones: ZoneSet,
    *,
    radius_m: float,
    accept_m: float = FIXED_WING_ACCEPT_M,
    clearance_m: float = TURN_CLEARANCE_M,
    start_yaw: float | None = None,
    straight: frozenset[int] = frozenset(),
    free: frozenset[int] = frozenset(),
    tol_m: float = CORNER_TOL_M,
) -> Course:
    """`points` (local, with `alts`) made flyable at `radius_m` for an autopilot with
    `accept_m` acceptance (module docstring). The aircraft is at `points[0]` heading
    `start_yaw` (None: heading along the first leg). `straight` holds the indexes i
    whose leg i -> i+1 must be flown as it is (entered aligned); `free` the indexes of
    points the course need not pass (the others it passes, though not necessarily
    along the planned legs).

    Walking the legs, a corner the aircraft cannot make (`sharp_ahead`), or a straight
    leg it would reach misaligned, is replaced by a connection: a Dubins path from a
    pose it flies through since the last point it had to pass (the corner itself, or
    earlier, or a little further along its heading) to a later pose of the plan (the
    next points up to the next one it must pass, heading along their legs or turned up
    to 90 degrees; a straight leg's start heading along it, or a little before it on
    its line), the cheapest whose sampled path keeps `clearance_m` clear of the zones
    in its altitude band. Less clearance only for a corner with an end it must pass
    near a zone (turning there may need to come closer): a half or a quarter of it
    for an end within a turn radius of that clearance, none for an end within a
    quarter of it. Raises `NoSafeRouteError` when none is clear."""
    if not (math.isfinite(radius_m) and radius_m > 0.0):
        raise InvalidParameterError(f"turn radius must be > 0, got {radius_m}")
    if len(points) != len(alts):
        raise InvalidParameterError("points and altitudes differ in length")
    pts = [(float(x), float(y)) for x, y in points]
    n = len(pts) - 1
    if n < 0:
        return Course((), (), (), (), 0.0)
    limit = max_corner_rad(radius_m, accept_m, tol_m)
    sample_rad = min(MAX_TURN_SAMPLE_RAD, limit)
    levels = (clearance_m, clearance_m / 2, clearance_m / 4, 0.0)
    blocked = [_Blocked(zones, c) for c in levels]
    # an end this near a zone may need to turn closer to it than the clearance: half
    # or a quarter of it within a turn radius of the clearance, none only inside it
    nearby = [_Blocked(zones, c + (radius_m if c > levels[2] else 0.0)) for c in levels]
    leads = (0.0, radius_m / 2, radius_m, 2 * radius_m)  # lead-ins / lead-outs on straight legs
    out: list[XY] = [pts[0]]
    out_alt: list[float] = [float(alts[0])]
    src: list[int] = [0]
    pieces: list[Piece] = []
    added = 0.0

    def seg_len(i: int) -> float:
        return math.dist(pts[i], pts[i + 1])

    def band(i: int, j: int) -> tuple[float, float]:
        a = [float(alts[k]) for k in range(min(i, j), max(i, j) + 1)]
        return min(a), max(a)

    def must(j: int) -> bool:
        return j not in free or j in straight or j == n

    def sharp_ahead(i: int, yaw: float) -> bool:
        """Whether flying on from `pts[i]` heading `yaw` meets corners the aircraft
        cannot make: the corner at i, or (legs too short for the turn between them)
        the turns at i, i+1, ... summed."""
        total = 0.0
        run = 0.0
        heading = yaw
        for k in range(i, n):
            if seg_len(k) < _MERGE_M:
                continue
            t = _turn(heading, _yaw(pts[k], pts[k + 1]))
            if k > i and (t * total < 0 or run >= radius_m * math.tan(min(abs(total), 3.0) / 2)):
                break  # turning the other way, or room to finish the turn
            total += t
            if abs(total) > limit:
                return True
            heading = _yaw(pts[k], pts[k + 1])
            run += seg_len(k)
        return False

    def flies_on(j: int, yaw: float, last: int) -> bool:
        """Whether the plan from `pts[j]` heading `yaw` to `pts[last]` (and into its
        leg, if that is straight) has no corner the aircraft cannot make."""
        for k in range(j, last + (1 if last in straight else 0)):
            if k >= n or seg_len(k) < _MERGE_M:
                continue
            if sharp_ahead(k, yaw):
                return False
            yaw = _yaw(pts[k], pts[k + 1])
        return True

    def remaining(j: int, last: int) -> float:
        return sum(seg_len(k) for k in range(j, last))

    def targets_from(i: int, variants: bool = False) -> list[tuple[int, float, float]]:
        """(index, heading, extra cost) of the poses a connection needed at i may end at:
        the points after i up to the next one it must pass (or i's own straight leg),
        heading along their legs or turned from them (a point it must pass: with
        `variants` only, as it leaves it facing another corner)."""
        if i in straight:
            return [(i, _yaw(pts[i], pts[i + 1]), 0.0)]
        out_t: list[tuple[int, float, float]] = []
        j = i + 1
        while j <= n and j - i <= _MAX_REJOIN:
            if j < n and seg_len(j) < _MERGE_M:
                j += 1
                continue
            if j == n:
                base = _yaw(pts[j - 1], pts[j]) if seg_len(j - 1) >= _MERGE_M else 0.0
                out_t += [(j, base + v, 0.0) for v in _HEADING_VARIANTS]
            elif j in straight:
                out_t.append((j, _yaw(pts[j], pts[j + 1]), 0.0))
            else:
                base = _yaw(pts[j], pts[j + 1])
                turned = _HEADING_VARIANTS if variants or not must(j) else (0.0,)
                out_t += [(j, base + v, radius_m * abs(v)) for v in turned]
            if must(j):
                break
            j += 1
        return out_t

    # the points flown through since the last one the course had to pass (or the end
    # of the last connection): (index, len(out), len(pieces), heading there, flown to it)
    window: list[tuple[int, int, int, float, float]] = []

    Window = tuple[int, int, int, float, float]
    Cand = tuple[float, Window, float, int, float, float, tuple[DubinsPath, ...]]

    def candidates(
        i: int, vias: bool, variants: bool = False, win: list[Window] | None = None
    ) -> list[Cand]:
        """The connections from a pose of the window (or `win`) to a target of
        `targets_from(i)`, cheapest first: every Dubins word; with `vias`, a first arc
        of 90, 180 or 270 degrees to either side before the word, or a last one after
        it (for a turn whose words all cross a zone: it turns away first, or comes
        round last)."""
        win = window if win is None else win
        targets = targets_from(i, variants)
        last = max(t[0] for t in targets)
        out_c: list[Cand] = []
        goes_on: dict[tuple[int, float], bool] = {}
        starts = win if not vias else [win[0]] + ([win[-1]] if len(win) > 1 else [])
        for w in starts:
            k, _o, _p, yaw_k, flown = w
            for lo_m in leads if k == i else (0.0,):
                s = Pose(*pts[k], yaw_k).forward(lo_m)
                for j, goal_yaw, extra in targets:
                    if vias and j != last:
                        continue
                    if j < last:
                        key = (j, goal_yaw)
                        if key not in goes_on:
                            goes_on[key] = flies_on(j, goal_yaw, last)
                        if not goes_on[key]:
                            continue  # rejoining there leads to a corner it cannot make
                    for li_m in leads if j in straight else (0.0,):
                        g = Pose(*pts[j], goal_yaw).forward(-li_m)
                        base = flown + lo_m + li_m + remaining(j, last) + extra
                        if not vias:
                            for path in all_paths(s, g, radius_m):
                                out_c.append(
                                    (base + path.length_m, w, lo_m, j, goal_yaw, li_m, (path,))
                                )
                            continue
                        for left, angle in _VIA_ARCS:
                            first = _arc(s, left, angle, radius_m)
                            for path in all_paths(first.end, g, radius_m):
                                length = first.length_m + path.length_m
                                out_c.append(
                                    (base + length, w, lo_m, j, goal_yaw, li_m, (first, path))
                                )
                            final = _arc_into(g, left, angle, radius_m)
                            for path in all_paths(s, final.start, radius_m):
                                length = final.length_m + path.length_m
                                out_c.append(
                                    (base + length, w, lo_m, j, goal_yaw, li_m, (path, final))
                                )
        out_c.sort(key=lambda c: c[0])
        return out_c

    def clear_cand(c: Cand, b: _Blocked) -> bool:
        _cost, w, _lo_m, j, _goal_yaw, _li, chain = c
        k = w[0]
        lo, hi = band(k, j)
        s, g = chain[0].start, chain[-1].end
        return (
            b.clear(np.asarray([pts[k], (s.x, s.y)]), lo, hi)
            and b.clear(np.asarray([(g.x, g.y), pts[j]]), lo, hi)
            and b.clear(np.concatenate([p.sample_xy(ARC_STEP_M) for p in chain]), lo, hi)
        )

    def can_leave(j: int, yaw: float, b: _Blocked) -> bool:
        """Whether the aircraft at `pts[j]` (a point it must pass) heading `yaw` can go
        on: no corner it cannot make ahead, or a connection clear at `b`'s clearance (a look one corner ahead, so that a connection never ends where
        the next one is impossible: heading at a zone close ahead)."""
        if j >= n or not (
            sharp_ahead(j, yaw)
            or (j + 1 in straight and j + 1 < n and sharp_ahead(j + 1, _yaw(pts[j], pts[j + 1])))
        ):
            return True
        here: list[Window] = [(j, 0, 0, yaw, 0.0)]
        for tier in range(3):
            for c in candidates(j, vias=tier == 2, variants=tier == 1, win=here):
                lo, hi = band(c[1][0], c[3])
                if not b.contains(pts[c[3]], lo, hi) and clear_cand(c, b):
                    return True
        return False

    def connect(i: int, yaw: float) -> None:
        tiers: list[list[Cand] | None] = [candidates(i, vias=False), None, None]
        near = False  # an end is within the clearance of a zone: less clearance allowed
        for b, b_near in zip(blocked, nearby, strict=True):
            for tier in range(3):  # the plain words, then arriving turned, then vias
                if tiers[tier] is None:
                    tiers[tier] = candidates(i, vias=tier == 2, variants=tier == 1)
                for c in tiers[tier] or []:
                    _cost, w, lo_m, j, goal_yaw, _li, chain = c
                    k = w[0]
                    lo, hi = band(k, j)
                    if b.contains(pts[k], lo, hi) or b.contains(pts[j], lo, hi):
                        near = True
                        continue  # an end this near a zone: tried with less clearance
                    near = (
                        near or b_near.contains(pts[k], lo, hi) or b_near.contains(pts[j], lo, hi)
                    )
                    if not clear_cand(c, b):
                        continue
                    if must(j) and j not in straight and not can_leave(j, goal_yaw, b):
                        continue
                    emit(w, lo_m, chain, j, goal_yaw)
                    return
            if not near:
                break
        raise NoSafeRouteError(
            f"no flyable turn at ({pts[i][0]:.0f}, {pts[i][1]:.0f}) at {radius_m:.0f} m "
            f"radius keeping {clearance_m:.0f} m clear of the no-fly zones"
        )

    def emit(
        w: Window, lo_m: float, chain: tuple[DubinsPath, ...], j: int, goal_yaw: float
    ) -> None:
        nonlocal added
        k, out_len, pieces_len, _yaw_k, _flown = w
        del out[out_len:], out_alt[out_len:], src[out_len:], pieces[pieces_len:]
        a0, a1 = float(alts[k]), float(alts[j])
        g = chain[-1].end
        total = lo_m + sum(p.length_m for p in chain) + math.dist((g.x, g.y), pts[j])
        added += total - remaining(k, j)

        def put(p: XY, s_m: float, source: int = -1) -> None:
            if math.dist(p, out[-1]) < _MERGE_M:
                if source >= 0:
                    src[-1] = source
                return
            out.append(p)
            out_alt.append(a0 + (a1 - a0) * (s_m / total if total > 0 else 1.0))
            src.append(source)

        trace: list[XY] = [pts[k]]
        s0 = lo_m
        if lo_m > 0.0:
            put((chain[0].start.x, chain[0].start.y), lo_m)
        for path in chain:
            for s in path.waypoint_s(sample_rad):
                q = path.pose_at(s)
                put((q.x, q.y), s0 + s)
            trace += [(float(x), float(y)) for x, y in path.sample_xy(ARC_STEP_M)]
            s0 += path.length_m
        trace.append(pts[j])
        if math.dist(pts[j], out[-1]) < _MERGE_M and src[-1] == -1:
            out.pop(), out_alt.pop(), src.pop()
        if j == k and math.dist(pts[j], out[-1]) < _MERGE_M:
            out.append(pts[j])  # round to the same point: it is passed again
            out_alt.append(a1)
            src.append(j)
        else:
            put(pts[j], total, j)
        out_alt[-1] = a1
        lo, hi = band(k, j)
        pieces.append(Piece(tuple(trace), lo, hi, True))
        window.clear()
        window.append((j, len(out), len(pieces), goal_yaw, 0.0))

    yaw = start_yaw
    window.append((0, 1, 0, yaw if yaw is not None else 0.0, 0.0))
    i = 0
    while i < n:
        if seg_len(i) < _MERGE_M and i not in straight:
            i += 1  # the same point again: passed already
            if must(i) and src[-1] >= 0:
                src[-1] = i
            if window:
                window[-1] = (i, *window[-1][1:])
            continue
        h = _yaw(pts[i], pts[i + 1])
        if yaw is None:
            yaw = h
            window[-1] = (i, window[-1][1], window[-1][2], h, window[-1][4])
        need = sharp_ahead(i, yaw)
        if not need and i not in straight and i + 1 in straight and i + 1 < n:
            need = sharp_ahead(i + 1, h)  # reaching a straight leg misaligned
        if not need and i not in straight and i + 1 < n and must(i + 1) and i + 1 not in straight:
            # flying on to a point it must pass: can it go on from there?
            need = not any(can_leave(i + 1, h, b) for b in blocked)
        if need:
            connect(i, yaw)
            i, yaw = window[-1][0], window[-1][3]
            continue
        out.append(pts[i + 1])
        out_alt.append(float(alts[i + 1]))
        src.append(i + 1)
        lo, hi = band(i, i + 1)
        pieces.append(Piece((pts[i], pts[i + 1]), lo, hi, False))
        flown = window[-1][4] + seg_len(i) if window else 0.0
        if must(i + 1):
            window.clear()
            flown = 0.0
        window.append((i + 1, len(out), len(pieces), h, flown))
        yaw, i = h, i + 1
    return Course(tuple(out), tuple(out_alt), tuple(src), tuple(pieces), added)


# --------------------------------------------------------------------------- checks


def flight_problems(
    points: Sequence[XY],
    alts: Sequence[float],
    zones: ZoneSet,
    *,
    radius_m: float,
    accept_m: float = FIXED_WING_ACCEPT_M,
    start: Pose | None = None,
    clearance_m: float = FLOWN_CLEARANCE_M,
    step_m: float = 2.0,
) -> list[str]:
    """Where the path `predict_flight` predicts through `points` comes within
    `clearance_m` of a zone (each stretch against the zones of its altitude band), or
    stops short of a waypoint. Empty when it flies them all clear."""
    flown = predict_flight(points, radius_m=radius_m, accept_m=accept_m, start=start, step_m=step_m)
    out = []
    if flown.reached < len(points):
        out.append(f"waypoint {flown.reached} is never reached (the aircraft circles)")
    zs = zones.with_margin(clearance_m)
    first = 0 if start is not None else 1
    for k in range(first, min(flown.reached + 1, len(points))):
        leg = flown.leg(k)
        if len(leg) == 0:
            continue
        a = [float(alts[k])] + ([float(alts[k - 1])] if k > 0 else [])
        z = zs.entered([tuple(p) for p in leg.tolist()], min(a), max(a), inflated=clearance_m > 0)
        if z is not None:
            x, y = leg[len(leg) // 2]
            out.append(
                f"the flown path to waypoint {k} enters zone {z.zone_id} near ({x:.0f}, {y:.0f})"
            )
    return out


# --------------------------------------------------------------------------- waypoints


def flyable_waypoints(
    waypoints: Sequence[Waypoint],
    frame: LocalFrame,
    zones: ZoneSet,
    *,
    radius_m: float,
    start: Pose | None = None,
    straight: frozenset[int] = frozenset(),
    free: frozenset[int] = frozenset(),
    accept_m: float = FIXED_WING_ACCEPT_M,
    clearance_m: float = TURN_CLEARANCE_M,
    vehicle_id: int = 0,
    check: bool = True,
) -> tuple[tuple[Waypoint, ...], tuple[Track, ...]]:
    """`flyable_course` over an uploadable waypoint list: each run of WAYPOINT items
    (other positioned items, loiters and landings, end a run; items without a position
    such as CHANGE_SPEED stay in order, before the next waypoint kept) made flyable, the
    first from `start` (the vehicle's pose; not a waypoint itself). `straight` and
    `free` hold item indexes. Returns the new list and its tracks (kind "leg" for a
    kept leg, "turn" for an added connection). With `check`, the path `predict_flight`
    predicts must stay out of the zones (`flight_problems`), else `NoSafeRouteError`."""
    items = list(waypoints)
    runs: list[list[int]] = []
    cur: list[int] = []
    for idx, w in enumerate(items):
        if w.kind == ItemKind.WAYPOINT:
            cur.append(idx)
        elif w.kind in (ItemKind.CHANGE_SPEED,):
            continue
        else:
            if cur:
                runs.append(cur)
            cur = []
    if cur:
        runs.append(cur)
    replaced: dict[int, list[Waypoint]] = {}  # first item of a run -> its new items
    dropped: set[int] = set()
    tracks: list[Track] = []
    for r, run in enumerate(runs):
        pts = [frame.to_local(items[k].lat_deg, items[k].lon_deg) for k in run]
        alts = [items[k].alt_rel_m for k in run]
        pos = {k: p for p, k in enumerate(run)}
        lead = 1 if (r == 0 and start is not None) else 0
        if lead:
            pts = [(start.x, start.y), *pts]  # type: ignore[union-attr]
            alts = [alts[0], *alts]
        st = frozenset(pos[k] + lead for k in straight if k in pos)
        fr = frozenset(pos[k] + lead for k in free if k in pos) | (
            frozenset({0}) if lead else frozenset()
        )
        course = flyable_course(
            pts,
            alts,
            zones,
            radius_m=radius_m,
            accept_m=accept_m,
            clearance_m=clearance_m,
            start_yaw=start.yaw if lead and start is not None else None,
            straight=st,
            free=fr,
        )
        if check:
            problems = flight_problems(
                course.points[lead:] if lead else course.points,
                course.alts[lead:] if lead else course.alts,
                zones,
                radius_m=radius_m,
                accept_m=accept_m,
                start=start if lead else None,
            )
            if problems:
                raise NoSafeRouteError(f"vehicle {vehicle_id}: {problems[0]}")
        # the new items of the run: do-items (no position) keep their place before the
        # waypoint they preceded, or before the turn that replaced it
        new: list[Waypoint] = []
        placed: set[int] = set()
        lo_item = run[0]
        for p, s in zip(range(len(course.points)), course.source, strict=True):
            if lead and p == 0:
                continue
            if s >= 0:
                item_idx = run[s - lead]
                for k in range(lo_item, item_idx + 1):
                    if k not in pos and k not in placed and items[k].kind != ItemKind.WAYPOINT:
                        new.append(items[k])
                        placed.add(k)
                lo_item = item_idx + 1
                new.append(items[item_idx])
            else:
                lat, lon = frame.to_geodetic(*course.points[p])
                new.append(Waypoint(ItemKind.WAYPOINT, lat, lon, course.alts[p]))
        for k in range(lo_item, run[-1] + 1):
            if k not in pos and k not in placed:
                new.append(items[k])
                placed.add(k)
        replaced[run[0]] = new
        dropped.update(range(run[0], run[-1] + 1))
        kinds = {True: "turn", False: "leg"}
        tracks += [
            Track(vehicle_id, kinds[pc.turn], pc.points, pc.alt_lo_m, pc.alt_hi_m)
            for pc in course.pieces
        ]
        if not course.pieces and course.points:
            tracks.append(Track(vehicle_id, "leg", (course.points[-1],), course.alts[-1]))
    out: list[Waypoint] = []
    for idx, w in enumerate(items):
        if idx in replaced:
            out += replaced[idx]
        elif idx not in dropped:
            out.append(w)
    return tuple(out), tuple(tracks)


# --------------------------------------------------------------------------- plans

#: track kinds that describe a share's waypoint legs (replaced by the flown course)
_PATH_KINDS = frozenset({"approach", "route", "lane", "transition", "leg", "turn"})


def _area_flags(plan: Any, vehicle_id: int, n_items: int) -> tuple[frozenset[int], frozenset[int]]:
    """Item indexes of an area share's lane starts (straight) and of the points of its
    transitions (free), from its coverage path."""
    path = plan.split.of(vehicle_id).path
    pts: list[XY] = []
    straight: set[int] = set()
    must: set[int] = set()
    for leg in path.legs:
        for k, p in enumerate(leg.points):
            if not pts or pts[-1] != p:
                pts.append(p)
            if leg.is_lane:
                must.add(len(pts) - 1)
                if k == 0:
                    straight.add(len(pts) - 1)
    offset = n_items - len(pts)  # the CHANGE_SPEED item first
    if offset < 0:
        return frozenset(), frozenset()
    free = {p for p in range(len(pts)) if p not in must}
    return (
        frozenset(s + offset for s in straight),
        frozenset(f + offset for f in free),
    )


def _start_pose(v: PlanVehicle, frame: LocalFrame) -> Pose | None:
    return Pose(*frame.pose(v.pose)) if v.pose is not None else None


def _speed(waypoints: Sequence[Waypoint]) -> float | None:
    return next(
        (w.speed_m_s for w in waypoints if w.kind == ItemKind.CHANGE_SPEED and w.speed_m_s), None
    )


def flyable_plan(
    plan: Any,
    vehicles: Sequence[PlanVehicle],
    zones: Sequence[NoFlyZone] = (),
    *,
    now_unix_s: float = 0.0,
    home_alt_msl_m: float = 0.0,
    accept_m: float = FIXED_WING_ACCEPT_M,
    clearance_m: float = TURN_CLEARANCE_M,
) -> Any:
    """`plan` (any planner's) with every fixed-wing share made flyable
    (`flyable_waypoints`, from the vehicle's pose at planning time) and its `tracks`
    the course each flies: those vehicles' legs replaced by the kept legs and added
    turns (loiter circles kept). An area plan's lanes stay straight and its
    transitions' points may be skipped; every other plan's waypoints are all passed.
    Turn radius: the vehicle's at its share's speed. Shares' lengths and times grow by
    what the turns add (an area plan's split and makespan stay the planner's)."""
    from .area import AreaPlan
    from .objective import ObjectivePlan

    if isinstance(plan, ObjectivePlan):
        targets = tuple(
            (
                p,
                flyable_plan(
                    t,
                    vehicles,
                    zones,
                    now_unix_s=now_unix_s,
                    home_alt_msl_m=home_alt_msl_m,
                    accept_m=accept_m,
                    clearance_m=clearance_m,
                ),
            )
            for p, t in plan.targets
        )
        return dataclasses.replace(plan, targets=targets)
    frame: LocalFrame = plan.frame
    zs = ZoneSet.from_messages(zones, frame, now_unix_s=now_unix_s, home_alt_msl_m=home_alt_msl_m)
    by_id = {v.vehicle_id: v for v in vehicles}
    new_shares = []
    tracks = list(plan.tracks)
    for share in plan.vehicles:
        v = by_id.get(share.vehicle_id)
        if v is None or not v.profile.is_fixed_wing or not share.waypoints:
            new_shares.append(share)
            continue
        speed = _speed(share.waypoints)
        r = v.profile.turn_radius_m(speed)
        straight, free = (
            _area_flags(plan, share.vehicle_id, len(share.waypoints))
            if isinstance(plan, AreaPlan)
            else (frozenset(), frozenset())
        )
        wps, new_tracks = flyable_waypoints(
            share.waypoints,
            frame,
            zs,
            radius_m=r,
            start=_start_pose(v, frame),
            straight=straight,
            free=free,
            accept_m=accept_m,
            clearance_m=clearance_m,
            vehicle_id=share.vehicle_id,
        )
        tracks = [
            t for t in tracks if not (t.vehicle_id == share.vehicle_id and t.kind in _PATH_KINDS)
        ]
        tracks += new_tracks
        added = _flown_m(new_tracks) - _flown_m(
            [t for t in plan.tracks if t.vehicle_id == share.vehicle_id and t.kind in _PATH_KINDS]
        )
        added = max(added, 0.0) if math.isfinite(added) else 0.0
        new_shares.append(
            dataclasses.replace(
                share,
                waypoints=wps,
                length_m=share.length_m + added,
                time_s=share.time_s + (added / speed if speed else 0.0),
            )
        )
    return dataclasses.replace(plan, vehicles=tuple(new_shares), tracks=tuple(tracks))


def _flown_m(tracks: Sequence[Track]) -> float:
    return sum(course_length_m(t.points) for t in tracks)


def course_length_m(points: Sequence[XY]) -> float:
    return sum(math.dist(a, b) for a, b in itertools.pairwise(points))
