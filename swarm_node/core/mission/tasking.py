"""Tasking (paper section 2.3.6, the deliberative module): who flies a QUANTITY mission,
decided by the vote with no leader, and the re-tasking rules that turn a TargetReport
into such a mission. The node routes QUANTITY missions, Votes, TargetReports and its
roster's losses here and carries out what comes back (docs/voting.md).

Who votes (the electorate), on each vehicle, from state every member already agrees on:

- a vehicle flying a mission with a frozen roster votes with that mission's fleet: the
  roster's members for the plan being flown (`Roster.planned`, proven equal by the
  members hash), with the selector's fleet (`--fleet`) as a filter; members the roster
  knows are gone are not waited for;
- a vehicle flying nothing (GO_MISSION, no mission) takes the mission up as any other:
  the idle candidates synchronise in STATE_PLAN and the frozen roster is the electorate;
- only one fleet votes, the one flying the most vehicles (ties: the lower mission id),
  counted from the VehicleInfo of the vehicles the selector addresses: an idle vehicle
  that hears a fleet flying, or a member of a smaller fleet, is not a candidate
  (NOT_ADDRESSED, "the fleet of mission N votes"); returning, landing or planning
  vehicles answer BUSY, and so does a vehicle already voting (one vote at a time).

Each voter scores itself once (`scoring.PaperScore`, the database's `voting` weights and
payload hierarchy) and runs a `voting.Ballot`; every vehicle ends with the same winners.
Winners fly the mission as a new fleet (its selector becomes the winners' ids); the rest
of a flying fleet lose the winners as members ("voted out", alive) and replan their
mission through the roster's inheritance path; idle vehicles not chosen stand down. A
ballot that fails raises a WARNING alert and the mission is dropped (paper Fig. 11).

Target re-tasking (`RetaskRules`, the database's `target re-tasking` module parameters):
a report whose class has a rule (`count.<class>`, else `count`) and whose confidence
reaches `min_confidence[.<class>]` becomes a TARGET mission for `count` vehicles, with
the reporting vehicle's payload model when `payload_of_source` is set. Its id is a hash
of (source, target id) (`target_mission_id`): every vehicle derives the same mission
from the same report, and a repeated report is the same mission. Reports of one target
by several sources (within `dedup_radius_m`, same class) are gathered for `hold_s`; the
earliest (time, source, target id) is kept, the others are duplicates, and so is any
later report near a target already tasked (for `keep_s`).

Inputs and outputs:

| input | what happens |
|---|---|
| `answer(mission, standing)` | candidate or why not (the node acks) |
| `start(...)` | a ballot starts; its first vote goes out |
| `handle(Vote)` | to the ballot of its mission (unknown missions counted) |
| `handle(VoterLost)` | to every ballot (the roster lost a member) |
| `handle(TargetReport)` | rules, duplicates, hold -> `Derived(mission)` |
| `on_timer(now)` | ballots' re-sends and deadlines, reports' hold |

Outputs: `Publish(Vote | Alert)`, `Note`, `Elected`, `VoteFailed`, `Derived`.
Pure: no I/O, `now` passed in.
"""

from __future__ import annotations

import hashlib
import logging
import math
from collections import Counter, OrderedDict
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field

import msgspec

from swarm_proto import (
    AckReason,
    Alert,
    AlertCode,
    Geometry,
    LatLon,
    Mission,
    MissionParams,
    MissionType,
    Selector,
    SelectorKind,
    Severity,
    TargetReport,
    TargetSource,
    Vote,
)
from swarm_proto.text import short_text

from ..outputs import Note, Publish
from ..planning.geo import LocalFrame
from ..profile import PayloadClass, VehicleProfile
from .scoring import Candidate, PaperScore, ScoreError, Terms, mission_terms, payload_wanted
from .voting import (
    Ballot,
    BallotConfig,
    BallotOutcome,
    Decided,
    Failed,
    SendVote,
    VoterLost,
)

VOTING_MODULE = "voting"
RETASK_MODULE = "target re-tasking"
TARGET_MISSION_BIT = 0x8000_0000  # derived target missions have the top bit set


class RetaskError(ValueError):
    """Bad re-tasking parameters (a clear message at start-up, never a crash later)."""


# --------------------------------------------------------------------------- settings


