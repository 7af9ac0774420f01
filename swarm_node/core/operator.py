"""The operator desk: the node's module for what the operator sends it. It answers
every command and mission exactly once (a repeat gets the first answer again:
`AnswerCache`), runs the commands' autopilot requests as owner OPERATOR
(`CommandTracker`), applies the acceptance checks to missions, and owns the operator's
active flag (ACTIVATE / SHUTDOWN).

    inputs                      outputs
    Command                     Declared(command) (every node keeps the declaring ones),
                                Regrouping (JOIN / SWAP addressed here), Submits, Answer,
                                the command's effects: SetBase, SetFleet, TakeOver
                                (with Delegate: the mission manager lands the vehicle
                                for the operator), StopLanding, Post(Cancelled)
    Mission                     Publish(ack) (refused); Accepted + Declared(mission) (the
                                coordinator answers once the fleet's plan is made), or
                                Candidacy (a QUANTITY mission: tasking answers it)
    results (owner OPERATOR)    Submits, Answer
    Answer(ack) (any module's)  remembered as the answer to repeats
    SetActive                   the state machine shut the node down (landed)

Pure: no I/O; `now` is passed in.
"""

from __future__ import annotations

import itertools
import logging
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

from swarm_proto import (
    Ack,
    AckReason,
    AckRef,
    Command,
    CommandKind,
    FsmState,
    Mission,
    MissionType,
    NoFlyZone,
    SelectorKind,
)
from swarm_proto.text import short_text

from . import state_machine as fsm
from .arbiter import Owner
from .autopilot.requests import ApResult, StartMission, UploadMission
from .commands import (
    AnswerCache,
    CancelMission,
    CommandTracker,
    Effect,
    LandAt,
    NodeView,
    answer_key,
    check_mission,
    plan_command,
)
from .declared import DECLARING
from .mission_manager import with_defaults
from .outputs import (
    Accepted,
    Answer,
    Candidacy,
    Declared,
    Delegate,
    ModuleOutput,
    Note,
    Post,
    Publish,
    Regrouping,
    SetActive,
    Submit,
    TakeOver,
    ToOperator,
)
from .planning import PlanningError
from .planning.transit import VehicleTransit

REGROUP = (CommandKind.JOIN_MISSION, CommandKind.SWAP_MISSION)


