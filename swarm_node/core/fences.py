"""No-fly zones and operating areas loaded into the autopilot as ArduPilot fences: the
backstop if the companion computer fails.

`plan_fence` decides what the autopilot's fence holds; `FenceKeeper` uploads it (one
request at a time) whenever that changes, and retries after a failure; `Fences` is the
node's module: it plans the fence again when a zone, its validity, home or the flight
ceiling changed (owner FENCE of the autopilot), alerts what did not fit or failed, and
has the backstop (backstop.py, owner BACKSTOP) check the autopilot still holds the fence
and the rally point.

What becomes a fence (docs/node.md, "Fences"):

- An ArduPilot polygon or circle fence is 2-D: inside an exclusion fence is a breach at
  any altitude. A no-fly zone is fenced only when the planners never fly over or under
  it: its floor is at or below home and its ceiling at or above the highest altitude
  this vehicle flies (`FENCE_FULL_HEIGHT_REL_M` above home, or the highest mission it
  holds). A zone the planners may overfly stays a companion-computer-only zone
  (monitoring still raises GEOFENCE_BREACH inside its altitude band).
- Operating areas are inclusion fences (2-D, as ArduPilot's; several: the vehicle must
  stay inside all of them, ArduPilot's default).
- The fence storage is limited (`FENCE_MAX_ITEMS`: a polygon vertex or a circle is one
  item). Operating areas come first, then zones nearest home. A polygon that does not
  fit is approximated with fewer vertices, always on the permissive side (an exclusion
  inside the zone, an inclusion around the area), so the backstop never fires where the
  planners legitimately fly; what still does not fit is left out and reported.

Pure: no I/O; `now` is passed in.
"""

from __future__ import annotations

import itertools
import logging
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field

import msgspec
from shapely.geometry import Polygon

from swarm_proto import Alert, AlertCode, GeometryKind, GeoPoint, NoFlyZone, Severity, VehicleType
from swarm_proto.geodesy import distance_m
from swarm_proto.text import short_text

from .arbiter import Owner
from .autopilot.requests import ApRequest, ApResult, SetParam, UploadFence
from .autopilot.state import AutopilotState
from .backstop import BackstopKeeper, rally_point
from .failsafe import FailsafeKeeper
from .outputs import ModuleOutput, Note, Publish, Submit
from .planning.geo import LocalFrame
from .safety.zones import ZoneBook

FENCE_MAX_ITEMS = 84  # ArduPilot on a Pixhawk (AC_PolyFence_loader::max_items)
FENCE_FULL_HEIGHT_REL_M = 120.0  # the planners' climb-over limit above home
FENCE_TYPE_POLYGON = 4.0  # FENCE_TYPE bit: polygon/circle fences only (not ALT_MAX, CIRCLE)
FENCE_RETRY_S = 5.0
_TOLERANCES_M = (1.0, 2.0, 5.0, 10.0, 20.0, 50.0, 100.0)


@dataclass(frozen=True)
class FencePlan:
    request: UploadFence  # what the autopilot should hold (request_id 0, enable set)
    fenced: tuple[int, ...] = ()  # zone ids loaded
    approximated: tuple[int, ...] = ()  # loaded with fewer vertices
    overflown: tuple[int, ...] = ()  # not fenced: the planners may fly over or under them
    left_out: tuple[int, ...] = ()  # not fenced: no room left in the autopilot


def _distance_m(a_lat: float, a_lon: float, b_lat: float, b_lon: float) -> float:
    return distance_m(a_lat, a_lon, b_lat, b_lon)  # the one geodesy (swarm_proto.geodesy)


def _zone_distance(zone: NoFlyZone, home: GeoPoint) -> float:
    pts = zone.geometry.points
    lat = sum(p.lat_deg for p in pts) / len(pts)
    lon = sum(p.lon_deg for p in pts) / len(pts)
    return _distance_m(home.lat_deg, home.lon_deg, lat, lon)


