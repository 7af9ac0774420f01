"""No-fly zone manager: zones in the local frame, route/zone conflicts with floor and
ceiling, and avoidance (climb over a zone whose ceiling the vehicle can clear, else a
lateral reroute around the inflated zones along the shortest path of a visibility
graph, else `NoSafeRouteError`: the mission must be replanned)."""

from __future__ import annotations

import heapq
import itertools
import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
import shapely
import shapely.ops
from shapely.geometry import LineString, Point, Polygon
from shapely.geometry.base import BaseGeometry

from swarm_proto import GeometryKind, NoFlyZone

from .errors import InvalidGeometryError, InvalidParameterError, NoSafeRouteError
from .geo import LocalFrame

XYZ = tuple[float, float, float]  # local x, y (m) and altitude above home (m)

_CLEAR_M = 0.5  # visibility-graph nodes sit this far outside the inflated zones


@dataclass(frozen=True, slots=True)
class Zone:
    """One no-fly zone in the local frame; altitudes above home (converted from MSL)."""

    zone_id: int
    polygon: Polygon
    floor_rel_m: float = -math.inf
    ceiling_rel_m: float = math.inf

    def applies_at(self, alt_lo_m: float, alt_hi_m: float | None = None) -> bool:
        """Whether the altitude band [lo, hi] overlaps the zone's [floor, ceiling]."""
        hi = alt_lo_m if alt_hi_m is None else alt_hi_m
        return hi >= self.floor_rel_m and alt_lo_m <= self.ceiling_rel_m


