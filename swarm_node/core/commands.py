"""Command manager (paper section 2.3.4, "CommandManager") and the swarm manager's
acceptance checks (section 2.3.3).

`plan_command` turns an operator command into autopilot requests (run in order), node
effects (set base, fleet, active flag, cancel, the operator taking the vehicle out of
its mission, an emergency landing route to plan, a landing cancelled) and, for anything
decided at once, an immediate Ack. The effects on the state machine follow the paper's
STATE_GO_MISSION cases (docs/state-machine.md, "Operator commands"). `CommandTracker` runs the requests one after another and answers every
command with exactly one Ack: accepted when all its requests succeed, rejected with the
autopilot's reason when one fails, TIMEOUT when the link never answers.
`check_mission` applies the paper's three rejection rules to a mission: every node
answers every mission it hears (NOT_ADDRESSED when it is not addressed).
`AnswerCache` makes both idempotent: the ground station repeats a command or mission
until it is answered (a radio loses frames), and a repeat is answered again with the
first answer, never carried out twice.

Pure: no I/O; `now` is passed in.
"""

from __future__ import annotations

import itertools
import math
from collections import OrderedDict
from dataclasses import dataclass, field

import msgspec

from swarm_proto import (
    Ack,
    AckReason,
    AckRef,
    AlertCode,
    Command,
    CommandKind,
    FsmState,
    GeoPoint,
    Mission,
    MissionType,
    SelectorKind,
    VehicleType,
)
from swarm_proto.text import short_text

from .autopilot.plans import CALIBRATIONS
from .autopilot.requests import (
    ApError,
    ApRequest,
    ApResult,
    Arm,
    Calibrate,
    ChangeAltitude,
    ChangeSpeed,
    Disarm,
    Goto,
    Land,
    Parachute,
    ReturnToLaunch,
    SetMode,
    Takeoff,
    UploadRally,
)
from .autopilot.state import AutopilotState
from .landing_point import landing_point
from .mission.phases import Phase
from .outputs import SetActive, SetBase, SetFleet, StopLanding, TakeOver
from .profile import VehicleProfile

ABORT_LANDING_MIN_ALT_M = 30.0  # climb to at least this (above home) when aborting a landing
# ArduPilot modes that bring a vehicle home or down (Copter, Plane/QuadPlane)
LANDING_MODES = frozenset({"LAND", "QLAND", "RTL", "QRTL", "SMART_RTL", "AUTO_RTL"})


@dataclass(frozen=True)
class NodeView:
    """What command and acceptance decisions look at (a snapshot taken by the node)."""

    self_id: int
    fleet_id: int
    profile: VehicleProfile
    autopilot: AutopilotState
    fsm_state: FsmState
    mission_id: int | None
    base: GeoPoint | None
    ready: bool  # vehicle monitoring says the vehicle is ready
    landing: bool = False  # the mission manager is bringing the vehicle home or down
    touching_down: bool = False  # ... and is landing it now (the way home's last stage)
    not_ready: str = ""  # what vehicle monitoring says is not ready

    @property
    def on_mission(self) -> bool:
        """Planning or flying a mission (the node's own return included)."""
        return (
            self.fsm_state in (FsmState.PLAN, FsmState.GO_MISSION) and self.mission_id is not None
        )


# ----------------------------------------------------------------------- node effects
# (SetBase, SetFleet, SetActive, TakeOver and StopLanding are outputs the node routes
# to their owners: outputs.py; these the operator desk carries out itself)


@dataclass(frozen=True)
class CancelMission:
    mission_id: int


@dataclass(frozen=True)
class LandAt:
    """EMERGENCY_LAND: the node plans the zone-safe route to `point` and lands there
    (its requests become the command's)."""

    point: GeoPoint


Effect = SetBase | SetFleet | SetActive | CancelMission | TakeOver | LandAt | StopLanding


@dataclass(frozen=True)
class CommandPlan:
    requests: tuple[ApRequest, ...] = ()
    effects: tuple[Effect, ...] = ()
    ack: Ack | None = None  # set: answered now (rejection, or nothing to ask the autopilot)


