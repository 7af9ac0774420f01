"""A fleet of radio node cores on the emulated channel in simulated time (pure).

Like aioquic's loss tests: no sockets, no threads; time jumps to the earliest deadline of
any node, the channel, a pending serial write or a producer, so a minute of swarm runs in
a second and every run repeats exactly from its seed. Write and read latencies can be
jittered (from the seed) to stand in for a busy computer, and each node can have its own
clock offset.

    fleet = Fleet(ChannelParams(loss=0.3, seed=1), timing, tdm, key)
    for i in range(1, 9):
        fleet.add(i, producer=status_producer(i))
    fleet.run(until=fleet.t + 20.0)
    fleet.deliveries   # (time, receiver, sender, radio bytes)

A member can also be a whole gateway (`add(..., bridge=Bridge(...), lan=...)`): its
`lan` producer stands for the node above it, publishing messages on its LAN; they go
through the bridge as in `radio-gateway run` (an own VehicleStatus to the node's send on
error, the rest to the outbox), what the node hears goes through the bridge back to the
LAN (`published`: (time, receiver, message), heard and predicted).
"""

from __future__ import annotations

import heapq
import itertools
import random
from collections.abc import Callable
from dataclasses import dataclass, field

import msgspec

from radio_gateway.core.airtime import LinkTiming
from radio_gateway.core.bridge import Bridge, OwnStatus
from radio_gateway.core.node import Deliver, NodeConfig, Notice, RadioNode, Transmit
from radio_gateway.core.outbox import OutMessage
from radio_gateway.core.slots import TdmConfig
from radio_gateway.core.telemetry import SendOnErrorConfig
from swarm_proto import lan as lan_codec
from swarm_proto.topics import key_of

from .model import ChannelParams, RadioChannelModel

Producer = Callable[[float], list[OutMessage]]  # source time -> messages to submit
LanProducer = Callable[[float], list[msgspec.Struct]]  # what the node above publishes


@dataclass
class Member:
    node: RadioNode
    module: int
    offset_s: float = 0.0  # this node's clock minus true time
    producer: Producer | None = None
    produce_every_s: float = 0.2
    next_produce: float = 0.0
    active: bool = True
    bridge: Bridge | None = None  # a whole gateway: its LAN side
    lan: LanProducer | None = None
    silent_s: float = 3.0  # predictions stop for a peer the radio has not heard this long


