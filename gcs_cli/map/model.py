"""The live map's view model: what the page shows, folded from what the ground station
hears, with time passed in. No I/O, no clock: the server (server.py) feeds it and
sends what it returns; the tests feed it messages and times.

    model = MapModel(now)
    model.handle(msg, now)   -> [PlanJob]   (a status, info, alert, ack, vote, zone,
                                              mission, liveliness news, a plan made,
                                              a command sent or finished)
    model.on_timer(now)      -> [PlanJob]   (a mission's roster settled: plan its shares)
    model.next_deadline()    -> when to call on_timer again
    model.frame(cursor, now) -> (frame, cursor)   what changed since `cursor`, JSON-able
    model.dismiss(vid, now)                    a LOST vehicle off the map (the operator's)

`now` is any monotonic time in seconds (the server's `time.monotonic()`, the replay's
time): link age, packets per second and trails are counted on it. A frame carries the
vehicles that changed, every vehicle's link (age, packets/s, lost), the trail points
and alerts that are new, and the zones, missions, vote and commands when they changed;
cursor 0 gives everything (a page that just connected).

A vehicle heard flying and not heard for `HEARD_ALIVE_S` is LOST: its link carries its
last position, its age and its predicted position (gcs_cli/core/lost.py) until it is
heard again, its last report says it landed, or the operator dismisses it (`dismiss`:
off the map, listed in the frame's `dismissed`, back if it is heard again).

Each mission's shares are each member's part of the plan, as the members plan it: when
a mission's roster (the vehicles whose VehicleInfo says they fly it) has stood still
for `SETTLE_S`, the model asks for a plan (`PlanJob`) and the shell runs the nodes'
planner (as `gcs plot` does) and hands back `PlanDone`. A roster that grows (a vehicle
joins) is planned again; one that shrinks keeps the first plan, the lost member's share
marked.
"""

from __future__ import annotations

from collections import Counter, deque
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Any

from gcs_cli.core.lost import NotLostError, finite_id, landed, lost_fields
from gcs_cli.core.reasons import alert_text, reason_text
from swarm_node.core.mission.voting import rank, score_key
from swarm_node.core.monitoring import SPECS
from swarm_proto import (
    Ack,
    AckReason,
    AckRef,
    Alert,
    AlertCode,
    AlertFlag,
    FsmState,
    Geometry,
    GeometryKind,
    GeoPoint,
    Mission,
    NoFlyZone,
    Selector,
    SelectorKind,
    Severity,
    VehicleInfo,
    VehicleStatus,
    VehicleType,
    Vote,
)
from swarm_proto.ardupilot import autopilot_mismatch, mode_name

TRAIL_S = 300.0  # trails: the last five minutes
TRAIL_STEP_S = 1.0  # one trail point a second per vehicle
HEARD_ALIVE_S = 5.0  # not heard for longer: lost (as the ground station counts alive)
RATE_WINDOW_S = 2.0  # packets per second counted over this window (as `gcs watch`)
SETTLE_S = 2.0  # a mission's roster unchanged this long: its shares are planned
ALERTS_KEPT = 200
COMMANDS_KEPT = 20
FLYING = (FsmState.PLAN, FsmState.GO_MISSION)

# the SYS_STATUS sensor bits the flight display shows (as `gcs vehicle`)
SENSORS = {
    "gyro": 1 << 0,
    "accel": 1 << 1,
    "compass": 1 << 2,
    "baro": 1 << 3,
    "airspeed": 1 << 4,
    "gps": 1 << 5,
}


# ----------------------------------------------------------------------------- inputs


@dataclass(frozen=True)
class Alive:
    """Liveliness news: a node's token came or went."""

    node_id: int
    alive: bool


@dataclass(frozen=True)
class PlanDone:
    """The shares of a mission's plan (lat, lon points per member), or why none."""

    mission_id: int
    members: tuple[int, ...]
    shares: dict[int, list[tuple[float, float]]] = field(default_factory=dict)
    error: str = ""