def approximate(
    points: Sequence[tuple[float, float]], max_vertices: int, *, inner: bool
) -> tuple[tuple[float, float], ...] | None:
    """`points` (lat, lon) with at most `max_vertices` vertices, inside the polygon
    (`inner`) or around it, checked; None when no tolerance up to 100 m gets there."""
    if max_vertices < 3:
        return None
    frame = LocalFrame(
        sum(p[0] for p in points) / len(points), sum(p[1] for p in points) / len(points)
    )  # the planners' ENU frame (pymap3d), at the polygon's centre
    poly = Polygon(frame.to_local_many(points))
    if not poly.is_valid:
        poly = poly.buffer(0)
    for tol in _TOLERANCES_M:
        grown = poly.buffer(-tol if inner else tol, join_style=2, mitre_limit=3.0)
        shape = grown.simplify(tol, preserve_topology=True)
        if not isinstance(shape, Polygon) or shape.is_empty or not shape.is_valid:
            if not inner:
                shape = poly.convex_hull.buffer(tol, join_style=2).simplify(tol)
            if not isinstance(shape, Polygon) or shape.is_empty:
                continue
        ring = list(shape.exterior.coords)[:-1]
        if not 3 <= len(ring) <= max_vertices:
            continue
        if not (poly.covers(shape) if inner else shape.covers(poly)):
            continue
        return tuple((float(a), float(b)) for a, b in frame.to_geodetic_many(ring))
    return None


def plan_fence(
    zones: Iterable[NoFlyZone],
    now: float,
    *,
    home: GeoPoint,
    fly_ceiling_rel_m: float = FENCE_FULL_HEIGHT_REL_M,
    max_items: int = FENCE_MAX_ITEMS,
) -> FencePlan:
    """What the autopilot's fence should hold for the zones in force at `now`."""
    inside: list[NoFlyZone] = []
    outside: list[NoFlyZone] = []
    overflown: list[int] = []
    top = home.alt_msl_m + max(fly_ceiling_rel_m, FENCE_FULL_HEIGHT_REL_M)
    for z in sorted(zones, key=lambda z: z.zone_id):
        if not z.in_force(now):
            continue
        if z.operating_area:
            inside.append(z)
        elif z.floor_alt_msl_m <= home.alt_msl_m and z.ceiling_alt_msl_m >= top:
            outside.append(z)
        else:
            overflown.append(z.zone_id)
    outside.sort(key=lambda z: (_zone_distance(z, home), z.zone_id))
    order = [(z, True) for z in inside] + [(z, False) for z in outside]

    def need(z: NoFlyZone) -> int:
        return 1 if z.geometry.kind == GeometryKind.CIRCLE else 3

    in_polys: list[tuple[tuple[float, float], ...]] = []
    in_circles: list[tuple[float, float, float]] = []
    ex_polys: list[tuple[tuple[float, float], ...]] = []
    ex_circles: list[tuple[float, float, float]] = []
    fenced: list[int] = []
    approximated: list[int] = []
    left_out: list[int] = []
    left = max_items
    for i, (z, inclusion) in enumerate(order):
        g = z.geometry
        if g.kind == GeometryKind.CIRCLE:
            if left < 1:
                left_out.append(z.zone_id)
                continue
            c = g.points[0]
            (in_circles if inclusion else ex_circles).append(
                (c.lat_deg, c.lon_deg, float(g.radius_m or 0.0))
            )
            left -= 1
            fenced.append(z.zone_id)
            continue
        pts: tuple[tuple[float, float], ...] = tuple((p.lat_deg, p.lon_deg) for p in g.points)
        if len(pts) > left:
            reserve = sum(need(later) for later, _ in order[i + 1 :])
            fitted = approximate(pts, max(3, left - reserve), inner=not inclusion)
            if fitted is None or len(fitted) > left:
                left_out.append(z.zone_id)
                continue
            pts = fitted
            approximated.append(z.zone_id)
        (in_polys if inclusion else ex_polys).append(pts)
        left -= len(pts)
        fenced.append(z.zone_id)
    request = UploadFence(
        exclusion_polygons=tuple(ex_polys),
        exclusion_circles=tuple(ex_circles),
        inclusion_polygons=tuple(in_polys),
        inclusion_circles=tuple(in_circles),
        enable=bool(fenced),
    )
    return FencePlan(
        request, tuple(sorted(fenced)), tuple(approximated), tuple(overflown), tuple(left_out)
    )


