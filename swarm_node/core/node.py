"""The vehicle node as one pure object: a router between vehicle monitoring, the swarm
manager (membership, roster, acceptance checks, VehicleInfo), the state machine, the
command manager, the mission manager and the fence keeper.

The runtime (swarm_node.runtime.node) feeds it inputs from Zenoh and the autopilot link
and carries out its outputs; tests and fast-time simulations join several NodeCores
with an in-memory bus and jump time from deadline to deadline.

    core.handle(input, now) -> list[Output]
    core.on_timer(now)      -> list[Output]
    core.next_deadline()    -> float

Routes (every input is matched; an unknown one is counted in `unhandled`, never
dropped silently):

    AutopilotUpdate        -> monitoring, mission manager, fence keeper (and, at the
                              5 Hz tick, avoidance: own state, ADS-B traffic)
    AutopilotResult        -> AutopilotArbiter -> its owner: command manager (OPERATOR),
                              mission manager (MISSION), fence keeper (FENCE),
                              emergency procedure (EMERGENCY: a refusal is alerted),
                              avoidance (AVOIDANCE, and its pad landing steps)
    PeerAlive              -> membership -> roster (MemberLost), avoidance (forget)
    BadInput               -> counted, logged
    IdentityNews           -> monitoring (this vehicle's identity conflict: an alert,
                              not ready), roster (untrusted peers: not members)
    Received(VehicleStatus)-> membership, avoidance (a contact)
    Received(VehicleInfo)  -> membership, roster (answers, MemberLost, hash mismatch),
                              avoidance (the contact's type)
    Received(Ack)          -> roster (the peers' answers to missions)
    Received(Command)      -> command manager -> effects, autopilot requests (OPERATOR)
    Received(Mission)      -> acceptance checks -> state machine (NewMission)
    Received(NoFlyZone)    -> monitoring's zones, fence keeper
    Received(FleetAssignment) -> fleet id
    Received(Mission QUANTITY | Vote | TargetReport) -> tasking (mission/tasking.py): the
                              vote, re-tasking; its outcome -> roster, state machine
    Received(Command JOIN_MISSION | SWAP_MISSION), Received(PlanLineage)
                           -> regroup (swarm/regroup.py): add and swap; both carried
                              out by FleetChanges (fleet_changes.py)
    PlanDone               -> mission manager (the plan job's outcome: fly the share)
    Learned(DeclaredState) -> the declared book (declared.py): newer zones, base, fleet
                              applied (from the node's database at start, or a peer)
    StoreResult            -> a failed store of the declared state is alerted once
    Received(Alert | SwarmView) -> declared, not used (counted)

Modules answer in one vocabulary (outputs.py): Publish, Submit(owner, request),
Post(fsm event), Note; the router posts events to the state machine, passes requests
through the arbiter (precedence EMERGENCY > AVOIDANCE > OPERATOR > MISSION > FENCE) and
hands the rest to the shell. Every Submit is shown to the avoidance module first
(safety/module.py): it holds the mission's requests while it flies a manoeuvre, holds
the mission's launch until the pad is clear, and turns its return into a landing on
the vehicle's own pad.
"""

from __future__ import annotations

import logging
import math
from collections import Counter
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import assert_never

import msgspec

from swarm_proto import (
    Ack,
    AckReason,
    AckRef,
    Alert,
    AlertCode,
    AlertFlag,
    Command,
    CommandKind,
    DeclaredState,
    FleetAssignment,
    FsmState,
    GeoPoint,
    Mission,
    MissionState,
    MissionType,
    NoFlyZone,
    PlanLineage,
    SelectorKind,
    Severity,
    SwarmView,
    TargetReport,
    VehicleInfo,
    VehicleStatus,
    Vote,
)
from swarm_proto.text import short_text

from . import state_machine as fsm
from .arbiter import AutopilotArbiter, Routed
from .autopilot.requests import ApResult, UploadRally
from .autopilot.state import AutopilotState
from .autopilot.status import to_vehicle_status
from .backstop import BackstopKeeper
from .commands import (
    AnswerCache,
    CancelMission,
    CommandTracker,
    Effect,
    LandAt,
    NodeView,
    SetActive,
    SetBase,
    SetFleet,
    StopLanding,
    TakeOver,
    answer_key,
    check_mission,
    emergency_requests,
    plan_command,
    rally_alt_rel_m,
)
from .declared import DeclaredBook, SortieRecord
from .emergency_route import zone_safe_emergency
from .fences import (
    FENCE_FULL_HEIGHT_REL_M,
    FENCE_MAX_ITEMS,
    FenceKeeper,
    FencePlan,
    plan_fence,
)
from .fleet_changes import FleetChanges
from .identity import IdentityNews
from .membership import PeerEvent, PeerJoined, PeerLeft, SwarmMembership
from .mission.published import (
    along_share,
    lineage_battery,
    published_home,
    published_progress,
)
from .mission.share import PlanOutcome, heading_on, pose_on
from .mission.tasking import Tasking, TaskingSettings
from .mission.voting import VoterLost
from .mission_manager import Member, MissionManager, Phase, replan_battery, with_defaults
from .monitoring import Thresholds, VehicleMonitor
from .outputs import ModuleOutput, Note, Owner, Persist, PlanJob, Post, Publish, Submit
from .planning import PlanningError
from .profile import VehicleProfile
from .reattach import Decision, Reattacher, dropped, same_share, sortie_record
from .safety.module import AvoidanceModule
from .stalls import StallMeter
from .swarm.regroup import Regroup
from .swarm.roster import MemberJoined, MemberLost, Roster, RosterEvent, RosterMismatch

log = logging.getLogger(__name__)

#: A stall of this node this long may have let its Zenoh session lapse (the 2 s lease)
#: and its peers' news go stale: peers leaving right after it are suspects first.
OWN_STALL_SUSPECT_S = 1.0

# ----------------------------------------------------------------------------- I/O


@dataclass(frozen=True)
class AutopilotUpdate:
    state: AutopilotState


@dataclass(frozen=True)
class AutopilotResult:
    result: ApResult


@dataclass(frozen=True)
class PeerAlive:
    node_id: int
    alive: bool


@dataclass(frozen=True)
class Received:
    msg: msgspec.Struct


@dataclass(frozen=True)
class BadInput:
    key: str
    error: str


@dataclass(frozen=True)
class PlanDone:
    """A plan job's outcome (the shell ran the node's PlanJob)."""

    outcome: PlanOutcome


@dataclass(frozen=True)
class Learned:
    """Declared state from the node's own database at start (`sortie`: the share it
    was flying) or from a peer: merged, the newest stamp wins."""

    state: DeclaredState
    sortie: SortieRecord | None = None
    source: str = "peer"


@dataclass(frozen=True)
class StoreResult:
    """The shell stored (or failed to store) the last `Persist`."""

    ok: bool
    error: str = ""


Input = (
    AutopilotUpdate
    | AutopilotResult
    | PeerAlive
    | Received
    | BadInput
    | PlanDone
    | Learned
    | StoreResult
    | IdentityNews
)


