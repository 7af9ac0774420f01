"""Transit geometry, pure (moved out of the mission manager): the legs a plan does not
cover (from where a vehicle is to its first waypoint, back to base, to an emergency
landing point), kept clear of the no-fly zones, and a fixed-wing's waypoints made
flyable from its pose at its planned turn radius.

    safe_transit        straight, or the shortest way round the inflated zones
    fixed_wing_transit  the same, entered along a zone-clear Dubins path
    fly_corners         a fixed-wing's waypoints flyable from where it is (flight.py)
    flown_turn_radius_m the radius those legs are planned at: the margin kept at the
                        speed the aircraft flies them (faster than cruise after a
                        PREMISSION's catch-up)
    flyable             (fleet_plan.py) the profile planners use: turns at 1.3 x the
                        minimum radius
    VehicleTransit      one vehicle's legs from where its autopilot says it is: the
                        approach to its share, the way home, an emergency landing
                        route; fixed-wing waypoints with their acceptance radius
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import msgspec
from shapely.geometry import LineString
from shapely.geometry.base import BaseGeometry

from swarm_proto import GeoPoint, LatLon, NoFlyZone, geodesy

from ..autopilot.items import ItemKind, Waypoint
from ..autopilot.state import AutopilotState
from ..margins import FIXED_WING_KEEP_M
from ..profile import VehicleProfile
from .dubins import Pose, all_paths
from .errors import PlanningError
from .fleet_plan import TURN_RADIUS_MARGIN, flyable
from .flight import FIXED_WING_ACCEPT_M, TURN_CLEARANCE_M, flyable_waypoints
from .geo import LocalFrame, heading_to_yaw
from .zones import ZoneSet

TRANSIT_MARGIN_M = 20.0  # least clearance from a no-fly zone on transit legs


def flown_turn_radius_m(profile: VehicleProfile, speed_m_s: float | None = None) -> float:
    """The turn radius a fixed-wing's legs off the plan (the approach to its share, the
    way home) are planned at: TURN_RADIUS_MARGIN times its minimum radius at the faster
    of its cruise speed and `speed_m_s`, the speed it flies now (None, 0 or not finite:
    cruise; capped at its maximum speed). `flyable` keeps that margin at cruise only:
    at a PREMISSION's catch-up speed (29.6 m/s for a 26 m/s Albatross) its radius is
    the aircraft's minimum, and a replan's approach planned at it (its Dubins entry at
    the 69 m cruise minimum) was flown wide, into the demo's field zone."""
    cruise = profile.cruise_speed_m_s
    v = speed_m_s if speed_m_s is not None and math.isfinite(speed_m_s) else 0.0
    if profile.max_speed_m_s > 0.0:
        v = min(v, profile.max_speed_m_s)
    return TURN_RADIUS_MARGIN * profile.turn_radius_m(max(v, cruise) if v > 0.0 else None)


def fly_corners(
    waypoints: Sequence[Waypoint],
    profile: VehicleProfile,
    zones: Sequence[NoFlyZone],
    *,
    start: tuple[float, float, float] | None,
    free: frozenset[int],
    now: float,
    home_alt_msl_m: float,
    speed_m_s: float | None = None,
) -> tuple[Waypoint, ...]:
    """A fixed-wing's waypoints made flyable from `start` (lat, lon, heading: where it
    is now) at its planned turn radius (`planning.flight.flyable_waypoints`): the
    points of `free` (item indexes: transit legs) may be skipped, the others are
    passed. The radius is the one of the waypoints' first CHANGE_SPEED; without one,
    of `speed_m_s`, the speed the aircraft flies now (`flown_turn_radius_m`). Other
    vehicles' waypoints unchanged. Raises `PlanningError` when a corner has no
    connection clear of the zones, or the flown path would enter one."""
    if not profile.is_fixed_wing:
        return tuple(waypoints)
    pos = [(w.lat_deg, w.lon_deg) for w in waypoints if w.kind == ItemKind.WAYPOINT]
    if not pos:
        return tuple(waypoints)
    frame = LocalFrame.at([LatLon(*p) for p in pos + ([start[:2]] if start else [])])
    speed = next(
        (w.speed_m_s for w in waypoints if w.kind == ItemKind.CHANGE_SPEED and w.speed_m_s), None
    )
    pose = None
    if start is not None:
        x, y = frame.to_local(start[0], start[1])
        pose = Pose(x, y, heading_to_yaw(start[2]))
    zs = ZoneSet.from_messages(zones, frame, now_unix_s=now, home_alt_msl_m=home_alt_msl_m)
    radius = (
        flown_turn_radius_m(profile, speed_m_s)
        if speed is None and speed_m_s is not None
        else flyable(profile).turn_radius_m(speed)
    )
    out, _tracks = flyable_waypoints(
        waypoints,
        frame,
        zs,
        radius_m=radius,
        start=pose,
        free=free,
        vehicle_id=profile.vehicle_id,
    )
    return out


