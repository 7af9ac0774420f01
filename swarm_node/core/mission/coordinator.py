"""The mission coordinator: the owner of the swarm state machine (paper section 2.3.4)
and of the mission in force, and of the parts of the mission layer that change it: the
roster (the members of the mission's fleet, agreed by all), tasking (the vote of a
QUANTITY mission, re-tasking), regroup (add and swap) and the mission manager (which
flies this vehicle's share). Only this module posts to the state machine: every other
module's events reach it as `Post` outputs.

    inputs (from NodeCore)                 what it does with them
    tick(facts, read, now)                 the state machine's step; its outputs carried
                                           out (BeginPlan -> the roster opens, the
                                           mission manager plans; ReleaseMission -> the
                                           fleet plans, votes, replans or joins; ...)
    take(Post)                             queued for the state machine
    take(Accepted)                         a mission past the acceptance checks: in force
    take(Candidacy)                        a QUANTITY mission past them: tasking answers
                                           it, a flying fleet votes at once
    take(Regrouping)                       JOIN / SWAP addressed to this vehicle
    take(TakeOver), take(StopLanding)      the operator flies the vehicle
    on_message(Vote | TargetReport), on_timer
                                           tasking; its outcomes (elected, failed,
                                           derived missions) carried out
    on_message(PlanLineage), heard_mission regroup
    on_message(Ack), on_info, peer_lost    the roster (members lost or joining: replan)
    restored(record), on_result(REATTACH)  a node restarted in flight: reattach
                                           (reattach.py, owner REATTACH) decides with
                                           the share on record, which is kept here
    on_autopilot, on_plan, on_result,      the mission manager
    on_suspended, pads_tick

It talks to the rest of the node through outputs (outputs.py): requests (owner
MISSION), control released, declarations kept or ended, this vehicle's fleet left,
the emergency procedure begun, our VehicleInfo published now. What it reads of the
other modules comes in as a `Context` (the autopilot's state, the peers, the base, the
fleet, the active flag, readiness, the zones, the missions on record), read only when an
input needs it.

Pure: no I/O; `now` is passed in.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import assert_never

from swarm_proto import (
    Ack,
    AckReason,
    AckRef,
    Alert,
    AlertCode,
    Command,
    CommandKind,
    FsmState,
    GeoPoint,
    LatLon,
    Mission,
    MissionState,
    MissionType,
    PlanLineage,
    SelectorKind,
    Severity,
    TargetReport,
    VehicleInfo,
    VehicleStatus,
    Vote,
)
from swarm_proto.text import short_text

from .. import state_machine as fsm
from ..arbiter import Owner
from ..autopilot.items import ItemKind, Waypoint
from ..autopilot.requests import ApResult
from ..autopilot.state import AutopilotState
from ..declared import SortieRecord
from ..fences import FENCE_FULL_HEIGHT_REL_M
from ..membership import Peer
from ..mission_manager import Member, MissionManager, replan_battery, with_defaults
from ..outputs import (
    Accepted,
    Answer,
    BeginEmergency,
    Candidacy,
    Ended,
    Heard,
    LeftFleet,
    ModuleOutput,
    Note,
    Post,
    Publish,
    PublishInfo,
    Regrouping,
    Release,
    SetActive,
    SilentShare,
    StopLanding,
    TakeOver,
    ToMission,
)
from ..profile import VehicleProfile, published_capacity_mah, with_autopilot_battery
from ..reattach import Decision, Reattacher, dropped, same_share, sortie_record
from ..reports import MissionReport
from ..safety.pad_sequence import PadSequence
from ..safety.zones import ZoneBook
from ..swarm.heal import Heal
from ..swarm.regroup import Lineage, Regroup
from ..swarm.roster import MemberJoined, MemberLost, Roster, RosterEvent, RosterMismatch
from .phases import Phase
from .published import along_share, lineage_battery, published_home, published_progress
from .scoring import Candidate
from .share import PlanOutcome, Replay, heading_on, pose_on, route_ahead
from .tasking import Derived, Elected, Standing, Tasking, TaskingOutput, TaskingSettings, VoteFailed
from .voting import VoterLost

#: past the state machine's plan timeout, a mission not answered yet is answered TIMEOUT
VERDICT_GRACE_S = 5.0

# what a replan takes over from a lost member: its fleet plans or flies the mission
REPLANNING = (MissionState.PREMISSION, MissionState.MISSION, MissionState.REPLAN)
# a member lost by these (membership.py) fell silent: its aircraft may fly on
SILENT = frozenset({"liveliness", "stale"})


@dataclass(frozen=True)
class Context:
    """What the coordinator reads of the other modules (NodeCore hands it in)."""

    autopilot: AutopilotState
    peers: Mapping[int, Peer]  # membership's
    base: GeoPoint | None  # the declarations'
    fleet_id: int
    active: bool  # the operator desk's
    ready: bool  # vehicle monitoring's
    zones: ZoneBook
    on_record: Callable[[int], tuple[Mission | None, str]]  # a mission the declarations keep


Read = Callable[[], Context]  # the Context, read when needed (most inputs need none)


@dataclass
class MissionCoordinator:
    profile: VehicleProfile
    plan_timeout_s: float = 60.0
    fleet_profiles: Mapping[int, VehicleProfile] = field(default_factory=dict)
    mission_defaults: Mapping[MissionType, Mapping[str, float]] = field(default_factory=dict)
    tasking_settings: TaskingSettings = field(default_factory=TaskingSettings)
    pads: PadSequence | None = None  # the mission manager's close pads
    now: float = 0.0
    silent_hold_s: float = 0.0  # a silent member's share held this long (0: replan at once)

    def __post_init__(self) -> None:
        vid = self.self_id = self.profile.vehicle_id
        self.fsm = fsm.StateMachine(plan_timeout_s=self.plan_timeout_s, now=self.now)
        self.manager = MissionManager(self.profile, with_pads=self.pads)
        self.roster = Roster(vid)  # the members of the current mission, agreed by all
        self.tasking = Tasking(vid, self.tasking_settings, self.fleet_profiles)
        self.regroup = Regroup(vid)  # add and swap: lineages of the fleets flown in
        self.heal = Heal(vid)  # a partition healed: the other parts' lineages
        self._merging: dict[int, tuple[PlanLineage, ...]] = {}  # mission -> parts to merge
        self.missions: dict[int, Mission] = {}  # the missions in force, by id
        self.lost_members: list[MemberLost] = []  # roster events (replanning picks them up)
        self.record: SortieRecord | None = None  # the share flown (restored or kept)
        self.reattach = Reattacher(vid)  # a start with the vehicle flying (reattach.py)
        self._record_changed = False
        self._replanning = False  # in PLAN for a replan of the current mission
        self._reboots = 0  # the autopilot's reboots when last seen
        # members fallen silent whose share is held: vehicle -> (mission, held until)
        self.held: dict[int, tuple[int, float]] = {}
        # the operator's missions not answered yet (the fleet's verdict comes with its
        # plan): mission id -> (mission, answered by then at the latest)
        self.unanswered: dict[int, tuple[Mission, float]] = {}
        self.idle_in: set[int] = set()  # missions whose plan left us nothing to fly

    # ------------------------------------------------------------------ views
    @property
    def mission_state(self) -> MissionState:
        """Owned by the mission manager's sortie (mission/sortie.py), read here."""
        return self.manager.mission_state

    @property
    def replanning(self) -> bool:
        return self._replanning

    def report(self, ap: AutopilotState) -> MissionReport:
        """Our VehicleInfo's mission part. Its battery, the first published in PLAN for
        the roster's mission, is what every node (this one too) plans this vehicle's
        share with."""
        pct = min(max(ap.battery_pct, -1), 100)
        r, f = self.roster, self.fsm
        planning = f.state == FsmState.PLAN and r.mission_id is not None
        if pct >= 0 and planning and r.mission_id == f.mission_id:
            r.plan_battery.setdefault(self.self_id, pct)
        sortie = self.manager.sortie
        progress_m, path_m = published_progress(sortie.progress_m, sortie.path_m)
        eta = self.manager.sync.eta_unix_s
        return MissionReport(f.mission_id, f.state, r.members_hash, progress_m, path_m, eta, pct)

    def fly_ceiling_rel_m(self) -> float:
        """The highest this vehicle flies above home: zones below it may be overflown."""
        top = FENCE_FULL_HEIGHT_REL_M
        for m in self.missions.values():
            n = max(1, len(m.selection.vehicle_ids), len(self.roster.members))
            top = max(top, m.params.altitude_rel_m + m.params.altitude_step_m * (n - 1))
        return top

    def next_deadline(self) -> float:
        t = self.fsm.next_deadline()
        held = min((until for _, until in self.held.values()), default=None)
        verdict = min((due for _, due in self.unanswered.values()), default=None)
        for due in (self.tasking.next_deadline(), self.reattach.next_deadline(), held, verdict):
            if due is not None and due < t:
                t = due
        return t

    # ------------------------------------------------------------------ the state machine
    def take(self, o: ToMission, ctx: Read, now: float) -> list[ModuleOutput]:
        """What other modules tell us (outputs.ToMission); `ctx` read when needed."""
        match o:
            case Post(event):
                self.fsm.post(event)
                return []
            case Accepted(mission):
                self.missions[mission.mission_id] = mission  # in force
                self.fsm.post(fsm.NewMission(mission.mission_id))
                # answered with the fleet's plan; a plan that never comes (the state
                # machine's plan timeout, a cancel) is answered at the latest then
                due = now + self.plan_timeout_s + VERDICT_GRACE_S
                replaced = self._replaced(mission.mission_id)
                self.unanswered[mission.mission_id] = (mission, due)
                return replaced
            case Candidacy(mission):
                return self._candidate(mission, ctx(), now)
            case Regrouping(cmd):
                return self._regroup(cmd, ctx(), now)
            case TakeOver(reason, phase):
                # the operator flies the vehicle out of its mission: the mission manager
                # only watches for the landing
                self.manager.take_over(phase)
                if self.fsm.state in (FsmState.PLAN, FsmState.GO_MISSION):
                    self.fsm.post(fsm.Recalled(reason))
                return []
            case StopLanding():
                self.manager.stop()  # the operator holds the vehicle; LAND or RTL ends it
                return []
            case _:
                assert_never(o)

    def tick(self, facts: fsm.Facts, read: Read, now: float) -> list[ModuleOutput]:
        """The state machine's step (`facts` from the other modules; the fleet's
        readiness and the take-off queue are ours); its outputs carried out."""
        planning = self.fsm.state == FsmState.PLAN and self.fsm.mission_id is not None
        facts = fsm.Facts(
            active=facts.active,
            base_set=facts.base_set,
            vehicle_ready=facts.vehicle_ready,
            emergency=facts.emergency,
            fleet_ready=planning and self._fleet_ready(read()),
            armed=facts.armed,
            launch_queued=self.manager.launch_queued,
        )
        tr = self.fsm.tick(now, facts)
        if tr is None:
            return []
        ctx = read()
        out: list[ModuleOutput] = [
            Note(logging.INFO, f"{tr.before.name} -> {tr.after.name} ({tr.rule})")
        ]
        if tr.before == FsmState.EMERGENCY and tr.after != FsmState.EMERGENCY:
            out.append(Release(Owner.EMERGENCY))
        for o in tr.outputs:
            out += self._carry_out(o, ctx, now)
        if tr.before != tr.after or any(isinstance(o, fsm.BeginPlan) for o in tr.outputs):
            out.append(PublishInfo())  # peers waiting on our state should not wait 1 s
        return out

    def _carry_out(self, o: fsm.Output, ctx: Context, now: float) -> list[ModuleOutput]:
        if isinstance(o, fsm.RaiseAlert):
            text = short_text(o.text)
            return [Publish(Alert(self.self_id, max(0.0, now), o.severity, o.code, text, o.detail))]
        if isinstance(o, fsm.StartEmergency):
            self.manager.stop()
            return [BeginEmergency(o.code, o.severity)]
        if isinstance(o, fsm.ReturnHome):
            return [Note(logging.WARNING, f"returning home: {o.reason}"), *self._return(ctx, now)]
        if isinstance(o, fsm.LeaveFleet):
            self.roster.close()
            return [LeftFleet()]
        if isinstance(o, fsm.FollowOperator):
            out: list[ModuleOutput] = []
            if o.mission_id is not None:
                self.missions.pop(o.mission_id, None)  # left, not completed
                out.append(Ended(o.mission_id))
            return [*out, Note(logging.WARNING, f"left mission {o.mission_id}: {o.reason}")]
        if isinstance(o, fsm.BeginPlan):
            return self._begin_plan(o, now)
        if isinstance(o, fsm.ReleaseMission):
            return self._release(o.mission_id, ctx, now)
        if isinstance(o, fsm.StandDown):
            self.missions.pop(o.mission_id, None)
            self.roster.close()
            self.manager.stop()
            return [Note(logging.INFO, f"mission {o.mission_id}: standing down ({o.reason})")]
        if isinstance(o, fsm.MissionFinished):
            return self._finished(o.mission_id, now)
        if isinstance(o, fsm.Shutdown):
            return [SetActive(False)]
        if isinstance(o, fsm.Deactivated):
            self.manager.stop()
            return [
                Release(Owner.OPERATOR),
                Note(logging.INFO, f"state machine deactivated: {o.reason}"),
            ]
        return []  # MissionStarted, Activated, Resume: nothing to carry out

    def _begin_plan(self, o: fsm.BeginPlan, now: float) -> list[ModuleOutput]:
        mission = self.missions.get(o.mission_id)
        if mission is None:
            self.roster.close()
        elif not o.replan:
            self.roster.open(o.mission_id, mission.selection)
        self._replanning = o.replan and mission is not None and self.roster.frozen
        if self._replanning:
            self.roster.rollback()  # a replan not agreed yet is made again from there
            self.manager.begin_replan(now)
        else:
            self.manager.plan(o.mission_id)
        return [Release(Owner.OPERATOR)]  # the state machine decides the next flight

    def _finished(self, mid: int, now: float) -> list[ModuleOutput]:
        mission = self.missions.pop(mid, None)
        handed = self.regroup.take_over(mid)  # an emptied fleet's mission handed to ours
        if handed is not None:
            self.missions[handed.mission.mission_id] = handed.mission
            self.fsm.post(fsm.NewMission(handed.mission.mission_id))
        out: list[ModuleOutput] = [Ended(mid)]
        if mid in self.idle_in:  # no share flown: not a MISSION_COMPLETE of ours
            self.idle_in.discard(mid)
            return [*out, Note(logging.INFO, f"mission {mid}: done; we had nothing to fly")]
        if mission is not None:
            alert = Alert(
                self.self_id,
                max(0.0, now),
                Severity.INFO,
                AlertCode.MISSION_COMPLETE,
                f"mission {mid}",
            )
            out.append(Publish(alert))
        return out

    def _fleet_ready(self, ctx: Context) -> bool:
        """The roster is settled (every live peer that may be addressed has answered)
        and every live member has reached PLAN for the same mission (or already left it
        for GO_MISSION: a fast member must not strand the others). Members that are
        lost do not hold the fleet back (roster.py)."""
        mid = self.fsm.mission_id
        if self.fsm.state != FsmState.PLAN or mid is None:
            return False
        if mid == fsm.RETURN_MISSION:
            return True  # each vehicle plans its own way back (no landing sequencing yet)
        if self._replanning and self.roster.frozen:
            return self.roster.ready_to_replan(ctx.peers)
        if self.regroup.joining == mid:  # a joiner: the fleet's lineage with it in
            return mid in self.regroup.offered
        if mid in self.regroup.adopting:  # an emptied fleet's mission, handed to ours
            return True
        return self.roster.ready(ctx.peers)

    # ------------------------------------------------------------------ the fleet plans
    def _release(self, mission_id: int, ctx: Context, now: float) -> list[ModuleOutput]:
        """The fleet is synchronised: hand the mission to the mission manager (the
        return-to-base mission: fly back to base and land)."""
        if mission_id == fsm.RETURN_MISSION:
            return self._return(ctx, now)
        mission = self.missions.get(mission_id)
        if mission is None:
            self.fsm.post(fsm.PlanFailed(mission_id, "unknown mission"))
            return []
        if self._replanning and self.roster.frozen:
            # the peers hold their replans until ours carries the same roster hash
            return [*self._replan(mission, ctx, now), PublishInfo()]
        if self.regroup.joining == mission_id or mission_id in self.regroup.adopting:
            return self._join(mission_id, ctx, now)
        if mission.selection.kind == SelectorKind.QUANTITY:  # idle candidates: vote first
            electorate = self.roster.freeze(ctx.peers)
            self.manager.vote()
            me, lead = _candidate(self.profile, ctx.autopilot), _lead(mission, ctx.peers)
            start = self.tasking.start(mission, electorate, (), me, now, home=None, lead=lead)
            return self._tasked(start, ctx, now)
        self.roster.freeze(ctx.peers)
        return self._plan(mission, ctx, now)

    def _plan(self, mission: Mission, ctx: Context, now: float) -> list[ModuleOutput]:
        """Plan `mission` for the roster's flying members."""
        mid = mission.mission_id
        members, unknown = self._members(ctx)
        if unknown:
            self.fsm.post(
                fsm.PlanFailed(mid, short_text(f"no profile for fleet members {unknown}"))
            )
            return [Note(logging.ERROR, f"cannot plan mission {mid}: no profile for {unknown}")]
        self.regroup.founded(mission, members)
        zones = ctx.zones.no_fly(now)
        return self.manager.release(mission, members, zones, ctx.autopilot, now)

    def _replan(self, mission: Mission, ctx: Context, now: float) -> list[ModuleOutput]:
        """Mission inheritance (paper Fig. 14 and 17): what is left of the fleet plan,
        from every member's published progress along its share, shared among the
        survivors, each posed where its progress puts it on its share (inputs every
        survivor has the same: no leader)."""
        base = self.manager.fleet_plan
        survivors = self.roster.survivors(ctx.peers)
        progress, flown = self.progress_now()
        members: list[Member] = []
        for vid in survivors:
            profile = self._profile_of(vid, ctx)
            if profile is None:
                continue
            members.append(
                Member(
                    profile,
                    pose_on(base, vid, progress) if base else None,
                    heading_deg=heading_on(base, vid, progress) if base else None,
                )
            )
        self.roster.replanned(survivors)
        battery = lineage_battery(  # on the lineage's grid: a joiner replays it exactly
            replan_battery(base, members, progress, flown, mission.params.altitude_rel_m)
            if base is not None
            else {}
        )
        took_in = self.regroup.replanned(
            mission.mission_id, [m.profile.vehicle_id for m in members], progress, battery
        )
        zones = ctx.zones.no_fly(now)
        merge = self._merge_inputs(mission.mission_id)
        if merge:  # a healed partition: every part's plan in one (battery: not modelled)
            battery = {}
        out = self.manager.replan(
            mission, members, progress, zones, ctx.autopilot, now, battery, merge=merge
        )
        lineage = self.regroup.lineages.get(mission.mission_id)
        if took_in and lineage is not None:  # a vehicle joins: it needs how the plan came to be
            out.append(Publish(lineage.message(self.self_id, self.roster.members_hash)))
        return out

    def progress_now(self) -> tuple[dict[int, float], dict[int, float]]:
        """Every member's metres along its share of the fleet plan and the metres it flew
        before the last replan, from what each published (held while replanning: the
        same everywhere), ours as we publish it: at the radio's resolution, as the
        others hear it (mission/published.py)."""
        base = self.manager.fleet_plan
        progress: dict[int, float] = {}
        flown: dict[int, float] = {}  # metres flown before the last replan
        if base is not None:
            sortie = self.manager.sortie
            for vid in base.roster:
                if vid not in base.shares:
                    continue
                p, path = (
                    published_progress(sortie.progress_m, sortie.path_m)
                    if vid == self.self_id
                    else self.roster.progress_of(vid)
                )
                progress[vid], flown[vid] = along_share(base.shares[vid].length_m, p, path)
        return progress, flown

    def _members(self, ctx: Context) -> tuple[list[Member], list[int]]:
        """The fleet as the planners see it: profiles from the database, homes from the
        members' VehicleInfo (the same on every node). Lost members are left out;
        members whose profile is unknown are returned apart (planning without them
        would send two vehicles over the same ground)."""
        battery = self.roster.plan_battery
        home = published_home(ctx.autopilot.home)  # as the others hear it
        out = [Member(self._own_profile(ctx), home, battery.get(self.self_id))]
        unknown = []
        for vid in self.roster.flying:
            if vid == self.self_id:
                continue
            peer = ctx.peers.get(vid)
            if peer is None or not peer.present:
                continue
            profile = self._profile_of(vid, ctx)
            if profile is None:
                unknown.append(vid)
                continue
            out.append(Member(profile, peer.info.home if peer.info else None, battery.get(vid)))
        return out, unknown

    def _own_profile(self, ctx: Context) -> VehicleProfile:
        """Our profile as every node plans with it: the battery our autopilot says it
        has, as we publish it in VehicleInfo."""
        own = published_capacity_mah(ctx.autopilot.battery_capacity_mah)
        return with_autopilot_battery(self.profile, own)

    def _profile_of(self, vid: int, ctx: Context) -> VehicleProfile | None:
        """A member's profile as every node plans with it: the database's, with the
        battery its autopilot says it has (published in VehicleInfo)."""
        if vid == self.self_id:
            return self._own_profile(ctx)
        profile = self.fleet_profiles.get(vid)
        if profile is None:
            return None
        peer = ctx.peers.get(vid)
        capacity = peer.info.battery_capacity_mah if peer is not None and peer.info else 0
        return with_autopilot_battery(profile, capacity)

    def _return(self, ctx: Context, now: float) -> list[ModuleOutput]:
        return self.manager.start_return(ctx.autopilot, ctx.zones.no_fly(now), now)

    # ------------------------------------------------------------------ missions in force
    def _candidate(self, mission: Mission, ctx: Context, now: float) -> list[ModuleOutput]:
        """A QUANTITY mission, sent or derived from a target report, past the acceptance
        checks: are we a candidate (tasking's), then the vote: a flying fleet votes at
        once, idle vehicles synchronise in PLAN first (mission/tasking.py)."""
        st = self._standing(ctx)
        reason, text = self.tasking.answer(mission, st)
        ok = reason == AckReason.OK
        mid = mission.mission_id
        ack = Ack(
            self.self_id, mission.issuer_id, AckRef.MISSION, mid, ok, reason, short_text(text)
        )
        out: list[ModuleOutput] = [Answer(ack) if ok else Publish(ack)]
        if not ok:
            return out
        if st.flying is not None:
            electorate, lost = self.tasking.electorate(mission, st)
            lead = _lead(mission, ctx.peers)
            start = self.tasking.start(
                mission, electorate, lost, st.me, now, home=st.flying, lead=lead
            )
            return out + self._tasked(start, ctx, now)
        self.missions[mid] = mission
        self.fsm.post(fsm.NewMission(mid))
        return out

    def _standing(self, ctx: Context) -> Standing:
        r, f = self.roster, self.fsm
        flying, replanning = None, False
        if (
            r.frozen
            and r.mission_id is not None
            and r.mission_id > 0
            and f.mission_id == r.mission_id
        ):
            flying = r.mission_id
            replanning = f.state != FsmState.GO_MISSION or self.mission_state not in (
                MissionState.PREMISSION,
                MissionState.MISSION,
            )
        present = {v: p for v, p in ctx.peers.items() if p.present and not p.is_ground_station}
        return Standing(
            self.self_id,
            ctx.fleet_id,
            _candidate(self.profile, ctx.autopilot),
            idle=f.state == FsmState.GO_MISSION and f.mission_id is None and ctx.active,
            flying=flying,
            replanning=replanning,
            fleet=r.planned,
            away=frozenset(
                v
                for v in r.planned
                if v not in r.flying or (v != self.self_id and v not in present)
            ),
            peer_fleets={v: p.fleet_id for v, p in present.items()},
            peer_missions={
                v: p.mission_id
                for v, p in present.items()
                if p.mission_id > 0 and p.fsm_state in (FsmState.PLAN, FsmState.GO_MISSION)
            },
        )

    # ------------------------------------------------------------------ messages
    def on_message(
        self, msg: Ack | Vote | TargetReport | PlanLineage, read: Read, now: float
    ) -> list[ModuleOutput]:
        """The peers' answers to missions (the roster), votes and target reports
        (tasking), how a fleet's plan came to be (regroup)."""
        match msg:
            case Ack():
                self.roster.on_ack(msg)
                return []
            case PlanLineage():
                self.regroup.on_lineage(msg)
                if self.heal.on_lineage(msg, self.roster.members_hash):  # a healed partition
                    return self._heal(msg.mission.mission_id, read(), now)
                return []
            case Vote() | TargetReport():
                return self._tasked(self.tasking.handle(msg, now), read(), now)
            case _:
                assert_never(msg)

    # ------------------------------------------------------------------ tasking

    def on_timer(self, read: Read, now: float) -> list[ModuleOutput]:
        """Tasking's deadlines (a vote's, a target's gathering) and reattach's."""
        due, out = self.tasking.next_deadline(), self._unanswered_due(now)
        if due is not None and now >= due:
            out += self._tasked(self.tasking.on_timer(now), read(), now)
        out += self._hold_over(now)
        if not self.reattach.active:
            return out
        ctx = read()
        peers = sorted(ctx.peers.values(), key=lambda p: p.node_id)
        infos = [p.info for p in peers if p.present and p.info is not None]
        decision, said = self.reattach.on_timer(ctx.autopilot, infos, self.fsm.state, now)
        out += said
        return out + ([] if decision is None else self._reattached(decision, ctx))

    def _tasked(self, outs: list[TaskingOutput], ctx: Context, now: float) -> list[ModuleOutput]:
        out: list[ModuleOutput] = []
        for o in outs:
            if isinstance(o, Publish | Note):
                out.append(o)
            elif isinstance(o, Derived):  # taken as a QUANTITY mission heard
                out.append(Heard(o.mission))
            elif isinstance(o, Elected):
                out += self._elected(o, ctx, now)
            elif (
                isinstance(o, VoteFailed) and o.home is None and self.fsm.mission_id == o.mission_id
            ):
                self.fsm.post(fsm.Unassigned(o.mission_id, "vote failed"))
        return out

    def _elected(self, e: Elected, ctx: Context, now: float) -> list[ModuleOutput]:
        """The vote decided: winners fly the mission as a new fleet (selected by their
        ids); a flying fleet's others lose them ("voted out") and replan; idle vehicles
        not chosen stand down."""
        mid, winners = e.mission.mission_id, e.outcome.winners
        if e.home is None:  # idle vehicles synchronised in PLAN for it
            if self.fsm.mission_id != mid or self.fsm.state != FsmState.PLAN:
                return []
            if not e.goes:
                self.fsm.post(fsm.Unassigned(mid, "not chosen"))
                return []
            self.missions[mid] = e.mission
            self.roster.elected(winners)
            self.manager.elected()
            return self._plan(e.mission, ctx, now)
        if e.goes:
            if self.fsm.mission_id == e.home:
                self.missions.pop(e.home, None)  # left for the new mission, not completed
            self.missions[mid] = e.mission
            self.fsm.post(fsm.NewMission(mid))
            out: list[ModuleOutput] = [
                Note(logging.INFO, f"leaving mission {e.home} for mission {mid}")
            ]
            if not e.outcome.stayers and self.self_id == min(winners):
                text = f"mission {e.home} left unfinished: its fleet went to {mid}"
                alert = Alert(
                    self.self_id,
                    max(0.0, now),
                    Severity.WARNING,
                    AlertCode.MISSION_FAILED,
                    short_text(text),
                )
                out.append(Publish(alert))
            return out
        if self.roster.mission_id == e.home:
            return self._roster_events(self.roster.voted_out(winners), ctx, now)
        return []

    # ------------------------------------------------------------------ add and swap
    def heard_mission(self, mission: Mission) -> None:
        self.regroup.heard_mission(mission)  # a vehicle may be told to join it later

    def _regroup(self, cmd: Command, ctx: Context, now: float) -> list[ModuleOutput]:
        """JOIN_MISSION / SWAP_MISSION (swarm/regroup.py): the vehicle leaves what it
        flies and joins the other fleet, which takes it in with a replan and tells it how
        its plan came to be; a swap that empties a fleet hands its mission over."""
        st, home, state = self._standing(ctx), ctx.autopilot.home, self.fsm.state
        reason, text, to = AckReason.OK, "", 0
        if home is None or ctx.base is None:
            reason = AckReason.HOME_NOT_SET if home is None else AckReason.NO_BASE
        elif state == FsmState.EMERGENCY:
            reason = AckReason.EMERGENCY
        elif not ctx.ready or state == FsmState.INACTIVE:
            reason = AckReason.NOT_READY
        elif st.replanning:
            reason, text = AckReason.BUSY, f"replanning mission {st.flying}"
        else:
            reason, text, to = self.regroup.answer(cmd, st.flying, st.idle)
        ok = reason == AckReason.OK
        ack = Ack(
            self.self_id, cmd.issuer_id, AckRef.COMMAND, cmd.seq, ok, reason, short_text(text)
        )
        out: list[ModuleOutput] = [Answer(ack)]
        if not ok:
            return out
        heard = self.regroup.heard[to]
        mission = with_defaults(heard, self.mission_defaults.get(heard.mission_type, {}))
        if st.flying is not None:
            if cmd.kind == CommandKind.SWAP_MISSION and self._emptied(cmd, st.flying, to, ctx):
                out += self._hand_over(st.flying, to)
            self.missions.pop(st.flying, None)  # left, not completed
        self.missions[to] = mission
        self.regroup.joining = to
        self.fsm.post(fsm.NewMission(to))
        return [*out, Note(logging.INFO, f"joining mission {to}'s fleet")]

    def _emptied(self, cmd: Command, ours: int, theirs: int, ctx: Context) -> bool:
        missions = {v: p.mission_id for v, p in ctx.peers.items() if p.present}
        return self.regroup.emptied(cmd, self.roster.flying, missions, theirs)

    def _hand_over(self, ours: int, theirs: int) -> list[ModuleOutput]:
        """Our fleet is emptied: its lineage, with the progress we leave at, goes to the
        fleet of `theirs` (the paper's SENDING_MISSION)."""
        msg = self.regroup.hand_over(ours, theirs, self.progress_now()[0], self.roster.members_hash)
        if msg is None:
            return [Note(logging.WARNING, f"mission {ours}: no plan to hand over")]
        text = f"mission {ours}: emptied, handed to mission {theirs}'s fleet"
        return [Note(logging.INFO, text), Publish(msg)]

    def _join(self, mid: int, ctx: Context, now: float) -> list[ModuleOutput]:
        """Fly the plan of the fleet we join (or an emptied fleet's, handed to ours),
        made again from its lineage."""
        try:
            msg, lineage, replay = self.regroup.join(mid, self.fleet_profiles)
        except KeyError as exc:
            self.fsm.post(fsm.PlanFailed(mid, short_text(f"no profile for fleet member {exc}")))
            return []
        self.missions[mid] = msg.mission
        self.roster.adopt(mid, lineage.everyone, lineage.members, len(lineage.steps))
        zones = ctx.zones.no_fly(now)
        return self.manager.release(
            msg.mission, replay.first, zones, ctx.autopilot, now, lineage=replay
        )

    # ------------------------------------------------------------------ the roster
    def on_info(self, info: VehicleInfo, read: Read, now: float) -> list[ModuleOutput]:
        events = self.roster.on_info(info)
        back = self._back(info)
        out = back + (self._roster_events(events, read(), now) if events else [])
        r = self.roster
        if (
            info.vehicle_id in r.lost
            and info.mission_id == r.mission_id
            and info.fsm_state == FsmState.GO_MISSION
            and info.members_hash not in (0, r.members_hash)
            and not events
        ):  # a part met while we could not heal yet (replanning): met again now
            ev = RosterMismatch(info.mission_id, info.vehicle_id, info.members_hash, r.members_hash)
            out += self._meet(ev, read(), now)
        return out

    def _replans(self, mission_id: int) -> bool:
        """A member lost now makes this vehicle replan `mission_id`."""
        f = self.fsm
        return (
            self.roster.frozen
            and f.mission_id == mission_id
            and f.state in (FsmState.GO_MISSION, FsmState.PLAN)
            and self.mission_state in REPLANNING
        )

    def _hold(self, ev: MemberLost, now: float) -> list[ModuleOutput]:
        """A member fallen silent (its node's liveliness or telemetry gone) is still an
        aircraft: its autopilot flies its share on until its GCS failsafe takes it home
        (failsafe.py). Its share is held, not handed out, for `silent_hold_s`; the
        others fly their own meanwhile. Heard again in its mission with our roster
        within the hold, it is a member again and flies on (`_back`)."""
        self.held[ev.vehicle_id] = (ev.mission_id, now + self.silent_hold_s)
        text = (
            f"mission {ev.mission_id}: member {ev.vehicle_id} silent ({ev.why}); "
            f"its share held {self.silent_hold_s:g} s"
        )
        out: list[ModuleOutput] = [Note(logging.WARNING, text)]
        base = self.manager.fleet_plan
        if base is not None:  # avoidance predicts it along what it still flies
            points, speed = route_ahead(base, ev.vehicle_id, self.progress_now()[0])
            if points:
                out.append(SilentShare(ev.vehicle_id, points, speed))
        return out

    def _hold_over(self, now: float) -> list[ModuleOutput]:
        """Held shares whose hold ran out: the member did not come back, its failsafe
        has taken its aircraft off its lanes; the fleet replans them."""
        out: list[ModuleOutput] = []
        for vid, (mid, until) in list(self.held.items()):
            if now < until:
                continue
            del self.held[vid]
            if vid in self.roster.lost and self._replans(mid):
                text = f"mission {mid}: member {vid} still silent; its share handed out"
                out += [Note(logging.WARNING, text), Post(fsm.Replan(mid))]
        return out

    def _back(self, info: VehicleInfo) -> list[ModuleOutput]:
        """A held member heard again: flying our roster, a member again; left the
        mission (its node handed the share on, or took it home), its share is the
        fleet's now; restarting (no mission yet), still held."""
        vid = info.vehicle_id
        held = self.held.get(vid)
        if held is None:
            return []
        mid = held[0]
        if info.fsm_state == FsmState.INACTIVE or not info.mission_id:
            return []  # a node restarting: its reattach decides (reattach.py), then says
        if info.mission_id != mid or info.fsm_state not in (FsmState.GO_MISSION, FsmState.PLAN):
            del self.held[vid]
            if not self._replans(mid):
                return []
            text = f"mission {mid}: member {vid} back, out of the mission; its share handed out"
            return [Note(logging.WARNING, text), Post(fsm.Replan(mid))]
        if info.fsm_state != FsmState.GO_MISSION or info.members_hash != self.roster.members_hash:
            return []
        del self.held[vid]
        self.roster.back(vid)
        text = f"mission {held[0]}: member {vid} back within the hold; it flies its share on"
        return [Note(logging.INFO, text)]

    def peer_lost(self, vid: int, why: str, read: Read, now: float) -> list[ModuleOutput]:
        events = self.roster.on_peer_left(vid, why)
        return self._roster_events(events, read(), now) if events else []

    def _roster_events(
        self, events: list[RosterEvent], ctx: Context, now: float
    ) -> list[ModuleOutput]:
        out: list[ModuleOutput] = []
        f = self.fsm
        for ev in events:
            if isinstance(ev, MemberLost):
                self.lost_members.append(ev)
                del self.lost_members[:-20]
                text = f"mission {ev.mission_id}: member {ev.vehicle_id} lost ({ev.why})"
                out.append(Note(logging.WARNING, text))
                out += self._tasked(self.tasking.handle(VoterLost(ev.vehicle_id), now), ctx, now)
                if not self._replans(ev.mission_id):
                    continue
                if ev.why in SILENT and self.silent_hold_s > 0 and f.state == FsmState.GO_MISSION:
                    out += self._hold(ev, now)
                else:
                    out.append(Post(fsm.Replan(ev.mission_id)))  # inherit its share
            elif isinstance(ev, MemberJoined):
                if (
                    f.mission_id == ev.mission_id
                    and f.state in (FsmState.GO_MISSION, FsmState.PLAN)
                    and self.mission_state in REPLANNING
                ):
                    self.roster.join(ev.vehicle_id)
                    text = f"mission {ev.mission_id}: vehicle {ev.vehicle_id} joins"
                    out += [
                        Note(logging.INFO, text),
                        Post(fsm.Replan(ev.mission_id)),  # share what is left with it
                    ]
            elif isinstance(ev, RosterMismatch):  # an alert, once per member and hash
                out += self._mismatch(ev, now)
                out += self._meet(ev, ctx, now)
        return out

    def _mismatch(self, ev: RosterMismatch, now: float) -> list[ModuleOutput]:
        r, f = self.roster, self.fsm
        if (
            dropped(self.self_id, ev.mission_id, r.planned, r.generation, ev.theirs)
            and f.state == FsmState.GO_MISSION
            and f.mission_id == ev.mission_id
        ):  # the fleet replanned our share away while we were stopped
            text = f"mission {ev.mission_id}: the fleet replanned without us; handing the share on"
            return [
                Post(fsm.LeftFleet("the fleet replanned without this vehicle")),
                Note(logging.WARNING, text),
            ]
        text = (
            f"mission {ev.mission_id}: vehicle {ev.vehicle_id} flies roster "
            f"{ev.theirs:#06x}, ours {ev.ours:#06x}"
        )
        alert = Alert(
            self.self_id,
            max(0.0, now),
            Severity.WARNING,
            AlertCode.ROSTER_MISMATCH,
            short_text(text),
        )
        return [Note(logging.ERROR, text), Publish(alert)]

    # ------------------------------------------------------------------ a partition heals
    def _healable(self, mid: int) -> bool:
        f, mission = self.fsm, self.missions.get(mid)
        return (
            mission is not None
            and mission.mission_type == MissionType.AREA
            and f.state == FsmState.GO_MISSION
            and f.mission_id == mid
            and self.roster.frozen
            and mid in self.regroup.lineages
            and self.mission_state in REPLANNING
        )

    def _meet(self, ev: RosterMismatch, ctx: Context, now: float) -> list[ModuleOutput]:
        """A member lost by silence flies our mission under another roster: the parts
        of a partition meet again (swarm/heal.py). Our part's lineage for theirs, once."""
        mid, r = ev.mission_id, self.roster
        if ev.vehicle_id not in r.lost or not self._healable(mid):
            return []
        if dropped(self.self_id, mid, r.planned, r.generation, ev.theirs):
            return []  # they replanned our share away: we hand it on (`_mismatch`)
        out: list[ModuleOutput] = []
        if self.heal.meet(mid, ev.theirs):
            lineage = self.regroup.lineages[mid]
            out.append(Publish(lineage.message(self.self_id, self.roster.members_hash)))
        return out + self._heal(mid, ctx, now)

    def _heal(self, mid: int, ctx: Context, now: float) -> list[ModuleOutput]:
        """Every other part's lineage held: their members join again and the fleet
        replans one plan of what none of the parts flew."""
        r = self.roster
        if mid in self._merging and not r.merging:
            del self._merging[mid]  # the last heal was agreed
        if mid in self._merging or not self._healable(mid):
            return []
        live = [
            v
            for v in r.lost
            if v in ctx.peers
            and ctx.peers[v].present
            and ctx.peers[v].info is not None
            and ctx.peers[v].info.mission_id == mid  # type: ignore[union-attr]
        ]
        hashes = {v: h for v, h in r.hashes.items() if h not in (0, r.members_hash)}
        parts = self.heal.parts(mid, hashes, live)
        if parts is None:
            return []
        others = {v for p in parts for v in Lineage.of(p).members}
        own = self.regroup.lineages[mid]
        generation = max(len(own.steps), *(len(p.replans) for p in parts))
        r.merge(others, generation, (p.members_hash for p in parts))
        self._merging[mid] = parts
        text = (
            f"mission {mid}: partition healed; merging with {sorted(others)} "
            f"(rosters {', '.join(f'{p.members_hash:#06x}' for p in parts)})"
        )
        return [Note(logging.WARNING, text), Post(fsm.Replan(mid))]

    def _merge_inputs(
        self, mid: int
    ) -> tuple[tuple[Replay, Mapping[int, tuple[float, float]]], ...]:
        """The other parts to merge with: each one's lineage made into planning inputs
        and its members' published progress (empty: nothing to merge)."""
        parts = self._merging.get(mid, ())
        if not parts:
            return ()
        if not self.roster.merging:  # agreed (roster.settle): merged
            del self._merging[mid]
            return ()
        profiles = {**self.fleet_profiles, self.self_id: self.profile}
        out = []
        for p in parts:
            lineage = Lineage.of(p)
            try:
                replay = lineage.replay(profiles)
            except KeyError:
                return ()  # a member with no profile: the parts keep their plans
            out.append((replay, {v: self.roster.progress_of(v) for v in lineage.members}))
        self.heal.done(mid)
        return tuple(out)

    # ------------------------------------------------------------------ a restart in flight
    def restored(self, record: SortieRecord | None, now: float) -> None:
        """The node starts (its database read): the share it was flying; its vehicle
        may be flying it (reattach.py)."""
        self.record = record
        self.reattach.start(record, now)

    def keep_record(self, now: float) -> bool:
        """The share flown now, stored when it changes (not its progress): a node that
        restarts in flight reattaches with it (reattach.py). Whether the record changed
        (since last asked)."""
        changed, self._record_changed = self._record_changed, False
        if self.reattach.active:
            return changed  # the record restored at start is the one to decide with
        m, r = self.manager, self.roster
        flying = m.phase == Phase.FLYING
        if self.record is None and not flying:
            return changed  # no share flown, none recorded: nothing to keep (most inputs)
        if (
            m.phase == Phase.STARTING
            and self.record is not None
            and m.mission_id == self.record.mission_id
        ):
            # a replan in the air, its share not flown yet (an avoidance manoeuvre may
            # hold its upload): the autopilot still holds the share on record, the one
            # a restart now must decide with (reattach.py)
            return changed
        rec = sortie_record(
            mission_id=m.mission_id,
            flying=flying,
            members=r.members,
            planned=r.planned,
            generation=r.generation,
            members_hash_=r.members_hash,
            items=m.items,
            last_item=m.last_item,
            path_m=m.sortie.path_m,
            progress_m=m.sortie.progress_m,
            now=now,
        )
        if not same_share(rec, self.record):
            self.record = rec
            return True
        return changed

    def _reattached(self, decision: Decision, ctx: Context) -> list[ModuleOutput]:
        """Carry out the reattach decision (reattach.py), with the mission on record
        (the declarations')."""
        rec = self.record
        if decision == Decision.HAND_ON:
            self.record = None
            self._record_changed = True
            return [Post(fsm.LeftFleet("share handed on after a restart"))]
        if decision != Decision.CONTINUE or rec is None:
            return []
        mission, why = ctx.on_record(rec.mission_id)
        if mission is None:  # not stored, or ended: the vehicle goes home
            return [Post(fsm.LeftFleet(why))]
        self.missions[mission.mission_id] = mission
        r = self.roster
        r.open(mission.mission_id, mission.selection)
        r.members, r.planned, r.generation = rec.members, rec.planned, rec.generation
        self.manager.reattach(rec.mission_id, rec.items, rec.last_item, rec.path_m, rec.progress_m)
        return [Post(fsm.Reattached(rec.mission_id))]

    # ------------------------------------------------------------------ the mission manager
    def on_autopilot(
        self, ap: AutopilotState, base: GeoPoint | None, now: float
    ) -> list[ModuleOutput]:
        out = self._rebooted(ap)
        out += self.manager.on_autopilot(ap, now, self.roster, base=base)
        return out + self.reattach.on_autopilot(ap, now)

    def _rebooted(self, ap: AutopilotState) -> list[ModuleOutput]:
        """A reboot while planning or flying a mission: the autopilot forgot what it was
        told and boots disarmed. Nothing the mission manager still holds (a share, a
        take-off queued, a replan to come) may arm it again: it stops at once, and the
        state machine takes the vehicle out of its fleet and the mission (`Rebooted`)."""
        seen, self._reboots = self._reboots, ap.reboots
        if ap.reboots <= seen:
            return []
        if (
            self.fsm.state not in (FsmState.PLAN, FsmState.GO_MISSION)
            or self.fsm.mission_id is None
        ):
            return []  # idle: nothing planned or flown to leave
        self.manager.stop()
        self.fsm.post(fsm.Rebooted())
        text = f"autopilot rebooted in {self.fsm.state.name}: leaving the fleet"
        return [Release(Owner.MISSION), Note(logging.WARNING, text)]

    def distrust(self, ids: frozenset[int]) -> None:
        """Vehicles whose identity is in doubt (two sources in one name): the roster
        keeps them out of new rosters, so out of voting and planning."""
        self.roster.distrust(ids)

    def on_plan(self, outcome: PlanOutcome, ap: AutopilotState, now: float) -> list[ModuleOutput]:
        """The fleet's plan: the verdict on an operator's mission first (the same on
        every node: each plans the whole fleet from the same inputs), then our share."""
        mid = self.fsm.mission_id
        pending = None if self._replanning or mid is None else self.unanswered.get(mid)
        if pending is None or mid is None:
            return self.manager.on_plan(outcome, ap, now, self.roster)
        outcome = fleet_verdict(outcome)
        out = self.manager.on_plan(outcome, ap, now, self.roster)
        if not out:  # an abandoned job's outcome: not this mission's plan
            return out
        del self.unanswered[mid]
        mission = pending[0]
        plan = outcome.plan
        if plan is None:
            ack = self._verdict(mission, False, AckReason.PLAN_FAILED, outcome.error, outcome)
            return [Answer(ack), *out]
        text = f"plan {plan.digest()}"
        if self.self_id in plan.roster and not _flies(plan.share(self.self_id).waypoints):
            # the split left us nothing (docs/paper-choices.md): we stay on our pad
            self.idle_in.add(mid)
            text += ": nothing to fly here, stays on its pad"
        return [Answer(self._verdict(mission, True, AckReason.OK, text, outcome)), *out]

    def _verdict(
        self, mission: Mission, ok: bool, reason: AckReason, text: str, outcome: PlanOutcome
    ) -> Ack:
        return Ack(
            self.self_id,
            mission.issuer_id,
            AckRef.MISSION,
            mission.mission_id,
            ok,
            reason,
            short_text(text),
            None if ok else outcome.detail,
        )

    def _replaced(self, mid: int) -> list[ModuleOutput]:
        """A newer mission replaces one not answered yet (the state machine plans the
        newest): that one is refused, naming the newer."""
        out: list[ModuleOutput] = []
        for old, (mission, _) in list(self.unanswered.items()):
            if old == mid:
                continue
            del self.unanswered[old]
            text = f"replaced by mission {mid} before its plan"
            out.append(
                Answer(self._verdict(mission, False, AckReason.BUSY, text, PlanOutcome(0, None)))
            )
        return out

    def _unanswered_due(self, now: float) -> list[ModuleOutput]:
        """Missions whose plan never came: refused, with what became of them."""
        out: list[ModuleOutput] = []
        for mid, (mission, due) in list(self.unanswered.items()):
            if now < due:
                continue
            del self.unanswered[mid]
            text = f"no fleet plan after {self.plan_timeout_s:g} s"
            ack = self._verdict(mission, False, AckReason.TIMEOUT, text, PlanOutcome(0, None))
            out.append(Answer(ack))
        return out

    def on_result(self, owner: Owner, result: ApResult, now: float) -> list[ModuleOutput]:
        """A result of the mission manager's request (MISSION) or reattach's (REATTACH)."""
        if owner == Owner.REATTACH:
            return self.reattach.on_result(result, now)
        return self.manager.on_result(result, now)

    def on_suspended(self, on: bool, now: float) -> list[ModuleOutput]:
        return self.manager.on_suspended(on, now)

    def pads_tick(self, ap: AutopilotState, now: float) -> list[ModuleOutput]:
        return self.manager.pads_tick(ap, now)

    def on_peer_status(self, status: VehicleStatus, now: float) -> None:
        self.manager.on_peer_status(status, now)  # MUM-T: the lead's telemetry