@dataclass(frozen=True, slots=True)
class ZoneSet:
    """The zones that apply to a plan. `margin_m` is the lateral clearance kept from every
    zone (the zones are inflated by it for routing); `vertical_margin_m` the clearance
    above a ceiling when climbing over."""

    zones: tuple[Zone, ...] = ()
    margin_m: float = 0.0
    vertical_margin_m: float = 20.0

    def __post_init__(self) -> None:
        if not (math.isfinite(self.margin_m) and self.margin_m >= 0.0):
            raise InvalidParameterError(f"zone margin must be >= 0, got {self.margin_m}")

    @classmethod
    def from_messages(
        cls,
        zones: Iterable[NoFlyZone],
        frame: LocalFrame,
        *,
        now_unix_s: float,
        home_alt_msl_m: float = 0.0,
        margin_m: float = 0.0,
        vertical_margin_m: float = 20.0,
    ) -> ZoneSet:
        """The zones valid at `now_unix_s`, in `frame`, altitudes relative to home."""
        out: list[Zone] = []
        for z in zones:
            if z.valid_from_unix_s > now_unix_s:
                continue
            if z.valid_until_unix_s is not None and z.valid_until_unix_s <= now_unix_s:
                continue
            if z.geometry.kind not in (GeometryKind.POLYGON, GeometryKind.CIRCLE):
                raise InvalidGeometryError(
                    f"zone {z.zone_id}: a no-fly zone is a POLYGON or CIRCLE, "
                    f"got {z.geometry.kind.name}"
                )
            poly = frame.shape(z.geometry, circumscribe=True)
            assert isinstance(poly, Polygon)
            out.append(
                Zone(
                    z.zone_id,
                    Polygon(poly.exterior),  # zones have no holes
                    z.floor_alt_msl_m - home_alt_msl_m,
                    z.ceiling_alt_msl_m - home_alt_msl_m,
                )
            )
        return cls(tuple(out), margin_m, vertical_margin_m)

    def with_margin(self, margin_m: float) -> ZoneSet:
        return ZoneSet(self.zones, margin_m, self.vertical_margin_m)

    def at(self, alt_lo_m: float | None, alt_hi_m: float | None = None) -> tuple[Zone, ...]:
        """The zones that apply in an altitude band (all zones when `alt_lo_m` is None)."""
        if alt_lo_m is None:
            return self.zones
        return tuple(z for z in self.zones if z.applies_at(alt_lo_m, alt_hi_m))

    def raw(self, alt_m: float | None = None) -> BaseGeometry:
        """Union of the zones (not inflated) at an altitude."""
        return _union(self.at(alt_m), 0.0)

    def keep_out(self, alt_m: float | None = None, extra_m: float = 0.0) -> BaseGeometry:
        """Union of the zones inflated by the margin (+ `extra_m`) at an altitude."""
        return _union(self.at(alt_m), self.margin_m + extra_m)

    def entered(
        self,
        points: Sequence[tuple[float, float]],
        alt_lo_m: float | None,
        alt_hi_m: float | None = None,
        *,
        inflated: bool = True,
    ) -> Zone | None:
        """The first zone applying in the altitude band whose interior (inflated by the
        margin unless `inflated` is False) the polyline through `points` enters; None
        when it stays clear (touching the boundary is clear)."""
        if not points:
            return None
        line = LineString(points) if len(points) > 1 else Point(points[0])
        grow = self.margin_m if inflated else 0.0
        for z in self.at(alt_lo_m, alt_hi_m):
            poly = z.polygon.buffer(grow, join_style="mitre") if grow > 0 else z.polygon
            if line.intersects(poly.buffer(-1e-6)):
                return z
        return None

    def entered_track(self, track: Track, *, inflated: bool = False) -> Zone | None:
        """`entered` for a planned `Track` (raw zones by default: the property the
        plans guarantee)."""
        return self.entered(track.points, track.alt_lo_m, track.alt_hi_m, inflated=inflated)

    def zone_containing(self, x: float, y: float, alt_m: float | None = None) -> Zone | None:
        p = Point(x, y)
        for z in self.at(alt_m):
            if z.polygon.covers(p):
                return z
        return None

    # ------------------------------------------------------------------- conflicts

    def conflicts(self, route: Sequence[XYZ]) -> list[Conflict]:
        """Where the polyline `route` enters a zone (waypoints inside or legs crossing),
        with the altitude band of each leg checked against floor and ceiling."""
        out: list[Conflict] = []
        for i, z in ((i, z) for i in range(len(route)) for z in self.zones):
            x, y, alt = route[i]
            if z.applies_at(alt) and z.polygon.covers(Point(x, y)):
                out.append(Conflict(z.zone_id, i, None))
        for i in range(len(route) - 1):
            a, b = route[i], route[i + 1]
            seg = LineString([a[:2], b[:2]]) if a[:2] != b[:2] else Point(a[:2])
            lo, hi = min(a[2], b[2]), max(a[2], b[2])
            for z in self.zones:
                if z.applies_at(lo, hi) and seg.intersects(z.polygon):
                    inter = seg.intersection(z.polygon)
                    if inter.length > 1e-6 or z.polygon.covers(Point(a[:2])):
                        out.append(Conflict(z.zone_id, i, i + 1))
        return out

    # ------------------------------------------------------------------- avoidance

    def avoid(self, route: Sequence[XYZ], *, max_alt_rel_m: float) -> list[XYZ]:
        """A route with the same end points that never enters a zone: over a zone when
        its ceiling + vertical margin is <= `max_alt_rel_m`, else around the inflated
        zones (visibility graph). Raises `NoSafeRouteError` when neither works."""
        if len(route) < 2:
            return list(route)
        for x, y, alt in (route[0], route[-1]):
            z = self.zone_containing(x, y, alt)
            if z is not None:
                raise NoSafeRouteError(f"route end point ({x:.0f}, {y:.0f}) is in zone {z.zone_id}")
        out: list[XYZ] = [route[0]]
        for a, b in itertools.pairwise(route):
            out += self._avoid_leg(a, b, max_alt_rel_m)[1:]
        left = self.conflicts(out)
        if left:
            raise NoSafeRouteError(f"no safe route around zone {left[0].zone_id}")
        return out

    def _avoid_leg(self, a: XYZ, b: XYZ, max_alt: float) -> list[XYZ]:
        lo, hi = min(a[2], b[2]), max(a[2], b[2])
        seg = LineString([a[:2], b[:2]]) if a[:2] != b[:2] else Point(a[:2])
        hit = [z for z in self.at(lo, hi) if seg.intersects(z.polygon)]
        if not hit:
            return [a, b]
        clear = [z for z in hit if z.ceiling_rel_m + self.vertical_margin_m <= max_alt]
        around = [z for z in hit if z not in clear]
        if around:
            legs2d = self.shortest_path(a[:2], b[:2], around_alt=(lo, hi), skip=clear)
            n = len(legs2d)
            pts: list[XYZ] = [
                (x, y, a[2] + (b[2] - a[2]) * i / (n - 1)) for i, (x, y) in enumerate(legs2d)
            ]
        else:
            pts = [a, b]
        if not clear:
            return pts
        out: list[XYZ] = [pts[0]]
        for p, q in itertools.pairwise(pts):
            out += self._climb_over(p, q, clear)[1:]
        return out

    def _climb_over(self, a: XYZ, b: XYZ, zones: Sequence[Zone]) -> list[XYZ]:
        seg = LineString([a[:2], b[:2]])
        hit = [z for z in zones if seg.intersects(z.polygon)]
        if not hit:
            return [a, b]
        grown = shapely.union_all(
            [z.polygon.buffer(self.margin_m + _CLEAR_M, join_style="mitre") for z in hit]
        )
        over = max(z.ceiling_rel_m for z in hit) + self.vertical_margin_m
        inter = seg.intersection(grown)
        s0, s1 = seg.length, 0.0
        for g in getattr(inter, "geoms", [inter]):
            for c in g.coords:
                s = seg.project(Point(c))
                s0, s1 = min(s0, s), max(s1, s)
        p0 = seg.interpolate(s0)
        p1 = seg.interpolate(s1)
        out: list[XYZ] = [a]
        if s0 > 1e-6:
            out.append((p0.x, p0.y, max(over, a[2])))
        else:
            out[0] = (a[0], a[1], max(over, a[2]))
        out.append((p1.x, p1.y, max(over, b[2])))
        if s1 < seg.length - 1e-6:
            out.append(b)
        return out

    def shortest_path(
        self,
        a: tuple[float, float],
        b: tuple[float, float],
        *,
        around_alt: tuple[float, float] | None = None,
        skip: Sequence[Zone] = (),
    ) -> list[tuple[float, float]]:
        """Shortest 2-D polyline from `a` to `b` outside the inflated zones that apply in
        the altitude band `around_alt` (all zones when None), over a visibility graph of
        the inflated zones' vertices. Raises `NoSafeRouteError` if there is none."""
        zones = [z for z in (self.at(*around_alt) if around_alt else self.zones) if z not in skip]
        if not zones:
            return [a, b]
        blocked = shapely.union_all(
            [
                z.polygon.buffer(self.margin_m, join_style="mitre")
                if self.margin_m > 0
                else z.polygon
                for z in zones
            ]
        )
        return visibility_path(a, b, blocked)