@dataclass(frozen=True)
class RetaskRules:
    """The database's `target re-tasking` module parameters.

    count / count.<class>                   vehicles sent to a target (0: none)
    min_confidence / min_confidence.<class> reports below it are ignored
    duration_s                              how long the vehicles hold on the target
    radius_m, altitude_rel_m                0: the target mission's defaults
    dedup_radius_m                          reports this close (same class) are one target
    hold_s                                  how long reports are gathered before tasking
    keep_s                                  how long a tasked target is remembered
    payload_of_source                       1: ask for the reporting vehicle's payload
    """

    count: int = 0
    min_confidence: float = 1.0
    per_class: Mapping[str, tuple[int | None, float | None]] = field(default_factory=dict)
    duration_s: float = 120.0
    radius_m: float = 0.0
    altitude_rel_m: float = 0.0
    dedup_radius_m: float = 100.0
    hold_s: float = 0.5
    keep_s: float = 900.0
    payload_of_source: bool = True

    @classmethod
    def from_params(cls, params: Mapping[str, float]) -> RetaskRules:
        plain: dict[str, float] = {}
        per_class: dict[str, tuple[int | None, float | None]] = {}
        for name, raw in params.items():
            value = float(raw)
            if not math.isfinite(value):
                raise RetaskError(f"target re-tasking: {name} = {value} is not finite")
            key, _, klass = name.partition(".")
            if klass:
                if key not in ("count", "min_confidence"):
                    raise RetaskError(
                        f"target re-tasking: {name}: only count.<class> and "
                        "min_confidence.<class> are set per class"
                    )
                count, conf = per_class.get(klass, (None, None))
                if key == "count":
                    count = _count(name, value)
                else:
                    conf = _confidence(name, value)
                per_class[klass] = (count, conf)
                continue
            plain[key] = value
        unknown = set(plain) - {f for f in cls.__dataclass_fields__ if f != "per_class"}
        if unknown:
            raise RetaskError(f"target re-tasking: unknown parameter(s) {sorted(unknown)}")
        for name in (
            "duration_s",
            "radius_m",
            "altitude_rel_m",
            "dedup_radius_m",
            "hold_s",
            "keep_s",
        ):
            if plain.get(name, 0.0) < 0.0:
                raise RetaskError(f"target re-tasking: {name} must be >= 0")
        return cls(
            count=_count("count", plain.get("count", 0.0)),
            min_confidence=_confidence("min_confidence", plain.get("min_confidence", 1.0)),
            per_class=per_class,
            duration_s=plain.get("duration_s", cls.duration_s),
            radius_m=plain.get("radius_m", 0.0),
            altitude_rel_m=plain.get("altitude_rel_m", 0.0),
            dedup_radius_m=plain.get("dedup_radius_m", cls.dedup_radius_m),
            hold_s=plain.get("hold_s", cls.hold_s),
            keep_s=plain.get("keep_s", cls.keep_s),
            payload_of_source=plain.get("payload_of_source", 1.0) != 0.0,
        )

    def rule(self, target_class: str) -> tuple[int, float]:
        """(vehicles, minimum confidence) for a class."""
        count, conf = self.per_class.get(target_class, (None, None))
        return (
            self.count if count is None else count,
            self.min_confidence if conf is None else conf,
        )


def _count(name: str, value: float) -> int:
    if value != int(value) or not 0 <= value <= 255:
        raise RetaskError(f"target re-tasking: {name} must be a whole number 0..255, got {value}")
    return int(value)


def _confidence(name: str, value: float) -> float:
    if not 0.0 <= value <= 1.0:
        raise RetaskError(f"target re-tasking: {name} must be in [0, 1], got {value}")
    return value


@dataclass(frozen=True)
class TaskingSettings:
    """What tasking reads from the swarm database: `module_params("voting")`,
    `module_params("target re-tasking")` and `payload_classes()`. Invalid parameters
    raise (`ScoreError`, `RetaskError`) when the settings are made, at the node's start."""

    voting: Mapping[str, float] = field(default_factory=dict)
    retask: Mapping[str, float] = field(default_factory=dict)
    payload_classes: Mapping[str, PayloadClass] = field(default_factory=dict)
    ballot: BallotConfig = field(default_factory=BallotConfig)

    def __post_init__(self) -> None:
        object.__setattr__(self, "score", PaperScore.from_params(self.voting))
        object.__setattr__(self, "rules", RetaskRules.from_params(self.retask))

    score: PaperScore = field(init=False)
    rules: RetaskRules = field(init=False)


# --------------------------------------------------------------------------- derived missions


