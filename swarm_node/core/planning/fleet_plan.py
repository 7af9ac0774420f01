"""The whole fleet's plan for one mission, and its replan when members drop out or join.

Every member of a fleet plans the whole mission for the whole roster from the same
inputs (`plan_fleet`) and keeps the `FleetPlan`: its own `Share` is what it flies, the
others' shares are what replanning needs. Progress is counted in metres along a share
(`Share.along_m`, `Share.progress_m`), so that every survivor can tell from a member's
published progress how much of its share is flown.

`FleetPlan.replan(progress_m, vehicles, ...)` shares out what is left, per mission type:

- AREA: the lanes (and parts of lanes) not flown yet, from every old member's progress,
  re-split among `vehicles` from where they are now (`replan_area`). Metres along a
  share are converted exactly to the coverage path's percentage: the share's waypoints
  at every lane's ends are found (the flyable stage keeps them), so the lane being
  flown is cut where the vehicle is; on a transition the last lane counts as done.
  With the survivors' `battery_pct`, none gets more than its charge flies home.
- PERIMETER: the patrol re-phased among the survivors from where they are
  (`plan_perimeter`: equal spacing, their order along the loop kept, a synchronized
  entry), for as many laps as the survivor with most laps left still had to fly
  (rounded up).
- TARGET: the formation re-spaced among the survivors from where they are
  (`plan_target`: equal phases in their angular order, a synchronized entry on the
  orbit); the hold (loops, duration) starts again.
- ROUTE: every vehicle flies the same route, so a member lost leaves nothing to share
  out: survivors keep their shares unchanged (the same `Share` objects, nothing to
  upload) and a joiner gets a route plan of its own from where it is.
- OBJECTIVE: the survivors spread again over the points (`plan_objective`: counts
  differ by at most one, least total travel, so most stay where they are).

Pure and deterministic: vehicles are sorted by id everywhere, so the same inputs in any
order give the same plan.
"""

from __future__ import annotations

import dataclasses
import hashlib
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import msgspec
import numpy as np

from swarm_node.core.autopilot.items import ItemKind, Waypoint
from swarm_node.core.margins import FIXED_WING_LANE_EXTRA_M, track_margin_m
from swarm_node.core.profile import VehicleProfile
from swarm_proto import Mission, MissionType, NoFlyZone

from .area import AreaPlan, merge_area, plan_area, replan_area
from .autoland import plan_autoland
from .context import PlanContext
from .endurance import launch_s, transition_s
from .errors import InfeasibleTimingError, InvalidParameterError, NoVehiclesError, PlanningError
from .flight import FIXED_WING_ACCEPT_M, flyable_plan, predict_flight
from .geo import LocalFrame, VehiclePose
from .mumt import LeadState, plan_mumt
from .objective import plan_objective
from .perimeter import PerimeterPlan, plan_perimeter
from .route import plan_route
from .target import plan_target
from .vehicles import PlanVehicle, VehiclePlan

PLANNERS: dict[MissionType, Callable[..., object]] = {
    MissionType.AREA: plan_area,
    MissionType.TARGET: plan_target,
    MissionType.PERIMETER: plan_perimeter,
    MissionType.ROUTE: plan_route,
    MissionType.OBJECTIVE: plan_objective,
    MissionType.AUTOLAND: plan_autoland,
}
#: AUTOLAND as the mission manager flies it: each vehicle holds over the fix until its
#: turn (mission/landing.py) and lands on its own pad, this far from the next
LANDING_PAD_SPACING_M = 15.0

#: a replan the batteries cannot fly keeps the largest part of the lost members' rest
#: they can, to 1/2**BATTERY_BISECTIONS of it
BATTERY_BISECTIONS = 6
#: a fixed-wing's turns are planned at this times its minimum radius (see `flyable`)
TURN_RADIUS_MARGIN = 1.3

_LANE_MATCH_M = 0.05  # a waypoint this close to a lane's end is that end


def flyable(profile: VehicleProfile) -> VehicleProfile:
    """The profile planners should use: a fixed-wing's turns planned at
    TURN_RADIUS_MARGIN times its minimum radius, so the autopilot's path following has
    room to converge on the planned arcs instead of overshooting them."""
    if not profile.is_fixed_wing:
        return profile
    return msgspec.structs.replace(
        profile, loiter_radius_m=TURN_RADIUS_MARGIN * profile.turn_radius_m()
    )


# --------------------------------------------------------------------------- share


