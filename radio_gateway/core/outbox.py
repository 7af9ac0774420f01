"""What goes into our next slot (pure): priority classes, latest-value telemetry,
fragmentation, acknowledgement and retransmission.

Classes are `swarm_proto.topics.RadioClass` values, lower first: CONTROL (commands, acks,
votes, missions, zones, fleets), ALERT, STATUS, INFO. Within a class, retransmissions
come before new messages, and older messages before newer ones. A message waiting longer
than `starve_s` moves up one class per `starve_s` waited, so slow classes are never
starved outright; PASSTHROUGH (a ground station's MAVLink, below INFO) never moves up:
it goes in the room the swarm's own traffic leaves, or waits.

- latest-only topics (telemetry) keep one message per key: a newer value replaces an
  unsent older one, and a key is not sent more often than its maximum rate. With
  `latest_keep` = k > 1 they keep the k newest unsent values instead, and a slot sends
  them together (oldest first): a TDM whose slots come every k cycles carries every
  status sampled at the cycle rate, in one authenticated frame (the per-packet sync,
  guard and tag paid once per k statuses).
- acked topics are split into 16-byte chunks (FRAG_ACKED records, any number per slot,
  a message spanning as many slots as it needs); every member acknowledges the chunks
  it holds; missing chunks are resent after `ack_timeout_s` until every member that was
  in the table when the message was queued (and still is) holds all of them, or
  `max_rounds` rounds have passed (counted as failed).
- anything else that does not fit a single MSG record is sent in unacknowledged
  chunks (FRAG), each once.
"""

from __future__ import annotations

import itertools
from collections import Counter
from dataclasses import dataclass, field

from swarm_proto.topics import RadioClass

from .frame import (
    CHUNK_BYTES,
    FRAG_FIXED,
    MAX_CHUNKS,
    MAX_RECORD_VALUE,
    RECORD_HEADER_BYTES,
    Ack,
    Frag,
    Msg,
    Record,
    record_size,
)

_MIN_FRAG = RECORD_HEADER_BYTES + FRAG_FIXED + 1


PASSTHROUGH = int(RadioClass.PASSTHROUGH)


@dataclass(frozen=True)
class OutMessage:
    key: str  # identity for latest-only replacement (the Zenoh key)
    data: bytes  # radio encoding
    klass: int = 3
    latest_only: bool = False
    acked: bool = False
    max_rate_hz: float | None = None
    ack_by: int = 0  # acked by this member only (an Ack: its issuer); 0: every member


@dataclass
class _Queued:
    msg: OutMessage
    since: float
    order: int


@dataclass
class _Chunked:
    seq: int
    msg: OutMessage
    since: float
    order: int
    total: int
    unsent: set[int]
    receivers: set[int] = field(default_factory=set)
    held: dict[int, set[int]] = field(default_factory=dict)
    last_round_s: float | None = None
    rounds: int = 0

    def missing(self) -> set[int]:
        every = set(range(self.total))
        out: set[int] = set()
        for r in self.receivers:
            out |= every - self.held.get(r, set())
        return out

    def done(self) -> bool:
        if self.unsent:
            return False
        if not self.msg.acked:
            return True
        return all(len(self.held.get(r, ())) == self.total for r in self.receivers)

    def chunk(self, i: int) -> bytes:
        return self.msg.data[i * CHUNK_BYTES : (i + 1) * CHUNK_BYTES]


