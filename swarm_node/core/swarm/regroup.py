"""Add and swap (paper section 2.3.5: the actions Add and Swap, the mission states
SENDING_MISSION and WAITING_MISSION): a vehicle joins a running mission's fleet, two
fleets exchange vehicles, an emptied fleet hands its unfinished mission to the other.

Every member of a fleet plans the whole fleet from the same inputs and keeps its own
share. A vehicle that joins needs the plan the fleet flies, which was made from inputs
it never saw: the homes the first plan posed the members at, and every replan's members
and progress. The fleet keeps those inputs, its *lineage* (`Lineage`), and its members
publish it (`PlanLineage`) when a replan takes a vehicle in; the joiner replays it
(`mission.share.replay`) and holds the fleet's plan exactly as the members do, so from
then on it is a member like any other: it is lost, inherits and votes as they do.

JOIN_MISSION (args.mission_id M), for each vehicle it addresses (`answer`):
  refused NOT_FOUND when M was never heard here, DUPLICATE when already flying it,
  BUSY when returning, landing or planning, the usual acceptance checks first;
  accepted: the vehicle leaves what it flies (its old fleet sees it leave and replans),
  enters PLAN for M and says so in its VehicleInfo. M's members see a vehicle outside
  the roster in PLAN for M (`roster.MemberJoined`), replan with it (unposed: it has no
  share, and its live position differs between vehicles) and publish the lineage; the joiner replays the lineage that
  ends with that replan and flies its share.
SWAP_MISSION (args.mission_id A, args.other_mission_id B): each addressed vehicle
  flying A joins B, each flying B joins A (any other: NOT_FOUND). When the vehicles
  named are all of A's fleet and none of B's, A is emptied: before going, its members
  publish A's lineage with the progress they leave at (`handed_to` B; the paper's
  SENDING_MISSION). Every member of B keeps it (`handed`), and when it has flown its
  share of B it takes up what is left of A with B's fleet as the swap left it (the
  members of B's replan that took the movers in), instead of flying home.

Pure: no I/O, no clock.
"""

from __future__ import annotations

from collections import Counter, OrderedDict
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field

from swarm_proto import (
    AckReason,
    Command,
    CommandKind,
    LineageBattery,
    LineageHome,
    LineageProgress,
    LineageStep,
    Mission,
    PlanLineage,
)

from ..mission.share import Member, Replay
from ..profile import VehicleProfile

KEEP = 16  # missions remembered (heard, lineages)


@dataclass
class Lineage:
    """How the plan of one fleet came to be."""

    mission: Mission
    first: tuple[LineageHome, ...]
    steps: list[LineageStep] = field(default_factory=list)

    @property
    def members(self) -> tuple[int, ...]:
        """The members of the plan flown now."""
        if self.steps and self.steps[-1].members:
            return self.steps[-1].members
        return tuple(h.vehicle_id for h in self.first)

    @property
    def everyone(self) -> tuple[int, ...]:
        ids = {h.vehicle_id for h in self.first}
        for s in self.steps:
            ids |= set(s.members)
        return tuple(sorted(ids))

    def message(self, sender: int, members_hash: int, handed_to: int = 0) -> PlanLineage:
        return PlanLineage(
            self.mission, sender, self.first, tuple(self.steps), members_hash, handed_to
        )

    @classmethod
    def of(cls, msg: PlanLineage) -> Lineage:
        return cls(msg.mission, msg.first, list(msg.replans))

    def replay(
        self, profiles: Mapping[int, VehicleProfile], adopters: Sequence[int] = ()
    ) -> Replay:
        """The planning inputs (`mission.share.replay`); a handed-over lineage (its last
        step has no members) is taken up by `adopters`. KeyError: a member whose
        profile is unknown here."""
        first = tuple(
            Member(profiles[h.vehicle_id], h.home, None if h.battery_pct < 0 else h.battery_pct)
            for h in self.first
        )
        steps = []
        for s in self.steps:
            ids = s.members or tuple(adopters)
            steps.append(
                (
                    tuple(profiles[v] for v in ids),
                    {p.vehicle_id: p.progress_m for p in s.progress},
                    {b.vehicle_id: b.battery_pct for b in s.battery},
                )
            )
        return Replay(first, tuple(steps))