def _xy(frame: LocalFrame, w: Waypoint) -> tuple[float, float]:
    return frame.to_local(w.lat_deg, w.lon_deg)


def local_xy(frame: LocalFrame, waypoints: Sequence[Waypoint]) -> list[tuple[float, float] | None]:
    """Each WAYPOINT item's local position (None for the other items)."""
    idx = [k for k, w in enumerate(waypoints) if w.kind == ItemKind.WAYPOINT]
    out: list[tuple[float, float] | None] = [None] * len(waypoints)
    if idx:
        arr = frame.to_local_many([(waypoints[k].lat_deg, waypoints[k].lon_deg) for k in idx])
        for k, (x, y) in zip(idx, arr.tolist(), strict=True):
            out[k] = (float(x), float(y))
    return out


def along_metres(waypoints: Sequence[Waypoint]) -> tuple[float, ...]:
    """Metres from the first WAYPOINT item to each item along the straight legs between
    WAYPOINT items; every other item repeats the previous value (0 before the first)."""
    pts = [(w.lat_deg, w.lon_deg) for w in waypoints if w.kind == ItemKind.WAYPOINT]
    if not pts:
        return tuple(0.0 for _ in waypoints)
    xy = iter(local_xy(LocalFrame(*pts[0]), waypoints))
    out: list[float] = []
    s = 0.0
    prev: tuple[float, float] | None = None
    for _w in waypoints:
        p = next(xy)
        if p is not None:
            if prev is not None:
                s += math.dist(prev, p)
            prev = p
        out.append(s)
    return tuple(out)


@dataclass(frozen=True)
class Share:
    """One member's share of a fleet plan."""

    vehicle_id: int
    waypoints: tuple[Waypoint, ...]  # what the vehicle uploads
    along_m: tuple[float, ...]  # planned metres from the share's start to each item
    length_m: float  # along_m of the last item
    time_s: float  # the planner's time for the share (speed, waits, turns)
    #: before the share: arming, take-off and climb from the ground at home
    #: (`endurance.launch_s`; 0 in a replan, flown from the air)
    launch_s: float = 0.0

    @classmethod
    def of(cls, vp: VehiclePlan, launch_s: float = 0.0) -> Share:
        along = along_metres(vp.waypoints)
        return cls(
            vp.vehicle_id,
            tuple(vp.waypoints),
            along,
            along[-1] if along else 0.0,
            vp.time_s,
            launch_s,
        )

    @property
    def sortie_s(self) -> float:
        """The planned time from the plan to the end of the share: launch and share."""
        return self.launch_s + self.time_s

    def at(self, progress_m: float) -> tuple[int, float, float]:
        """Where a vehicle `progress_m` along this share is: (index of the last item
        reached, lat, lon), the inverse of `progress_m` (simulations, tests)."""
        pos = [k for k, w in enumerate(self.waypoints) if w.kind == ItemKind.WAYPOINT]
        if not pos:
            raise PlanningError(f"vehicle {self.vehicle_id}'s share has no waypoint")
        m = min(max(progress_m, 0.0), self.length_m)
        k = max((i for i in pos if self.along_m[i] <= m), default=pos[0])
        if m <= 0.0:
            k = pos[0]
        nxt = next((i for i in pos if i > k), None)
        a = self.waypoints[k]
        if nxt is None or self.along_m[nxt] <= self.along_m[k]:
            return k, a.lat_deg, a.lon_deg
        b = self.waypoints[nxt]
        f = (m - self.along_m[k]) / (self.along_m[nxt] - self.along_m[k])
        frame = LocalFrame(a.lat_deg, a.lon_deg)
        bx, by = _xy(frame, b)
        lat, lon = frame.to_geodetic(f * bx, f * by)
        return k, lat, lon

    def planned_s_at(self, progress_m: float) -> float:
        """Planned seconds from the share's start to `progress_m` along it (the share's
        time spread evenly over its metres)."""
        if self.length_m <= 0.0:
            return 0.0
        return self.time_s * min(max(progress_m, 0.0), self.length_m) / self.length_m

    def progress_m(self, reached_index: int, lat_deg: float | None, lon_deg: float | None) -> float:
        """Metres of this share flown: `along_m` of the last item reached
        (`reached_index`, an index into `waypoints`; < 0: none yet) plus the projection
        of the position (if given) on the leg to the next WAYPOINT item, clamped to the
        leg. Monotone in `reached_index` for a given position; in [0, length_m]."""
        n = len(self.waypoints)
        if n == 0 or reached_index < 0:
            return 0.0
        if reached_index >= n - 1:
            return self.length_m
        done = self.along_m[reached_index]
        if (
            lat_deg is None
            or lon_deg is None
            or not (math.isfinite(lat_deg) and math.isfinite(lon_deg))
        ):
            return done
        prev = next(
            (
                w
                for w in reversed(self.waypoints[: reached_index + 1])
                if w.kind == ItemKind.WAYPOINT
            ),
            None,
        )
        nxt = next(
            (w for w in self.waypoints[reached_index + 1 :] if w.kind == ItemKind.WAYPOINT), None
        )
        if prev is None or nxt is None:
            return done
        frame = LocalFrame(prev.lat_deg, prev.lon_deg)
        bx, by = _xy(frame, nxt)
        px, py = frame.to_local(lat_deg, lon_deg)
        leg = math.hypot(bx, by)
        if leg <= 1e-9:
            return done
        t = min(max((px * bx + py * by) / leg, 0.0), leg)
        return min(done + t, self.length_m)