def _ack(
    cmd: Command, view: NodeView, ok: bool, reason: AckReason = AckReason.OK, text: str = ""
) -> Ack:
    return Ack(view.self_id, cmd.issuer_id, AckRef.COMMAND, cmd.seq, ok, reason, short_text(text))


def _land_request(profile: VehicleProfile) -> tuple[ApRequest, ...]:
    if profile.vehicle_type in (VehicleType.ROVER, VehicleType.BOAT):
        return (SetMode(mode="HOLD"),)
    return (Land(),)


#: Lowest rally point altitude above home per vehicle type: ArduPlane's RTL
#: flies to a rally point at the rally point's own altitude (RTL_ALTITUDE is no floor:
#: recorded, a QuadPlane sent to a rally point at 0 m flew into the ground) and circles it
#: there; ArduCopter climbs to max(rally altitude, RTL_ALT) and lands below it.
SAFE_RALLY_ALT_REL_M: dict[VehicleType, float] = {
    VehicleType.PLANE: 40.0,
    VehicleType.VTOL: 40.0,
    VehicleType.COPTER: 15.0,  # ArduCopter's RTL_ALT default
}


def rally_alt_rel_m(vehicle_type: VehicleType, base_alt_rel_m: float) -> float:
    """The rally point's altitude above home (the point: `landing_point`, the vehicle's
    own pad at the base or its slot there): the operator's base altitude,
    never below home (a base given without an altitude is 0 m above sea
    level, `gcs cmd set-base --point LAT,LON`; with home 10 m above sea level a rover's
    rally point went to -10 m) and never below the vehicle type's safe floor."""
    rel = max(base_alt_rel_m, 0.0) if math.isfinite(base_alt_rel_m) else 0.0
    floor = SAFE_RALLY_ALT_REL_M.get(vehicle_type)
    return rel if floor is None else max(rel, floor)


