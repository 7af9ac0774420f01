"""A whole swarm in one process, in fast time, without sockets or threads: for each
vehicle a simulated autopilot (`VehicleEndpoint`), the node's autopilot link
(`LinkCore`) and the node itself (`NodeCore`), exchanging real MAVLink bytes and real
swarm messages while time jumps from deadline to deadline. A 15-minute mission of a
heterogeneous fleet runs in seconds and every run is the same.

    fleet = FastFleet.build([(1, "vtol"), (7, "copter")], profiles)
    fleet.broadcast(Command(...))           # as if a ground station had published it
    fleet.run_until(lambda: ..., timeout_s=900)

Swarm messages between nodes go through the LAN encoding (encode, decode), so what
travels is what would travel on Zenoh.
"""

from __future__ import annotations

import functools
import heapq
import itertools
import random
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

import msgspec

from swarm_node.core.autopilot.link import Complete, LinkCore, LinkSettings, Transmit
from swarm_node.core.autopilot.link import Output as LinkOutput
from swarm_node.core.autopilot.requests import ApRequest
from swarm_node.core.declared import SortieRecord
from swarm_node.core.mission.tasking import TaskingSettings
from swarm_node.core.node import (
    AutopilotResult,
    AutopilotUpdate,
    Input,
    Learned,
    NodeCore,
    NodeSettings,
    Note,
    PeerAlive,
    Persist,
    PlanDone,
    PlanJob,
    Publish,
    Received,
    StoreResult,
    Submit,
)
from swarm_node.core.profile import VehicleProfile
from swarm_node.plan_memo import PlanMemo
from swarm_node.testing import published_matching
from swarm_proto import DeclaredState, EncodeError, MissionType, VehicleType, lan, radio

from .core import SITL_HOME, Home, VehicleEndpoint
from .runtime.server import spread_homes

AP_POLL_S = 0.2  # the node reads the link's state at 5 Hz, as the runtime does
#: which simulated model flies a database profile of each vehicle type
MODEL_OF_TYPE = {
    VehicleType.VTOL: "vtol",
    VehicleType.PLANE: "plane",
    VehicleType.COPTER: "copter",
    VehicleType.ROVER: "rover",
    VehicleType.BOAT: "boat",
}


@functools.cache
def seed_tasking() -> TaskingSettings:
    """Voting weights, re-tasking rules and payload hierarchy of the seed database."""
    from swarm_node.database import SwarmDatabase
    from swarm_node.runtime.node import tasking_settings_of

    with SwarmDatabase.memory() as db:
        return tasking_settings_of(db)


@dataclass
class MemoryStore:
    """A node's database as FastFleet keeps it: the last state it stored (`full`: the
    disk is full, every store fails)."""

    state: DeclaredState | None = None
    sortie: SortieRecord | None = None
    full: bool = False
    writes: int = 0
    failures: int = 0

    def save(self, p: Persist) -> StoreResult:
        if self.full:
            self.failures += 1
            return StoreResult(False, "disk is full")
        self.state, self.sortie = p.state, p.sortie
        self.writes += 1
        return StoreResult(True)


@dataclass
class SimVehicle:
    node: NodeCore
    link: LinkCore
    endpoint: VehicleEndpoint
    next_poll: float = 0.0
    tokens: dict[int, int] = field(default_factory=dict)  # link token -> request id
    stalled_until: float = float("-inf")  # the node's process is stopped until then
    backlog: bytearray = field(default_factory=bytearray)  # MAVLink waiting in its socket
    down: bool = False  # the node's process is dead (kill -9); the vehicle flies on
    store: MemoryStore = field(default_factory=MemoryStore)  # its database
    # its link's, autopilot poll's and simulator's next deadline at its last scheduling
    # (None: ask them again): a node input with no output moves only the node's
    others_due: float | None = None