@dataclass
class FenceKeeper:
    """Keeps the autopilot's fence equal to the last `FencePlan`: one request at a time
    (FENCE_TYPE once, then the upload with DO_FENCE_ENABLE), a retry `retry_s` after a
    failure, and a new upload when the wanted fence changed meanwhile."""

    retry_s: float = FENCE_RETRY_S
    held: UploadFence | None = None  # what the autopilot holds (after our last upload)
    want: UploadFence | None = None
    type_set: bool = False  # FENCE_TYPE written since this node started
    failures: int = 0  # consecutive failed requests
    _in_flight: ApRequest | None = None
    _retry_at: float | None = None
    _ids: itertools.count[int] = field(default_factory=lambda: itertools.count(1))

    @property
    def busy(self) -> bool:
        return self._in_flight is not None

    def update(self, want: UploadFence, now: float) -> list[ApRequest]:
        self.want = msgspec.structs.replace(want, request_id=0)
        return self._next(now)

    def _next(self, now: float) -> list[ApRequest]:
        if self._in_flight is not None or self.want is None or self.want == self.held:
            return []
        if self._retry_at is not None and now < self._retry_at:
            return []
        self._retry_at = None
        req: ApRequest
        if not self.type_set and self.want.enable:
            req = SetParam(name="FENCE_TYPE", value=FENCE_TYPE_POLYGON)
        else:
            req = self.want
        self._in_flight = msgspec.structs.replace(req, request_id=next(self._ids))
        return [self._in_flight]

    def on_result(self, result: ApResult, now: float) -> tuple[list[ApRequest], str | None]:
        """The next request, and what failed (None: nothing)."""
        done = self._in_flight
        if done is None or result.request_id != done.request_id:
            return [], None
        self._in_flight = None
        if not result.ok:
            self.failures += 1
            self._retry_at = now + self.retry_s
            what = "FENCE_TYPE" if isinstance(done, SetParam) else "fence upload"
            return [], f"{what} failed: {result.reason}"
        self.failures = 0
        if isinstance(done, SetParam):
            self.type_set = True
        else:
            assert isinstance(done, UploadFence)
            self.held = msgspec.structs.replace(done, request_id=0)
        return self._next(now), None

    def forget(self) -> None:
        """The autopilot may no longer hold what was uploaded (it rebooted, or its store
        was found different: backstop.py): upload it again, FENCE_TYPE first."""
        self.held = None
        self.type_set = False
        self._retry_at = None

    def on_timer(self, now: float) -> list[ApRequest]:
        return self._next(now)

    def next_deadline(self) -> float | None:
        if self._in_flight is None and self.want != self.held:
            return self._retry_at
        return None


