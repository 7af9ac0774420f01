"""A fleet heals after a partition: the parts of a fleet that replanned apart (each
lost the others for longer than the hold, each replanned what was left without them)
hear each other again flying one mission under different rosters (ROSTER_MISMATCH)
and merge back into one plan.

The rule, the same on every node (no leader):

1. A member lost by silence heard again flying our mission with another roster hash
   (roster.py's RosterMismatch, not a roster that dropped us) starts a heal: every
   node publishes its part's lineage (`PlanLineage`: how its plan came to be,
   swarm/regroup.py) once per hash it meets.
2. A node holds every other part's lineage (one per hash the live members of the
   parts publish): every part's members join the roster again, its generation becomes
   the longest lineage's (so every node makes the next roster hash alike), and the
   fleet replans (PLAN: every member holds and publishes its progress).
3. The replan (mission/share.py `merge`, planning `FleetPlan.merged`): every other
   part's plan made again from its lineage, each member's progress along its part's
   plan, and the lanes none of the parts flew shared among all the members, posed
   where their progress puts them: the same plan on every node, no lane flown twice.

AREA missions only (other mission types keep flying their parts' plans, alerted).

Pure: no I/O, no clock.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field

from swarm_proto import PlanLineage

KEEP = 8  # lineages kept per mission


@dataclass
class Heal:
    self_id: int
    #: the other parts' lineages, by mission and roster hash
    foreign: dict[int, dict[int, PlanLineage]] = field(default_factory=dict)
    #: (mission, hash) our lineage was published for
    published: set[tuple[int, int]] = field(default_factory=set)
    merged: int = 0  # heals carried out

    def meet(self, mission_id: int, theirs: int) -> bool:
        """A part flying roster `theirs`: True the first time (publish our lineage)."""
        key = (mission_id, theirs)
        if key in self.published:
            return False
        self.published.add(key)
        return True

    def on_lineage(self, msg: PlanLineage, ours: int) -> bool:
        """Another part's lineage (True: kept)."""
        if msg.handed_to or not msg.members_hash or msg.members_hash == ours:
            return False
        if msg.sender_id == self.self_id:
            return False
        book = self.foreign.setdefault(msg.mission.mission_id, {})
        book[msg.members_hash] = msg
        while len(book) > KEEP:
            del book[next(iter(book))]
        return True

    def parts(
        self, mission_id: int, hashes: Mapping[int, int], live: Iterable[int]
    ) -> tuple[PlanLineage, ...] | None:
        """The other parts to merge with, one lineage per hash the `live` members
        (`hashes`: their published hashes, ours left out) fly; None while one is
        missing (or there is none)."""
        need = sorted({hashes[v] for v in live if hashes.get(v)})
        if not need:
            return None
        book = self.foreign.get(mission_id, {})
        if any(h not in book for h in need):
            return None
        return tuple(book[h] for h in need)

    def done(self, mission_id: int) -> None:
        self.foreign.pop(mission_id, None)
        self.published = {k for k in self.published if k[0] != mission_id}
        self.merged += 1