def plan_command(cmd: Command, view: NodeView) -> CommandPlan | None:
    """What to do with a command; None when it does not address this vehicle (a command
    is answered by the vehicles it addresses only: one Ack per vehicle of the swarm for
    every command would cost airtime on the radio for nothing)."""
    if not cmd.target.addresses(view.self_id, view.fleet_id):
        return None
    k, a, p, ap = cmd.kind, cmd.args, view.profile, view.autopilot

    def reject(reason: AckReason, text: str = "") -> CommandPlan:
        return CommandPlan(ack=_ack(cmd, view, False, reason, text))

    if cmd.target.kind == SelectorKind.QUANTITY:  # this vehicle is a candidate
        return reject(AckReason.UNSUPPORTED, "voting chooses vehicles for missions, not commands")

    def done(*effects: Effect) -> CommandPlan:
        return CommandPlan(effects=effects, ack=_ack(cmd, view, True))

    # ---- swarm-level commands: decided here
    if k == CommandKind.SET_BASE:
        if a.point is None:
            return reject(AckReason.INVALID, "SET_BASE needs a point")
        reqs: tuple[ApRequest, ...] = ()
        if ap.link_ok and ap.home is not None:
            # RTL goes to the nearest rally point: this vehicle's own landing point
            alt = rally_alt_rel_m(p.vehicle_type, a.point.alt_msl_m - ap.home.alt_msl_m)
            lat, lon = landing_point(view.self_id, ap.home, a.point)
            reqs = (UploadRally(points=((lat, lon, alt),)),)
        return CommandPlan(
            requests=reqs, effects=(SetBase(a.point),), ack=None if reqs else _ack(cmd, view, True)
        )
    if k == CommandKind.SET_FLEET:
        return done(SetFleet(a.fleet_id))
    if k == CommandKind.ACTIVATE:
        return done(SetActive(True))
    if k == CommandKind.SHUTDOWN:
        if not ap.armed:
            return done(SetActive(False))
        # an aircraft never leaves the swarm's control with no owner: home first, as the
        # operator's RTL (the arbiter rules on it); on a mission the landing ends the
        # sortie and shuts the node down (the state machine's "landed")
        if not ap.link_ok:
            return reject(AckReason.NOT_READY, "flying, autopilot link down: cannot send it home")
        if view.on_mission:
            return CommandPlan(
                requests=(ReturnToLaunch(),),
                effects=(TakeOver("operator SHUTDOWN", Phase.RETURNING),),
            )
        return CommandPlan(requests=(ReturnToLaunch(),), effects=(SetActive(False),))
    if k == CommandKind.CANCEL_MISSION:
        if view.mission_id is None or a.mission_id != view.mission_id:
            return reject(AckReason.NOT_FOUND, f"not flying mission {a.mission_id}")
        return done(CancelMission(a.mission_id))
    if k in (CommandKind.JOIN_MISSION, CommandKind.SWAP_MISSION):
        return reject(AckReason.UNSUPPORTED, "add/swap are handled by the mission manager")

    # ---- autopilot commands
    if not ap.link_ok:
        return reject(AckReason.NOT_READY, "autopilot link is down")
    if k == CommandKind.ARM:
        return CommandPlan(requests=(Arm(),))
    if k == CommandKind.DISARM:
        return CommandPlan(requests=(Disarm(),))
    if k == CommandKind.TAKEOFF:
        if a.value is None or a.value <= 0:
            return reject(AckReason.INVALID, "TAKEOFF needs an altitude > 0 (m above home)")
        if not p.can_hover and p.vehicle_type == VehicleType.PLANE and not ap.armed:
            return reject(AckReason.NOT_READY, "arm the plane first")
        return CommandPlan(requests=(Takeoff(alt_rel_m=a.value),))
    if k == CommandKind.SET_MODE:
        if not a.text:
            return reject(AckReason.INVALID, "SET_MODE needs a mode name")
        return CommandPlan(requests=(SetMode(mode=a.text.upper()),))
    if k == CommandKind.GOTO:
        if a.point is None:
            return reject(AckReason.INVALID, "GOTO needs a point")
        if ap.home is None:
            return reject(AckReason.HOME_NOT_SET)
        alt_rel = a.point.alt_msl_m - ap.home.alt_msl_m
        return CommandPlan(
            requests=(Goto(lat_deg=a.point.lat_deg, lon_deg=a.point.lon_deg, alt_rel_m=alt_rel),)
        )
    if k == CommandKind.SET_SPEED:
        if a.value is None or a.value <= 0:
            return reject(AckReason.INVALID, "SET_SPEED needs a speed > 0 m/s")
        if p.is_fixed_wing and p.min_speed_m_s and a.value < p.min_speed_m_s:
            return reject(AckReason.INVALID, f"below the stall speed {p.min_speed_m_s:g} m/s")
        return CommandPlan(requests=(ChangeSpeed(speed_m_s=a.value, airspeed=p.is_fixed_wing),))
    if k == CommandKind.SET_ALTITUDE:
        if a.value is None:
            return reject(AckReason.INVALID, "SET_ALTITUDE needs an altitude (m above home)")
        return CommandPlan(requests=(ChangeAltitude(alt_rel_m=a.value),))
    # During a mission (the node's own return included) RTL, LAND, EMERGENCY_LAND and
    # PARACHUTE take the vehicle out of it at once: the state machine leaves the fleet
    # (Recalled) and the sortie ends with the landing, whatever the autopilot answers
    # (the operator decides what comes next).
    recall = view.on_mission
    if k == CommandKind.RTL:
        return CommandPlan(
            requests=(ReturnToLaunch(),),
            effects=(TakeOver("operator RTL", Phase.RETURNING),) if recall else (),
        )
    if k == CommandKind.LAND:
        return CommandPlan(
            requests=_land_request(p),
            effects=(TakeOver("operator LAND", Phase.LANDING),) if recall else (),
        )
    if k == CommandKind.EMERGENCY_LAND:
        # paper 3.5.1: "if the landing route has been specified; otherwise, it requests
        # the entry of the route": the route ends at args.point, planned around the zones
        if a.point is None:
            return reject(AckReason.INVALID, "EMERGENCY_LAND needs the landing point")
        if not ap.armed:
            return reject(AckReason.NOT_READY, "not flying")
        if ap.home is None or ap.lat_deg is None or ap.lon_deg is None:
            return reject(AckReason.HOME_NOT_SET, "no home or position")
        return CommandPlan(
            effects=(LandAt(a.point), TakeOver("operator EMERGENCY_LAND", Phase.LANDING))
        )
    if k == CommandKind.ABORT_LANDING:
        # the paper's "Cancel Landing": stop a landing (or the way home) and hold above
        if not (view.landing or ap.mode_name in LANDING_MODES) or not ap.armed:
            return reject(AckReason.NOT_FOUND, "not landing")
        if ap.lat_deg is None or ap.lon_deg is None:
            return reject(AckReason.NOT_READY, "no position")
        alt = max(ap.alt_rel_m or 0.0, ABORT_LANDING_MIN_ALT_M)
        return CommandPlan(
            requests=(
                SetMode(mode="GUIDED"),
                Goto(lat_deg=ap.lat_deg, lon_deg=ap.lon_deg, alt_rel_m=alt),
            ),
            effects=(StopLanding(),),
        )
    if k == CommandKind.PARACHUTE:
        # paper 3.5.1 "Parachute All": every vehicle with a parachute; the others refuse
        if not p.has_parachute:
            return reject(AckReason.UNSUPPORTED, "no parachute fitted")
        return CommandPlan(
            requests=(Parachute(),),
            effects=(TakeOver("operator PARACHUTE", Phase.PARACHUTE),)
            if recall or ap.armed
            else (),
        )
    if k == CommandKind.CALIBRATE:
        what = a.text or "gyro"
        if what not in CALIBRATIONS:
            return reject(AckReason.INVALID, f"calibrate one of {', '.join(CALIBRATIONS)}")
        if ap.armed:
            return reject(AckReason.BUSY, "calibrate on the ground, disarmed")
        if view.on_mission:
            return reject(AckReason.BUSY, f"on mission {view.mission_id}")
        return CommandPlan(requests=(Calibrate(what=what),))
    return reject(AckReason.UNSUPPORTED, k.name)


