"""The TDM slot table: a pure function of the membership and the configuration, so that
every node that agrees on the members computes the same table.

Time is split into cycles of `cycle_s` (200 ms: 5 Hz) aligned to GPS time: cycle c starts
at c * cycle_s. A *period* is k cycles (k = 1 normally). Each period is split into equal
slots, one per member in ascending node-id order, plus, when it fits, a join slot at the
end for nodes asking to join. A slot is

    | guard/2 | sync preamble + frame | spare | guard/2 |

and the smallest slot that carries `min_payload` record bytes is the physical limit. When
the members do not fit in one cycle, k grows (each node sends every k-th cycle: 5/k Hz)
instead of slots colliding; `over_limit` says so. When no join slot fits, every
`join_every`-th period the slot of one member (in rotation) becomes the join window.

A lone member (n = 1) sends at a pseudo-random offset within its slot, so that two nodes
that bootstrapped alone at the same time do not collide forever and can find each other.

**Shares by need (the adaptive schedule).** Each member has a need *level*
(0 parked, 1 flying: the default, 2 avoiding or control traffic, 3 spare), agreed like the members
themselves (scheduled changes, `membership.py`) and carried in every frame's header. A
member of level l gets w = 2^(l - lowest level) slots per period, evenly spaced: the
period is W (the largest w) sub-periods, and a member sits in every (W / w)-th one
(`_weighted`), at most once per cycle (a frame's cycle counter is its replay identity).
The period is as many cycles as the slots need, so past the physical limit every
member's rate falls in proportion, never into collisions; when the whole table fits one
cycle everyone has every cycle and levels change nothing. When every member has the same
level the table is the unweighted one, with the same hash.
"""

from __future__ import annotations

import functools
import hashlib
import math
from collections.abc import Mapping
from dataclasses import dataclass

from .airtime import LinkTiming
from .frame import frame_overhead


@dataclass(frozen=True)
class TdmConfig:
    cycle_s: float = 0.2
    guard_s: float = 0.005
    min_payload: int = 42  # record bytes every slot must carry: a 40-byte status + header
    silent_periods: int = 5  # leave detection: periods without evidence of life
    activation_periods: int = 2  # membership changes take effect this many periods later
    # a LEAVE of a member heard (directly, or ourselves in a peer's bitmap) in the last
    # fresh_periods periods is a stale sender's view: not adopted (< silent_periods)
    fresh_periods: int = 2
    # every other member unheard at once (the channel, or our receiver, went quiet): no
    # evidence against any of them for this many periods; past it, their silence counts
    # (the members that all left at once leave; two groups that formed apart and collide
    # slot for slot on one channel fall apart and re-merge: membership.py)
    outage_periods: int = 25
    join_every: int = 25  # periods between stolen join windows when no join slot fits
    listen_cycles: int = 3  # silence before a node bootstraps a table of its own
    join_backoff: int = 4  # initial random backoff (join windows), doubles per failure
    mismatch_periods: int = 2  # periods a better table must persist before a resync
    # leave detection under loss: a member is silent only once a silence that long has at
    # most this chance for a member still on the air, at the loss it showed over the last
    # `loss_window_periods` (a loaded host's late packets collide: every receiver loses
    # them at once, and 5 periods of it is no longer rare; membership.silence_limit)
    leave_confidence: float = 1e-5
    loss_window_periods: int = 50

    def __post_init__(self) -> None:
        if not (self.cycle_s > 0 and 0 <= self.guard_s < self.cycle_s):
            raise ValueError("need 0 <= guard_s < cycle_s")
        if self.silent_periods < 1 or self.activation_periods < 1 or self.join_every < 1:
            raise ValueError("silent_periods, activation_periods and join_every must be >= 1")
        if self.outage_periods < self.silent_periods:
            raise ValueError("outage_periods must be >= silent_periods")
        if not 0 < self.leave_confidence < 1 or self.loss_window_periods < 1:
            raise ValueError("leave_confidence is in (0, 1) and loss_window_periods >= 1")


MAX_LEVEL = 3  # need levels 0..3 (two header bits)
DEFAULT_LEVEL = 1  # a member's level until it asks for another (a vehicle in flight)


