"""A replan is flown only once the survivors agree on it ("a member lost ...
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
- GIVE_UP: no agreement within AGREE_TIMEOUT_S, or a mismatch after MAX_RESYNC: the
  replan is abandoned, with an alert; every node flies on with the share it has, so
  nobody flies another's lanes (the lost member's rest stays unflown) and nobody
  leaves the mission over it (the state machine's plan timeout would send it home).

What the window measures is waiting, not planning. Planning is the host's work (wall
time: a replan took 1-3 s on a loaded 2-core machine, 5-15 s of flight at the demo's
speed-up); it is bounded by the state machine's plan timeout, on every node. So the
window runs from the loss while this node waits for the survivors to enter the replan,
stops while its own plan job runs, and runs again from when its replan is made (held).
(A survivor publishes the new roster's hash as it starts planning, so the others can
agree while it plans.) Counting planning in the window, a node whose replan took more
than 15 s of simulated time (5 s of wall time at the demo's 3x on a loaded host) gave it
up and flew on with its old share while the others flew the replan: the rosters
diverged, the demo's survey was 98.4 % covered.

Pure: no I/O, no clock.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import Enum

from ..swarm.roster import Roster

AGREE_TIMEOUT_S = 15.0  # waiting (not planning) -> every survivor flying the replan
MAX_RESYNC = 3


class Verdict(Enum):
    WAIT = "wait"
    AGREED = "agreed"
    MISMATCH = "mismatch"
    GIVE_UP = "give up"


@dataclass
class ReplanAgreement:
    started: float | None = None  # the replan began (the loss was noticed)
    held_at: float | None = None  # our replan was made: the window runs from here
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
        self.held_at = None

    def verdict(self, roster: Roster, now: float, *, held: bool, planning: bool = False) -> Verdict:
        """`held`: our replanned share is made and waits for the others; `planning`:
        our plan job runs (the window does not: the plan timeout bounds it)."""
        if self.started is None:
            return Verdict.WAIT
        if not held:
            self.held_at = None  # dropped (a re-synchronisation): made again later
        elif self.held_at is None:
            self.held_at = now
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
        if planning and not held:
            return Verdict.WAIT
        since = self.held_at if self.held_at is not None else self.started
        if now - since >= AGREE_TIMEOUT_S:
            return Verdict.GIVE_UP
        return Verdict.WAIT