# --------------------------------------------------------------------------- fleet plan


@dataclass(frozen=True)
class FleetPlan:
    """A mission planned for a whole roster: every member's share and the planner's own
    plan (`detail`: AreaPlan, PerimeterPlan, TargetPlan, RoutePlan, ObjectivePlan)."""

    mission: Mission
    roster: tuple[int, ...]  # sorted member ids the plan was made for
    shares: Mapping[int, Share]
    detail: object
    makespan_s: float
    vehicles: tuple[PlanVehicle, ...] = field(default=(), repr=False)  # as planned (flyable)
    homes: Mapping[int, VehiclePose] = field(default_factory=dict, repr=False)  # first plan's poses
    #: a replan: the part of the lost members' rest that no survivor's battery flies
    #: (left unflown, `_replan_within_battery`)
    unflown_fraction: float = 0.0
    #: the battery each member had at the first plan (missing: full), what it was given
    #: work for; a replan counts down from it
    launch_battery_pct: Mapping[int, float] = field(default_factory=dict)

    def digest(self) -> str:
        """8 hex digits of every member's share to the bit: nodes that log the same
        digest hold the same plan (the node logs it with every plan it makes)."""
        shares = [(vid, s.waypoints) for vid, s in sorted(self.shares.items())]
        return hashlib.blake2s(msgspec.msgpack.encode(shares), digest_size=4).hexdigest()

    def share(self, vehicle_id: int) -> Share:
        try:
            return self.shares[vehicle_id]
        except KeyError:
            raise PlanningError(f"the plan has no share for vehicle {vehicle_id}") from None

    def replan(
        self,
        progress_m: Mapping[int, float],
        vehicles: Sequence[PlanVehicle],
        *,
        zones: Sequence[NoFlyZone],
        now_unix_s: float,
        home_alt_msl_m: float,
        battery_pct: Mapping[int, float] | None = None,
    ) -> FleetPlan:
        """What is left of this plan shared among `vehicles` (the survivors and any
        joiner, each posed where it is now) from every old member's progress in metres
        along its share (missing: 0). Old members missing from `vehicles` dropped out.
        AREA: a vehicle in `battery_pct` gets no more than its charge flies with the
        way home to where it started (`homes`) and its landing (`InfeasibleTimingError`
        when the survivors cannot cover what is left). See the module docstring for
        what each mission type does."""
        for vid, m in progress_m.items():
            if not math.isfinite(m):
                raise InvalidParameterError(f"vehicle {vid}: progress {m} m is not finite")
        new = self._replan(
            progress_m,
            vehicles,
            zones=zones,
            now_unix_s=now_unix_s,
            home_alt_msl_m=home_alt_msl_m,
            battery_pct=battery_pct,
        )
        return dataclasses.replace(new, launch_battery_pct=self.launch_battery_pct)

    def _replan(
        self,
        progress_m: Mapping[int, float],
        vehicles: Sequence[PlanVehicle],
        *,
        zones: Sequence[NoFlyZone],
        now_unix_s: float,
        home_alt_msl_m: float,
        battery_pct: Mapping[int, float] | None,
    ) -> FleetPlan:
        vs = _sorted_flyable(vehicles)
        kind = self.mission.mission_type
        if kind == MissionType.AREA:
            assert isinstance(self.detail, AreaPlan)
            pct = {vid: self.area_percent(vid, m) for vid, m in sorted(progress_m.items())}
            frame = self.detail.frame
            homes = {
                vid: frame.to_local(h.lat_deg, h.lon_deg) for vid, h in sorted(self.homes.items())
            }
            detail, dropped = self._replan_within_battery(pct, vs, battery_pct, homes)
            detail = flyable_plan(
                detail, vs, zones, now_unix_s=now_unix_s, home_alt_msl_m=home_alt_msl_m
            )
            plan = _fleet_plan(self.mission, vs, detail, self.homes)
            return dataclasses.replace(plan, unflown_fraction=dropped)
        if kind == MissionType.PERIMETER:
            assert isinstance(self.detail, PerimeterPlan)
            mission = _with_params(self.mission, loops=self._laps_left(progress_m, vs))
            return _plan(
                mission,
                vs,
                zones=zones,
                now_unix_s=now_unix_s,
                home_alt_msl_m=home_alt_msl_m,
                homes=self.homes,
            )
        if kind in (MissionType.TARGET, MissionType.OBJECTIVE):
            return _plan(
                self.mission,
                vs,
                zones=zones,
                now_unix_s=now_unix_s,
                home_alt_msl_m=home_alt_msl_m,
                homes=self.homes,
            )
        if kind == MissionType.ROUTE:
            return self._replan_route(
                vs, zones=zones, now_unix_s=now_unix_s, home_alt_msl_m=home_alt_msl_m
            )
        raise PlanningError(f"{kind.name} missions are not replanned")

    def merged(
        self,
        progress_m: Mapping[int, float],
        others: Sequence[tuple[FleetPlan, Mapping[int, float]]],
        vehicles: Sequence[PlanVehicle],
        *,
        zones: Sequence[NoFlyZone],
        now_unix_s: float,
        home_alt_msl_m: float,
    ) -> FleetPlan:
        """A fleet split apart meets again (a partition healed): this plan with its
        members' `progress_m` and the `others` parts' plans with theirs (each part
        replanned from the same first plan without the rest) make one plan of what
        none of them flew, shared among `vehicles` (everyone, each posed where its
        progress puts it on its part's plan). AREA only; the same whichever part is
        `self` (`merge_area`)."""
        if self.mission.mission_type != MissionType.AREA:
            raise PlanningError(f"{self.mission.mission_type.name} plans are not merged")
        # in one order on every node, whichever part it flew in: by each part's roster
        parts = sorted([(self, progress_m), *others], key=lambda p: p[0].roster)
        for plan, prog in parts:
            if (
                not isinstance(plan.detail, AreaPlan)
                or plan.mission.mission_id != self.mission.mission_id
            ):
                raise PlanningError("plans of another mission are not merged")
            for vid, m in prog.items():
                if not math.isfinite(m):
                    raise InvalidParameterError(f"vehicle {vid}: progress {m} m is not finite")
        vs = _sorted_flyable(vehicles)
        pcts = [
            (plan.detail, {v: plan.area_percent(v, m) for v, m in sorted(prog.items())})
            for plan, prog in parts
        ]
        detail = merge_area(pcts, vs, self.mission.params)  # type: ignore[arg-type]
        detail = flyable_plan(
            detail, vs, zones, now_unix_s=now_unix_s, home_alt_msl_m=home_alt_msl_m
        )
        homes: dict[int, VehiclePose] = {}
        for plan, _prog in parts:
            homes.update({v: h for v, h in plan.homes.items() if v not in homes})
        plan = _fleet_plan(self.mission, vs, detail, homes)
        return dataclasses.replace(plan, launch_battery_pct=self.launch_battery_pct)

    # -- area

    def _replan_within_battery(
        self,
        pct: Mapping[int, float],
        vehicles: Sequence[PlanVehicle],
        battery_pct: Mapping[int, float] | None,
        homes: Mapping[int, tuple[float, float]],
    ) -> tuple[AreaPlan, float]:
        """`replan_area`; when the survivors' batteries cannot fly all that is left, as
        much of the lost members' rest as they can (the survivors' own rest always: it
        was planned within their batteries): each lost member counts as having flown
        more of its share, the largest part left found by bisection (the lanes right
        after where it was lost stay unflown). `InfeasibleTimingError` when even the
        survivors' own rest does not fit."""
        assert isinstance(self.detail, AreaPlan)
        params = self.mission.params

        def attempt(extra: float) -> AreaPlan:
            p = {
                vid: x if vid in alive else x + extra * (100.0 - x)
                for vid, x in sorted(pct.items())
            }
            return replan_area(
                self.detail,  # type: ignore[arg-type]
                p,
                vehicles,
                params,
                battery_pct=battery_pct,
                homes=homes,
            )

        alive = {v.vehicle_id for v in vehicles}
        try:
            return attempt(0.0), 0.0
        except InfeasibleTimingError:
            if not battery_pct or not set(pct) - alive:
                raise
        best = attempt(1.0)  # the survivors' own rest only (raises if that does not fit)
        lo, hi = 0.0, 1.0  # lo: infeasible share of the lost rest dropped, hi: feasible
        for _ in range(BATTERY_BISECTIONS):
            mid = 0.5 * (lo + hi)
            try:
                best, hi = attempt(mid), mid
            except InfeasibleTimingError:
                lo = mid
        return best, hi

    def area_percent(self, vehicle_id: int, progress_m: float) -> float:
        """`progress_m` along `vehicle_id`'s share as the percentage of its coverage
        path flown (what `replan_area` takes): on a lane, the lane's start plus the
        metres flown along it; on a transition, the end of the lane before it."""
        assert isinstance(self.detail, AreaPlan)
        if vehicle_id not in self.shares:
            return 0.0
        share = self.shares[vehicle_id]
        path = self.detail.split.of(vehicle_id).path
        if path.length_m <= 0.0:
            return 0.0
        anchors = _lane_anchors(self.detail.frame, share, path)
        if anchors is None:  # not found: proportional (never expected)
            f = progress_m / share.length_m if share.length_m > 0 else 0.0
            return 100.0 * min(max(f, 0.0), 1.0)
        done = 0.0
        for share_a, share_b, path_a, lane_m in anchors:
            if progress_m < share_a:
                break
            if progress_m < share_b:
                done = path_a + min(progress_m - share_a, lane_m)
                break
            done = path_a + lane_m
        return 100.0 * min(max(done / path.length_m, 0.0), 1.0)

    # -- perimeter

    def _laps_left(self, progress_m: Mapping[int, float], vehicles: Sequence[PlanVehicle]) -> int:
        assert isinstance(self.detail, PerimeterPlan)
        loops = max(self.mission.params.loops, 1)
        lap = self.detail.length_m
        left = 0.0
        for v in vehicles:
            share = self.shares.get(v.vehicle_id)
            if share is None:
                left = max(left, float(loops))
                continue
            entry_m = max(share.length_m - lap * loops, 0.0)
            done = max(progress_m.get(v.vehicle_id, 0.0) - entry_m, 0.0) / lap
            left = max(left, loops - done)
        return max(1, math.ceil(left - 1e-6))

    # -- route

    def _replan_route(
        self,
        vehicles: Sequence[PlanVehicle],
        *,
        zones: Sequence[NoFlyZone],
        now_unix_s: float,
        home_alt_msl_m: float,
    ) -> FleetPlan:
        shares = {
            v.vehicle_id: self.shares[v.vehicle_id] for v in vehicles if v.vehicle_id in self.shares
        }
        joiners = [v for v in vehicles if v.vehicle_id not in self.shares]
        detail: object = self.detail
        if joiners:
            joined = _plan(
                self.mission,
                joiners,
                zones=zones,
                now_unix_s=now_unix_s,
                home_alt_msl_m=home_alt_msl_m,
            )
            shares.update(joined.shares)
            detail = (self.detail, joined.detail)
        ordered = {vid: shares[vid] for vid in sorted(shares)}
        return FleetPlan(
            self.mission,
            tuple(ordered),
            ordered,
            detail,
            max((s.time_s for s in ordered.values()), default=0.0),
            tuple(vehicles),
            {**self.homes, **joined.homes} if joiners else self.homes,
        )