@dataclass
class Fences:
    """The autopilot's fence kept equal to the zones in force, and the backstop kept
    true (the node's module)."""

    vehicle_id: int
    vehicle_type: VehicleType
    max_items: int = FENCE_MAX_ITEMS  # what the autopilot's fence storage takes
    keeper: FenceKeeper = field(default_factory=FenceKeeper)
    plan: FencePlan | None = None  # the last plan (what is fenced, overflown, left out)
    backstop: BackstopKeeper = field(init=False)  # the fence and rally point checked
    failsafe: FailsafeKeeper = field(init=False)  # the lost-companion failsafe set
    _key: object = None
    _version: int = 0  # the zone book's version the fence was last planned for

    def __post_init__(self) -> None:
        self.backstop = BackstopKeeper(self.vehicle_id, self.keeper)
        # both answer to BACKSTOP: the failsafe's request ids are its own range, each
        # result goes to the one that asked
        self.failsafe = FailsafeKeeper(self.vehicle_id, self.vehicle_type)

    def on_autopilot(
        self,
        ap: AutopilotState,
        zones: ZoneBook,
        base: GeoPoint | None,
        ceiling_rel_m: float,
        now: float,
    ) -> list[ModuleOutput]:
        rally = rally_point(self.vehicle_id, self.vehicle_type, base, ap.home)
        out = self.keep(zones, ap.home, ceiling_rel_m, now)
        out += self.failsafe.on_autopilot(ap, now)
        return out + self.backstop.on_autopilot(ap, rally, now)

    def on_timer(
        self, ap: AutopilotState, zones: ZoneBook, ceiling_rel_m: float, now: float
    ) -> list[ModuleOutput]:
        out = self.keep(zones, ap.home, ceiling_rel_m, now)
        out += self.failsafe.on_timer(ap, now)
        return out + self.backstop.on_timer(ap, now)

    def recheck(self, why: str, restore: bool, now: float) -> list[ModuleOutput]:
        """A ground station changed the fence, the rally points or their parameters
        through passthrough: the backstop checks them as after a reboot."""
        self.backstop.recheck(why, restore=restore, now=now)
        return []

    def new_zones(
        self, zones: ZoneBook, home: GeoPoint | None, ceiling: Callable[[], float], now: float
    ) -> list[ModuleOutput]:
        """`keep`, when a zone changed since the fence was last planned (asked after any
        input: a zone heard, a book merged); `ceiling`: the flight ceiling, asked then."""
        if zones.version == self._version:
            return []
        return self.keep(zones, home, ceiling(), now)

    def keep(
        self, zones: ZoneBook, home: GeoPoint | None, ceiling_rel_m: float, now: float
    ) -> list[ModuleOutput]:
        """A new plan when a zone, its validity, home or the flight ceiling changed; the
        keeper's retry otherwise. No zone heard yet (version 0): the autopilot's fence is
        left alone."""
        if zones.version == 0 or home is None:
            return []
        self._version = zones.version
        in_force = tuple(sorted(z.zone_id for z in zones.values() if z.in_force(now)))
        key = (zones.version, in_force, home, ceiling_rel_m)
        if key == self._key:
            return [Submit(r, Owner.FENCE) for r in self.keeper.on_timer(now)]
        self._key = key
        before = self.plan
        plan = self.plan = plan_fence(
            zones.values(),
            now,
            home=home,
            fly_ceiling_rel_m=ceiling_rel_m,
            max_items=self.max_items,
        )
        out: list[ModuleOutput] = []
        if plan.left_out and (before is None or before.left_out != plan.left_out):
            ids = ",".join(str(i) for i in plan.left_out)
            text = f"fence full: zones {ids} not in the autopilot"
            out += [Note(logging.WARNING, text), self._alert(now, text)]
        return out + [Submit(r, Owner.FENCE) for r in self.keeper.update(plan.request, now)]

    def on_result(
        self, owner: Owner, result: ApResult, ap: AutopilotState, now: float
    ) -> list[ModuleOutput]:
        """A result of ours (owner FENCE) or of the backstop (BACKSTOP)."""
        if owner == Owner.BACKSTOP and self.failsafe.expects(result.request_id):
            return self.failsafe.on_result(result, ap, now)
        if owner == Owner.BACKSTOP:
            return self.backstop.on_result(result, ap, now)
        reqs, problem = self.keeper.on_result(result, now)
        out: list[ModuleOutput] = [Submit(r, Owner.FENCE) for r in reqs]
        if problem is not None and self.keeper.failures == 1:  # once per run of failures
            out += [
                Note(logging.WARNING, f"{problem}; retrying every {self.keeper.retry_s:g} s"),
                self._alert(now, problem),
            ]
        return out

    def next_deadline(self) -> float | None:
        due = (self.keeper.next_deadline(), self.backstop.next_deadline())
        times = [t for t in (*due, self.failsafe.next_deadline()) if t is not None]
        return min(times) if times else None

    def _alert(self, now: float, text: str) -> Publish:
        alert = Alert(
            self.vehicle_id,
            max(0.0, now),
            Severity.WARNING,
            AlertCode.NO_FLY_ZONE,
            short_text(text),
        )
        return Publish(alert)
