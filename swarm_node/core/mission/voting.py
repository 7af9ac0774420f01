"""The paper's vote (section 2.3.6, Figure 18) with no leader: a pure `Ballot` core.

One `Ballot` per vehicle per QUANTITY mission. The electorate is the fleet's frozen
roster (its `members_hash` travels in every vote). Each voter's own score is computed
once, by itself, from what it measures itself (`scoring.PaperScore`); a `Vote` carries
the voter's whole *table*: its own score and every other member's as received. Tables
merge as a grow-only map (a score seen twice keeps the lower radio value: merging is
commutative and idempotent), so every vehicle that hears the others ends with the same
table, and the same table gives the same winners everywhere:

    winners = the `quantity` best of the table (score at radio resolution 1e-4,
              ties by the lower vehicle id)

Commit rule (docs/voting.md): a vehicle commits when every live member of the
electorate has a score in its table and every live member's vote, received *after* the
vehicle's table or live set last changed, carries exactly its table. A voter reported
lost (`VoterLost`, from the roster's liveliness) is no longer waited for; its score
stays in the table if anyone received it (so every vehicle decides on the same
candidates). Votes are re-sent every `retry_s` (sooner, coalesced, when the table
grows) until `linger_s` after the commit; with no commit by `deadline_s` the ballot
fails (the paper's "an alert is displayed and the task is removed").

Inputs:

| input | effect |
|---|---|
| `Vote` of this mission, roster and electorate | merged; a reply scheduled if it differs |
| `Vote` of another mission | counted `other_mission`, ignored |
| `Vote` with another members_hash | counted `wrong_roster`, ignored |
| `Vote` from outside the electorate | counted `not_member`, ignored |
| score of a vehicle outside the electorate | counted `foreign_score`, entry ignored |
| `VoterLost` | no longer waited for; confirmations start again |

Outputs: `SendVote(vote)`, then `Decided(outcome)` or `Failed(...)` once.
"""

from __future__ import annotations

import hashlib
import math
from collections import Counter
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field

from swarm_proto import Vote, VoteScore

SCORE_RESOLUTION = 10_000  # VoteScore.score's radio resolution, 1e-4


def members_hash(mission_id: int, members: Iterable[int]) -> int:
    """16 bits of BLAKE2s of the mission id (uint32) and the sorted members, never 0: the same
    function as the fleet roster's (swarm/roster.py), so a ballot can be
    given the roster's hash or compute it."""
    data = (mission_id & 0xFFFF_FFFF).to_bytes(4, "little") + b"".join(
        m.to_bytes(2, "little") for m in sorted(set(members))
    )
    h = int.from_bytes(hashlib.blake2s(data, digest_size=2, person=b"bdroster").digest(), "little")
    return h or 1


def score_key(score: float) -> int:
    """A score at radio resolution, as an integer: what the ranking compares, so a
    score relayed over the radio (quantized) ranks as the original."""
    return round(min(1.0, max(0.0, score)) * SCORE_RESOLUTION)


def rank(table: Mapping[int, int], quantity: int) -> tuple[int, ...]:
    """The `quantity` best of a table {vehicle id: score key}: highest score first,
    ties by the lower vehicle id."""
    order = sorted(table.items(), key=lambda kv: (-kv[1], kv[0]))
    return tuple(vid for vid, _ in order[:quantity])


@dataclass(frozen=True, slots=True)
class VoterLost:
    """The roster (liveliness) says this electorate member is gone."""

    vehicle_id: int


@dataclass(frozen=True, slots=True)
class SendVote:
    vote: Vote


@dataclass(frozen=True, slots=True)
class BallotOutcome:
    """What the vote decided: the same on every vehicle that commits."""

    mission_id: int
    winners: tuple[int, ...]  # leave the fleet for the new mission, best first
    stayers: tuple[int, ...]  # scored, not chosen: replan the current mission
    absent: tuple[int, ...]  # electorate members with no score (never voted)
    scores: tuple[VoteScore, ...]  # the table, by vehicle id

    def goes(self, vehicle_id: int) -> bool:
        return vehicle_id in self.winners