def normalised_levels(
    members: tuple[int, ...], levels: Mapping[int, int] | None
) -> tuple[int, ...]:
    """Each member's level (sorted members) less the lowest: only differences count."""
    lv = [
        min(MAX_LEVEL, max(0, (levels or {}).get(m, DEFAULT_LEVEL))) for m in sorted(set(members))
    ]
    low = min(lv, default=0)
    return tuple(x - low for x in lv)


def table_hash(members: tuple[int, ...], levels: Mapping[int, int] | None = None) -> int:
    """The slot-table version carried in frames: 16 bits of BLAKE2s of the members (and
    of their need levels, when they differ)."""
    ms = sorted(set(members))
    data = b"".join(m.to_bytes(2, "little") for m in ms)
    norm = normalised_levels(tuple(ms), levels)
    person = b"bdslots1"
    if any(norm):
        data += bytes(norm)
        person = b"bdslots2"
    return int.from_bytes(hashlib.blake2s(data, digest_size=2, person=person).digest(), "little")


def min_slot_s(n: int, timing: LinkTiming, config: TdmConfig) -> float:
    return config.guard_s + timing.airtime_s(frame_overhead(n, config.min_payload))


def physical_limit(timing: LinkTiming, config: TdmConfig) -> int:
    """The most members that fit one cycle (every node every cycle), no join slot."""
    n = 1
    while (n + 1) * min_slot_s(n + 1, timing, config) <= config.cycle_s + 1e-12:
        n += 1
    return n if n * min_slot_s(n, timing, config) <= config.cycle_s + 1e-12 else 0


