"""The fleet roster of a mission (the paper's swarm manager): which vehicles fly it,
agreed by every node without a leader.

Every vehicle answers every mission it hears (an Ack: accepted, or why not, and
NOT_ADDRESSED when the selector does not name it), and every node hears every answer.
The roster of a mission is this vehicle and the peers that accepted it: for an IDS
selector the named vehicles that accepted, for ALL and FLEET the vehicles that found
themselves addressed and accepted. A peer whose VehicleInfo shows it in PLAN or
GO_MISSION for the mission has accepted too (an Ack lost on the radio is not fatal).

While the fleet synchronises in STATE_PLAN the roster is open: it waits for an answer
from every live peer that may be addressed (`pending`). When every live member is in
PLAN and nobody is pending, the node freezes it (`freeze`): from the same answers every
node freezes the same members, and `members_hash` (16 bits of BLAKE2s of the mission
id and the sorted members, like the radio's slot `table_hash`) lets each node prove it:
it is published in VehicleInfo and checked against the peers'. After the freeze, a
member that leaves (liveliness or silence, an emergency, recalled by the operator) is a
`MemberLost` event, once.

Inputs (what `handle` takes):

    Ack (ref MISSION)        -> an answer of a peer (any mission, kept for a while)
    VehicleInfo              -> an answer (in PLAN/GO_MISSION for the mission); a
                                member that left the mission -> MemberLost;
                                a different members_hash -> RosterMismatch (a
                                member lost by silence too: a partition healed)
    PeerLeft                 -> a frozen member lost -> MemberLost
    distrust(ids)            -> vehicles whose identity is in doubt (core/identity.py):
                                neither members nor waited for while the roster is
                                open, and never joined to a frozen one (a frozen
                                member stays: its share is flown, by it or nobody)

Pure: no I/O, no clock.
"""

from __future__ import annotations

import hashlib
from collections import OrderedDict
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field

from swarm_proto import Ack, AckRef, FsmState, Selector, SelectorKind, VehicleInfo

from ..membership import Peer

KEEP_MISSIONS = 16  # answers kept for this many recent missions


def members_hash(mission_id: int, members: Iterable[int], generation: int = 0) -> int:
    """16 bits of BLAKE2s of the mission id (its 4 bytes as uint32), the sorted members and (after replans) how
    many times the roster was replanned; never 0 (0 = no roster)."""
    data = (mission_id & 0xFFFF_FFFF).to_bytes(4, "little") + b"".join(
        m.to_bytes(2, "little") for m in sorted(set(members))
    )
    if generation:
        data += b"R" + generation.to_bytes(2, "little")
    h = int.from_bytes(hashlib.blake2s(data, digest_size=2, person=b"bdroster").digest(), "little")
    return h or 1


@dataclass(frozen=True)
class MemberLost:
    """A member of the frozen roster left the mission."""

    mission_id: int
    vehicle_id: int
    why: str  # "liveliness" | "stale" | "emergency" | "left the mission"


@dataclass(frozen=True)
class RosterMismatch:
    """A member planned with another roster (its members hash differs from ours)."""

    mission_id: int
    vehicle_id: int
    theirs: int
    ours: int


@dataclass(frozen=True)
class MemberJoined:
    """A vehicle outside the frozen roster is in PLAN for our mission: it joins the
    fleet (JOIN_MISSION, SWAP_MISSION; swarm/regroup.py)."""

    mission_id: int
    vehicle_id: int


RosterEvent = MemberLost | RosterMismatch | MemberJoined


