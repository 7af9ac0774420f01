"""Who is on the channel, and therefore the slot table (pure: cycles and frames in).

Phases (`TRANSITIONS` is the whole state machine):

- LISTENING: a node starting (or resynchronising) sends nothing. It groups the frames it
  hears by the table version they carry; once the sources carrying the best version are
  exactly the members that version hashes to, it has learned the table: MEMBER if it is
  already in it (a quick restart), JOINING otherwise. A version that is the hash of its
  own configured initial members (which include it) is adopted at once. If it hears nothing for
  `listen_cycles`, it bootstraps: the configured initial members if it is one of them,
  else a table of its own.
- JOINING: sends a JOIN frame in a join window (after a random backoff that doubles
  after each unanswered attempt). Members that hear it schedule JOIN(node) to take
  effect `activation_periods` periods later and repeat that change in their frames
  until then, so members that missed the request still apply it on the same cycle.
- MEMBER: sends in its slot every period. A member without evidence of life for
  `silent_periods` periods (no frame of its own and no peer reporting it in a heard
  bitmap) gets a LEAVE, scheduled and spread the same way. Changes merge by taking the
  earliest activation cycle, so every node applies them on the same cycle.
  Silence of every other member at once is no evidence against any of them, for up to
  `outage_periods` (an outage: the channel, or our own receiver, went quiet; members
  fail one by one): no LEAVE, and the first member heard again gives all a fresh grace
  period. Past `outage_periods` the silence counts as before: the members that all left
  at once leave, and two groups that formed apart and collide slot for slot on one
  channel (each hears nobody) fall apart into lone members, whose random offsets let
  them find each other and merge.

Convergence after disagreement (loss of every copy of a change): frames carry the
16-bit hash of their sender's table. A node whose table is outvoted for
`mismatch_periods` periods by the tables its members carry (ties: more members, then
the larger hash), or that hears a better foreign table (a separate group met on the
air), goes back to LISTENING and re-learns.
"""

from __future__ import annotations

import math
import random
from dataclasses import dataclass, field
from enum import Enum

from .airtime import LinkTiming
from .frame import Change, Frame, LevelChange, frame_overhead
from .slots import DEFAULT_LEVEL, MAX_LEVEL, SlotLayout, TdmConfig, table_hash


class Phase(Enum):
    LISTENING = "listening"
    JOINING = "joining"
    MEMBER = "member"


class Trigger(Enum):
    LEARNED_MEMBER = "learned a table that includes us"
    LEARNED_OTHER = "learned a table without us"
    SILENCE = "heard nobody: bootstrap"
    ADMITTED = "our JOIN took effect"
    REMOVED = "a LEAVE of us took effect"
    OUTVOTED = "our table is outvoted"
    FOREIGN = "a better foreign table is on the air"
    LOST = "gave up joining"


TRANSITIONS: dict[tuple[Phase, Trigger], Phase] = {
    (Phase.LISTENING, Trigger.LEARNED_MEMBER): Phase.MEMBER,
    (Phase.LISTENING, Trigger.LEARNED_OTHER): Phase.JOINING,
    (Phase.LISTENING, Trigger.SILENCE): Phase.MEMBER,
    (Phase.JOINING, Trigger.ADMITTED): Phase.MEMBER,
    (Phase.JOINING, Trigger.OUTVOTED): Phase.LISTENING,
    (Phase.JOINING, Trigger.LOST): Phase.LISTENING,
    (Phase.MEMBER, Trigger.REMOVED): Phase.JOINING,
    (Phase.MEMBER, Trigger.OUTVOTED): Phase.LISTENING,
    (Phase.MEMBER, Trigger.FOREIGN): Phase.LISTENING,
}


@dataclass(frozen=True)
class TxSlot:
    start: float  # slot start, network time
    air_start: float  # when the packet should start on air
    cycle: int  # the frame's cycle counter
    period: int
    join: bool  # a JOIN request in a join window
    budget: int  # record bytes


@dataclass(frozen=True)
class Transition:
    cycle: int
    old: Phase
    new: Phase
    trigger: Trigger
    members: tuple[int, ...]


