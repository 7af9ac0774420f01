"""The swarm state machine of paper section 2.3.4, as data.

Three working states (STATE_PLAN, STATE_GO_MISSION, STATE_EMERGENCY) plus INACTIVE
(the paper's "deactivated": not active, or no base defined). Each 5 Hz tick the
current state's rules are tried in order; the first that fires yields one of the
paper's actions (NONE, READY, NEW, REPLAN, EMERGENCY, and DEACTIVATE for the paper's
"the state machine will be deactivated") and the outputs the node must carry out.
The action alone decides the next state (`ACTION_TARGET`).

Inputs are level facts sampled at each tick (`Facts`: active flag, base set, vehicle
ready, the most severe emergency alert, whether the fleet is all in PLAN) and one-shot
events queued between ticks (`NewMission`, `PlanSucceeded`, ...). Choices where the
paper is vague are documented in docs/state-machine.md, which also shows the diagram
generated from `RULES` (`python -m swarm_node.core.state_machine`).

Pure: no I/O, time comes in as `now`.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from enum import IntEnum

from swarm_proto import AlertCode, FsmState, ReasonDetail, Severity
from swarm_proto.text import short_text

TICK_S = 0.2  # 5 Hz


class Action(IntEnum):
    NONE = 0
    READY = 1
    NEW = 2
    REPLAN = 3
    EMERGENCY = 4
    DEACTIVATE = 5


ACTION_TARGET: dict[Action, FsmState | None] = {
    Action.NONE: None,
    Action.READY: FsmState.GO_MISSION,
    Action.NEW: FsmState.PLAN,
    Action.REPLAN: FsmState.PLAN,
    Action.EMERGENCY: FsmState.EMERGENCY,
    Action.DEACTIVATE: FsmState.INACTIVE,
}

RETURN_MISSION = -1  # the "return to base" mission the FSM assigns itself


# --------------------------------------------------------------------------- inputs


@dataclass(frozen=True)
class Emergency:
    code: AlertCode
    severity: Severity


@dataclass(frozen=True)
class Facts:
    """Level inputs, sampled every tick."""

    active: bool = True  # the operator's ACTIVATE / SHUTDOWN flag
    base_set: bool = False
    vehicle_ready: bool = False  # vehicle monitoring: started correctly
    emergency: Emergency | None = None  # most severe active emergency-level alert
    fleet_ready: bool = False  # every live member of the fleet is in PLAN for our mission
    armed: bool = False  # the vehicle is armed (flying, or about to)
    # the plan is made and the take-off waits its turn at the close pads (safety/pads.py):
    # a wait that grows with the fleet, not planning, so the plan timeout does not count it
    launch_queued: bool = False


@dataclass(frozen=True)
class NewMission:
    mission_id: int


@dataclass(frozen=True)
class Replan:
    mission_id: int


@dataclass(frozen=True)
class PlanSucceeded:
    mission_id: int


@dataclass(frozen=True)
class PlanFailed:
    mission_id: int
    reason: str = ""
    detail: ReasonDetail | None = None  # the reason's numbers, for the alert
    # what failed, under its true name: planning, or the autopilot refusing a step of
    # the start (an arm refusal is not a planning failure)
    code: AlertCode = AlertCode.PLAN_FAILED


@dataclass(frozen=True)
class MissionComplete:
    mission_id: int


@dataclass(frozen=True)
class LandingComplete:
    pass


@dataclass(frozen=True)
class LeftFleet:
    """A mission alert: this vehicle has departed from its fleet."""

    reason: str = ""


@dataclass(frozen=True)
class Cancelled:
    """The operator cancelled the current mission (CANCEL_MISSION): not a failure; the
    vehicle leaves the fleet and returns to base."""

    mission_id: int


@dataclass(frozen=True)
class Recalled:
    """The operator took the vehicle out of its mission (RTL, LAND, EMERGENCY_LAND,
    PARACHUTE): the command manager already drives the autopilot; the vehicle leaves
    its fleet and the mission, and its landing completes the sortie."""

    reason: str = ""


@dataclass(frozen=True)
class Rebooted:
    """The autopilot rebooted while this vehicle planned or flew a mission: it boots
    disarmed with no fix, and what it was told is gone. The vehicle leaves its fleet at
    once (its share handed on) and the mission; nothing arms it again but the operator
    or a mission accepted after the reboot."""


@dataclass(frozen=True)
class Unassigned:
    """The vote of a QUANTITY mission this vehicle synchronised for (idle, in PLAN) did
    not choose it, or failed: it stands down (mission/tasking.py)."""

    mission_id: int
    reason: str = ""


@dataclass(frozen=True)
class Reattached:
    """The node restarted while its vehicle flew its share of `mission_id`, and no peer
    took it over: it continues it (reattach.py)."""

    mission_id: int


Event = (
    NewMission
    | Reattached
    | Replan
    | PlanSucceeded
    | PlanFailed
    | MissionComplete
    | LandingComplete
    | LeftFleet
    | Cancelled
    | Recalled
    | Rebooted
    | Unassigned
)


# --------------------------------------------------------------------------- outputs


@dataclass(frozen=True)
class BeginPlan:
    """Enter planning for a mission (RETURN_MISSION: return to base with the fleet)."""

    mission_id: int
    replan: bool = False


@dataclass(frozen=True)
class ReleaseMission:
    """The whole fleet is in PLAN: hand the mission to the mission manager."""

    mission_id: int


@dataclass(frozen=True)
class MissionStarted:
    mission_id: int


@dataclass(frozen=True)
class MissionFinished:
    mission_id: int


@dataclass(frozen=True)
class Resume:
    """Take up `mission_id` as flying (released) without planning it: after a restart."""

    mission_id: int


@dataclass(frozen=True)
class ReturnHome:
    """Go back to base now, alone (after a planning failure or timeout)."""

    reason: str


@dataclass(frozen=True)
class LeaveFleet:
    reason: str


@dataclass(frozen=True)
class FollowOperator:
    """Drop `mission_id` (never completed) and let the operator's command fly the
    vehicle home or down; the machine waits in GO_MISSION for the landing."""

    mission_id: int | None
    reason: str


@dataclass(frozen=True)
class StandDown:
    """Drop `mission_id` (a vote did not choose this vehicle): back to no mission."""

    mission_id: int
    reason: str


@dataclass(frozen=True)
class StartEmergency:
    code: AlertCode
    severity: Severity


@dataclass(frozen=True)
class RaiseAlert:
    code: AlertCode
    severity: Severity
    text: str
    detail: ReasonDetail | None = None


@dataclass(frozen=True)
class Activated:
    pass


@dataclass(frozen=True)
class Deactivated:
    reason: str


@dataclass(frozen=True)
class Shutdown:
    """Clear the active flag (the paper: on landing "a command to shut down" is
    delivered); the operator's ACTIVATE sets it again."""


