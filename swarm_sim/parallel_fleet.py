"""A FastFleet split over worker processes, one per core: each worker runs the vehicles
of its share (simulated autopilots, their links and node cores, as FastFleet does) and
the parts keep one clock.

The swarm's messages are broadcast: every node hears every other, so a swarm's cost
grows with the square of its size and a 100-vehicle swarm is more than one Python
process can run at ten times real time (docs/benchmarks.md, `sim`). Split in two, each
part delivers half of the messages.

Time is kept in lock step: the first part runs in the calling process and coordinates;
every part runs everything due at the earliest deadline of all (`FastFleet.step_at`)
and answers with the messages it published meanwhile (LAN bytes) and its own next
deadline. Those messages are handed
to the other parts at the same time, and the step repeats at that time until no part
has anything left there. Every run with the same split is the same; messages between
parts are taken after the ones published inside a part at the same time (in one
process they would interleave in publishing order).

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

Outgoing = list[tuple[int, bytes, type]]


def _part_main(
    conn: Connection,
    members: Sequence[int],
    profiles: Mapping[int, VehicleProfile],
    homes: Sequence[Home],
    start_unix_s: float,
) -> None:
    from .fast_fleet import FastFleet

    fleet = FastFleet.build(members, profiles, homes=homes, start_unix_s=start_unix_s)
    fleet.export = []
    conn.send(("ready", fleet._deadline()))
    cpu0 = time.process_time()
    while True:
        cmd, t, incoming = conn.recv()
        if cmd == "stop":
            conn.send(("stopped", time.process_time() - cpu0))
            return
        if cmd == "peers":
            conn.send(_live_peers(fleet))
            continue
        for raw, cls in incoming:
            fleet.receive(raw, cls, t)
        nxt = fleet.step_at(t)
        out, fleet.export = fleet.export, []
        conn.send((out, nxt))


def _live_peers(fleet: Any) -> dict[int, list[int]]:
    return {vid: v.node.members.live_ids() for vid, v in fleet.vehicles.items()}


class ParallelFleet:
    """`members` (database ids, profiles as for FastFleet.build) split into `parts`
    worker processes (contiguous shares of the list), homes as FastFleet.build gives
    the whole list."""

    def __init__(
        self,
        members: Iterable[int],
        profiles: Mapping[int, VehicleProfile],
        *,
        parts: int = 2,
        home: Home = SITL_HOME,
        spacing_m: float = 40.0,
        start_unix_s: float = 1.8e9,
    ) -> None:
        from .fast_fleet import FastFleet

        ids = list(members)
        homes = spread_homes(home, len(ids), spacing_m)
        size = -(-len(ids) // parts)
        shares = [ids[k * size : (k + 1) * size] for k in range(parts)]
        ctx = mp.get_context("spawn")
        self.now = start_unix_s
        self.workers: list[tuple[Any, Connection]] = []
        self.cpu_s: list[float] = []  # each part's CPU seconds (after close)
        self.steps = 0
        self.exchanged = 0  # messages handed from one part to the others
        for k, share in enumerate(shares[1:], start=1):
            if not share:
                continue
            mine, theirs = ctx.Pipe()
            proc = ctx.Process(
                target=_part_main,
                args=(theirs, share, {v: profiles[v] for v in share},
                      homes[k * size : k * size + len(share)], start_unix_s),
                daemon=True,
            )  # fmt: skip
            proc.start()
            self.workers.append((proc, mine))
        # the first part runs here, beside the others: one process per core, no idle
        # coordinator
        self.local = FastFleet.build(
            shares[0], {v: profiles[v] for v in shares[0]}, homes=homes[: len(shares[0])],
            start_unix_s=start_unix_s,
        )  # fmt: skip
        self.local.export = []
        self._cpu0 = time.process_time()
        self._next = [self.local._deadline()] + [conn.recv()[1] for _p, conn in self.workers]
        self._incoming: list[list[tuple[bytes, type]]] = [[] for _ in self._next]

    def run_for(self, seconds: float) -> None:
        end = self.now + seconds
        while True:
            t = self.now if any(self._incoming) else min(self._next)
            if t > end:
                break
            self.now = max(self.now, t)
            for (_proc, conn), incoming in zip(self.workers, self._incoming[1:], strict=True):
                conn.send(("step", self.now, incoming))
            for raw, cls in self._incoming[0]:
                self.local.receive(raw, cls, self.now)
            nxt = self.local.step_at(self.now)
            mine, self.local.export = self.local.export, []
            answers = [(mine, nxt)] + [conn.recv() for _proc, conn in self.workers]
            self.steps += 1
            self._incoming = [[] for _ in answers]
            for k, (out, nxt) in enumerate(answers):
                self._next[k] = nxt
                if not out:
                    continue
                sent = [(raw, cls) for _sender, raw, cls in out]
                for j in range(len(answers)):
                    if j != k:
                        self._incoming[j] += sent
                self.exchanged += len(out)
        self.now = end

    def live_peers(self) -> dict[int, list[int]]:
        """Every vehicle's node: the peers it lists as live."""
        out = _live_peers(self.local)
        for _proc, conn in self.workers:
            conn.send(("peers", self.now, []))
            out.update(conn.recv())
        return out

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
