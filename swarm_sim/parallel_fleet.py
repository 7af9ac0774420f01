"""A FastFleet split over worker processes, one per core: each worker runs the vehicles
of its share (simulated autopilots, their links and node cores, as FastFleet does) and
the parts keep one clock.

The swarm's messages are broadcast: every node hears every other, so a swarm's cost
grows with the square of its size and a 100-vehicle swarm is more than one Python
process can run at ten times real time (docs/benchmarks.md, `sim`). Split in two, each
part delivers half of the messages.

Time is kept in windows as long as the swarm's network latency (`latency_s`, 10 ms
by default, a LAN's): a message published at t is heard at t + latency_s, in its own
part as in the others, so in a window [T, T + latency_s) nothing a part hears from
another can be due; each part runs its window alone, then the parts exchange what they
published (LAN bytes, with the time they are heard) and the next window starts, when
something is first due in any part (each part says when its next deadline is): windows
with nothing in them are not run (one exchange per window, and most of the wall time is
the exchanges); the same run as back-to-back windows (`skip_idle=False`,
tests/swarm_node/test_scaling.py). Every run with the same split is the same; in one process with the same latency, messages
heard at the same time interleave in publishing order, here a part's own first.

    with ParallelFleet(range(1, 101), profiles, parts=2) as fleet:
        fleet.run_for(10.0)
"""

from __future__ import annotations

import multiprocessing as mp
import time
from collections.abc import Iterable, Mapping, Sequence
from multiprocessing.connection import Connection
from typing import Any

from swarm_node.core.profile import VehicleProfile

from .core import SITL_HOME, Home
from .runtime.server import spread_homes

Outgoing = list[tuple[float, int, bytes, type]]
LATENCY_S = 0.010  # the swarm's network latency (a LAN's), the length of a window


def _part_main(
    conn: Connection,
    members: Sequence[int],
    profiles: Mapping[int, VehicleProfile],
    homes: Sequence[Home],
    start_unix_s: float,
    latency_s: float,
    tokens: Sequence[int] | None,
) -> None:
    from .fast_fleet import FastFleet

    fleet = FastFleet.build(members, profiles, homes=homes, start_unix_s=start_unix_s)
    fleet.export, fleet.latency_s = [], latency_s
    if tokens is not None:
        fleet.hold_tokens(tokens)
    conn.send(("ready", fleet.next_deadline()))
    cpu0 = time.process_time()
    while True:
        cmd, t, incoming = conn.recv()
        if cmd == "stop":
            conn.send(("stopped", time.process_time() - cpu0))
            return
        if cmd == "peers":
            conn.send(_live_peers(fleet))
            continue
        if cmd == "heard":
            conn.send(fleet.heard_messages)
            continue
        if cmd == "published":
            conn.send(fleet.published)
            continue
        for at, raw, cls in incoming:
            fleet.receive(raw, cls, at)
        fleet.run_before(t)
        out, fleet.export = fleet.export, []
        conn.send((out, fleet.next_deadline()))


def _live_peers(fleet: Any) -> dict[int, list[int]]:
    return {vid: v.node.members.live_ids() for vid, v in fleet.vehicles.items()}