@dataclass
class Outbox:
    ack_timeout_s: float = 0.3
    max_rounds: int = 8
    starve_s: float = 5.0
    queue_limit: int = 64
    seq: int = 0
    latest_keep: int = 1
    latest: dict[str, _Queued] = field(default_factory=dict)
    older: dict[str, list[_Queued]] = field(default_factory=dict)  # latest_keep > 1
    last_sent: dict[str, float] = field(default_factory=dict)
    fifo: list[_Queued] = field(default_factory=list)
    chunked: list[_Chunked] = field(default_factory=list)
    counts: Counter[str] = field(default_factory=Counter)
    _order: itertools.count[int] = field(default_factory=itertools.count)

    def submit(self, msg: OutMessage, now: float) -> bool:
        """Queue a message; False (and counted) if it cannot ever be sent."""
        if not msg.data or len(msg.data) > CHUNK_BYTES * MAX_CHUNKS:
            self.counts["too_large" if msg.data else "empty"] += 1
            return False
        q = _Queued(msg, now, next(self._order))
        if msg.latest_only and not msg.acked:
            old = self.latest.get(msg.key)
            if old is not None and self.latest_keep > 1:
                kept = self.older.setdefault(msg.key, [])
                kept.append(old)
                if len(kept) >= self.latest_keep:
                    kept.pop(0)
                    self.counts["replaced"] += 1
            elif old is not None:
                self.counts["replaced"] += 1
                q.since = old.since
            self.latest[msg.key] = q
            return True
        if len(self.fifo) >= self.queue_limit:
            self.fifo.pop(0)
            self.counts["overflow"] += 1
        self.fifo.append(q)
        return True

    def pending(self) -> int:
        older = sum(len(v) for v in self.older.values())
        return len(self.latest) + older + len(self.fifo) + len(self.chunked)

    def control_backlog(self, klass: int = 0) -> int:
        """Bytes of class `klass` (CONTROL: commands, acks, votes, missions) still to go
        on air: queued messages, unsent chunks and chunks some receiver still misses."""
        total = sum(len(q.msg.data) for q in self.fifo if q.msg.klass <= klass)
        for c in self.chunked:
            if c.msg.klass <= klass:
                total += len(c.unsent | c.missing()) * CHUNK_BYTES
        return total

    def on_ack(self, from_node: int, ack: Ack) -> None:
        for c in self.chunked:
            if c.seq == ack.seq and c.msg.acked:
                if not ack.mask:
                    c.held[from_node] = set(range(c.total))
                else:
                    have = c.held.setdefault(from_node, set())
                    for i in range(min(c.total, len(ack.mask) * 8)):
                        if ack.mask[i // 8] >> (i % 8) & 1:
                            have.add(i)
                return

    def forget(self, node: int) -> None:
        """A member left: stop waiting for its acknowledgements."""
        for c in self.chunked:
            c.receivers.discard(node)

    def _klass(self, msg: OutMessage, since: float, now: float) -> int:
        if msg.klass >= PASSTHROUGH:  # a ground station's MAVLink never moves up
            return msg.klass
        return max(0, msg.klass - int(max(0.0, now - since) // self.starve_s))

    def fill(self, budget: int, now: float, receivers: frozenset[int]) -> list[Record]:
        """Records for one slot of `budget` bytes; `receivers` must acknowledge."""
        self._retire()
        out: list[Record] = []
        room = budget
        items: list[tuple[int, int, int, object]] = []
        for c in self.chunked:
            items.append((self._klass(c.msg, c.since, now), 0, c.order, c))
        older = [q for kept in self.older.values() for q in kept]
        for q in older + list(self.latest.values()) + self.fifo:
            if self._rate_ok(q.msg, now):
                items.append((self._klass(q.msg, q.since, now), 1, q.order, q))
        for _, _, _, item in sorted(items, key=lambda t: t[:3]):
            if room < _MIN_FRAG:
                break
            if isinstance(item, _Chunked):
                room -= self._send_chunks(item, room, now, out)
            else:
                assert isinstance(item, _Queued)
                room -= self._send_new(item, room, budget, now, receivers, out)
        self._retire()
        return out

    def _rate_ok(self, msg: OutMessage, now: float) -> bool:
        if msg.max_rate_hz is None or msg.key not in self.last_sent:
            return True
        return now - self.last_sent[msg.key] >= 0.75 / msg.max_rate_hz

    def _dequeue(self, q: _Queued) -> None:
        kept = self.older.get(q.msg.key)
        if self.latest.get(q.msg.key) is q:
            del self.latest[q.msg.key]
        elif kept is not None and q in kept:
            kept.remove(q)
            if not kept:
                del self.older[q.msg.key]
        elif q in self.fifo:
            self.fifo.remove(q)

    def _send_new(
        self,
        q: _Queued,
        room: int,
        budget: int,
        now: float,
        receivers: frozenset[int],
        out: list[Record],
    ) -> int:
        msg = q.msg
        if not msg.acked and len(msg.data) <= MAX_RECORD_VALUE:
            rec = Msg(msg.data)
            if record_size(rec) <= room:
                out.append(rec)
                self._dequeue(q)
                self.last_sent[msg.key] = now
                self.counts["sent"] += 1
                return record_size(rec)
            if record_size(rec) <= budget:
                return 0  # fits a whole slot: wait for one with room rather than split it
        total = -(-len(msg.data) // CHUNK_BYTES)
        c = _Chunked(
            seq=self.seq,
            msg=msg,
            since=q.since,
            order=q.order,
            total=total,
            unsent=set(range(total)),
            receivers=(
                set()
                if not msg.acked
                else {msg.ack_by}
                if msg.ack_by in receivers
                else set(receivers)
            ),
        )
        self.seq = (self.seq + 1) & 0xFFFF
        self._dequeue(q)
        self.last_sent[msg.key] = now
        self.chunked.append(c)
        self.counts["sent"] += 1
        return self._send_chunks(c, room, now, out)

    def _send_chunks(self, c: _Chunked, room: int, now: float, out: list[Record]) -> int:
        todo = set(c.unsent)
        resend = (
            c.msg.acked
            and not c.unsent
            and (c.last_round_s is None or now - c.last_round_s >= self.ack_timeout_s)
        )
        if resend:
            todo = c.missing()
            if todo:
                c.rounds += 1
                self.counts["retransmitted"] += 1
        if not todo:
            return 0
        used = 0
        sent: set[int] = set()
        order = sorted(todo)
        i = 0
        by = c.msg.ack_by if c.msg.acked and c.receivers == {c.msg.ack_by} else 0
        fixed = FRAG_FIXED + (2 if by else 0)
        while i < len(order):
            avail = min(room - used - RECORD_HEADER_BYTES - fixed, MAX_RECORD_VALUE - fixed)
            first = order[i]
            data = b""
            while i < len(order) and order[i] == first + len(data) // CHUNK_BYTES:
                piece = c.chunk(order[i])
                if len(data) + len(piece) > avail:
                    break
                data += piece
                i += 1
            if not data:
                break
            rec = Frag(c.seq, c.total, first, data, c.msg.acked, by)
            out.append(rec)
            used += record_size(rec)
            sent.update(rec.chunks)
        if sent:
            c.unsent -= sent
            if not c.unsent:
                c.last_round_s = now
        return used

    def _retire(self) -> None:
        keep = []
        for c in self.chunked:
            if c.done():
                continue
            if c.msg.acked and c.rounds >= self.max_rounds and not c.unsent:
                self.counts["failed"] += 1
                continue
            keep.append(c)
        self.chunked = keep


def ack_mask(held: set[int], total: int) -> bytes:
    out = bytearray((total + 7) // 8)
    for i in held:
        out[i // 8] |= 1 << (i % 8)
    return bytes(out)