def fleet_verdict(outcome: PlanOutcome) -> PlanOutcome:
    """The fleet's plan as every member judges it: flyable only when every member's
    share is (a share with nothing to fly is one only where the split may leave a member
    on its pad: an AREA). Every node holds the same plan, so every node refuses the same
    way, naming the member."""
    plan = outcome.plan
    if plan is None or plan.mission.mission_type == MissionType.AREA:
        return outcome
    for vid in plan.roster:
        if not _flies(plan.share(vid).waypoints):
            return PlanOutcome(outcome.job_id, None, f"planning: nothing to fly for vehicle {vid}")
    return outcome


def _flies(waypoints: Sequence[Waypoint]) -> bool:
    return any(w.kind == ItemKind.WAYPOINT for w in waypoints)


def _candidate(profile: VehicleProfile, ap: AutopilotState) -> Candidate:
    at = None if ap.lat_deg is None or ap.lon_deg is None else LatLon(ap.lat_deg, ap.lon_deg)
    battery = float(ap.battery_pct) if ap.battery_pct >= 0 else None
    return Candidate.of(profile, at, battery)


def _lead(mission: Mission, peers: Mapping[int, Peer]) -> LatLon | None:
    peer = peers.get(mission.params.lead_vehicle_id)
    st = peer.status if peer is not None else None
    return LatLon(st.lat_deg, st.lon_deg) if st is not None else None