@dataclass
class Roster:
    self_id: int
    mission_id: int | None = None
    selection: Selector = field(default_factory=Selector)
    members: tuple[int, ...] = ()  # frozen members (sorted), () while open
    lost: dict[int, str] = field(default_factory=dict)  # frozen members that left, and why
    finished: set[int] = field(default_factory=set)  # members that flew all their share
    planned: tuple[int, ...] = ()  # the members the current plan was made for
    generation: int = 0  # replans of this roster
    #: each member's last published (progress_m, path_m) in this mission: a survivor's
    #: progress is held while it replans, so every survivor replans from the same values
    progress: dict[int, tuple[float, float]] = field(default_factory=dict)
    #: each member's last published PREMISSION entry time (VehicleInfo.entry_unix_s)
    entry_at: dict[int, float] = field(default_factory=dict)
    #: each member's last published members hash in this mission (VehicleInfo)
    hashes: dict[int, int] = field(default_factory=dict)
    #: the battery each member published on entering PLAN for the mission (the one
    #: VehicleInfo every node hears alike): what the plan gives it work for
    plan_battery: dict[int, int] = field(default_factory=dict)
    mismatches: int = 0
    #: the rosters of the parts merging back (swarm/heal.py): a member still flying one
    #: has not replanned yet, as one flying our previous roster
    merging: frozenset[int] = frozenset()
    _previous_hash: int = 0
    #: the last roster every member flew (planned, generation, previous hash): a replan
    #: is made from it and, without agreement, rolled back to it (`rollback`)
    _agreed: tuple[tuple[int, ...], int, int] = ((), 0, 0)
    _reported: set[tuple[int, int]] = field(default_factory=set)  # (vehicle, hash) alerted
    _answers: OrderedDict[int, dict[int, bool]] = field(default_factory=OrderedDict)
    #: vehicles heard from two sources (core/identity.py): kept out of voting and planning
    untrusted: frozenset[int] = frozenset()

    # ------------------------------------------------------------------ lifecycle
    def open(self, mission_id: int, selection: Selector) -> None:
        """This vehicle accepted `mission_id`: a new, open roster."""
        self.mission_id, self.selection = mission_id, selection
        self._reset()
        self._answer(mission_id, self.self_id, True)

    def close(self) -> None:
        self.mission_id = None
        self._reset()

    def _reset(self) -> None:
        self.members, self.lost, self.finished, self.planned = (), {}, set(), ()
        self.generation = 0
        self.progress = {}
        self.entry_at = {}
        self.hashes = {}
        self.plan_battery = {}
        self.merging = frozenset()
        self._previous_hash = 0
        self._agreed = ((), 0, 0)
        self._reported = set()

    @property
    def frozen(self) -> bool:
        return bool(self.members)

    @property
    def members_hash(self) -> int:
        if not self.planned or self.mission_id is None:
            return 0
        return members_hash(self.mission_id, self.planned, self.generation)

    @property
    def flying(self) -> tuple[int, ...]:
        """Frozen members that have not left nor finished their share."""
        return tuple(m for m in self.members if m not in self.lost and m not in self.finished)

    def distrust(self, ids: frozenset[int]) -> None:
        """The vehicles whose identity is in doubt now (all of them, every time)."""
        self.untrusted = frozenset(ids)

    # ------------------------------------------------------------------ answers
    def _answer(self, mission_id: int, vid: int, accepted: bool) -> None:
        answers = self._answers.setdefault(mission_id, {})
        self._answers.move_to_end(mission_id)
        if accepted or vid not in answers:  # an acceptance (info) outranks a stale refusal
            answers[vid] = accepted
        while len(self._answers) > KEEP_MISSIONS:
            self._answers.popitem(last=False)

    def on_ack(self, ack: Ack) -> None:
        if ack.ref == AckRef.MISSION and ack.vehicle_id != self.self_id:
            self._answer(ack.ref_id, ack.vehicle_id, ack.accepted)

    def on_info(self, info: VehicleInfo) -> list[RosterEvent]:
        mid = self.mission_id
        vid = info.vehicle_id
        if mid is None or vid == self.self_id:
            return []
        in_mission = info.mission_id == mid and info.fsm_state in (
            FsmState.PLAN,
            FsmState.GO_MISSION,
        )
        if in_mission and not self.frozen:
            self._answer(mid, vid, True)
        if in_mission:
            mark = (info.mission_progress_m, info.mission_path_m)
            self.progress[vid] = mark
            if info.entry_unix_s > 0.0:
                self.entry_at[vid] = info.entry_unix_s
            self.hashes[vid] = info.members_hash
            if info.fsm_state == FsmState.PLAN and info.battery_pct >= 0:
                self.plan_battery.setdefault(vid, info.battery_pct)
        out: list[RosterEvent] = []
        if (
            self.frozen
            and in_mission
            and info.fsm_state == FsmState.PLAN
            and vid not in self.flying
            and vid not in self.finished  # done with it (nothing to fly): still in PLAN
            and vid not in self.untrusted
        ):
            return [MemberJoined(mid, vid)]  # a vehicle joining (or a lost one back)
        if (
            self.frozen
            and vid in self.lost
            and in_mission
            and info.fsm_state == FsmState.GO_MISSION
            and info.members_hash
            and info.members_hash not in (self.members_hash, self._previous_hash)
            and (vid, info.members_hash) not in self._reported
        ):
            # a member lost by silence flies the mission with another roster: the two
            # sides of a partition replanned apart (once per member and hash)
            self.mismatches += 1
            self._reported.add((vid, info.members_hash))
            return [RosterMismatch(mid, vid, info.members_hash, self.members_hash)]
        if (
            self.frozen
            and vid in self.members
            and vid not in self.lost
            and vid not in self.finished
        ):
            if info.fsm_state == FsmState.EMERGENCY:
                out += self._lose(vid, "emergency")
            elif info.mission_id != mid and (
                info.fsm_state != FsmState.PLAN or info.mission_id > 0  # planning another
            ):
                # progress is kept on the way home: a member that flew all its share
                # says so in the same VehicleInfo that shows it left the mission
                done, path = info.mission_progress_m, info.mission_path_m
                if path > 0.0 and done >= path - 0.5:
                    self.finished.add(vid)  # flew its share and went home: not lost
                else:
                    out += self._lose(vid, "left the mission")
            else:
                theirs = info.members_hash
                # a member one replan behind has not noticed the loss yet
                if (
                    in_mission
                    and info.fsm_state == FsmState.GO_MISSION
                    and theirs
                    and theirs not in (self.members_hash, self._previous_hash)
                ):
                    self.mismatches += 1
                    if (vid, theirs) not in self._reported:  # an event once, not every second
                        self._reported.add((vid, theirs))
                        out.append(RosterMismatch(mid, vid, theirs, self.members_hash))
        return out

    def on_peer_left(self, vid: int, why: str) -> list[RosterEvent]:
        """A member lost: of the frozen roster, or (still in PLAN) a peer that had
        accepted the mission."""
        if vid in self.lost or self.mission_id is None:
            return []
        if self.frozen:
            return self._lose(vid, why) if vid in self.flying else []
        if self._answers.get(self.mission_id, {}).get(vid):
            return self._lose(vid, why)
        return []

    def back(self, vid: int) -> None:
        """A member lost by silence heard again, flying this roster, before any replan
        without it: a member again (mission/coordinator.py holds its share meanwhile)."""
        self.lost.pop(vid, None)

    def _lose(self, vid: int, why: str) -> list[RosterEvent]:
        assert self.mission_id is not None
        self.lost[vid] = why
        return [MemberLost(self.mission_id, vid, why)]

    # ------------------------------------------------------------------ sync
    def accepted(self, peers: Mapping[int, Peer]) -> tuple[int, ...]:
        """The members as the answers stand: this vehicle and the live peers that
        accepted."""
        if self.mission_id is None:
            return ()
        answers = self._answers.get(self.mission_id, {})
        named = self.selection.vehicle_ids if self.selection.kind == SelectorKind.IDS else None
        ids = {self.self_id} | {
            v
            for v, ok in answers.items()
            if ok
            and v in peers
            and peers[v].present
            and v not in self.untrusted
            and (named is None or v in named)
        }
        return tuple(sorted(ids))

    def may_be_addressed(self, peer: Peer) -> bool:
        sel = self.selection
        if peer.is_ground_station or not peer.present:
            return False
        if sel.kind == SelectorKind.IDS:
            return peer.node_id in sel.vehicle_ids
        if sel.kind == SelectorKind.FLEET or (sel.kind == SelectorKind.QUANTITY and sel.fleet_id):
            return peer.fleet_id == sel.fleet_id or peer.mission_id == self.mission_id
        return True  # ALL, QUANTITY of any fleet (every vehicle answers: a candidate or not)

    def pending(self, peers: Mapping[int, Peer]) -> tuple[int, ...]:
        """Live peers that may be addressed and have not answered yet."""
        if self.mission_id is None:
            return ()
        answers = self._answers.get(self.mission_id, {})
        return tuple(
            sorted(
                vid
                for vid, p in peers.items()
                if vid != self.self_id
                and vid not in answers
                and vid not in self.untrusted
                and self.may_be_addressed(p)
            )
        )

    def ready(self, peers: Mapping[int, Peer]) -> bool:
        """Nobody pending and every live member in PLAN (or already in GO_MISSION) for
        this mission."""
        mid = self.mission_id
        if mid is None or self.pending(peers):
            return False
        for vid in self.accepted(peers):
            if vid == self.self_id:
                continue
            info = peers[vid].info
            if info is None or info.fsm_state not in (FsmState.PLAN, FsmState.GO_MISSION):
                return False
            if info.mission_id != mid:
                return False
        return True

    def freeze(self, peers: Mapping[int, Peer]) -> tuple[int, ...]:
        self.members = self.planned = self.accepted(peers)
        self.lost = {v: why for v, why in self.lost.items() if v in self.members}
        self._agreed = (self.planned, self.generation, self._previous_hash)
        return self.members

    # ------------------------------------------------------------------ replan
    def ready_to_replan(self, peers: Mapping[int, Peer]) -> bool:
        """Every live flying member is in PLAN for the mission (it noticed the loss and
        published its progress) or already flies the replanned roster (its hash is the
        next generation's): no leader, the same inputs everywhere."""
        mid = self.mission_id
        if mid is None or not self.frozen:
            return False
        nxt = members_hash(mid, self.survivors(peers), self.generation + 1)
        for vid in self.survivors(peers):
            if vid == self.self_id:
                continue
            info = peers[vid].info
            if info is None or info.mission_id != mid:
                return False
            if info.fsm_state != FsmState.PLAN and info.members_hash != nxt:
                return False
        return True

    def nothing_to_fly(self, ids: Iterable[int]) -> None:
        """The plan gives these members no share (an area no battery of theirs reaches,
        say): they stay on the ground and are done with the mission, as a member that
        flew all its share is; leaving it is not a loss to replan for. Every member
        marks the same, from the same plan."""
        self.finished |= set(ids) & set(self.members)

    def survivors(self, peers: Mapping[int, Peer]) -> tuple[int, ...]:
        return tuple(
            v for v in self.flying if v == self.self_id or (v in peers and peers[v].present)
        )

    def agreement(self) -> tuple[bool, tuple[tuple[int, int], ...]]:
        """Whether every member the current plan was made for (but this vehicle) has
        published its hash, and the members that published another one: neither it,
        nor the hash of the last roster every member flew (a member that has not
        replanned yet), nor 0."""
        ours = self.members_hash
        agreed_hash = (
            members_hash(self.mission_id, self._agreed[0], self._agreed[1])
            if self.mission_id is not None and self._agreed[0]
            else 0
        )
        all_in, other = True, []
        for vid in self.planned:
            if vid == self.self_id or vid in self.lost:
                continue
            h = self.hashes.get(vid, 0)
            if h != ours:
                all_in = False
                if h not in (0, agreed_hash, self._previous_hash) and h not in self.merging:
                    other.append((vid, h))
        return all_in, tuple(other)

    def settle(self) -> None:
        """Every member flies the current roster: the next replan starts from it."""
        self._agreed = (self.planned, self.generation, self._previous_hash)
        self.merging = frozenset()

    def rollback(self) -> None:
        """Back to the last roster every member flew (a replan not agreed is dropped:
        the next one is made from there, as every other member makes it)."""
        self.planned, self.generation, self._previous_hash = self._agreed

    def replanned(self, survivors: tuple[int, ...]) -> None:
        """The replan is made for `survivors` (the next generation)."""
        for v in set(self.flying) - set(survivors):
            self.lost.setdefault(v, "stale")
        self._previous_hash = self.members_hash
        self.planned = survivors
        self.generation += 1

    # ------------------------------------------------------------------ voting
    def voted_out(self, winners: Iterable[int]) -> list[RosterEvent]:
        """Members a vote sent to another mission leave this one: alive, but lost to
        this fleet (`MemberLost`, "voted out"), so the others replan without them."""
        out: list[RosterEvent] = []
        for vid in sorted(set(winners)):
            if self.frozen and vid in self.flying and vid != self.self_id:
                out += self._lose(vid, "voted out")
        return out

    def elected(self, winners: Iterable[int]) -> None:
        """A vote among this (frozen) roster chose `winners` to fly its mission: they are
        the roster now (the others stood down)."""
        self.members = self.planned = tuple(sorted(set(winners)))
        self.lost = {v: why for v, why in self.lost.items() if v in self.members}
        self.finished &= set(self.members)
        self._agreed = (self.planned, self.generation, self._previous_hash)

    # ------------------------------------------------------------------ add / swap
    def join(self, vid: int) -> None:
        """A vehicle joins the frozen roster (the next replan takes it in)."""
        if self.frozen and vid not in self.flying:
            self.members = tuple(sorted({*self.members, vid}))
            self.lost.pop(vid, None)
            self.finished.discard(vid)

    def merge(self, others: Iterable[int], generation: int, rosters: Iterable[int] = ()) -> None:
        """The parts of a partition meet again (swarm/heal.py): their members are
        members again, and the next replan is generation `generation` + 1 on every
        node (kept through a rollback)."""
        if not self.frozen:
            return
        others = set(others) - {self.self_id}
        self.members = tuple(sorted({*self.members, *others}))
        for v in others:
            self.lost.pop(v, None)
            self.finished.discard(v)
        g = max(self.generation, generation)
        self.generation = g
        self.merging = frozenset({*rosters, self.members_hash})
        self._agreed = (self._agreed[0], max(self._agreed[1], g), self._agreed[2])

    def adopt(
        self, mission_id: int, members: Iterable[int], planned: Iterable[int], generation: int
    ) -> None:
        """Take a fleet's roster as its lineage shows it (a vehicle joining the fleet, or a
        fleet taking over an emptied fleet's mission): frozen at once."""
        self.mission_id = mission_id
        self._reset()
        self.planned = tuple(sorted(set(planned)))
        self.members = tuple(sorted(set(members) | set(self.planned)))
        self.lost = {v: "left before" for v in self.members if v not in self.planned}
        self.generation = generation
        self._agreed = (self.planned, self.generation, 0)  # what the fleet flies now

    def progress_of(self, vid: int) -> tuple[float, float]:
        """A member's last published (progress_m, path_m); (0, 0): nothing heard."""
        return self.progress.get(vid, (0.0, 0.0))