@dataclass(frozen=True)
class CommandSent:
    """The page's request, confirmed, is being sent through the exchange core."""

    cid: int
    what: str  # "rtl", "mission 12 (area)", "zone 3"
    question: str  # the confirmation the operator accepted, naming the vehicles


@dataclass(frozen=True)
class CommandRef:
    """What answers it carry (the exchange's request, once it is made): the Acks that
    answer it are shown as they arrive."""

    cid: int
    ref: AckRef
    ref_id: int
    issuer_id: int


@dataclass(frozen=True)
class CommandDone:
    """The exchange's outcome (answers.outcome_json) and its summary line."""

    cid: int
    outcome: dict[str, Any]
    summary: str


@dataclass(frozen=True)
class CommandFailed:
    cid: int
    error: str


Message = (
    VehicleStatus
    | VehicleInfo
    | Alert
    | Ack
    | Vote
    | NoFlyZone
    | Mission
    | Alive
    | PlanDone
    | CommandSent
    | CommandRef
    | CommandDone
    | CommandFailed
)

# ----------------------------------------------------------------------------- outputs


@dataclass(frozen=True)
class PlanJob:
    """Plan `mission` for `members` (ids, sorted) posed at `homes`, as its members do
    (the shell reads their profiles from the swarm database)."""

    mission: Mission
    members: tuple[int, ...]
    homes: dict[int, GeoPoint]
    battery_pct: dict[int, float]
    zones: tuple[NoFlyZone, ...]


# ----------------------------------------------------------------------------- state


@dataclass
class _Vehicle:
    vid: int
    status: VehicleStatus | None = None
    info: VehicleInfo | None = None
    heard_at: float | None = None
    alive: bool = False
    arrivals: deque[float] = field(default_factory=lambda: deque(maxlen=64))
    trail: deque[tuple[int, float, float, float]] = field(default_factory=deque)
    severity: dict[AlertCode, Severity] = field(default_factory=dict)
    changed: int = 0


@dataclass
class _Plan:
    roster: tuple[int, ...] = ()  # the members seen now
    since: float = 0.0  # ... since then
    asked: tuple[int, ...] = ()  # the roster a plan was asked for
    members: tuple[int, ...] = ()  # the roster of the shares held
    shares: dict[int, list[tuple[float, float]]] = field(default_factory=dict)
    error: str = ""


@dataclass
class _Command:
    sent: CommandSent
    ref: CommandRef | None = None
    answers: dict[int, Ack] = field(default_factory=dict)
    done: CommandDone | None = None
    error: str = ""


def worst_severity(status: VehicleStatus, heard: dict[AlertCode, Severity]) -> Severity | None:
    """The most severe of a vehicle's active conditions (its status's alert bits): the
    severity its last Alert of that code said, else the node's own rule for the
    condition (monitoring.SPECS: armed or on the ground), else WARNING."""
    worst: Severity | None = None
    for flag in AlertFlag:
        if not flag or flag not in status.alerts or flag.name is None:
            continue
        code = AlertCode[flag.name]
        spec = SPECS.get(code)
        rule = (
            (spec.armed_severity if status.armed else spec.ground_severity)
            if spec is not None
            else Severity.WARNING
        )
        sev = heard.get(code, rule)
        if worst is None or sev > worst:
            worst = sev
    return worst


def _r(x: float, nd: int = 1) -> float:
    return round(float(x), nd)


def _point(p: GeoPoint | None) -> list[float] | None:
    return None if p is None else [_r(p.lat_deg, 7), _r(p.lon_deg, 7), _r(p.alt_msl_m)]


def geometry_json(g: Geometry) -> dict[str, Any]:
    """A geometry as the page draws it: kind, [lat, lon] points, holes, radius."""
    out: dict[str, Any] = {
        "kind": g.kind.name.lower(),
        "points": [[p.lat_deg, p.lon_deg] for p in g.points],
    }
    if g.holes:
        out["holes"] = [[[p.lat_deg, p.lon_deg] for p in h] for h in g.holes]
    if g.kind == GeometryKind.CIRCLE:
        out["radius_m"] = g.radius_m
    return out


