"""Invariant checkers shared by the tests and usable at run time (like Fields2Cover's
isPathCorrect): each returns a list of human-readable problems, empty when all holds."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

from shapely.geometry.base import BaseGeometry

from swarm_node.core.autopilot.items import ItemKind, Waypoint

from .coverage import CoveragePath, Lane, coverage_ratio
from .dubins import DubinsPath
from .geo import LocalFrame
from .route import Arrival, Leg
from .zones import Track, ZoneSet, circle_points

_POSITIONED = {
    ItemKind.WAYPOINT,
    ItemKind.LOITER_TURNS,
    ItemKind.LOITER_TIME,
    ItemKind.LOITER_UNLIMITED,
    ItemKind.LAND,
}


def dubins_problems(path: DubinsPath, *, step_m: float = 1.0, tol_m: float = 1e-6) -> list[str]:
    """Continuity in position and heading along the path, and no curvature above 1/R:
    between samples `ds` apart the heading turns by at most ds / R and the chord is
    at least 2 R sin(ds / 2R)."""
    out: list[str] = []
    r = path.radius_m
    n = max(2, math.ceil(path.length_m / step_m))
    ds = path.length_m / n
    prev = path.pose_at(0.0)
    if abs(prev.x - path.start.x) + abs(prev.y - path.start.y) > tol_m:
        out.append("path does not start at its start pose")
    for i in range(1, n + 1):
        cur = path.pose_at(ds * i)
        chord = math.hypot(cur.x - prev.x, cur.y - prev.y)
        turn = abs(math.remainder(cur.yaw - prev.yaw, 2 * math.pi))
        if chord > ds + tol_m:
            out.append(f"position jumps {chord:.6f} m over {ds:.6f} m at s={ds * i:.3f}")
        if turn > ds / r + 1e-9:
            out.append(f"heading turns {turn:.6f} rad over {ds:.6f} m (> ds/R) at s={ds * i:.3f}")
        if chord < 2 * r * math.sin(min(ds / (2 * r), math.pi / 2)) - tol_m:
            out.append(f"curvature above 1/R at s={ds * i:.3f}")
        prev = cur
        if len(out) > 5:
            break
    return out


def coverage_problems(
    lanes: Sequence[Lane], area: BaseGeometry, spacing_m: float, min_coverage: float
) -> list[str]:
    cov = coverage_ratio(lanes, area, spacing_m)
    return [] if cov >= min_coverage else [f"coverage {cov:.4f} < {min_coverage}"]


def path_problems(path: CoveragePath, obstacles: BaseGeometry | None = None) -> list[str]:
    """Legs join end to start; no leg crosses the interior of `obstacles`."""
    out: list[str] = []
    for a, b in zip(path.legs[:-1], path.legs[1:], strict=True):
        if math.dist(a.points[-1], b.points[0]) > 1e-6:
            out.append(f"gap of {math.dist(a.points[-1], b.points[0]):.3f} m between legs")
    if obstacles is not None and not obstacles.is_empty:
        from shapely.geometry import LineString

        inner = obstacles.buffer(-1e-6)
        for leg in path.legs:
            if len(leg.points) > 1 and LineString(leg.points).intersects(inner):
                out.append("a leg enters a no-fly zone")
    return out


def waypoint_zone_problems(
    waypoints: Sequence[Waypoint],
    zones: ZoneSet,
    frame: LocalFrame,
    *,
    start: tuple[float, float, float] | None = None,
) -> list[str]:
    """No positioned item inside a zone, no straight leg between consecutive positioned
    items crossing one (altitude band of the leg against floor and ceiling)."""
    pts = [start] if start is not None else []
    for w in waypoints:
        if w.kind in _POSITIONED:
            x, y = frame.to_local(w.lat_deg, w.lon_deg)
            pts.append((x, y, w.alt_rel_m))
    return [
        f"zone {c.zone_id}: "
        + (
            f"waypoint {c.index} inside"
            if c.leg_end is None
            else f"leg {c.index}->{c.leg_end} crosses"
        )
        for c in zones.conflicts(pts)
    ]


def arrival_spread_s(legs: Sequence[Leg], arrivals: Mapping[int, Arrival]) -> float:
    """Largest difference between the vehicles' arrival times recomputed from what
    each flies (path + orbits, or hold + path) at its planned speed."""
    times = []
    for leg in legs:
        a = arrivals[leg.vehicle_id]
        if not (leg.min_speed_m_s - 1e-9 <= a.speed_m_s <= leg.max_speed_m_s + 1e-9):
            return math.inf
        times.append(a.hold_s + a.flown_m(leg) / a.speed_m_s)
    return max(times) - min(times) if times else 0.0


def track_zone_problems(tracks: Sequence[Track], zones: ZoneSet) -> list[str]:
    """No planned track (approach, waiting orbit, target orbit, patrol loop, landing
    leg, all sampled along their arcs) enters a zone's interior in its altitude band.
    Checked against the zones as given (the margin is the planner's business)."""
    out = []
    for t in tracks:
        z = zones.entered_track(t, inflated=False)
        if z is not None:
            out.append(f"vehicle {t.vehicle_id}: {t.kind} track enters zone {z.zone_id}")
    return out


def track_cover_problems(
    vehicle_id: int,
    waypoints: Sequence[Waypoint],
    tracks: Sequence[Track],
    frame: LocalFrame,
    *,
    tol_m: float = 1.0,
) -> list[str]:
    """The tracks describe what is uploaded: every positioned item of `waypoints` lies
    on one of the vehicle's tracks, and every loiter circle (with a radius) is one of
    them, within `tol_m`."""
    from shapely.geometry import LineString, MultiPoint, Point

    mine = [t for t in tracks if t.vehicle_id == vehicle_id]
    if not mine:
        if not any(w.kind in _POSITIONED for w in waypoints):
            return []  # an empty share (the others fly it all): nothing to describe
        return [f"vehicle {vehicle_id}: no tracks"]
    geoms = [LineString(t.points) if len(t.points) > 1 else Point(t.points[0]) for t in mine]
    out = []
    for i, w in enumerate(waypoints):
        if w.kind not in _POSITIONED:
            continue
        x, y = frame.to_local(w.lat_deg, w.lon_deg)
        if w.loiter_radius_m and w.kind != ItemKind.WAYPOINT:
            ring = MultiPoint(circle_points(x, y, abs(w.loiter_radius_m), 10.0))
            if not any(g.buffer(tol_m).contains(ring) for g in geoms):
                out.append(f"vehicle {vehicle_id}: item {i} ({w.kind.name}) circle not on a track")
        elif min(g.distance(Point(x, y)) for g in geoms) > tol_m:
            out.append(f"vehicle {vehicle_id}: item {i} ({w.kind.name}) not on a track")
    return out