def target_mission_id(source_id: int, target_id: int) -> int:
    """The mission a target report asks for: the same on every vehicle (and the ground
    station) for the same (source, target id); top bit set, never 0."""
    data = source_id.to_bytes(2, "little") + (target_id & 0xFFFF_FFFF).to_bytes(4, "little")
    h = hashlib.blake2s(data, digest_size=4, person=b"bdtarget").digest()
    return TARGET_MISSION_BIT | (int.from_bytes(h, "little") & 0x7FFF_FFFF)


def target_mission(
    report: TargetReport,
    rules: RetaskRules,
    profiles: Mapping[int, VehicleProfile],
    count: int,
) -> Mission:
    """The QUANTITY target mission for a report (a pure function of the report, the
    rules and the database: every vehicle derives the same)."""
    payload = ""
    source = profiles.get(report.source_id)
    if rules.payload_of_source and report.source == TargetSource.PAYLOAD and source is not None:
        payload = source.payload_model
    params = MissionParams(
        altitude_rel_m=rules.altitude_rel_m or MissionParams().altitude_rel_m,
        duration_s=rules.duration_s or None,
        radius_m=rules.radius_m or None,
    )
    return Mission(
        target_mission_id(report.source_id, report.target_id),
        report.source_id,
        MissionType.TARGET,
        Geometry.point(report.position.lat_deg, report.position.lon_deg),
        params,
        Selector(SelectorKind.QUANTITY, quantity=count, payload_model=payload[:48]),
        f"target {report.target_class}"[:48],
        report.time_unix_s,
    )


# --------------------------------------------------------------------------- node view


@dataclass(frozen=True)
class Standing:
    """What tasking needs to know of the node when a QUANTITY mission arrives."""

    self_id: int
    fleet_id: int
    me: Candidate
    idle: bool = False  # active, GO_MISSION, no mission
    flying: int | None = None  # the mission flown with a frozen roster (its fleet votes)
    replanning: bool = False  # that fleet is replanning (its roster is changing)
    fleet: tuple[int, ...] = ()  # that roster's members for the plan flown
    away: frozenset[int] = frozenset()  # fleet members no longer flying it
    peer_fleets: Mapping[int, int] = field(default_factory=dict)  # live vehicles' fleet ids
    peer_missions: Mapping[int, int] = field(default_factory=dict)  # live vehicles flying, by id


def _voting_fleet(fleets: Mapping[int, int]) -> int | None:
    """Which flying fleet votes: the one flying the most vehicles (ties: the lower
    mission id); None when no fleet flies."""
    return min(fleets, key=lambda m: (-fleets[m], m), default=None)


def _addressed(sel: Selector, fleet_id: int) -> bool:
    return sel.fleet_id == 0 or fleet_id == sel.fleet_id


# --------------------------------------------------------------------------- outputs


@dataclass(frozen=True)
class Elected:
    """The vote decided (the same on every vehicle). `mission` is the QUANTITY mission as
    its fleet flies it: selected by the winners' ids."""

    mission: Mission
    outcome: BallotOutcome
    home: int | None  # the mission the electorate flew (None: idle vehicles)
    goes: bool  # this vehicle is a winner


@dataclass(frozen=True)
class VoteFailed:
    mission_id: int
    home: int | None
    reason: str


@dataclass(frozen=True)
class Derived:
    """A target report's mission: handle it as a received QUANTITY mission."""

    mission: Mission


TaskingOutput = Publish | Note | Elected | VoteFailed | Derived
TaskingInput = Vote | VoterLost | TargetReport


# --------------------------------------------------------------------------- the module


@dataclass
class _Running:
    mission: Mission
    ballot: Ballot
    home: int | None
    terms: Terms


@dataclass
class _Target:
    report: TargetReport
    mission_id: int
    xy_frame: LocalFrame
    due_s: float | None  # gathering until then (None: tasked)
    until_s: float