def _lane_anchors(
    frame: LocalFrame, share: Share, path: object
) -> list[tuple[float, float, float, float]] | None:
    """For each lane of `path` in flight order: (share metres at its start, at its end,
    path metres at its start, its length); None if a lane's ends are not in the share."""
    from .coverage import CoveragePath

    assert isinstance(path, CoveragePath)
    xy = local_xy(frame, share.waypoints)
    out = []
    s = 0.0
    k = 0
    lanes = iter(path.lanes)
    for leg in path.legs:
        if not leg.is_lane:
            s += leg.length_m
            continue
        lane = next(lanes)
        ends = []
        for p in (lane.a, lane.b):
            while k < len(xy) and (xy[k] is None or math.dist(xy[k], p) > _LANE_MATCH_M):  # type: ignore[arg-type]
                k += 1
            if k == len(xy):
                return None
            ends.append(share.along_m[k])
        out.append((ends[0], ends[1], s, leg.length_m))
        s += leg.length_m
    return out


# --------------------------------------------------------------------------- planning


def _sorted_flyable(vehicles: Sequence[PlanVehicle]) -> list[PlanVehicle]:
    ids = [v.vehicle_id for v in vehicles]
    if not ids:
        raise NoVehiclesError("a plan needs at least one vehicle")
    if len(set(ids)) != len(ids):
        raise InvalidParameterError(f"duplicate vehicle ids: {sorted(ids)}")
    return [
        PlanVehicle(flyable(v.profile), v.pose)
        for v in sorted(vehicles, key=lambda v: v.vehicle_id)
    ]