@dataclass(frozen=True, slots=True)
class Decided:
    outcome: BallotOutcome


@dataclass(frozen=True, slots=True)
class Failed:
    """No commit by the deadline: the mission is dropped with an alert (paper Fig. 11)."""

    mission_id: int
    waiting_for: tuple[int, ...]  # live members that never confirmed our table
    reason: str


BallotOutput = SendVote | Decided | Failed
BallotInput = Vote | VoterLost


@dataclass(frozen=True, slots=True)
class BallotConfig:
    retry_s: float = 0.5  # re-send period
    reply_s: float = 0.05  # a changed table or a differing vote is answered this soon
    deadline_s: float = 20.0  # no commit by then: Failed
    linger_s: float = 3.0  # keep re-sending this long after the commit (for the others)

    def __post_init__(self) -> None:
        vals = (self.retry_s, self.reply_s, self.deadline_s, self.linger_s)
        if not all(math.isfinite(v) and v > 0 for v in vals) or self.reply_s > self.retry_s:
            raise ValueError(f"bad ballot timing {self}")


@dataclass
class Ballot:
    """One vehicle's ballot for one QUANTITY mission. Construct it when the mission
    arrives (`started_s`), then feed it `Vote`s and `VoterLost`s, and call `on_timer` at
    `next_deadline()` (the first call sends the first vote)."""

    mission_id: int
    own_id: int
    electorate: frozenset[int]
    quantity: int
    own_score: float
    started_s: float
    config: BallotConfig = BallotConfig()
    roster_hash: int = 0  # 0: computed from the mission id and the electorate
    table: dict[int, int] = field(default_factory=dict)  # vehicle id -> score key
    lost: set[int] = field(default_factory=set)  # members the roster already knows are gone
    confirmed: set[int] = field(default_factory=set)  # their table == ours, since it changed
    committed_peers: set[int] = field(default_factory=set)  # seen with committed=True
    outcome: BallotOutcome | None = None
    failed: Failed | None = None
    decided_s: float | None = None
    sent: int = 0
    counts: Counter[str] = field(default_factory=Counter)
    _next_send: float | None = None

    def __post_init__(self) -> None:
        self.electorate = frozenset(self.electorate)
        if self.own_id not in self.electorate:
            raise ValueError(f"vehicle {self.own_id} is not in the electorate")
        if self.quantity < 1:
            raise ValueError("a ballot needs quantity >= 1")
        if not math.isfinite(self.own_score):
            raise ValueError(f"own score must be finite, got {self.own_score}")
        self.lost = set(self.lost) & (self.electorate - {self.own_id})
        if not self.roster_hash:
            self.roster_hash = members_hash(self.mission_id, self.electorate)
        self.table[self.own_id] = score_key(self.own_score)
        self._next_send = self.started_s

    # ------------------------------------------------------------------ core API
    @property
    def live(self) -> frozenset[int]:
        return self.electorate - self.lost

    @property
    def done(self) -> bool:
        """Decided (or failed) and nothing left to send."""
        return (self.outcome is not None or self.failed is not None) and self._next_send is None

    def next_deadline(self) -> float | None:
        if self.failed is not None:
            return None
        if self.outcome is None:
            end = self.started_s + self.config.deadline_s
            return end if self._next_send is None else min(self._next_send, end)
        return self._next_send

    def handle(self, msg: BallotInput, now: float) -> list[BallotOutput]:
        if self.failed is not None:
            return []
        if isinstance(msg, VoterLost):
            if msg.vehicle_id in self.live and msg.vehicle_id != self.own_id:
                self.lost.add(msg.vehicle_id)
                self.confirmed.clear()  # only votes sent after this count (docs/voting.md)
            return self._maybe_commit(now)
        return self._on_vote(msg, now)

    def on_timer(self, now: float) -> list[BallotOutput]:
        if self.failed is not None:
            return []
        if self.outcome is None and now >= self.started_s + self.config.deadline_s:
            waiting = tuple(sorted(self.live - self.confirmed - {self.own_id}))
            missing = sorted(self.live - self.table.keys())
            self.failed = Failed(
                self.mission_id,
                waiting,
                f"no agreement in {self.config.deadline_s:g} s"
                + (f"; no score from {missing}" if missing else ""),
            )
            self._next_send = None
            return [self.failed]
        out: list[BallotOutput] = []
        if self._next_send is not None and now >= self._next_send:
            out.append(SendVote(self.vote()))
            self.sent += 1
            self._next_send = None if self._quiet(now) else now + self.config.retry_s
        out.extend(self._maybe_commit(now))  # an electorate of one decides alone
        return out

    def vote(self) -> Vote:
        """Our vote now: the whole table."""
        return Vote(
            self.mission_id,
            self.own_id,
            tuple(VoteScore(v, k / SCORE_RESOLUTION) for v, k in sorted(self.table.items())),
            round=min(self.sent, 255),
            members_hash=self.roster_hash,
            committed=self.outcome is not None,
        )

    # ------------------------------------------------------------------ internals
    def _quiet(self, now: float) -> bool:
        """After the commit, stop re-sending once every live member has committed too,
        or `linger_s` after ours (a late vote still gets one reply)."""
        if self.decided_s is None:
            return False
        everyone = self.live - {self.own_id} <= self.committed_peers
        return everyone or now >= self.decided_s + self.config.linger_s

    def _on_vote(self, v: Vote, now: float) -> list[BallotOutput]:
        if v.mission_id != self.mission_id:
            self.counts["other_mission"] += 1
            return []
        if v.members_hash != self.roster_hash:
            self.counts["wrong_roster"] += 1
            return []
        if v.voter_id not in self.electorate:
            self.counts["not_member"] += 1
            return []
        if v.voter_id == self.own_id:
            self.counts["own_echo"] += 1
            return []
        theirs: dict[int, int] = {}
        for s in v.scores:
            if s.vehicle_id not in self.electorate or not math.isfinite(s.score):
                self.counts["foreign_score"] += 1
                continue
            k = score_key(s.score)
            theirs[s.vehicle_id] = min(k, theirs.get(s.vehicle_id, k))
        if v.committed:
            self.committed_peers.add(v.voter_id)
        if self.outcome is not None:  # our table is final
            if theirs != self.table:
                self.counts["differs_after_commit"] += 1
            if theirs != self.table or not v.committed:
                self._reply(now)  # they may need a vote of ours sent after their change
            return []
        changed = False
        for vid, k in theirs.items():
            if vid not in self.table or k < self.table[vid]:
                if vid in self.table:
                    self.counts["score_conflict"] += 1
                self.table[vid] = k
                changed = True
        if changed:
            self.confirmed.clear()
            self._reply(now)  # tell the others what we learnt
        if theirs == self.table:
            self.confirmed.add(v.voter_id)
        else:
            self._reply(now)  # they lack something we have
        return self._maybe_commit(now)

    def _reply(self, now: float) -> None:
        at = now + self.config.reply_s
        if self._next_send is None or at < self._next_send:
            self._next_send = at

    def _maybe_commit(self, now: float) -> list[BallotOutput]:
        if self.outcome is not None:
            return []
        live = self.live
        if not live <= self.table.keys():
            return []
        if not live - {self.own_id} <= self.confirmed:
            return []
        winners = rank(self.table, self.quantity)
        scored = sorted(self.table)
        self.outcome = BallotOutcome(
            self.mission_id,
            winners,
            tuple(v for v in scored if v not in winners),
            tuple(sorted(self.electorate - self.table.keys())),
            tuple(VoteScore(v, self.table[v] / SCORE_RESOLUTION) for v in scored),
        )
        self.decided_s = now
        self._reply(now)  # say so at once: the others stop re-sending when all have
        return [Decided(self.outcome)]
