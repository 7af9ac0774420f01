"""Mission manager (paper section 2.3.5), first version: plans a released mission with
the planning library, uploads this vehicle's share, takes off, flies it, reports
progress and completion, and flies the return to base.

Every fleet member plans the whole mission for the whole fleet from the same inputs
(the mission, the members' profiles from the swarm database and their homes) and
keeps its own share, so the members agree without exchanging plans: the split must
not depend on anything that differs between nodes (live positions, arrival times of
telemetry). Voting, pre-mission Dubins legs, replanning on drop-out, add and swap are
for the later mission-manager work.

Pure: `release`, `start_return`, `on_result` and `on_autopilot` take `now` and return
`Submit`s for the autopilot and `FsmEvent`s for the state machine.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from enum import Enum

import msgspec
from shapely.geometry import LineString

from swarm_proto import (
    GeometryKind,
    GeoPoint,
    LatLon,
    Mission,
    MissionParams,
    MissionState,
    MissionType,
    NoFlyZone,
    VehicleType,
)

from . import state_machine as fsm
from .autopilot.items import ItemKind, Waypoint
from .autopilot.requests import (
    ApRequest,
    ApResult,
    Arm,
    Disarm,
    Land,
    ReturnToLaunch,
    SetMode,
    StartMission,
    Takeoff,
    UploadMission,
)
from .autopilot.state import AutopilotState
from .fences import FENCE_FIRST_REQUEST_ID
from .planning import (
    LocalFrame,
    PlanningError,
    PlanVehicle,
    Pose,
    VehiclePose,
    ZoneSet,
    heading_to_yaw,
    plan_area,
    plan_objective,
    plan_perimeter,
    plan_route,
    plan_target,
)
from .planning.flight import FIXED_WING_ACCEPT_M, flyable_waypoints
from .profile import VehicleProfile

PLANNERS: dict[MissionType, Callable[..., object]] = {
    MissionType.AREA: plan_area,
    MissionType.TARGET: plan_target,
    MissionType.PERIMETER: plan_perimeter,
    MissionType.ROUTE: plan_route,
    MissionType.OBJECTIVE: plan_objective,
}

#: parameters a planner reads as "not given" when 0 (besides None), per mission type
UNSET_WHEN_ZERO: dict[MissionType, frozenset[str]] = {
    MissionType.AUTOLAND: frozenset({"separation_s", "altitude_step_m"}),
    MissionType.MUMT: frozenset({"altitude_step_m", "radius_m"}),
}


def with_defaults(mission: Mission, defaults: Mapping[str, float]) -> Mission:
    """The mission with its unspecified parameters taken from the swarm database's
    defaults for its type (`SwarmDatabase.mission_defaults`). Unspecified: None, or 0
    where the planner reads 0 as "not given" (`UNSET_WHEN_ZERO`); a circle's radius is
    its geometry's. Parameters with a value are the operator's (the ground station
    fills them from the same defaults). A default that is not a valid value is ignored."""
    p = mission.params
    zero_unset = UNSET_WHEN_ZERO.get(mission.mission_type, frozenset())
    changes: dict[str, float] = {}
    for name, value in defaults.items():
        if name not in MissionParams.__struct_fields__:
            continue
        if name == "radius_m" and mission.geometry.kind == GeometryKind.CIRCLE:
            continue
        current = getattr(p, name)
        if current is None or (current == 0 and name in zero_unset):
            changes[name] = value
    if not changes:
        return mission
    try:
        params = msgspec.convert({**msgspec.to_builtins(p), **changes}, MissionParams, strict=False)
    except msgspec.ValidationError:
        return mission
    return msgspec.structs.replace(mission, params=params)


CLIMB_FRACTION = 0.8  # start the mission once this much of the take-off altitude is reached
LAND_AT_HOME_M = 30.0  # multirotors: land once RTL has brought them this close to home
TRANSIT_MARGIN_M = 20.0  # least clearance from a no-fly zone on transit legs
# Fixed-wing waypoint acceptance (planning.flight.FIXED_WING_ACCEPT_M, 15 m): every
# plain waypoint asks for it (ArduPlane's 90 m default would count the closely spaced
# waypoints of a planned turn as reached at once and loop wide); the flyable stage
# plans every corner for it.
TURN_RADIUS_MARGIN = 1.3
FIRST_REQUEST_ID = 1_000_000  # the command manager uses small ids


class Phase(Enum):
    IDLE = "idle"
    STARTING = "starting"  # upload, arm, take off
    CLIMBING = "climbing"  # waiting for the take-off altitude
    FLYING = "flying"  # the mission is running on the autopilot
    RETURNING = "returning"  # RTL
    LANDING = "landing"
    PARACHUTE = "parachute"  # released: coming down under the canopy


@dataclass(frozen=True)
class Member:
    profile: VehicleProfile
    home: GeoPoint | None


@dataclass(frozen=True)
class Submit:
    request: ApRequest


@dataclass(frozen=True)
class FsmEvent:
    event: fsm.Event


@dataclass(frozen=True)
class Log:
    text: str


Out = Submit | FsmEvent | Log


def flyable(profile: VehicleProfile) -> VehicleProfile:
    """The profile planners should use: a fixed-wing's turns planned at
    TURN_RADIUS_MARGIN times its minimum radius, so the autopilot's path following has
    room to converge on the planned arcs instead of overshooting them."""
    if not profile.is_fixed_wing:
        return profile
    return msgspec.structs.replace(
        profile, loiter_radius_m=TURN_RADIUS_MARGIN * profile.turn_radius_m()
    )


def plan_share(
    mission: Mission,
    members: Sequence[Member],
    self_id: int,
    zones: Sequence[NoFlyZone],
    now: float,
    home_alt_msl_m: float,
) -> tuple[Waypoint, ...]:
    """This vehicle's waypoints in a plan made for every member (sorted by id, posed at
    their homes: inputs every member sees the same): `planning.plan_fleet`'s share."""
    from .planning.fleet_plan import plan_fleet

    vehicles = [
        PlanVehicle(m.profile, VehiclePose(m.home.lat_deg, m.home.lon_deg) if m.home else None)
        for m in members
    ]
    plan = plan_fleet(mission, vehicles, zones=zones, now_unix_s=now, home_alt_msl_m=home_alt_msl_m)
    return plan.share(self_id).waypoints