def _with_params(mission: Mission, **changes: object) -> Mission:
    return msgspec.structs.replace(
        mission, params=msgspec.structs.replace(mission.params, **changes)
    )


def _makespan(detail: object, shares: Mapping[int, Share]) -> float:
    """From the plan to the last share flown: launch (from the ground, in a first plan)
    and the share's time, the latest of the fleet."""
    span = getattr(detail, "makespan_s", None)
    flown = max((s.sortie_s for s in shares.values()), default=0.0)
    if isinstance(span, float) and math.isfinite(span):
        launch = min((s.launch_s for s in shares.values()), default=0.0)
        return max(span + launch, flown)
    return flown


def _fleet_plan(
    mission: Mission,
    vehicles: Sequence[PlanVehicle],
    detail: object,
    homes: Mapping[int, VehiclePose] | None = None,
) -> FleetPlan:
    plans: tuple[VehiclePlan, ...] = detail.vehicles  # type: ignore[attr-defined]
    # a first plan: every vehicle starts from the ground at its home (a replan: in the air)
    launch = {
        v.vehicle_id: launch_s(v.profile, mission.params.altitude_rel_m) if homes is None else 0.0
        for v in vehicles
    }
    by_id = {vp.vehicle_id: Share.of(vp, launch.get(vp.vehicle_id, 0.0)) for vp in plans}
    roster = tuple(v.vehicle_id for v in vehicles)
    missing = [vid for vid in roster if vid not in by_id]
    if missing:
        raise PlanningError(f"the plan has no share for vehicles {missing}")
    shares = {vid: by_id[vid] for vid in roster}
    if homes is None:  # a first plan: the vehicles are where they start from
        homes = {v.vehicle_id: v.pose for v in vehicles if v.pose is not None}
    return FleetPlan(
        mission, roster, shares, detail, _makespan(detail, shares), tuple(vehicles), dict(homes)
    )


