"""A fleet harness for pure node cores (like h11's ConnectionPair, for N nodes).

`Fleet` joins NodeCores with an in-memory broadcast bus, lets a seeded random source
drop or delay messages per link, answers autopilot requests through a pluggable
function, and advances time by jumping to the earliest deadline: a long scenario runs
in milliseconds and every run with the same seed is the same. With `over_air` every
node hears the others' messages as the radio carries them (`swarm_proto.radio.quantized`:
floats at the radio's resolution), as in `swarm-sim demo --radio`.
"""

from __future__ import annotations

import heapq
import itertools
import random
from collections.abc import Callable
from dataclasses import dataclass, field

import msgspec

from swarm_node.core.autopilot.requests import ApRequest, ApResult
from swarm_node.core.node import (
    AutopilotResult,
    AutopilotUpdate,
    Input,
    NodeCore,
    Note,
    PlanDone,
    PlanJob,
    Publish,
    Received,
    Submit,
)
from swarm_node.plan_memo import PlanMemo
from swarm_proto import EncodeError, radio

AutopilotFn = Callable[[int, ApRequest], ApResult | None]  # (node id, request) -> answer


def always_ok(node_id: int, req: ApRequest) -> ApResult:
    return ApResult(req.request_id, True)


@dataclass
class Fleet:
    nodes: dict[int, NodeCore]
    now: float = 0.0
    seed: int = 0
    loss: float = 0.0  # probability a message is lost on a link
    delay_s: tuple[float, float] = (0.0, 0.0)  # uniform delay range per link
    autopilot: AutopilotFn = always_ok
    plan_delay_s: float = 0.0  # how long a plan job takes (it runs inline, in no time)
    plan_delays: dict[int, float] = field(default_factory=dict)  # per node, over plan_delay_s
    plans: PlanMemo = field(default_factory=PlanMemo)  # each distinct plan job planned once
    #: (sender, receiver, message) -> lost: a link that fails one way, or for one message
    drop: Callable[[int, int, msgspec.Struct], bool] | None = None
    published: list[tuple[float, int, msgspec.Struct]] = field(default_factory=list)
    submitted: list[tuple[float, int, ApRequest]] = field(default_factory=list)
    notes: list[tuple[float, int, str]] = field(default_factory=list)
    #: the others hear what a node publishes at the radio's resolution (every node
    #: behind its own radio gateway)
    over_air: bool = False

    def __post_init__(self) -> None:
        self.rng = random.Random(self.seed)
        self._scans: dict[tuple[type, int | None], tuple[int, object, list]] = {}
        self._queue: list[tuple[float, int, int, Input]] = []
        self._seq = itertools.count()

    def deliver(self, node_id: int, event: Input, at: float | None = None) -> None:
        t = self.now if at is None else at
        heapq.heappush(self._queue, (t, next(self._seq), node_id, event))

    def _heard(self, msg: msgspec.Struct) -> msgspec.Struct:
        """`msg` as the others hear it (over the air: at radio resolution; a message the
        radio has no encoding for as it is)."""
        if not self.over_air:
            return msg
        try:
            return radio.quantized(msg, now_unix_s=self.now)
        except EncodeError:
            return msg

    def set_autopilot(self, node_id: int, state: object) -> None:
        assert isinstance(state, msgspec.Struct)
        self.deliver(node_id, AutopilotUpdate(state))  # type: ignore[arg-type]

    def _execute(self, node_id: int, outputs: list) -> None:
        for o in outputs:
            if isinstance(o, Publish):
                self.published.append((self.now, node_id, o.msg))
                heard = self._heard(o.msg)
                for other in self.nodes:
                    if other == node_id or self.rng.random() < self.loss:
                        continue
                    if self.drop is not None and self.drop(node_id, other, o.msg):
                        continue
                    delay = self.rng.uniform(*self.delay_s)
                    self.deliver(other, Received(heard), self.now + delay)
            elif isinstance(o, Submit):
                self.submitted.append((self.now, node_id, o.request))
                answer = self.autopilot(node_id, o.request)
                if answer is not None:
                    self.deliver(node_id, AutopilotResult(answer))
            elif isinstance(o, Note):
                self.notes.append((self.now, node_id, o.text))
            elif isinstance(o, PlanJob):
                done = PlanDone(self.plans.run(o.request))
                delay = self.plan_delays.get(node_id, self.plan_delay_s)
                self.deliver(node_id, done, self.now + delay)

    def run_until(self, t_end: float) -> None:
        """Process inputs and timers in time order up to t_end."""
        while True:
            next_timer = min(n.next_deadline() for n in self.nodes.values())
            next_input = self._queue[0][0] if self._queue else float("inf")
            t = min(next_timer, next_input)
            if t > t_end:
                self.now = t_end
                return
            self.now = max(self.now, t)
            if next_input <= next_timer:
                _, _, nid, event = heapq.heappop(self._queue)
                if nid in self.nodes:  # a node removed from the fleet hears nothing
                    self._execute(nid, self.nodes[nid].handle(event, self.now))
            else:
                for nid, node in list(self.nodes.items()):
                    if node.next_deadline() <= self.now:
                        self._execute(nid, node.on_timer(self.now))
                        if node.next_deadline() <= self.now:
                            raise RuntimeError(
                                f"node {nid} did not move its deadline past {self.now}"
                            )

    def messages(self, cls: type, sender: int | None = None) -> list:
        """Every published `cls` (from `sender`), in order. Scans only what was published
        since the last call with the same arguments (a predicate calling this at every
        step of a long flight stays linear), unless `published` was changed under it."""
        return published_matching(self.published, self._scans, cls, sender)


def published_matching(
    published: list[tuple[float, int, msgspec.Struct]],
    scans: dict[tuple[type, int | None], tuple[int, object, list]],
    cls: type,
    sender: int | None,
) -> list:
    """Every `cls` in `published` (from `sender`), scanning only what was appended since
    the last call with the same `scans` key (FastFleet and the fleet harness share it)."""
    start, last, found = scans.get((cls, sender), (0, None, []))
    if start > len(published) or (start and published[start - 1] is not last):
        start, found = 0, []  # cleared or replaced: scan afresh
    found = found + [
        m for _, s, m in published[start:] if isinstance(m, cls) and (sender is None or s == sender)
    ]
    if published:
        scans[(cls, sender)] = (len(published), published[-1], found)
    return list(found)