@dataclass
class Regroup:
    self_id: int
    heard: OrderedDict[int, Mission] = field(default_factory=OrderedDict)
    lineages: OrderedDict[int, Lineage] = field(default_factory=OrderedDict)  # fleets flown in
    joining: int | None = None  # the mission this vehicle is joining
    offered: dict[int, PlanLineage] = field(default_factory=dict)  # for our join, by mission
    handed: dict[int, dict[int, PlanLineage]] = field(default_factory=dict)  # ours -> theirs
    adopting: dict[int, tuple[PlanLineage, tuple[int, ...]]] = field(default_factory=dict)
    counts: Counter[str] = field(default_factory=Counter)

    # ------------------------------------------------------------------ what is heard
    def heard_mission(self, mission: Mission) -> None:
        self.heard[mission.mission_id] = mission
        self.heard.move_to_end(mission.mission_id)
        while len(self.heard) > KEEP:
            self.heard.popitem(last=False)

    def on_lineage(self, msg: PlanLineage) -> None:
        mid = msg.mission.mission_id
        if msg.handed_to:
            # an emptied fleet's mission for ours: kept by sender (each says its own
            # progress exactly)
            self.handed.setdefault(msg.handed_to, {})[msg.sender_id] = msg
            self.counts["handed"] += 1
            return
        if self.joining == mid and msg.replans and self.self_id in msg.replans[-1].members:
            old = self.offered.get(mid)
            if old is None or len(msg.replans) > len(old.replans):
                self.offered[mid] = msg
            return
        self.counts["lineage_not_for_us"] += 1

    # ------------------------------------------------------------------ a fleet's record
    def founded(self, mission: Mission, members: Sequence[Member]) -> None:
        """The first plan of a fleet this vehicle flies in."""
        first = tuple(
            LineageHome(
                m.profile.vehicle_id, m.home, -1 if m.battery_pct is None else round(m.battery_pct)
            )
            for m in members
        )
        self.lineages[mission.mission_id] = Lineage(mission, first)
        self.lineages.move_to_end(mission.mission_id)
        while len(self.lineages) > KEEP:
            self.lineages.popitem(last=False)

    def replanned(
        self,
        mission_id: int,
        members: Sequence[int],
        progress: Mapping[int, float],
        battery: Mapping[int, float] | None = None,
    ) -> bool:
        """A replan of our fleet; True when it takes a vehicle in (publish the lineage)."""
        lin = self.lineages.get(mission_id)
        if lin is None:
            return False
        before = set(lin.everyone)
        lin.steps.append(
            LineageStep(
                tuple(members),
                tuple(LineageProgress(v, max(0.0, p)) for v, p in sorted(progress.items())),
                tuple(
                    LineageBattery(v, min(100.0, max(0.0, b)))
                    for v, b in sorted((battery or {}).items())
                ),
            )
        )
        return bool(set(members) - before)

    def adopted(self, msg: PlanLineage) -> Lineage:
        """This vehicle takes the fleet's lineage as its own (it joined)."""
        lin = Lineage.of(msg)
        self.lineages[msg.mission.mission_id] = lin
        self.joining = None
        self.offered.pop(msg.mission.mission_id, None)
        return lin

    # ------------------------------------------------------------------ commands
    def answer(self, cmd: Command, flying: int | None, idle: bool) -> tuple[AckReason, str, int]:
        """JOIN_MISSION / SWAP_MISSION for this (addressed) vehicle: (reason, text, the
        mission it goes to)."""
        a = cmd.args
        if cmd.kind == CommandKind.JOIN_MISSION:
            to = a.mission_id
        elif flying is not None and flying == a.mission_id:
            to = a.other_mission_id
        elif flying is not None and flying == a.other_mission_id:
            to = a.mission_id
        else:
            return AckReason.NOT_FOUND, f"flying neither {a.mission_id} nor {a.other_mission_id}", 0
        if to == 0:
            return AckReason.INVALID, f"{cmd.kind.name} needs the mission ids", 0
        if to == flying:
            return AckReason.DUPLICATE, f"already flying mission {to}", 0
        if to not in self.heard:
            return AckReason.NOT_FOUND, f"mission {to} not heard here", 0
        if flying is None and not idle:
            return AckReason.BUSY, "returning, landing or planning", 0
        return AckReason.OK, "", to

    def handover(self, ours: int) -> dict[int, PlanLineage]:
        """Lineages of an emptied fleet's mission handed to our mission's fleet."""
        return self.handed.pop(ours, {})

    def emptied(
        self, cmd: Command, flying: Iterable[int], missions: Mapping[int, int], theirs: int
    ) -> bool:
        """This swap takes every member of our fleet (`flying`) and none of theirs
        (`missions`: the live peers' missions)."""
        named = set(cmd.target.vehicle_ids)
        if not set(flying) <= named:
            return False
        return not any(missions.get(v) == theirs for v in named)

    def hand_over(
        self, ours: int, theirs: int, progress: Mapping[int, float], members_hash: int
    ) -> PlanLineage | None:
        """Our fleet is emptied: its lineage, with the progress we leave at, for the
        fleet of `theirs` (the paper's SENDING_MISSION; None: no plan to hand over). We
        go to their fleet: we take it up with them."""
        lineage = self.lineages.get(ours)
        if lineage is None:
            return None
        last = Lineage(lineage.mission, lineage.first, list(lineage.steps))
        self.replanned(ours, (), progress)  # the hand-over step
        msg = self.lineages[ours].message(self.self_id, members_hash, theirs)
        self.lineages[ours] = last
        self.on_lineage(msg)
        return msg

    def take_over(self, ours: int) -> PlanLineage | None:
        """Our mission is flown: an emptied fleet's mission handed to ours, to take up
        (the fleet as the swap left it flies what is left of it), instead of flying
        home; its adopters are noted for `join`."""
        handed = self.handover(ours)
        if not handed:
            return None
        msg = handed_lineage(handed)
        mine = self.lineages.get(ours)
        movers = set(handed)
        adopters: tuple[int, ...] = mine.members if mine else (self.self_id,)
        for step in mine.steps if mine else ():
            if movers & set(step.members):
                adopters = step.members
                break
        self.adopting[msg.mission.mission_id] = (msg, adopters)
        return msg

    def join(
        self, mid: int, profiles: Mapping[int, VehicleProfile]
    ) -> tuple[PlanLineage, Lineage, Replay]:
        """The plan of the fleet we join (or of an emptied fleet's, handed to ours),
        made again from its lineage. Raises KeyError for a member with no profile."""
        adopting = self.adopting.pop(mid, None)
        if adopting is not None:
            msg, adopters = adopting
            lineage = Lineage.of(msg)
        else:
            msg, adopters = self.offered[mid], ()
            lineage = self.adopted(msg)
        replay = lineage.replay(profiles, adopters)
        if adopters:  # the hand-over step is ours now: taken up by the adopters
            lineage.steps[-1] = LineageStep(tuple(adopters), lineage.steps[-1].progress)
            self.lineages[mid] = lineage
        return msg, lineage, replay


def handed_lineage(msgs: Mapping[int, PlanLineage]) -> PlanLineage:
    """One lineage from the emptied fleet's members' (each knows its own progress
    exactly: every member's last step entry is taken from its own message, else from the
    lowest id that reported it)."""
    first = msgs[min(msgs)]
    progress: dict[int, float] = {}
    for sender in sorted(msgs):
        for p in msgs[sender].replans[-1].progress:
            if p.vehicle_id == sender or p.vehicle_id not in progress:
                progress[p.vehicle_id] = p.progress_m
    step = LineageStep((), tuple(LineageProgress(v, m) for v, m in sorted(progress.items())))
    return PlanLineage(
        first.mission,
        first.sender_id,
        first.first,
        (*first.replans[:-1], step),
        first.members_hash,
        first.handed_to,
    )
