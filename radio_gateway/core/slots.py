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

**Shares by need (the adaptive schedule, issue 19).** Each member has a need *level*
(0 calm, 1 manoeuvring, 2 avoiding or control traffic, 3 spare), agreed like the members
themselves (scheduled changes, `membership.py`) and carried in every frame's header. A
member of level l gets 2^(l - lowest level) slots per period, spread evenly over the
period (a stride order: its j-th slot at (j + 1/2) / w of the period, ties by rank), at
most one per cycle (a frame's cycle counter is its replay identity): a slot that would
be a member's second in one cycle is dropped, deterministically. The period is as many
cycles as the slots need, so past the physical limit every member's rate falls in
proportion, never into collisions. When every member has the same level the table is
the unweighted one, with the same hash.
"""

from __future__ import annotations

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
    join_every: int = 25  # periods between stolen join windows when no join slot fits
    listen_cycles: int = 3  # silence before a node bootstraps a table of its own
    join_backoff: int = 4  # initial random backoff (join windows), doubles per failure
    mismatch_periods: int = 2  # periods a better table must persist before a resync

    def __post_init__(self) -> None:
        if not (self.cycle_s > 0 and 0 <= self.guard_s < self.cycle_s):
            raise ValueError("need 0 <= guard_s < cycle_s")
        if self.silent_periods < 1 or self.activation_periods < 1 or self.join_every < 1:
            raise ValueError("silent_periods, activation_periods and join_every must be >= 1")


MAX_LEVEL = 3  # need levels 0..3 (two header bits)


def normalised_levels(
    members: tuple[int, ...], levels: Mapping[int, int] | None
) -> tuple[int, ...]:
    """Each member's level (sorted members) less the lowest: only differences count."""
    lv = [min(MAX_LEVEL, max(0, (levels or {}).get(m, 0))) for m in sorted(set(members))]
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
        weights = [1 << x for x in norm]
        order: tuple[int, ...] = ()
        k = max(1, math.ceil(n * lmin / c - 1e-9))
        if any(norm):
            weights, order, k = _weighted(weights, lmin, c)
        total = sum(weights) if order else n
        join = (total + 1) * lmin <= k * c + 1e-9
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
        try:
            return self.members.index(node)
        except ValueError:
            return None

    @property
    def member_slots_total(self) -> int:
        """Member slots per period (the join slot not counted)."""
        return len(self.order) if self.order else self.n

    def slot_start(self, period: int, index: int) -> float:
        return period * self.k * self.cycle_s + index * self.slot_s

    def slot_cycle(self, period: int, index: int) -> int:
        """The cycle counter of a slot: the cycle in which it starts."""
        return period * self.k + (index * self.k) // self.slots

    def join_index(self, period: int) -> int | None:
        """Which slot of `period` is the join window, if any."""
        if self.join_slot:
            return self.slots - 1
        total = self.member_slots_total
        if total and period % self.join_every == 0:
            return (period // self.join_every) % total
        return None

    def slots_of(self, node: int, period: int) -> tuple[int, ...]:
        """The slot indices `node` sends in during `period`, in time order (none: not a
        member; a slot that is this period's join window is left out)."""
        r = self.rank(node)
        if r is None:
            return ()
        own = tuple(i for i, x in enumerate(self.order) if x == r) if self.order else (r,)
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
        return sum(1 for x in self.order if x == r) if self.order else 1

    def lone_offset(self, node: int, cycle: int, timing: LinkTiming) -> float:
        """A lone member's pseudo-random start offset inside its slot."""
        room = self.slot_s - self.min_slot_s
        if room <= 0:
            return 0.0
        h = hashlib.blake2s(f"{node}:{cycle}".encode(), digest_size=4).digest()
        return room * int.from_bytes(h, "little") / 2**32


def _weighted(
    weights: list[int], lmin: float, cycle_s: float
) -> tuple[list[int], tuple[int, ...], int]:
    """Weighted slots: each member's weight capped at the period's cycles, its slots in a
    stride order, a slot that would be a member's second in one cycle dropped. Returns
    the weights kept, the order (member rank per slot) and k."""
    w = list(weights)
    for _ in range(64):
        total = sum(w)
        k = max(1, math.ceil(total * lmin / cycle_s - 1e-9))
        capped = [min(x, k) for x in w]
        if capped != w:
            w = capped
            continue
        marks = sorted(((j + 0.5) / x, r) for r, x in enumerate(w) for j in range(x))
        order = [r for _, r in marks]
        join = (total + 1) * lmin <= k * cycle_s + 1e-9
        slots = total + (1 if join else 0)
        seen: set[tuple[int, int]] = set()
        keep: list[int] = []
        for i, r in enumerate(order):
            cyc = (i * k) // slots
            if (r, cyc) in seen:
                continue
            seen.add((r, cyc))
            keep.append(r)
        if len(keep) == len(order):
            return w, tuple(order), k
        w = [sum(1 for x in keep if x == r) for r in range(len(w))]
    raise AssertionError("weighted slot table did not settle")