def emergency_requests(code: AlertCode, profile: VehicleProfile) -> tuple[ApRequest, ...]:
    """The emergency procedure for an alert (docs/state-machine.md lists the choices).

    Link loss: nothing can be sent; ArduPilot's own failsafes are the backstop.
    """
    if code == AlertCode.AUTOPILOT_LINK_LOSS:
        return ()
    if code == AlertCode.ATTITUDE_ABNORMAL:
        return (Parachute(),) if profile.has_parachute else ()
    if code == AlertCode.GEOFENCE_BREACH:
        return (ReturnToLaunch(),)
    if code in (AlertCode.BATTERY_CRITICAL, AlertCode.GPS_LOSS, AlertCode.EKF_FAILURE):
        if profile.vehicle_type == VehicleType.PLANE:
            # a plane cannot land where it is: battery -> home; GPS/EKF -> leave it to the autopilot
            return (ReturnToLaunch(),) if code == AlertCode.BATTERY_CRITICAL else ()
        return _land_request(profile)
    return (ReturnToLaunch(),)


def check_mission(mission: Mission, view: NodeView) -> AckReason:
    """The swarm manager's acceptance checks (paper section 2.3.3): OK or the first
    reason to reject. A mission that does not address this vehicle is NOT_ADDRESSED
    whatever the vehicle's state (its other problems do not concern this mission);
    then the paper's order: home not defined (then no base), vehicle not ready
    (an emergency first, then not ready); then a vehicle landing is BUSY."""
    sel = mission.selection
    if not sel.addresses(view.self_id, view.fleet_id):
        return AckReason.NOT_ADDRESSED
    if mission.mission_type == MissionType.MUMT and mission.params.lead_vehicle_id == view.self_id:
        return AckReason.NOT_ADDRESSED  # the lead of a MUM-T mission is not one of its followers
    if mission.mission_type == MissionType.MUMT and not mission.params.lead_vehicle_id:
        return AckReason.INVALID  # followers of nobody
    if view.autopilot.home is None:
        return AckReason.HOME_NOT_SET
    if view.base is None:
        return AckReason.NO_BASE
    if view.fsm_state == FsmState.EMERGENCY:
        return AckReason.EMERGENCY
    if not view.ready or view.fsm_state == FsmState.INACTIVE:
        return AckReason.NOT_READY
    if view.touching_down:
        # a VTOL in its final descent sent into AUTO sat armed on its pad for ever: the
        # mission is for after the landing (ACTIVATE, then send it again)
        return AckReason.BUSY
    return AckReason.OK


