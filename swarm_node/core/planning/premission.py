"""PREMISSION (paper section 2.3.5): from where each vehicle is to the entry point of its
share so that the fleet arrives together, and in MISSION a speed rule that keeps the
vehicles of one mission on the same schedule.

`premission(plan, vehicles, ...)`: each vehicle's entry is where its share's work
starts, past the approach its planner made from the vehicle's home (`entry_index`: an
area share's first lane start, heading along the lane; a route's first point; a
patrol's start on its loop; a target slot), heading along the share's next leg. A fixed-wing flies the shortest Dubins
path from its pose (position and heading) to the entry pose, at its planned turn
radius (`fleet_plan.flyable`), clear of the zones (`route.approach`: else around
them); a hover-capable vehicle flies straight and may wait on the spot. The common
arrival time is the earliest every vehicle can meet within its speed range on that
radius, with whole waiting orbits where needed (`route.synchronize`), so the predicted
arrival spread is 0 (the benchmark checks it <= 2 s). Each vehicle then uploads
`PremissionLeg.waypoints` (arrival speed, hover wait, approach with its waiting orbit,
the entry, then the mission speed) followed by its share from `resume_index`
(`PremissionPlan.mission_waypoints`).

`sync_speed(...)`: the MISSION rule. Every member knows its own and (from their
published progress in metres) the others' lateness against the planned schedule
(`Share.planned_s_at`: metres along a share -> planned seconds since the share
started); a vehicle later than the fleet's mean lateness speeds up, one earlier slows
down, in proportion (`SYNC_GAIN_PER_S` per second of difference) within its speed
range, with a dead band so that nobody hunts. The whole fleet late together (a
headwind) changes nobody's speed: the rule keeps the members together, not on the
clock.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

from swarm_node.core.autopilot.items import ItemKind, Waypoint
from swarm_proto import LatLon, NoFlyZone

from .area import AreaPlan
from .dubins import Pose
from .errors import InvalidParameterError, PlanningError
from .fleet_plan import FleetPlan, Share, along_metres, flyable, local_xy
from .geo import LocalFrame
from .objective import ObjectivePlan
from .perimeter import PerimeterPlan
from .route import Arrival, Leg, RoutePlan, approach, arrival_waypoints, synchronize
from .target import TargetPlan
from .vehicles import PlanVehicle
from .zones import ZoneSet

#: speed change per second of lateness against the fleet (fraction of the nominal speed)
SYNC_GAIN_PER_S = 0.02
#: lateness differences below this are left alone
SYNC_DEADBAND_S = 1.0
#: how fast a vehicle changes speed on a new speed command (TECS-like, assumption)
SPEED_CHANGE_M_S2 = 2.0


@dataclass(frozen=True)
class PremissionLeg:
    vehicle_id: int
    waypoints: tuple[Waypoint, ...]  # to upload before the share's rest
    resume_index: int  # the share's items from here follow `waypoints`
    entry: Pose  # local, in `PremissionPlan.frame`
    path_m: float  # the approach path (without waiting orbits)
    orbits: int
    hold_s: float
    speed_m_s: float  # on the approach
    arrival_s: float  # predicted, from now
    orbit_m: float = 0.0  # one waiting orbit

    @property
    def flown_m(self) -> float:
        return self.path_m + self.orbits * self.orbit_m

    def remaining_m(self, reached_index: int, lat_deg: float, lon_deg: float) -> float | None:
        """Metres of the approach left to a vehicle whose last reached item of
        `waypoints` is `reached_index` (< 0: none) at (lat, lon): along the approach's
        waypoints to the entry; None while a waiting orbit is still to be flown (its
        progress is not measured)."""
        loiter = next(
            (k for k, w in enumerate(self.waypoints) if w.kind == ItemKind.LOITER_TURNS), None
        )
        if loiter is not None and reached_index < loiter:
            return None
        along = along_metres(self.waypoints)
        share = Share(self.vehicle_id, self.waypoints, along, along[-1] if along else 0.0, 0.0)
        return max(share.length_m - share.progress_m(reached_index, lat_deg, lon_deg), 0.0)


@dataclass(frozen=True)
class PremissionPlan:
    frame: LocalFrame
    arrival_s: float  # the common arrival time, from now
    legs: Mapping[int, PremissionLeg]

    @property
    def spread_s(self) -> float:
        """Predicted spread of the arrivals at the entry points (s)."""
        times = [leg.arrival_s for leg in self.legs.values()]
        return max(times) - min(times) if times else 0.0

    def mission_waypoints(self, share: Share) -> tuple[Waypoint, ...]:
        """What the vehicle uploads: its approach, then its share from the entry on."""
        leg = self.legs[share.vehicle_id]
        return (*leg.waypoints, *share.waypoints[leg.resume_index :])


def entry_index(plan: FleetPlan, vehicle_id: int) -> int:
    """The item where a share's work starts, past the approach its planner made from
    where the vehicle was at planning time: an area share's first lane start (the
    flyable stage keeps it); a route's first point or a patrol's start on its loop (the
    last waypoint before the share's second CHANGE_SPEED: the arrival speed, then the
    mission speed); a target slot (the last waypoint before the final hold); else the
    first waypoint."""
    share = plan.share(vehicle_id)
    wps = share.waypoints
    positioned = [k for k, w in enumerate(wps) if w.kind == ItemKind.WAYPOINT]
    if not positioned:
        raise PlanningError(f"vehicle {vehicle_id}'s share has no waypoint to enter at")
    detail = plan.detail[0] if isinstance(plan.detail, tuple) else plan.detail
    if isinstance(detail, AreaPlan):
        path = detail.split.of(vehicle_id).path if vehicle_id in plan.roster else None
        if path is not None and path.lanes:
            a = path.lanes[0].a
            xy = local_xy(detail.frame, wps)
            for k in positioned:
                p = xy[k]
                if p is not None and math.dist(p, a) < 0.05:
                    return k
        return positioned[0]
    if isinstance(detail, RoutePlan | PerimeterPlan):
        speeds = [k for k, w in enumerate(wps) if w.kind == ItemKind.CHANGE_SPEED]
        if len(speeds) >= 2:
            before = [k for k in positioned if k < speeds[1]]
            if before:
                return before[-1]
        return positioned[0]
    if isinstance(detail, TargetPlan | ObjectivePlan) and wps[-1].kind in _HOLDS:
        before = [k for k in positioned if k < len(wps) - 1]
        if before:
            return before[-1]
    return positioned[0]


_HOLDS = frozenset({ItemKind.LOITER_TURNS, ItemKind.LOITER_UNLIMITED, ItemKind.LOITER_TIME})


def _entry_pose(frame: LocalFrame, share: Share, k: int) -> Pose:
    xy = local_xy(frame, share.waypoints)
    here = xy[k]
    assert here is not None
    nxt = next((p for p in xy[k + 1 :] if p is not None and math.dist(p, here) > 0.5), None)
    prev = next((p for p in reversed(xy[:k]) if p is not None and math.dist(p, here) > 0.5), None)
    if nxt is not None:
        yaw = math.atan2(nxt[1] - here[1], nxt[0] - here[0])
    elif prev is not None:
        yaw = math.atan2(here[1] - prev[1], here[0] - prev[0])
    else:
        yaw = 0.0
    return Pose(here[0], here[1], yaw)


def _share_speed(share: Share, vehicle: PlanVehicle) -> float:
    s = next(
        (w.speed_m_s for w in share.waypoints if w.kind == ItemKind.CHANGE_SPEED and w.speed_m_s),
        None,
    )
    return s if s is not None else vehicle.profile.cruise_speed_m_s


def premission(
    plan: FleetPlan,
    vehicles: Sequence[PlanVehicle],
    *,
    zones: Sequence[NoFlyZone] = (),
    now_unix_s: float = 0.0,
    home_alt_msl_m: float = 0.0,
    not_before_s: float = 0.0,
) -> PremissionPlan:
    """Every vehicle of `vehicles` (posed where it is now, heading included; each with
    a share in `plan`) from its pose to its entry, arriving together (not before
    `not_before_s` from now). The time a vehicle takes to change from the speed it
    flies now (`VehiclePose.groundspeed_m_s`) to its arrival speed is counted
    (`SPEED_CHANGE_M_S2`). Raises `InfeasibleTimingError` when no common arrival
    fits the speed ranges and orbits, `NoSafeRouteError` when an approach has no
    clear way."""
    vs = sorted(vehicles, key=lambda v: v.vehicle_id)
    if not vs:
        raise InvalidParameterError("PREMISSION needs at least one vehicle")
    if any(v.pose is None for v in vs):
        raise InvalidParameterError("PREMISSION needs every vehicle's pose")
    entries = {v.vehicle_id: entry_index(plan, v.vehicle_id) for v in vs}
    pts: list[LatLon] = []
    for v in vs:
        w = plan.share(v.vehicle_id).waypoints[entries[v.vehicle_id]]
        assert v.pose is not None
        pts += [LatLon(w.lat_deg, w.lon_deg), LatLon(v.pose.lat_deg, v.pose.lon_deg)]
    frame = LocalFrame.at(pts)
    margin = max(flyable(v.profile).turn_radius_m() for v in vs)
    zs = ZoneSet.from_messages(
        zones, frame, now_unix_s=now_unix_s, home_alt_msl_m=home_alt_msl_m, margin_m=margin
    )
    aps = {}
    for v in vs:
        fv = PlanVehicle(flyable(v.profile), v.pose)
        share = plan.share(v.vehicle_id)
        k = entries[v.vehicle_id]
        goal = _entry_pose(frame, share, k)
        assert v.pose is not None
        start = Pose(*frame.pose(v.pose))
        speed = min(max(_share_speed(share, fv), fv.speed_range()[0]), fv.speed_range()[1])
        alt = share.waypoints[k].alt_rel_m
        aps[v.vehicle_id] = (start, goal, speed, alt, approach(fv, start, goal, speed, zs, alt))
    # from the speed each flies now to its arrival speed it gains (or loses) distance:
    # counted as path made longer (shorter), and the arrival solved again
    legs: list[Leg] = [ap.leg for *_rest, ap in aps.values()]
    sync: dict[int, Arrival] = synchronize(legs, not_before_s=not_before_s)
    for _ in range(2):
        adjusted = []
        for v, leg in zip(vs, legs, strict=True):
            assert v.pose is not None
            v0 = v.pose.groundspeed_m_s
            dv = sync[v.vehicle_id].speed_m_s - v0 if v0 > 0.0 else 0.0
            lag = math.copysign(dv * dv / (2.0 * SPEED_CHANGE_M_S2), dv)
            adjusted.append(dataclasses.replace(leg, path_m=max(leg.path_m + lag, 0.0)))
        sync = synchronize(adjusted, not_before_s=not_before_s)
    out: dict[int, PremissionLeg] = {}
    for v in vs:
        start, goal, speed, alt, ap = aps[v.vehicle_id]
        arr = sync[v.vehicle_id]
        wps = list(arrival_waypoints(frame, ap, arr, alt, start))
        wps.append(Waypoint(ItemKind.CHANGE_SPEED, speed_m_s=speed))
        arrival = arr.arrival_s
        out[v.vehicle_id] = PremissionLeg(
            v.vehicle_id,
            tuple(wps),
            entries[v.vehicle_id] + 1,
            goal,
            ap.leg.path_m,
            arr.orbits,
            arr.hold_s,
            arr.speed_m_s,
            arrival,
            ap.leg.orbit_m,
        )
    t = next(iter(sync.values())).arrival_s if sync else 0.0
    return PremissionPlan(frame, t, out)


def premission_speed(
    remaining_m: float, time_left_s: float, speed_range: tuple[float, float]
) -> float:
    """Closed-loop PREMISSION airspeed: what reaches the entry `time_left_s` from now
    over `remaining_m`, within `speed_range` (the top when the time is up)."""
    lo, hi = speed_range
    if not (math.isfinite(remaining_m) and math.isfinite(time_left_s)):
        raise InvalidParameterError("remaining metres and time must be finite")
    if time_left_s <= 0.0:
        return hi
    return min(max(remaining_m / time_left_s, lo), hi)


# --------------------------------------------------------------------------- MISSION


def lateness_s(share: Share, progress_m: float, elapsed_s: float) -> float:
    """How late a vehicle `progress_m` along its share is, `elapsed_s` after the share
    started, against the planned schedule (negative: early)."""
    return elapsed_s - share.planned_s_at(progress_m)


@dataclass(frozen=True, slots=True)
class SpeedCommand:
    speed_m_s: float
    lateness_s: float  # this vehicle's, against the schedule
    behind_fleet_s: float  # its lateness minus the fleet's mean lateness
    changed: bool  # outside the dead band: command it


def sync_speed(
    own_lateness_s: float,
    fleet_lateness_s: Mapping[int, float],
    nominal_m_s: float,
    speed_range: tuple[float, float],
    *,
    gain_per_s: float = SYNC_GAIN_PER_S,
    deadband_s: float = SYNC_DEADBAND_S,
) -> SpeedCommand:
    """The MISSION speed rule: `nominal_m_s` (the planned speed) times 1 + gain x (own
    lateness - the fleet's mean lateness), clamped to `speed_range` (for a fixed-wing,
    `PlanVehicle.speed_range_on` its planned turn radius); the nominal speed inside the
    dead band. `fleet_lateness_s`: the other members' lateness (by id)."""
    vals = [own_lateness_s, *fleet_lateness_s.values()]
    if not all(math.isfinite(x) for x in vals):
        raise InvalidParameterError("lateness must be finite")
    lo, hi = speed_range
    if not (math.isfinite(nominal_m_s) and nominal_m_s > 0.0 and 0.0 <= lo <= hi):
        raise InvalidParameterError(f"bad speed {nominal_m_s} or range {speed_range}")
    mean = sum(vals) / len(vals) if fleet_lateness_s else own_lateness_s
    behind = own_lateness_s - mean
    if abs(behind) < deadband_s:
        v = min(max(nominal_m_s, lo), hi)
        return SpeedCommand(v, own_lateness_s, behind, False)
    v = nominal_m_s * (1.0 + gain_per_s * behind)
    return SpeedCommand(min(max(v, lo), hi), own_lateness_s, behind, True)