# what the shell carries out (Post stays inside)
Output = Publish | Submit | Note | PlanJob | Persist
__all__ = [  # noqa: RUF022 (inputs, outputs, the core)
    "AutopilotResult",
    "AutopilotUpdate",
    "BadInput",
    "Input",
    "Learned",
    "PeerAlive",
    "PlanDone",
    "Received",
    "StoreResult",
    "Note",
    "Output",
    "Persist",
    "PlanJob",
    "Post",
    "Publish",
    "Submit",
    "NodeCore",
    "NodeSettings",
]


@dataclass(frozen=True)
class NodeSettings:
    status_period_s: float = 0.2  # 5 Hz
    info_period_s: float = 1.0  # 1 Hz
    plan_timeout_s: float = 60.0
    stale_after_s: float = 2.0
    info_stale_after_s: float = 5.0  # peers that send only VehicleInfo (ground stations)
    thresholds: Thresholds | None = None  # default: from the profile
    fence_max_items: int = FENCE_MAX_ITEMS  # what the autopilot's fence storage takes
    avoidance: bool = True  # collision avoidance (safety/module.py); off: compare without it
    mav_sysid: int = 0  # the autopilot's MAVLink system id, from the database (0: not checked)


# ----------------------------------------------------------------------------- core


@dataclass
class NodeCore:
    profile: VehicleProfile
    settings: NodeSettings = field(default_factory=NodeSettings)
    now: float = 0.0
    fleet_profiles: Mapping[int, VehicleProfile] = field(default_factory=dict)  # from the database
    # the database's default parameters per kind of mission (fill what a mission leaves unset)
    mission_defaults: Mapping[MissionType, Mapping[str, float]] = field(default_factory=dict)
    # the database's voting weights, payload hierarchy and re-tasking rules
    tasking_settings: TaskingSettings = field(default_factory=TaskingSettings)

    def __post_init__(self) -> None:
        vid = self.profile.vehicle_id
        self.self_id = vid
        self.autopilot = AutopilotState()
        self.monitor = VehicleMonitor(
            vid,
            self.settings.thresholds or Thresholds.from_profile(self.profile),
            vehicle_type=self.profile.vehicle_type,  # an autopilot of another type is flagged
            mav_sysid=self.settings.mav_sysid,  # and one of another MAVLink system id
        )
        self.members = SwarmMembership(
            vid,
            stale_after_s=self.settings.stale_after_s,
            info_stale_after_s=self.settings.info_stale_after_s,
        )
        self.fsm = fsm.StateMachine(plan_timeout_s=self.settings.plan_timeout_s, now=self.now)
        self.commands = CommandTracker(vid)
        self.answers = AnswerCache()  # repeated commands and missions get the same answer
        self.manager = MissionManager(self.profile)
        self.active = True
        self.base: GeoPoint | None = None
        self.fleet_id = 0
        self.roster = Roster(vid)  # the members of the current mission, agreed by all
        self.tasking = Tasking(vid, self.tasking_settings, self.fleet_profiles)  # votes, targets
        self.regroup = Regroup(vid)  # add and swap: lineages of the fleets flown in
        self.changes = FleetChanges(self)  # carries out the two above (fleet_changes.py)
        self.missions: dict[int, Mission] = {}
        self.bad_input: Counter[str] = Counter()
        self.unhandled: Counter[str] = Counter()  # inputs no route takes (counted, logged once)
        self.arbiter = AutopilotArbiter()
        self.fence = FenceKeeper()  # zones -> the autopilot's fence (fences.py)
        # the fence and rally point checked on the autopilot (backstop.py)
        self.backstop = BackstopKeeper(vid, self.fence)
        self.fence_plan: FencePlan | None = None
        # its first tick at once: now, not at time 0 (a deadline of 0 reads as a stall)
        self.avoid = AvoidanceModule(
            self.profile, enabled=self.settings.avoidance, _next_tick=self.now
        )
        self._zones_version = 0  # 0: no zone heard yet, the autopilot's fence is left alone
        self._fence_key: object = None
        self._next_status = self.now
        self._next_info = self.now
        self.lost_members: list[MemberLost] = []  # roster events (replanning picks them up)
        self._replanning = False  # in PLAN for a replan of the current mission
        self.stalls = StallMeter()  # the node's own stalls, apart from link loss (stalls.py)
        self._due: float | None = None  # the deadline this core last declared
        # every module's deadline but the membership's, as last computed; fresh while
        # only peers' telemetry that changed nothing came in since (handle's fast path)
        self._rest_due = math.inf
        self._rest_fresh = False
        self.declared = DeclaredBook()  # what the operator declared (declared.py)
        self._base_stamp = 0.0  # the stamp of the declaration our base came from
        self._fleet_stamp = 0.0
        self._dirty = False  # the declared state changed: store it
        self._store_failing = False
        self.sortie_record: SortieRecord | None = None  # restored or kept (reattach)
        self._own_stall_until = float("-inf")  # peers leaving before then are suspects
        self._suspects: dict[int, str] = {}
        self.reattach = Reattacher(vid)  # a start with the vehicle flying (reattach.py)

    # ------------------------------------------------------------------ views
    @property
    def mission_state(self) -> MissionState:
        """Owned by the mission manager's sortie (mission/sortie.py), read here."""
        return self.manager.mission_state

    @property
    def mission_progress_pct(self) -> int:
        return self.manager.progress_pct

    def view(self) -> NodeView:
        return NodeView(
            self_id=self.self_id,
            fleet_id=self.fleet_id,
            profile=self.profile,
            autopilot=self.autopilot,
            fsm_state=self.fsm.state,
            mission_id=self.fsm.mission_id,
            base=self.base,
            ready=self.monitor.ready,
            landing=self.manager.landing,
            touching_down=self.manager.touching_down,
        )

    def status(self, now: float) -> VehicleStatus | None:
        """This vehicle's VehicleStatus (None until the autopilot has a position)."""
        return to_vehicle_status(
            self.autopilot,
            vehicle_id=self.self_id,
            now_unix_s=now,
            fsm_state=self.fsm.state,
            mission_state=self.mission_state,
            mission_progress=self.mission_progress_pct,
            fleet_id=self.fleet_id,
            alerts=self.monitor.flags | (AlertFlag.COLLISION_RISK if self.avoid.active else 0),
        )

    def info(self) -> VehicleInfo:
        p = self.profile
        mid = self.fsm.mission_id
        progress_m, path_m = published_progress(
            self.manager.sortie.progress_m, self.manager.sortie.path_m
        )
        return VehicleInfo(
            vehicle_id=self.self_id,
            vehicle_type=p.vehicle_type,
            model=p.model[:48],
            user_id=p.user_id[:48],
            mav_sysid=self.autopilot.sysid & 0xFF,
            payload_model=p.payload_model[:48],
            payload_subtype=p.payload_subtype[:48],
            payload_type=p.payload_type[:48],
            cruise_speed_m_s=_clamp(p.cruise_speed_m_s, 0.0, 300.0),
            home=published_home(self.autopilot.home),
            base=self.base,
            fleet_id=self.fleet_id,
            mission_id=mid if mid is not None and mid > 0 else 0,
            fsm_state=self.fsm.state,
            errors=self.monitor.active_codes,
            members_hash=self.roster.members_hash,
            # on the radio's grid: what every member hears and plans from, we too
            mission_progress_m=progress_m,
            mission_path_m=path_m,
            roll_deg=_clamp(self.autopilot.roll_deg, -180.0, 180.0),
            pitch_deg=_clamp(self.autopilot.pitch_deg, -180.0, 180.0),
            sensors_present=self.autopilot.sensors_present & 0xFFFFFFFF,
            sensors_health=self.autopilot.sensors_health & 0xFFFFFFFF,
            mav_type=self.autopilot.mav_type & 0xFF,
            entry_unix_s=_clamp(self.manager.sync.eta_unix_s, 0.0, 4.0e9),
            battery_pct=self._plan_battery(),
        )

    def _plan_battery(self) -> int:
        """The battery for VehicleInfo; the first published in PLAN for the roster's
        mission is what every node (this one too) plans this vehicle's share with."""
        pct = min(max(self.autopilot.battery_pct, -1), 100)
        if (
            pct >= 0
            and self.fsm.state == FsmState.PLAN
            and self.roster.mission_id is not None
            and self.roster.mission_id == self.fsm.mission_id
        ):
            self.roster.plan_battery.setdefault(self.self_id, pct)
        return pct

    # ------------------------------------------------------------------ inputs
    def handle(self, event: Input, now: float) -> list[Output]:
        self.now = now
        fresh, self._rest_fresh = self._rest_fresh, False
        if type(event) is Received and not self._dirty and self.stalls.idle(now, self._due):
            # a peer's telemetry (by far the most frequent input, 5 Hz per peer) and, with
            # no mission, its info: their route without the dispatch; when they change
            # nothing here (the usual case), no share record to keep, nothing to store or
            # route, and no deadline moved but the membership's
            events = self._peer_telemetry(event.msg, now)
            if events is not None:
                if not events:
                    self._rest_fresh = fresh
                    return []
                return self._peers_changed(events, now)
        out: list[ModuleOutput] = self._stalled(now)
        match event:
            case Received(msg):
                out += self._on_message(msg, now)
            case AutopilotUpdate(state):
                out += self._on_autopilot(state, now)
            case AutopilotResult(result):
                routed = self.arbiter.on_result(result)
                if routed is None:
                    out += self._unhandled("result", f"autopilot result {result.request_id}")
                else:
                    out += self._on_result(routed, now)
            case PeerAlive(node_id, alive):
                out += self._peer_events(self.members.on_alive(node_id, alive, now))
            case BadInput(key, error):
                self.bad_input[key] += 1
                out += [Note(logging.WARNING, f"dropped malformed input on {key}: {error}")]
            case PlanDone(outcome):
                out += self.manager.on_plan(outcome, self.autopilot, now, self.roster)
            case Learned(state, sortie, source):
                out += self._learn(state, sortie, source, now)
            case StoreResult(ok, error):
                out += self._stored(ok, error, now)
            case IdentityNews(conflict, untrusted):
                out += [Publish(a) for a in self.monitor.on_identity(conflict, now)]
                self.roster.distrust(untrusted)
            case _:
                assert_never(event)
        if self.manager.info_due():  # a PREMISSION ETA for the fleet: at once, not in 1 s
            out.append(Publish(self.info()))
        return self._routed(out, now)

    def hear(self, events: Sequence[Input], now: float) -> list[tuple[int, list[Output]]]:
        """`handle` for each of `events` in turn, all at `now` (what a harness hands a
        node at one time, in one call): the outputs of those that answered, by index.
        A peer's telemetry that changes nothing runs as `handle`'s first branch does,
        without the call."""
        answered: list[tuple[int, list[Output]]] = []
        # handle's check for its first branch, again only after an input that took
        # another (a quiet one changes neither)
        quiet = not self._dirty and self.stalls.idle(now, self._due)
        i, n = 0, len(events)
        while i < n:
            if quiet:  # known peers' statuses heard again, a run at once (most of it)
                i = self._statuses_again(events, i, now)
                if i == n:
                    break
            event = events[i]
            i += 1
            changed = None
            if quiet and type(event) is Received:
                self.now = now
                changed = self._peer_telemetry(event.msg, now)
                if changed is not None and not changed:
                    continue
            if changed:
                self._rest_fresh = False
                out = self._peers_changed(changed, now)
            else:
                out = self.handle(event, now)
            if out:
                answered.append((i - 1, out))
            quiet = not self._dirty and self.stalls.idle(now, self._due)
        return answered

    def _statuses_again(self, events: Sequence[Input], i: int, now: float) -> int:
        """From `events[i]`, the run of peers' statuses (and infos, with no mission: the
        messages `_peer_telemetry` takes) that change nothing but what is kept of those
        peers (known peers heard again: the membership's usual event), taken together
        as `_peer_telemetry` takes each; returns where the run ends."""
        run: list[VehicleStatus | VehicleInfo] = []
        statuses: list[VehicleStatus] = []
        infos = self.roster.mission_id is None
        for k in range(i, len(events)):
            event = events[k]
            if type(event) is not Received:
                break
            msg = event.msg
            if type(msg) is VehicleStatus:
                statuses.append(msg)
            elif type(msg) is not VehicleInfo or not infos:
                break
            run.append(msg)
        taken = self.members.heard_again(run, now) if run else 0
        if taken:
            self.now = now
            if taken < len(run):
                run = run[:taken]
                statuses = [m for m in run if type(m) is VehicleStatus]
            if statuses:
                self.manager.on_peer_statuses(statuses, now)
            self.avoid.on_peers(run, now, len(statuses))
        return i + taken

    def _peer_telemetry(self, msg: msgspec.Struct, now: float) -> list[PeerEvent] | None:
        """A peer's telemetry (by far the most frequent input, 5 Hz per peer) and, with no
        mission, its info, to the modules that keep them: the membership's events. None:
        not such a message (it takes the dispatch)."""
        if type(msg) is VehicleStatus:
            return self._peer_status(msg, now)
        if type(msg) is VehicleInfo and self.roster.mission_id is None:
            self.avoid.on_peer(msg, now)  # no roster to answer: nothing else hears it
            return self.members.on_info(msg, now)
        return None

    def _peers_changed(self, events: list[PeerEvent], now: float) -> list[Output]:
        out: list[ModuleOutput] = list(self._peer_events(events))
        if self.manager.info_due():
            out.append(Publish(self.info()))
        return self._routed(out, now)

    def _routed(self, out: list[ModuleOutput], now: float) -> list[Output]:
        self._keep_sortie_record(now)
        if self._dirty:
            self._dirty = False
            out.append(Persist(self.declared_state(now), self.sortie_record))
        return self._route(out, now) if out else []

    # ------------------------------------------------------------------ declared state
    def declared_state(self, now: float) -> DeclaredState:
        """What the operator declared, as this node holds it (the DECLARED queryable)."""
        mid = self.fsm.mission_id
        return self.declared.snapshot(
            self.self_id,
            now,
            base=self.base,
            fleet_id=self.fleet_id,
            mission_id=mid if mid is not None and mid > 0 else 0,
        )

    def _learn(
        self, state: DeclaredState, sortie: SortieRecord | None, source: str, now: float
    ) -> list[ModuleOutput]:
        """Merge another book (ours from the database, a peer's): newer zones go to
        monitoring and the fence, a newer base or fleet for this vehicle is taken."""
        changed = self.declared.merge(state, now)
        out: list[ModuleOutput] = []
        for z in changed.zones:
            self.monitor.zones[z.zone_id] = z
            self._zones_version += 1
        if changed.zones:
            ids = ",".join(str(z.zone_id) for z in changed.zones)
            out.append(Note(logging.INFO, f"zones {ids} learned from {source}"))
            out += self._keep_fence(now)
        out += self._take_declared(source)
        if source == "database":  # the node starts: its vehicle may be flying
            self.sortie_record = sortie
            self.reattach.start(sortie, now)
        if changed:
            self._dirty = True
        return out

    def _keep_sortie_record(self, now: float) -> None:
        """The share flown now, stored when it changes (not its progress): a node that
        restarts in flight reattaches with it (reattach.py)."""
        if self.reattach.active:
            return  # the record restored at start is the one to decide with
        m, r = self.manager, self.roster
        if self.sortie_record is None and m.phase.value != "flying":
            return  # no share flown, none recorded: nothing to keep (most inputs)
        rec = sortie_record(
            mission_id=m.mission_id,
            flying=m.phase.value == "flying",
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
        if not same_share(rec, self.sortie_record):
            self.sortie_record = rec
            self._dirty = True

    def _reattached(self, decision: Decision, now: float) -> list[ModuleOutput]:
        """Carry out the reattach decision (reattach.py)."""
        rec = self.sortie_record
        if decision == Decision.HAND_ON:
            self.sortie_record = None
            self._dirty = True
            return [Post(fsm.LeftFleet("share handed on after a restart"))]
        if decision != Decision.CONTINUE or rec is None:
            return []
        held = self.declared.missions.get(rec.mission_id)
        if held is None:  # the mission itself was not stored: the vehicle goes home
            return [Post(fsm.LeftFleet("restarted without the mission on record"))]
        if self.declared.cancelled(rec.mission_id) or not held.in_force:
            return [Post(fsm.LeftFleet(f"mission {rec.mission_id} no longer in force"))]
        mission = held.mission
        self.missions[mission.mission_id] = mission
        r = self.roster
        r.open(mission.mission_id, mission.selection)
        r.members, r.planned, r.generation = rec.members, rec.planned, rec.generation
        self.manager.reattach(rec.mission_id, rec.items, rec.last_item, rec.path_m, rec.progress_m)
        return [Post(fsm.Reattached(rec.mission_id))]

    def _take_declared(self, source: str) -> list[ModuleOutput]:
        """This vehicle's base and fleet as the book resolves them, when newer than what
        set ours."""
        base, base_at, fleet, fleet_at = self.declared.resolve(self.self_id)
        out: list[ModuleOutput] = []
        if base is not None and base_at > self._base_stamp:
            self.base, self._base_stamp = base, base_at
            out.append(
                Note(
                    logging.INFO,
                    f"base {base.lat_deg:.6f},{base.lon_deg:.6f} learned from {source}",
                )
            )
        if fleet_at > self._fleet_stamp:
            if fleet != self.fleet_id:
                out.append(Note(logging.INFO, f"fleet {fleet} learned from {source}"))
            self.fleet_id, self._fleet_stamp = fleet, fleet_at
        return out

    def _stored(self, ok: bool, error: str, now: float) -> list[ModuleOutput]:
        if ok:
            was, self._store_failing = self._store_failing, False
            return [Note(logging.INFO, "declared state stored again")] if was else []
        if self._store_failing:
            return []
        self._store_failing = True
        text = f"declared state not stored: {error}"
        return [
            Note(logging.WARNING, f"{text} (held in memory and by the peers; retried)"),
            Publish(
                Alert(self.self_id, max(0.0, now), Severity.WARNING, AlertCode.GENERIC, text[:64])
            ),
        ]

    def _stalled(self, now: float) -> list[ModuleOutput]:
        """The node's own stall (served later than its declared deadline): not counted
        as autopilot link loss, reported apart (stalls.py)."""
        if self.stalls.idle(now, self._due):
            return []
        stall = self.stalls.observe(now, self._due)
        if stall:
            self.monitor.note_stall(stall)
            self.stalls.note(now, stall)
            if stall >= OWN_STALL_SUSPECT_S:  # our session and our news of the peers lapsed
                self._own_stall_until = now + self.settings.stale_after_s
        stall = self.stalls.due_report(now)
        if not stall:
            return []
        text = f"node stalled {stall:.1f} s (host busy), not a link loss"
        return [
            Note(logging.WARNING, text),
            Publish(
                Alert(self.self_id, max(0.0, now), Severity.WARNING, AlertCode.GENERIC, text[:64])
            ),
        ]

    def _route(self, outs: list[ModuleOutput], now: float) -> list[Output]:
        """Posts to the state machine, requests through the arbiter (a refusal goes
        straight back to its module), the rest to the shell."""
        out: list[Output] = []
        todo = list(outs)
        while todo:
            o = todo.pop(0)
            match o:
                case Post(event):
                    self.fsm.post(event)
                case Submit(request, owner, route):
                    took = self.avoid.on_submit(o, self.autopilot, now)
                    if took is not None:  # held, or replaced (safety/module.py)
                        subs, answer = took
                        todo[0:0] = subs + (self._on_result(answer, now) if answer else [])
                        continue
                    sent = self.arbiter.submit(owner, request, route)
                    if isinstance(sent, Routed):
                        todo[0:0] = self._on_result(sent, now)
                    else:
                        out.append(Submit(sent, owner, route))
                case Publish():
                    out.append(o)
                case Note() | PlanJob() | Persist():
                    out.append(o)
                case _:
                    assert_never(o)
        return out

    def _on_result(self, routed: Routed, now: float) -> list[ModuleOutput]:
        result = routed.result
        match routed.owner:
            case Owner.FENCE:
                return self._fence_result(result, now)
            case Owner.MISSION:
                return self.manager.on_result(result, now)
            case Owner.OPERATOR:
                reqs, acks = self.commands.on_result(result, now)
                return [*(Submit(r, Owner.OPERATOR) for r in reqs), *self._answer(acks)]
            case Owner.EMERGENCY:
                if result.ok:
                    return []
                text = f"emergency procedure refused: {result.reason}"
                return [
                    Note(logging.ERROR, text),
                    Publish(
                        Alert(
                            self.self_id,
                            max(0.0, now),
                            Severity.CRITICAL,
                            AlertCode.GENERIC,
                            short_text(text),
                        )
                    ),
                ]
            case Owner.AVOIDANCE:
                return self._avoided(self.avoid.on_result(result, now))
            case _:
                assert_never(routed.owner)

    def _unhandled(self, kind: str, text: str) -> list[ModuleOutput]:
        self.unhandled[kind] += 1
        if self.unhandled[kind] == 1:
            return [Note(logging.WARNING, f"no route for {text} (counted in unhandled)")]
        return []

    def _on_autopilot(self, state: AutopilotState, now: float) -> list[ModuleOutput]:
        self.autopilot = state
        out: list[ModuleOutput] = [Publish(a) for a in self.monitor.update(state, now)]
        out += self.manager.on_autopilot(state, now, self.roster)
        out += self._keep_fence(now)
        out += self.reattach.on_autopilot(state, now)
        return out + self.backstop.on_autopilot(state, self.rally_want(), now)

    def rally_want(self) -> UploadRally | None:
        """The rally point the autopilot should hold: the base (commands.rally_alt_rel_m)."""
        base, home = self.base, self.autopilot.home
        if base is None or home is None:
            return None
        alt = rally_alt_rel_m(self.profile.vehicle_type, base.alt_msl_m - home.alt_msl_m)
        return UploadRally(points=((base.lat_deg, base.lon_deg, alt),))

    def _on_message(self, msg: msgspec.Struct, now: float) -> list[ModuleOutput]:
        match msg:
            case VehicleStatus():
                events = self._peer_status(msg, now)
                return self._peer_events(events) if events else []
            case VehicleInfo():
                self.avoid.on_peer(msg, now)
                out = self._peer_events(self.members.on_info(msg, now))
                return out + self._roster_events(self.roster.on_info(msg))
            case Ack():
                self.roster.on_ack(msg)
                return []
            case Command():
                return self._on_command(msg, now)
            case Mission():
                self.regroup.heard_mission(msg)  # a vehicle may be told to join it later
                if msg.selection.kind == SelectorKind.QUANTITY:
                    return self.changes.on_quantity(msg, now)
                return self._on_mission(msg)
            case NoFlyZone():
                held = self.monitor.zones.get(msg.zone_id)
                zone = self.declared.offer_zone(msg, now)
                if zone is None:  # older than the declaration held: a withdrawal stays
                    return self._zone_ack(msg, held)
                self.monitor.zones[zone.zone_id] = zone
                self._zones_version += 1
                self._dirty = True
                return self._zone_ack(msg, held) + self._keep_fence(now)
            case FleetAssignment():
                return self._on_fleet(msg)
            case Vote() | TargetReport():  # the vote, re-tasking (mission/tasking.py)
                return self.changes.tasked(self.tasking.handle(msg, now), now)
            case PlanLineage():
                self.regroup.on_lineage(msg)
                return []
            case Alert() | SwarmView():
                self.unhandled[type(msg).__name__] += 1  # declared: not for the node yet
                return []
            case _:
                return self._unhandled(type(msg).__name__, f"message {type(msg).__name__}")

    def _peer_status(self, msg: VehicleStatus, now: float) -> list[PeerEvent]:
        """A peer's telemetry to the modules that keep it; the membership's events."""
        self.manager.on_peer_status(msg, now)  # MUM-T: the lead's telemetry
        self.avoid.on_peer(msg, now)
        return self.members.on_status(msg, now)  # usually none: a known peer

    def _zone_ack(self, zone: NoFlyZone, held: NoFlyZone | None) -> list[ModuleOutput]:
        """Answer the zone's issuer (a repeat too): held, or for a withdrawal of a zone
        this vehicle never held, NOT_FOUND (the withdrawal is kept all the same)."""
        if not zone.issuer_id:
            return []
        if zone.active:
            ok, text = True, "operating area held" if zone.operating_area else "held"
        elif held is None:
            ok, text = False, f"zone {zone.zone_id} was not held"
        else:
            ok, text = True, "withdrawn" if held.active else "already withdrawn"
        reason = AckReason.OK if ok else AckReason.NOT_FOUND
        ack = Ack(self.self_id, zone.issuer_id, AckRef.ZONE, zone.zone_id, ok, reason, text)
        return [Publish(ack)]

    def _answer(self, acks: list[Ack]) -> list[ModuleOutput]:
        for a in acks:
            self.answers.answered(a)
        return [Publish(a) for a in acks]

    def _repeat(self, msg: Command | Mission) -> list[ModuleOutput] | None:
        """A command or mission already taken up: its first answer again (nothing while it
        still runs). None: not a repeat."""
        key = answer_key(msg)
        if not self.answers.seen(key):
            return None
        ack = self.answers.answer_of(key)
        return [Publish(ack)] if ack is not None else []

    def _on_command(self, cmd: Command, now: float) -> list[ModuleOutput]:
        repeat = self._repeat(cmd)
        if repeat is not None:
            return repeat
        declared = self.declared.offer_command(cmd, now)  # every node keeps every one
        if declared is not None:
            self._dirty = True
            if cmd.target.addresses(self.self_id, self.fleet_id):
                if cmd.kind == CommandKind.SET_BASE:
                    self._base_stamp = declared.time_unix_s
                elif cmd.kind == CommandKind.SET_FLEET:
                    self._fleet_stamp = declared.time_unix_s
        if cmd.kind in (CommandKind.JOIN_MISSION, CommandKind.SWAP_MISSION):
            return self.changes.on_regroup(cmd, now)
        plan = plan_command(cmd, self.view())
        if plan is None:
            return []
        self.answers.taken(answer_key(cmd))
        requests = plan.requests
        for effect in plan.effects:
            if isinstance(effect, LandAt):
                try:
                    requests += self.manager.landing_route(
                        effect.point, self.autopilot, self.planning_zones(now), now
                    )
                except (PlanningError, ValueError) as exc:
                    ack = Ack(
                        self.self_id,
                        cmd.issuer_id,
                        AckRef.COMMAND,
                        cmd.seq,
                        False,
                        AckReason.INVALID,
                        short_text(f"no landing route: {exc}"),
                    )
                    return self._answer([ack])
        for effect in plan.effects:
            self._apply(effect)
        started = self.commands.start(cmd, requests, now)
        out: list[ModuleOutput] = [Submit(r, Owner.OPERATOR) for r in started]
        if plan.ack is not None:
            out += self._answer([plan.ack])
            if not plan.ack.accepted:
                out.append(
                    Note(
                        logging.INFO,
                        f"command {cmd.kind.name} #{cmd.seq} rejected: {plan.ack.reason.name}",
                    )
                )
        return out

    def _apply(self, effect: Effect) -> None:
        if isinstance(effect, SetBase):
            self.base = self.manager.base = effect.point
        elif isinstance(effect, SetFleet):
            self.fleet_id = effect.fleet_id
        elif isinstance(effect, SetActive):
            self.active = effect.active
        elif isinstance(effect, CancelMission):
            self.fsm.post(fsm.Cancelled(effect.mission_id))
        elif isinstance(effect, TakeOver):
            self.manager.take_over(effect.phase)
            if self.fsm.state in (FsmState.PLAN, FsmState.GO_MISSION):
                self.fsm.post(fsm.Recalled(effect.reason))
        elif isinstance(effect, StopLanding):
            self.manager.stop()  # the operator holds the vehicle; LAND or RTL ends the sortie

    def _on_mission(self, mission: Mission) -> list[ModuleOutput]:
        repeat = self._repeat(mission)
        if repeat is not None:
            return repeat
        reason = check_mission(mission, self.view())
        ok = reason == AckReason.OK
        why = self._not_ready_text() if reason == AckReason.NOT_READY else ""
        if reason == AckReason.BUSY and self.manager.touching_down:
            why = "landing: activate it once landed, then send it again"
        ack = Ack(
            self.self_id,
            mission.issuer_id,
            AckRef.MISSION,
            mission.mission_id,
            ok,
            reason,
            short_text(why),
        )
        # only an acceptance is remembered: a rejected mission sent again is checked again
        # (the operator may have fixed what was wrong, e.g. set the base; a vehicle may
        # have joined the fleet the mission addresses)
        out: list[ModuleOutput] = self._answer([ack]) if ok else [Publish(ack)]
        if ok:
            mission = with_defaults(mission, self.mission_defaults.get(mission.mission_type, {}))
            self.missions[mission.mission_id] = mission
            self._dirty |= self.declared.accept_mission(mission, self.now) is not None
            self.fsm.post(fsm.NewMission(mission.mission_id))
        return out

    def _not_ready_text(self) -> str:
        why = self.monitor.not_ready_text(self.autopilot)
        if why or self.fsm.state != FsmState.INACTIVE:
            return why
        return "shut down: send activate" if not self.active else "state machine not started"

    def _on_fleet(self, msg: FleetAssignment) -> list[ModuleOutput]:
        held = self.declared.offer_assignment(msg, self.now)
        if held is None:
            return []  # a repeat, or older than the assignment held
        self._dirty = True
        if self.self_id in msg.vehicle_ids or self.fleet_id == msg.fleet_id:
            self._fleet_stamp = max(self._fleet_stamp, held.time_unix_s)
        if self.self_id in msg.vehicle_ids:
            self.fleet_id = msg.fleet_id
        elif self.fleet_id == msg.fleet_id:
            self.fleet_id = 0  # dropped from the fleet
            self.fsm.post(fsm.LeftFleet("removed from the fleet"))
        return []

    # ------------------------------------------------------------------ fences
    def fly_ceiling_rel_m(self) -> float:
        """The highest this vehicle flies above home: zones below it may be overflown."""
        top = FENCE_FULL_HEIGHT_REL_M
        for m in self.missions.values():
            n = max(1, len(m.selection.vehicle_ids), len(self.roster.members))
            top = max(top, m.params.altitude_rel_m + m.params.altitude_step_m * (n - 1))
        return top

    def _keep_fence(self, now: float) -> list[ModuleOutput]:
        """Keep the autopilot's fence equal to the zones in force (fences.py): a new plan
        when a zone, its validity, home or the flight ceiling changed."""
        home = self.autopilot.home
        if self._zones_version == 0 or home is None:
            return []
        in_force = tuple(sorted(z.zone_id for z in self.monitor.zones.values() if z.in_force(now)))
        ceiling = self.fly_ceiling_rel_m()
        key = (self._zones_version, in_force, home, ceiling)
        if key == self._fence_key:
            return [Submit(r, Owner.FENCE) for r in self.fence.on_timer(now)]
        self._fence_key = key
        before = self.fence_plan
        plan = plan_fence(
            self.monitor.zones.values(),
            now,
            home=home,
            fly_ceiling_rel_m=ceiling,
            max_items=self.settings.fence_max_items,
        )
        self.fence_plan = plan
        out: list[ModuleOutput] = []
        if plan.left_out and (before is None or before.left_out != plan.left_out):
            ids = ",".join(str(i) for i in plan.left_out)
            text = f"fence full: zones {ids} not in the autopilot"
            out += [
                Note(logging.WARNING, text),
                Publish(
                    Alert(
                        self.self_id,
                        max(0.0, now),
                        Severity.WARNING,
                        AlertCode.NO_FLY_ZONE,
                        short_text(text),
                    )
                ),
            ]
        return out + [Submit(r, Owner.FENCE) for r in self.fence.update(plan.request, now)]

    def _fence_result(self, result: ApResult, now: float) -> list[ModuleOutput]:
        if self.reattach.owns(result.request_id):
            return self.reattach.on_result(result, now)
        if self.backstop.owns(result.request_id):
            return self.backstop.on_result(result, self.autopilot, now)
        reqs, problem = self.fence.on_result(result, now)
        out: list[ModuleOutput] = [Submit(r, Owner.FENCE) for r in reqs]
        if problem is not None and self.fence.failures == 1:  # once per run of failures
            out += [
                Note(logging.WARNING, f"{problem}; retrying every {self.fence.retry_s:g} s"),
                Publish(
                    Alert(
                        self.self_id,
                        max(0.0, now),
                        Severity.WARNING,
                        AlertCode.NO_FLY_ZONE,
                        short_text(problem),
                    )
                ),
            ]
        return out

    def planning_zones(self, now: float) -> list[NoFlyZone]:
        """The no-fly zones the planners avoid: those in force (operating areas are not
        no-fly zones)."""
        return [z for z in self.monitor.zones.values() if z.in_force(now) and not z.operating_area]

    def _peer_events(self, events: list[PeerEvent]) -> list[ModuleOutput]:
        """Peers joined and left. A peer that leaves just after this node's own long
        stall (its Zenoh session dropped by the lease, its peers' news late) is only a
        suspect until `own_stall_grace_s` has passed: it is lost then if it did not come
        back (a node stopped 3 s otherwise took every member for lost and
        replanned their shares alone)."""
        out: list[ModuleOutput] = []
        for ev in events:
            if isinstance(ev, PeerJoined):
                if self._suspects.pop(ev.node_id, None) is None:
                    out.append(Note(logging.INFO, f"peer {ev.node_id} joined ({ev.how})"))
            elif isinstance(ev, PeerLeft):
                if self.now < self._own_stall_until:
                    self._suspects[ev.node_id] = ev.why
                    continue
                self.avoid.forget(ev.node_id, self.now)
                out.append(Note(logging.WARNING, f"peer {ev.node_id} lost ({ev.why})"))
                out += self._roster_events(self.roster.on_peer_left(ev.node_id, ev.why))
        return out

    def _suspects_left(self, now: float) -> list[ModuleOutput]:
        """Suspects that did not come back within the grace after our own stall."""
        if not self._suspects or now < self._own_stall_until:
            return []
        gone, self._suspects = self._suspects, {}
        out: list[ModuleOutput] = []
        for vid, why in gone.items():
            out.append(Note(logging.WARNING, f"peer {vid} lost ({why})"))
            out += self._roster_events(self.roster.on_peer_left(vid, why))
        return out

    def _roster_events(self, events: list[RosterEvent]) -> list[ModuleOutput]:
        out: list[ModuleOutput] = []
        for ev in events:
            if isinstance(ev, MemberLost):
                self.lost_members.append(ev)
                del self.lost_members[:-20]
                out.append(
                    Note(
                        logging.WARNING,
                        f"mission {ev.mission_id}: member {ev.vehicle_id} lost ({ev.why})",
                    )
                )
                out += self.changes.tasked(
                    self.tasking.handle(VoterLost(ev.vehicle_id), self.now), self.now
                )
                if (
                    self.roster.frozen
                    and self.fsm.mission_id == ev.mission_id
                    and self.fsm.state in (FsmState.GO_MISSION, FsmState.PLAN)
                    and self.manager.mission_state
                    in (MissionState.PREMISSION, MissionState.MISSION, MissionState.REPLAN)
                ):
                    out.append(Post(fsm.Replan(ev.mission_id)))  # inherit its share
            elif isinstance(ev, MemberJoined):
                if (
                    self.fsm.mission_id == ev.mission_id
                    and self.fsm.state in (FsmState.GO_MISSION, FsmState.PLAN)
                    and self.manager.mission_state
                    in (MissionState.PREMISSION, MissionState.MISSION, MissionState.REPLAN)
                ):
                    self.roster.join(ev.vehicle_id)
                    out += [
                        Note(
                            logging.INFO, f"mission {ev.mission_id}: vehicle {ev.vehicle_id} joins"
                        ),
                        Post(fsm.Replan(ev.mission_id)),  # share what is left with it
                    ]
            elif isinstance(ev, RosterMismatch):  # an alert, once per member and hash
                r = self.roster
                if (
                    dropped(self.self_id, ev.mission_id, r.planned, r.generation, ev.theirs)
                    and self.fsm.state == FsmState.GO_MISSION
                    and self.fsm.mission_id == ev.mission_id
                ):  # the fleet replanned our share away while we were stopped
                    out.append(Post(fsm.LeftFleet("the fleet replanned without this vehicle")))
                    out.append(
                        Note(
                            logging.WARNING,
                            f"mission {ev.mission_id}: the fleet "
                            "replanned without us; handing the share on",
                        )
                    )
                    continue
                text = (
                    f"mission {ev.mission_id}: vehicle {ev.vehicle_id} flies roster "
                    f"{ev.theirs:#06x}, ours {ev.ours:#06x}"
                )
                out += [
                    Note(logging.ERROR, text),
                    Publish(
                        Alert(
                            self.self_id,
                            max(0.0, self.now),
                            Severity.WARNING,
                            AlertCode.ROSTER_MISMATCH,
                            text[:64],
                        )
                    ),
                ]
        return out

    # ------------------------------------------------------------------ time
    def next_deadline(self) -> float:
        # called at every step of a runtime or harness (after every input): O(1), and
        # after a peer's telemetry that changed nothing, only the membership's is asked
        m = self.members.next_deadline()
        t = self._rest_due if self._rest_fresh else self._rest_deadline()
        if m is not None and m < t:
            t = m
        self._due = t  # the deadline declared: served later than it, the node stalled
        return t

    def _rest_deadline(self) -> float:
        """Every module's next deadline but the membership's."""
        t = min(self._next_status, self._next_info, self.fsm.next_deadline())
        for d in (
            self.commands.next_deadline(),
            self.fence.next_deadline(),
            self.tasking.next_deadline(),
            self.avoid.next_deadline(),
            self.backstop.next_deadline(),
            self.stalls.next_deadline(),
            self._own_stall_until if self._suspects else None,
            self.reattach.next_deadline(),
        ):
            if d is not None and d < t:
                t = d
        self._rest_due, self._rest_fresh = t, True
        return t

    def on_timer(self, now: float) -> list[Output]:
        self.now = now
        self._rest_fresh = False
        out: list[ModuleOutput] = self._stalled(now)
        out += self._peer_events(self.members.on_timer(now))
        out += self._suspects_left(now)
        out += self._answer(self.commands.on_timer(now))
        out += self._keep_fence(now)
        due = self.tasking.next_deadline()
        if due is not None and now >= due:
            out += self.changes.tasked(self.tasking.on_timer(now), now)
        out += self._avoidance_tick(now)
        out += self.backstop.on_timer(self.autopilot, now)
        if self.reattach.active:
            infos = [p.info for p in self.members.live() if p.info is not None]
            decision, said = self.reattach.on_timer(self.autopilot, infos, self.fsm.state, now)
            out += said
            if decision is not None:
                out += self._reattached(decision, now)
        if now >= self.fsm.next_deadline():
            # alerts that escalate with time (a lasting link loss) are
            # re-evaluated at every tick, not only when the link reports a new state
            out += [Publish(a) for a in self.monitor.update(self.autopilot, now)]
            out += self._tick_fsm(now)
        if now >= self._next_status:
            self._next_status = max(self._next_status + self.settings.status_period_s, now)
            st = self.status(now)
            if st is not None:
                out.append(Publish(st))
        if now >= self._next_info:
            self._next_info = max(self._next_info + self.settings.info_period_s, now)
            out.append(Publish(self.info()))
        return self._routed(out, now)

    def _avoidance_tick(self, now: float) -> list[ModuleOutput]:
        """Collision avoidance at 5 Hz (safety/module.py): the own state, ADS-B traffic,
        the altitude to come back to and the zones' ceiling in; manoeuvres out."""
        due = self.avoid.next_deadline()
        if due is None or now < due:
            return []
        climbing = self.manager.phase == Phase.CLIMBING
        out = self.avoid.tick(
            now,
            self.status(now),
            self.autopilot,
            zones=self.monitor.zones,
            climb_target_rel_m=self.manager.takeoff_alt_m if climbing else None,
            holder=self.arbiter.holder,
            pads=self._pads,
            peers=self._peer_homes,
        )
        return self._avoided(out)

    def _peer_homes(self) -> list[tuple[VehicleStatus, GeoPoint | None]]:
        """The live peers' latest statuses with their homes (the pad rules')."""
        return [
            (p.status, p.info.home if p.info else None)
            for p in self.members.peers.values()
            if p.present and p.status is not None
        ]

    def _pads(self) -> dict[int, GeoPoint]:
        """Every known vehicle's home (VehicleInfo), ours included: the pads."""
        pads = {v: p.info.home for v, p in self.members.peers.items() if p.info and p.info.home}
        if self.autopilot.home is not None:
            pads[self.self_id] = self.autopilot.home
        return pads

    def _avoided(self, out: list[ModuleOutput]) -> list[ModuleOutput]:
        """Avoidance gave the autopilot back: to whoever held it before, and the
        mission's requests held meanwhile go on."""
        if self.avoid.release_due:
            self.avoid.release_due = False
            self.arbiter.release(Owner.AVOIDANCE)
            if self.avoid.restore is not None:
                self.arbiter.take(self.avoid.restore)
            out += self.avoid.take_held()
        return out

    def facts(self) -> fsm.Facts:
        return fsm.Facts(
            active=self.active,
            base_set=self.base is not None,
            vehicle_ready=self.monitor.ready,
            emergency=self.monitor.emergency,
            fleet_ready=self._fleet_ready(),
            armed=self.autopilot.armed,
            launch_queued=self.avoid.launch is not None,
        )

    def _fleet_ready(self) -> bool:
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
            return self.roster.ready_to_replan(self.members.peers)
        if self.regroup.joining == mid:  # a joiner: the fleet's lineage with it in
            return mid in self.regroup.offered
        if mid in self.regroup.adopting:  # an emptied fleet's mission, handed to ours
            return True
        return self.roster.ready(self.members.peers)

    def _tick_fsm(self, now: float) -> list[ModuleOutput]:
        tr = self.fsm.tick(now, self.facts())
        if tr is None:
            return []
        out: list[ModuleOutput] = [
            Note(logging.INFO, f"{tr.before.name} -> {tr.after.name} ({tr.rule})")
        ]
        if tr.before == FsmState.EMERGENCY and tr.after != FsmState.EMERGENCY:
            self.arbiter.release(Owner.EMERGENCY)
        for o in tr.outputs:
            out += self._carry_out(o, now)
        if tr.before != tr.after or any(isinstance(o, fsm.BeginPlan) for o in tr.outputs):
            out.append(Publish(self.info()))  # peers waiting on our state should not wait 1 s
        return out

    def _carry_out(self, o: fsm.Output, now: float) -> list[ModuleOutput]:
        if isinstance(o, fsm.RaiseAlert):
            return [
                Publish(Alert(self.self_id, max(0.0, now), o.severity, o.code, short_text(o.text)))
            ]
        if isinstance(o, fsm.StartEmergency):
            self.manager.stop()
            alert = Alert(
                self.self_id, max(0.0, now), o.severity, o.code, f"emergency: {o.code.name}"
            )
            out: list[ModuleOutput] = [Publish(alert)]
            self.arbiter.take(Owner.EMERGENCY)
            requests, why = zone_safe_emergency(
                emergency_requests(o.code, self.profile),
                self.autopilot,
                self.base,
                self.planning_zones(now),
                self.profile,
                now,
            )
            if why:
                out.append(Note(logging.WARNING, f"emergency: {why}"))
            return out + [Submit(r, Owner.EMERGENCY) for r in requests]
        if isinstance(o, fsm.ReturnHome):
            note = Note(logging.WARNING, f"returning home: {o.reason}")
            return [note, *self._start_return(now)]
        if isinstance(o, fsm.LeaveFleet):
            self.fleet_id = 0
            self.roster.close()
            return []
        if isinstance(o, fsm.FollowOperator):
            if o.mission_id is not None:
                self.missions.pop(o.mission_id, None)  # left, not completed
                self._dirty |= self.declared.end_mission(o.mission_id, now) is not None
            return [Note(logging.WARNING, f"left mission {o.mission_id}: {o.reason}")]
        if isinstance(o, fsm.BeginPlan):
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
            self.arbiter.release(Owner.OPERATOR)  # the state machine decides the next flight
            return []
        if isinstance(o, fsm.ReleaseMission):
            return self._release(o.mission_id, now)
        if isinstance(o, fsm.StandDown):
            self.missions.pop(o.mission_id, None)
            self.roster.close()
            self.manager.stop()
            return [Note(logging.INFO, f"mission {o.mission_id}: standing down ({o.reason})")]
        if isinstance(o, fsm.MissionStarted):
            return []
        if isinstance(o, fsm.MissionFinished):
            mission = self.missions.pop(o.mission_id, None)
            self.changes.take_over_handed(o.mission_id)
            self._dirty |= self.declared.end_mission(o.mission_id, now) is not None
            if mission is not None:
                return [
                    Publish(
                        Alert(
                            self.self_id,
                            max(0.0, now),
                            Severity.INFO,
                            AlertCode.MISSION_COMPLETE,
                            f"mission {o.mission_id}",
                        )
                    )
                ]
            return []
        if isinstance(o, fsm.Shutdown):
            self.active = False
            return []
        if isinstance(o, fsm.Deactivated):
            self.manager.stop()
            self.arbiter.release(Owner.OPERATOR)
            return [Note(logging.INFO, f"state machine deactivated: {o.reason}")]
        return []

    def _release(self, mission_id: int, now: float) -> list[ModuleOutput]:
        """The fleet is synchronised: hand the mission to the mission manager (the
        return-to-base mission: fly back to base and land)."""
        if mission_id == fsm.RETURN_MISSION:
            return self._start_return(now)
        mission = self.missions.get(mission_id)
        if mission is None:
            self.fsm.post(fsm.PlanFailed(mission_id, "unknown mission"))
            return []
        if self._replanning and self.roster.frozen:
            # the peers hold their replans until ours carries the same roster hash
            return [*self._replan(mission, now), Publish(self.info())]
        if self.regroup.joining == mission_id or mission_id in self.regroup.adopting:
            return self.changes.join(mission_id, now)
        if mission.selection.kind == SelectorKind.QUANTITY:  # idle candidates: vote first
            electorate = self.roster.freeze(self.members.peers)
            self.manager.vote()
            start = self.tasking.start(
                mission,
                electorate,
                (),
                self.changes.candidate(),
                now,
                home=None,
                lead=self.changes.lead(mission),
            )
            return self.changes.tasked(start, now)
        self.roster.freeze(self.members.peers)
        members, unknown = self._members()
        if unknown:
            self.fsm.post(
                fsm.PlanFailed(mission_id, short_text(f"no profile for fleet members {unknown}"))
            )
            return [
                Note(logging.ERROR, f"cannot plan mission {mission_id}: no profile for {unknown}")
            ]
        self.regroup.founded(mission, members)
        return self.manager.release(mission, members, self.planning_zones(now), self.autopilot, now)

    def _replan(self, mission: Mission, now: float) -> list[ModuleOutput]:
        """Mission inheritance (paper Fig. 14 and 17): what is left of the fleet plan,
        from every member's published progress along its share, shared among the
        survivors, each posed where its progress puts it on its share (inputs every
        survivor has the same: no leader)."""
        base = self.manager.fleet_plan
        peers = self.members.peers
        survivors = self.roster.survivors(peers)
        progress, flown = self._progress_now()
        members: list[Member] = []
        for vid in survivors:
            profile = self.profile if vid == self.self_id else self.fleet_profiles.get(vid)
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
        out = self.manager.replan(
            mission, members, progress, self.planning_zones(now), self.autopilot, now, battery
        )
        lineage = self.regroup.lineages.get(mission.mission_id)
        if took_in and lineage is not None:  # a vehicle joins: it needs how the plan came to be
            out.append(Publish(lineage.message(self.self_id, self.roster.members_hash)))
        return out

    def _progress_now(self) -> tuple[dict[int, float], dict[int, float]]:
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

    def _start_return(self, now: float) -> list[ModuleOutput]:
        return self.manager.start_return(self.autopilot, self.planning_zones(now), now)

    def _members(self) -> tuple[list[Member], list[int]]:
        """The fleet as the planners see it: profiles from the database, homes from the
        members' VehicleInfo (the same on every node). Lost members are left out;
        members whose profile is unknown are returned apart (planning without them
        would send two vehicles over the same ground)."""
        battery = self.roster.plan_battery
        home = published_home(self.autopilot.home)  # as the others hear it
        out = [Member(self.profile, home, battery.get(self.self_id))]
        unknown = []
        for vid in self.roster.flying:
            if vid == self.self_id:
                continue
            peer = self.members.peers.get(vid)
            if peer is None or not peer.present:
                continue
            profile = self.fleet_profiles.get(vid)
            if profile is None:
                unknown.append(vid)
                continue
            out.append(Member(profile, peer.info.home if peer.info else None, battery.get(vid)))
        return out, unknown


def _clamp(x: float, lo: float, hi: float) -> float:
    if x != x:  # NaN from a broken value: report the low bound, never crash
        return lo
    return min(max(x, lo), hi)
