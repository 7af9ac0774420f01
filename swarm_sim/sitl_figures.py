"""The figures `make sitl-fleet` gives, from the positions ArduPilot itself reported
(each SITL's SERIAL1, 10 Hz), never from the nodes' telemetry. Pure functions over
tracks: lists of `Fix` (wall time, position, armed), in a local frame at the base.

- `coverage`: the share of the coverable area (the field less the no-fly zones) a
  camera saw from the tracks flown on the survey: each stretch of track sweeps its
  footprint, `altitude x tan(HFOV / 2)` either side.
- `flown_twice`: the share of the survey tracks flown within half a lane spacing of
  another vehicle's survey track (two vehicles on the same lanes).
- `separations`: the least 3-D distance of every pair while both were airborne
  (armed and above `AIRBORNE_M`), on a common time grid.
- `zone_clearance`: the least horizontal distance from each vehicle's airborne track
  to the edge of each zone (negative: inside).
- `simultaneous_low`: neighbouring pads' vehicles low in the air at the same time
  (landings and take-offs not taken in turn).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from shapely.geometry import LineString, MultiLineString, Point, Polygon
from shapely.ops import unary_union

AIRBORNE_M = 2.0  # above home, armed: in the air
DANGER_M = 10.0
NEAR_M = 5.0


@dataclass(frozen=True, slots=True)
class Fix:
    t: float  # wall seconds (one clock for every vehicle)
    e: float  # east of the base, m
    n: float  # north of the base, m
    alt_rel: float  # above the vehicle's home
    alt_msl: float
    armed: bool

    @property
    def airborne(self) -> bool:
        return self.armed and self.alt_rel > AIRBORNE_M


def within(track: Sequence[Fix], spans: Iterable[tuple[float, float]]) -> list[list[Fix]]:
    """The stretches of `track` inside the time spans (each its own list)."""
    out = []
    for a, b in spans:
        part = [f for f in track if a <= f.t <= b]
        if len(part) >= 2:
            out.append(part)
    return out


def _line(part: Sequence[Fix]) -> LineString:
    return LineString([(f.e, f.n) for f in part])


def coverable(field: Polygon, zones: Sequence[tuple[float, float, float]]) -> Polygon:
    """The field less the zones (circles: east, north, radius)."""
    holes = [Point(e, n).buffer(r, 64) for e, n, r in zones]
    return field.difference(unary_union(holes)) if holes else field


def coverage(
    stretches: Mapping[int, Sequence[Sequence[Fix]]],
    hfov_deg: Mapping[int, float],
    region: Polygon,
    step_s: float = 1.0,
) -> float:
    """The share of `region` swept by the footprints along the stretches (per vehicle,
    its camera's horizontal field of view), sampled every `step_s`."""
    swept = []
    for vid, parts in stretches.items():
        tan = math.tan(math.radians(hfov_deg[vid]) / 2.0)
        for part in parts:
            pts = _thin(part, step_s)
            for a, b in itertools.pairwise(pts):
                half = max(0.0, min(a.alt_rel, b.alt_rel)) * tan
                if half > 0:
                    swept.append(LineString([(a.e, a.n), (b.e, b.n)]).buffer(half, 8))
    if not swept or region.area <= 0:
        return 0.0
    return float(unary_union(swept).intersection(region).area / region.area)


def _thin(part: Sequence[Fix], step_s: float) -> list[Fix]:
    out = [part[0]]
    for f in part[1:]:
        if f.t - out[-1].t >= step_s:
            out.append(f)
    if out[-1] is not part[-1]:
        out.append(part[-1])
    return out


def flown_twice(stretches: Mapping[int, Sequence[Sequence[Fix]]], spacing_m: float) -> float:
    """The share of all survey track length within `spacing_m / 2` of another vehicle's
    survey track."""
    lines = {
        vid: MultiLineString([_line(_thin(p, 0.5)) for p in parts])
        for vid, parts in stretches.items()
        if parts
    }
    total = twice = 0.0
    for vid, line in lines.items():
        others = [ln for v, ln in lines.items() if v != vid]
        total += line.length
        if others:
            near = unary_union([o.buffer(spacing_m / 2.0, 8) for o in others])
            twice += line.intersection(near).length
    return twice / total if total > 0 else 0.0


def resample(track: Sequence[Fix], grid: np.ndarray, gap_s: float = 1.0) -> np.ndarray:
    """(len(grid), 4): east, north, alt MSL, airborne (NaN where no fix within
    `gap_s`)."""
    out = np.full((len(grid), 4), np.nan)
    if len(track) < 2:
        return out
    t = np.array([f.t for f in track])
    cols = [
        np.array([f.e for f in track]),
        np.array([f.n for f in track]),
        np.array([f.alt_msl for f in track]),
        np.array([1.0 if f.airborne else 0.0 for f in track]),
    ]
    idx = np.clip(np.searchsorted(t, grid), 1, len(t) - 1)
    t0, t1 = t[idx - 1], t[idx]
    ok = (grid >= t[0]) & (grid <= t[-1]) & (t1 - t0 <= gap_s)
    w = np.where(t1 > t0, (grid - t0) / np.where(t1 > t0, t1 - t0, 1.0), 0.0)
    for k, c in enumerate(cols[:3]):
        out[:, k] = np.where(ok, c[idx - 1] + w * (c[idx] - c[idx - 1]), np.nan)
    out[:, 3] = np.where(ok, np.minimum(cols[3][idx - 1], cols[3][idx]), np.nan)
    return out


@dataclass(frozen=True, slots=True)
class PairSeparation:
    a: int
    b: int
    min_m: float  # inf: never both airborne
    at_t: float | None
    horizontal_m: float | None  # at that moment
    vertical_m: float | None


def separations(
    tracks: Mapping[int, Sequence[Fix]], t0: float, t1: float, step_s: float = 0.1
) -> list[PairSeparation]:
    grid = np.arange(t0, t1, step_s)
    res = {vid: resample(tr, grid) for vid, tr in tracks.items()}
    out = []
    ids = sorted(res)
    for i, a in enumerate(ids):
        for b in ids[i + 1 :]:
            ra, rb = res[a], res[b]
            both = (ra[:, 3] == 1.0) & (rb[:, 3] == 1.0)
            if not both.any():
                out.append(PairSeparation(a, b, math.inf, None, None, None))
                continue
            dh = np.hypot(ra[:, 0] - rb[:, 0], ra[:, 1] - rb[:, 1])
            dv = np.abs(ra[:, 2] - rb[:, 2])
            d = np.where(both, np.hypot(dh, dv), np.inf)
            k = int(np.argmin(d))
            out.append(
                PairSeparation(a, b, float(d[k]), float(grid[k]), float(dh[k]), float(dv[k]))
            )
    return out


def zone_clearance(
    track: Sequence[Fix], zones: Sequence[tuple[float, float, float]]
) -> float | None:
    """The least horizontal distance from the airborne track to any zone's edge."""
    air = [f for f in track if f.airborne]
    if not air or not zones:
        return None
    e = np.array([f.e for f in air])
    n = np.array([f.n for f in air])
    return float(min(np.min(np.hypot(e - ze, n - zn) - r) for ze, zn, r in zones))


def inside_zones(track: Sequence[Fix], zones: Sequence[tuple[float, float, float]]) -> int:
    """How many airborne fixes lie inside a zone (the fence breached)."""
    return sum(
        1
        for f in track
        if f.airborne and any(math.hypot(f.e - e, f.n - n) < r for e, n, r in zones)
    )


def simultaneous_low(
    tracks: Mapping[int, Sequence[Fix]],
    pads: Mapping[int, tuple[float, float]],
    t0: float,
    t1: float,
    near_m: float = 40.0,
    low_m: float = 15.0,
    step_s: float = 0.5,
) -> list[tuple[int, int, float]]:
    """Pairs of vehicles on neighbouring pads (closer than `near_m`) both airborne and
    below `low_m` within `near_m` of their pads at the same moment: (a, b, seconds)."""
    grid = np.arange(t0, t1, step_s)
    low: dict[int, np.ndarray] = {}
    for vid, tr in tracks.items():
        r = resample(tr, grid)
        pe, pn = pads[vid]
        alt_rel = np.interp(grid, [f.t for f in tr], [f.alt_rel for f in tr]) if tr else None
        if alt_rel is None:
            continue
        at_pad = np.hypot(r[:, 0] - pe, r[:, 1] - pn) < near_m
        low[vid] = (r[:, 3] == 1.0) & at_pad & (alt_rel < low_m)
    out = []
    ids = sorted(low)
    for i, a in enumerate(ids):
        for b in ids[i + 1 :]:
            if math.dist(pads[a], pads[b]) >= near_m:
                continue
            both = float(np.sum(low[a] & low[b]) * step_s)
            if both > 0:
                out.append((a, b, both))
    return out


def field_polygon(corners: Sequence[tuple[float, float]]) -> Polygon:
    return Polygon(corners)
