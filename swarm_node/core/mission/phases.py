"""Which leg of its sortie the mission manager flies (`Phase`), as a table: every move
is checked against `TRANSITIONS` (an illegal move is our own bug and raises, as the
sortie's does: mission/sortie.py). The diagram in docs/state-machine.md is generated
from the table (`python -m swarm_node.core.mission.phases`).

The wire MissionState (the sortie) says where the mission is; the phase says what the
mission manager waits for on the autopilot:

    IDLE        nothing flown
    STARTING    its steps in flight: upload, arm, take off; or StartMission
    CLIMBING    taken off, waiting for the take-off altitude
    MEETING     PREMISSION, climbed: waiting for the fleet's meet time, then its leg
    FOLLOWING   MUM-T: holding its slot around the lead
    FLYING      the share runs on the autopilot (progress, its end)
    RETURNING   the way home (RTL, or zone-safe legs then RTL; the pad's mission)
    LANDING     landing (a hover-capable vehicle near home; the operator's LAND)
    PARACHUTE   released: coming down under the canopy

Planning a share starts over from any phase (a new mission on the way home, a replan
in flight); so do the way home and a stop.
"""

from __future__ import annotations

from enum import Enum


class Phase(Enum):
    IDLE = "idle"
    STARTING = "starting"
    CLIMBING = "climbing"
    MEETING = "meeting"
    FOLLOWING = "following"
    FLYING = "flying"
    RETURNING = "returning"
    LANDING = "landing"
    PARACHUTE = "parachute"


class Step(Enum):
    PLANNED = "planned: upload, arm, take off"
    MEET = "planned, in the air: PREMISSION's meet"
    FOLLOW = "planned, in the air: MUM-T"
    TOOK_OFF = "took off"
    STARTED = "StartMission done"
    CLIMBED = "climbed: StartMission"
    DEPART = "the meet's leg departs"
    FROM_HERE = "no meet: the share from here"
    REATTACHED = "restarted in flight"
    RETURN = "the way home"
    NEAR_HOME = "near home or base: land"
    OPERATOR_RTL = "the operator's RTL"
    OPERATOR_LAND = "the operator's LAND"
    OPERATOR_PARACHUTE = "the operator's PARACHUTE"
    STOP = "stop"


ID, S, C, M, F, Y, R, L, P = tuple(Phase)

#: (phase, step) -> next phase; anything else is a bug
TRANSITIONS: dict[tuple[Phase, Step], Phase] = {}


def _add(froms: tuple[Phase, ...], step: Step, to: Phase) -> None:
    for p in froms:
        TRANSITIONS[(p, step)] = to


_ALL = tuple(Phase)
_add(_ALL, Step.PLANNED, S)
_add(_ALL, Step.MEET, M)  # the climb done too (CLIMBING)
_add(_ALL, Step.FOLLOW, F)  # the climb done too (CLIMBING)
_add((S,), Step.TOOK_OFF, C)
_add((S,), Step.STARTED, Y)
_add((C,), Step.CLIMBED, S)
_add((M,), Step.DEPART, S)
_add((M, Y), Step.FROM_HERE, S)  # the meet dropped, or its leg overdue
_add((ID,), Step.REATTACHED, Y)
_add(_ALL, Step.RETURN, R)
_add((R,), Step.NEAR_HOME, L)
_add((ID,), Step.OPERATOR_RTL, R)  # (the mission manager stops first)
_add((ID,), Step.OPERATOR_LAND, L)
_add((ID,), Step.OPERATOR_PARACHUTE, P)
_add(_ALL, Step.STOP, ID)

#: the phase the operator's take-over leaves the mission manager watching
TAKE_OVER = {R: Step.OPERATOR_RTL, L: Step.OPERATOR_LAND, P: Step.OPERATOR_PARACHUTE}


class IllegalMove(AssertionError):
    pass


def go(phase: Phase, step: Step) -> Phase:
    """The phase after `step`; raises IllegalMove for a move the table does not have."""
    new = TRANSITIONS.get((phase, step))
    if new is None:
        raise IllegalMove(f"no phase transition from {phase.name} on {step.value}")
    return new


def mermaid() -> str:
    """The phases' diagram, generated from TRANSITIONS (docs/state-machine.md): a step
    from every phase is drawn once, from `[*]` (any phase)."""
    lines = ["stateDiagram-v2", "    [*] --> IDLE"]
    every = {step for step in Step if all((p, step) in TRANSITIONS for p in Phase)}
    for step in Step:
        if step in every:
            lines.append(f"    [*] --> {TRANSITIONS[(ID, step)].name}: {step.value} (any phase)")
    for (p, step), to in TRANSITIONS.items():
        if step not in every:
            lines.append(f"    {p.name} --> {to.name}: {step.value}")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    print(mermaid(), end="")
