"""Planner glue: a mission and its roster in, the whole fleet's plan out.

Every fleet member plans the whole mission for the whole fleet from the same inputs
(the mission, the frozen roster's database profiles sorted by id, their homes, the
zones) and keeps its own share, so the members agree without exchanging plans: the
split must not depend on anything that differs between nodes (live positions, arrival
times of telemetry). The whole `FleetPlan` is kept (every member's share), which is
what replanning after a loss starts from.

Planning can take seconds (a 4,000-vertex area), so it never runs on the node's control
loop: the mission manager emits a `PlanJob` (a picklable `PlanRequest`), the shell runs
`run_plan` in a worker (runtime) or inline (Fleet, FastFleet) and hands the
`PlanOutcome` back as an input (`PlanDone`).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

from swarm_proto import GeoPoint, Mission, MissionType, NoFlyZone

from ..autopilot.items import Waypoint
from ..planning import (
    PlanningError,
    PlanVehicle,
    VehiclePose,
    plan_area,
    plan_objective,
    plan_perimeter,
    plan_route,
    plan_target,
)
from ..planning.flight import flyable_plan
from ..planning.transit import flyable
from ..profile import VehicleProfile

PLANNERS: dict[MissionType, Callable[..., object]] = {
    MissionType.AREA: plan_area,
    MissionType.TARGET: plan_target,
    MissionType.PERIMETER: plan_perimeter,
    MissionType.ROUTE: plan_route,
    MissionType.OBJECTIVE: plan_objective,
}


@dataclass(frozen=True)
class Member:
    profile: VehicleProfile
    home: GeoPoint | None


@dataclass(frozen=True)
class FleetPlan:
    """Every member's waypoints (by vehicle id) and the planner's own plan object."""

    mission_id: int
    members: tuple[int, ...]
    shares: dict[int, tuple[Waypoint, ...]]
    plan: object = field(default=None, compare=False)

    def share(self, vehicle_id: int) -> tuple[Waypoint, ...]:
        if vehicle_id not in self.shares:
            raise PlanningError(f"the plan has no share for vehicle {vehicle_id}")
        return self.shares[vehicle_id]


@dataclass(frozen=True)
class PlanRequest:
    """Everything a plan needs, picklable (a worker process may run it)."""

    job_id: int
    mission: Mission
    members: tuple[Member, ...]
    zones: tuple[NoFlyZone, ...]
    now: float
    home_alt_msl_m: float


@dataclass(frozen=True)
class PlanOutcome:
    job_id: int
    plan: FleetPlan | None
    error: str = ""


def plan_fleet(
    mission: Mission,
    members: Sequence[Member],
    zones: Sequence[NoFlyZone],
    now: float,
    home_alt_msl_m: float,
) -> FleetPlan:
    """The whole fleet's plan (members sorted by id, posed at their homes: inputs every
    member sees the same); every fixed-wing share made flyable as planned."""
    planner = PLANNERS.get(mission.mission_type)
    if planner is None:
        raise PlanningError(f"{mission.mission_type.name} missions are not planned yet")
    ordered = sorted(members, key=lambda m: m.profile.vehicle_id)
    vehicles = [
        PlanVehicle(
            flyable(m.profile), VehiclePose(m.home.lat_deg, m.home.lon_deg) if m.home else None
        )
        for m in ordered
    ]
    plan = planner(
        mission.geometry,
        vehicles,
        mission.params,
        zones=zones,
        now_unix_s=now,
        home_alt_msl_m=home_alt_msl_m,
        zone_margin_m=max((flyable(m.profile).turn_radius_m() for m in members), default=0.0),
    )
    plan = flyable_plan(plan, vehicles, zones, now_unix_s=now, home_alt_msl_m=home_alt_msl_m)
    shares = {s.vehicle_id: tuple(s.waypoints) for s in plan.vehicles}
    return FleetPlan(
        mission.mission_id, tuple(m.profile.vehicle_id for m in ordered), shares, plan
    )


def run_plan(req: PlanRequest) -> PlanOutcome:
    """Run a plan job; a planning error is an outcome, never an exception."""
    try:
        plan = plan_fleet(req.mission, req.members, req.zones, req.now, req.home_alt_msl_m)
    except (PlanningError, ValueError) as exc:
        return PlanOutcome(req.job_id, None, f"planning: {exc}")
    return PlanOutcome(req.job_id, plan)
