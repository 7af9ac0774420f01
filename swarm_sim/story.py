"""The paper's experiment 1 as a ground-station script: a pure core that hears what a
ground station hears (VehicleStatus, VehicleInfo, Alert, Ack, Vote) and says what the
operator does next. The demo (`swarm-sim demo`, demo.py) runs it against real
processes; `fly_fast` runs the same script against FastFleet (tests, development).

    UP       every vehicle has a GPS fix and a home
    BASE     set the base (every vehicle activates: STATE_GO_MISSION)
    ZONES    declare the no-fly zones (every vehicle acknowledges each)
    AREA     an area survey for every vehicle (one fleet, split on board)
    LAUNCH   every vehicle in the air on its share (take-off deconflicted by the nodes)
    SURVEY   at `target_at_pct` of the survey a vehicle's camera reports a person
    VOTE     the fleet votes who goes (the database's rule: 2 for a person)
    REPLAN   the others re-split the area
    FAIL     after `fail_after_s` one of them fails (node and aircraft gone)
    INHERIT  the survivors share out its rest
    FINISH   the survivors finish the survey; the target's pair then patrols a perimeter
             and flies a route (each time meeting at its entry points: PREMISSION)
    HOME     every vehicle returns to its pad and lands
    DONE

A vehicle of ours in STATE_EMERGENCY (a no-fly zone entered, a link lost, a battery
critical) ends the story there, failed, with the vehicle's critical alert: the demo
says what went wrong when it happens, not at a phase's timeout minutes later.

The core: `handle(msg, now)` and `on_timer(now)` return actions (`Send`, `Fail`, `Say`,
`Finished`); `next_deadline()`; time in simulated seconds, never read. What happened
is kept in `record` (the report's source: missions, completions, votes, replans)."""

from __future__ import annotations

import enum
import functools
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import msgspec

from swarm_node.core.mission.tasking import target_mission_id
from swarm_node.core.planning.geo import LocalFrame
from swarm_proto import (
    Ack,
    AckRef,
    Alert,
    AlertCode,
    Command,
    CommandArgs,
    CommandKind,
    FsmState,
    Geometry,
    GeometryKind,
    GeoPoint,
    LatLon,
    Mission,
    MissionParams,
    MissionState,
    MissionType,
    NoFlyZone,
    Selector,
    Severity,
    TargetReport,
    TargetSource,
    VehicleInfo,
    VehicleStatus,
    Vote,
)

GCS_ID = 900
AREA_ID = 101
PERIMETER_ID = 103
ROUTE_ID = 104
TARGET_ID = 1  # the report's id (the target mission's id is derived from it)
LANDED_M = 3.0  # a vehicle this low above home, disarmed, is on the ground
TARGET_WAIT_S = 20.0  # the pair's second watches the target at most this much longer

Heard = VehicleStatus | VehicleInfo | Alert | Ack | Vote


# --------------------------------------------------------------------------- the plan