def safe_transit(
    start: tuple[float, float],
    end: tuple[float, float],
    alt_rel_m: float,
    zones: Sequence[NoFlyZone],
    *,
    now: float,
    home_alt_msl_m: float,
    margin_m: float,
    max_alt_rel_m: float = 120.0,
    floor_m: float = 0.0,
) -> list[Waypoint]:
    """Waypoints (excluding `start`, including `end`) that fly from start to end keeping
    `margin_m` clear of every no-fly zone at that altitude: straight when the straight
    leg is clear, else the shortest way round the inflated zones (visibility graph);
    if the ends are too close to a zone for the margin, a half or a quarter of it (never
    less than `floor_m`), then the raw-zone avoidance of the planners (over or around).
    The legs a plan does not cover (to the first waypoint, back to base) go through
    here."""
    direct = [Waypoint(lat_deg=end[0], lon_deg=end[1], alt_rel_m=alt_rel_m)]
    if not zones:
        return direct
    frame = LocalFrame.at([LatLon(*start), LatLon(*end)])
    a, b = frame.to_local(*start), frame.to_local(*end)
    route: list[tuple[float, float, float]] | None = None
    margins = sorted({max(m, floor_m) for m in (margin_m, margin_m / 2, margin_m / 4)})
    for m in reversed(margins):  # an end close to a zone: less margin
        zs = ZoneSet.from_messages(
            zones, frame, now_unix_s=now, home_alt_msl_m=home_alt_msl_m, margin_m=m
        )
        if not LineString([a, b]).intersects(zs.keep_out(alt_rel_m)):
            return direct
        try:
            route = [
                (x, y, alt_rel_m)
                for x, y in zs.shortest_path(a, b, around_alt=(alt_rel_m, alt_rel_m))
            ]
            break
        except PlanningError:
            continue
    if route is None:
        zs = ZoneSet.from_messages(zones, frame, now_unix_s=now, home_alt_msl_m=home_alt_msl_m)
        route = zs.avoid(
            [(a[0], a[1], alt_rel_m), (b[0], b[1], alt_rel_m)], max_alt_rel_m=max_alt_rel_m
        )
    out = []
    for x, y, alt in route[1:]:
        lat, lon = frame.to_geodetic(x, y)
        out.append(Waypoint(lat_deg=lat, lon_deg=lon, alt_rel_m=alt))
    return out


def fixed_wing_transit(
    start: tuple[float, float],
    heading_deg: float,
    end: tuple[float, float],
    alt_rel_m: float,
    zones: Sequence[NoFlyZone],
    *,
    radius_m: float,
    now: float,
    home_alt_msl_m: float,
) -> list[Waypoint]:
    """A fixed-wing's transit: it cannot turn on the spot, so the first turn (up to two
    turn radii wide) must not sweep through a zone. Flies the zone-safe polyline of
    `safe_transit`, entering it along the Dubins word (of all six, for several entry
    headings) whose sampled path keeps clear of the zones; its arcs become waypoints.
    The entry keeps `flight.TURN_CLEARANCE_M` from the zones, as every turn the flyable
    stage adds does (ArduPlane passes a planned arc's waypoints up to 37 m on their
    inside); only when no entry keeps that much, TRANSIT_MARGIN_M (an entry
    kept 20 m clear was flown 9.9 m from the demo's zone on the way home)."""
    legs = safe_transit(
        start,
        end,
        alt_rel_m,
        zones,
        now=now,
        home_alt_msl_m=home_alt_msl_m,
        margin_m=radius_m,
        floor_m=FIXED_WING_KEEP_M,  # what ArduPlane cuts off a corner, and its clearance
    )
    if not zones or radius_m <= 0:
        return legs
    frame = LocalFrame.at([LatLon(*start), LatLon(*end)])
    for clearance in (TURN_CLEARANCE_M, TRANSIT_MARGIN_M):
        zs = ZoneSet.from_messages(
            zones, frame, now_unix_s=now, home_alt_msl_m=home_alt_msl_m, margin_m=clearance
        )
        entry = _entry(frame, start, heading_deg, legs, zs.keep_out(alt_rel_m), radius_m)
        if entry is not None:
            return [
                *(Waypoint(lat_deg=la, lon_deg=lo, alt_rel_m=alt_rel_m) for la, lo in entry),
                *legs,
            ]
    return legs  # no clear entry: the straight legs are the best we have