def _plan(
    mission: Mission,
    vehicles: Sequence[PlanVehicle],
    *,
    zones: Sequence[NoFlyZone],
    now_unix_s: float,
    home_alt_msl_m: float,
    homes: Mapping[int, VehiclePose] | None = None,
    battery_pct: Mapping[int, float] | None = None,
) -> FleetPlan:
    """`vehicles` already sorted and flyable."""
    if mission.mission_type == MissionType.MUMT:
        return _plan_mumt(mission, vehicles, zones=zones, home_alt_msl_m=home_alt_msl_m)
    planner = PLANNERS.get(mission.mission_type)
    if planner is None:
        raise PlanningError(f"{mission.mission_type.name} missions are not planned yet")
    if mission.mission_type == MissionType.AREA:
        return _plan_area(
            mission,
            vehicles,
            zones=zones,
            now_unix_s=now_unix_s,
            home_alt_msl_m=home_alt_msl_m,
            battery_pct=battery_pct,
        )
    extra: dict[str, object] = {}
    if mission.mission_type == MissionType.AUTOLAND:
        extra = {"hold_until_released": True, "pad_spacing_m": LANDING_PAD_SPACING_M}
    ctx = PlanContext(
        mission.geometry,
        vehicles,
        mission.params,
        zones,
        now_unix_s,
        home_alt_msl_m,
        zone_margin_m(vehicles),
    )
    detail = planner(ctx, **extra)
    # every fixed-wing share flyable as planned (the plan's tracks follow)
    detail = flyable_plan(
        detail, vehicles, zones, now_unix_s=now_unix_s, home_alt_msl_m=home_alt_msl_m
    )
    return _fleet_plan(mission, vehicles, detail, homes)