@dataclass(frozen=True)
class StoryPlan:
    """What the operator will do: the vehicles, the places, when."""

    members: tuple[int, ...]
    origin: tuple[float, float]  # the first pad (lat, lon): everything is placed from it
    area: Geometry
    zones: tuple[NoFlyZone, ...]
    target: tuple[float, float]
    perimeter: Geometry
    route: Geometry
    reporter: int  # whose camera reports the target
    area_alt_m: float = 80.0
    # each member of the survey at its own height, this far above the one before (the
    # planner's altitude_step_m): planned lanes and replanned shares cross, and a turning
    # aircraft is seen late by avoidance's straight-line prediction (a demo run came
    # within 2.8 m at one height); lanes are spaced for the lowest camera
    area_layer_m: float = 10.0
    side_overlap: float = 0.5
    # the target's pair patrols the perimeter and flies the route above the survey's
    # layers (80 m up to 80 + 10 x 5 for six), as an operator gives missions that cross
    # each other their own altitude blocks: the pair's leg to the perimeter crosses the
    # whole field while the survivors still survey it, and avoidance predicts a turning
    # fixed-wing straight on (at 100 m a run's leg met a surveying member at its lane
    # end: a CRITICAL 'too slow' climb 3 s ahead)
    perimeter_alt_m: float = 140.0
    route_alt_m: float = 140.0
    # the pair flies the perimeter and the route together (one PREMISSION meet, the same
    # final loiter): layered further apart than avoidance's conflict distance (20 m), or
    # they would fly the whole mission as a conflict, and end it stacked over one point
    layer_m: float = 30.0
    target_class: str = "person"
    target_at_pct: int = 15  # the survey's progress (its slowest member) at the report
    fail_after_s: float = 20.0  # the stayers fly their new shares this long before one fails
    victim: int | None = None  # who fails (None: the stayer with the highest id)
    repeat_s: float = 5.0  # unanswered messages are sent again this often
    planning_s: float = 300.0  # a step that waits for a plan is allowed this much more
    # the next missions: who flies them (None: the target's pair)
    perimeter_by: tuple[int, ...] | None = None
    route_by: tuple[int, ...] | None = None

    @classmethod
    def experiment_one(
        cls,
        members: Sequence[int],
        origin: tuple[float, float],
        *,
        scale: float = 1.0,
        **kw: object,
    ) -> StoryPlan:
        """The places, north of pads going east from `origin`: a 1000 x 700 m field
        1 km north with a no-fly zone in it, the target 250 m east of the field, a
        400 m square perimeter west of it and a route north of it past a second zone
        (every distance times `scale`: a shorter story for tests)."""
        f = LocalFrame(*origin)

        def at(east: float, north: float) -> tuple[float, float]:
            return f.to_geodetic(east * scale, north * scale)

        def poly(*pts: tuple[float, float]) -> Geometry:
            return Geometry.polygon([at(e, n) for e, n in pts])

        area = poly((-425, 650), (575, 650), (575, 1350), (-425, 1350))
        zone1 = NoFlyZone(
            1,
            Geometry.circle(*at(250, 1050), 60.0 * scale),
            floor_alt_msl_m=-100.0,
            ceiling_alt_msl_m=1000.0,
            name="field zone",
        )
        zone2 = NoFlyZone(
            2,
            Geometry.circle(*at(75, 1760), 80.0 * scale),
            floor_alt_msl_m=-100.0,
            ceiling_alt_msl_m=1000.0,
            name="route zone",
        )
        perimeter = poly((-1150, 800), (-750, 800), (-750, 1200), (-1150, 1200))
        route = Geometry(
            GeometryKind.POLYLINE,
            tuple(LatLon(*at(e, n)) for e, n in ((-500, 1700), (650, 1800), (1150, 1300))),
        )
        members = tuple(members)
        kw.setdefault("reporter", members[len(members) // 2])
        return cls(members, origin, area, (zone1, zone2), at(825, 1000), perimeter, route, **kw)  # type: ignore[arg-type]

    @property
    def target_mission_id(self) -> int:
        return target_mission_id(self.reporter, TARGET_ID)

    def area_mission(self, now: float) -> Mission:
        params = MissionParams(
            altitude_rel_m=self.area_alt_m,
            side_overlap=self.side_overlap,
            altitude_step_m=self.area_layer_m,
        )
        return Mission(
            AREA_ID,
            GCS_ID,
            MissionType.AREA,
            self.area,
            params,
            Selector.ids(*self.members),
            "survey",
            max(0.0, now),
        )

    def perimeter_mission(self, ids: Sequence[int], now: float) -> Mission:
        params = MissionParams(
            altitude_rel_m=self.perimeter_alt_m, loops=1, altitude_step_m=self.layer_m
        )
        return Mission(
            PERIMETER_ID,
            GCS_ID,
            MissionType.PERIMETER,
            self.perimeter,
            params,
            Selector.ids(*ids),
            "perimeter",
            max(0.0, now),
        )

    def route_mission(self, ids: Sequence[int], now: float) -> Mission:
        params = MissionParams(altitude_rel_m=self.route_alt_m, altitude_step_m=self.layer_m)
        return Mission(
            ROUTE_ID,
            GCS_ID,
            MissionType.ROUTE,
            self.route,
            params,
            Selector.ids(*ids),
            "route",
            max(0.0, now),
        )


# --------------------------------------------------------------------------- actions


@dataclass(frozen=True)
class Send:
    msg: msgspec.Struct


@dataclass(frozen=True)
class Fail:
    """Make a vehicle's node fail (its companion computer dies): its aircraft flies on as
    it was told, then its autopilot's GCS failsafe takes it home (docs/reliability.md)."""

    vehicle_id: int


@dataclass(frozen=True)
class Say:
    text: str


@dataclass(frozen=True)
class Finished:
    ok: bool
    why: str


Action = Send | Fail | Say | Finished


class Phase(enum.Enum):
    UP = "up"
    BASE = "base"
    ZONES = "zones"
    AREA = "area"
    LAUNCH = "launch"
    SURVEY = "survey"
    VOTE = "vote"
    REPLAN = "replan"
    FAIL = "fail"
    INHERIT = "inherit"
    FINISH = "finish"
    HOME = "home"
    DONE = "done"


# how long each phase may take (simulated s), `planning_s` more where a plan is made
LIMIT_S: dict[Phase, tuple[float, bool]] = {
    Phase.UP: (300.0, False),
    Phase.BASE: (120.0, False),
    Phase.ZONES: (120.0, False),
    Phase.AREA: (120.0, False),
    Phase.LAUNCH: (600.0, True),
    Phase.SURVEY: (1200.0, False),
    Phase.VOTE: (300.0, True),
    Phase.REPLAN: (600.0, True),
    Phase.FAIL: (600.0, False),
    Phase.INHERIT: (600.0, True),
    Phase.FINISH: (3600.0, True),
    Phase.HOME: (1800.0, False),
}


# --------------------------------------------------------------------------- the record


@dataclass
class MissionRecord:
    mission_id: int
    kind: str
    sent_at: float | None = None  # None: derived by the vehicles (a target)
    flew: set[int] = field(default_factory=set)  # vehicles whose VehicleInfo showed it
    left: set[int] = field(default_factory=set)  # moved on to another mission unfinished
    completed: dict[int, float] = field(default_factory=dict)  # vehicle -> when

    def expected(self, failed: set[int]) -> set[int]:
        return self.flew - self.left - failed

    def done(self, failed: set[int]) -> bool:
        want = self.expected(failed)
        return bool(want) and want <= set(self.completed)


@dataclass
class Record:
    """What happened, for the report: in simulated seconds since `t0`."""

    t0: float | None = None
    steps: list[tuple[float, str]] = field(default_factory=list)
    missions: dict[int, MissionRecord] = field(default_factory=dict)
    votes: dict[int, dict[int, Vote]] = field(default_factory=dict)  # mission -> voter -> vote
    chosen: dict[int, dict[int, str]] = field(default_factory=dict)  # mission -> winner -> text
    replans: list[tuple[float, int, int, str]] = field(
        default_factory=list
    )  # t, mission, vid, phase
    failed: dict[int, float] = field(default_factory=dict)
    alerts: list[tuple[float, Alert]] = field(default_factory=list)
    winners: tuple[int, ...] = ()
    stayers: tuple[int, ...] = ()
    survivors: tuple[int, ...] = ()
    landed: set[int] = field(default_factory=set)
    outcome: str = ""

    def rel(self, now: float) -> float:
        return now - (self.t0 if self.t0 is not None else now)


@dataclass
class _Outstanding:
    """A message sent until everyone it addresses has answered."""

    msg: msgspec.Struct
    ref: AckRef
    ref_id: int
    addressed: frozenset[int]
    last_sent: float


# --------------------------------------------------------------------------- the story


class Story:
    def __init__(self, plan: StoryPlan, now: float) -> None:
        self.plan = plan
        self.phase = Phase.UP
        self.since = now
        self.status: dict[int, VehicleStatus] = {}
        self.info: dict[int, VehicleInfo] = {}
        self.acks: dict[tuple[AckRef, int], dict[int, Ack]] = {}
        self.record = Record()
        self.outstanding: list[_Outstanding] = []
        self._replanning: dict[int, float] = {}  # vehicle -> when last seen in REPLAN
        self._last_mission: dict[int, int] = {}  # vehicle -> last positive mission id
        self._mark = now  # when the current wait began (REPLAN: the stayers flying)
        self._finish_sent: set[int] = set()
        self._base_seq = 1
        self.finished: Finished | None = None
        self._airborne: set[int] = set()  # members seen armed

    # ------------------------------------------------------------------ views
    @property
    def members(self) -> tuple[int, ...]:
        return self.plan.members

    @property
    def alive(self) -> list[int]:
        return [m for m in self.members if m not in self.record.failed]

    @property
    def surveyors(self) -> list[int]:
        """The alive members that fly the survey: not those the fleet's plan gave no
        share (they completed it on the ground: an area beyond a quadcopter's battery,
        a boat's speed adding nothing), who stay down for the rest of the story."""
        return [v for v in self.alive if not self._stood_by(v)]

    def _stood_by(self, vid: int) -> bool:
        rec = self.record.missions.get(AREA_ID)
        return rec is not None and vid in rec.completed and vid not in self._airborne

    def _flying_share(self, vid: int, mission_id: int) -> bool:
        s, i = self.status.get(vid), self.info.get(vid)
        return (
            s is not None
            and i is not None
            and i.mission_id == mission_id
            and s.mission_state in (MissionState.PREMISSION, MissionState.MISSION)
            and s.armed
        )

    def _landed(self, vid: int) -> bool:
        s = self.status.get(vid)
        return (
            s is not None
            and not s.armed
            and s.alt_rel_m < LANDED_M
            and s.fsm_state == FsmState.INACTIVE
        )

    def _completed(self, mission_id: int, ids: Sequence[int]) -> bool:
        rec = self.record.missions.get(mission_id)
        return rec is not None and bool(ids) and set(ids) <= set(rec.completed)

    def _mission(self, mission_id: int, kind: str) -> MissionRecord:
        return self.record.missions.setdefault(mission_id, MissionRecord(mission_id, kind))

    # ------------------------------------------------------------------ inputs
    def handle(self, msg: Heard, now: float) -> list[Action]:
        if isinstance(msg, VehicleStatus):
            self._on_status(msg, now)
        elif isinstance(msg, VehicleInfo):
            self._on_info(msg)
        elif isinstance(msg, Alert):
            self._on_alert(msg, now)
        elif isinstance(msg, Ack):
            if msg.issuer_id == GCS_ID or msg.ref == AckRef.MISSION:
                self.acks.setdefault((msg.ref, msg.ref_id), {}).setdefault(msg.vehicle_id, msg)
        elif isinstance(msg, Vote):
            votes = self.record.votes.setdefault(msg.mission_id, {})
            old = votes.get(msg.voter_id)
            if old is None or msg.committed or not old.committed:
                votes[msg.voter_id] = msg
        return self.on_timer(now)

    def _on_status(self, s: VehicleStatus, now: float) -> None:
        if s.vehicle_id not in self.members:
            return
        self.status[s.vehicle_id] = s
        if s.armed:
            self._airborne.add(s.vehicle_id)
        if s.mission_state == MissionState.REPLAN:
            if s.vehicle_id not in self._replanning or now - self._replanning[s.vehicle_id] > 2.0:
                mid = self._last_mission.get(s.vehicle_id, 0)
                self.record.replans.append(
                    (self.record.rel(now), mid, s.vehicle_id, self.phase.value)
                )
            self._replanning[s.vehicle_id] = now

    def _on_info(self, i: VehicleInfo) -> None:
        if i.vehicle_id not in self.members:
            return
        self.info[i.vehicle_id] = i
        mid = i.mission_id
        if mid > 0:
            before = self._last_mission.get(i.vehicle_id)
            if before is not None and before != mid:
                old = self.record.missions.get(before)
                if old is not None and i.vehicle_id not in old.completed:
                    old.left.add(i.vehicle_id)
            self._last_mission[i.vehicle_id] = mid
            kind = "target" if mid == self.plan.target_mission_id else "mission"
            self._mission(mid, kind).flew.add(i.vehicle_id)

    def _on_alert(self, a: Alert, now: float) -> None:
        self.record.alerts.append((self.record.rel(now), a))
        if a.code == AlertCode.MISSION_COMPLETE and a.text.startswith("mission "):
            try:
                mid = int(a.text.split()[1])
            except (IndexError, ValueError):
                return
            self._mission(mid, "mission").completed.setdefault(a.vehicle_id, self.record.rel(now))
        elif a.text.startswith("chosen for mission "):
            try:
                mid = int(a.text.split()[3].rstrip(","))
            except (IndexError, ValueError):
                return
            self.record.chosen.setdefault(mid, {})[a.vehicle_id] = a.text

    # ------------------------------------------------------------------ sending
    def _send(
        self, msg: msgspec.Struct, ref: AckRef, ref_id: int, addressed: Sequence[int], now: float
    ) -> list[Action]:
        self.outstanding.append(_Outstanding(msg, ref, ref_id, frozenset(addressed), now))
        return [Send(msg)]

    def _answered(
        self, ref: AckRef, ref_id: int, ids: Sequence[int], accepted: bool = True
    ) -> bool:
        got = self.acks.get((ref, ref_id), {})
        return all(v in got and (got[v].accepted or not accepted) for v in ids)

    def _repeats(self, now: float) -> list[Action]:
        out: list[Action] = []
        keep = []
        for o in self.outstanding:
            want = o.addressed - set(self.record.failed)
            got = self.acks.get((o.ref, o.ref_id), {})
            if want <= set(got):
                continue
            keep.append(o)
            if now - o.last_sent >= self.plan.repeat_s:
                o.last_sent = now
                out.append(Send(o.msg))
        self.outstanding = keep
        return out

    # ------------------------------------------------------------------ timers
    def next_deadline(self) -> float:
        due = [o.last_sent + self.plan.repeat_s for o in self.outstanding]
        if self.phase == Phase.FAIL:
            due.append(self._mark + self.plan.fail_after_s)
        limit, planned = LIMIT_S.get(self.phase, (math.inf, False))
        due.append(self.since + limit + (self.plan.planning_s if planned else 0.0))
        return min(due)

    def on_timer(self, now: float) -> list[Action]:
        if self.finished is not None:
            return []
        out = self._repeats(now)
        for _ in range(len(Phase)):  # phases whose condition already holds go on at once
            before = self.phase
            out += self._step(now)
            if self.finished is not None or self.phase == before:
                break
        if self.finished is None:
            limit, planned = LIMIT_S.get(self.phase, (math.inf, False))
            if now - self.since > limit + (self.plan.planning_s if planned else 0.0):
                out += self._finish(False, f"{self.phase.value}: {self._waiting_for()}", now)
        return out

    def _go(self, phase: Phase, now: float) -> None:
        self.phase = phase
        self.since = now
        self.record.steps.append((self.record.rel(now), phase.value))

    def _finish(self, ok: bool, why: str, now: float) -> list[Action]:
        self.finished = Finished(ok, why)
        self.record.outcome = why
        self._go(Phase.DONE, now)
        return [self.finished]

    def _waiting_for(self) -> str:
        """Which vehicles the current phase still waits for (a timeout's message)."""
        late = []
        for v in self.alive:
            s, i = self.status.get(v), self.info.get(v)
            if s is None:
                late.append(f"{v}: not heard")
            else:
                mid = i.mission_id if i else 0
                late.append(
                    f"{v}: {s.fsm_state.name}/{s.mission_state.name} mission {mid} "
                    f"{s.mission_progress_pct}% {s.alt_rel_m:.0f} m"
                )
        return "timed out; " + "; ".join(late)

    # ------------------------------------------------------------------ the script
    def _step(self, now: float) -> list[Action]:
        p, plan, rec = self.plan, self.plan, self.record
        if self.phase not in (Phase.UP, Phase.DONE):
            for v in self.alive:  # the experiment has failed: say why now, not at a timeout
                s = self.status.get(v)
                if s is not None and s.fsm_state == FsmState.EMERGENCY:
                    why = next(
                        (
                            a.text
                            for _, a in reversed(rec.alerts)
                            if a.vehicle_id == v and a.severity >= Severity.CRITICAL
                        ),
                        "",
                    )
                    return self._finish(
                        False,
                        f"{self.phase.value}: vehicle {v} in an "
                        f"emergency{': ' + why if why else ''}",
                        now,
                    )
        match self.phase:
            case Phase.UP:
                up = all(
                    v in self.status
                    and self.status[v].gps_fix >= 3
                    and v in self.info
                    and self.info[v].home is not None
                    for v in self.members
                )
                if not up:
                    return []
                rec.t0 = now
                home = self.info[self.members[0]].home
                assert home is not None
                base = GeoPoint(home.lat_deg, home.lon_deg, home.alt_msl_m)
                self._go(Phase.BASE, now)
                cmd = Command(
                    GCS_ID,
                    self._base_seq,
                    CommandKind.SET_BASE,
                    Selector(),
                    CommandArgs(point=base),
                    max(0.0, now),
                )
                return [
                    Say(
                        f"set the base at vehicle {self.members[0]}'s pad "
                        f"({base.lat_deg:.5f}, {base.lon_deg:.5f}): every vehicle activates"
                    ),
                    *self._send(cmd, AckRef.COMMAND, cmd.seq, self.members, now),
                ]
            case Phase.BASE:
                if not (
                    self._answered(AckRef.COMMAND, self._base_seq, self.members)
                    and all(self.status[v].fsm_state == FsmState.GO_MISSION for v in self.members)
                ):
                    return []
                self._go(Phase.ZONES, now)
                out: list[Action] = [
                    Say(
                        "declare the no-fly zones: "
                        + "; ".join(
                            f"{z.name} ({z.geometry.radius_m or 0:.0f} m circle)" for z in p.zones
                        )
                    )
                ]
                for z in p.zones:
                    out += self._send(
                        msgspec.structs.replace(z, issuer_id=GCS_ID),
                        AckRef.ZONE,
                        z.zone_id,
                        self.members,
                        now,
                    )
                return out
            case Phase.ZONES:
                if not all(self._answered(AckRef.ZONE, z.zone_id, self.members) for z in p.zones):
                    return []
                self._go(Phase.AREA, now)
                m = plan.area_mission(now)
                self._mission(AREA_ID, "area").sent_at = rec.rel(now)
                return [
                    Say(
                        f"send the area survey to vehicles {list(self.members)} "
                        f"({p.area_alt_m:.0f} m above home, {p.side_overlap:.0%} side overlap)"
                    ),
                    *self._send(m, AckRef.MISSION, AREA_ID, self.members, now),
                ]
            case Phase.AREA:
                if not self._answered(AckRef.MISSION, AREA_ID, self.members):
                    got = self.acks.get((AckRef.MISSION, AREA_ID), {})
                    refused = [a for a in got.values() if not a.accepted]
                    if refused:
                        why = ", ".join(f"{a.vehicle_id} {a.reason.name}" for a in refused)
                        return self._finish(False, f"area survey refused: {why}", now)
                    return []
                self._go(Phase.LAUNCH, now)
                return [Say("the fleet plans the survey together and takes off")]
            case Phase.LAUNCH:
                if not all(
                    self._stood_by(v)
                    or (
                        self._flying_share(v, AREA_ID)
                        and self.status[v].mission_state == MissionState.MISSION
                    )
                    for v in self.members
                ):
                    return []
                self._go(Phase.SURVEY, now)
                down = [v for v in self.members if self._stood_by(v)]
                if not down:
                    return [Say(f"all {len(self.members)} vehicles fly their shares of the survey")]
                return [
                    Say(
                        f"{len(self.surveyors)} vehicles fly their shares of the survey; the "
                        f"plan gave {', '.join(map(str, down))} none (beyond their battery "
                        "or adding nothing at their speed): they stay down"
                    )
                ]
            case Phase.SURVEY:
                progress = [self.status[v].mission_progress_pct for v in self.surveyors]
                if min(progress) < p.target_at_pct:
                    return []
                self._go(Phase.VOTE, now)
                lat, lon = p.target
                report = TargetReport(
                    TARGET_ID,
                    p.reporter,
                    TargetSource.PAYLOAD,
                    max(0.0, now),
                    GeoPoint(lat, lon, 0.0),
                    p.target_class,
                    0.93,
                )
                self._mission(p.target_mission_id, "target").sent_at = rec.rel(now)
                return [
                    Say(
                        f"vehicle {p.reporter}'s camera reports a {p.target_class} at "
                        f"{lat:.5f}, {lon:.5f} (confidence 0.93): the swarm's rule sends 2"
                    ),
                    *self._send(report, AckRef.MISSION, p.target_mission_id, self.members, now),
                ]
            case Phase.VOTE:
                tmid = p.target_mission_id
                going = sorted(
                    v
                    for v in self.alive
                    if self.info.get(v) is not None and self.info[v].mission_id == tmid
                )
                if len(going) < 2 and not (going and now - self.since > 60.0):
                    return []
                rec.winners = tuple(going)
                rec.stayers = tuple(v for v in self.surveyors if v not in going)
                self._go(Phase.REPLAN, now)
                return [
                    Say(
                        f"voted out to the target: {', '.join(map(str, going))}; "
                        f"{', '.join(map(str, rec.stayers))} re-split the area"
                    )
                ]
            case Phase.REPLAN:
                if not self._replanned(rec.stayers, rec.steps[-1][0]):
                    return []
                self._mark = now
                self._go(Phase.FAIL, now)
                return [Say(f"the {len(rec.stayers)} stayers fly their new shares")]
            case Phase.FAIL:
                if now - self._mark < p.fail_after_s:
                    return []
                victim = p.victim if p.victim is not None else max(rec.stayers)
                rec.failed[victim] = rec.rel(now)
                rec.survivors = tuple(v for v in rec.stayers if v != victim)
                self._go(Phase.INHERIT, now)
                return [
                    Say(
                        f"vehicle {victim} fails: its companion computer is lost, its "
                        f"failsafe flies it home; {', '.join(map(str, rec.survivors))} "
                        "inherit its share"
                    ),
                    Fail(victim),
                ]
            case Phase.INHERIT:
                if not self._replanned(rec.survivors, rec.steps[-1][0]):
                    return []
                self._go(Phase.FINISH, now)
                return [Say(f"{', '.join(map(str, rec.survivors))} fly the inherited shares")]
            case Phase.FINISH:
                return self._finish_phase(now)
            case Phase.HOME:
                if not all(self._landed(v) for v in self.alive):
                    return []
                rec.landed = set(self.alive)
                return self._finish(True, "every vehicle landed", now)
            case Phase.DONE:
                return []
        return []  # pragma: no cover

    def _replanned(self, ids: Sequence[int], since_rel: float) -> bool:
        """Each of `ids` went through REPLAN since `since_rel` and flies its share again."""
        t0 = self.record.t0 or 0.0
        return all(
            v in self._replanning
            and self._replanning[v] - t0 >= since_rel
            and self._flying_share(v, AREA_ID)
            and self.status[v].mission_state == MissionState.MISSION
            for v in ids
        )

    def _target_watched(self, now: float) -> bool:
        """Both of the pair have flown their share of the target, or one has and the
        other has watched on for TARGET_WAIT_S more: the first is on its way home and
        must get the perimeter before it is landing (a vehicle in its final descent
        refuses a mission BUSY; without avoidance's holding layers one was, 40 s after
        it finished the target)."""
        rec = self.record.missions.get(self.plan.target_mission_id)
        if rec is None or not self.record.winners:
            return False
        done = [rec.completed[v] for v in self.record.winners if v in rec.completed]
        if len(done) == len(self.record.winners):
            return True
        return bool(done) and self.record.rel(now) - min(done) >= TARGET_WAIT_S

    def _finish_phase(self, now: float) -> list[Action]:
        """The target's pair, once it has watched the target, patrols the perimeter and
        then flies the route (each a PREMISSION meet: the pair finishes a mission within
        seconds of each other, so the second is in the air when the next comes); the
        survivors finish the survey. A vehicle that finished early flies home and lands."""
        p, rec = self.plan, self.record
        out: list[Action] = []
        pair = p.perimeter_by or rec.winners
        crew = p.route_by or rec.winners
        if PERIMETER_ID not in self._finish_sent and self._target_watched(now):
            self._finish_sent.add(PERIMETER_ID)
            self._mission(PERIMETER_ID, "perimeter").sent_at = rec.rel(now)
            out += [
                Say(
                    f"target watched: {', '.join(map(str, pair))} patrol the perimeter west "
                    "of the field (they meet at their entry points)"
                )
            ]
            out += self._send(
                p.perimeter_mission(pair, now), AckRef.MISSION, PERIMETER_ID, pair, now
            )
        if ROUTE_ID not in self._finish_sent and self._completed(PERIMETER_ID, pair):
            self._finish_sent.add(ROUTE_ID)
            self._mission(ROUTE_ID, "route").sent_at = rec.rel(now)
            out += [
                Say(
                    f"perimeter patrolled: {', '.join(map(str, crew))} fly the route north "
                    "past the second zone (they meet at their entry points)"
                )
            ]
            out += self._send(p.route_mission(crew, now), AckRef.MISSION, ROUTE_ID, crew, now)
        for mid, ids in ((PERIMETER_ID, pair), (ROUTE_ID, crew)):
            got = self.acks.get((AckRef.MISSION, mid), {})
            refused = [a for v, a in got.items() if v in ids and not a.accepted]
            if refused:
                why = ", ".join(f"{a.vehicle_id} {a.reason.name} {a.text}" for a in refused)
                return out + self._finish(False, f"mission {mid} refused: {why}", now)
        if (
            self._completed(ROUTE_ID, crew)
            and self._completed(AREA_ID, rec.survivors)
            and ROUTE_ID in self._finish_sent
        ):
            self._go(Phase.HOME, now)
            out.append(Say("every mission flown: the vehicles return to their pads and land"))
        return out


# --------------------------------------------------------------------------- fast time


@functools.cache
def seed_mission_defaults() -> dict[MissionType, dict[str, float]]:
    """The seed database's mission parameters (what a node process loads)."""
    from swarm_node.database import SwarmDatabase
    from swarm_node.runtime.node import mission_defaults_of

    with SwarmDatabase.memory() as db:
        return mission_defaults_of(db)


@dataclass
class FastRun:
    story: Story
    fleet: object  # the FastFleet flown
    duration_s: float


def fly_fast(
    plan: StoryPlan,
    profiles: Mapping[int, object],
    *,
    spacing_m: float = 30.0,
    settings: object | None = None,
    timeout_s: float = 7200.0,
    on_step: object | None = None,
    on_message: object | None = None,
    over_air: bool = False,
) -> FastRun:
    """The story against a FastFleet: the ground station hears everything the vehicles
    publish (`on_message(msg, now)` hears it too), its messages reach every vehicle at
    once, `Fail` vanishes a vehicle. `over_air`: every message heard at the radio's
    resolution (`FastFleet.over_air`)."""
    from swarm_node.core.node import NodeSettings

    from .fast_fleet import FastFleet

    # the nodes' defaults (a 60 s plan timeout: the close pads' take-off queue is not
    # counted in it, state_machine.Facts.launch_queued)
    settings = settings or NodeSettings()
    fleet = FastFleet.build(
        list(plan.members),
        profiles,  # type: ignore[arg-type]
        spacing_m=spacing_m,
        settings=settings,  # type: ignore[arg-type]
        mission_defaults=seed_mission_defaults(),
    )
    fleet.over_air = over_air
    t_start = fleet.now
    story = Story(plan, fleet.now)
    seen = 0
    while story.finished is None and fleet.now - t_start < timeout_s:
        fleet.run_for(0.5)
        actions: list[Action] = []
        for _t, _vid, msg in fleet.published[seen:]:
            if isinstance(msg, VehicleStatus | VehicleInfo | Alert | Ack | Vote):
                actions += story.handle(msg, fleet.now)
                if on_message is not None:
                    on_message(msg, fleet.now)  # type: ignore[operator]
        seen = len(fleet.published)
        actions += story.on_timer(fleet.now)
        for a in actions:
            if isinstance(a, Send):
                fleet.broadcast(a.msg)
            elif isinstance(a, Fail):
                fleet.kill_node(a.vehicle_id)
        if on_step is not None:
            on_step(fleet, story, actions)  # type: ignore[operator]
    return FastRun(story, fleet, fleet.now - t_start)
