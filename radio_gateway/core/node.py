"""One radio node (pure, sans-I/O): serial bytes, local messages and `now` in; frames to
write (with the exact time to write them), messages heard and notices out.

    node = RadioNode(NodeConfig(node_id=7), key, now)
    node.submit(OutMessage(key, radio_bytes, klass, latest_only, acked, max_rate), now)
    actions = node.handle_bytes(serial_bytes, now)   # Deliver(...) for what we heard
    actions = node.on_timer(now)                     # Transmit(data, at) in our slot
    deadline = node.next_deadline()                  # when to call on_timer next

`now` is the node's time source (GPS time, UNIX seconds). The node adds its own
received-frame correction (`TimeSync`) to get the network time that slots follow, and
returns times in the source's time again.
"""

from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass, field

from swarm_proto import VehicleStatus, radio

from . import frame as fr
from .airtime import LinkTiming
from .auth import ReplayGuard
from .cobs import Deframer
from .membership import Membership, Phase, TxSlot
from .outbox import Outbox, OutMessage
from .reassembly import Reassembly
from .slots import DEFAULT_LEVEL, MAX_LEVEL, TdmConfig
from .telemetry import Candidate, OwnTelemetry, SendOnErrorConfig
from .timesync import TimeSync

_EPS = 1e-6  # seconds; UNIX times near 1.7e9 carry ~2e-7 s of float rounding
_STALL_CYCLES = 2  # a timer this many cycles late: our process stalled (not a peer's silence)


@dataclass(frozen=True)
class NodeConfig:
    node_id: int
    timing: LinkTiming = field(default_factory=LinkTiming)
    tdm: TdmConfig = field(default_factory=TdmConfig)
    source_stratum: int = 0  # 0: GPS-disciplined time source, 3: free-running clock
    initial_members: tuple[int, ...] = ()  # the table to bootstrap with, if nobody is heard
    prep_s: float = 0.02  # build the frame this long before the slot
    seed: int = 0
    replay_window_cycles: int = 2
    # spare room in our slot repeats peers' latest telemetry heard in the last period
    # (radio messages whose (version, type tag) is listed; default: VehicleStatus)
    relay_headers: frozenset[bytes] = frozenset({b"\x01\x01"})
    # latest-only telemetry kept per key between slots (see Outbox): 2 with 400 ms cycles
    # carries every 5 Hz status, two to a frame
    latest_keep: int = 1
    # send on error: our own vehicle's status goes on air only when the peers'
    # dead reckoning of it would be off (telemetry.OwnTelemetry); None: as queued
    send_on_error: SendOnErrorConfig | None = None
    # the adaptive schedule: ask for a slot share that follows our need level
    adaptive: bool = False
    min_level: int = 0  # never ask for less (a ground station that wants a double share: 2)
    level_hold_s: float = 5.0  # a need level is kept this long after the need
    delivery_s: float = 0.05  # from a frame's slot until its peers republish what it held

    def __post_init__(self) -> None:
        if not 1 <= self.node_id <= 65534:
            raise ValueError("node_id is 1..65534")
        if self.latest_keep < 1:
            raise ValueError("latest_keep is >= 1")
        if not 0 <= self.min_level <= MAX_LEVEL:
            raise ValueError(f"min_level is 0..{MAX_LEVEL}")


@dataclass(frozen=True)
class Transmit:
    data: bytes  # one frame, to be written in one serial write
    at: float  # when to start writing (time-source time)
    cycle: int
    join: bool
    latest: float = float("inf")  # past this, the packet would overrun its slot: drop it


@dataclass(frozen=True)
class Deliver:
    src: int  # the node whose frame carried it
    data: bytes  # a radio-encoded message
    relayed: bool = False  # repeated by `src` for another node


@dataclass(frozen=True)
class Notice:
    level: str  # "info" or "warning"
    text: str


Action = Transmit | Deliver | Notice