def _plan_mumt(
    mission: Mission,
    vehicles: Sequence[PlanVehicle],
    *,
    zones: Sequence[NoFlyZone],
    home_alt_msl_m: float,
) -> FleetPlan:
    """MUM-T: the followers' slots around the lead, assigned once from what every
    member has (the followers at their homes, the lead at the mission's point, its
    course `heading_deg` or north, standing still); in flight each follower follows
    the lead's telemetry in its slot (mission/follow.py). The lead is no follower."""
    lead_id = mission.params.lead_vehicle_id
    if not lead_id:
        raise InvalidParameterError("a MUM-T mission needs its lead (lead_vehicle_id)")
    followers = [v for v in vehicles if v.vehicle_id != lead_id]
    if not followers or not mission.geometry.points:
        raise NoVehiclesError("a MUM-T mission needs followers and the lead's position")
    p = mission.geometry.points[0]
    lead = LeadState(p.lat_deg, p.lon_deg, 0.0, mission.params.heading_deg or 0.0, 0.0)
    detail = plan_mumt(
        lead,
        followers,
        mission.params,
        zones=zones,
        home_alt_msl_m=home_alt_msl_m,
        zone_margin_m=zone_margin_m(followers),
    )
    return _fleet_plan(mission, followers, detail)


def _turn_margin_m(profile: VehicleProfile) -> float:
    """A fixed-wing's lanes end its planned turn radius and FIXED_WING_LANE_EXTRA_M
    from a zone: the turn at a lane's end then keeps FIXED_WING_KEEP_M from it (at the
    turn radius alone a U-turn kept 30-39 m, and ArduPlane flies up to 37 m inside it)."""
    if not profile.is_fixed_wing:
        return profile.turn_radius_m()
    return profile.turn_radius_m() + FIXED_WING_LANE_EXTRA_M


def zone_margin_m(vehicles: Sequence[PlanVehicle]) -> float:
    """How far a plan keeps from the zones: the widest planned turn radius of a
    fixed-wing (`vehicles` are already `flyable`) and the room its turns need
    (`_turn_margin_m`), or what ArduPilot flies off a multirotor's or ground vehicle's
    legs around its corners (`margins.track_margin_m`)."""
    return max(
        (max(_turn_margin_m(v.profile), track_margin_m(v.profile)) for v in vehicles),
        default=0.0,
    )


#: rounds of the area split fed with the time the flyable stage added to each share
FLYABLE_ROUNDS = 3
#: plan areas as before (no endurance, no waypoint stops, one split): only for
#: the benchmark's baseline (bench/mission.py)
BASELINE_SPLIT = False


def _plan_area(
    mission: Mission,
    vehicles: Sequence[PlanVehicle],
    *,
    zones: Sequence[NoFlyZone],
    now_unix_s: float,
    home_alt_msl_m: float,
    battery_pct: Mapping[int, float] | None = None,
) -> FleetPlan:
    """An area plan whose split knows each vehicle's endurance (`plan_area(endurance=
    True)`: the vehicles are at their homes) and the time the flyable stage adds to a
    fixed-wing's share: the split is made again with each vehicle's added time as its
    `extra_s` (up to FLYABLE_ROUNDS splits), and the plan with the least makespan as
    flown is kept."""
    margin = zone_margin_m(vehicles)
    aware = not BASELINE_SPLIT
    # a VTOL starts its share in hover: the forward transition costs it time
    start = {
        v.vehicle_id: transition_s(v.profile, v.speed(mission.params)) if aware else 0.0
        for v in vehicles
    }
    extra = dict(start)
    best: tuple[float, Any] | None = None
    rounds = FLYABLE_ROUNDS if aware and any(v.profile.is_fixed_wing for v in vehicles) else 1
    for _ in range(rounds):
        raw = plan_area(
            PlanContext(
                mission.geometry,
                vehicles,
                mission.params,
                zones,
                now_unix_s,
                home_alt_msl_m,
                margin,
            ),
            endurance=aware,
            extra_s=extra,
            legacy_split=not aware,
            battery_pct=battery_pct if aware else None,
        )
        detail = flyable_plan(
            raw, vehicles, zones, now_unix_s=now_unix_s, home_alt_msl_m=home_alt_msl_m
        )
        by_id = {v.vehicle_id: v for v in vehicles}
        detail = dataclasses.replace(
            detail,
            vehicles=tuple(
                dataclasses.replace(
                    vp,
                    time_s=(_flown_s(vp, by_id[vp.vehicle_id], detail.frame) if aware else None)
                    or vp.time_s + start[vp.vehicle_id],
                )
                for vp in detail.vehicles
            ),
        )
        span = max(vp.time_s for vp in detail.vehicles)
        if best is None or span < best[0] - 1e-6:
            best = (span, detail)
        # what the flyable stage added to each share, and the transition
        new = {
            vp.vehicle_id: max(vp.time_s - raw.split.of(vp.vehicle_id).path_time_s, 0.0)
            for vp in detail.vehicles
        }
        if all(abs(new[k] - extra.get(k, 0.0)) < 0.02 * span for k in new):
            break
        extra = new
    assert best is not None
    plan = _fleet_plan(mission, vehicles, best[1])
    return dataclasses.replace(plan, launch_battery_pct=dict(sorted((battery_pct or {}).items())))