@dataclass
class OperatorDesk:
    transit: VehicleTransit  # an emergency landing's route
    # the database's default parameters per kind of mission (fill what a mission leaves unset)
    mission_defaults: Mapping[MissionType, Mapping[str, float]] = field(default_factory=dict)
    active: bool = True  # the operator's ACTIVATE / SHUTDOWN
    answers: AnswerCache = field(default_factory=AnswerCache)  # repeats get the same answer
    # the operator's request ids (the passthrough sessions draw from it too: passthrough.py)
    ids: itertools.count[int] = field(default_factory=lambda: itertools.count(1))
    commands: CommandTracker = field(init=False)

    def __post_init__(self) -> None:
        self.commands = CommandTracker(self.transit.profile.vehicle_id, ids=self.ids)

    # ------------------------------------------------------------------ commands
    def on_command(
        self, cmd: Command, view: NodeView, zones: Sequence[NoFlyZone], now: float
    ) -> list[ModuleOutput]:
        repeat = self._repeat(cmd)
        if repeat is not None:
            return repeat
        out: list[ModuleOutput] = [Declared(cmd)] if cmd.kind in DECLARING else []
        if cmd.kind in REGROUP:
            return out + self._regroup(cmd, view)
        plan = plan_command(cmd, view)
        if plan is None:
            return out
        self.answers.taken(answer_key(cmd))
        requests = plan.requests
        for effect in plan.effects:
            if isinstance(effect, LandAt):
                try:
                    items = self.transit.landing_route(effect.point, view.autopilot, zones, now)
                except (PlanningError, ValueError) as exc:
                    text = short_text(f"no landing route: {exc}")
                    reason = AckReason.INVALID
                    ack = Ack(
                        view.self_id, cmd.issuer_id, AckRef.COMMAND, cmd.seq, False, reason, text
                    )
                    return [*out, Answer(ack)]
                requests += (UploadMission(items=items), StartMission())
        for effect in plan.effects:
            out += self._apply(effect, view)
        out += [Submit(r, Owner.OPERATOR) for r in self.commands.start(cmd, requests, now)]
        if plan.ack is not None:
            out.append(Answer(plan.ack))
            if not plan.ack.accepted:
                text = f"command {cmd.kind.name} #{cmd.seq} rejected: {plan.ack.reason.name}"
                out.append(Note(logging.INFO, text))
        return out

    def _regroup(self, cmd: Command, view: NodeView) -> list[ModuleOutput]:
        """JOIN_MISSION / SWAP_MISSION: the mission layer's (swarm/regroup.py) when it
        addresses this vehicle by id or fleet; refused for a QUANTITY selector."""
        if cmd.target.kind == SelectorKind.QUANTITY or not cmd.target.addresses(
            view.self_id, view.fleet_id
        ):
            plan = plan_command(cmd, view)  # not addressed: no answer; QUANTITY: refused
            return [Answer(plan.ack)] if plan is not None and plan.ack else []
        self.answers.taken(answer_key(cmd))
        return [Regrouping(cmd)]

    def _apply(self, effect: Effect, view: NodeView) -> list[ModuleOutput]:
        """A command's effect: to the module that owns what it changes."""
        if isinstance(effect, SetActive):
            self.active = effect.active
            return []
        if isinstance(effect, CancelMission):
            return [Post(fsm.Cancelled(effect.mission_id))]
        if isinstance(effect, TakeOver):
            # the mission manager watches the landing the operator asked for
            return [effect, Delegate(Owner.MISSION, Owner.OPERATOR)]
        if isinstance(effect, LandAt):
            return []  # its route is the command's requests
        return [effect]

    def on_result(self, result: ApResult, now: float) -> list[ModuleOutput]:
        reqs, acks = self.commands.on_result(result, now)
        return [*(Submit(r, Owner.OPERATOR) for r in reqs), *(Answer(a) for a in acks)]

    def on_timer(self, now: float) -> list[ModuleOutput]:
        return [Answer(a) for a in self.commands.on_timer(now)]

    def next_deadline(self) -> float | None:
        return self.commands.next_deadline()

    # ------------------------------------------------------------------ missions
    def on_mission(self, mission: Mission, view: NodeView) -> list[ModuleOutput]:
        """The acceptance checks (commands.check_mission). Only an acceptance is
        remembered: a rejected mission sent again is checked again (the operator may
        have fixed what was wrong, e.g. set the base; a vehicle may have joined the
        fleet the mission addresses)."""
        repeat = self._repeat(mission)
        if repeat is not None:
            return repeat
        reason = check_mission(mission, view)
        quantity = mission.selection.kind == SelectorKind.QUANTITY
        why = ""
        if not quantity and reason == AckReason.NOT_READY:
            why = self._not_ready_text(view)
        elif not quantity and reason == AckReason.BUSY and view.touching_down:
            why = "landing: activate it once landed, then send it again"
        if reason != AckReason.OK:
            return [Publish(self._ack(view, mission, reason, why))]
        mission = with_defaults(mission, self.mission_defaults.get(mission.mission_type, {}))
        if quantity:  # whether we are a candidate is tasking's (mission/tasking.py)
            return [Candidacy(mission)]
        # the fleet's verdict (accepted, or refused by all with the reason) comes once the
        # fleet's plan is made: the mission coordinator answers it
        self.answers.taken(answer_key(mission))
        return [Accepted(mission), Declared(mission)]

    def _ack(self, view: NodeView, mission: Mission, reason: AckReason, why: str) -> Ack:
        ok = reason == AckReason.OK
        return Ack(
            view.self_id,
            mission.issuer_id,
            AckRef.MISSION,
            mission.mission_id,
            ok,
            reason,
            short_text(why),
        )

    def _not_ready_text(self, view: NodeView) -> str:
        if view.not_ready or view.fsm_state != FsmState.INACTIVE:
            return view.not_ready
        return "shut down: send activate" if not self.active else "state machine not started"

    # ------------------------------------------------------------------ answers
    def take(self, o: ToOperator) -> list[ModuleOutput]:
        """An answer to remember (a repeat gets it again) and publish; the active flag
        cleared by the state machine (landed: the paper's shutdown)."""
        if isinstance(o, Answer):
            self.answers.answered(o.ack)
            return [Publish(o.ack)]
        self.active = o.active
        return []

    def _repeat(self, msg: Command | Mission) -> list[ModuleOutput] | None:
        """A command or mission already taken up: its first answer again (nothing while it
        still runs). None: not a repeat."""
        key = answer_key(msg)
        if not self.answers.seen(key):
            return None
        ack = self.answers.answer_of(key)
        return [Publish(ack)] if ack is not None else []
