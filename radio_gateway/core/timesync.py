"""Slot timing from GPS time, trimmed by the timing of received frames (pure).

Each node reads a time source (GPS time from the autopilot, NMEA or a PPS-disciplined
clock: stratum 0; a free-running system clock: stratum 3) and advertises its stratum
in every frame. Every frame received in a known slot gives an offset sample: when it
arrived minus when it should have arrived had both clocks agreed (slot start + guard/2
+ the link's transmit and receive delays for its length).

A node corrects its time only towards a *reference*: the peer with the lowest
(stratum, node id) heard recently, if that is lower than its own (source stratum,
node id). It then advertises the reference's stratum + 1 (at most 2; 3 stays 3). Along
any chain of references (stratum, id) strictly decreases, so there are no loops, and
the root never moves, so the swarm cannot drift together. GPS nodes never correct: their
samples are only reported (stats: per-peer time offset).
"""

from __future__ import annotations

import statistics
from collections import deque
from dataclasses import dataclass, field

GPS = 0
FREE = 3


@dataclass
class TimeSync:
    my_id: int
    source_stratum: int = GPS
    max_correction_s: float = 0.1
    gain: float = 0.5
    lock_tolerance_s: float = 0.001
    window: int = 7
    fresh_cycles: int = 15
    correction_s: float = 0.0
    samples: dict[int, deque[float]] = field(default_factory=dict)
    strata: dict[int, tuple[int, int]] = field(default_factory=dict)  # src -> (stratum, cycle)

    def __post_init__(self) -> None:
        if self.source_stratum not in (GPS, FREE):
            raise ValueError("a time source is GPS (0) or FREE (3)")

    def heard(self, src: int, stratum: int, cycle: int) -> None:
        self.strata[src] = (stratum, cycle)

    def sample(self, src: int, offset_s: float) -> None:
        """arrival - expected arrival, seconds (positive: the sender looks late)."""
        q = self.samples.setdefault(src, deque(maxlen=self.window))
        q.append(offset_s)

    def offset_s(self, src: int) -> float | None:
        q = self.samples.get(src)
        return statistics.median(q) if q else None

    def reference(self, cycle: int) -> int | None:
        if self.source_stratum == GPS:
            return None
        best: tuple[int, int] | None = None
        for src, (stratum, seen) in self.strata.items():
            if cycle - seen <= self.fresh_cycles and (best is None or (stratum, src) < best):
                best = (stratum, src)
        if best is None or best >= (self.source_stratum, self.my_id):
            return None
        return best[1]

    def stratum(self, cycle: int) -> int:
        ref = self.reference(cycle)
        if ref is None:
            return self.source_stratum
        return min(self.strata[ref][0] + 1, 2) if self.strata[ref][0] < FREE else FREE

    def locked(self, cycle: int) -> bool:
        """Whether our time is good enough to transmit."""
        ref = self.reference(cycle)
        if ref is None:
            return True
        q = self.samples.get(ref)
        if not q or len(q) < 3:
            return False
        return abs(statistics.median(q)) <= max(self.lock_tolerance_s, 0.0)

    def update(self, cycle: int) -> None:
        """Once per cycle: move towards the reference."""
        ref = self.reference(cycle)
        if ref is None:
            return
        q = self.samples.get(ref)
        if not q or len(q) < 3:
            return
        est = statistics.median(q)
        step = -self.gain * est
        new = max(-self.max_correction_s, min(self.max_correction_s, self.correction_s + step))
        delta = new - self.correction_s
        self.correction_s = new
        for src, dq in self.samples.items():  # stored samples were measured before the step
            self.samples[src] = deque((x + delta for x in dq), maxlen=self.window)