def _union(zones: Sequence[Zone], grow_m: float) -> BaseGeometry:
    polys = [
        z.polygon.buffer(grow_m, join_style="mitre") if grow_m > 0 else z.polygon for z in zones
    ]
    return shapely.union_all(polys) if polys else Polygon()


@dataclass(frozen=True, slots=True)
class Track:
    """Where a plan flies a vehicle, as a densely sampled polyline (arcs every couple of
    metres, circles closed): its approach, a waiting orbit, a target orbit, a patrol
    loop, a landing leg. Every plan lists its tracks so that checks (and tests) can
    verify that no planned path enters a no-fly zone, arcs included."""

    vehicle_id: int
    kind: str  # "approach", "wait", "orbit", "loop", "transit", "hold", "final"
    points: tuple[tuple[float, float], ...]
    alt_lo_m: float
    alt_hi_m: float | None = None  # None: flown at alt_lo_m


ARC_STEP_M = 2.0  # sampling step of planned arcs and circles


def circle_points(
    cx: float, cy: float, radius_m: float, step_m: float = ARC_STEP_M
) -> tuple[tuple[float, float], ...]:
    """A closed circle sampled every `step_m` of arc (at least 72 points, at most 2000)."""
    n = min(max(72, math.ceil(2 * math.pi * radius_m / step_m)), 2000)
    a = np.linspace(0.0, 2 * math.pi, n + 1)
    return tuple(
        zip((cx + radius_m * np.cos(a)).tolist(), (cy + radius_m * np.sin(a)).tolist(), strict=True)
    )