# ----------------------------------------------------------------------- repeats

AnswerKey = tuple[AckRef, int, int]  # (what, issuer id, command seq or mission id)


def answer_key(msg: Command | Mission) -> AnswerKey:
    if isinstance(msg, Command):
        return (AckRef.COMMAND, msg.issuer_id, msg.seq)
    return (AckRef.MISSION, msg.issuer_id, msg.mission_id)


@dataclass
class AnswerCache:
    """The last `size` commands and missions this vehicle took up, with their answers.

    A repeat of one still running is ignored (its answer comes when it is done); a
    repeat of one answered gets the same Ack again. Bounded: the oldest are forgotten.
    """

    size: int = 256
    _answers: OrderedDict[AnswerKey, Ack | None] = field(default_factory=OrderedDict)

    def seen(self, key: AnswerKey) -> bool:
        return key in self._answers

    def answer_of(self, key: AnswerKey) -> Ack | None:
        """The answer already given (None: not seen, or still running)."""
        return self._answers.get(key)

    def taken(self, key: AnswerKey) -> None:
        """Taken up, not answered yet."""
        self._answers[key] = None
        self._answers.move_to_end(key)
        while len(self._answers) > self.size:
            self._answers.popitem(last=False)

    def answered(self, ack: Ack) -> None:
        key = (ack.ref, ack.issuer_id, ack.ref_id)
        self._answers[key] = ack
        self._answers.move_to_end(key)
        while len(self._answers) > self.size:
            self._answers.popitem(last=False)


# ----------------------------------------------------------------------- the tracker


@dataclass
class _Running:
    cmd: Command
    remaining: list[ApRequest]
    waiting_for: int
    deadline: float


@dataclass
class CommandTracker:
    """Runs each command's autopilot requests in order and answers it exactly once."""

    self_id: int
    timeout_s: float = 30.0  # the link retries itself; this only catches a link that never answers
    # the operator's request ids, shared with the passthrough sessions (one space for
    # the results the arbiter routes to OPERATOR)
    ids: itertools.count[int] = field(default_factory=lambda: itertools.count(1))
    _running: dict[int, _Running] = field(default_factory=dict)  # request_id -> command

    def start(self, cmd: Command, requests: tuple[ApRequest, ...], now: float) -> list[ApRequest]:
        """Submit the first request (with a fresh request_id); [] if there is none."""
        if not requests:
            return []
        return [self._submit(cmd, list(requests), now)]

    def _submit(self, cmd: Command, requests: list[ApRequest], now: float) -> ApRequest:
        rid = next(self.ids)
        req = msgspec.structs.replace(requests[0], request_id=rid)
        self._running[rid] = _Running(cmd, requests[1:], rid, now + self.timeout_s)
        return req

    def on_result(self, result: ApResult, now: float) -> tuple[list[ApRequest], list[Ack]]:
        run = self._running.pop(result.request_id, None)
        if run is None:
            return [], []  # not ours (emergency or mission requests), or already timed out
        if not result.ok:
            # the arbiter's own refusal is the node's, not the autopilot's
            who = (
                AckReason.PREEMPTED
                if result.error == ApError.PREEMPTED
                else AckReason.AUTOPILOT_REJECTED
            )
            return [], [self._ack(run.cmd, False, who, result.reason)]
        if run.remaining:
            return [self._submit(run.cmd, run.remaining, now)], []
        return [], [self._ack(run.cmd, True, AckReason.OK, result.reason)]

    def on_timer(self, now: float) -> list[Ack]:
        late = [rid for rid, r in self._running.items() if now >= r.deadline]
        return [
            self._ack(
                self._running.pop(rid).cmd,
                False,
                AckReason.TIMEOUT,
                "no answer from the autopilot link",
            )
            for rid in late
        ]

    def next_deadline(self) -> float | None:
        if not self._running:  # the usual case: nothing running
            return None
        return min(r.deadline for r in self._running.values())

    def _ack(self, cmd: Command, ok: bool, reason: AckReason, text: str) -> Ack:
        return Ack(
            self.self_id, cmd.issuer_id, AckRef.COMMAND, cmd.seq, ok, reason, short_text(text)
        )