@dataclass
class Tasking:
    self_id: int
    settings: TaskingSettings = field(default_factory=TaskingSettings)
    profiles: Mapping[int, VehicleProfile] = field(default_factory=dict)
    ballots: OrderedDict[int, _Running] = field(default_factory=OrderedDict)
    targets: OrderedDict[int, _Target] = field(default_factory=OrderedDict)
    counts: Counter[str] = field(default_factory=Counter)
    outcomes: OrderedDict[int, BallotOutcome] = field(default_factory=OrderedDict)

    # ------------------------------------------------------------------ quantity missions
    @property
    def voting(self) -> int | None:
        """The mission this vehicle is voting for (undecided), if any."""
        for mid, r in self.ballots.items():
            if r.ballot.outcome is None and r.ballot.failed is None:
                return mid
        return None

    def answer(self, mission: Mission, st: Standing) -> tuple[AckReason, str]:
        """Whether this vehicle is a candidate for a QUANTITY mission, and why not."""
        sel = mission.selection
        busy = self.voting
        if busy is not None and busy != mission.mission_id:
            return AckReason.BUSY, f"voting for mission {busy}"
        try:
            payload_wanted(sel.payload_model, self.settings.payload_classes)
        except ScoreError as exc:
            return AckReason.INVALID, short_text(str(exc))
        fleets = Counter(
            m
            for v, m in st.peer_missions.items()
            if m != mission.mission_id and _addressed(sel, st.peer_fleets.get(v, 0))
        )
        if st.flying is not None:
            if st.replanning:
                return AckReason.BUSY, f"replanning mission {st.flying}"
            fleets[st.flying] += 1
        voters = _voting_fleet(fleets)
        if st.flying is not None:
            if voters != st.flying:
                return AckReason.NOT_ADDRESSED, f"the fleet of mission {voters} votes"
            return AckReason.OK, ""
        if st.idle:
            if voters is not None:
                return AckReason.NOT_ADDRESSED, f"the fleet of mission {voters} votes"
            return AckReason.OK, ""
        return AckReason.BUSY, "on another mission or returning"

    @staticmethod
    def electorate(mission: Mission, st: Standing) -> tuple[frozenset[int], frozenset[int]]:
        """A flying fleet's electorate and the members it need not wait for."""
        sel = mission.selection
        members = {st.self_id} | {
            v for v in st.fleet if sel.fleet_id == 0 or st.peer_fleets.get(v) == sel.fleet_id
        }
        return frozenset(members), frozenset(st.away & members) - {st.self_id}

    def start(
        self,
        mission: Mission,
        electorate: Iterable[int],
        lost: Iterable[int],
        me: Candidate,
        now: float,
        *,
        home: int | None,
        lead: LatLon | None = None,
    ) -> list[TaskingOutput]:
        """Start voting for `mission`: score ourselves, send our first vote."""
        mid = mission.mission_id
        if mid in self.ballots:
            return []
        terms = mission_terms(self.settings.score, mission, me, self.settings.payload_classes, lead)
        ballot = Ballot(
            mid,
            self.self_id,
            frozenset(electorate),
            mission.selection.quantity,
            terms.score,
            now,
            self.settings.ballot,
            lost=set(lost),
        )
        self.ballots[mid] = _Running(mission, ballot, home, terms)
        note = Note(
            logging.INFO,
            f"mission {mid}: voting among {sorted(ballot.electorate)} for "
            f"{mission.selection.quantity}; our score {terms.score:.4f} (payload "
            f"{terms.payload:g}, time {terms.time:.3f}, battery {terms.battery:.2f})",
        )
        return [note, *self._ballot_out(self.ballots[mid], ballot.on_timer(now), now)]

    def handle(self, event: TaskingInput, now: float) -> list[TaskingOutput]:
        """A vote, a voter the roster lost, a target report."""
        if isinstance(event, Vote):
            return self.on_vote(event, now)
        if isinstance(event, VoterLost):
            return self.voter_lost(event.vehicle_id, now)
        return self.on_target(event, now)

    def on_vote(self, vote: Vote, now: float) -> list[TaskingOutput]:
        r = self.ballots.get(vote.mission_id)
        if r is None:
            self.counts["vote_unknown_mission"] += 1
            return []
        return self._ballot_out(r, r.ballot.handle(vote, now), now)

    def voter_lost(self, vid: int, now: float) -> list[TaskingOutput]:
        out: list[TaskingOutput] = []
        for r in list(self.ballots.values()):
            if vid in r.ballot.electorate:
                out += self._ballot_out(r, r.ballot.handle(VoterLost(vid), now), now)
        return out

    def _ballot_out(self, r: _Running, outs: list, now: float) -> list[TaskingOutput]:
        out: list[TaskingOutput] = []
        mid = r.mission.mission_id
        for o in outs:
            if isinstance(o, SendVote):
                out.append(Publish(o.vote))
            elif isinstance(o, Decided):
                oc = o.outcome
                self.outcomes[mid] = oc
                while len(self.outcomes) > 16:
                    self.outcomes.popitem(last=False)
                goes = oc.goes(self.self_id)
                scores = ", ".join(f"{s.vehicle_id}: {s.score:.4f}" for s in oc.scores)
                out.append(
                    Note(
                        logging.INFO,
                        f"mission {mid}: vote decided, winners {list(oc.winners)} ({scores})",
                    )
                )
                if goes:
                    out.append(
                        Publish(
                            Alert(
                                self.self_id,
                                max(0.0, now),
                                Severity.INFO,
                                AlertCode.GENERIC,
                                short_text(f"chosen for mission {mid}, score {r.terms.score:.4f}"),
                            )
                        )
                    )
                flown = msgspec.structs.replace(r.mission, selection=Selector.ids(*oc.winners))
                out.append(Elected(flown, oc, r.home, goes))
            elif isinstance(o, Failed):
                text = f"vote for mission {mid} failed: {o.reason}"
                out += [
                    Note(logging.WARNING, text),
                    Publish(
                        Alert(
                            self.self_id,
                            max(0.0, now),
                            Severity.WARNING,
                            AlertCode.MISSION_FAILED,
                            short_text(text),
                        )
                    ),
                    VoteFailed(mid, r.home, o.reason),
                ]
        return out

    def cancel(self, mission_id: int) -> None:
        """Forget a ballot (its mission was dropped)."""
        self.ballots.pop(mission_id, None)

    # ------------------------------------------------------------------ targets
    def on_target(self, report: TargetReport, now: float) -> list[TaskingOutput]:
        rules = self.settings.rules
        mid = target_mission_id(report.source_id, report.target_id)
        if mid in self.targets:
            self.counts["target_repeat"] += 1
            return []
        count, min_conf = rules.rule(report.target_class)
        if count == 0:
            self.counts["target_no_rule"] += 1
            return self._once(
                "target_no_rule", f"target {report.target_class!r}: no re-tasking rule"
            )
        if report.confidence < min_conf:
            self.counts["target_low_confidence"] += 1
            return []
        lat, lon = report.position.lat_deg, report.position.lon_deg
        here = _Target(report, mid, LocalFrame(lat, lon), now + rules.hold_s, now + rules.keep_s)
        for other in self.targets.values():
            if other.report.target_class != report.target_class:
                continue
            x, y = other.xy_frame.to_local(lat, lon)
            if math.hypot(x, y) > rules.dedup_radius_m:
                continue
            self.counts["target_duplicate"] += 1
            if other.due_s is not None and _earlier(report, other.report):
                # still gathering: the earliest report of the target is the one tasked
                here.due_s = other.due_s
                other.due_s = None
                other.until_s = now + rules.keep_s
                self.targets[mid] = here
                return [
                    Note(
                        logging.INFO,
                        f"target report {report.source_id}/{report.target_id}"
                        f" replaces {other.report.source_id}/{other.report.target_id}",
                    )
                ]
            here.due_s = None  # remembered as a duplicate (a repeat stays one)
            self.targets[mid] = here
            return [
                Note(
                    logging.INFO,
                    f"target report {report.source_id}/{report.target_id} "
                    f"is a duplicate of mission {other.mission_id}",
                )
            ]
        self.targets[mid] = here
        return []

    def _once(self, key: str, text: str) -> list[TaskingOutput]:
        return [Note(logging.INFO, text)] if self.counts[key] == 1 else []

    # ------------------------------------------------------------------ time
    def next_deadline(self) -> float | None:
        ds = [d for r in self.ballots.values() if (d := r.ballot.next_deadline()) is not None]
        ds += [t.due_s for t in self.targets.values() if t.due_s is not None]
        return min(ds, default=None)

    def on_timer(self, now: float) -> list[TaskingOutput]:
        out: list[TaskingOutput] = []
        for r in list(self.ballots.values()):
            d = r.ballot.next_deadline()
            if d is not None and d <= now:
                out += self._ballot_out(r, r.ballot.on_timer(now), now)
        for mid in [m for m, r in self.ballots.items() if r.ballot.done]:
            del self.ballots[mid]
        for t in list(self.targets.values()):
            if t.due_s is not None and t.due_s <= now:
                t.due_s = None
                count, _ = self.settings.rules.rule(t.report.target_class)
                mission = target_mission(t.report, self.settings.rules, self.profiles, count)
                out.append(
                    Note(
                        logging.INFO,
                        f"target {t.report.target_class!r} reported by "
                        f"{t.report.source_id}: mission {mission.mission_id} for {count}",
                    )
                )
                out.append(Derived(mission))
        for mid in [m for m, t in self.targets.items() if t.due_s is None and t.until_s <= now]:
            del self.targets[mid]
        return out


def _earlier(a: TargetReport, b: TargetReport) -> bool:
    return (a.time_unix_s, a.source_id, a.target_id) < (b.time_unix_s, b.source_id, b.target_id)
