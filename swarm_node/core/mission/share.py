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

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

from swarm_proto import GeoPoint, Mission, NoFlyZone, ReasonDetail

from ..autopilot.items import ItemKind
from ..planning import PlanningError, PlanVehicle, VehiclePose
from ..planning.fleet_plan import PLANNERS, FleetPlan, Share
from ..planning.fleet_plan import plan_fleet as plan_whole_fleet
from ..planning.geo import LocalFrame
from ..profile import VehicleProfile

__all__ = [
    "PLANNERS",
    "FleetPlan",
    "Member",
    "PlanOutcome",
    "PlanRequest",
    "Replay",
    "Share",
    "heading_on",
    "plan_fleet",
    "pose_on",
    "replay",
    "run_plan",
    "warm",
]


@dataclass(frozen=True)
class Member:
    """A roster member as the planners see it: its database profile and where it is
    posed (its home for a new plan; for a replan, where its published progress puts it
    on its share: the same on every node)."""

    profile: VehicleProfile
    home: GeoPoint | None
    #: the battery it published on entering PLAN (None: unknown, planned as full)
    battery_pct: float | None = None
    #: a replan's survivor: its heading along its share there (None: north, a home)
    heading_deg: float | None = None


def _vehicles(members: Sequence[Member]) -> list[PlanVehicle]:
    return [
        PlanVehicle(
            m.profile,
            VehiclePose(m.home.lat_deg, m.home.lon_deg, heading_deg=m.heading_deg or 0.0)
            if m.home
            else None,
        )
        for m in members
    ]


def pose_on(base: FleetPlan, vehicle_id: int, progress_m: Mapping[int, float]) -> GeoPoint | None:
    """Where a member's progress puts it on its share of `base` (how a replan poses the
    survivors; None: no share in `base`, a joiner)."""
    share = base.shares.get(vehicle_id)
    if share is None or not share.waypoints:
        return None
    try:
        _k, lat, lon = share.at(progress_m.get(vehicle_id, 0.0))
    except (PlanningError, ValueError):
        return None
    return GeoPoint(lat, lon, 0.0)


def heading_on(base: FleetPlan, vehicle_id: int, progress_m: Mapping[int, float]) -> float | None:
    """The heading (degrees from north) of a member's share where its progress puts it:
    along the leg it is on (how a replan heads the survivors: a fixed-wing's first turn
    depends on it; the same on every node). None: no share, or no leg there."""
    share = base.shares.get(vehicle_id)
    if share is None or not share.waypoints:
        return None
    try:
        k, lat, lon = share.at(progress_m.get(vehicle_id, 0.0))
    except (PlanningError, ValueError):
        return None
    ahead = next(
        (
            w
            for w in share.waypoints[k + 1 :]
            if w.kind == ItemKind.WAYPOINT and (w.lat_deg, w.lon_deg) != (lat, lon)
        ),
        None,
    )
    if ahead is None:
        return None
    x, y = LocalFrame(lat, lon).to_local(ahead.lat_deg, ahead.lon_deg)
    if math.hypot(x, y) < 1e-6:
        return None
    return math.degrees(math.atan2(x, y)) % 360.0


def route_ahead(
    base: FleetPlan, vehicle_id: int, progress_m: Mapping[int, float]
) -> tuple[tuple[tuple[float, float, float], ...], float]:
    """What is left of a member's share of `base` from where its progress puts it:
    (lat, lon, height above its home) of every waypoint ahead, in order, and the
    share's speed (0: not given). Empty: no share, or nothing left."""
    share = base.shares.get(vehicle_id)
    if share is None or not share.waypoints:
        return (), 0.0
    try:
        k, lat, lon = share.at(progress_m.get(vehicle_id, 0.0))
    except (PlanningError, ValueError):
        return (), 0.0
    ahead = [w for w in share.waypoints[k + 1 :] if w.kind == ItemKind.WAYPOINT]
    if not ahead:
        return (), 0.0
    points = (
        (lat, lon, ahead[0].alt_rel_m),
        *tuple((w.lat_deg, w.lon_deg, w.alt_rel_m) for w in ahead),
    )
    speed = next((w.speed_m_s for w in share.waypoints if w.speed_m_s), None) or 0.0
    return points, float(speed)


@dataclass(frozen=True)
class Replay:
    """A fleet's plan as it came to be (swarm/regroup.py): the first plan's members at
    their homes, then every replan's members (profiles) and the progress it started
    from; the last replan may be handed to `adopters` (an emptied fleet's mission)."""

    first: tuple[Member, ...]
    #: (members, progress, battery) of each replan
    steps: tuple[
        tuple[tuple[VehicleProfile, ...], Mapping[int, float], Mapping[int, float]], ...
    ] = ()