def _flown_s(vp: VehiclePlan, v: PlanVehicle, frame: LocalFrame) -> float | None:
    """A fixed-wing share's time as its autopilot flies it: the path `predict_flight`
    predicts through its waypoints (at the turn radius of its speed, the acceptance
    radius the mission manager asks for) at its speed, plus a VTOL's transition; None
    for other vehicles or when the prediction stops short."""
    if not v.profile.is_fixed_wing:
        return None
    pts = [
        frame.to_local(w.lat_deg, w.lon_deg) for w in vp.waypoints if w.kind == ItemKind.WAYPOINT
    ]
    speed = next(
        (w.speed_m_s for w in vp.waypoints if w.kind == ItemKind.CHANGE_SPEED and w.speed_m_s),
        v.profile.cruise_speed_m_s,
    )
    if len(pts) < 2 or speed <= 0.0:
        return None
    flown = predict_flight(
        pts, radius_m=v.profile.turn_radius_m(speed), accept_m=FIXED_WING_ACCEPT_M, step_m=2.0
    )
    if flown.reached < len(pts):
        return None
    length = float(np.hypot(*np.diff(flown.points, axis=0).T).sum())
    return length / speed + transition_s(v.profile, speed)


def plan_fleet(
    mission: Mission,
    vehicles: Sequence[PlanVehicle],
    *,
    zones: Sequence[NoFlyZone],
    now_unix_s: float,
    home_alt_msl_m: float,
    battery_pct: Mapping[int, float] | None = None,
) -> FleetPlan:
    """The whole fleet's plan: `vehicles` (profiles as in the swarm database, poses
    every member sees the same, e.g. their homes) sorted by id, fixed-wing profiles
    made `flyable`, the mission type's planner with a zone margin of the widest turn
    radius, every fixed-wing share made flyable (`flyable_plan`). `battery_pct`: the
    members' batteries as every member sees them (missing: full): an area gives none
    more than its battery flies."""
    plan = _plan(
        mission,
        _sorted_flyable(vehicles),
        zones=zones,
        now_unix_s=now_unix_s,
        home_alt_msl_m=home_alt_msl_m,
        battery_pct=battery_pct,
    )
    if battery_pct and not plan.launch_battery_pct:
        plan = dataclasses.replace(plan, launch_battery_pct=dict(sorted(battery_pct.items())))
    return plan


def flown_lanes(plan: FleetPlan, progress_m: Mapping[int, float]) -> list[object]:
    """The lanes (and parts of lanes) of an area plan flown at `progress_m`: the
    complement of what `replan` shares out (tests and benchmarks measure coverage and
    double flying with it)."""
    assert isinstance(plan.detail, AreaPlan)
    out: list[object] = []
    for a in plan.detail.split.assignments:
        pct = plan.area_percent(a.vehicle_id, progress_m.get(a.vehicle_id, 0.0))
        done_m = pct / 100.0 * a.path.length_m
        s = 0.0
        lanes = iter(a.path.lanes)
        for leg in a.path.legs:
            if not leg.is_lane:
                s += leg.length_m
                continue
            lane = next(lanes)
            if s + leg.length_m <= done_m:
                out.append(lane)
            elif s < done_m:
                done, _rest = lane.cut((done_m - s) / leg.length_m)
                if done.length_m > 1e-6:
                    out.append(done)
            s += leg.length_m
    return out


__all__ = [
    "PLANNERS",
    "TURN_RADIUS_MARGIN",
    "FleetPlan",
    "Share",
    "along_metres",
    "flown_lanes",
    "flyable",
    "plan_fleet",
]