Output = (
    BeginPlan
    | ReleaseMission
    | MissionStarted
    | MissionFinished
    | Resume
    | ReturnHome
    | LeaveFleet
    | FollowOperator
    | StandDown
    | StartEmergency
    | RaiseAlert
    | Activated
    | Deactivated
    | Shutdown
)


# --------------------------------------------------------------------------- the table


@dataclass(frozen=True)
class Context:
    """What a rule sees: the machine's own memory, the facts and the triggering event."""

    state: FsmState
    mission_id: int | None
    released: bool
    emergency: Emergency | None
    plan_elapsed_s: float
    plan_timeout_s: float
    facts: Facts
    event: Event | None


@dataclass(frozen=True)
class Rule:
    name: str
    states: tuple[FsmState, ...]
    when: str  # human description, shown in the diagram
    action: Action
    event: type | None = None  # fires on a pending event of this type ...
    guard: Callable[[Context], bool] = lambda c: True  # ... and/or when this holds
    outputs: Callable[[Context], Sequence[Output]] = lambda c: ()


P, G, E, INACTIVE = FsmState.PLAN, FsmState.GO_MISSION, FsmState.EMERGENCY, FsmState.INACTIVE


def _deactivate_reason(c: Context) -> str:
    return "shutdown" if not c.facts.active else "no base"


def _is_current(c: Context) -> bool:
    ev = c.event
    return getattr(ev, "mission_id", None) == c.mission_id


def _link_back(c: Context) -> bool:
    """An autopilot link loss drove the emergency and it is over (before, a
    loss longer than 2 s ended the mission for good, though ArduPilot flew on)."""
    e = c.emergency
    return (
        e is not None
        and e.code == AlertCode.AUTOPILOT_LINK_LOSS
        and c.facts.emergency is None
        and c.facts.vehicle_ready
    )