def replay(
    mission: Mission, lineage: Replay, zones: Sequence[NoFlyZone], now: float, home_alt_msl_m: float
) -> FleetPlan:
    """The plan a fleet flies, made again from its lineage: the same calls, with the same
    inputs, every member made (`plan_fleet`, then `FleetPlan.replan` per step, survivors
    posed by `pose_on`)."""
    plan = plan_fleet(mission, lineage.first, zones, now, home_alt_msl_m)
    for profiles, progress, battery in lineage.steps:
        members = [
            Member(
                p,
                pose_on(plan, p.vehicle_id, progress),
                heading_deg=heading_on(plan, p.vehicle_id, progress),
            )
            for p in profiles
        ]
        plan = plan.replan(
            progress,
            _vehicles(members),
            zones=zones,
            now_unix_s=now,
            home_alt_msl_m=home_alt_msl_m,
            battery_pct=dict(battery) or None,
        )
    return plan


def merge(req: PlanRequest) -> FleetPlan:
    """A healed partition's plan (`FleetPlan.merged`): every other part's plan made
    again from its lineage, its members' progress along their shares of it (as they
    published it), and every member posed where its progress puts it on its part's
    plan."""
    from .published import along_share

    assert req.base is not None
    others: list[tuple[FleetPlan, dict[int, float]]] = []
    for lineage, published in req.merge:
        plan = replay(req.mission, lineage, req.zones, req.now, req.home_alt_msl_m)
        prog = {
            v: along_share(plan.shares[v].length_m, p, path)[0]
            for v, (p, path) in sorted(published.items())
            if v in plan.shares
        }
        others.append((plan, prog))
    parts = [(req.base, dict(req.progress_m)), *others]
    members = []
    for m in req.members:
        vid = m.profile.vehicle_id
        part = next(((p, g) for p, g in parts if vid in p.shares), None)
        if part is None:
            members.append(m)
            continue
        members.append(
            Member(
                m.profile,
                pose_on(part[0], vid, part[1]),
                heading_deg=heading_on(part[0], vid, part[1]),
            )
        )
    return req.base.merged(
        req.progress_m,
        others,
        _vehicles(members),
        zones=req.zones,
        now_unix_s=req.now,
        home_alt_msl_m=req.home_alt_msl_m,
    )


@dataclass(frozen=True)
class PlanRequest:
    """Everything a plan needs, picklable (a worker process may run it). With `base`,
    a replan: what is left of `base` (every old member's `progress_m` along its share)
    shared among `members` (the survivors, posed where their progress puts them)."""

    job_id: int
    mission: Mission
    members: tuple[Member, ...]
    zones: tuple[NoFlyZone, ...]
    now: float
    home_alt_msl_m: float
    base: FleetPlan | None = None
    progress_m: Mapping[int, float] = field(default_factory=dict)
    lineage: Replay | None = None  # a joiner: the fleet's plan made again (`replay`)
    #: a replan's survivors' battery left by the model (`Endurance.left_pct`): an area
    #: replan gives none more than its charge flies home
    battery_pct: Mapping[int, float] = field(default_factory=dict)
    #: a healed partition: each other part's lineage and its members' published
    #: (progress_m, path_m); `base` and `progress_m` are this part's (`merge`)
    merge: tuple[tuple[Replay, Mapping[int, tuple[float, float]]], ...] = ()


@dataclass(frozen=True)
class PlanOutcome:
    job_id: int
    plan: FleetPlan | None
    error: str = ""
    detail: ReasonDetail | None = None  # the error's numbers (an endurance budget)


def plan_fleet(
    mission: Mission,
    members: Sequence[Member],
    zones: Sequence[NoFlyZone],
    now: float,
    home_alt_msl_m: float,
) -> FleetPlan:
    """The whole fleet's plan (`planning.fleet_plan.plan_fleet`: members sorted by id,
    posed at their homes, inputs every member sees the same)."""
    battery = {m.profile.vehicle_id: m.battery_pct for m in members if m.battery_pct is not None}
    return plan_whole_fleet(
        mission,
        _vehicles(members),
        zones=zones,
        now_unix_s=now,
        home_alt_msl_m=home_alt_msl_m,
        battery_pct=battery or None,
    )


def warm() -> bool:
    """Nothing: a worker process that runs it has imported the planners (what a node's
    planner worker does once the node is active, before its first plan job)."""
    return True


def run_plan(req: PlanRequest) -> PlanOutcome:
    """Run a plan job; a planning error is an outcome, never an exception."""
    try:
        if req.merge and req.base is not None:
            plan = merge(req)
        elif req.lineage is not None:
            plan = replay(req.mission, req.lineage, req.zones, req.now, req.home_alt_msl_m)
        elif req.base is None:
            plan = plan_fleet(req.mission, req.members, req.zones, req.now, req.home_alt_msl_m)
        else:
            plan = req.base.replan(
                req.progress_m,
                _vehicles(req.members),
                zones=req.zones,
                now_unix_s=req.now,
                home_alt_msl_m=req.home_alt_msl_m,
                battery_pct=dict(req.battery_pct) or None,
            )
    except (PlanningError, ValueError) as exc:
        return PlanOutcome(req.job_id, None, f"planning: {exc}", getattr(exc, "detail", None))
    return PlanOutcome(req.job_id, plan)
