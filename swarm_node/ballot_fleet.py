"""A harness for voting cores only: N `Ballot`s on an in-memory lossy broadcast bus.

Like `swarm_node.testing.Fleet` (seeded loss and delay per link, time jumping from
deadline to deadline), for ballots alone: voters may start late (the mission reached
them late), die mid-vote (the others get `VoterLost` a lease later, each at its own
moment), and votes may go through the radio encoding (quantized scores) or the LAN's
MessagePack. Used by tests/swarm_node/mission/test_voting.py and bench/voting.py.
"""

from __future__ import annotations

import heapq
import itertools
import random
from collections.abc import Mapping
from dataclasses import dataclass, field

import msgspec

from swarm_node.core.mission.voting import (
    Ballot,
    BallotConfig,
    BallotInput,
    BallotOutcome,
    Failed,
    SendVote,
    VoterLost,
)
from swarm_proto import Vote
from swarm_proto import radio as radio_codec

_LAN = msgspec.msgpack.Encoder()
_LAN_VOTE = msgspec.msgpack.Decoder(Vote)


@dataclass
class TrialResult:
    outcomes: dict[int, BallotOutcome]  # by vehicle, the live ones that decided
    failures: dict[int, Failed]
    decided_s: dict[int, float]
    dead: frozenset[int]
    messages: int  # votes sent
    deliveries: int  # votes delivered
    end_s: float  # when the last live ballot went quiet

    @property
    def agree_s(self) -> float | None:
        """When the last live vehicle decided (None if one did not)."""
        live = set(self.outcomes) | set(self.failures)
        if self.failures or not live:
            return None
        return max(self.decided_s.values())

    def problems(self, electorate: frozenset[int]) -> list[str]:
        """What breaks the vote's promise: different winners, a vehicle both going and
        staying, a live vehicle neither, a live vehicle undecided."""
        out: list[str] = []
        live = electorate - self.dead
        for vid in sorted(live):
            if vid not in self.outcomes:
                out.append(f"vehicle {vid} did not decide ({self.failures.get(vid)})")
        go: set[int] = set()
        stay: set[int] = set()
        for o in self.outcomes.values():
            go |= set(o.winners)
            stay |= set(o.stayers)
        for vid in sorted(go & stay):
            out.append(f"vehicle {vid} assigned twice (goes on one vehicle, stays on another)")
        for vid in sorted(live - go - stay):
            out.append(f"vehicle {vid} left out (neither goes nor stays)")
        if len({(o.winners, o.stayers) for o in self.outcomes.values()}) > 1:
            out.append(
                "vehicles disagree: " + str({v: o.winners for v, o in self.outcomes.items()})
            )
        return out


