"""What each vehicle is doing and why, in words, from what a ground station hears
(VehicleStatus, VehicleInfo, Alert, Vote): the demo's live commentary.

A pure core: `handle(msg, now) -> list[Line]`, one line when a vehicle's activity
changes (on its pad, planning, voting, taking off, on its way to its entry point,
flying its share, replanning, returning, landing, landed, in an emergency), when its
share passes a quarter, and for what it says itself (chosen by a vote, a mission
complete, a warning). `context` lets the script say why a replan happens (a vehicle
voted out, one lost)."""

from __future__ import annotations

import enum
from dataclasses import dataclass, field

from swarm_proto import (
    Alert,
    AlertCode,
    FsmState,
    MissionState,
    Severity,
    VehicleInfo,
    VehicleStatus,
    VehicleType,
    Vote,
)
from swarm_proto.ardupilot import mode_name

ON_GROUND_M = 3.0
CLIMBING_M = 0.7  # below this fraction of the mission's altitude after arming: taking off


class Doing(enum.Enum):
    PAD = "on its pad"
    READY = "ready on its pad"
    PLANNING = "planning"
    VOTING = "voting"
    TAKING_OFF = "taking off"
    TO_ENTRY = "flying to its entry point"
    SHARE = "flying its share"
    REPLANNING = "replanning"
    RETURNING = "returning to its pad"
    LANDING = "landing"
    LANDED = "landed"
    EMERGENCY = "in an emergency"


@dataclass(frozen=True)
class Line:
    t_s: float  # since the narrator started
    vehicle_id: int  # 0: not about one vehicle
    text: str
    severity: int = 0  # 0 info, 1 worth noticing, 2 a problem


@dataclass
class _Vehicle:
    doing: Doing | None = None
    mission_id: int = 0
    quarter: int = 0
    status: VehicleStatus | None = None
    info: VehicleInfo | None = None
    voted: set[int] = field(default_factory=set)
    completed: set[int] = field(default_factory=set)  # missions it said MISSION_COMPLETE of
    flew: bool = False  # seen armed