class ParallelFleet:
    """`members` (database ids, profiles as for FastFleet.build) split into `parts`
    worker processes (contiguous shares of the list), homes as FastFleet.build gives
    the whole list. `liveliness`: a LAN swarm, every node sees every other's liveliness
    token (FastFleet.hold_tokens)."""

    def __init__(
        self,
        members: Iterable[int],
        profiles: Mapping[int, VehicleProfile],
        *,
        parts: int = 2,
        home: Home = SITL_HOME,
        spacing_m: float = 40.0,
        start_unix_s: float = 1.8e9,
        latency_s: float = LATENCY_S,
        liveliness: bool = False,
        skip_idle: bool = True,
    ) -> None:
        from .fast_fleet import FastFleet

        ids = list(members)
        homes = spread_homes(home, len(ids), spacing_m)
        size = -(-len(ids) // parts)
        shares = [ids[k * size : (k + 1) * size] for k in range(parts)]
        ctx = mp.get_context("spawn")
        if not latency_s > 0.0:
            raise ValueError(f"a split fleet needs a network latency > 0, not {latency_s}")
        self.now = start_unix_s
        self.latency_s = latency_s
        self.workers: list[tuple[Any, Connection]] = []
        self.cpu_s: list[float] = []  # each part's CPU seconds (after close)
        self.steps = 0  # windows run
        self.skip_idle = skip_idle
        self.exchanged = 0  # messages handed from one part to the others
        for k, share in enumerate(shares[1:], start=1):
            if not share:
                continue
            mine, theirs = ctx.Pipe()
            proc = ctx.Process(
                target=_part_main,
                args=(
                    theirs,
                    share,
                    {v: profiles[v] for v in share},
                    homes[k * size : k * size + len(share)],
                    start_unix_s,
                    latency_s,
                    ids if liveliness else None,
                ),
                daemon=True,
            )
            proc.start()
            self.workers.append((proc, mine))
        # the first part runs here, beside the others: one process per core, no idle
        # coordinator
        self.local = FastFleet.build(
            shares[0],
            {v: profiles[v] for v in shares[0]},
            homes=homes[: len(shares[0])],
            start_unix_s=start_unix_s,
        )
        self.local.export, self.local.latency_s = [], latency_s
        if liveliness:
            self.local.hold_tokens(ids)
        self._cpu0 = time.process_time()
        # the earliest time anything is due in any part (its timers, what it was handed)
        self._next = min(
            [self.local.next_deadline()] + [conn.recv()[1] for _p, conn in self.workers]
        )
        self._incoming: list[Outgoing] = [[] for _ in range(1 + len(self.workers))]

    def run_for(self, seconds: float) -> None:
        """`seconds` of the swarm, window by window. A window starts when something is
        first due in any part (`skip_idle`; otherwise right after the last one, the
        reference): until then no part does anything, and nothing it publishes in the
        window is heard before the window's end, so windows with nothing in them are
        not run and every run is the same as with back-to-back windows."""
        end = self.now + seconds
        while self.now < end:
            start = min(max(self._next, self.now), end) if self.skip_idle else self.now
            window_end = min(start + self.latency_s, end)
            for (_proc, conn), incoming in zip(self.workers, self._incoming[1:], strict=True):
                conn.send(("window", window_end, [(at, raw, cls) for at, _s, raw, cls in incoming]))
            for at, _sender, raw, cls in self._incoming[0]:
                self.local.receive(raw, cls, at)
            self.local.run_before(window_end)
            mine, self.local.export = self.local.export, []
            answers = [(mine, self.local.next_deadline())] + [
                conn.recv() for _p, conn in self.workers
            ]
            self.steps += 1
            self._incoming = [[] for _ in answers]
            nxt = min(due for _out, due in answers)
            for k, (out, _due) in enumerate(answers):
                if not out:
                    continue
                for j in range(len(answers)):
                    if j != k:
                        self._incoming[j] += out
                self.exchanged += len(out)
                nxt = min(nxt, min(at for at, _s, _raw, _cls in out))
            self._next = nxt
            self.now = window_end

    def live_peers(self) -> dict[int, list[int]]:
        """Every vehicle's node: the peers it lists as live."""
        out = _live_peers(self.local)
        for _proc, conn in self.workers:
            conn.send(("peers", self.now, []))
            out.update(conn.recv())
        return out

    def published(self) -> list[tuple[float, int, Any]]:
        """Every swarm message published so far, in every part (time, sender, message),
        part by part."""
        out = list(self.local.published)
        for _proc, conn in self.workers:
            conn.send(("published", self.now, []))
            out += conn.recv()
        return out

    def heard_messages(self) -> int:
        """Swarm messages handed to the nodes so far, one per hearer, in every part."""
        total = self.local.heard_messages
        for _proc, conn in self.workers:
            conn.send(("heard", self.now, []))
            total += conn.recv()
        return int(total)

    def close(self) -> None:
        for _proc, conn in self.workers:
            conn.send(("stop", 0.0, []))
        self.cpu_s = [time.process_time() - self._cpu0] + [
            conn.recv()[1] for _proc, conn in self.workers
        ]
        for proc, _conn in self.workers:
            proc.join(10)

    def __enter__(self) -> ParallelFleet:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