@dataclass(frozen=True)
class SlotLayout:
    members: tuple[int, ...]
    cycle_s: float
    guard_s: float
    k: int  # cycles per period: each member sends once per period
    slots: int  # slots per period
    slot_s: float
    join_slot: bool  # a dedicated join slot closes each period
    join_every: int
    budget: int  # record bytes a slot carries
    min_slot_s: float
    table_hash: int
    levels: tuple[int, ...] = ()  # need level of each member (normalised); () = all 0
    order: tuple[int, ...] = ()  # member rank of each slot; () = one slot each, by rank

    @classmethod
    def build(
        cls,
        members: tuple[int, ...],
        timing: LinkTiming,
        config: TdmConfig,
        levels: Mapping[int, int] | None = None,
    ) -> SlotLayout:
        members = tuple(sorted(set(members)))
        n = len(members)
        norm = normalised_levels(members, levels)
        lmin = min_slot_s(n, timing, config)
        c = config.cycle_s
        order: tuple[int, ...] = ()
        k = max(1, math.ceil(n * lmin / c - 1e-9))
        join = (n + 1) * lmin <= k * c + 1e-9
        total = n
        if any(norm):
            _, order, k, join = _weighted([1 << x for x in norm], lmin, c)
            total = len(order)
        slots = total + (1 if join else 0)
        slot_s = k * c / max(1, slots)
        air = min(timing.bytes_in(slot_s - config.guard_s), timing.max_packet)
        budget = 0
        while frame_overhead(n, budget + 1) <= air:
            budget += 1
        return cls(
            members=members,
            cycle_s=c,
            guard_s=config.guard_s,
            k=k,
            slots=slots,
            slot_s=slot_s,
            join_slot=join,
            join_every=config.join_every,
            budget=budget,
            min_slot_s=lmin,
            table_hash=table_hash(members, dict(zip(members, norm, strict=True))),
            levels=norm if any(norm) else (),
            order=order,
        )

    @property
    def n(self) -> int:
        return len(self.members)

    @property
    def over_limit(self) -> bool:
        return self.k > 1

    @property
    def period_s(self) -> float:
        return self.k * self.cycle_s

    @property
    def rate_hz(self) -> float:
        return 1.0 / self.period_s

    def rank(self, node: int) -> int | None:
        return self._ranks.get(node)

    @property
    def member_slots_total(self) -> int:
        """Slots per period but the join slot (a weighted table's idle ones included)."""
        return len(self.order) if self.order else self.n

    def slot_start(self, period: int, index: int) -> float:
        return period * self.k * self.cycle_s + index * self.slot_s

    def slot_cycle(self, period: int, index: int) -> int:
        """The cycle counter of a slot: the cycle in which it starts."""
        return period * self.k + (index * self.k) // self.slots

    def join_index(self, period: int) -> int | None:
        """Which slot of `period` is the join window, if any: the join slot, else a
        weighted table's first idle slot, else every `join_every` periods one member
        slot in rotation."""
        if self.join_slot:
            return self.slots - 1
        if -1 in self.order:
            return self.order.index(-1)
        total = self.member_slots_total
        if total and period % self.join_every == 0:
            return (period // self.join_every) % total
        return None

    @functools.cached_property
    def _by_rank(self) -> dict[int, tuple[int, ...]]:
        out: dict[int, list[int]] = {}
        for i, r in enumerate(self.order):
            out.setdefault(r, []).append(i)
        return {r: tuple(v) for r, v in out.items()}

    @functools.cached_property
    def _ranks(self) -> dict[int, int]:
        return {m: i for i, m in enumerate(self.members)}

    def slots_of(self, node: int, period: int) -> tuple[int, ...]:
        """The slot indices `node` sends in during `period`, in time order (none: not a
        member; a slot that is this period's join window is left out)."""
        r = self._ranks.get(node)
        if r is None:
            return ()
        own = self._by_rank.get(r, ()) if self.order else (r,)
        if not self.join_slot:
            j = self.join_index(period)
            own = tuple(i for i in own if i != j)
        return own

    def member_slot(self, node: int, period: int) -> int | None:
        """The first slot index `node` sends in during `period` (None: not a member, or
        its only slot is this period's join window)."""
        own = self.slots_of(node, period)
        return own[0] if own else None

    def share(self, node: int) -> int:
        """Slots per period of `node` (0: not a member)."""
        r = self.rank(node)
        if r is None:
            return 0
        return len(self._by_rank.get(r, ())) if self.order else 1

    def lone_offset(self, node: int, cycle: int, timing: LinkTiming) -> float:
        """A lone member's pseudo-random start offset inside its slot."""
        room = self.slot_s - self.min_slot_s
        if room <= 0:
            return 0.0
        h = hashlib.blake2s(f"{node}:{cycle}".encode(), digest_size=4).digest()
        return room * int.from_bytes(h, "little") / 2**32


def _weighted(
    weights: list[int], lmin: float, cycle_s: float
) -> tuple[list[int], tuple[int, ...], int, bool]:
    """The weighted table: returns the weights kept, the order (member rank of each slot,
    -1 for an idle one), k and whether a join slot closes the period.

    Weights are powers of two; W is the largest. The period is W sub-periods of L slots
    each: a member of weight w sits in every (W / w)-th sub-period, in a group chosen to
    balance the sub-periods' loads (members by weight, then rank; the least loaded group,
    then the lowest), at the same position in each when w = W; L is the largest load
    (a sub-period with fewer members has idle slots, which serve as join windows). A
    member's slots are then at least a sub-period apart: k is the smallest number of
    cycles that fits every slot and gives each sub-period at least one cycle (a frame's
    cycle counter is its replay identity: one frame per member per cycle). Weights are
    capped so that W <= k: a table that fits one cycle gives everyone every cycle."""
    w = list(weights)
    n = len(w)
    while True:
        big = max(w)
        subs: list[list[int]] = [[] for _ in range(big)]
        for r in sorted(range(n), key=lambda i: (-w[i], i)):
            step = big // w[r]
            group = min(
                range(step), key=lambda g: (max(len(subs[s]) for s in range(g, big, step)), g)
            )
            for s in range(group, big, step):
                subs[s].append(r)
        per = max(len(x) for x in subs)
        total = big * per
        k = max(1, math.ceil(total * lmin / cycle_s - 1e-9))
        if big <= k or big == 1:
            break
        cap = 1 << (k.bit_length() - 1)  # the largest power of two <= k
        w = [min(x, cap) for x in w]
    order = [-1] * total
    for sub, ranks in enumerate(subs):
        for pos, r in enumerate(ranks):
            order[sub * per + pos] = r
    while True:
        join = (total + 1) * lmin <= k * cycle_s + 1e-9
        slots = total + (1 if join else 0)
        cycles: set[tuple[int, int]] = set()
        ok = True
        for i, r in enumerate(order):
            if r < 0:
                continue
            key = (r, (i * k) // slots)
            if key in cycles:
                ok = False
                break
            cycles.add(key)
        if ok:
            return w, tuple(order), k, join
        k += 1