def _emergency_escalates(c: Context) -> bool:
    new, old = c.facts.emergency, c.emergency
    return new is not None and (old is None or new.severity > old.severity)


def _failed_text(c: Context) -> str:
    """Why a plan was given up, for LeaveFleet and ReturnHome."""
    if getattr(c.event, "code", AlertCode.PLAN_FAILED) == AlertCode.AUTOPILOT_REFUSED:
        return "the autopilot refused"
    return "planning failed"


def _mid(c: Context) -> int:
    return c.mission_id if c.mission_id is not None else 0


RULES: tuple[Rule, ...] = (
    Rule(
        "activate",
        (INACTIVE,),
        "active, base set and vehicle ready",
        Action.READY,
        guard=lambda c: c.facts.active and c.facts.base_set and c.facts.vehicle_ready,
        outputs=lambda c: (Activated(),),
    ),
    Rule(
        "deactivate",
        (P, G, E),
        "shutdown, or base no longer set",
        Action.DEACTIVATE,
        guard=lambda c: not (c.facts.active and c.facts.base_set),
        outputs=lambda c: (Deactivated(_deactivate_reason(c)),),
    ),
    Rule(
        "emergency",
        (P, G),
        "emergency alert from vehicle monitoring",
        Action.EMERGENCY,
        guard=lambda c: c.facts.emergency is not None,
        outputs=lambda c: (
            StartEmergency(c.facts.emergency.code, c.facts.emergency.severity),  # type: ignore[union-attr]
        ),
    ),
    Rule(
        "escalate",
        (E,),
        "a more severe emergency alert",
        Action.NONE,
        guard=_emergency_escalates,
        outputs=lambda c: (
            StartEmergency(c.facts.emergency.code, c.facts.emergency.severity),  # type: ignore[union-attr]
        ),
    ),
    Rule(
        "link back on the ground",
        (E,),
        "the autopilot link is back after a link-loss emergency, disarmed",
        Action.READY,
        guard=lambda c: _link_back(c) and not c.facts.armed,
        outputs=lambda c: (
            LeaveFleet("autopilot link back"),
            RaiseAlert(AlertCode.AUTOPILOT_LINK_LOSS, Severity.INFO, "autopilot link back"),
        ),
    ),
    Rule(
        "link back",
        (E,),
        "the autopilot link is back after a link-loss emergency, flying",
        Action.NEW,
        guard=_link_back,
        outputs=lambda c: (
            LeaveFleet("autopilot link back: the others took the share"),
            RaiseAlert(
                AlertCode.AUTOPILOT_LINK_LOSS,
                Severity.WARNING,
                "autopilot link back: returning to base",
            ),
            BeginPlan(RETURN_MISSION),
        ),
    ),
    # ---- STATE_GO_MISSION (paper Figure 7)
    Rule(
        "landed",
        (G,),
        "landing complete",
        Action.DEACTIVATE,
        event=LandingComplete,
        outputs=lambda c: (MissionFinished(_mid(c)), Shutdown(), Deactivated("landed")),
    ),
    Rule(
        "mission complete",
        (G,),
        "mission complete ack",
        Action.NEW,
        event=MissionComplete,
        guard=_is_current,
        outputs=lambda c: (MissionFinished(_mid(c)), BeginPlan(RETURN_MISSION)),
    ),
    Rule(
        "left fleet",
        (G,),
        "mission alert: departed from the fleet",
        Action.NEW,
        event=LeftFleet,
        outputs=lambda c: (
            LeaveFleet(getattr(c.event, "reason", "")),
            RaiseAlert(AlertCode.MISSION_FAILED, Severity.WARNING, "left the fleet, returning"),
            BeginPlan(RETURN_MISSION),
        ),
    ),
    Rule(
        "cancelled",
        (G, P),
        "the operator cancelled the mission",
        Action.NEW,
        event=Cancelled,
        guard=_is_current,
        outputs=lambda c: (
            LeaveFleet("mission cancelled"),
            RaiseAlert(AlertCode.MISSION_CANCELLED, Severity.INFO, f"mission {_mid(c)} cancelled"),
            FollowOperator(c.mission_id, "cancelled"),
            BeginPlan(RETURN_MISSION),
        ),
    ),
    Rule(
        "recalled",
        (G, P),
        "the operator took the vehicle out of the mission",
        Action.READY,
        event=Recalled,
        outputs=lambda c: (
            LeaveFleet(getattr(c.event, "reason", "")),
            RaiseAlert(
                AlertCode.MISSION_FAILED,
                Severity.WARNING,
                short_text(f"left the mission: {getattr(c.event, 'reason', '')}"),
            ),
            FollowOperator(c.mission_id, getattr(c.event, "reason", "")),
        ),
    ),
    Rule(
        "autopilot rebooted",
        (G, P),
        "the autopilot rebooted",
        Action.READY,
        event=Rebooted,
        outputs=lambda c: (
            LeaveFleet("autopilot rebooted"),
            RaiseAlert(
                AlertCode.MISSION_FAILED, Severity.WARNING, "autopilot rebooted: left the fleet"
            ),
            # a return home the reboot cut short is not a mission to end
            FollowOperator(
                c.mission_id if c.mission_id not in (None, RETURN_MISSION) else None,
                "autopilot rebooted",
            ),
        ),
    ),
    Rule(
        "reattached",
        (G,),
        "restarted while flying its share, nobody took it over",
        Action.NONE,
        event=Reattached,
        guard=lambda c: c.mission_id is None,
        outputs=lambda c: (
            Resume(c.event.mission_id),  # type: ignore[union-attr]
            MissionStarted(c.event.mission_id),  # type: ignore[union-attr]
        ),
    ),
    Rule(
        "new mission",
        (G, P),
        "a new mission for this vehicle",
        Action.NEW,
        event=NewMission,
        outputs=lambda c: (BeginPlan(c.event.mission_id),),  # type: ignore[union-attr]
    ),
    Rule(
        "replan",
        (G, P),
        "replan of the current mission",
        Action.REPLAN,
        event=Replan,
        guard=_is_current,  # a replan of a mission a newer one replaced is stale
        outputs=lambda c: (BeginPlan(c.event.mission_id, replan=True),),  # type: ignore[union-attr]
    ),
    # ---- STATE_PLAN (paper Figure 6)
    Rule(
        "plan ok",
        (P,),
        "mission manager confirms the plan",
        Action.READY,
        event=PlanSucceeded,
        guard=_is_current,
        outputs=lambda c: (MissionStarted(_mid(c)),),
    ),
    Rule(
        "plan failed",
        (P,),
        "mission manager reports a planning error",
        Action.READY,
        event=PlanFailed,
        guard=_is_current,
        outputs=lambda c: (
            RaiseAlert(
                getattr(c.event, "code", AlertCode.PLAN_FAILED),
                Severity.WARNING,
                short_text(getattr(c.event, "reason", "")),
                getattr(c.event, "detail", None),
            ),
            LeaveFleet(_failed_text(c)),
            ReturnHome(_failed_text(c)),
        ),
    ),
    Rule(
        "not chosen",
        (P,),
        "a vote chose other vehicles (or failed)",
        Action.READY,
        event=Unassigned,
        guard=_is_current,
        outputs=lambda c: (StandDown(_mid(c), getattr(c.event, "reason", "")),),
    ),
    Rule(
        "plan timeout",
        (P,),
        "too long in STATE_PLAN",
        Action.READY,
        guard=lambda c: c.plan_elapsed_s > c.plan_timeout_s,
        outputs=lambda c: (
            RaiseAlert(
                AlertCode.PLAN_TIMEOUT, Severity.WARNING, f"no plan after {c.plan_timeout_s:g} s"
            ),
            LeaveFleet("planning timed out"),
            ReturnHome("planning timed out"),
        ),
    ),
    Rule(
        "fleet synced",
        (P,),
        "every fleet member is in PLAN",
        Action.NONE,
        guard=lambda c: c.facts.fleet_ready and not c.released,
        outputs=lambda c: (ReleaseMission(_mid(c)),),
    ),
)


