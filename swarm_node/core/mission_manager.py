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
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from enum import Enum

import msgspec

from swarm_proto import GeoPoint, Mission, MissionState, MissionType, NoFlyZone, VehicleType

from . import state_machine as fsm
from .autopilot.items import Waypoint
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
from .planning import (
    PlanningError,
    PlanVehicle,
    VehiclePose,
    plan_area,
    plan_objective,
    plan_perimeter,
    plan_route,
    plan_target,
)
from .profile import VehicleProfile

PLANNERS: dict[MissionType, Callable[..., object]] = {
    MissionType.AREA: plan_area,
    MissionType.TARGET: plan_target,
    MissionType.PERIMETER: plan_perimeter,
    MissionType.ROUTE: plan_route,
    MissionType.OBJECTIVE: plan_objective,
}

CLIMB_FRACTION = 0.8  # start the mission once this much of the take-off altitude is reached
LAND_AT_HOME_M = 30.0  # multirotors: land once RTL has brought them this close to home
FIRST_REQUEST_ID = 1_000_000  # the command manager uses small ids


class Phase(Enum):
    IDLE = "idle"
    STARTING = "starting"  # upload, arm, take off
    CLIMBING = "climbing"  # waiting for the take-off altitude
    FLYING = "flying"  # the mission is running on the autopilot
    RETURNING = "returning"  # RTL
    LANDING = "landing"


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


Out = Submit | FsmEvent


def plan_share(
    mission: Mission,
    members: Sequence[Member],
    self_id: int,
    zones: Sequence[NoFlyZone],
    now: float,
    home_alt_msl_m: float,
) -> tuple[Waypoint, ...]:
    """This vehicle's waypoints in a plan made for every member (sorted by id, posed at
    their homes: inputs every member sees the same)."""
    planner = PLANNERS.get(mission.mission_type)
    if planner is None:
        raise PlanningError(f"{mission.mission_type.name} missions are not planned yet")
    vehicles = [
        PlanVehicle(m.profile, VehiclePose(m.home.lat_deg, m.home.lon_deg) if m.home else None)
        for m in sorted(members, key=lambda m: m.profile.vehicle_id)
    ]
    plan = planner(
        mission.geometry,
        vehicles,
        mission.params,
        zones=zones,
        now_unix_s=now,
        home_alt_msl_m=home_alt_msl_m,
        zone_margin_m=max((m.profile.turn_radius_m() for m in members), default=0.0),
    )
    for share in plan.vehicles:  # type: ignore[attr-defined]  # every plan has .vehicles
        if share.vehicle_id == self_id:
            return tuple(share.waypoints)
    raise PlanningError(f"the plan has no share for vehicle {self_id}")


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
        }[self.phase]

    @property
    def land_radius_m(self) -> float:
        """How close RTL must bring the vehicle before it lands: a VTOL loiters around
        home at its turn radius in RTL, a multirotor comes right over it."""
        return max(LAND_AT_HOME_M, 1.5 * self.profile.turn_radius_m())

    def owns(self, request_id: int) -> bool:
        return request_id >= FIRST_REQUEST_ID

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
        self.mission_id = mid
        self.items = len(waypoints) + 1
        self.takeoff_alt_m = mission.params.altitude_rel_m
        steps: list[ApRequest] = [UploadMission(items=waypoints)]
        if not ap.armed:
            steps += self._launch_steps()
        else:
            steps.append(StartMission())
        self._steps = steps
        self.phase = Phase.STARTING
        return self._next()

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
    def start_return(self, now: float) -> list[Out]:
        """Fly back to base (the rally point) and land there."""
        self.mission_id = fsm.RETURN_MISSION
        self.phase = Phase.RETURNING
        self._steps = [ReturnToLaunch()]
        return [FsmEvent(fsm.PlanSucceeded(fsm.RETURN_MISSION)), *self._next()]

    def stop(self) -> None:
        self.phase, self.mission_id, self._steps, self._in_flight = Phase.IDLE, None, [], None

    # ------------------------------------------------------------------ inputs
    def on_result(self, result: ApResult, now: float) -> list[Out]:
        done = self._in_flight
        if done is None or result.request_id != done.request_id:
            return []
        self._in_flight = None
        mid = self.mission_id if self.mission_id is not None else 0
        if not result.ok:
            phase = self.phase
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
        if self.phase == Phase.CLIMBING:
            if (ap.alt_rel_m or 0.0) >= CLIMB_FRACTION * self.takeoff_alt_m:
                self.phase = Phase.STARTING
                self._steps = [StartMission()]
                return self._next()
        elif self.phase == Phase.FLYING and self.items > 1:
            if ap.mission_reached >= self.items - 1 and self.mission_id is not None:
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
        if (
            self.phase in (Phase.RETURNING, Phase.LANDING)
            and not ap.armed
            and (ap.alt_rel_m or 0.0) < 2.0
        ):
            self.stop()
            return [FsmEvent(fsm.LandingComplete())]
        return []

    def progress_pct(self, ap: AutopilotState) -> int | None:
        """Mission progress from the autopilot (None: let the link compute it)."""
        if self.phase == Phase.FLYING and self.items > 1:
            done = max(0, min(ap.mission_reached, self.items - 1))
            return int(100 * done / (self.items - 1))
        return None