@dataclass
class BallotFleet:
    scores: Mapping[int, float]  # each voter's own score
    quantity: int
    seed: int = 0
    loss: float = 0.0
    delay_s: tuple[float, float] = (0.001, 0.010)
    start_s: Mapping[int, float] = field(default_factory=dict)  # late joiners
    death_s: Mapping[int, float] = field(default_factory=dict)  # voters dying mid-vote
    lease_s: float = 1.5  # liveliness: a dead voter is reported lost after this...
    lost_jitter_s: float = 0.5  # ... plus up to this, independently on each vehicle
    config: BallotConfig = field(default_factory=BallotConfig)
    encoding: str = "lan"  # "lan" (MessagePack maps) or "radio" (positional, quantized)
    cut_s: float | None = None  # from then on, `side` and the rest do not hear each other
    side: frozenset[int] = frozenset()
    mission_id: int = 7

    def __post_init__(self) -> None:
        self.rng = random.Random(self.seed)
        self.electorate = frozenset(self.scores)
        self.ballots: dict[int, Ballot] = {}
        self._queue: list[tuple[float, int, int, BallotInput | None]] = []
        self._seq = itertools.count()
        self.messages = 0
        self.deliveries = 0

    def _push(self, t: float, vid: int, ev: BallotInput | None) -> None:
        heapq.heappush(self._queue, (t, next(self._seq), vid, ev))

    def _alive(self, vid: int, t: float) -> bool:
        return t < self.death_s.get(vid, float("inf"))

    def _cut(self, a: int, b: int, t: float) -> bool:
        return self.cut_s is not None and t >= self.cut_s and (a in self.side) != (b in self.side)

    def _wire(self, v: Vote) -> Vote:
        if self.encoding == "radio":
            out = radio_codec.decode(radio_codec.encode(v), now_unix_s=0.0)
            assert isinstance(out, Vote)
            return out
        return _LAN_VOTE.decode(_LAN.encode(v))

    def _broadcast(self, src: int, v: Vote, now: float) -> None:
        self.messages += 1
        wire = self._wire(v)
        for dst in sorted(self.electorate - {src}):
            if self.rng.random() < self.loss or self._cut(src, dst, now):
                continue
            self._push(now + self.rng.uniform(*self.delay_s), dst, wire)

    def _run_outputs(self, vid: int, outs: list, now: float) -> None:
        for o in outs:
            if isinstance(o, SendVote):
                self._broadcast(vid, o.vote, now)

    def run(self, until_s: float = 60.0) -> TrialResult:
        for vid in sorted(self.electorate):
            self._push(self.start_s.get(vid, 0.0), vid, None)  # None: the mission arrives
        for gone, t in self.death_s.items():
            for vid in sorted(self.electorate - {gone}):
                at = t + self.lease_s + self.rng.uniform(0.0, self.lost_jitter_s)
                self._push(at, vid, VoterLost(gone))
        if self.cut_s is not None:  # each side's liveliness loses the other side
            for vid in sorted(self.electorate):
                for other in sorted(self.electorate):
                    if self._cut(vid, other, self.cut_s):
                        at = self.cut_s + self.lease_s + self.rng.uniform(0.0, self.lost_jitter_s)
                        self._push(at, vid, VoterLost(other))
        decided: dict[int, float] = {}
        known_lost: dict[int, set[int]] = {v: set() for v in self.electorate}
        now = last = 0.0
        while True:
            timers = [
                (d, vid)
                for vid, b in self.ballots.items()
                if self._alive(vid, now) and (d := b.next_deadline()) is not None
            ]
            t_timer = min(timers)[0] if timers else float("inf")
            t_msg = self._queue[0][0] if self._queue else float("inf")
            now = min(t_timer, t_msg)
            if now == float("inf") or now > until_s:
                break
            last = now
            if t_msg <= t_timer:
                _, _, vid, ev = heapq.heappop(self._queue)
                if not self._alive(vid, now):
                    continue
                if ev is None:
                    self.ballots[vid] = Ballot(
                        self.mission_id,
                        vid,
                        self.electorate,
                        self.quantity,
                        self.scores[vid],
                        now,
                        self.config,
                        lost=set(known_lost[vid]),
                    )
                    continue
                if isinstance(ev, VoterLost):
                    known_lost[vid].add(ev.vehicle_id)  # the node's liveliness knows it
                b = self.ballots.get(vid)
                if b is None:
                    continue  # the mission has not reached it yet: the vote is lost to it
                if isinstance(ev, Vote):
                    self.deliveries += 1
                outs = b.handle(ev, now)
            else:
                vid = min(timers)[1]
                b = self.ballots[vid]
                outs = b.on_timer(now)
            if b.outcome is not None and vid not in decided:
                decided[vid] = now
            self._run_outputs(vid, outs, now)
        dead = frozenset(v for v in self.electorate if not self._alive(v, last))
        live = {v: b for v, b in self.ballots.items() if v not in dead}
        return TrialResult(
            outcomes={v: b.outcome for v, b in live.items() if b.outcome is not None},
            failures={v: b.failed for v, b in live.items() if b.failed is not None},
            decided_s={v: t for v, t in decided.items() if v not in dead},
            dead=dead,
            messages=self.messages,
            deliveries=self.deliveries,
            end_s=last,
        )


def lossy_trial(seed: int, encoding: str = "lan") -> tuple[BallotFleet, TrialResult]:
    """One of the issue's lossy trials: 20 % loss, 3-10 voters with coarse scores (so
    ties happen), a random quantity, in 80 % of the trials a voter dying in the first
    second, each voter starting up to 2 s late with probability 0.3 (random join order)."""
    r = random.Random(seed)
    n = r.randint(3, 10)
    ids = r.sample(range(1, 60), n)
    scores = {v: round(r.random(), 2) for v in ids}
    death = {r.choice(ids): r.uniform(0.0, 1.0)} if r.random() < 0.8 else {}
    start = {v: r.uniform(0.0, 2.0) if r.random() < 0.3 else 0.0 for v in ids}
    f = BallotFleet(
        scores,
        r.randint(1, n - 1),
        seed=seed,
        loss=0.2,
        start_s=start,
        death_s=death,
        encoding=encoding,
    )
    return f, f.run()
