"""A replan is flown only once the survivors agree on it (issue 12: "a member lost ...
is an event"; a roster hash mismatch is one too).

Every survivor replans alone from the inputs they all have (the last plan they all
flew, every member's published progress, the survivors): the same inputs, the same
plan. What can differ is who survives: a loss noticed by one node a moment before
another, two losses close together, a link that fails one way. So the new share is
held (the vehicle flies on with the share it has; the sortie shows REPLAN) until every
survivor it was made for publishes the same roster hash (`Roster.agreement`).

- AGREED: every survivor publishes our hash: fly the new share.
- MISMATCH: a survivor publishes another hash (not ours, not the last agreed one): it
  planned with other survivors. An alert (ROSTER_MISMATCH), and the node
  re-synchronises: the replan is dropped, the roster rolled back to the last agreed
  one, and the replan made again once the fleet has synchronised again (by then the
  nodes' views of who survives have usually converged). Each foreign hash is reacted
  to once; at most MAX_RESYNC times per replan.
- GIVE_UP: no agreement within AGREE_TIMEOUT_S of the loss (waiting for the survivors
  to enter the replan, or for their hashes), or a mismatch after MAX_RESYNC: the
  replan is abandoned, with an alert; every node flies on with the share it has, so
  nobody flies another's lanes (the lost member's rest stays unflown) and nobody
  leaves the mission over it (the state machine's plan timeout would send it home).

Pure: no I/O, no clock.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import Enum

from ..swarm.roster import Roster

AGREE_TIMEOUT_S = 15.0  # loss -> every survivor flying the replan (measured: 2.2 s)
MAX_RESYNC = 3


class Verdict(Enum):
    WAIT = "wait"
    AGREED = "agreed"
    MISMATCH = "mismatch"
    GIVE_UP = "give up"


@dataclass
class ReplanAgreement:
    started: float | None = None  # the replan began (the loss was noticed)
    resyncs: int = 0
    seen: set[int] = field(default_factory=set)  # foreign hashes reacted to
    others: tuple[tuple[int, int], ...] = ()  # the last verdict's (member, hash) apart
    agreed_in_s: list[float] = field(default_factory=list)  # loss -> agreement (figures)

    def begin(self, now: float) -> None:
        """A replan begins (again, after a re-synchronisation: the time runs on)."""
        if self.started is None:
            self.started = now

    def end(self) -> None:
        self.started, self.resyncs, self.seen, self.others = None, 0, set(), ()

    def verdict(self, roster: Roster, now: float, *, held: bool) -> Verdict:
        """`held`: our replanned share is made and waits for the others."""
        if self.started is None:
            return Verdict.WAIT
        if held:
            agreed, others = roster.agreement()
            new = [(v, h) for v, h in others if h not in self.seen]
            if agreed:
                self.agreed_in_s.append(now - self.started)
                del self.agreed_in_s[:-20]
                self.end()
                return Verdict.AGREED
            if new:
                self.seen.update(h for _v, h in new)
                self.others = tuple(new)
                if self.resyncs >= MAX_RESYNC:
                    return Verdict.GIVE_UP
                self.resyncs += 1
                return Verdict.MISMATCH
        if now - self.started >= AGREE_TIMEOUT_S:
            return Verdict.GIVE_UP
        return Verdict.WAIT