@dataclass
class _Heard:
    table_hash: int
    n: int
    cycle: int
    join: bool
    level: int = 0


@dataclass
class Membership:
    my_id: int
    timing: LinkTiming
    config: TdmConfig
    initial_members: tuple[int, ...] = ()
    seed: int = 0
    max_pending_levels: int = 4  # level changes in flight at once (frame room)
    phase: Phase = Phase.LISTENING
    layout: SlotLayout = field(init=False)
    pending: dict[tuple[bool, int], int] = field(default_factory=dict)  # (join, node) -> at
    # the adaptive schedule: each member's need level in force, and scheduled changes
    levels: dict[int, int] = field(default_factory=dict)  # member -> level (absent: default)
    pending_levels: dict[int, tuple[int, int]] = field(default_factory=dict)  # node -> (at, lvl)
    level_request: tuple[int, int] | None = None  # ours (at, level), until a member echoes it
    evidence: dict[int, int] = field(default_factory=dict)  # member -> last cycle alive
    # member -> periods (of the table in force) with evidence of life, the last
    # `loss_window_periods`: its loss as every receiver sees it (silence_limit)
    alive_periods: dict[int, set[int]] = field(default_factory=dict)
    since: dict[int, int] = field(default_factory=dict)  # member -> period it was adopted in
    direct: dict[int, int] = field(default_factory=dict)  # node -> last cycle heard directly
    heard: dict[int, _Heard] = field(default_factory=dict)  # src -> its latest frame
    transitions: list[Transition] = field(default_factory=list)
    changes_applied: int = 0
    # (cycle learned, join?, node, activation cycle) of every change, and the tables
    # adopted (cycle, members): for statistics and tests
    learned: list[tuple[int, bool, int, int]] = field(default_factory=list)
    tables: list[tuple[int, tuple[int, ...]]] = field(default_factory=list)
    _cycle: int = -1
    _listen_since: int | None = None
    _last_heard_any: int | None = None
    _mismatch: int = 0
    _foreign: int = 0
    _join_cycle: int | None = None  # earliest cycle we may send a JOIN in
    _join_sent: int | None = None  # cycle of our last JOIN
    _join_attempts: int = 0
    _join_pick: float = 0.0  # where in the join window our JOIN goes (0..1)
    _confirmed: int | None = None  # last cycle a member's frame carried our table version
    _contest_echoed: bool = False  # a member repeated our JOIN contesting a LEAVE of us
    _leave_carriers: set[int] = field(default_factory=set)  # members that sent a LEAVE of us
    _unsure_since: int | None = None  # our contest may have gone unheard: quiet until settled
    _rng: random.Random = field(init=False)

    def __post_init__(self) -> None:
        self.layout = SlotLayout.build((), self.timing, self.config)
        self._rng = random.Random(self.seed * 65_537 + self.my_id)

    # ------------------------------------------------------------------ views
    @property
    def members(self) -> tuple[int, ...]:
        return self.layout.members

    @property
    def table_hash(self) -> int:
        return self.layout.table_hash

    def projected_members(self) -> tuple[int, ...]:
        """The members once every pending change has taken effect."""
        ms = set(self.members)
        for join, node in self.pending:
            if join:
                ms.add(node)
            elif (True, node) not in self.pending:  # a JOIN of a node beats a LEAVE of it
                ms.discard(node)
        return tuple(sorted(ms))

    def projected_levels(self) -> dict[int, int]:
        """The need levels once every pending change has taken effect."""
        members = self.projected_members()
        lv = {m: self.levels.get(m, DEFAULT_LEVEL) for m in members}
        for node, (_, level) in self.pending_levels.items():
            if node in lv:
                lv[node] = level
        return lv

    def projected_hash(self) -> int:
        return table_hash(self.projected_members(), self.projected_levels())

    def level_of(self, node: int) -> int:
        return self.levels.get(node, DEFAULT_LEVEL)

    def request_level(self, level: int, cycle: int) -> bool:
        """Ask for our slot share to follow our need (adaptive schedule): a LEVEL change
        of ourselves, carried in our next frame (`request_sent` schedules it for us once
        it went out); like a JOIN, every member that hears it, or a member's repeat of
        it, schedules it (`activation_periods` later, on a period boundary) and repeats
        it until then. One at a time, none while the membership changes or
        `max_pending_levels` changes are in flight; True if asked."""
        level = min(MAX_LEVEL, max(0, level))
        me = self.my_id
        if self.level_request is not None and self.level_request[0] <= cycle + 1:
            self.level_request = None  # not echoed in time: ask again later
        if (
            self.phase is not Phase.MEMBER
            or self.level_request is not None
            or me in self.pending_levels
            or self.pending
            or len(self.pending_levels) >= self.max_pending_levels
            or self.level_of(me) == level
        ):
            return False
        self.level_request = (self._activation(cycle), level)
        return True

    def heard_bitmap(self, cycle: int) -> bytes:
        """Bit i: the member of rank i was heard directly during the last period."""
        out = bytearray((self.layout.n + 7) // 8)
        since = cycle - self.layout.k
        for i, m in enumerate(self.members):
            if m != self.my_id and self.direct.get(m, -(10**9)) >= since:
                out[i // 8] |= 1 << (i % 8)
        return bytes(out)

    def change_records(self, rotate: int = 0) -> list[Change | LevelChange]:
        """Membership changes, then our own level request, then the level changes in
        flight, their order rotated by `rotate` (a frame has room for a few: every
        member repeats them, each starting elsewhere, so each is repeated)."""
        out: list[Change | LevelChange] = [
            Change(join, node, at)
            for (join, node), at in sorted(self.pending.items())
            if join or node != self.my_id  # our removal is not ours to spread: we contest it
        ]
        if self.level_request is not None:
            out.append(LevelChange(self.my_id, self.level_request[1], self.level_request[0]))
        lv = [LevelChange(n, x, at) for n, (at, x) in sorted(self.pending_levels.items())]
        if lv:
            r = rotate % len(lv)
            out += lv[r:] + lv[:r]
        return out

    def request_sent(self, cycle: int) -> None:
        """Our level request went out in a frame: it is in flight (we apply it when
        every member that heard it, or a repeat of it, does)."""
        req = self.level_request
        if req is None:
            return
        self.level_request = None
        if req[0] > cycle:
            self.pending_levels[self.my_id] = req

    # ------------------------------------------------------------------ transitions
    def _go(self, trigger: Trigger, cycle: int) -> None:
        new = TRANSITIONS.get((self.phase, trigger))
        if new is None:
            raise AssertionError(f"no transition from {self.phase} on {trigger}")
        self.transitions.append(Transition(cycle, self.phase, new, trigger, self.members))
        self.phase = new
        self._mismatch = self._foreign = 0
        self._unsure_since = None
        if new is Phase.LISTENING:
            self._listen_since = cycle
            self._last_heard_any = None
            self.pending.clear()
            self.pending_levels.clear()
            self.level_request = None
            self.levels.clear()
            self.evidence.clear()
            self.alive_periods.clear()
            self.since.clear()
            self.layout = SlotLayout.build((), self.timing, self.config)
        elif new is Phase.JOINING:
            self._join_attempts = 0
            self._join_sent = None
            self._join_cycle = cycle + self.layout.k * (
                1 + self._rng.randrange(self.config.join_backoff)
            )
            self._join_pick = self._rng.random()
            self._confirmed = cycle  # the table was just learned or adopted

    def _adopt(
        self, members: tuple[int, ...], cycle: int, levels: dict[int, int] | None = None
    ) -> None:
        if levels is not None:
            self.levels = {
                m: lv for m, lv in levels.items() if lv != DEFAULT_LEVEL and m in members
            }
        else:
            self.levels = {m: lv for m, lv in self.levels.items() if m in members}
        old_k = self.layout.k
        self._unsure_since = None  # a new table: whatever the doubt was about is settled
        self.layout = SlotLayout.build(members, self.timing, self.config, self.levels)
        self.tables.append((cycle, self.layout.members))
        del self.tables[:-16]
        if self.layout.k != old_k:  # periods of another length: start the loss history over
            self.alive_periods.clear()
            self.since = {m: cycle // self.layout.k for m in self.since}
        for m in self.members:
            self.evidence.setdefault(m, cycle)  # a new member gets the full grace period
            self.since.setdefault(m, cycle // self.layout.k)
        for d in (self.evidence, self.since, self.alive_periods):
            for m in [m for m in d if m not in self.members]:
                del d[m]

    def _period_of(self, cycle: int) -> int:
        return cycle // self.layout.k

    def _activation(self, cycle: int) -> int:
        k = self.layout.k
        at = cycle + self.config.activation_periods * k
        return -(-at // k) * k

    # ------------------------------------------------------------------ inputs
    def on_frame(self, f: Frame) -> None:
        """A frame that passed every check (tag, freshness, replay)."""
        self.heard[f.src] = _Heard(f.table_hash, f.n_members, f.cycle, f.join, f.level)
        self._last_heard_any = f.cycle
        if f.join:
            if (
                self.phase is Phase.MEMBER
                and f.table_hash in (self.table_hash, self.projected_hash())
                and f.src not in self.projected_members()
            ):
                self._propose(True, f.src, self._activation(f.cycle))
            return
        if f.src != self.my_id and f.src in self.evidence and self._outage(f.cycle):
            # the first member heard after every other one went quiet at once: the
            # silence told nothing of them; each gets a fresh grace period
            for m in self.evidence:
                if m != self.my_id:  # ours is what peers report of us
                    self._excuse(m, f.cycle)
        self.direct[f.src] = f.cycle
        if f.src in self.members and f.table_hash == self.table_hash:
            self._confirmed = f.cycle
        if f.src in self.evidence:
            self._note_alive(f.src, f.cycle)
        if self.phase is Phase.LISTENING or f.table_hash != self.table_hash:
            return
        k = self.layout.k
        for i, m in enumerate(self.members):
            if i // 8 < len(f.heard) and f.heard[i // 8] >> (i % 8) & 1 and m in self.evidence:
                self._note_alive(m, f.cycle - k)
        for r in f.records:
            if isinstance(r, Change):
                self.on_change(r, f.cycle, f.src)
            elif isinstance(r, LevelChange):
                self.on_level_change(r)

    def on_change(self, c: Change, cycle: int | None = None, src: int | None = None) -> None:
        """A scheduled change, carried in a frame of `src` sent in `cycle`."""
        if self.phase is Phase.LISTENING:
            return
        me = self.my_id
        if c.node == me and self.phase is Phase.MEMBER:
            # a LEAVE of us: we are on the air, so we contest it (a JOIN of us at its
            # cycle: a JOIN beats a LEAVE); we hold it, and decide at its cycle (_apply_due)
            if not c.join:
                self._propose(True, me, c.at_cycle)
                if src is not None:
                    self._leave_carriers.add(src)
            elif src is not None:  # a member repeats our contest: it held the LEAVE too
                self._contest_echoed = True
        if not c.join and c.node != me and cycle is not None and self._alive(c.node, cycle):
            return  # a stale view (its sender stalled or went deaf): not adopted, not repeated
        key = (c.join, c.node)
        if key in self.pending:
            self.pending[key] = min(self.pending[key], c.at_cycle)
        elif (c.node in self.members) != c.join or (c.join and (False, c.node) in self.pending):
            # (a JOIN of a member with a LEAVE pending: the member contests it; it wins)
            self.pending[key] = c.at_cycle
            self._learned(c.join, c.node, c.at_cycle)

    def _alive(self, node: int, cycle: int) -> bool:
        """We heard `node` directly in the last `fresh_periods` periods: a LEAVE of it
        comes from a sender whose view is older than ours (a gateway whose loop stalled
        for `silent_periods` finds every peer silent and schedules them all out:
        `swarm-sim demo --radio` run 5). A LEAVE of ourselves is contested instead."""
        cfg = self.config  # fresher than the silence that proposes a LEAVE, always
        window = min(cfg.fresh_periods, cfg.silent_periods - 1) * self.layout.k
        last = self.direct.get(node)
        return last is not None and cycle - last <= window

    def on_level_change(self, c: LevelChange) -> None:
        """A member's scheduled need level: merged like membership changes (the earliest
        activation; at the same activation, the higher level), so every node that heard
        a copy applies the same share on the same cycle."""
        if self.phase is Phase.LISTENING or c.node not in self.projected_members():
            return
        if c.node == self.my_id and self.level_request is not None:
            if (c.at_cycle, c.level) != self.level_request:
                return  # an old echo: ours stands
            self.level_request = None
        old = self.pending_levels.get(c.node)
        if old is None:
            if c.level != self.level_of(c.node):
                self.pending_levels[c.node] = (c.at_cycle, c.level)
        elif (c.at_cycle, -c.level) < (old[0], -old[1]):
            self.pending_levels[c.node] = (c.at_cycle, c.level)

    def _learned(self, join: bool, node: int, at: int) -> None:
        self.learned.append((self._cycle, join, node, at))
        del self.learned[:-16]

    def _propose(self, join: bool, node: int, at: int) -> None:
        key = (join, node)
        if key not in self.pending:
            self._learned(join, node, at)
            if join and node == self.my_id:
                self._contest_echoed = False
                self._leave_carriers = set()
        self.pending[key] = min(self.pending.get(key, at), at)

    def _note_alive(self, m: int, cycle: int) -> None:
        """Evidence that member `m` was on the air in `cycle` (its frame, or a peer's
        heard bitmap): its grace period and its loss history."""
        self.evidence[m] = max(self.evidence[m], cycle)
        seen = self.alive_periods.setdefault(m, set())
        p = cycle // self.layout.k
        seen.add(p)
        if len(seen) > 2 * self.config.loss_window_periods:
            low = max(seen) - self.config.loss_window_periods
            seen.difference_update([x for x in seen if x < low])

    def _excuse(self, m: int, until: int) -> None:
        """A silence of `m` up to cycle `until` that told nothing of it (our stall, an
        outage of everyone): a fresh grace period, and no loss in its history."""
        k = self.layout.k
        first = max(self.evidence[m] // k + 1, until // k - self.config.loss_window_periods)
        self.alive_periods.setdefault(m, set()).update(range(first, until // k + 1))
        self._note_alive(m, until)

    def silence_limit(self, m: int, cycle: int) -> int:
        """Periods without evidence of life after which member `m` is proposed gone:
        `silent_periods` for a member heard every period, longer for one that has been
        missed: the silence whose chance, were it still on the air with the loss it
        showed over the last `loss_window_periods`, is `leave_confidence` (at most
        `outage_periods`). A loaded host sends late; a late packet collides with the next
        slot's and every receiver loses both: loss that the heard bitmaps cannot cover.
        With no history the estimate leans to a clean channel (a member that died right
        after joining still leaves after `silent_periods`)."""
        cfg = self.config
        k = self.layout.k
        last = self.evidence.get(m, cycle) // k
        low = max(last - cfg.loss_window_periods + 1, self.since.get(m, last))
        total = max(0, last - low + 1)
        seen = self.alive_periods.get(m, set())
        heard = sum(1 for p in seen if low <= p <= last)
        missed = max(0, total - heard)
        loss = (missed + 0.5) / (total + 5.0)
        need = math.ceil(math.log(cfg.leave_confidence) / math.log(loss))
        return max(cfg.silent_periods, min(cfg.outage_periods, need))

    def sent(self, slot: TxSlot) -> None:
        """We transmitted in `slot`."""
        if slot.join:
            self._join_sent = slot.cycle
            self._join_attempts += 1

    def stalled(self, cycles: int) -> None:
        """We heard nothing for `cycles` cycles through no fault of the peers (our
        process was descheduled: what the port held is too old for the replay window):
        that silence is no evidence against anyone, so every member's grace period is
        moved on by it. Without this a gateway stalled past `silent_periods` scheduled
        every peer out on resuming (`swarm-sim demo --radio` run 5)."""
        if cycles > 0:
            for m in self.evidence:
                if m != self.my_id:  # ours is what peers report of us: none came
                    self._excuse(m, self.evidence[m] + cycles)

    def advance(self, cycle: int) -> None:
        """Called once at the start of every cycle, in order."""
        self._cycle = cycle
        self._apply_due(cycle)
        if self.phase is Phase.LISTENING:
            self._listen(cycle)
            return
        if cycle % self.layout.k:
            return
        self._check_votes(cycle)
        if self.phase is Phase.MEMBER and self._unsure_since is not None:
            self._settle(cycle)
        if self.phase is Phase.MEMBER:
            self._check_leaves(cycle)
        elif self.phase is Phase.JOINING:
            self._check_join(cycle)

    # ------------------------------------------------------------------ internals
    def _apply_due(self, cycle: int) -> None:
        """Apply the changes due, on a period boundary of the table in force (every node
        has that table, so all apply on the same cycle; a change scheduled under an
        earlier table's periods waits for the next boundary of this one: a table never
        changes inside a period)."""
        if cycle % self.layout.k:
            return
        due = {key: at for key, at in self.pending.items() if at <= cycle}
        due_lv = sorted((at, n, lv) for n, (at, lv) in self.pending_levels.items() if at <= cycle)
        if (not due and not due_lv) or self.phase is Phase.LISTENING:
            return
        # a JOIN and a LEAVE of one node: the JOIN wins, at the earlier of the two (a
        # member contests a LEAVE of itself that way; a removed node asks back in)
        for join, node in list(due):
            if (not join, node) in self.pending:
                due[(not join, node)] = self.pending[(not join, node)]
        me = self.my_id
        others = len(self.members) - 1
        if (
            (True, me) in due
            and (False, me) in due
            and not self._contest_echoed
            and 2 * len(self._leave_carriers) > others
        ):
            # most members sent the LEAVE and none repeated our contest before its cycle:
            # those that heard the contest keep us, the others remove us. We keep our
            # table but send nothing until the members' frames settle which table holds
            # (our slot may be someone else's now); outvoted, we re-learn and rejoin.
            self._unsure_since = cycle
        ms = set(self.members)
        for join, node in due:
            del self.pending[(join, node)]
            if join:
                ms.add(node)
            elif (True, node) not in due:
                ms.discard(node)
        new = tuple(sorted(ms))
        levels = {m: self.levels.get(m, DEFAULT_LEVEL) for m in new}
        for _, node, lv in due_lv:
            del self.pending_levels[node]
            if node in levels:
                levels[node] = lv
        for node in [n for n in self.pending_levels if n not in new]:
            del self.pending_levels[node]
        if new == self.members and all(self.level_of(m) == levels[m] for m in new):
            return
        self.changes_applied += 1
        was_member = self.my_id in self.members
        self._adopt(new, cycle, levels)
        if self.phase is Phase.JOINING and self.my_id in new:
            self._go(Trigger.ADMITTED, cycle)
        elif self.phase is Phase.MEMBER and was_member and self.my_id not in new:
            self._go(Trigger.REMOVED, cycle)

    def _silence(self, cycle: int) -> int | None:
        """Cycles since any other member last showed evidence of life (None: we are
        alone in the table)."""
        last = max((c for m, c in self.evidence.items() if m != self.my_id), default=None)
        return None if last is None else cycle - last

    def _outage(self, cycle: int) -> bool:
        """Every other member unheard for over `fresh_periods` periods at once: the
        channel or our own receiver went quiet, not all of them (they send every period,
        and fail one by one). The `swarm-sim demo --radio` run at load 17: the channel
        emulator's process descheduled for 1-2 s, every gateway heard nobody and
        scheduled every peer out (tables of 4, 1, 0 members)."""
        silence = self._silence(cycle)
        quiet = max(1, min(self.config.fresh_periods, self.config.silent_periods - 1))
        return silence is not None and silence > quiet * self.layout.k

    def _settle(self, cycle: int) -> None:
        """After a contest of a LEAVE of us that may have gone unheard (we keep our
        table, quiet): the members' frames since its cycle decide. At least half of the
        other members on our table: we send again. At least half on another: the LEAVE
        held, we apply it (REMOVED) and rejoin."""
        since = self._unsure_since
        assert since is not None
        mine = other = 0
        for src, h in self.heard.items():
            if src in self.members and src != self.my_id and h.cycle >= since and not h.join:
                if h.table_hash == self.table_hash:
                    mine += 1
                else:
                    other += 1
        half = (self.layout.n - 1) / 2
        if mine > other and mine >= half:
            self._unsure_since = None
        elif other > mine and other >= half:
            self.changes_applied += 1
            self._adopt(tuple(m for m in self.members if m != self.my_id), cycle)
            self._go(Trigger.REMOVED, cycle)

    def _check_leaves(self, cycle: int) -> None:
        k = self.layout.k
        silence = self._silence(cycle) or 0
        if self._outage(cycle) and silence <= self.config.outage_periods * k:
            return  # no evidence against anyone (a grace period when one is heard again)
        for m in self.members:
            if m == self.my_id or (False, m) in self.pending:
                continue
            if cycle - self.evidence.get(m, cycle) > self.silence_limit(m, cycle) * k:
                self._propose(False, m, self._activation(cycle))

    def _recent(self, cycle: int) -> dict[int, _Heard]:
        """Frames of the last period sent under our current table (older ones carry the
        version we just left, which is no vote against the new one)."""
        horizon = cycle - self.layout.k - 1
        if self.tables:
            horizon = max(horizon, self.tables[-1][0])
        return {s: h for s, h in self.heard.items() if h.cycle >= horizon and not h.join}

    def _check_votes(self, cycle: int) -> None:
        recent = self._recent(cycle)
        projected = self.projected_members()
        mine = {self.table_hash, self.projected_hash()}
        tally: dict[tuple[int, int], int] = {}
        my_votes = 1 if self.phase is Phase.MEMBER else 0
        foreign: dict[tuple[int, int], int] = {}
        for src, h in recent.items():
            if src in self.members:
                if h.table_hash in mine:
                    my_votes += 1
                else:
                    tally[(h.n, h.table_hash)] = tally.get((h.n, h.table_hash), 0) + 1
            elif h.table_hash not in mine and src not in projected:  # not a joiner of ours
                foreign[(h.n, h.table_hash)] = foreign.get((h.n, h.table_hash), 0) + 1
        me = (self.layout.n, self.table_hash)
        outvoted = any(v > my_votes or (v == my_votes and t > me) for t, v in tally.items())
        self._mismatch = self._mismatch + 1 if outvoted else 0
        better = any(t > me and v >= min(t[0], 2) for t, v in foreign.items())
        self._foreign = self._foreign + 1 if better else 0
        if self._mismatch >= self.config.mismatch_periods:
            self._go(Trigger.OUTVOTED, cycle)
        elif self._foreign >= self.config.mismatch_periods:
            self._go(Trigger.FOREIGN, cycle) if self.phase is Phase.MEMBER else self._go(
                Trigger.LOST, cycle
            )

    def _check_join(self, cycle: int) -> None:
        if self._join_sent is None:
            return
        k = self.layout.k
        wait = (self.config.activation_periods + 2) * k
        if cycle - self._join_sent > wait and (True, self.my_id) not in self.pending:
            if self._join_attempts >= 16:
                self._go(Trigger.LOST, cycle)
                return
            backoff = self.config.join_backoff << min(self._join_attempts, 5)
            self._join_cycle = cycle + k * (1 + self._rng.randrange(backoff))
            self._join_pick = self._rng.random()
            self._join_sent = None

    def _listen(self, cycle: int) -> None:
        since = self._listen_since if self._listen_since is not None else cycle
        if self._listen_since is None:
            self._listen_since = cycle
        if cycle - since < self.config.listen_cycles:
            return
        if self._last_heard_any is None:
            init = tuple(sorted(set(self.initial_members)))
            self._adopt(init if self.my_id in init else (self.my_id,), cycle)
            self._go(Trigger.SILENCE, cycle)
            return
        if cycle - self._last_heard_any > 4 * self.config.listen_cycles + 20:
            self._last_heard_any = None  # everyone went quiet: listen afresh
            self._listen_since = cycle
            return
        groups: dict[tuple[int, int], set[int]] = {}
        for src, h in self.heard.items():
            if h.join or h.cycle < since or src == self.my_id:
                continue
            horizon = max(self.config.listen_cycles, 2 * self._k_of(h.n) + 1)
            if cycle - h.cycle <= horizon:
                groups.setdefault((h.n, h.table_hash), set()).add(src)
        init = tuple(sorted(set(self.initial_members)))
        for (n, th), srcs in sorted(groups.items(), reverse=True):
            if self.my_id in init and len(init) == n and table_hash(init) == th:
                self._adopt(init, cycle)  # our configured table, started before us
                self._go(Trigger.LEARNED_MEMBER, cycle)
                return
            srcs_t = tuple(sorted(srcs))
            lv = {src: self.heard[src].level for src in srcs}  # levels in force, from headers
            if len(srcs) == n and table_hash(srcs_t, lv) == th:
                self._adopt(srcs_t, cycle, lv)
                self._go(Trigger.LEARNED_OTHER, cycle)
                return
            with_me = tuple(sorted(srcs | {self.my_id}))
            if len(with_me) == n and table_hash(with_me, lv) == th:
                self._adopt(with_me, cycle, lv)
                self._go(Trigger.LEARNED_MEMBER, cycle)
                return

    def _k_of(self, n: int) -> int:
        return SlotLayout.build(tuple(range(1, n + 1)), self.timing, self.config).k

    # ------------------------------------------------------------------ output
    def tx_state(self) -> tuple[object, ...]:
        """What `next_tx` depends on besides its arguments: while it is unchanged, a slot
        `next_tx` gave is still the one (a caller may keep it)."""
        return (
            self.phase,
            self.table_hash,
            tuple(sorted(self.pending.items())),
            tuple(sorted(self.pending_levels.items())),
            self._join_cycle,
            self._join_sent,
        )

    def next_tx(self, now: float, min_cycle: int) -> TxSlot | None:
        """Our next transmission whose air start is not in the past."""
        lay = self.layout
        if self.phase is Phase.LISTENING:
            return None
        half = lay.guard_s / 2
        p = max(int(now // lay.period_s) - 1, 0)
        change = min(
            (*self.pending.values(), *(at for at, _ in self.pending_levels.values())),
            default=None,
        )
        if change is not None:  # it takes effect on the next boundary of this table
            change = -(-change // lay.k) * lay.k
        for period in range(p, p + 3 + lay.join_every):
            pend = (period + 1) * lay.k
            if change is not None and change < pend:
                # the table changes inside this period, or before it (a frame is built
                # `prep_s` before its slot, still under the old table; the first slots
                # of a new table may belong to someone else): stay quiet
                continue
            if self.phase is Phase.MEMBER:
                if self._unsure_since is not None:
                    return None
                for idx in lay.slots_of(self.my_id, period):
                    start = lay.slot_start(period, idx)
                    cycle = lay.slot_cycle(period, idx)
                    offset = lay.lone_offset(self.my_id, cycle, self.timing) if lay.n == 1 else 0.0
                    air = start + half + offset
                    if air >= now and cycle >= min_cycle:
                        return TxSlot(start, air, cycle, period, False, lay.budget)
                continue
            if self._join_cycle is None or (period + 1) * lay.k <= self._join_cycle:
                continue
            if self._join_sent is not None or not self._view_is_fresh(now):
                return None
            jdx = lay.join_index(period)
            if jdx is None:
                continue
            start = lay.slot_start(period, jdx)
            cycle = lay.slot_cycle(period, jdx)
            air = start + half + self._join_offset()
            if air < now or cycle < min_cycle:
                continue
            return TxSlot(start, air, cycle, period, True, 0)
        return None

    def _view_is_fresh(self, now: float) -> bool:
        """A joiner sends only while members confirm its view of the table: a stale
        view would put its JOIN in someone's slot."""
        if self._confirmed is None:
            return False
        cycle = int(now // self.config.cycle_s)
        return cycle - self._confirmed <= 2 * self.layout.k + 1 and self._mismatch == 0

    def _join_offset(self) -> float:
        """Joiners spread their JOINs over the join window (a JOIN frame is short)."""
        lay = self.layout
        jlen = lay.guard_s + self.timing.airtime_s(frame_overhead(lay.n, 0))
        positions = max(1, int((lay.slot_s - lay.guard_s) // jlen))
        return int(self._join_pick * positions) * jlen
