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
import logging
from collections.abc import Mapping, Sequence
from dataclasses import InitVar, dataclass, field

import msgspec

from swarm_proto import (
    Alert,
    AlertCode,
    GeometryKind,
    GeoPoint,
    Mission,
    MissionParams,
    MissionState,
    MissionType,
    NoFlyZone,
    ReasonDetail,
    Severity,
    VehicleStatus,
    VehicleType,
)
from swarm_proto.text import short_text

from . import state_machine as fsm
from .autopilot.items import ItemKind, Waypoint
from .autopilot.requests import (
    ApRequest,
    ApResult,
    Arm,
    ChangeSpeed,
    Disarm,
    Land,
    ReturnToLaunch,
    SetMode,
    StartMission,
    Takeoff,
    UploadMission,
)
from .autopilot.state import AutopilotState
from .mission.agreement import ReplanAgreement, Verdict
from .mission.fleet_sync import FleetSync
from .mission.follow import Follow
from .mission.landing import LandingTurn
from .mission.phases import TAKE_OVER, Phase, Step, go
from .mission.share import (
    FleetPlan,
    Member,
    PlanOutcome,
    PlanRequest,
    Replay,
    Share,
    plan_fleet,
)
from .mission.sortie import Sortie, Trigger
from .outputs import ModuleOutput, Note, Owner, PlanJob, Post, Publish, Submit
from .planning import (
    PlanningError,
)
from .planning.endurance import CLIMB_FRACTION, Endurance, launch_s
from .planning.transit import VehicleTransit, distance_m
from .planning.transit import flyable as flyable  # re-exported (was defined here)
from .profile import VehicleProfile
from .safety.pad_sequence import PadSequence
from .swarm.roster import Roster