# --------------------------------------------------------------------------- the machine


@dataclass
class Transition:
    """What one tick did (for logs and tests)."""

    rule: str
    action: Action
    before: FsmState
    after: FsmState
    outputs: list[Output] = field(default_factory=list)


class StateMachine:
    """Feed events with `post`, facts and time with `tick`; carry out the outputs."""

    def __init__(self, *, plan_timeout_s: float = 60.0, now: float = 0.0) -> None:
        self.state = FsmState.INACTIVE
        self.mission_id: int | None = None
        self.released = False
        self.emergency: Emergency | None = None
        self.plan_timeout_s = plan_timeout_s
        self.entered_at = now
        self._queued_s = 0.0  # time in this PLAN spent in the take-off queue
        self._queued_since: float | None = None
        self._next_tick = now
        self._pending: list[Event] = []
        self.ignored: list[tuple[FsmState, Event]] = []  # events no rule wanted (for logs)

    # inputs ---------------------------------------------------------------
    def post(self, event: Event) -> None:
        self._pending.append(event)

    def next_deadline(self) -> float:
        return self._next_tick

    def tick(self, now: float, facts: Facts) -> Transition | None:
        """One 5 Hz step: at most one rule fires. Returns what happened, or None."""
        self._next_tick = max(self._next_tick + TICK_S, now)
        self._count_queue(now, facts)
        fired = self._fire(now, facts)
        if fired is None:
            self._drop_pending()
            return None
        rule, event, ctx = fired
        if event is not None:
            self._pending.remove(event)
        before = self.state
        outputs = list(rule.outputs(ctx))
        self._apply(rule, outputs, now, facts)
        if self.state == before:
            self._drop_pending()  # events this state has no rule for are stale
        return Transition(rule.name, rule.action, before, self.state, outputs)

    # internals ------------------------------------------------------------
    def _count_queue(self, now: float, facts: Facts) -> None:
        queued = self.state == FsmState.PLAN and facts.launch_queued
        if queued and self._queued_since is None:
            self._queued_since = now
        elif not queued and self._queued_since is not None:
            self._queued_s += now - self._queued_since
            self._queued_since = None

    def plan_elapsed_s(self, now: float) -> float:
        """Time in STATE_PLAN, less the take-off queue's wait."""
        if self.state != FsmState.PLAN:
            return 0.0
        queued = self._queued_s + (
            now - self._queued_since if self._queued_since is not None else 0.0
        )
        return now - self.entered_at - queued

    def _context(self, now: float, facts: Facts, event: Event | None) -> Context:
        return Context(
            state=self.state,
            mission_id=self.mission_id,
            released=self.released,
            emergency=self.emergency,
            plan_elapsed_s=self.plan_elapsed_s(now),
            plan_timeout_s=self.plan_timeout_s,
            facts=facts,
            event=event,
        )

    def _fire(self, now: float, facts: Facts) -> tuple[Rule, Event | None, Context] | None:
        for rule in RULES:
            if self.state not in rule.states:
                continue
            if rule.event is None:
                ctx = self._context(now, facts, None)
                if rule.guard(ctx):
                    return rule, None, ctx
                continue
            for ev in self._pending:
                if isinstance(ev, rule.event):
                    ctx = self._context(now, facts, ev)
                    if rule.guard(ctx):
                        return rule, ev, ctx
        return None

    def _drop_pending(self) -> None:
        self.ignored.extend((self.state, ev) for ev in self._pending)
        del self.ignored[:-50]
        self._pending.clear()

    def _apply(self, rule: Rule, outputs: list[Output], now: float, facts: Facts) -> None:
        for out in outputs:
            if isinstance(out, BeginPlan):
                self.mission_id = out.mission_id
                self.released = False
            elif isinstance(out, Resume):
                self.mission_id = out.mission_id
                self.released = True
            elif isinstance(out, ReleaseMission):
                self.released = True
            elif isinstance(out, StartEmergency):
                self.emergency = Emergency(out.code, out.severity)
            elif isinstance(out, StandDown):
                self.mission_id, self.released = None, False
            elif isinstance(out, ReturnHome | FollowOperator | Deactivated):
                self.mission_id = None if isinstance(out, Deactivated) else RETURN_MISSION
                self.released = False
        target = ACTION_TARGET[rule.action]
        if target is not None and (
            target != self.state or rule.action in (Action.NEW, Action.REPLAN)
        ):
            self.state = target
            self.entered_at = now
            self._queued_s, self._queued_since = 0.0, None
            if target != FsmState.EMERGENCY:
                self.emergency = None


# --------------------------------------------------------------------------- diagram


def mermaid() -> str:
    """The state diagram, generated from RULES (docs/state-machine.md)."""
    lines = ["stateDiagram-v2", "    [*] --> INACTIVE"]
    for rule in RULES:
        target = ACTION_TARGET[rule.action]
        for s in rule.states:
            to = target if target is not None else s
            label = f"{rule.name}: {rule.when} / ACTION_{rule.action.name}"
            lines.append(f"    {s.name} --> {to.name}: {label}")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    print(mermaid(), end="")
