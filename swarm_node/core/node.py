"""The vehicle node as one pure object: a router between the modules that own its state
(docs/node.md). It owns none itself: it hands each input to the module that owns it, and
what each module returns, as it returns it, to the module it concerns (routes.py; the
table is outputs.py's) or to the shell (swarm_node.runtime.node; tests and fast-time
simulations join several NodeCores and jump from deadline to deadline).

    core.handle(input, now) -> list[Output]    core.on_timer(now) -> list[Output]
    core.hear(inputs, now)  (handle, for a batch)   core.next_deadline() -> float

    input                       to
    AutopilotUpdate             monitoring (the latest state), mission coordinator, fences
    AutopilotResult             the arbiter, then the request's owner (arbiter.py)
    PeerAlive                   membership -> peers joined and lost (stalls.py)
    Received(VehicleStatus)     membership, avoidance, the mission manager (peer_traffic.py)
    Received(VehicleInfo)       the same, and the roster (the coordinator's)
    Received(Command | Mission) the operator desk (operator.py); missions to regroup too
    Received(NoFlyZone | FleetAssignment), Learned, StoreResult
                                the declarations (declarations.py); new zones: the fences
    Received(Mavlink*), MavlinkUp  the ground stations' MAVLink sessions (passthrough.py)
    Received(Ack | Vote | TargetReport | PlanLineage), PlanDone
                                the mission coordinator (mission/coordinator.py)
    BadInput, anything else     counted (`bad_input`, `unhandled`), never dropped silently
"""

from __future__ import annotations

import itertools
import logging
import math
from collections import Counter
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import assert_never

import msgspec

from swarm_proto import DeclaredState, MissionType, VehicleInfo, VehicleStatus