@dataclass
class FastFleet:
    vehicles: dict[int, SimVehicle]
    now: float
    published: list[tuple[float, int, msgspec.Struct]] = field(default_factory=list)
    notes: list[tuple[float, int, str]] = field(default_factory=list)
    submitted: list[tuple[float, int, ApRequest]] = field(default_factory=list)
    plan_delay_s: float = 0.0  # simulated time a plan job takes
    plans: PlanMemo = field(default_factory=PlanMemo)  # each distinct plan job planned once
    # with a list here, every swarm message published is also appended to it as (time it
    # is heard, sender, LAN bytes, type): the part of a fleet split over processes
    # (parallel_fleet.py)
    export: list[tuple[float, int, bytes, type]] | None = None
    # the swarm's network latency: a message published at t is heard at t + latency_s
    # (0: at once; a fleet split over processes needs some, to run apart meanwhile)
    latency_s: float = 0.0
    loss: float = 0.0  # fraction of swarm messages lost between nodes (seeded)
    groups: dict[int, int] | None = None  # a partition: nodes hear only their own group
    # nodes that hear nothing until a time, while the others still hear them: a node whose
    # radio gateway is descheduled (the others' gateways go on predicting it): vid -> until
    deaf: dict[int, float] = field(default_factory=dict)
    seed: int = 1
    # a LAN swarm (Zenoh): every node's liveliness token is seen by its peers, who know
    # it by that token rather than by the staleness of its telemetry (the membership's
    # cheaper path); a partition withdraws the tokens across it a lease later, a vanished
    # node's token goes a lease later too (`hold_tokens`; off: peers known by telemetry)
    liveliness: bool = False
    lease_s: float = 2.0  # the Zenoh lease (swarm_node/runtime/config.py)
    # each node takes what it hears at one time in one call (off: entry by entry, the
    # reference the same run must match, tests/swarm_sim/test_fast_fleet.py)
    hear_together: bool = True
    # what a restarted node is built with (restart_node)
    profiles: Mapping[int, VehicleProfile] = field(default_factory=dict)
    settings: NodeSettings | None = None
    tasking: TaskingSettings | None = None
    mission_defaults: Mapping[MissionType, Mapping[str, float]] | None = None
    # every swarm message heard as the radio carries it (`radio.quantized`: floats at the
    # radio's resolution; one the radio cannot encode as the LAN carries it), as in
    # `swarm-sim demo --radio` where each node is behind its own gateway
    over_air: bool = False

    def __post_init__(self) -> None:
        # swarm messages and results in time order; a broadcast is one entry for all its
        # recipients (they take it in turn, as separate entries would be taken)
        self._bus: list[tuple[float, int, tuple[int, ...], Input]] = []
        self._seq = itertools.count()
        self._tokens = itertools.count(1)
        self._rng = random.Random(self.seed)
        self.lost_messages = 0
        self.batches_heard = 0  # batches the nodes took together (_hear_together)
        self.heard_messages = 0  # swarm messages handed to nodes (one per hearer)
        self._scans: dict[tuple[type, int | None], tuple[int, object, list]] = {}
        # one global deadline heap: each vehicle's earliest deadline (its
        # endpoint, link, poll and node), pushed again whenever the vehicle was touched;
        # entries that no longer match `_due` are stale and skipped
        self._timers: list[tuple[float, int, int]] = []
        self._due: dict[int, float] = {}
        self._rank: dict[int, int] = {}
        self._dirty: set[int] = set()
        self._heard: set[int] = set()  # nodes that took an input and answered nothing
        self._from: dict[int, int] = {}  # bus entries for every vehicle but their sender
        self._token_ids: list[int] = []  # the peers whose liveliness tokens are seen here
        self._token_groups: dict[int, int] | None = None  # the partition they were seen in
        self._everyone: tuple[int, ...] = ()  # the vehicles when `_others` was made
        self._others: dict[int, tuple[int, ...]] = {}  # every vehicle but the key
        self._rescan()

    @classmethod
    def build(
        cls,
        members: Sequence[int],
        profiles: Mapping[int, VehicleProfile],
        *,
        home: Home = SITL_HOME,
        spacing_m: float = 40.0,
        start_unix_s: float = 1.8e9,
        settings: NodeSettings | None = None,
        tasking: TaskingSettings | None = None,
        mission_defaults: Mapping[MissionType, Mapping[str, float]] | None = None,
        homes: Sequence[Home] | None = None,
    ) -> FastFleet:
        """Vehicles `members` (database ids), each simulated as its profile's model,
        homes `spacing_m` apart going east (or the `homes` given, one per member); voting
        and re-tasking as the seed database sets them unless `tasking` is given."""
        vehicles: dict[int, SimVehicle] = {}
        if homes is not None and len(homes) != len(members):
            raise ValueError(f"{len(homes)} homes for {len(members)} vehicles")
        homes = list(homes) if homes is not None else spread_homes(home, len(members), spacing_m)
        for i, vid in enumerate(members):
            profile = profiles[vid]
            model = MODEL_OF_TYPE[profile.vehicle_type]
            h = homes[i]
            endpoint = VehicleEndpoint.create(model, home=h, now=start_unix_s, sysid=vid)
            link = LinkCore(
                LinkSettings(vehicle_type=profile.vehicle_type, link_timeout_s=0.6), start_unix_s
            )
            node = NodeCore(
                profile,
                settings or NodeSettings(),
                now=start_unix_s,
                fleet_profiles=profiles,
                tasking_settings=tasking or seed_tasking(),
                mission_defaults=mission_defaults or {},
            )
            vehicles[vid] = SimVehicle(node, link, endpoint, next_poll=start_unix_s)
        return cls(
            vehicles,
            start_unix_s,
            profiles=profiles,
            settings=settings,
            tasking=tasking,
            mission_defaults=mission_defaults,
        )

    # ------------------------------------------------------------------ inputs
    def broadcast(self, msg: msgspec.Struct, to: Sequence[int] | None = None) -> None:
        """Deliver a swarm message (e.g. from a ground station) to nodes now."""
        decoded = self._wire(msg, lan.encode(msg))
        targets = tuple(to) if to is not None else tuple(self.vehicles)
        heapq.heappush(self._bus, (self.now, next(self._seq), targets, Received(decoded)))

    def _wire(self, msg: msgspec.Struct, raw: bytes) -> msgspec.Struct:
        """`msg` as its receivers decode it (the LAN's bytes `raw`, or over the air)."""
        if self.over_air:
            try:
                return radio.quantized(msg, now_unix_s=self.now)
            except EncodeError:
                pass
        return lan.decode(raw, type(msg))

    def _deliver(self, vid: int, event: Input, at: float) -> None:
        heapq.heappush(self._bus, (at, next(self._seq), (vid,), event))

    def deliver(self, vid: int, event: Input, at: float) -> None:
        """Hand vehicle `vid`'s node `event` at `at` (a fault, a peer's liveliness)."""
        self._deliver(vid, event, at)

    def hold_tokens(self, ids: Sequence[int] | None = None) -> None:
        """A LAN swarm: the nodes here see the liveliness tokens of peers `ids` (default:
        the fleet's vehicles; a split fleet names the other parts' too) from now on, as
        a node's liveliness subscriber lists the tokens already declared when it starts."""
        self.liveliness = True
        known = set(self._token_ids)
        self._token_ids += [
            i for i in (ids if ids is not None else self.vehicles) if i not in known
        ]
        self._token_groups = dict(self.groups) if self.groups is not None else None
        for vid in self.vehicles:
            for other in self._token_ids:
                if other != vid and other not in known and self._reachable(vid, other):
                    self._deliver(vid, PeerAlive(other, True), self.now)

    def _retoken(self) -> None:
        """The partition changed: tokens across a new cut go a lease later, tokens across
        a healed one are seen again at once."""
        old, self._token_groups = (
            self._token_groups,
            (dict(self.groups) if self.groups is not None else None),
        )
        for vid in self.vehicles:
            for other in self._token_ids:
                if other == vid:
                    continue
                before = old is None or old.get(vid) == old.get(other)
                now_ = self._reachable(vid, other)
                if before and not now_:
                    self._deliver(vid, PeerAlive(other, False), self.now + self.lease_s)
                elif now_ and not before:
                    self._deliver(vid, PeerAlive(other, True), self.now)

    # ------------------------------------------------------------------ plumbing
    def _node_out(self, vid: int, outputs: list) -> None:
        v = self.vehicles[vid]
        self._dirty.add(vid)  # its node had an input: its deadlines may have moved
        for o in outputs:
            if isinstance(o, Publish):
                self.published.append((self.now, vid, o.msg))
                raw = lan.encode(o.msg)
                wire = self._wire(o.msg, raw)
                seq = next(self._seq)
                if self.groups is None and self.loss <= 0.0 and not self.deaf:  # all hear it
                    others = self._others_of(vid)
                    self._from[seq] = vid
                else:
                    others = tuple(o for o in self.vehicles if o != vid and self._carried(vid, o))
                heard = self.now + self.latency_s
                heapq.heappush(self._bus, (heard, seq, others, Received(wire)))
                if self.export is not None:
                    self.export.append((heard, vid, raw, type(o.msg)))
            elif isinstance(o, Persist):
                self._deliver(vid, v.store.save(o), self.now)
            elif isinstance(o, Submit):
                self.submitted.append((self.now, vid, o.request))
                token = next(self._tokens)
                v.tokens[token] = o.request.request_id
                self._link_out(vid, v.link.submit(token, o.request, self.now))
            elif isinstance(o, Note):
                self.notes.append((self.now, vid, o.text))
            elif isinstance(o, PlanJob):  # inline, after the simulated planning time
                done = PlanDone(self.plans.run(o.request))
                self._deliver(vid, done, self.now + self.plan_delay_s)

    def _others_of(self, vid: int) -> tuple[int, ...]:
        """Every vehicle here but `vid`, in the fleet's order (kept while the fleet's
        vehicles stay the same)."""
        if self._everyone != tuple(self.vehicles):
            self._everyone, self._others = tuple(self.vehicles), {}
        others = self._others.get(vid)
        if others is None:
            others = self._others[vid] = tuple(o for o in self._everyone if o != vid)
        return others

    def _carried(self, src: int, dst: int) -> bool:
        """Whether a message from `src` reaches `dst` (a partition, seeded loss)."""
        if self.groups is not None and self.groups.get(src) != self.groups.get(dst):
            return False
        if self.deaf.get(dst, float("-inf")) > self.now:
            return False
        if self.loss > 0.0 and self._rng.random() < self.loss:
            self.lost_messages += 1
            return False
        return True

    def _link_out(self, vid: int, outputs: list[LinkOutput]) -> None:
        """Carry out the link's outputs: results to the node, bytes to the vehicle, and
        the vehicle's immediate answers back into the link, until nothing is left."""
        v = self.vehicles[vid]
        self._dirty.add(vid)
        while outputs:
            data = bytearray()
            for o in outputs:
                if isinstance(o, Transmit):
                    data += o.data
                elif isinstance(o, Complete):
                    rid = v.tokens.pop(o.token, o.result.request_id)
                    result = msgspec.structs.replace(o.result, request_id=rid)
                    self._deliver(vid, AutopilotResult(result), self.now)
                # Emit: the node polls the state; events only speed that up in the runtime
            back = v.endpoint.receive(bytes(data), self.now) if data else b""
            outputs = v.link.receive(back, self.now) if back else []

    # ------------------------------------------------------------------ scheduling
    def _vehicle_deadline(self, v: SimVehicle) -> float:
        ep = v.endpoint.next_deadline()
        v.others_due = None
        if v.down:  # the autopilot flies on; nobody reads it
            t = float("inf")
        elif v.stalled_until > self.now:  # nothing of the node runs until it resumes
            t = v.stalled_until
        else:
            others = min(v.link.next_deadline(), v.next_poll)
            if ep is not None and ep < others:
                others = ep
            v.others_due = others
            node = v.node.next_deadline()
            return node if node < others else others
        return ep if ep is not None and ep < t else t

    def _schedule_node(self, vid: int) -> None:
        """Vehicle `vid`'s node took an input and answered nothing: only the node's
        deadline may have moved (a peer's telemetry, the usual bus message)."""
        v = self.vehicles.get(vid)
        if v is None or v.others_due is None:
            self._schedule(vid)
            return
        node = v.node.next_deadline()
        self._push(vid, node if node < v.others_due else v.others_due)

    def _reschedule(self) -> None:
        """The vehicles something happened to since the last time, afresh."""
        for vid in self._dirty:
            self._schedule(vid)
        for vid in self._heard:
            if vid not in self._dirty:
                self._schedule_node(vid)
        self._dirty.clear()
        self._heard.clear()

    def _schedule(self, vid: int) -> None:
        v = self.vehicles.get(vid)
        if v is None:
            self._due.pop(vid, None)
            return
        self._push(vid, self._vehicle_deadline(v))

    def _push(self, vid: int, d: float) -> None:
        """Vehicle `vid` is due at `d`: into the heap if that is new (the entry it
        had is skipped as stale when it comes up)."""
        if self._due.get(vid) != d:
            self._due[vid] = d
            heapq.heappush(self._timers, (d, self._rank[vid], vid))

    def _rescan(self) -> None:
        """Every vehicle's deadline afresh: at each entry from outside (a test may have
        changed a vehicle between runs: swapped its endpoint, sent its link a request)."""
        if self.liveliness and self.groups != self._token_groups:
            self._retoken()
        self._rank = {vid: i for i, vid in enumerate(self.vehicles)}
        self._timers = []
        self._due = {}
        self._dirty.clear()
        self._heard.clear()
        for vid in self.vehicles:
            self._schedule(vid)

    def _next_timer(self) -> float:
        timers = self._timers
        while timers:
            d, _rank, vid = timers[0]
            if self._due.get(vid) == d and vid in self.vehicles:
                return d
            heapq.heappop(timers)  # stale: the vehicle moved its deadline or is gone
        return float("inf")

    def _deadline(self) -> float:
        self._reschedule()
        t = self._bus[0][0] if self._bus else float("inf")
        return min(t, self._next_timer())

    def next_deadline(self) -> float:
        """When anything here is next due: a message or result on the bus, a vehicle's
        timer (a split fleet's parts agree their windows on it)."""
        return self._deadline()

    def step(self) -> None:
        """Everything due at the next deadline: the swarm messages and results first,
        then each vehicle whose time has come (in the fleet's order)."""
        self._rescan()
        self._step()

    def _step(self) -> None:
        self._step_at(self._deadline())

    def receive(self, raw: bytes, cls: type, at: float) -> None:
        """A swarm message published elsewhere (another part of a split fleet), for
        every vehicle here at `at`."""
        msg: msgspec.Struct = lan.decode(raw, cls)
        heapq.heappush(self._bus, (at, next(self._seq), tuple(self.vehicles), Received(msg)))

    def step_at(self, t: float) -> float:
        """Everything due at `t` (a split fleet's common time; nothing may be due
        earlier); returns the next deadline."""
        self._step_at(t)
        return self._deadline()

    def _step_at(self, t: float) -> None:
        self.now = max(self.now, t)
        bus = self._bus
        while bus and bus[0][0] <= self.now:
            batch = []
            while bus and bus[0][0] <= self.now:
                batch.append(heapq.heappop(bus))
            if not self._hear_together(batch):
                for entry in batch:
                    self._hear_one(entry)
        self._reschedule()
        due: set[int] = set()
        while self._next_timer() <= self.now:
            vid = heapq.heappop(self._timers)[2]
            self._due.pop(vid, None)  # pushed again after its timers, even at the same time
            due.add(vid)
        for vid in sorted(due, key=self._rank.__getitem__):
            self._timers_of(vid, self.vehicles[vid])
            self._schedule(vid)
            # scheduled after all its timers did: what they marked is taken into account
            # (nothing else touches this vehicle before the next step)
            self._dirty.discard(vid)
            self._heard.discard(vid)

    def _hear_one(self, entry: tuple[float, int, tuple[int, ...], Input]) -> None:
        """A bus entry, target by target."""
        _, seq, targets, event = entry
        self._from.pop(seq, None)
        vehicles, now = self.vehicles, self.now
        for vid in targets:
            v = vehicles.get(vid)
            if v is None or v.down:  # a killed vehicle or node hears nothing
                continue
            if v.stalled_until > now:  # a stopped process reads it when it resumes
                heapq.heappush(self._bus, (v.stalled_until, seq, (vid,), event))
                continue
            out = v.node.handle(event, now)
            self.heard_messages += type(event) is Received
            if out:
                self._node_out(vid, out)  # anything of it may have moved
            else:
                self._heard.add(vid)  # only its node's deadline may have moved

    def _hear_together(self, batch: list[tuple[float, int, tuple[int, ...], Input]]) -> bool:
        """The usual batch: swarm messages due now, each for every vehicle here but its
        sender, none of them stopped or dead. Each node takes its share in one call
        (`NodeCore.hear`, in the bus's order), then what they answered is carried out in
        the order entry by entry, target by target would have given (only the harness
        sees the answers: no node hears them before). False: not such a batch, nothing
        done (take it entry by entry)."""
        vehicles, now = self.vehicles, self.now
        if len(batch) < 2 or not self.hear_together:
            return False
        n = len(vehicles)
        senders: list[int | None] = []
        for _, seq, targets, event in batch:
            sender = self._from.get(seq)
            if type(event) is not Received or len(targets) != (n - 1 if sender in vehicles else n):
                return False  # (targets were every vehicle but the sender when it was sent)
            senders.append(sender)
        if any(v.down or v.stalled_until > now for v in vehicles.values()):
            return False
        for _, seq, _, _ in batch:
            self._from.pop(seq, None)
        self.batches_heard += 1
        events = [entry[3] for entry in batch]
        sent: dict[int | None, list[int]] = {}  # each sender's entries in the batch
        for k, sender in enumerate(senders):
            sent.setdefault(sender, []).append(k)
        answers: list[tuple[int, int, int, list]] = []
        for vid, v in vehicles.items():
            own = sent.get(vid)
            if own is None:
                mine = events
            elif len(own) == 1:
                mine = events[: own[0]] + events[own[0] + 1 :]
            else:
                mine = [
                    event for sender, event in zip(senders, events, strict=True) if sender != vid
                ]
            self.heard_messages += len(mine)
            answered = v.node.hear(mine, now)
            if answered:
                ks = [k for k, sender in enumerate(senders) if sender != vid]
                rank = self._rank[vid]
                answers += [(ks[i], rank, vid, out) for i, out in answered]
            else:
                self._heard.add(vid)  # only its node's deadline may have moved
        answers.sort(key=lambda a: (a[0], a[1]))
        for _k, _rank, vid, out in answers:
            self._node_out(vid, out)
        return True

    def _timers_of(self, vid: int, v: SimVehicle) -> None:
        ep = v.endpoint.next_deadline()
        if v.down:  # the autopilot flies on; nobody reads it
            if ep is not None and ep <= self.now:
                v.endpoint.on_timer(self.now)
            return
        if v.stalled_until > self.now:  # the autopilot flies on; its bytes wait
            if ep is not None and ep <= self.now:
                v.backlog += v.endpoint.on_timer(self.now)
            return
        if v.backlog:
            self._resume(vid, v)
        if ep is not None and ep <= self.now:
            back = v.endpoint.on_timer(self.now)
            if back:
                self._link_out(vid, v.link.receive(back, self.now))
        if v.link.next_deadline() <= self.now:
            self._link_out(vid, v.link.on_timer(self.now))
        if v.next_poll <= self.now:
            v.next_poll = max(v.next_poll + AP_POLL_S, self.now)
            self._node_out(vid, v.node.handle(AutopilotUpdate(v.link.state), self.now))
        if v.node.next_deadline() <= self.now:
            self._node_out(vid, v.node.on_timer(self.now))

    def _resume(self, vid: int, v: SimVehicle) -> None:
        """A stopped node process runs again, in the worst order for it: its timers
        first (the link's silence timer and the node's tick run late), then what waited
        in its socket meanwhile."""
        self._link_out(vid, v.link.on_timer(self.now))
        self._node_out(vid, v.node.handle(AutopilotUpdate(v.link.state), self.now))
        self._node_out(vid, v.node.on_timer(self.now))
        data, v.backlog = bytes(v.backlog), bytearray()
        self._link_out(vid, v.link.receive(data, self.now))

    def stall(self, vid: int, seconds: float) -> None:
        """Stop vehicle `vid`'s node process (SIGSTOP) for `seconds`: its autopilot flies
        on and what it sends waits in the socket; nothing of the node runs meanwhile."""
        self.vehicles[vid].stalled_until = self.now + seconds
        self._dirty.add(vid)

    def kill_node(self, vid: int) -> None:
        """The node's process dies (kill -9) while its vehicle flies on: the others lose
        its liveliness token at once (Zenoh notices a dead process in milliseconds)."""
        v = self.vehicles[vid]
        v.down = True
        self._dirty.add(vid)
        for other in self.vehicles:
            if other != vid:
                self._deliver(other, PeerAlive(vid, False), self.now)

    def restart_node(self, vid: int, *, keep_database: bool = True) -> NodeCore:
        """Start node `vid` again (a new process: new node core, new autopilot link) on
        its database (`keep_database=False`: a new, empty one); it reattaches to its
        vehicle as it is. It and its peers exchange their declared state as they meet
        (each asks the other's DECLARED queryable)."""
        v = self.vehicles[vid]
        profile = v.node.profile
        if not keep_database:
            v.store = MemoryStore(full=v.store.full)
        v.node = NodeCore(
            profile,
            self.settings or NodeSettings(),
            now=self.now,
            fleet_profiles=self.profiles or {profile.vehicle_id: profile},
            tasking_settings=self.tasking or seed_tasking(),
            mission_defaults=self.mission_defaults or {},
        )
        v.link = LinkCore(
            LinkSettings(vehicle_type=profile.vehicle_type, link_timeout_s=0.6), self.now
        )
        v.tokens, v.down, v.backlog = {}, False, bytearray()
        v.stalled_until, v.next_poll = float("-inf"), self.now
        self._dirty.add(vid)
        stored = v.store.state or DeclaredState(vehicle_id=vid, time_unix_s=self.now)
        self._deliver(vid, Learned(stored, v.store.sortie, "database"), self.now)
        for other, o in self.vehicles.items():
            if other == vid or o.down:
                continue
            self._deliver(other, PeerAlive(vid, True), self.now)
            self._deliver(vid, PeerAlive(other, True), self.now)
        self.exchange_declared(vid)
        return v.node

    def exchange_declared(self, vid: int, delay_s: float = 0.1) -> None:
        """Node `vid` and every peer it reaches ask each other's DECLARED queryable."""
        v = self.vehicles[vid]
        for other, o in self.vehicles.items():
            if other == vid or o.down or not self._reachable(vid, other):
                continue
            at = self.now + delay_s
            self._deliver(vid, Learned(o.node.declared_state(self.now), None, f"peer {other}"), at)
            self._deliver(other, Learned(v.node.declared_state(self.now), None, f"peer {vid}"), at)

    def _reachable(self, a: int, b: int) -> bool:
        return self.groups is None or self.groups.get(a) == self.groups.get(b)

    def reboot_autopilot(self, vid: int, *, keep_stores: bool = False) -> None:
        """Power-cycle vehicle `vid`'s autopilot where it stands: it boots again, by
        default with empty mission, fence and rally stores; the node's link
        sees its time since boot go back."""
        self.vehicles[vid].endpoint.reboot(self.now, keep_stores=keep_stores)
        self._dirty.add(vid)

    def kill(self, vid: int) -> SimVehicle:
        """The vehicle and its node vanish at once (a crash, a dead companion computer):
        nothing more is heard from it; the others notice by its silence (on a LAN, by
        its liveliness token, which goes a lease later)."""
        if self.liveliness:
            self._token_ids = [i for i in self._token_ids if i != vid]
            for other in self.vehicles:
                if other != vid:
                    self._deliver(other, PeerAlive(vid, False), self.now + self.lease_s)
        return self.vehicles.pop(vid)

    def run_for(self, seconds: float) -> None:
        end = self.now + seconds
        self._rescan()
        while self._deadline() <= end:
            self._step()
        self.now = end

    def run_before(self, end: float) -> None:
        """Everything due before `end` (not at it), then the clock at `end`: one window
        of a split fleet, whose parts hear each other `latency_s` late (nothing heard
        from outside can be due before the window's end). Nothing outside the fleet may
        have changed a vehicle since the last window (messages come by `receive`)."""
        while self._deadline() < end:
            self._step()
        self.now = max(self.now, end)

    def run_until(self, predicate: Callable[[], bool], timeout_s: float) -> bool:
        end = self.now + timeout_s
        self._rescan()
        while not predicate():
            if self._deadline() > end:
                self.now = end
                return False
            self._step()
        return True

    def messages(self, cls: type, sender: int | None = None) -> list:
        """Every published `cls` (from `sender`), in order. Scans only what was published
        since the last call with the same arguments (a predicate calling this at every
        step of a long flight stays linear), unless `published` was changed under it."""
        return published_matching(self.published, self._scans, cls, sender)