def fly_corners(
    waypoints: Sequence[Waypoint],
    profile: VehicleProfile,
    zones: Sequence[NoFlyZone],
    *,
    start: tuple[float, float, float] | None,
    free: frozenset[int],
    now: float,
    home_alt_msl_m: float,
) -> tuple[Waypoint, ...]:
    """A fixed-wing's waypoints made flyable from `start` (lat, lon, heading: where it
    is now) at its planned turn radius (`planning.flight.flyable_waypoints`): the
    points of `free` (item indexes: transit legs) may be skipped, the others are
    passed. Other vehicles' waypoints unchanged. Raises `PlanningError` when a corner
    has no connection clear of the zones, or the flown path would enter one."""
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
    out, _tracks = flyable_waypoints(
        waypoints, frame, zs, radius_m=flyable(profile).turn_radius_m(speed), start=pose,
        free=free, vehicle_id=profile.vehicle_id,
    )  # fmt: skip
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
) -> list[Waypoint]:
    """Waypoints (excluding `start`, including `end`) that fly from start to end keeping
    `margin_m` clear of every no-fly zone at that altitude: straight when the straight
    leg is clear, else the shortest way round the inflated zones (visibility graph);
    if the ends are too close to a zone for the margin, the raw-zone avoidance of the
    planners (over or around). The legs a plan does not cover (to the first waypoint,
    back to base) go through here."""
    direct = [Waypoint(lat_deg=end[0], lon_deg=end[1], alt_rel_m=alt_rel_m)]
    if not zones:
        return direct
    frame = LocalFrame.at([LatLon(*start), LatLon(*end)])
    a, b = frame.to_local(*start), frame.to_local(*end)
    route: list[tuple[float, float, float]] | None = None
    for m in (margin_m, margin_m / 2, margin_m / 4):  # an end close to a zone: less margin
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
    headings) whose sampled path keeps clear of the zones; its arcs become waypoints."""
    from .planning.dubins import Pose, all_paths

    legs = safe_transit(
        start, end, alt_rel_m, zones, now=now, home_alt_msl_m=home_alt_msl_m, margin_m=radius_m
    )
    if not zones or radius_m <= 0:
        return legs
    frame = LocalFrame.at([LatLon(*start), LatLon(*end)])
    zs = ZoneSet.from_messages(
        zones, frame, now_unix_s=now, home_alt_msl_m=home_alt_msl_m, margin_m=TRANSIT_MARGIN_M
    )
    blocked = zs.keep_out(alt_rel_m)
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
        return legs  # no clear entry: the straight legs are the best we have
    arc = []
    for q in best.waypoints()[:-1]:
        lat, lon = frame.to_geodetic(q.x, q.y)
        arc.append(Waypoint(lat_deg=lat, lon_deg=lon, alt_rel_m=alt_rel_m))
    return [*arc, *legs]


def _distance_m(lat1: float, lon1: float, lat2: float, lon2: float) -> float:
    dn = (lat2 - lat1) * 111_320.0
    de = (lon2 - lon1) * 111_320.0 * math.cos(math.radians(lat1))
    return math.hypot(dn, de)


@dataclass
class MissionManager:
    profile: VehicleProfile
    phase: Phase = Phase.IDLE
    mission_id: int | None = None
    takeoff_alt_m: float = 0.0
    items: int = 0  # mission items uploaded (home + waypoints)
    last_item: int = 0  # reaching this item completes the mission
    zones: tuple[NoFlyZone, ...] = ()
    _steps: list[ApRequest] = field(default_factory=list)
    _in_flight: ApRequest | None = None  # the request we wait for
    _ids: itertools.count[int] = field(default_factory=lambda: itertools.count(FIRST_REQUEST_ID))

    @property
    def mission_state(self) -> MissionState:
        return {
            Phase.IDLE: MissionState.IDLE,
            Phase.STARTING: MissionState.PREMISSION,
            Phase.CLIMBING: MissionState.PREMISSION,
            Phase.FLYING: MissionState.MISSION,
            Phase.RETURNING: MissionState.MISSION,
            Phase.LANDING: MissionState.MISSION,
            Phase.PARACHUTE: MissionState.PARACHUTE,
        }[self.phase]

    @property
    def land_radius_m(self) -> float:
        """How close RTL must bring the vehicle before it lands: a VTOL loiters around
        home at its turn radius in RTL, a multirotor comes right over it."""
        return max(LAND_AT_HOME_M, 1.5 * self.profile.turn_radius_m())

    @property
    def transit_margin_m(self) -> float:
        """Clearance from zones on transit legs: a fixed-wing may start the leg with a
        U-turn as wide as two turn radii."""
        return max(TRANSIT_MARGIN_M, 2.0 * self.profile.turn_radius_m())

    def owns(self, request_id: int) -> bool:
        return FIRST_REQUEST_ID <= request_id < FENCE_FIRST_REQUEST_ID

    # ------------------------------------------------------------------ start
    def release(
        self,
        mission: Mission,
        members: Sequence[Member],
        zones: Sequence[NoFlyZone],
        ap: AutopilotState,
        now: float,
    ) -> list[Out]:
        """Plan the mission and start flying this vehicle's share."""
        mid = mission.mission_id
        home_alt = ap.home.alt_msl_m if ap.home else 0.0
        try:
            waypoints = plan_share(mission, members, self.profile.vehicle_id, zones, now, home_alt)
        except (PlanningError, ValueError) as exc:
            return [FsmEvent(fsm.PlanFailed(mid, f"planning: {exc}"[:64]))]
        if not waypoints:
            return [FsmEvent(fsm.PlanFailed(mid, "nothing to fly for this vehicle"))]
        try:
            waypoints = self._tight(self._with_approach(waypoints, ap, zones, now, home_alt))
        except (PlanningError, ValueError) as exc:
            return [FsmEvent(fsm.PlanFailed(mid, f"approach: {exc}"[:64]))]
        self.zones = tuple(zones)
        self.mission_id = mid
        fleet_ids = sorted(m.profile.vehicle_id for m in members)
        note = Log(
            f"mission {mid}: planned for fleet {fleet_ids} around {len(zones)} zone(s); {len(waypoints)} items for us"
        )
        # end on an unlimited loiter over the last waypoint: the autopilot holds there
        # (ArduPlane would otherwise RTL by itself, straight through any zone) until the
        # node flies the zone-safe way home
        last = next((w for w in reversed(waypoints) if w.kind == ItemKind.WAYPOINT), None)
        if last is not None:
            waypoints = (
                *waypoints,
                Waypoint(ItemKind.LOITER_UNLIMITED, last.lat_deg, last.lon_deg, last.alt_rel_m),
            )
        self.items = len(waypoints) + 1
        self.last_item = self.items - (2 if last is not None else 1)  # the item that completes it
        self.takeoff_alt_m = mission.params.altitude_rel_m
        steps: list[ApRequest] = [UploadMission(items=waypoints)]
        if not ap.armed:
            steps += self._launch_steps()
        else:
            steps.append(StartMission())
        self._steps = steps
        self.phase = Phase.STARTING
        return [note, *self._next()]

    def _tight(self, waypoints: Sequence[Waypoint]) -> tuple[Waypoint, ...]:
        """Fixed-wing: every plain waypoint asks for FIXED_WING_ACCEPT_M acceptance."""
        if not self.profile.is_fixed_wing:
            return tuple(waypoints)
        return tuple(
            msgspec.structs.replace(w, acceptance_radius_m=FIXED_WING_ACCEPT_M)
            if w.kind == ItemKind.WAYPOINT and w.acceptance_radius_m == 0.0
            else w
            for w in waypoints
        )

    def _with_approach(
        self,
        waypoints: tuple[Waypoint, ...],
        ap: AutopilotState,
        zones: Sequence[NoFlyZone],
        now: float,
        home_alt: float,
    ) -> tuple[Waypoint, ...]:
        """Prefix the leg from where the vehicle is to its first waypoint, around zones;
        a fixed-wing's then made flyable from its pose (the leg's points and the plan's
        first one, where the plan assumed it starts, may be skipped)."""
        first_at = next((i for i, w in enumerate(waypoints) if w.kind == ItemKind.WAYPOINT), None)
        if first_at is None or ap.lat_deg is None or ap.lon_deg is None:
            return waypoints
        first = waypoints[first_at]
        leg: list[Waypoint] = []
        if zones:
            leg = self._transit(
                (ap.lat_deg, ap.lon_deg),
                ap.heading_deg,
                (first.lat_deg, first.lon_deg),
                first.alt_rel_m,
                zones,
                now,
                home_alt,
            )[:-1]
        out = (*leg, *waypoints)
        free = frozenset(range(len(leg))) | {len(leg) + first_at}
        return fly_corners(
            out, self.profile, zones, start=(ap.lat_deg, ap.lon_deg, ap.heading_deg),
            free=free, now=now, home_alt_msl_m=home_alt,
        )  # fmt: skip

    def _transit(
        self,
        start: tuple[float, float],
        heading_deg: float,
        end: tuple[float, float],
        alt_rel_m: float,
        zones: Sequence[NoFlyZone],
        now: float,
        home_alt: float,
    ) -> list[Waypoint]:
        if self.profile.is_fixed_wing:
            return fixed_wing_transit(
                start, heading_deg, end, alt_rel_m, zones,
                radius_m=self.profile.turn_radius_m(), now=now, home_alt_msl_m=home_alt,
            )  # fmt: skip
        return safe_transit(
            start,
            end,
            alt_rel_m,
            zones,
            now=now,
            home_alt_msl_m=home_alt,
            margin_m=self.transit_margin_m,
        )

    def _launch_steps(self) -> list[ApRequest]:
        vt = self.profile.vehicle_type
        if vt in (VehicleType.ROVER, VehicleType.BOAT):
            return [Arm(), StartMission()]
        steps: list[ApRequest] = [SetMode(mode="GUIDED")] if self.profile.can_hover else []
        return [
            *steps,
            Arm(),
            Takeoff(alt_rel_m=self.takeoff_alt_m),
        ]  # StartMission after the climb

    def _next(self) -> list[Out]:
        if not self._steps:
            self._in_flight = None
            return []
        req = msgspec.structs.replace(self._steps.pop(0), request_id=next(self._ids))
        self._in_flight = req
        return [Submit(req)]

    # ------------------------------------------------------------------ return
    def start_return(self, ap: AutopilotState, zones: Sequence[NoFlyZone], now: float) -> list[Out]:
        """Fly back to base around the no-fly zones and land there: a short mission of
        zone-safe waypoints to above home, then RTL (whose landing the autopilot or
        `on_autopilot` completes). Without zones in the way, plain RTL."""
        self.mission_id = fsm.RETURN_MISSION
        self.phase = Phase.RETURNING
        done = [FsmEvent(fsm.PlanSucceeded(fsm.RETURN_MISSION))]
        home = ap.home
        if not zones or home is None or ap.lat_deg is None or ap.lon_deg is None or not ap.armed:
            self._steps = [ReturnToLaunch()]
            return [*done, *self._next()]
        try:
            leg = self._transit_from(ap, (home.lat_deg, home.lon_deg), zones, now, home.alt_msl_m)
        except (PlanningError, ValueError):
            leg = []
        note: list[Out] = []
        if len(leg) > 1:
            try:
                leg = list(self._flyable_leg(leg, ap, zones, now, home.alt_msl_m))
            except (PlanningError, ValueError) as exc:  # the zone-safe legs, as planned
                note = [Log(f"return: no flyable turns ({exc}); flying the legs as they are")]
        if len(leg) <= 1:  # nothing in the way: plain RTL
            self._steps = [ReturnToLaunch()]
        else:
            self.items = len(leg) + 2
            self.last_item = self.items - 1
            self._steps = [
                UploadMission(items=(*self._tight(leg), Waypoint(ItemKind.RTL))),
                StartMission(),
            ]
        return [*done, *note, *self._next()]

    def _transit_from(
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
        return self._transit(
            (ap.lat_deg, ap.lon_deg), ap.heading_deg, there, alt, zones, now, home_alt
        )

    def _flyable_leg(
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
            leg, self.profile, zones, start=(ap.lat_deg, ap.lon_deg, ap.heading_deg),
            free=frozenset(range(len(leg) - 1)), now=now, home_alt_msl_m=home_alt,
        )  # fmt: skip

    def stop(self) -> None:
        self.phase, self.mission_id, self._steps, self._in_flight = Phase.IDLE, None, [], None

    def take_over(self, phase: Phase) -> None:
        """The operator's command (RTL, LAND, EMERGENCY_LAND, PARACHUTE) flies the
        vehicle now: drop whatever was planned and only watch for the landing
        (RETURNING: a hover-capable vehicle is landed once near home, as on the node's
        own return)."""
        self.stop()
        self.phase, self.mission_id = phase, fsm.RETURN_MISSION

    @property
    def landing(self) -> bool:
        """On the way down or home (what ABORT_LANDING can cancel)."""
        return self.phase in (Phase.RETURNING, Phase.LANDING)

    def landing_route(
        self, point: GeoPoint, ap: AutopilotState, zones: Sequence[NoFlyZone], now: float
    ) -> tuple[ApRequest, ...]:
        """An emergency landing at `point` (paper section 3.5.1: "if the landing route has
        been specified"): a zone-safe leg from here at the current altitude (at least
        30 m), then a landing item there, flown in AUTO."""
        home = ap.home
        if home is None or ap.lat_deg is None or ap.lon_deg is None:
            raise PlanningError("no position or home")
        leg = self._transit_from(ap, (point.lat_deg, point.lon_deg), zones, now, home.alt_msl_m)
        leg = list(self._flyable_leg(leg, ap, zones, now, home.alt_msl_m))
        land = Waypoint(ItemKind.LAND, point.lat_deg, point.lon_deg, 0.0)
        return (UploadMission(items=(*self._tight(leg[:-1]), land)), StartMission())

    # ------------------------------------------------------------------ inputs
    def on_result(self, result: ApResult, now: float) -> list[Out]:
        done = self._in_flight
        if done is None or result.request_id != done.request_id:
            return []
        self._in_flight = None
        mid = self.mission_id if self.mission_id is not None else 0
        if not result.ok:
            phase = self.phase
            if phase == Phase.RETURNING and not isinstance(done, ReturnToLaunch):
                self._steps = [ReturnToLaunch()]  # the zone-safe way home failed: plain RTL
                return self._next()
            self.stop()
            if phase == Phase.STARTING:
                return [FsmEvent(fsm.PlanFailed(mid, f"autopilot: {result.reason}"[:64]))]
            return []  # RTL/land refused: monitoring and the operator take it from here
        if self.phase == Phase.STARTING and not self._steps:
            if isinstance(done, Takeoff):
                self.phase = Phase.CLIMBING  # the mission starts once it has climbed
                return []
            if isinstance(done, StartMission):
                self.phase = Phase.FLYING
                return [FsmEvent(fsm.PlanSucceeded(mid))]
        return self._next()

    def on_autopilot(self, ap: AutopilotState, now: float) -> list[Out]:
        if (
            self.phase in (Phase.RETURNING, Phase.LANDING, Phase.PARACHUTE)
            and not ap.armed
            and (ap.alt_rel_m or 0.0) < 2.0
        ):
            self.stop()
            return [FsmEvent(fsm.LandingComplete())]
        if self.phase == Phase.CLIMBING:
            if (ap.alt_rel_m or 0.0) >= CLIMB_FRACTION * self.takeoff_alt_m:
                self.phase = Phase.STARTING
                self._steps = [StartMission()]
                return self._next()
        elif self.phase == Phase.FLYING and self.items > 1:
            if ap.mission_reached >= self.last_item and self.mission_id is not None:
                mid = self.mission_id
                self.stop()
                return [FsmEvent(fsm.MissionComplete(mid))]
        elif self.phase == Phase.RETURNING and self._in_flight is None and self.profile.can_hover:
            home = ap.home
            if (
                home
                and ap.lat_deg is not None
                and ap.lon_deg is not None
                and _distance_m(ap.lat_deg, ap.lon_deg, home.lat_deg, home.lon_deg)
                < self.land_radius_m
            ):
                self.phase = Phase.LANDING
                ground = self.profile.vehicle_type in (VehicleType.ROVER, VehicleType.BOAT)
                self._steps = [Land(), Disarm()] if ground else [Land()]
                return self._next()
        return []

    def progress_pct(self, ap: AutopilotState) -> int | None:
        """Mission progress from the autopilot (None: let the link compute it)."""
        if self.phase == Phase.FLYING and self.items > 1:
            done = max(0, min(ap.mission_reached, self.last_item))
            return int(100 * done / max(1, self.last_item))
        return None