@dataclass(frozen=True, slots=True)
class Conflict:
    """A route enters zone `zone_id`: at waypoint `index` (leg_end None) or on the leg
    `index` -> `leg_end`."""

    zone_id: int
    index: int
    leg_end: int | None


class Obstacles:
    """Polygons a path must not cross, with their visibility graph built once: nodes
    are the vertices of the polygons grown by a little, edges the node pairs that see
    each other. `path(a, b)` adds the two end points and runs Dijkstra."""

    def __init__(self, blocked: BaseGeometry, core: BaseGeometry | None = None) -> None:
        self.blocked = blocked
        # the zones themselves when `blocked` is them grown by a margin: a vehicle inside
        # the margin may leave it (`path_from`), one inside a zone is not led through it
        self.core = core
        # equal by value: the area planner's rounds (and a worker's later jobs) build the
        # same obstacles again, and the memoized transitions (coverage._cached_transition)
        # are found again only for an equal key (by identity, a 11-member survey planned
        # 4,000 transitions, most of them twice or three times)
        self._key = (blocked.wkb, core.wkb if core is not None else None)
        self._hash = hash(self._key)
        self.inner = blocked.buffer(-1e-6) if not blocked.is_empty else blocked
        shapely.prepare(self.inner)
        nodes: list[tuple[float, float]] = []
        if not blocked.is_empty:
            grown = blocked.buffer(_CLEAR_M, join_style="mitre")
            for poly in getattr(grown, "geoms", [grown]):
                if isinstance(poly, Polygon):
                    for ring in [poly.exterior, *poly.interiors]:
                        nodes += [(float(x), float(y)) for x, y in list(ring.coords)[:-1]]
        self.nodes = nodes
        pts = np.asarray(nodes, dtype=np.float64).reshape(-1, 2)
        self._pts = pts
        n = len(nodes)
        self.adj: list[list[tuple[int, float]]] = [[] for _ in range(n)]
        if n > 1:
            ii, jj = np.triu_indices(n, k=1)
            segs = shapely.linestrings(np.stack([pts[ii], pts[jj]], axis=1))
            ok = ~shapely.intersects(self.inner, segs)  # prepared first: GEOS uses it
            ii, jj = ii[ok], jj[ok]
            w = np.hypot(*(pts[ii] - pts[jj]).T)
            for i, j, d in zip(ii.tolist(), jj.tolist(), w.tolist(), strict=True):
                self.adj[i].append((j, d))
                self.adj[j].append((i, d))

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Obstacles) and self._key == other._key

    def __hash__(self) -> int:
        return self._hash

    @property
    def is_empty(self) -> bool:
        return bool(self.blocked.is_empty)

    def clearance(self, points: Sequence[tuple[float, float]]) -> float:
        """Distance from the polyline through `points` to the polygons (0 if it touches
        or enters them; infinite without polygons)."""
        if self.is_empty or not points:
            return math.inf
        line = LineString(points) if len(points) > 1 else Point(points[0])
        return float(self.blocked.distance(line))

    def crosses(self, points: Sequence[tuple[float, float]] | npt.NDArray[np.float64]) -> bool:
        if self.is_empty or len(points) < 2:
            return False
        return bool(self.inner.intersects(LineString(points)))  # prepared first

    def _visible_from(self, p: tuple[float, float]) -> list[tuple[int, float]]:
        if not self.nodes:
            return []
        segs = shapely.linestrings(
            np.stack([np.broadcast_to(np.asarray(p), self._pts.shape), self._pts], axis=1)
        )
        ok = np.flatnonzero(~shapely.intersects(self.inner, segs))  # prepared first
        d = np.hypot(*(self._pts[ok] - np.asarray(p)).T)
        return list(zip(ok.tolist(), d.tolist(), strict=True))

    def way_out(self, p: tuple[float, float]) -> tuple[float, float] | None:
        """The nearest point `_CLEAR_M` outside the polygons from `p` when `p` is inside
        them (None when it is not)."""
        if self.is_empty or not self.inner.contains(Point(p)):
            return None
        edge = shapely.ops.nearest_points(self.blocked.boundary, Point(p))[0]
        dx, dy = edge.x - p[0], edge.y - p[1]
        d = math.hypot(dx, dy)
        if d < 1e-9:
            return (float(edge.x), float(edge.y))
        return (float(edge.x + dx / d * _CLEAR_M), float(edge.y + dy / d * _CLEAR_M))

    def path_from(
        self, a: tuple[float, float], b: tuple[float, float]
    ) -> list[tuple[float, float]]:
        """`path` from where a vehicle is: a vehicle inside the inflated zones (in a
        zone's margin: turning at the end of a lane next to it, overshooting a corner)
        first leaves them the shortest way (straight away from the zone the margin is
        around), then goes around them. A goal inside them is still `NoSafeRouteError`."""
        out = self.way_out(a)
        if (
            out is None
            or self.core is None
            or self.inner.contains(Point(out))
            or LineString([a, out]).intersects(self.core)
        ):
            return self.path(a, b)  # not in a margin we know: NoSafeRouteError
        return [a, *self.path(out, b)]

    def path(self, a: tuple[float, float], b: tuple[float, float]) -> list[tuple[float, float]]:
        """Shortest polyline from `a` to `b` not crossing the interior of the polygons;
        `NoSafeRouteError` if an end is inside or there is no way around."""
        if self.is_empty:
            return [a, b]
        if self.inner.contains(Point(a)) or self.inner.contains(Point(b)):
            raise NoSafeRouteError("route end point is inside an inflated no-fly zone")
        if not self.inner.intersects(LineString([a, b])):
            return [a, b]
        n = len(self.nodes)
        src, dst = n, n + 1
        extra: dict[int, list[tuple[int, float]]] = {src: self._visible_from(a)}
        into_b = {i: d for i, d in self._visible_from(b)}
        dist: dict[int, float] = {src: 0.0}
        prev: dict[int, int] = {}
        heap = [(0.0, src)]
        while heap:
            d, u = heapq.heappop(heap)
            if u == dst:
                break
            if d > dist.get(u, math.inf):
                continue
            nbrs = extra[src] if u == src else self.adj[u]
            cand = list(nbrs)
            if u in into_b:
                cand.append((dst, into_b[u]))
            for v, c in cand:
                if d + c < dist.get(v, math.inf):
                    dist[v] = d + c
                    prev[v] = u
                    heapq.heappush(heap, (d + c, v))
        if dst not in dist:
            raise NoSafeRouteError("no lateral route around the no-fly zones")
        path = [dst]
        while path[-1] != src:
            path.append(prev[path[-1]])
        pts = {src: a, dst: b}
        return [pts[k] if k in pts else self.nodes[k] for k in reversed(path)]


def visibility_path(
    a: tuple[float, float], b: tuple[float, float], blocked: BaseGeometry
) -> list[tuple[float, float]]:
    """Shortest polyline from `a` to `b` that does not cross the interior of `blocked`
    (one-off; build an `Obstacles` to answer many queries)."""
    return Obstacles(blocked).path(a, b)
