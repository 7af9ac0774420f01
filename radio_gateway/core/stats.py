"""Per-peer radio statistics as a `RadioStats` message (pure): rates and loss over the
interval since the previous report, totals since start."""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field

from swarm_proto.messages import PeerRadioStats, RadioStats

from . import frame as fr
from .node import PeerCounters, RadioNode


@dataclass
class StatsReporter:
    """Call `report(node, now)` about once a second."""

    _prev_t: float | None = None
    _prev_peers: dict[int, PeerCounters] = field(default_factory=dict)
    _prev_counts: Counter[str] = field(default_factory=Counter)

    def report(self, node: RadioNode, now: float, extra: Counter[str] | None = None) -> RadioStats:
        m = node.membership
        lay = m.layout
        c = node.counts
        extra = extra or Counter()
        dt = max(1e-3, now - self._prev_t) if self._prev_t is not None else None
        capacity = fr.frame_overhead(lay.n, lay.budget)
        peers = []
        cycle = int(node.network_time(now) // node.cycle_s)
        for pid, p in sorted(node.peers.items()):
            prev = self._prev_peers.get(pid, PeerCounters())
            frames = p.frames - prev.frames
            expected = p.expected - prev.expected
            loss = 0.0 if expected <= 0 else min(1.0, max(0.0, 1.0 - frames / expected))
            avg = (p.bytes - prev.bytes) / frames if frames else 0.0
            offset = node.timesync.offset_s(pid)
            last = p.last_cycle
            peers.append(
                PeerRadioStats(
                    node_id=pid,
                    packets_per_s=round(min(frames / dt, 10_000.0), 2) if dt else 0.0,
                    loss=round(loss, 4),
                    slot_utilization=round(min(1.0, avg / capacity), 4) if capacity else 0.0,
                    time_offset_ms=round(max(-1e6, min(1e6, (offset or 0.0) * 1000)), 2),
                    last_heard_s=round(
                        max(0.0, (cycle - last) * node.cycle_s) if last is not None else 0.0, 2
                    ),
                    time_stratum=p.last_stratum,
                )
            )
        budget = c["budget_bytes"] - self._prev_counts["budget_bytes"]
        used = c["payload_bytes"] - self._prev_counts["payload_bytes"]

        def total(*names: str, src: Counter[str] = c) -> int:
            return min(sum(src[n] for n in names), 2**32 - 1)

        msg = RadioStats(
            node_id=node.config.node_id,
            time_unix_s=round(max(0.0, min(now, 4.0e9)), 3),
            phase=m.phase.value,
            members=lay.members,
            table_version=lay.table_hash,
            rate_divisor=min(lay.k, 255),
            slot_s=round(lay.slot_s, 6),
            slot_budget_bytes=min(lay.budget, 65535),
            slot_utilization=round(min(1.0, used / budget), 4) if budget > 0 else 0.0,
            time_offset_ms=round(node.timesync.correction_s * 1000, 2),
            time_stratum=node.timesync.stratum(cycle),
            tx_frames=total("tx_frames", "tx_join"),
            rx_frames=total("rx_frames"),
            dropped_corrupt=total("drop_cobs", "drop_crc", "drop_short", "drop_version"),
            dropped_forged=total("drop_mac"),
            dropped_replayed=total("drop_replay", "drop_stale", "drop_own"),
            dropped_malformed=total("drop_malformed"),
            dropped_duplicates=total("air_duplicate", src=extra),
            retransmissions=min(node.outbox.counts["retransmitted"], 2**32 - 1),
            failed_deliveries=min(node.outbox.counts["failed"], 2**32 - 1),
            peers=tuple(peers),
        )
        self._prev_t = now
        self._prev_peers = {
            k: PeerCounters(v.frames, v.bytes, v.expected) for k, v in node.peers.items()
        }
        self._prev_counts = Counter(c)
        return msg