@dataclass
class Fleet:
    params: ChannelParams
    timing: LinkTiming
    tdm: TdmConfig
    key: bytes
    t: float = 1.75e9
    max_nodes: int = 64
    write_jitter_s: float = 0.0  # uniform extra delay of each serial write
    read_jitter_s: float = 0.0  # uniform extra delay before a host reads what arrived
    seed: int = 0
    latest_keep: int = 1  # NodeConfig.latest_keep of every node
    model: RadioChannelModel = field(init=False)
    members: dict[int, Member] = field(default_factory=dict)
    deliveries: list[tuple[float, int, int, bytes]] = field(default_factory=list)
    notices: list[tuple[float, int, Notice]] = field(default_factory=list)
    transmits: list[tuple[float, int, Transmit]] = field(default_factory=list)
    published: list[tuple[float, int, msgspec.Struct]] = field(default_factory=list)
    swarm: str = "default"
    keep_predictions: bool = True  # record gateways' predicted statuses in `published`
    _events: list[tuple[float, int, str, int, bytes, bool]] = field(default_factory=list)
    _seq: itertools.count[int] = field(default_factory=itertools.count)
    _rng: random.Random = field(init=False)
    _dl: dict[int, float] = field(default_factory=dict)  # member deadlines (fleet time)
    _dirty: set[int] = field(default_factory=set)  # members whose deadline to recompute

    def __post_init__(self) -> None:
        self.model = RadioChannelModel(self.max_nodes, self.params)
        bd = {230_400: 8, 115_200: 7, 57_600: 6, 38_400: 5, 19_200: 4, 9_600: 3}
        for i in range(self.max_nodes):
            self.model.preset(
                i,
                BD=bd[self.timing.serial_baud],
                BR=1 if self.timing.rf_bps == 115_200 else 0,
                RO=self.timing.ro_chars,
                PK=self.timing.max_packet,
                RB=self.timing.max_packet,
                DT=0xFFFF,
                MT=0,
                RR=0,
            )
        self._rng = random.Random(self.seed)

    def add(
        self,
        node_id: int,
        *,
        producer: Producer | None = None,
        produce_every_s: float | None = None,
        offset_s: float = 0.0,
        source_stratum: int = 0,
        initial_members: tuple[int, ...] = (),
        send_on_error: SendOnErrorConfig | None = None,
        adaptive: bool = False,
        min_level: int = 0,
        bridge: Bridge | None = None,
        lan: LanProducer | None = None,
    ) -> RadioNode:
        if node_id in self.members and self.members[node_id].active:
            raise ValueError(f"node {node_id} is already running")
        module = len(self.members) if node_id not in self.members else self.members[node_id].module
        cfg = NodeConfig(
            node_id,
            timing=self.timing,
            tdm=self.tdm,
            source_stratum=source_stratum,
            initial_members=initial_members,
            seed=self.seed,
            latest_keep=self.latest_keep,
            send_on_error=send_on_error,
            adaptive=adaptive,
            min_level=min_level,
        )
        node = RadioNode(cfg, self.key, self.t + offset_s)
        every = produce_every_s if produce_every_s is not None else self.tdm.cycle_s
        self.members[node_id] = Member(
            node,
            module,
            offset_s,
            producer,
            every,
            self.t + self._rng.uniform(0, every),
            bridge=bridge,
            lan=lan,
        )
        self._dirty.add(node_id)
        return node

    def stop(self, node_id: int) -> None:
        """The node goes silent (power off): its module stays on the channel, unused."""
        self.members[node_id].active = False
        self._dirty.add(node_id)

    def resume(self, node_id: int) -> None:
        """A stopped node's process runs again, with its state (a stall: descheduled,
        swapped out); what its port received meanwhile is lost, as a real stall's
        backlog is too old for the replay window."""
        self.members[node_id].active = True
        self._dirty.add(node_id)

    def node(self, node_id: int) -> RadioNode:
        return self.members[node_id].node

    # ------------------------------------------------------------------ loop
    def _member_deadline(self, m: Member) -> float:
        times = [m.node.next_deadline() - m.offset_s]
        if m.producer is not None or m.lan is not None:
            times.append(m.next_produce)
        if m.bridge is not None:
            d = m.bridge.next_deadline()
            if d is not None:
                times.append(d - m.offset_s)
        return min(times)

    def _next(self) -> float:
        """The earliest deadline; members' deadlines are kept and recomputed only for
        members something happened to (a 50-node fleet is O(1) per event, not O(n))."""
        for nid in self._dirty:
            m = self.members.get(nid)
            if m is not None and m.active:
                self._dl[nid] = self._member_deadline(m)
            else:
                self._dl.pop(nid, None)
        self._dirty.clear()
        times = [self.t + 1.0]
        if self._dl:
            times.append(min(self._dl.values()))
        d = self.model.next_deadline()
        if d is not None:
            times.append(d)
        if self._events:
            times.append(self._events[0][0])
        return min(times)

    def run(self, until: float) -> None:
        stuck = 0
        self._dirty.update(self.members)
        while True:
            t = max(self.t, self._next())
            if t > until:
                self.t = until
                return
            stuck = stuck + 1 if t == self.t else 0
            if stuck > 10_000:
                raise RuntimeError(f"simulated time stuck at {t}: a deadline never clears")
            self.t = t
            by_module = {m.module: nid for nid, m in self.members.items()}
            while self._events and self._events[0][0] <= t:
                _, _, kind, idx, data, late = heapq.heappop(self._events)
                if kind == "write":
                    self.model.from_host(idx, data, t, late=late)
                else:
                    nid = by_module.get(idx)
                    if nid is not None and self.members[nid].active:
                        self._dirty.add(nid)
                        self._actions(
                            nid,
                            self.members[nid].node.handle_bytes(
                                data, t + self.members[nid].offset_s
                            ),
                        )
            for idx, data in self.model.on_timer(t):
                delay = self._rng.uniform(0, self.read_jitter_s) if self.read_jitter_s else 0.0
                heapq.heappush(self._events, (t + delay, next(self._seq), "read", idx, data, False))
            due = [nid for nid, d in self._dl.items() if d <= t] + list(self._dirty)
            for nid in dict.fromkeys(due):
                m = self.members[nid]
                if not m.active:
                    continue
                self._dirty.add(nid)
                local = t + m.offset_s
                if m.producer is not None and t >= m.next_produce:
                    for msg in m.producer(local):
                        m.node.submit(msg, local)
                    m.next_produce += m.produce_every_s
                if m.lan is not None and t >= m.next_produce:
                    for lmsg in m.lan(local):
                        self._from_lan(m, lmsg, local)
                    m.next_produce += m.produce_every_s
                self._actions(nid, m.node.on_timer(local))
                if m.bridge is not None:
                    self._gateway_timer(nid, m, local)

    def _actions(self, nid: int, actions: list[Transmit | Deliver | Notice]) -> None:
        m = self.members[nid]
        for a in actions:
            if isinstance(a, Transmit):
                at = max(a.at - m.offset_s, self.t)
                if self.write_jitter_s:
                    at += self._rng.uniform(0, self.write_jitter_s)
                self.transmits.append((at, nid, a))
                late = at > a.latest - m.offset_s  # past it the packet overruns its slot
                heapq.heappush(self._events, (at, next(self._seq), "write", m.module, a.data, late))
            elif isinstance(a, Deliver):
                self.deliveries.append((self.t, nid, a.src, a.data))
                if m.bridge is not None:
                    pub = m.bridge.from_air(a.data, self.t + m.offset_s)
                    if pub is not None:
                        self.published.append((self.t, nid, pub.message))
            else:
                self.notices.append((self.t, nid, a))

    # ------------------------------------------------------------------ gateways
    def _from_lan(self, m: Member, msg: msgspec.Struct, now: float) -> None:
        """What `radio-gateway run` does with a sample of its LAN."""
        assert m.bridge is not None
        out = m.bridge.from_lan(key_of(self.swarm, msg), lan_codec.encode(msg), now)
        if isinstance(out, OwnStatus):
            m.node.own_status(out.status, now)
        elif out is not None:
            m.node.submit(out, now)

    def _gateway_timer(self, nid: int, m: Member, now: float) -> None:
        assert m.bridge is not None
        d = m.bridge.next_deadline()
        if d is None or d > now:
            return
        node = m.node

        def alive(vid: int) -> bool:
            return vid not in node.peers or node.silent_s(vid, now) <= m.silent_s

        for pub in m.bridge.due(now):
            self.published.append((self.t, nid, pub.message))
        for pub in m.bridge.predictions(now, alive):
            if self.keep_predictions:
                self.published.append((self.t, nid, pub.message))