#: parameters a planner reads as "not given" when 0 (besides None), per mission type
UNSET_WHEN_ZERO: dict[MissionType, frozenset[str]] = {
    MissionType.AUTOLAND: frozenset({"separation_s", "altitude_step_m"}),
    MissionType.MUMT: frozenset({"altitude_step_m", "radius_m"}),
    # fixed-wing orbiting one point at one height rely on their phases alone, which an
    # ArduPilot loiter does not hold: a target's step of 0 is the database's
    MissionType.TARGET: frozenset({"altitude_step_m"}),
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


# CLIMB_FRACTION (planning.endurance): start the mission once this much of the take-off
# altitude is reached
LAND_AT_HOME_M = 30.0  # multirotors: land once RTL has brought them this close to home
# Fixed-wing waypoint acceptance (planning.flight.FIXED_WING_ACCEPT_M, 15 m): every
# plain waypoint asks for it (ArduPlane's 90 m default would count the closely spaced
# waypoints of a planned turn as reached at once and loop wide); the flyable stage
# plans every corner for it.
AP_POLL_S = 0.2  # the node reads the autopilot's state this often
#: how long after our StartMission the autopilot's state may still show the mode before
#: it (the command's ack, then the next heartbeat; simulated seconds)
START_SEEN_S = 3.0


Out = ModuleOutput  # the node's one output vocabulary (outputs.py)


def Log(text: str) -> Note:
    return Note(logging.INFO, text)


def plan_share(
    mission: Mission,
    members: Sequence[Member],
    self_id: int,
    zones: Sequence[NoFlyZone],
    now: float,
    home_alt_msl_m: float,
) -> tuple[Waypoint, ...]:
    """This vehicle's waypoints in a plan made for every member (mission/share.py)."""
    return plan_fleet(mission, members, zones, now, home_alt_msl_m).share(self_id).waypoints


@dataclass
class MissionManager:
    profile: VehicleProfile
    phase: Phase = Phase.IDLE
    mission_id: int | None = None
    takeoff_alt_m: float = 0.0
    items: int = 0  # mission items uploaded (home + waypoints)
    last_item: int = 0  # reaching this item completes the mission
    zones: tuple[NoFlyZone, ...] = ()
    sortie: Sortie = field(default_factory=Sortie)  # the one owner of the mission state
    along_m: tuple[float, ...] = ()  # metres along the share at each item (index = seq)
    hold_s: float = 0.0  # a timed hold on the share's unlimited loiter (target --duration)
    hold_seq: int = 0  # that loiter's item
    hold_since: float | None = None
    _hold_wp: Waypoint | None = None
    _stale: tuple[int, int] = (-1, 0)  # MISSION_ITEM_REACHED, MISSION_CURRENT of an earlier mission
    _fresh_reached: bool = False  # the autopilot reported an item of this mission
    _fresh_current: bool = False
    _reached: int = 0  # the last item reached flying this mission (`_reached_item`)
    fleet_plan: FleetPlan | None = None  # the whole fleet's plan (replanning starts from it)
    reattached: bool = False  # flying a share uploaded before the node restarted
    share: Share | None = None  # our share of it, as flown
    _share_index: tuple[int, ...] = ()  # uploaded item seq -> index in share.waypoints
    _offset: float = 0.0  # metres flown before the last replan
    replanned_from: dict[int, float] = field(default_factory=dict)  # the last replan's progress
    _job: int = 0  # the plan job we wait for
    _planning: tuple[Mission, tuple[NoFlyZone, ...]] | None = None
    _steps: list[ApRequest] = field(default_factory=list)
    _in_flight: ApRequest | None = None  # the request we wait for
    _ids: itertools.count[int] = field(default_factory=lambda: itertools.count(1))
    mission: Mission | None = None  # the mission being flown (its parameters)
    sync: FleetSync = field(init=False)  # PREMISSION and the MISSION speed rule
    agreement: ReplanAgreement = field(default_factory=ReplanAgreement)
    _held: PlanOutcome | None = None  # a replan made, flown once the survivors agree
    turn: LandingTurn | None = None  # AUTOLAND: our turn to leave the hold and land
    lands: bool = False  # the share ends with a landing (AUTOLAND): landed completes it
    follow: Follow | None = None  # MUM-T: our slot around the lead
    _confirmed: bool = False  # PlanSucceeded posted for this plan
    # an airborne share's approach: planned from where the vehicle was; planned again if
    # it has moved on by the time its upload is done (held, slow link): (share waypoints,
    # zones, home altitude, lat, lon, times planned again)
    _approach: (
        tuple[tuple[Waypoint, ...], tuple[NoFlyZone, ...], float, float, float, int] | None
    ) = None
    _ap: AutopilotState | None = None  # the autopilot as last seen
    # take-off and landing at close pads (safety/pad_sequence.py): its requests are ours
    pads: PadSequence = field(init=False)
    with_pads: InitVar[PadSequence | None] = None  # default: pads from the profile alone
    _pad_requests: dict[int, ApRequest] = field(default_factory=dict)
    uploaded: tuple[Waypoint, ...] = ()  # the mission the autopilot holds (items 1..)
    suspended: bool = False  # avoidance holds the autopilot: our flight requests wait
    # our last StartMission and when: a manoeuvre that begins before the autopilot shows
    # AUTO must go back to it, not to the mode it saw
    _started: tuple[ApRequest, float] | None = None

    def __post_init__(self, with_pads: PadSequence | None) -> None:
        self.sync = FleetSync(self.profile.vehicle_id, self.profile)
        self.transit = VehicleTransit(self.profile)  # the legs a plan does not cover
        self.pads = with_pads if with_pads is not None else PadSequence(self.profile)

    def _go(self, step: Step) -> None:
        """The next phase, checked against the table (mission/phases.py)."""
        self.phase = go(self.phase, step)

    @property
    def launch_queued(self) -> bool:
        """The take-off waits its turn at the close pads (not planning time)."""
        return self.pads.launch is not None

    @property
    def mission_state(self) -> MissionState:
        return self.sortie.state

    @property
    def progress_pct(self) -> int:
        return self.sortie.progress_pct

    def plan(self, mission_id: int) -> None:
        """The state machine began planning `mission_id` (the way home keeps the
        progress of the mission just flown)."""
        self.sortie.begin(keep_progress=mission_id == fsm.RETURN_MISSION)
        self._planning = None

    @property
    def land_radius_m(self) -> float:
        """How close RTL must bring the vehicle before it lands: a VTOL loiters around
        home (or the rally point) at its turn radius in RTL, a multirotor comes right
        over it."""
        return max(LAND_AT_HOME_M, 1.5 * self.profile.turn_radius_m())

    # ------------------------------------------------------------------ start
    def release(
        self,
        mission: Mission,
        members: Sequence[Member],
        zones: Sequence[NoFlyZone],
        ap: AutopilotState,
        now: float,
        *,
        lineage: Replay | None = None,
    ) -> list[Out]:
        """Plan the mission (a `PlanJob` the shell runs off the control loop; its
        outcome comes back to `on_plan`) and then fly this vehicle's share. With
        `lineage`, the plan of a fleet this vehicle joins, made again (swarm/regroup.py)."""
        if self.sortie.state not in (MissionState.PLANNING, MissionState.REPLAN):
            self.sortie.begin(keep_progress=False)
        home_alt = ap.home.alt_msl_m if ap.home else 0.0
        self._job += 1
        self._planning = (mission, tuple(zones))
        req = PlanRequest(
            self._job, mission, tuple(members), tuple(zones), now, home_alt, lineage=lineage
        )
        fleet_ids = sorted(m.profile.vehicle_id for m in members)
        return [Log(f"mission {mission.mission_id}: planning for fleet {fleet_ids}"), PlanJob(req)]

    def on_plan(
        self, outcome: PlanOutcome, ap: AutopilotState, now: float, fleet: Roster | None = None
    ) -> list[Out]:
        """The fleet's plan is made: fly our share from where the vehicle is now (a
        replan once the survivors agree on it: `_agree`). An outcome of an abandoned job
        (stopped, a newer mission) is ignored."""
        if outcome.job_id != self._job or self._planning is None:
            return []
        if self.sortie.state == MissionState.REPLAN:
            if outcome.plan is not None and fleet is not None:
                self._held = outcome
                note = Log(
                    f"mission {self._planning[0].mission_id}: replanned for "
                    f"{list(outcome.plan.roster)} (plan {outcome.plan.digest()}); "
                    "flown once they all agree"
                )
                return [note, *self._agree(ap, now, fleet)]  # maybe at once
            if fleet is not None:  # no replan: fly on, with the roster every member flies
                fleet.rollback()
            self.agreement.end()
        return self._take_plan(outcome, ap, now, fleet)

    def _agree(self, ap: AutopilotState, now: float, fleet: Roster) -> list[Out]:
        """REPLAN: fly the held replan once every survivor planned it with our roster;
        re-synchronise on a mismatch; fly on without it when no agreement comes
        (mission/agreement.py)."""
        self.agreement.begin(now)
        verdict = self.agreement.verdict(
            fleet, now, held=self._held is not None, planning=self._planning is not None
        )
        if verdict == Verdict.WAIT:
            return []
        if verdict == Verdict.AGREED:
            held, self._held = self._held, None
            assert held is not None
            fleet.settle()
            out = self._take_plan(held, ap, now)
            unflown = held.plan.unflown_fraction if held.plan is not None else 0.0
            if unflown > 0.0:  # the batteries fly only part of the lost members' rest
                mid = self.mission_id if self.mission_id is not None else 0
                text = f"mission {mid}: {unflown:.0%} of the lost member's rest left (battery)"
                out += [
                    Note(logging.WARNING, text),
                    self._alert(Severity.WARNING, text, now, AlertCode.MISSION_FAILED),
                ]
            return out
        mid = self.mission_id if self.mission_id is not None else 0
        others = ", ".join(f"{v} with {h:#06x}" for v, h in self.agreement.others)
        fleet.rollback()
        self._held, self._planning = None, None
        if verdict == Verdict.MISMATCH:
            text = f"mission {mid}: replan roster {others}, ours {fleet.members_hash:#06x}"
            note = f"{text}; planning again from the roster all flew"
            return [
                Note(logging.WARNING, note),
                self._alert(Severity.WARNING, text, now),
                Post(fsm.Replan(mid)),
            ]
        self.agreement.end()
        why = f"different rosters ({others})" if others else "no answer in time"
        text = f"mission {mid}: no replan agreed, {why}; flying on"
        return [
            Note(logging.WARNING, text),
            self._alert(Severity.WARNING, text, now),
            *self._resume(mid),
        ]

    def _alert(
        self, severity: Severity, text: str, now: float, code: AlertCode = AlertCode.ROSTER_MISMATCH
    ) -> Publish:
        return Publish(
            Alert(self.profile.vehicle_id, max(now, 0.0), severity, code, short_text(text))
        )

    def _take_plan(
        self, outcome: PlanOutcome, ap: AutopilotState, now: float, fleet: Roster | None = None
    ) -> list[Out]:
        assert self._planning is not None
        mission, zones = self._planning
        self._planning = None
        mid = mission.mission_id
        home_alt = ap.home.alt_msl_m if ap.home else 0.0
        replan = self.sortie.state == MissionState.REPLAN
        if outcome.plan is None:
            if replan:  # keep flying the share we have: the lost rest stays unflown
                text = f"mission {mid}: no replan ({outcome.error}); flying on"
                return [
                    Note(logging.WARNING, text),
                    self._alert(Severity.WARNING, text, now, AlertCode.MISSION_FAILED),
                    *self._resume(mid),
                ]
            return self._failed(mid, outcome.error, outcome.detail)
        old = self.share
        self.fleet_plan = outcome.plan
        try:
            share = outcome.plan.share(self.profile.vehicle_id)
        except PlanningError as exc:
            if replan:
                return [Log(f"mission {mid}: replan without us ({exc})"), *self._resume(mid)]
            return self._failed(mid, str(exc))
        waypoints = share.waypoints
        if replan and old is not None and waypoints == old.waypoints:
            self.share = share
            return self._resume(mid)  # our share did not change (a route): nothing to upload
        split = outcome.plan.mission.mission_type == MissionType.AREA  # a share may be empty
        if split and not replan and fleet is not None:  # members given nothing stay down
            fleet.nothing_to_fly(idle_members(outcome.plan))
        if (replan or split) and not any(w.kind == ItemKind.WAYPOINT for w in waypoints):
            # nothing (left) for us: the mission is done here. On the ground the vehicle
            # does not take off (the split found no work its battery or speed adds: a
            # quadcopter whose field is beyond its reach would hover at its take-off
            # altitude until BATTERY_CRITICAL); in the air it flies home
            self.sortie.finish()
            self.stop(Trigger.COMPLETE)
            note = Log(f"mission {mid}: the plan gives us nothing to fly; done")
            return [note, Post(fsm.PlanSucceeded(mid)), Post(fsm.MissionComplete(mid))]
        if not waypoints:
            return self._failed(mid, "nothing to fly for this vehicle")
        follow = Follow.of(outcome.plan, self.profile) if not replan else self.follow
        if follow is not None:
            return self._begin_follow(mission, outcome.plan, follow, zones, ap, now)
        self.follow, self.turn = None, None
        launch = 0.0 if ap.armed else launch_s(self.profile, mission.params.altitude_rel_m)
        sync = not replan and self.sync.begin(outcome.plan, ap, zones, now, home_alt, launch)
        self._approach = None
        if not sync:
            base_waypoints = waypoints
            try:
                waypoints = self.transit.tight(
                    self.transit.with_approach(waypoints, ap, zones, now, home_alt)
                )
            except (PlanningError, ValueError) as exc:
                return self._failed(mid, f"approach: {exc}")
            if ap.armed and ap.lat_deg is not None and ap.lon_deg is not None:
                self._approach = (base_waypoints, tuple(zones), home_alt, ap.lat_deg, ap.lon_deg, 0)
        self.zones = tuple(zones)
        self.mission_id = mid
        self.mission = mission
        self._confirmed = False
        fleet_ids = list(outcome.plan.roster)
        self.takeoff_alt_m = mission.params.altitude_rel_m
        self.share = share
        self._offset = self.sortie.progress_m if replan else 0.0  # flown before the replan
        self.sortie.path_m = self._offset + share.length_m
        self.sortie.progress_m = self._offset
        self.sortie.go(Trigger.RELEASED)
        if sync:  # PREMISSION: launch, climb, then our leg to the fleet's meet time
            group = list(self.sync.group)
            note = Log(
                f"mission {mid}: planned for fleet {fleet_ids}; PREMISSION with {group}, "
                f"at our entry by {self.sync.eta_unix_s:.1f} at the earliest "
                f"(plan {outcome.plan.digest()})"
            )
            if ap.armed:
                self._go(Step.MEET)
                return [note, *self._confirm(mid)]
            self._steps = self._launch_steps()
            self._go(Step.PLANNED)
            return [note, *self._next(now)]
        note = Log(
            f"mission {mid}: planned for fleet {fleet_ids} around {len(zones)} zone(s); {len(waypoints)} items for us"
        )
        waypoints = self._load(waypoints, ap)
        self.turn = LandingTurn.of(outcome.plan, self.profile.vehicle_id, waypoints)
        steps: list[ApRequest] = [UploadMission(items=waypoints)]
        if not ap.armed:
            steps += self._launch_steps()
        else:
            steps.append(StartMission())
        self._steps = steps
        self._go(Step.PLANNED)
        return [note, *self._next(now)]

    def vote(self) -> None:
        """Idle candidates synchronised for a QUANTITY mission vote (mission/tasking.py)."""
        self.sortie.go(Trigger.VOTE)

    def elected(self) -> None:
        """Chosen by the vote: the mission is planned for the winners (`release`)."""
        self.sortie.go(Trigger.ELECTED)

    def _begin_follow(
        self,
        mission: Mission,
        plan: FleetPlan,
        follow: Follow,
        zones: Sequence[NoFlyZone],
        ap: AutopilotState,
        now: float,
    ) -> list[Out]:
        """MUM-T: launch and climb (on the ground), then follow the lead in our slot
        (mission/follow.py); no path: progress is 0 of 1 m until the follow ends."""
        mid = mission.mission_id
        self.zones, self.mission_id, self.mission = tuple(zones), mid, mission
        self.takeoff_alt_m = mission.params.altitude_rel_m
        self.follow, self._confirmed = follow, False
        self.share = plan.share(self.profile.vehicle_id)
        self.items, self.last_item = 0, 0
        self.sortie.path_m, self.sortie.progress_m = 1.0, 0.0
        self.sortie.go(Trigger.RELEASED)
        note = Log(
            f"mission {mid}: following lead {follow.lead_id} in slot {follow.slot} "
            f"of {len(follow.offsets)}"
        )
        if ap.armed:
            self._go(Step.FOLLOW)
            self.sortie.go(Trigger.STARTED)
            follow.begin(now)
            return [note, *self._confirm(mid)]
        self._steps = self._launch_steps()
        self._go(Step.PLANNED)
        return [note, *self._next(now)]

    def _following(self, ap: AutopilotState, now: float) -> list[Out]:
        """MUM-T: our slot where the lead will be, every second; the end after the
        duration, or when the lead is no longer heard."""
        follow = self.follow
        assert follow is not None and self.mission_id is not None
        why = follow.over(now)
        if why is not None:
            mid = self.mission_id
            self.sortie.finish()
            self.stop(Trigger.COMPLETE)
            return [Log(f"mission {mid}: {why}"), Post(fsm.MissionComplete(mid))]
        home_alt = ap.home.alt_msl_m if ap.home else 0.0
        return [
            Submit(msgspec.structs.replace(r, request_id=next(self._ids)), Owner.MISSION)
            for r in follow.step(ap, now, self.zones, home_alt)
        ]

    def on_peer_status(self, status: VehicleStatus, now: float) -> None:
        """A peer's telemetry: MUM-T's lead."""
        if self.follow is not None:
            self.follow.on_status(status, now)

    def on_peer_statuses(self, statuses: Sequence[VehicleStatus], now: float) -> None:
        """`on_peer_status` for each of `statuses` in turn."""
        if self.follow is not None:
            for status in statuses:
                self.follow.on_status(status, now)

    def _load(self, waypoints: tuple[Waypoint, ...], ap: AutopilotState) -> tuple[Waypoint, ...]:
        """The items to upload for `waypoints` (our share, with its approach), and what
        following them needs: the item that completes the share, a timed hold, metres
        along each item, the share's index of each item, and what the autopilot reported
        before (an earlier mission's items do not count)."""
        # end on an unlimited loiter over the last waypoint: the autopilot holds there
        # (ArduPlane would otherwise RTL by itself, straight through any zone) until the
        # node flies the zone-safe way home; a share that lands (AUTOLAND) ends landed
        self.lands = bool(waypoints) and waypoints[-1].kind == ItemKind.LAND
        last = next((w for w in reversed(waypoints) if w.kind == ItemKind.WAYPOINT), None)
        if self.lands:
            last = None
        if last is not None:
            waypoints = (
                *waypoints,
                Waypoint(ItemKind.LOITER_UNLIMITED, last.lat_deg, last.lon_deg, last.alt_rel_m),
            )
        self.items = len(waypoints) + 1
        self.last_item = self.items - (2 if last is not None else 1)  # the item that completes it
        self._timed_hold(waypoints, self.mission.params.duration_s if self.mission else None)
        self.along_m = along_path(ap, waypoints)
        assert self.share is not None
        self._share_index = share_index_of_items(waypoints, self.share.waypoints)
        self._stale = (ap.mission_reached, ap.mission_current)
        self._fresh_reached = self._fresh_current = False
        self._reached = 0
        return waypoints

    def _confirm(self, mid: int) -> list[Out]:
        """The plan is flown: PlanSucceeded, once per plan."""
        if self._confirmed:
            return []
        self._confirmed = True
        return [Post(fsm.PlanSucceeded(mid))]

    def info_due(self) -> bool:
        """Our PREMISSION ETA changed since asked: publish VehicleInfo now."""
        due, self.sync.info_due = self.sync.info_due, False
        return due

    def _meet(self, ap: AutopilotState, fleet: Roster | None, now: float) -> list[Out]:
        """PREMISSION, climbed: once the meet time is known, plan our leg to our entry
        from where we are and upload it with our share from the entry on; start it at
        its departure time (a VTOL in hover waits there)."""
        sync = self.sync
        assert self.share is not None and self.mission_id is not None
        if self._in_flight is not None or self._steps:
            return []  # uploading
        if not sync.active:  # a replan dropped the meet (begin_replan): fly on from here
            return self._fly_share_from_here(ap, now, "the meet dropped by a replan")
        if sync.leg is not None:
            if now < sync.depart_unix_s - AP_POLL_S / 2:
                return []
            self._steps = [StartMission()]
            self._go(Step.DEPART)
            return self._next(now)
        etas = fleet.entry_at if fleet is not None else {}
        gone = set(fleet.lost) | fleet.finished if fleet is not None else set()
        t = sync.ready(etas, gone, now)
        if t is None:
            return []
        home_alt = ap.home.alt_msl_m if ap.home else 0.0
        try:
            waypoints = sync.plan_leg(ap, self.zones, now, home_alt, t)
            leg = sync.leg
            assert leg is not None
            note = Log(
                f"mission {self.mission_id}: PREMISSION leg {leg.flown_m:.0f} m at "
                f"{leg.speed_m_s:.1f} m/s, leaving in {sync.depart_unix_s - now:.1f} s, "
                f"at our entry at {sync.meet_unix_s:.1f} ({sync.meet_unix_s - now:.1f} s)"
            )
            self._steps = [UploadMission(items=self._load(self.transit.tight(waypoints), ap))]
        except (PlanningError, ValueError) as exc:  # fly the share as planned
            sync.stop()
            return self._fly_share_from_here(ap, now, f"no PREMISSION leg ({exc})")
        return [note, *self._next(now)]

    def _fly_share_from_here(self, ap: AutopilotState, now: float, why: str) -> list[Out]:
        """Climbed, without a meet: our share with an approach from where we are."""
        assert self.share is not None
        home_alt = ap.home.alt_msl_m if ap.home else 0.0
        try:
            waypoints = self.transit.with_approach(
                self.share.waypoints, ap, self.zones, now, home_alt
            )
        except (PlanningError, ValueError) as exc2:
            return self._abandon(f"approach: {exc2}")
        note = Log(f"mission {self.mission_id}: {why}; flying the share")
        self._steps = [
            UploadMission(items=self._load(self.transit.tight(waypoints), ap)),
            StartMission(),
        ]
        self._go(Step.FROM_HERE)
        return [note, *self._next(now)]

    def _abandon(self, reason: str, code: AlertCode = AlertCode.PLAN_FAILED) -> list[Out]:
        """The share cannot be flown after all: a plan the state machine has not taken
        yet failed (`code`: planning, or the autopilot refusing a step); one it has
        (PREMISSION confirms at the take-off) is left."""
        mid = self.mission_id if self.mission_id is not None else 0
        confirmed = self._confirmed
        self.stop(Trigger.FAILED)
        if confirmed:
            return [Post(fsm.LeftFleet(short_text(reason)))]
        return [Post(fsm.PlanFailed(mid, short_text(reason), code=code))]

    def reattach(
        self, mission_id: int, items: int, last_item: int, path_m: float, progress_m: float
    ) -> None:
        """After the node restarted: the autopilot flies the share this node uploaded
        before (`items`, completed at `last_item`); watch it again to its end, without
        a request (reattach.py). Progress in metres resumes from `progress_m`."""
        self.stop()
        self.sortie.begin(keep_progress=False)
        self.sortie.go(Trigger.RELEASED)
        self.sortie.go(Trigger.STARTED)
        self.sortie.path_m, self.sortie.progress_m = path_m, min(progress_m, path_m)
        self.mission_id, self.items, self.last_item = mission_id, items, last_item
        self._stale = (-2, -2)  # everything the autopilot reports now is of this mission
        self._fresh_reached = self._fresh_current = True
        self._reached = 0
        self.hold_s, self.hold_seq = 0.0, 0
        self._go(Step.REATTACHED)
        self.reattached = True  # the autopilot past the last item: the share is flown

    def begin_replan(self, now: float | None = None) -> None:
        """A member was lost: the fleet replans what is left. We keep flying our share
        meanwhile; the progress we published is what the others replan from."""
        if self.sortie.state in (MissionState.MISSION, MissionState.PREMISSION):
            self.sortie.go(Trigger.REPLAN)
        if now is not None:
            self.agreement.begin(now)
        self._planning, self._held = None, None
        self.sync.stop()  # a replanned share is flown from where we are, without a meet

    def replan(
        self,
        mission: Mission,
        survivors: Sequence[Member],
        progress_m: Mapping[int, float],
        zones: Sequence[NoFlyZone],
        ap: AutopilotState,
        now: float,
        battery_pct: Mapping[int, float] | None = None,
        merge: tuple[tuple[Replay, Mapping[int, tuple[float, float]]], ...] = (),
    ) -> list[Out]:
        """What is left of the fleet plan (every old member's `progress_m` along its
        share) shared among `survivors`, posed where their progress puts them (and, for
        an area, none given more than `battery_pct` flies home): a `PlanJob` whose
        outcome comes back to `on_plan`."""
        base = self.fleet_plan
        if base is None or self.sortie.state != MissionState.REPLAN:
            return self.release(mission, survivors, zones, ap, now)
        home_alt = ap.home.alt_msl_m if ap.home else 0.0
        self._job += 1
        self._planning = (mission, tuple(zones))
        self.replanned_from = dict(progress_m)
        req = PlanRequest(
            self._job,
            mission,
            tuple(survivors),
            tuple(zones),
            now,
            home_alt,
            base=base,
            progress_m=dict(progress_m),
            battery_pct=dict(battery_pct or {}),
            merge=merge,
        )
        ids = sorted(m.profile.vehicle_id for m in survivors)
        done = {v: round(p) for v, p in sorted(progress_m.items())}
        return [
            Log(f"mission {mission.mission_id}: replanning for {ids} from {done} m"),
            PlanJob(req),
        ]

    def _resume(self, mid: int) -> list[Out]:
        if self.sortie.state == MissionState.REPLAN:
            self.sortie.go(Trigger.RESUMED)
        return [Post(fsm.PlanSucceeded(mid))]

    def share_progress_m(self) -> float:
        """Metres flown along our share of the current fleet plan (published progress
        less what was flown before the last replan)."""
        return max(0.0, self.sortie.progress_m - self._offset)

    def _failed(self, mid: int, reason: str, detail: ReasonDetail | None = None) -> list[Out]:
        self.sortie.go(Trigger.FAILED)
        return [Post(fsm.PlanFailed(mid, short_text(reason), detail))]

    def _timed_hold(self, waypoints: Sequence[Waypoint], duration_s: float | None) -> None:
        """A mission with a duration that holds on an unlimited loiter (a fixed-wing's
        target orbit): the hold ends after `duration_s` on station, then the mission is
        complete."""
        self.hold_s, self.hold_seq, self.hold_since, self._hold_wp = 0.0, 0, None, None
        if not duration_s:
            return
        for i, w in enumerate(waypoints[:-1]):  # the appended final loiter is not the hold
            if w.kind == ItemKind.LOITER_UNLIMITED:
                self.hold_s, self.hold_seq, self._hold_wp = float(duration_s), i + 1, w
                self.last_item = max(self.last_item, i + 1)
                return

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

    def _next(self, now: float) -> list[Out]:
        if not self._steps:
            self._in_flight = None
            return []
        req = msgspec.structs.replace(self._steps.pop(0), request_id=next(self._ids))
        self._in_flight = req
        return self._ask(req, now)

    def _ask(self, req: ApRequest, now: float) -> list[Out]:
        """Our next step to the arbiter, as the close pads fly it (pad_sequence.py): the
        launch waits its turn, the way home ends on the own pad, whose landing answers
        our Land at once."""
        ap, pads = self._ap or AutopilotState(), self.pads
        if isinstance(req, UploadMission):
            req = self._in_flight = pads.upload(req, ap)
            self.uploaded = req.items
        elif isinstance(req, Arm):
            held = pads.hold_launch(req, ap, now)
            if held is not None:
                return [held]
        elif isinstance(req, ReturnToLaunch):
            home = pads.home(ap)
            if home is not None:
                note, reqs = home
                answer = ApResult(req.request_id, True, "home to its pad")
                return [note, *self._pad_submit(reqs), *self.on_result(answer, now)]
        elif isinstance(req, Land) and pads.answers_land:
            return self.on_result(ApResult(req.request_id, True, "landing on its pad"), now)
        elif isinstance(req, StartMission) and not self.suspended:
            self._started = (req, now)
        return [Submit(req, Owner.MISSION)]

    def _pad_submit(self, reqs: Sequence[ApRequest]) -> list[Out]:
        """The landing on the pad's own requests (their results to `pads`)."""
        out: list[Out] = []
        for r in reqs:
            req = msgspec.structs.replace(r, request_id=next(self._ids))
            self._pad_requests[req.request_id] = req
            if isinstance(req, UploadMission):
                self.uploaded = req.items
            out.append(Submit(req, Owner.MISSION))
        return out

    def pads_tick(self, ap: AutopilotState, now: float) -> list[Out]:
        """The close pads at the avoidance's 5 Hz (pad_sequence.py): the held launch let
        go, the landing's gate."""
        launched, out, reqs = self.pads.tick(ap, now)
        if launched is not None:
            out.append(Submit(launched, Owner.MISSION))
        return out + self._pad_submit(reqs)

    def on_suspended(self, on: bool, now: float) -> list[Out]:
        """Avoidance suspended us (the arbiter holds our flight requests meanwhile) or
        gave the autopilot back. A StartMission of ours the autopilot's state may not
        show yet (a VTOL's PREMISSION leg sent from its hover over the pad) is asked
        again, held: the manoeuvre's resume, going back to the mode it saw, would put
        it back in GUIDED over the pad for good (a mixed demo's VTOL hovered there)."""
        self.suspended = self.pads.suspended = on
        if not on:
            self.pads.resumed()
            return []
        started, self._started = self._started, None
        ap = self._ap
        if started is None or now - started[1] > START_SEEN_S or ap is None:
            return []
        return [Submit(started[0], Owner.MISSION)] if ap.mode_name != "AUTO" else []

    # ------------------------------------------------------------------ return
    def start_return(self, ap: AutopilotState, zones: Sequence[NoFlyZone], now: float) -> list[Out]:
        """Fly back to base around the no-fly zones and land there: a short mission of
        zone-safe waypoints to above home, then RTL (whose landing the autopilot or
        `on_autopilot` completes). Without zones in the way, plain RTL."""
        self.mission_id = fsm.RETURN_MISSION
        self._approach = None
        self._go(Step.RETURN)
        self._planning, self._held = None, None  # a plan job still running is abandoned
        self.agreement.end()
        self.sortie.go(Trigger.RETURN)
        self.hold_s, self.hold_seq = 0.0, 0
        done = [Post(fsm.PlanSucceeded(fsm.RETURN_MISSION))]
        home = ap.home
        if not ap.armed and ap.link_ok and (ap.alt_rel_m or 0.0) < 2.0:
            # on the ground (a member its fleet's plan gave nothing): nothing to fly; an
            # RTL would leave the disarmed vehicle in RTL mode. Landed at the next update
            self._steps = []
            return [*done]
        if not zones or home is None or ap.lat_deg is None or ap.lon_deg is None or not ap.armed:
            self._steps = [ReturnToLaunch()]
            return [*done, *self._next(now)]
        try:
            leg = self.transit.from_here(
                ap, (home.lat_deg, home.lon_deg), zones, now, home.alt_msl_m
            )
        except (PlanningError, ValueError):
            leg = []
        note: list[Out] = []
        if len(leg) > 1:
            try:
                leg = list(self.transit.flyable_leg(leg, ap, zones, now, home.alt_msl_m))
            except (PlanningError, ValueError) as exc:  # the zone-safe legs, as planned
                note = [Log(f"return: no flyable turns ({exc}); flying the legs as they are")]
        if len(leg) <= 1:  # nothing in the way: plain RTL
            self._steps = [ReturnToLaunch()]
        else:
            self.items = len(leg) + 2
            self.last_item = self.items - 1
            self._steps = [
                UploadMission(items=(*self.transit.tight(leg), Waypoint(ItemKind.RTL))),
                StartMission(),
            ]
        return [*done, *note, *self._next(now)]

    def stop(self, trigger: Trigger = Trigger.STOP) -> None:
        self._go(Step.STOP)
        self.mission_id, self._steps, self._in_flight = None, [], None
        self.pads.stop()
        self.reattached = False
        self._planning, self._held = None, None  # a plan job still running is abandoned
        self.share, self._share_index, self._offset = None, (), 0.0
        self.turn, self.lands, self.follow, self._approach = None, False, None, None
        self.sync.stop()
        self.agreement.end()
        self.sortie.go(trigger)

    def take_over(self, phase: Phase) -> None:
        """The operator's command (RTL, LAND, EMERGENCY_LAND, PARACHUTE, or a ground
        station's mode through passthrough: OPERATOR) flies the vehicle now: drop
        whatever was planned and only watch for the landing (RETURNING: a hover-capable
        vehicle is landed once near home, as on the node's own return)."""
        self.stop()
        self.sortie.go(Trigger.PARACHUTE if phase == Phase.PARACHUTE else Trigger.TAKE_OVER)
        self._go(TAKE_OVER[phase])
        self.mission_id = fsm.RETURN_MISSION

    @property
    def landing(self) -> bool:
        """On the way down or home (what ABORT_LANDING can cancel)."""
        return self.phase in (Phase.RETURNING, Phase.LANDING)

    @property
    def touching_down(self) -> bool:
        """Landing now (the way home's last stage): a new mission waits for the landing."""
        return self.phase == Phase.LANDING

    # ------------------------------------------------------------------ inputs
    def on_result(self, result: ApResult, now: float) -> list[Out]:
        pad = self._pad_requests.pop(result.request_id, None)
        if pad is not None:
            if result.ok:
                return []
            out, fallback = self.pads.failed(pad, result.reason, now)
            if fallback:  # its result is not waited for
                rtl = ReturnToLaunch(request_id=next(self._ids))
                out.append(Submit(rtl, Owner.MISSION))
            return out
        done = self._in_flight
        if done is None or result.request_id != done.request_id:
            return []
        self._in_flight = None
        mid = self.mission_id if self.mission_id is not None else 0
        if not result.ok:
            phase = self.phase
            if phase == Phase.RETURNING and not isinstance(done, ReturnToLaunch):
                self._steps = [ReturnToLaunch()]  # the zone-safe way home failed: plain RTL
                return self._next(now)
            if phase in (Phase.STARTING, Phase.MEETING):
                return self._abandon(result.reason, AlertCode.AUTOPILOT_REFUSED)
            self.stop()
            return []  # RTL/land refused: monitoring and the operator take it from here
        if (
            isinstance(done, UploadMission)
            and self._steps
            and isinstance(self._steps[0], StartMission)
        ):
            again = self._approach_again(now)
            if again:
                return again
        if self.phase == Phase.STARTING and not self._steps:
            if isinstance(done, Takeoff):
                self._go(Step.TOOK_OFF)  # the mission starts once it has climbed
                # the plan is flown from the take-off: the climb (held level for
                # minutes by avoidance under a fleet taking off at close pads) and a
                # PREMISSION's meet would otherwise count against the state machine's
                # plan timeout (a demo vehicle was sent home from 46 m)
                return self._confirm(mid)
            if isinstance(done, StartMission):
                self._go(Step.STARTED)
                if not self.sync.flying_leg:  # PREMISSION: MISSION from the entry on
                    self.sortie.go(Trigger.STARTED)
                return self._confirm(mid)
        return self._next(now)

    def _approach_again(self, now: float) -> list[Out]:
        """The share is uploaded but the vehicle has flown on meanwhile (its upload held
        under an avoidance manoeuvre, a slow link, a loaded host): started now, a
        fixed-wing would turn back to an approach planned from where it was, through
        whatever the approach went around. Planned again from here (at most 3 times;
        then started as it is: the autopilot flies to the leg's next item)."""
        a, ap = self._approach, self._ap
        if self.phase != Phase.STARTING or self.share is None or a is None:
            return []  # only a share's own upload (not a way home, a landing route)
        if ap is None or ap.lat_deg is None or ap.lon_deg is None or not ap.armed:
            return []
        base, zones, home_alt, lat, lon, tries = a
        moved = distance_m(lat, lon, ap.lat_deg, ap.lon_deg)
        if moved <= self._approach_slack_m() or tries >= 3:
            return []
        try:
            waypoints = self.transit.tight(
                self.transit.with_approach(base, ap, zones, now, home_alt)
            )
        except (PlanningError, ValueError):
            return []  # keep the approach we have
        self._approach = (base, zones, home_alt, ap.lat_deg, ap.lon_deg, tries + 1)
        self._steps = [UploadMission(items=self._load(waypoints, ap)), StartMission()]
        mid = self.mission_id if self.mission_id is not None else 0
        return [
            Log(
                f"mission {mid}: moved {moved:.0f} m while uploading; approach planned "
                "again from here"
            ),
            *self._next(now),
        ]

    def _approach_slack_m(self) -> float:
        """How far the vehicle may move between planning its approach and starting it:
        a quarter of a fixed-wing's turn radius, 10 m for the others."""
        if self.profile.is_fixed_wing:
            return max(10.0, 0.25 * self.profile.turn_radius_m())
        return 10.0

    def on_autopilot(
        self,
        ap: AutopilotState,
        now: float,
        fleet: Roster | None = None,
        base: GeoPoint | None = None,
    ) -> list[Out]:
        """`fleet`: the mission's roster (the members' published ETAs, progress and
        hashes: PREMISSION, the MISSION speed rule, the agreement on a replan); `base`:
        the operator's (the autopilot's rally point)."""
        self._ap = ap
        if fleet is not None and self.sortie.state == MissionState.REPLAN:
            agreed = self._agree(ap, now, fleet)
            if agreed:
                return agreed
        if (
            self.phase in (Phase.RETURNING, Phase.LANDING, Phase.PARACHUTE, Phase.OPERATOR)
            and not ap.armed
            and (ap.alt_rel_m or 0.0) < 2.0
        ):
            self.stop(Trigger.LANDED)
            return [Post(fsm.LandingComplete())]
        if self.phase == Phase.CLIMBING:
            if (ap.alt_rel_m or 0.0) >= CLIMB_FRACTION * self.takeoff_alt_m:
                if self.follow is not None and self.mission_id is not None:
                    self._go(Step.FOLLOW)
                    self.sortie.go(Trigger.STARTED)
                    self.follow.begin(now)
                    return self._confirm(self.mission_id)
                if self.sync.active:
                    self._go(Step.MEET)
                    return self._meet(ap, fleet, now)
                self._go(Step.CLIMBED)
                self._steps = [StartMission()]
                return self._next(now)
        elif self.phase == Phase.MEETING:
            return self._meet(ap, fleet, now)
        elif self.phase == Phase.FOLLOWING:
            return self._following(ap, now)
        elif self.phase == Phase.FLYING and self.items > 1 and self.mission_id is not None:
            return self._flying(ap, now, fleet)
        elif self.phase == Phase.RETURNING and self._in_flight is None and self.profile.can_hover:
            # RTL flies to the nearer of home and the rally point (the base: ArduPilot's
            # RALLY_INCL_HOME): land near either (a VTOL whose home is far from the base
            # circled the base for ever)
            places = [p for p in (ap.home, base) if p is not None]
            if (
                places
                and ap.lat_deg is not None
                and ap.lon_deg is not None
                and min(distance_m(ap.lat_deg, ap.lon_deg, p.lat_deg, p.lon_deg) for p in places)
                < self.land_radius_m
            ):
                self._go(Step.NEAR_HOME)
                ground = self.profile.vehicle_type in (VehicleType.ROVER, VehicleType.BOAT)
                self._steps = [Land(), Disarm()] if ground else [Land()]
                return self._next(now)
        return []

    def _flying(self, ap: AutopilotState, now: float, fleet: Roster | None = None) -> list[Out]:
        """Progress along the share and its end: the last item reached, or the timed
        hold over. Only items this mission's autopilot run reported count: the last
        MISSION_ITEM_REACHED of an earlier mission is still in the state (see also
        `_reached_item`)."""
        stale_current = self._stale[1]
        self._fresh_current |= ap.mission_current != stale_current
        reached = self._reached_item(ap)
        if self._fresh_current and ap.mission_current > self.last_item:
            reached = self.last_item  # set past its last item (avoidance resumed it there)
        out = self._keep_pace(ap, now, reached, fleet)
        if self.phase != Phase.FLYING:  # the PREMISSION watchdog flies the share from here
            return out
        if self.share is not None and self._share_index:
            k = self._share_index[min(reached, len(self._share_index) - 1)] if reached else -1
            self.sortie.advance(self._offset + self.share.progress_m(k, ap.lat_deg, ap.lon_deg))
        if self.lands:
            return out + self._landing(ap, now, fleet)
        done = reached >= self.last_item and self.hold_seq == 0
        if self.reattached and ap.mission_current > self.last_item:  # passed while we were away
            done = True
        if self.hold_seq and self._fresh_current and ap.mission_current >= self.hold_seq:
            if self.hold_since is None and self._on_station(ap):
                self.hold_since = now
            done = self.hold_since is not None and now - self.hold_since >= self.hold_s
        if not done or self.sortie.state != MissionState.MISSION:
            return out
        mid = self.mission_id
        assert mid is not None
        self.sortie.finish()
        self.stop(Trigger.COMPLETE)
        return [*out, Post(fsm.MissionComplete(mid))]

    def _reached_item(self, ap: AutopilotState) -> int:
        """The last item of our upload the autopilot reached flying it (0: none yet).
        A report counts once it differs from what the autopilot reported before our
        upload (`_stale`), and only while the autopilot flies an item after it: our
        shares have no jumps, so an item reported reached at or beyond the current one
        (MISSION_CURRENT known, > 0) is not of this run. Uploaded in AUTO, the autopilot
        keeps its item index and flies the new mission's item there until our
        StartMission sets the first one, and may report that item (deep in a replanned
        share) reached: a demo survivor's progress jumped 1,500 m down its new share,
        the field's top lane, the second it started it; lost soon after, its inheritors
        took that lane as flown and nobody flew it. A state read between a
        MISSION_ITEM_REACHED and the MISSION_CURRENT after it keeps the item before."""
        self._fresh_reached |= ap.mission_reached != self._stale[0]
        if self._fresh_reached and not 0 < ap.mission_current <= ap.mission_reached:
            self._reached = max(0, min(ap.mission_reached, self.last_item))
        return self._reached

    def _landing(self, ap: AutopilotState, now: float, fleet: Roster | None) -> list[Out]:
        """AUTOLAND: leave the hold in our turn (mission/landing.py); landed (disarmed
        on the ground), the share is flown and the sortie over."""
        turn = self.turn
        current = ap.mission_current if self._fresh_current else 0
        if turn is not None and self._in_flight is None and turn.release(current, fleet, now):
            self._steps = [StartMission(first_item=turn.hold_seq + 1)]
            return [Log(f"mission {self.mission_id}: our turn to land"), *self._next(now)]
        if not self._fresh_current or ap.armed or (ap.alt_rel_m or 0.0) >= 2.0:
            return []
        self.sortie.finish()  # peers see it in our VehicleInfo: the next may land
        self.stop(Trigger.LANDED)
        return [Post(fsm.LandingComplete())]

    def _keep_pace(
        self, ap: AutopilotState, now: float, reached: int, fleet: Roster | None
    ) -> list[Out]:
        """PREMISSION and the MISSION speed rule (mission/fleet_sync.py): the airspeed
        to command; at the entry the sortie enters MISSION."""
        sync = self.sync
        if sync.leg is None:
            return []
        etas = fleet.entry_at if fleet is not None else {}
        gone = set(fleet.lost) | fleet.finished if fleet is not None else set()
        meet = sync.meet_time(etas, gone) or sync.meet_unix_s
        late = sync.overdue(now, meet)
        if late is not None and self._in_flight is None and not self._steps:
            return self._leg_overdue(ap, now, late)
        speed = sync.control(
            ap,
            now,
            reached,
            self.share_progress_m(),
            meet,
            fleet.progress if fleet is not None else {},
            gone,
        )
        out: list[Out] = []
        if sync.arrived_at is not None and self.sortie.state == MissionState.PREMISSION:
            self.sortie.go(Trigger.STARTED)
            out.append(
                Log(
                    f"mission {self.mission_id}: at our entry, {now - meet:+.1f} s from the meet time"
                )
            )
        if speed is not None:
            req = ChangeSpeed(request_id=next(self._ids), speed_m_s=speed)
            out.append(Submit(req, Owner.MISSION))
        return out

    def _leg_overdue(self, ap: AutopilotState, now: float, late_s: float) -> list[Out]:
        """The PREMISSION watchdog (FleetSync.overdue): the leg makes no progress to the
        entry; the meet is given up and the share flown from here, with an alert."""
        text = f"mission {self.mission_id}: PREMISSION leg not at its entry {late_s:.0f} s after the meet"
        self.sync.stop()
        return [
            Note(logging.WARNING, text),
            self._alert(Severity.WARNING, text, now, AlertCode.GENERIC),
            *self._fly_share_from_here(ap, now, "the PREMISSION leg overdue"),
        ]

    def _on_station(self, ap: AutopilotState) -> bool:
        """Within the hold's loiter circle (its radius plus a turn radius)."""
        if ap.lat_deg is None or ap.lon_deg is None or not self.along_m:
            return False
        w = self._hold_wp
        if w is None:
            return True
        r = abs(w.loiter_radius_m or 0.0) + max(LAND_AT_HOME_M, 1.5 * self.profile.turn_radius_m())
        return distance_m(ap.lat_deg, ap.lon_deg, w.lat_deg, w.lon_deg) <= r


def idle_members(plan: FleetPlan) -> tuple[int, ...]:
    """The members a plan gives no waypoint to fly (the same on every node)."""
    return tuple(
        sorted(
            vid
            for vid, share in plan.shares.items()
            if not any(w.kind == ItemKind.WAYPOINT for w in share.waypoints)
        )
    )


def replan_battery(
    base: FleetPlan,
    survivors: Sequence[Member],
    progress_m: Mapping[int, float],
    flown_before_m: Mapping[int, float],
    altitude_m: float,
) -> dict[int, float]:
    """Each survivor's battery left by the model (`Endurance.left_pct`): climbed to
    `altitude_m`, then flown its share's planned time to `progress_m` and the metres it
    flew before the last replan at its mission speed. Every survivor computes the same
    from the progress all published (the measured batteries differ by when each node
    last heard them: two nodes would split differently)."""
    out: dict[int, float] = {}
    for m in survivors:
        vid, p = m.profile.vehicle_id, m.profile
        share = base.shares.get(vid)
        if share is None or p.battery_capacity_mah <= 0.0:
            continue
        speed = next((v.speed_m_s for v in share.waypoints if v.speed_m_s), p.cruise_speed_m_s)
        flown_s = share.planned_s_at(progress_m.get(vid, 0.0))
        flown_s += flown_before_m.get(vid, 0.0) / max(speed or 1.0, 0.1)
        start = base.launch_battery_pct.get(vid, 100.0)  # what it had at the first plan
        out[vid] = Endurance.of(p, altitude_m).left_pct(flown_s, p.battery_capacity_mah, start)
    return out


def share_index_of_items(
    uploaded: Sequence[Waypoint], share: Sequence[Waypoint]
) -> tuple[int, ...]:
    """For each uploaded item seq (0 = home), the index in `share` of the last share
    waypoint passed at it (-1 before the share starts): the approach leg and the points
    the flyable stage adds map to the share item before them."""
    out = [-1]
    k = -1
    for w in uploaded:
        for j in range(k + 1, len(share)):
            sw = share[j]
            if (
                sw.kind == w.kind
                and abs(sw.lat_deg - w.lat_deg) < 1e-6
                and abs(sw.lon_deg - w.lon_deg) < 1e-6
            ):
                k = j
                break
        out.append(k)
    return tuple(out)


def along_path(ap: AutopilotState, waypoints: Sequence[Waypoint]) -> tuple[float, ...]:
    """Metres along the path at each mission item (index = item seq, 0 = home): from
    where the vehicle is through every item with a position."""
    out = [0.0]
    at = (ap.lat_deg, ap.lon_deg) if ap.lat_deg is not None and ap.lon_deg is not None else None
    total = 0.0
    for w in waypoints:
        if w.kind in (ItemKind.CHANGE_SPEED, ItemKind.RTL) or (
            w.lat_deg == 0.0 and w.lon_deg == 0.0
        ):
            out.append(total)
            continue
        if at is not None:
            total += distance_m(at[0], at[1], w.lat_deg, w.lon_deg)
        at = (w.lat_deg, w.lon_deg)
        out.append(total)
    return tuple(out)