from .arbiter import AutopilotArbiter
from .declarations import Declarations
from .emergency import EmergencyProcedure
from .fences import Fences
from .inbound import Inbound
from .inputs import AutopilotResult as AutopilotResult
from .inputs import (
    AutopilotUpdate,
    BadInput,
    IdentityNews,
    Input,
    Learned,
    MavlinkUp,
    PeerAlive,
    PlanDone,
    Received,
)
from .inputs import StoreResult as StoreResult
from .membership import PeerEvent, SwarmMembership
from .mission.coordinator import MissionCoordinator
from .mission.phases import Phase
from .mission.tasking import TaskingSettings
from .monitoring import Thresholds, VehicleMonitor
from .operator import OperatorDesk
from .outputs import ModuleOutput, Note, Output, Publish
from .outputs import Persist as Persist  # the shell's vocabulary, re-exported
from .outputs import PlanJob as PlanJob
from .outputs import Submit as Submit
from .passthrough import Passthrough
from .peer_traffic import PeerTraffic
from .planning.transit import VehicleTransit
from .profile import VehicleProfile
from .reports import Beacon
from .routes import Routes
from .safety.module import AvoidanceModule
from .safety.pad_sequence import PadSequence
from .settings import NodeSettings as NodeSettings
from .stalls import StallGuard
from .views import Views
from .views import module_view as _view


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
        p, s, vid, now = self.profile, self.settings, self.profile.vehicle_id, self.now
        fp, md, ts = self.fleet_profiles, self.mission_defaults, self.tasking_settings
        self.self_id = vid
        d = self.declarations = Declarations(vid)  # zones, base, fleet: what was declared
        limits = s.thresholds or Thresholds.from_profile(p)
        # the vehicle's latest state; reads the zone book; flags an autopilot of another type
        mon = self.monitor = VehicleMonitor(
            vid, limits, d.zones, vehicle_type=p.vehicle_type, mav_sysid=s.mav_sysid
        )
        m = self.members = SwarmMembership(vid, s.stale_after_s, s.info_stale_after_s)
        ids = itertools.count(1)  # the operator's request ids: commands and passthrough
        op = self.operator = OperatorDesk(VehicleTransit(p), md, ids=ids)
        pt = self.passthrough = Passthrough(vid, ids)  # ground stations' MAVLink sessions
        arb = self.arbiter = AutopilotArbiter()  # who commands the autopilot (arbiter.py)
        fen = self.fences = Fences(vid, p.vehicle_type, s.fence_max_items)
        em = self.emergency = EmergencyProcedure(p)
        # its first tick at once: now, not at time 0 (a deadline of 0 reads as a stall)
        av = self.avoid = AvoidanceModule(p, enabled=s.avoidance, next_tick=now, intent=s.intent)
        pads = PadSequence(p, s.avoidance, peers=m.statuses_and_homes, pads=m.homes, types=m.types)
        mi = self.mission = MissionCoordinator(p, s.plan_timeout_s, fp, md, ts, pads, now)
        mi.silent_hold_s = s.silent_hold_s
        self.stalls = StallGuard(vid, s.stale_after_s)  # our own stalls (stalls.py)
        self.beacon = Beacon(s.status_period_s, s.info_period_s, now, now)  # status, info
        views = self.views = Views(p, mon, d, m, op, mi, av)  # what modules read of others
        # each module's outputs, as it returns them, to the module that takes it
        self.routes = Routes(arb, mi, d, op, av, em, fen, mon, views, self._message, pt)
        self._route = self.routes.route
        # peers' telemetry, the hot path, to the modules that keep it (peer_traffic.py)
        self._manager = mi.manager
        self.traffic = PeerTraffic(m, av, mi.manager, mi.roster)
        self.bad_input: Counter[str] = Counter()
        # each swarm message to the module that owns what it says (inbound.py)
        self.inbound = Inbound(m, self.traffic, self.stalls, av, mi, op, d, pt, views)
        self.unhandled = self.inbound.unhandled  # inputs no route takes (counted, logged once)
        self._due: float | None = None  # the deadline this core last declared
        # every module's deadline but the membership's, as last computed; fresh while
        # only peers' telemetry that changed nothing came in since (handle's fast path)
        self._rest_due, self._rest_fresh = math.inf, False

    # ------------------------------------------------------------------ views
    fsm, manager, roster = _view("mission.fsm"), _view("mission.manager"), _view("mission.roster")
    tasking, regroup = _view("mission.tasking"), _view("mission.regroup")
    missions, lost_members = _view("mission.missions"), _view("mission.lost_members")
    reattach, backstop = _view("mission.reattach"), _view("fences.backstop")
    mission_state = _view("mission.mission_state")
    mission_progress_pct = _view("mission.manager.progress_pct")
    zones, base = _view("declarations.zones"), _view("declarations.base")
    fleet_id, active = _view("declarations.fleet_id"), _view("operator.active")
    autopilot = _view("monitor.state")

    def status(self, now: float) -> VehicleStatus | None:
        return self.views.status(now)

    def info(self) -> VehicleInfo:
        return self.views.info()

    def declared_state(self, now: float) -> DeclaredState:
        """What the operator declared, as this node holds it (the DECLARED queryable)."""
        return self.declarations.snapshot(now, self.mission.fsm.mission_id)

    # ------------------------------------------------------------------ inputs
    def handle(self, event: Input, now: float) -> list[Output]:
        self.now = now
        fresh, self._rest_fresh = self._rest_fresh, False
        if type(event) is Received and self._quiet(now):
            # a peer's telemetry (by far the most frequent input, 5 Hz per peer) and, with
            # no mission, its info: their route without the dispatch; when they change
            # nothing here (the usual case), no share record to keep, nothing to store or
            # route, and no deadline moved but the membership's
            events = self.traffic.one(event.msg, now)
            if events is not None:
                if not events:
                    self._rest_fresh = fresh
                    return []
                return self._peers_changed(events, now)
        sink: list[Output] = []
        self._route(self.stalls.check(now, self._due), now, sink)  # our own stall first
        outs: list[ModuleOutput] = []
        match event:
            case Received(msg):
                outs = self.inbound.message(msg, now)
            case AutopilotUpdate(state):
                d, ceiling = self.declarations, self.mission.fly_ceiling_rel_m()
                outs = [Publish(a) for a in self.monitor.update(state, now)]
                outs += self.mission.on_autopilot(state, d.base, now)
                outs += self.fences.on_autopilot(state, d.zones, d.base, ceiling, now)
            case AutopilotResult(result):
                routed = self.arbiter.on_result(result)
                what = f"autopilot result {result.request_id}"
                outs = (
                    self.routes.result(routed, now)
                    if routed
                    else self.inbound.no_route("result", what)
                )
            case PeerAlive(node_id, alive):
                outs = self.stalls.peer_events(self.members.on_alive(node_id, alive, now), now)
            case MavlinkUp(session_id, data):
                outs = self.passthrough.on_frames(session_id, data, self.views.node_view(), now)
            case BadInput(key, error):
                self.bad_input[key] += 1
                outs = [Note(logging.WARNING, f"dropped malformed input on {key}: {error}")]
            case PlanDone(outcome):
                outs = self.mission.on_plan(outcome, self.monitor.state, now)
            case Learned(state, sortie, source):
                outs = self.declarations.learn(state, source, now)
                if source == "database":  # at start: the share we flew (the vehicle may fly)
                    self.mission.restored(sortie, now)
            case StoreResult(ok, error):
                outs = self.declarations.stored(ok, error, now)
            case IdentityNews(conflict, untrusted):  # from the shell's identity book
                outs = [Publish(a) for a in self.monitor.on_identity(conflict, now)]
                self.mission.distrust(untrusted)
            case _:
                assert_never(event)
        self._route(outs, now, sink)
        zones, home = self.declarations.zones, self.monitor.state.home
        fly_ceiling = self.mission.fly_ceiling_rel_m  # asked only when a zone changed
        self._route(self.fences.new_zones(zones, home, fly_ceiling, now), now, sink)
        if self._manager.info_due():  # a PREMISSION ETA for the fleet: at once, not in 1 s
            sink.append(Publish(self.info()))
        self.routes.persist(sink, now)
        return sink

    def hear(self, events: Sequence[Input], now: float) -> list[tuple[int, list[Output]]]:
        """`handle` for each of `events` in turn, all at `now` (what a harness hands a
        node at one time, in one call): the outputs of those that answered, by index.
        A peer's telemetry that changes nothing runs as `handle`'s first branch does,
        without the call."""
        answered: list[tuple[int, list[Output]]] = []
        # handle's check for its first branch, again only after an input that took
        # another (a quiet one changes neither)
        quiet, i, n = self._quiet(now), 0, len(events)
        while i < n:
            if quiet:  # known peers' statuses heard again, a run at once (most of it)
                self.now, i = now, self.traffic.run(events, i, now)
                if i == n:
                    break
            event, changed = events[i], None
            i += 1
            if quiet and type(event) is Received:
                self.now = now
                changed = self.traffic.one(event.msg, now)
                if changed is not None and not changed:
                    continue
            if changed:
                self._rest_fresh = False
                out = self._peers_changed(changed, now)
            else:
                out = self.handle(event, now)
            if out:
                answered.append((i - 1, out))
            quiet = self._quiet(now)
        return answered

    def _quiet(self, now: float) -> bool:
        """Nothing to store, no stall: a peer's telemetry may take the fast path."""
        return not self.declarations.store_due and self.stalls.idle(now, self._due)

    def _peers_changed(self, events: list[PeerEvent], now: float) -> list[Output]:
        sink: list[Output] = []
        self._route(self.stalls.peer_events(events, now), now, sink)
        if self._manager.info_due():
            sink.append(Publish(self.info()))
        self.routes.persist(sink, now)
        return sink

    def _message(self, msg: msgspec.Struct, now: float) -> list[ModuleOutput]:
        return self.inbound.message(msg, now)  # a message a module hands back (Heard)

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
        t = min(self.beacon.next_deadline(), self.mission.next_deadline())
        for m in (self.operator, self.fences, self.avoid, self.stalls, self.passthrough):
            d = m.next_deadline()
            if d is not None and d < t:
                t = d
        self._rest_due, self._rest_fresh = t, True
        return t

    def on_timer(self, now: float) -> list[Output]:
        self.now, self._rest_fresh = now, False
        sink: list[Output] = []
        self._route(self.stalls.check(now, self._due), now, sink)  # our own stall first
        ap, ceiling, go = self.monitor.state, self.mission.fly_ceiling_rel_m(), self._route
        go(self.stalls.peer_events(self.members.on_timer(now), now), now, sink)
        go(self.stalls.on_timer(now), now, sink)  # suspects that did not come back
        go(self.operator.on_timer(now), now, sink)
        go(self.passthrough.on_timer(now, self.views.node_view), now, sink)
        go(self.fences.on_timer(ap, self.declarations.zones, ceiling, now), now, sink)
        go(self.mission.on_timer(self.views.context, now), now, sink)  # tasking, reattach
        go(self._avoidance_tick(now), now, sink)
        if now >= self.mission.fsm.next_deadline():
            # alerts that escalate with time (a lasting link loss) are
            # re-evaluated at every tick, not only when the link reports a new state
            go([Publish(a) for a in self.monitor.update(ap, now)], now, sink)
            go(self.mission.tick(self.views.facts(), self.views.context, now), now, sink)
        if self.beacon.status_due(now) and (st := self.status(now)) is not None:
            sink.append(Publish(st))
        if self.beacon.info_due(now):
            sink.append(Publish(self.info()))
        self.routes.persist(sink, now)
        return sink

    def _avoidance_tick(self, now: float) -> list[ModuleOutput]:
        """Collision avoidance at 5 Hz (safety/module.py), and the mission manager's
        close pads with it (safety/pad_sequence.py)."""
        due = self.avoid.next_deadline()
        if due is None or now < due:
            return []
        m, ap, a, z = self._manager, self.monitor.state, self.arbiter, self.declarations.zones
        climb = m.takeoff_alt_m if m.phase == Phase.CLIMBING else None
        out = self.mission.pads_tick(ap, now)
        return out + self.avoid.tick(
            now,
            self.status(now),
            ap,
            zones=z,
            climb_target_rel_m=climb,
            holder=a.holder,
            items=m.uploaded,
            will_steer=a.will_steer,
        )