class Narrator:
    def __init__(self, t0: float, names: dict[int, str] | None = None) -> None:
        self.t0 = t0
        self.names = names or {}  # mission id -> what it is ("the area survey")
        self.context: dict[int, str] = {}  # mission id -> why its fleet replans now
        self.chosen: dict[int, list[int]] = {}  # mission id -> members voted out of it
        self.vehicles: dict[int, _Vehicle] = {}

    def lost(self, vehicle_id: int) -> None:
        """A vehicle is gone (the script made it fail): its fleet's replan is for it."""
        mid = self.vehicles.get(vehicle_id, _Vehicle()).mission_id
        if mid:
            self.context[mid] = f"vehicle {vehicle_id} lost, its share is shared out"

    def mission(self, mission_id: int) -> str:
        return self.names.get(mission_id, f"mission {mission_id}")

    def handle(self, msg: object, now: float) -> list[Line]:
        t = now - self.t0
        if isinstance(msg, VehicleStatus):
            return self._status(msg, t)
        if isinstance(msg, VehicleInfo):
            if msg.vehicle_type == VehicleType.GCS:
                return []
            self.vehicles.setdefault(msg.vehicle_id, _Vehicle()).info = msg
            return []
        if isinstance(msg, Alert):
            return self._alert(msg, t)
        if isinstance(msg, Vote):
            return self._vote(msg, t)
        return []

    # ------------------------------------------------------------------ activity
    def _doing(self, v: _Vehicle) -> Doing:
        s, i = v.status, v.info
        assert s is not None
        mid = i.mission_id if i is not None else 0
        if s.fsm_state == FsmState.EMERGENCY:
            return Doing.EMERGENCY
        if not s.armed and s.alt_rel_m < ON_GROUND_M:
            if v.doing in (Doing.LANDING, Doing.RETURNING, Doing.LANDED):
                return Doing.LANDED
            if s.mission_state == MissionState.VOTING:
                return Doing.VOTING
            if s.fsm_state == FsmState.PLAN:
                return Doing.PLANNING
            if s.fsm_state == FsmState.GO_MISSION and mid > 0:
                return Doing.TAKING_OFF  # planned: waiting its turn to launch, or launching
            return Doing.READY if s.fsm_state == FsmState.GO_MISSION else Doing.PAD
        match s.mission_state:
            case MissionState.VOTING:
                return Doing.VOTING
            case MissionState.PLANNING:
                # a vehicle that has flown its share plans its way home (STATE_PLAN of
                # the return): it is returning, not planning the mission again
                if s.alt_rel_m >= ON_GROUND_M and (not mid or mid in v.completed):
                    return Doing.RETURNING
                return Doing.PLANNING
            case MissionState.REPLAN:
                return Doing.REPLANNING
            case MissionState.PREMISSION:
                return Doing.TAKING_OFF if s.alt_rel_m < 20.0 else Doing.TO_ENTRY
            case MissionState.MISSION if mid > 0:
                mode = mode_name(i.vehicle_type if i else VehicleType.OTHER, s.ap_mode)
                if s.alt_rel_m < 20.0 and mode in ("GUIDED", "QHOVER", "QLOITER", "TAKEOFF"):
                    return Doing.TAKING_OFF
                return Doing.SHARE
            case _:
                mode = mode_name(i.vehicle_type if i else VehicleType.OTHER, s.ap_mode)
                if mode in ("QLAND", "LAND") or (mode in ("QRTL", "RTL") and s.alt_rel_m < 40.0):
                    return Doing.LANDING
                return Doing.RETURNING

    def _status(self, s: VehicleStatus, t: float) -> list[Line]:
        v = self.vehicles.setdefault(s.vehicle_id, _Vehicle())
        v.status = s
        v.flew = v.flew or s.armed
        doing = self._doing(v)
        mid = v.info.mission_id if v.info is not None else 0
        out: list[Line] = []
        if doing != v.doing or (doing == Doing.SHARE and mid != v.mission_id):
            if doing == Doing.SHARE and mid != v.mission_id:
                v.quarter = 0
            v.doing = doing
            v.mission_id = mid if mid else v.mission_id
            out.append(
                Line(
                    t, s.vehicle_id, self._words(doing, v, s), 2 if doing == Doing.EMERGENCY else 0
                )
            )
        if doing == Doing.SHARE:
            q = s.mission_progress_pct // 25
            if q > v.quarter and q < 4:
                v.quarter = q
                out.append(
                    Line(
                        t,
                        s.vehicle_id,
                        f"{self.mission(mid)}: {s.mission_progress_pct}% "
                        f"of its share flown, {s.battery_pct}% battery",
                    )
                )
        return out

    def _words(self, doing: Doing, v: _Vehicle, s: VehicleStatus) -> str:
        mid = v.mission_id
        m = self.mission(mid)
        match doing:
            case Doing.PLANNING:
                m = m if mid else "a new mission"  # its VehicleInfo does not show it yet
                return f"planning {m} with its fleet (STATE_PLAN: waits until all are there)"
            case Doing.VOTING:
                return f"voting who flies {m}"
            case Doing.TAKING_OFF:
                if not s.armed:
                    return f"launching for {m} (in turn with the pads next to it)"
                return f"taking off for {m}"
            case Doing.TO_ENTRY:
                return f"flying to its entry point of {m} (PREMISSION: the fleet arrives together)"
            case Doing.SHARE:
                return f"flying its share of {m} at {s.alt_rel_m:.0f} m"
            case Doing.REPLANNING:
                why = self.context.get(mid, "its fleet changed")
                return f"replanning {m}: {why} (flies on meanwhile)"
            case Doing.RETURNING:
                return f"returning to its pad ({s.battery_pct}% battery)"
            case Doing.LANDING:
                return "landing on its pad"
            case Doing.LANDED:
                return f"landed, {s.battery_pct}% battery left"
            case Doing.EMERGENCY:
                return "EMERGENCY (see its alerts)"
            case Doing.READY:
                return "ready on its pad (base set: STATE_GO_MISSION)"
            case Doing.PAD:
                return "on its pad"
        return doing.value  # pragma: no cover

    # ------------------------------------------------------------------ what vehicles say
    def _alert(self, a: Alert, t: float) -> list[Line]:
        if a.code == AlertCode.MISSION_COMPLETE:
            mid = _mission_of(a.text)
            v = self.vehicles.setdefault(a.vehicle_id, _Vehicle())
            v.completed.add(mid)
            m = self.mission(mid) if mid else a.text
            if not v.flew:  # the fleet's plan gave it nothing to fly
                return [
                    Line(
                        t,
                        a.vehicle_id,
                        f"{m}: the plan gives it no share (beyond its "
                        "battery, or nothing its speed adds): it stays on its pad "
                        "(MISSION_COMPLETE)",
                    )
                ]
            return [Line(t, a.vehicle_id, f"{m}: its share is flown (MISSION_COMPLETE)")]
        if a.text.startswith("chosen for mission "):
            mid = _mission_of(a.text, 3)
            left = self.vehicles.setdefault(a.vehicle_id, _Vehicle()).mission_id
            if left:
                self.chosen.setdefault(left, []).append(a.vehicle_id)
                gone = " and ".join(map(str, self.chosen[left]))
                self.context[left] = f"{gone} voted out to {self.mission(mid)}"
            score = a.text.rsplit(" ", 1)[-1]
            return [
                Line(
                    t,
                    a.vehicle_id,
                    f"chosen by the vote for {self.mission(mid)} (score {score}): leaves its fleet",
                    1,
                )
            ]
        if a.code == AlertCode.CONDITION_CLEARED or a.severity < Severity.WARNING:
            return []
        sev = 2 if a.severity >= Severity.CRITICAL else 1
        return [Line(t, a.vehicle_id, f"{a.severity.name} {a.code.name}: {a.text}", sev)]

    def _vote(self, vote: Vote, t: float) -> list[Line]:
        v = self.vehicles.setdefault(vote.voter_id, _Vehicle())
        if vote.mission_id in v.voted:
            return []
        own = next((s.score for s in vote.scores if s.vehicle_id == vote.voter_id), None)
        if own is None:
            return []
        v.voted.add(vote.mission_id)
        return [
            Line(
                t,
                vote.voter_id,
                f"votes for {self.mission(vote.mission_id)}: scores "
                f"itself {own:.3f} (payload, arrival time, battery)",
            )
        ]


def _mission_of(text: str, index: int = 1) -> int:
    try:
        return int(text.split()[index].rstrip(",:"))
    except (IndexError, ValueError):
        return 0
