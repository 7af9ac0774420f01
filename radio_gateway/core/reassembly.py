"""Inbound fragments (pure): reassembly, duplicate suppression and the acknowledgements
we owe.

A message is identified by (source, seq). Chunks may arrive in any order, repeated, over
many slots. A completed acked message is remembered for `done_ttl_s`, so retransmitted
chunks are acknowledged again but never delivered twice. Partial messages expire after
`partial_ttl_s`; at most `max_partials` per source are kept (the oldest goes first).
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field

from .frame import CHUNK_BYTES, Ack, Frag
from .outbox import ack_mask


@dataclass
class _Partial:
    total: int
    acked: bool
    started_s: float
    chunks: dict[int, bytes] = field(default_factory=dict)


@dataclass
class Reassembly:
    node_id: int = 0  # ours: a fragment acked by another node only is not acked by us
    partial_ttl_s: float = 10.0
    done_ttl_s: float = 60.0
    max_partials: int = 8
    partials: dict[tuple[int, int], _Partial] = field(default_factory=dict)
    done: dict[tuple[int, int], float] = field(default_factory=dict)
    owed: dict[tuple[int, int], Ack] = field(default_factory=dict)
    counts: Counter[str] = field(default_factory=Counter)

    def on_frag(self, src: int, f: Frag, now: float) -> bytes | None:
        """The whole message when this fragment completes it, else None."""
        key = (src, f.seq)
        owe = f.acked and f.ack_by in (0, self.node_id)
        if key in self.done:
            if owe:
                self.owed[key] = Ack(src, f.seq)
            self.counts["duplicate"] += 1
            return None
        p = self.partials.get(key)
        if p is not None and (p.total != f.total or p.acked != f.acked):
            self.counts["inconsistent"] += 1
            p = None
        if p is None:
            mine = [k for k in self.partials if k[0] == src]
            if len(mine) >= self.max_partials:
                oldest = min(mine, key=lambda k: self.partials[k].started_s)
                del self.partials[oldest]
                self.owed.pop(oldest, None)
                self.counts["evicted"] += 1
            p = self.partials[key] = _Partial(f.total, f.acked, now)
        for j, i in enumerate(f.chunks):
            p.chunks[i] = f.data[j * CHUNK_BYTES : (j + 1) * CHUNK_BYTES]
        if len(p.chunks) < p.total:
            if owe:
                self.owed[key] = Ack(src, f.seq, ack_mask(set(p.chunks), p.total))
            return None
        del self.partials[key]
        self.done[key] = now
        if owe:
            self.owed[key] = Ack(src, f.seq)
        self.counts["complete"] += 1
        return b"".join(p.chunks[i] for i in range(p.total))

    def take_acks(self) -> list[Ack]:
        acks = list(self.owed.values())
        self.owed.clear()
        return acks

    def give_back(self, acks: list[Ack]) -> None:
        """Acknowledgements that did not fit this slot."""
        for a in acks:
            self.owed.setdefault((a.src, a.seq), a)

    def expire(self, now: float) -> None:
        for k in [k for k, p in self.partials.items() if now - p.started_s > self.partial_ttl_s]:
            del self.partials[k]
            self.owed.pop(k, None)
            self.counts["expired"] += 1
        for k in [k for k, t in self.done.items() if now - t > self.done_ttl_s]:
            del self.done[k]