def selection_text(sel: Selector) -> str:
    match sel.kind:
        case SelectorKind.IDS:
            return "vehicles " + ", ".join(map(str, sel.vehicle_ids))
        case SelectorKind.FLEET:
            return f"fleet {sel.fleet_id}"
        case SelectorKind.QUANTITY:
            of = f" of fleet {sel.fleet_id}" if sel.fleet_id else ""
            return f"{sel.quantity} chosen by voting{of}"
        case _:
            return "every vehicle"


class MapModel:
    def __init__(
        self, now: float, *, trail_s: float = TRAIL_S, gcs_id: int = 900, mode: str = "live"
    ) -> None:
        self.t0 = now
        self.trail_s = trail_s
        self.gcs_id = gcs_id
        self.mode = mode
        self.seq = 0
        self.vehicles: dict[int, _Vehicle] = {}
        self.ground: set[int] = set()  # ground stations heard (not drawn)
        self.alerts: deque[tuple[int, float, Alert]] = deque(maxlen=ALERTS_KEPT)
        self.zones: dict[int, NoFlyZone] = {}
        self.missions: dict[int, Mission] = {}
        self.plans: dict[int, _Plan] = {}
        self.votes: dict[int, dict[int, Vote]] = {}
        self.last_vote = 0  # the mission of the vote heard last
        self.commands: dict[int, _Command] = {}
        self.acks: deque[Ack] = deque(maxlen=500)  # to us, lately: a ref made after them
        self.swarm_time = 0.0  # the newest status time heard (the swarm's clock)
        self.changed = {"zones": 0, "missions": 0, "vote": 0, "commands": 0}
        self.dismissed: dict[int, int] = {}  # vehicle -> the seq it was dismissed at

    # ------------------------------------------------------------------ inputs
    def _bump(self, section: str | None = None) -> int:
        self.seq += 1
        if section is not None:
            self.changed[section] = self.seq
        return self.seq

    def _vehicle(self, vid: int) -> _Vehicle:
        v = self.vehicles.get(vid)
        if v is None:
            v = self.vehicles[vid] = _Vehicle(vid)
            self.dismissed.pop(vid, None)  # heard again
        return v

    def dismiss(self, vehicle_id: Any, now: float) -> int:
        """The operator takes a LOST vehicle off the map (it is accounted for): the
        vehicle's id. NotLostError (one line): not an id, or not a lost vehicle."""
        vid = finite_id(vehicle_id)
        v = self.vehicles.get(vid)
        if v is None or not self.link(v, now)["lost"]:
            lost = [str(i) for i, w in sorted(self.vehicles.items()) if self.link(w, now)["lost"]]
            raise NotLostError(f"vehicle {vid} is not lost (lost: {', '.join(lost) or 'none'})")
        del self.vehicles[vid]
        self.dismissed[vid] = self._bump()
        return vid

    def _heard(self, v: _Vehicle, now: float) -> None:
        v.heard_at = now
        v.arrivals.append(now)
        v.changed = self._bump()

    def handle(self, msg: Message, now: float) -> list[PlanJob]:
        match msg:
            case VehicleStatus():
                self._on_status(msg, now)
            case VehicleInfo():
                if msg.vehicle_type == VehicleType.GCS:
                    self.ground.add(msg.vehicle_id)
                    self.vehicles.pop(msg.vehicle_id, None)
                    return []
                v = self._vehicle(msg.vehicle_id)
                v.info = msg
                self._heard(v, now)
            case Alert():
                self.alerts.append((self._bump(), now, msg))
                if msg.vehicle_id in self.vehicles or msg.vehicle_id not in self.ground:
                    v = self._vehicle(msg.vehicle_id)
                    v.severity[msg.code] = msg.severity
                    v.changed = self.seq
            case Ack():
                self._on_ack(msg)
            case Vote():
                self._on_vote(msg)
            case NoFlyZone():
                old = self.zones.get(msg.zone_id)
                if old is None or msg.time_unix_s >= old.time_unix_s:
                    self.zones[msg.zone_id] = msg
                    self._bump("zones")
            case Mission():
                if msg.mission_id not in self.missions:
                    self.missions[msg.mission_id] = msg
                    self._bump("missions")
            case Alive(node_id, alive):
                if node_id == self.gcs_id or node_id in self.ground:
                    return []
                v = self._vehicle(node_id)
                if v.alive != alive:
                    v.alive = alive
                    v.changed = self._bump()
            case PlanDone():
                plan = self.plans.setdefault(msg.mission_id, _Plan())
                plan.members, plan.shares, plan.error = msg.members, msg.shares, msg.error
                self._bump("missions")
            case CommandSent():
                self.commands[msg.cid] = _Command(msg)
                while len(self.commands) > COMMANDS_KEPT:
                    del self.commands[min(self.commands)]
                self._bump("commands")
            case CommandRef():
                c = self.commands.get(msg.cid)
                if c is not None:
                    c.ref = msg
                    for a in self.acks:
                        self._fold(c, a)
                    self._bump("commands")
            case CommandDone():
                c = self.commands.get(msg.cid)
                if c is not None:
                    c.done = msg
                    self._bump("commands")
            case CommandFailed():
                c = self.commands.get(msg.cid)
                if c is not None:
                    c.error = msg.error
                    self._bump("commands")
        if isinstance(msg, VehicleInfo | Mission | NoFlyZone):  # what a roster or plan needs
            return self.on_timer(now)
        return []

    def _on_status(self, msg: VehicleStatus, now: float) -> None:
        if msg.vehicle_id in self.ground:
            return
        v = self._vehicle(msg.vehicle_id)
        v.status = msg
        self.swarm_time = max(self.swarm_time, msg.time_unix_s)
        self._heard(v, now)
        if msg.lat_deg == 0.0 and msg.lon_deg == 0.0:
            return  # no position yet (no GPS fix): nothing to draw
        if not v.trail or now - v.trail[-1][1] >= TRAIL_STEP_S:
            v.trail.append((self.seq, now, msg.lat_deg, msg.lon_deg))
        while v.trail and v.trail[0][1] < now - self.trail_s:
            v.trail.popleft()

    def _on_ack(self, ack: Ack) -> None:
        if ack.issuer_id != self.gcs_id:
            return
        self.acks.append(ack)
        for c in self.commands.values():
            if self._fold(c, ack):
                self._bump("commands")

    @staticmethod
    def _fold(c: _Command, ack: Ack) -> bool:
        r = c.ref
        if r is None or (ack.ref, ack.ref_id, ack.issuer_id) != (r.ref, r.ref_id, r.issuer_id):
            return False
        if ack.vehicle_id in c.answers:
            return False  # a repeat is answered again: the first answer counts
        c.answers[ack.vehicle_id] = ack
        return True

    def _on_vote(self, vote: Vote) -> None:
        mine = self.votes.setdefault(vote.mission_id, {})
        old = mine.get(vote.voter_id)
        if old is None or vote.committed or not old.committed:  # a decided vote stays
            mine[vote.voter_id] = vote
        self.last_vote = vote.mission_id
        while len(self.votes) > 8:
            del self.votes[min(self.votes)]
        self._bump("vote")

    # ------------------------------------------------------------------ plans
    def on_timer(self, now: float) -> list[PlanJob]:
        jobs = []
        for mid, mission in self.missions.items():
            roster = self.roster(mid)
            plan = self.plans.setdefault(mid, _Plan())
            if roster != plan.roster:
                plan.roster, plan.since = roster, now
                self._bump("missions")
            if not roster or now - plan.since < SETTLE_S:
                continue
            if plan.asked and set(roster) <= set(plan.asked):
                continue  # planned (or asked) for these: a lost member keeps its share
            homes = {v: h for v in roster if (h := self._home(v)) is not None}
            if len(homes) < len(roster):
                continue  # a member's home not heard yet
            battery = {
                v: float(info.battery_pct)
                for v in roster
                if (info := self.vehicles[v].info) is not None and info.battery_pct >= 0
            }
            zones = tuple(
                z for z in self.zones.values() if self._in_force(z) and not z.operating_area
            )
            plan.asked = roster
            jobs.append(PlanJob(mission, roster, homes, battery, zones))
        return jobs

    def next_deadline(self) -> float | None:
        waiting = [
            p.since + SETTLE_S
            for mid, p in self.plans.items()
            if p.roster and (not p.asked or not set(p.roster) <= set(p.asked))
        ]
        return min(waiting) if waiting else None

    def roster(self, mission_id: int) -> tuple[int, ...]:
        """The vehicles that say (VehicleInfo) they fly this mission now."""
        return tuple(
            sorted(
                v.vid
                for v in self.vehicles.values()
                if v.info is not None
                and v.info.mission_id == mission_id
                and v.info.fsm_state in FLYING
            )
        )

    def _home(self, vid: int) -> GeoPoint | None:
        info = self.vehicles[vid].info
        return info.home if info is not None else None

    def _in_force(self, z: NoFlyZone) -> bool:
        # judged on the swarm's clock (the vehicles' time: simulated in fast time)
        return z.active and (not self.swarm_time or z.in_force(self.swarm_time))

    # ------------------------------------------------------------------ the view
    def link(self, v: _Vehicle, now: float) -> dict[str, Any]:
        age = None if v.heard_at is None else max(0.0, now - v.heard_at)
        pps = sum(now - t <= RATE_WINDOW_S for t in v.arrivals) / RATE_WINDOW_S
        out = {
            "age_s": None if age is None else _r(age),
            "pps": _r(pps),
            "alive": v.alive,
            "lost": age is None or age > HEARD_ALIVE_S,
        }
        if out["lost"] and v.status is not None:
            # heard flying: last position, its age and where it is predicted now
            gone = lost_fields(v.status, v.info, age)
            out.update(landed=landed(v.status), last=gone.get("last"))
            out["predicted"] = gone.get("predicted")
        return out

    def vehicle(self, v: _Vehicle) -> dict[str, Any]:
        """One vehicle as the page shows it: the icon, the list's row and the paper's
        flight display (attitude, speeds, altitude, battery, GPS, sensors, base)."""
        st, info = v.status, v.info
        vt = info.vehicle_type if info is not None else VehicleType.OTHER
        d: dict[str, Any] = {"id": v.vid, "type": vt.name}
        if info is not None:
            d.update(
                model=info.model,
                user_id=info.user_id,
                fleet=info.fleet_id,
                mission_id=info.mission_id,
                fsm=info.fsm_state.name,
                roll_deg=_r(info.roll_deg),
                pitch_deg=_r(info.pitch_deg),
                payload=info.payload_model,
                home=_point(info.home),
                base=_point(info.base),
                errors=[c.name for c in info.errors],
                autopilot_mismatch=autopilot_mismatch(vt, info.mav_type),
                sensors={
                    name: (
                        "absent"
                        if not info.sensors_present & bit
                        else "ok"
                        if info.sensors_health & bit
                        else "NOT HEALTHY"
                    )
                    for name, bit in SENSORS.items()
                }
                if info.sensors_present
                else {},
            )
        if st is not None:
            worst = worst_severity(st, v.severity)
            d.update(
                t=st.time_unix_s,
                fleet=st.fleet_id,
                fsm=st.fsm_state.name,
                lat=_r(st.lat_deg, 7),
                lon=_r(st.lon_deg, 7),
                alt_rel_m=_r(st.alt_rel_m),
                alt_msl_m=_r(st.alt_msl_m),
                heading_deg=_r(st.heading_deg),
                groundspeed_m_s=_r(st.groundspeed_m_s),
                airspeed_m_s=_r(st.airspeed_m_s),
                climb_m_s=_r(-st.vel_down_m_s),
                battery_pct=st.battery_pct,
                battery_v=_r(st.battery_v, 2),
                gps_fix=st.gps_fix.name,
                gps_sats=st.gps_sats,
                armed=st.armed,
                mode=mode_name(vt, st.ap_mode) if vt != VehicleType.OTHER else str(st.ap_mode),
                mission_state=st.mission_state.name,
                progress_pct=st.mission_progress_pct,
                alerts=[f.name for f in AlertFlag if f and f in st.alerts],
                worst=worst.name if worst is not None else None,
                # a radio gateway's prediction: the truth is within this circle
                position_error_m=_r(st.position_error_m),
                predicted_s=_r(st.predicted_s),
                has_position=not (st.lat_deg == 0.0 and st.lon_deg == 0.0),
            )
        return d

    def zone_list(self) -> list[dict[str, Any]]:
        return [
            {
                "id": z.zone_id,
                "name": z.name,
                "operating_area": z.operating_area,
                "floor_m": z.floor_alt_msl_m,
                "ceiling_m": z.ceiling_alt_msl_m,
                "geometry": geometry_json(z.geometry),
            }
            for z in sorted(self.zones.values(), key=lambda z: z.zone_id)
            if self._in_force(z)
        ]

    def mission_list(self) -> list[dict[str, Any]]:
        out = []
        for mid, m in sorted(self.missions.items()):
            plan = self.plans.get(mid, _Plan())
            roster = self.roster(mid)
            members = sorted(set(plan.members) | set(roster))
            if plan.shares:
                state = "planned"
            elif plan.error:
                state = plan.error
            elif plan.asked:
                state = "planning"
            elif roster:
                state = "waiting for the roster to settle"
            else:
                state = "no vehicle flies it"
            out.append(
                {
                    "id": mid,
                    "type": m.mission_type.name.lower(),
                    "name": m.name,
                    "selection": selection_text(m.selection),
                    "geometry": geometry_json(m.geometry),
                    "members": members,
                    "flying": list(roster),
                    "shares": {str(v): pts for v, pts in plan.shares.items()},
                    "plan": state,
                }
            )
        return out

    def vote_view(self) -> dict[str, Any] | None:
        """The last vote heard: every score, who goes (by the vehicles' own ranking when
        the mission's quantity is known) and who said it was chosen."""
        mid = self.last_vote
        votes = self.votes.get(mid)
        if not votes:
            return None
        committed = [v for v in votes.values() if v.committed]
        pool = committed or list(votes.values())
        best = max(pool, key=lambda v: len(v.scores))
        scores = {s.vehicle_id: s.score for s in best.scores}
        m = self.missions.get(mid)
        quantity = m.selection.quantity if m is not None else 0
        winners = (
            list(rank({v: score_key(s) for v, s in scores.items()}, quantity))
            if quantity and scores
            else None
        )
        said = f"chosen for mission {mid},"
        went = sorted({a.vehicle_id for _, _, a in self.alerts if a.text.startswith(said)})
        order = sorted(scores, key=lambda v: (-score_key(scores[v]), v))
        return {
            "mission_id": mid,
            "decided": bool(committed),
            "quantity": quantity,
            "scores": [[v, round(scores[v], 4)] for v in order],
            "winners": winners if winners is not None else went,
            "said_chosen": went,
            "voters": sorted(votes),
        }

    def command_list(self) -> list[dict[str, Any]]:
        out = []
        for cid, c in sorted(self.commands.items(), reverse=True):
            entry: dict[str, Any] = {
                "id": cid,
                "what": c.sent.what,
                "question": c.sent.question,
            }
            if c.error:
                entry.update(state="failed", summary=c.error, answers=[])
            elif c.done is not None:
                o = c.done.outcome
                entry.update(
                    state="ok" if o.get("ok") else "failed",
                    summary=c.done.summary,
                    answers=[
                        {k: r[k] for k in ("id", "answer", "reason", "why", "notes")}
                        for r in o.get("vehicles", [])
                    ],
                    not_addressed=o.get("not_addressed", []),
                    absent=o.get("absent", []),
                )
            else:
                apart = AckReason.NOT_ADDRESSED
                entry.update(
                    state="waiting",
                    summary=f"{c.sent.what}: {len(c.answers)} answered, waiting",
                    answers=[
                        {
                            "id": vid,
                            "answer": "accepted" if a.accepted else "rejected",
                            "reason": a.reason.name,
                            "why": reason_text(a.reason, a.text, a.detail),
                            "notes": [],
                        }
                        for vid, a in sorted(c.answers.items())
                        if a.reason != apart
                    ],
                    not_addressed=sorted(v for v, a in c.answers.items() if a.reason == apart),
                )
            out.append(entry)
        return out

    def summary(self, now: float) -> dict[str, Any]:
        by_state: dict[str, list[int]] = {s.name: [] for s in FsmState}
        by_state["LOST"] = []
        fleets: dict[str, list[int]] = {}
        bases: Counter[GeoPoint] = Counter()
        for vid, v in sorted(self.vehicles.items()):
            if self.link(v, now)["lost"]:
                by_state["LOST"].append(vid)
            else:
                fsm = (
                    v.status.fsm_state
                    if v.status is not None
                    else (v.info.fsm_state if v.info is not None else FsmState.INACTIVE)
                )
                by_state[fsm.name].append(vid)
            fleet = v.status.fleet_id if v.status else (v.info.fleet_id if v.info else 0)
            fleets.setdefault(str(fleet), []).append(vid)
            if v.info is not None and v.info.base is not None:
                bases[v.info.base] += 1
        base = bases.most_common(1)[0][0] if bases else None
        return {
            "count": len(self.vehicles),
            "by_state": by_state,
            "fleets": fleets,
            "base": _point(base),
            "bases_disagree": len(bases) > 1,
        }

    def alert_json(self, t: float, a: Alert) -> dict[str, Any]:
        return {
            "vehicle": a.vehicle_id,
            "time_unix_s": a.time_unix_s,
            "severity": a.severity.name,
            "code": a.code.name,
            "text": alert_text(a.code, a.text, a.detail),
        }

    def frame(self, cursor: int, now: float) -> tuple[dict[str, Any], int]:
        """What changed since `cursor` (0: everything), and the cursor to ask with next."""
        full = cursor <= 0
        out: dict[str, Any] = {
            "seq": self.seq,
            "full": full,
            "mode": self.mode,
            "now": _r(now - self.t0, 2),
            "trail_s": self.trail_s,
            "vehicles": [self.vehicle(v) for v in self.vehicles.values() if v.changed > cursor],
            "links": {str(vid): self.link(v, now) for vid, v in self.vehicles.items()},
            "trails": {
                str(vid): [
                    [_r(t - self.t0, 2), lat, lon] for s, t, lat, lon in v.trail if s > cursor
                ]
                for vid, v in self.vehicles.items()
                if v.trail and v.trail[-1][0] > cursor
            },
            "alerts": [self.alert_json(t, a) for s, t, a in self.alerts if s > cursor],
            "dismissed": sorted(v for v, s in self.dismissed.items() if s > cursor),
            "summary": self.summary(now),
        }
        if self.changed["zones"] > cursor:
            out["zones"] = self.zone_list()
        if self.changed["missions"] > cursor:
            out["missions"] = self.mission_list()
        if self.changed["vote"] > cursor:
            out["vote"] = self.vote_view()
        if self.changed["commands"] > cursor:
            out["commands"] = self.command_list()
        return out, self.seq

    def known_ids(self) -> Iterable[int]:
        return self.vehicles.keys()