def _entry(
    frame: LocalFrame,
    start: tuple[float, float],
    heading_deg: float,
    legs: Sequence[Waypoint],
    blocked: BaseGeometry,
    radius_m: float,
) -> list[tuple[float, float]] | None:
    """The waypoints (lat, lon) of the shortest Dubins entry from the pose at `start`
    onto the first leg whose sampled path does not touch `blocked`, or None."""
    x0, y0 = frame.to_local(*start)
    pose = Pose(x0, y0, math.radians(90.0 - heading_deg))
    first = frame.to_local(legs[0].lat_deg, legs[0].lon_deg)
    after = frame.to_local(legs[1].lat_deg, legs[1].lon_deg) if len(legs) > 1 else None
    ref = after if after is not None else first
    base = (
        math.atan2(ref[1] - first[1], ref[0] - first[0])
        if after is not None
        else math.atan2(first[1] - y0, first[0] - x0)
    )
    best = None
    for k in range(8):  # the natural entry heading first, then others 45 deg apart
        goal = Pose(
            first[0],
            first[1],
            base + k * math.pi / 4 * (1 if k % 2 else -1) * ((k + 1) // 2) / max(1, k),
        )
        for path in all_paths(pose, goal, radius_m):
            if best is not None and path.length_m >= best.length_m:
                break
            pts = [(q.x, q.y) for q in path.sample(10.0)]
            if not LineString(pts).intersects(blocked):
                best = path
                break
        if best is not None and k == 0:
            break
    if best is None:
        return None
    return [frame.to_geodetic(q.x, q.y) for q in best.waypoints()[:-1]]


def distance_m(lat1: float, lon1: float, lat2: float, lon2: float) -> float:
    """Ground distance, metres: the one geodesy (swarm_proto.geodesy)."""
    return geodesy.distance_m(lat1, lon1, lat2, lon2)


def flown_speed_m_s(ap: AutopilotState) -> float:
    """The speed a vehicle flies now, for the radius of its next turn: the faster of its
    airspeed and groundspeed (a tailwind widens the turn over the ground); 0 when
    unknown or not finite."""
    v = max(ap.airspeed_m_s, ap.groundspeed_m_s)
    return v if math.isfinite(v) and v > 0.0 else 0.0


@dataclass(frozen=True)
class VehicleTransit:
    """The transit legs of one vehicle (its profile), from where its autopilot says it
    is: the approach to its share, the way home, an emergency landing route."""

    profile: VehicleProfile

    @property
    def margin_m(self) -> float:
        """Clearance from zones on transit legs: a fixed-wing may start the leg with a
        U-turn as wide as two turn radii."""
        return max(TRANSIT_MARGIN_M, 2.0 * self.profile.turn_radius_m())

    def tight(self, waypoints: Sequence[Waypoint]) -> tuple[Waypoint, ...]:
        """Fixed-wing: every plain waypoint asks for FIXED_WING_ACCEPT_M acceptance."""
        if not self.profile.is_fixed_wing:
            return tuple(waypoints)
        return tuple(
            msgspec.structs.replace(w, acceptance_radius_m=FIXED_WING_ACCEPT_M)
            if w.kind == ItemKind.WAYPOINT and w.acceptance_radius_m == 0.0
            else w
            for w in waypoints
        )

    def with_approach(
        self,
        waypoints: tuple[Waypoint, ...],
        ap: AutopilotState,
        zones: Sequence[NoFlyZone],
        now: float,
        home_alt: float,
    ) -> tuple[Waypoint, ...]:
        """Prefix the leg from where the vehicle is to its first waypoint, around zones;
        a fixed-wing's then made flyable from its pose (the leg's points and the plan's
        first one, where the plan assumed it starts, may be skipped). The share's speed
        is set before the leg (the leg is flown at the speed the flyable stage plans its
        turns for), and the leg's first turn, flown while the aircraft is still at its
        speed now, is planned at the radius of the faster of the two."""
        first_at = next((i for i, w in enumerate(waypoints) if w.kind == ItemKind.WAYPOINT), None)
        if first_at is None or ap.lat_deg is None or ap.lon_deg is None:
            return waypoints
        first = waypoints[first_at]
        speed = next(
            (i for i, w in enumerate(waypoints[:first_at]) if w.kind == ItemKind.CHANGE_SPEED),
            None,
        )
        lead: tuple[Waypoint, ...] = ()
        if speed is not None and self.profile.is_fixed_wing:
            lead, waypoints = (waypoints[speed],), (*waypoints[:speed], *waypoints[speed + 1 :])
            first_at -= 1
        leg: list[Waypoint] = []
        if zones:
            now_m_s = flown_speed_m_s(ap)
            if lead and lead[0].speed_m_s is not None:
                now_m_s = max(now_m_s, lead[0].speed_m_s)
            leg = self.leg(
                (ap.lat_deg, ap.lon_deg),
                ap.heading_deg,
                (first.lat_deg, first.lon_deg),
                first.alt_rel_m,
                zones,
                now,
                home_alt,
                speed_m_s=now_m_s,
            )[:-1]
        out = (*lead, *leg, *waypoints)
        free = frozenset(range(len(lead) + len(leg))) | {len(lead) + len(leg) + first_at}
        return fly_corners(
            out,
            self.profile,
            zones,
            start=(ap.lat_deg, ap.lon_deg, ap.heading_deg),
            free=free,
            now=now,
            home_alt_msl_m=home_alt,
        )

    def leg(
        self,
        start: tuple[float, float],
        heading_deg: float,
        end: tuple[float, float],
        alt_rel_m: float,
        zones: Sequence[NoFlyZone],
        now: float,
        home_alt: float,
        speed_m_s: float | None = None,
    ) -> list[Waypoint]:
        """A zone-safe transit; a fixed-wing's entered along a Dubins path at the radius
        of `speed_m_s` (what it flies now) with the planners' margin
        (`flown_turn_radius_m`)."""
        if self.profile.is_fixed_wing:
            return fixed_wing_transit(
                start,
                heading_deg,
                end,
                alt_rel_m,
                zones,
                radius_m=flown_turn_radius_m(self.profile, speed_m_s),
                now=now,
                home_alt_msl_m=home_alt,
            )
        return safe_transit(
            start,
            end,
            alt_rel_m,
            zones,
            now=now,
            home_alt_msl_m=home_alt,
            margin_m=self.margin_m,
        )

    def from_here(
        self,
        ap: AutopilotState,
        there: tuple[float, float],
        zones: Sequence[NoFlyZone],
        now: float,
        home_alt: float,
    ) -> list[Waypoint]:
        """A zone-safe leg from where the vehicle is to `there`, at its current height
        (at least 30 m above home)."""
        assert ap.lat_deg is not None and ap.lon_deg is not None
        alt = max(ap.alt_rel_m or 0.0, 30.0)
        return self.leg(
            (ap.lat_deg, ap.lon_deg),
            ap.heading_deg,
            there,
            alt,
            zones,
            now,
            home_alt,
            speed_m_s=flown_speed_m_s(ap),
        )

    def flyable_leg(
        self,
        leg: Sequence[Waypoint],
        ap: AutopilotState,
        zones: Sequence[NoFlyZone],
        now: float,
        home_alt: float,
    ) -> tuple[Waypoint, ...]:
        """A transit leg (its end included) a fixed-wing can fly from where it is: its
        points but the end may be skipped."""
        if ap.lat_deg is None or ap.lon_deg is None:
            return tuple(leg)
        return fly_corners(
            leg,
            self.profile,
            zones,
            start=(ap.lat_deg, ap.lon_deg, ap.heading_deg),
            free=frozenset(range(len(leg) - 1)),
            now=now,
            home_alt_msl_m=home_alt,
            speed_m_s=flown_speed_m_s(ap),
        )

    def landing_route(
        self, point: GeoPoint, ap: AutopilotState, zones: Sequence[NoFlyZone], now: float
    ) -> tuple[Waypoint, ...]:
        """An emergency landing at `point` (paper section 3.5.1: "if the landing route has
        been specified"): a zone-safe leg from here at the current altitude (at least
        30 m), then a landing item there (to fly in AUTO)."""
        home = ap.home
        if home is None or ap.lat_deg is None or ap.lon_deg is None:
            raise PlanningError("no position or home")
        leg = self.from_here(ap, (point.lat_deg, point.lon_deg), zones, now, home.alt_msl_m)
        leg = list(self.flyable_leg(leg, ap, zones, now, home.alt_msl_m))
        land = Waypoint(ItemKind.LAND, point.lat_deg, point.lon_deg, 0.0)
        return (*self.tight(leg[:-1]), land)