@dataclass
class PeerCounters:
    frames: int = 0
    bytes: int = 0
    expected: int = 0
    first_cycle: int | None = None
    last_cycle: int | None = None
    last_stratum: int = 3


@dataclass
class RadioNode:
    config: NodeConfig
    key: bytes
    start_s: float
    membership: Membership = field(init=False)
    timesync: TimeSync = field(init=False)
    outbox: Outbox = field(init=False)
    reassembly: Reassembly = field(default_factory=Reassembly)
    replay: ReplayGuard = field(init=False)
    deframer: Deframer = field(default_factory=Deframer)
    counts: Counter[str] = field(default_factory=Counter)
    peers: dict[int, PeerCounters] = field(default_factory=dict)
    _cycle: int = field(init=False)
    _last_now: float = field(init=False)
    _last_tx_cycle: int = -1
    _slot: TxSlot | None = None
    _slot_key: tuple[object, ...] = ()
    _relay: dict[int, tuple[bytes, int]] = field(default_factory=dict)  # src -> (data, cycle)
    own: OwnTelemetry | None = None  # send on error: our own vehicle's state
    _need: int = DEFAULT_LEVEL  # need level asked for
    _need_since: float = -math.inf  # when a need at least that high was last seen

    def __post_init__(self) -> None:
        c = self.config
        if len(self.key) != 32:
            raise ValueError("the swarm key is 32 bytes")
        self.membership = Membership(
            c.node_id, c.timing, c.tdm, initial_members=c.initial_members, seed=c.seed
        )
        self.timesync = TimeSync(
            c.node_id, c.source_stratum, lock_tolerance_s=max(c.tdm.guard_s / 4, 0.0005)
        )
        self.replay = ReplayGuard(c.replay_window_cycles)
        self.reassembly.node_id = c.node_id
        first = int(self.start_s // c.tdm.cycle_s)
        self.outbox = Outbox(
            ack_timeout_s=1.5 * c.tdm.cycle_s, seq=first & 0xFFFF, latest_keep=c.latest_keep
        )
        self._cycle = first - 1
        self._last_now = self.start_s
        if c.send_on_error is not None:
            self.own = OwnTelemetry(c.send_on_error, encode=radio.encode)

    # ------------------------------------------------------------------ time
    @property
    def cycle_s(self) -> float:
        return self.config.tdm.cycle_s

    def _net(self, now: float) -> float:
        return now + self.timesync.correction_s

    def network_time(self, now: float) -> float:
        """The time slots follow: the time source plus our received-frame correction."""
        return self._net(now)

    def _raw(self, t: float) -> float:
        return t - self.timesync.correction_s

    def silent_s(self, node: int, now: float) -> float:
        """Seconds since a frame of `node` was last heard directly (inf: never)."""
        p = self.peers.get(node)
        if p is None or p.last_cycle is None:
            return math.inf
        return max(0.0, self._net(now) - (p.last_cycle + 1) * self.cycle_s)

    def silence_limit_s(self, floor_s: float) -> float:
        """How long a peer may go unheard before we stop predicting it to our node: at
        least `floor_s`, and never sooner than the slot table itself would remove it
        (`silent_periods` + `activation_periods` periods: past the physical limit a
        period is several cycles, and each member is heard once per period)."""
        tdm = self.config.tdm
        periods = tdm.silent_periods + tdm.activation_periods
        return max(floor_s, periods * self.membership.layout.period_s)

    # ------------------------------------------------------------------ inputs
    def submit(self, msg: OutMessage, now: float) -> None:
        if not self.outbox.submit(msg, self._net(now)):
            self.counts["tx_refused"] += 1

    def own_status(self, status: VehicleStatus, now: float) -> None:
        """Our own vehicle's VehicleStatus (send on error: it goes on air when due)."""
        if self.own is None:
            raise RuntimeError("own_status needs NodeConfig.send_on_error")
        self.own.update(status, self._net(now))

    def handle_bytes(self, data: bytes, now: float) -> list[Action]:
        self._last_now = max(self._last_now, now)
        out: list[Action] = []
        for raw in self.deframer.feed(data, now):
            out += self._on_raw(raw, now)
        return out

    def on_timer(self, now: float) -> list[Action]:
        self._last_now = max(self._last_now, now)
        out: list[Action] = []
        t = self._net(now)
        # deadlines went through the correction and back: allow for the rounding
        cyc = math.floor((t + _EPS) / self.cycle_s)
        if cyc - self._cycle > _STALL_CYCLES:  # our loop stalled: not the peers' silence
            self.membership.stalled(cyc - self._cycle - 1)
        while self._cycle < cyc:
            self._cycle += 1
            out += self._advance(self._cycle, t)
        slot = self._next_slot(t)
        if slot is not None and t + _EPS >= slot.air_start - self.config.prep_s:
            out += self._transmit(slot, t)
        return out

    def next_deadline(self) -> float:
        t = self._net(self._last_now)
        deadline = (self._cycle + 1) * self.cycle_s
        slot = self._next_slot(t)
        if slot is not None:
            deadline = min(deadline, slot.air_start - self.config.prep_s)
        return self._raw(deadline)

    # ------------------------------------------------------------------ receive
    def _drop(self, reason: str) -> list[Action]:
        self.counts[f"drop_{reason}"] += 1
        return []

    def _on_raw(self, raw: bytes, now: float) -> list[Action]:
        t = self._net(now)
        my_cycle = math.floor(t / self.cycle_s)
        try:
            u = fr.open_frame(raw)
        except fr.FrameError as exc:
            return self._drop(exc.reason)
        if u.src == self.config.node_id:
            return self._drop("own")
        try:
            f = fr.verify(u, self.key, my_cycle)
        except fr.FrameError as exc:
            return self._drop(exc.reason)
        why = self.replay.check(f.src, f.cycle, my_cycle)
        if why is not None:
            return self._drop(why)
        self.counts["rx_frames"] += 1
        self.counts["unknown_records"] += f.unknown_records
        p = self.peers.setdefault(f.src, PeerCounters())
        p.frames += 1
        p.bytes += len(raw) + 1
        p.first_cycle = f.cycle if p.first_cycle is None else p.first_cycle
        p.last_cycle = f.cycle
        p.last_stratum = f.stratum
        if not f.join:
            self.timesync.heard(f.src, f.stratum, f.cycle)
            self._time_sample(f, len(raw) + 1, t)
        self.membership.on_frame(f)
        out: list[Action] = []
        for r in f.records:
            if isinstance(r, fr.Msg):
                out.append(Deliver(f.src, r.data))
                if r.data[:2] in self.config.relay_headers:
                    self._relay[f.src] = (r.data, f.cycle)
            elif isinstance(r, fr.Relay):
                self.counts["rx_relayed"] += 1
                out.append(Deliver(f.src, r.data, relayed=True))
            elif isinstance(r, fr.Frag):
                whole = self.reassembly.on_frag(f.src, r, t)
                if whole is not None:
                    out.append(Deliver(f.src, whole))
            elif isinstance(r, fr.Ack) and r.src == self.config.node_id:
                self.outbox.on_ack(f.src, r)
        return out

    def _time_sample(self, f: fr.Frame, wire: int, arrival: float) -> None:
        lay = self.membership.layout
        if f.table_hash != lay.table_hash or lay.n < 2 or f.src not in lay.members:
            return
        period = f.cycle // lay.k
        idx = next(
            (i for i in lay.slots_of(f.src, period) if lay.slot_cycle(period, i) == f.cycle), None
        )
        if idx is None:
            return
        expected = lay.slot_start(period, idx) + lay.guard_s / 2
        expected += self.config.timing.rx_delay_s(wire)
        self.timesync.sample(f.src, arrival - expected)

    # ------------------------------------------------------------------ cycles
    def _advance(self, cycle: int, t: float) -> list[Action]:
        m = self.membership
        before_members, before_phase, before_k = m.members, m.phase, m.layout.k
        before_hash = m.layout.table_hash
        m.advance(cycle)
        self.timesync.update(cycle)
        self.reassembly.expire(t)
        out: list[Action] = []
        if m.phase is not before_phase:
            tr = m.transitions[-1]
            out.append(
                Notice("info", f"radio: {tr.old.value} -> {tr.new.value} ({tr.trigger.value})")
            )
        if m.layout.table_hash != before_hash:
            # resend missing chunks only once every receiver has had a slot to ack them
            self.outbox.ack_timeout_s = max(
                1.5 * self.cycle_s, m.layout.period_s + 0.5 * self.cycle_s
            )
        if m.members != before_members:
            for gone in set(before_members) - set(m.members):
                self.outbox.forget(gone)
            lay = m.layout
            out.append(
                Notice(
                    "info",
                    f"radio: slot table v{lay.table_hash:04x}: {len(lay.members)} members "
                    f"{list(lay.members)}, {lay.slots} slots of {lay.slot_s * 1000:.1f} ms, "
                    f"{lay.budget} B per slot",
                )
            )
            if lay.k != before_k and lay.k > 1:
                out.append(
                    Notice(
                        "warning",
                        f"radio: {lay.n} members exceed what one {self.cycle_s * 1000:.0f} ms "
                        f"cycle carries; every node now sends every {lay.k} cycles "
                        f"({lay.rate_hz:.2f} Hz)",
                    )
                )
        if m.phase is Phase.MEMBER and cycle % m.layout.k == 0:
            period = cycle // m.layout.k
            for peer in m.members:
                if peer != self.config.node_id:
                    slots = len(m.layout.slots_of(peer, period))
                    if slots:
                        self.peers.setdefault(peer, PeerCounters()).expected += slots
            if self.config.adaptive:
                self._ask_share(cycle, t)
        return out

    # ------------------------------------------------------------------ adaptive schedule
    def desired_level(self, t: float) -> int:
        """Our need now: the own vehicle's (parked 0, flying 1, avoiding 2; no vehicle of
        our own: 1), 2 while a backlog of control traffic (commands, acks, votes,
        missions) waits for more than a slot carries, never below `min_level`."""
        c = self.config
        need = c.min_level
        # a vehicle: its own need; a node without one (a ground station): the default
        own = self.own.need_level(t) if self.own is not None and self.own.latest else DEFAULT_LEVEL
        need = max(need, own)
        if self.outbox.control_backlog() > self.membership.layout.budget:
            need = max(need, 2)
        return need

    def _ask_share(self, cycle: int, t: float) -> None:
        """Once a period: the level to ask for. Up at once, down only after the need has
        stayed lower for `level_hold_s` (a share does not flap)."""
        if self.own is not None and self.own.latest is None:
            return  # no status from our vehicle yet: nothing to base a need on
        # a table that fits one cycle gives everyone every cycle whatever the levels:
        # changing them there would only change the table's version
        want = self.desired_level(t) if self.membership.layout.k > 1 else DEFAULT_LEVEL
        if want >= self._need or t - self._need_since >= self.config.level_hold_s:
            self._need, self._need_since = want, t
        if self.membership.request_level(self._need, cycle):
            self.counts["level_requests"] += 1

    # ------------------------------------------------------------------ transmit
    def _next_slot(self, t: float) -> TxSlot | None:
        m = self.membership
        key = (m.tx_state(), self._last_tx_cycle)
        if self._slot is not None and key == self._slot_key and self._slot.air_start >= t:
            return self._slot
        self._slot = m.next_tx(t, self._last_tx_cycle + 1)
        self._slot_key = key
        return self._slot

    def _transmit(self, slot: TxSlot, t: float) -> list[Action]:
        self._last_tx_cycle = slot.cycle
        self._slot = None
        if not self.timesync.locked(slot.cycle):
            self.counts["tx_skipped_unsynced"] += 1
            return []
        m = self.membership
        lay = m.layout
        stratum = self.timesync.stratum(slot.cycle)
        records: list[fr.Record] = []
        if not slot.join:
            room = slot.budget
            for ch in m.change_records(rotate=slot.cycle + self.config.node_id):
                if fr.record_size(ch) <= room:
                    records.append(ch)
                    room -= fr.record_size(ch)
                    if isinstance(ch, fr.LevelChange) and ch.node == self.config.node_id:
                        m.request_sent(slot.cycle)
            # send on error: our own status, when due, goes first (a peer's belief of us
            # is about to be off by the threshold: a safety matter, and rare by design)
            cand = self._own_candidate(slot, t)
            if cand is not None and self.own is not None:
                rec = fr.Msg(cand.data)
                if fr.record_size(rec) <= room:
                    records.append(rec)
                    room -= fr.record_size(rec)
                    self.own.sent(cand, t)
                    self.counts[f"own_status_{cand.reason}"] += 1
            # acknowledgements we owe, at most half the room while messages wait (a
            # ground station owing fifty of them must still get its commands out)
            ack_room = room // 2 if self.outbox.pending() else room
            acks = self.reassembly.take_acks()
            for i, a in enumerate(acks):
                if fr.record_size(a) > ack_room:
                    self.reassembly.give_back(acks[i:])
                    break
                records.append(a)
                room -= fr.record_size(a)
                ack_room -= fr.record_size(a)
            receivers = frozenset(lay.members) - {self.config.node_id}
            own = self.outbox.fill(room, t, receivers)
            records += own
            room -= sum(fr.record_size(r) for r in own)
            records += self._relays(room, slot.cycle - lay.k)
            self.counts["payload_bytes"] += sum(fr.record_size(r) for r in records)
            self.counts["budget_bytes"] += slot.budget
        f = fr.Frame(
            src=self.config.node_id,
            cycle=slot.cycle,
            table_hash=lay.table_hash,
            n_members=lay.n,
            heard=b"\x00" * fr.heard_bytes(lay.n) if slot.join else m.heard_bitmap(slot.cycle),
            join=slot.join,
            stratum=stratum,
            records=tuple(records),
            level=m.level_of(self.config.node_id),
        )
        data = fr.encode(f, self.key)
        m.sent(slot)
        self.counts["tx_relayed"] += sum(isinstance(r, fr.Relay) for r in f.records)
        self.counts["tx_join" if slot.join else "tx_frames"] += 1
        self.counts["tx_bytes"] += len(data)
        timing = self.config.timing
        at = slot.air_start - timing.tx_delay_s(len(data))
        # a late packet may use its spare room and half of the next guard: it still ends
        # before the next slot's packet starts, if that one is on time
        end = slot.start + lay.slot_s
        latest = end - timing.airtime_s(len(data)) - timing.tx_delay_s(len(data))
        return [Transmit(data, self._raw(at), slot.cycle, slot.join, self._raw(max(latest, at)))]

    def _own_candidate(self, slot: TxSlot, t: float) -> Candidate | None:
        """Send on error: our own status for this frame, if due; the horizon is until a
        status sent at our next opportunity would reach the peers."""
        if self.own is None:
            return None
        nxt = self.membership.next_tx(slot.air_start + 1e-3, slot.cycle + 1)
        lay = self.membership.layout
        gap = nxt.air_start if nxt is not None else slot.air_start + lay.period_s
        return self.own.candidate(t, gap - t + self.config.delivery_s)

    def _relays(self, room: int, since_cycle: int) -> list[fr.Record]:
        out: list[fr.Record] = []
        for src, (data, cycle) in sorted(self._relay.items(), key=lambda kv: kv[1][1]):
            if cycle < since_cycle:
                del self._relay[src]
                continue
            r = fr.Relay(data)
            if fr.record_size(r) <= room:
                out.append(r)
                room -= fr.record_size(r)
                del self._relay[src]
        return out
