"""The sortie as a table over the wire `MissionState` (what VehicleStatus.mission_state
publishes): one owner of the mission state, every move checked against `TRANSITIONS`
(an illegal move is our own bug and raises, as `radio_gateway.core.membership` does).
The diagram in docs/state-machine.md is generated from the table
(`python -m swarm_node.core.mission.sortie`).

Which leg of the sortie is flown (climbing, the share, the way home, the landing) is the
mission manager's detail (`Phase`); the wire state says where the mission is:

    IDLE        nothing to fly
    PLANNING    the fleet synchronises in STATE_PLAN, the plan is made
    VOTING      idle vehicles synchronised for a QUANTITY mission vote who flies it
    PREMISSION  the plan is uploaded; arming, take-off, climb to the mission altitude
    MISSION     flying: the share, then (a new mission, RETURN_MISSION) the way home
    REPLAN      a member was lost: the unflown part is being replanned in flight
    PARACHUTE   released, coming down under the canopy

Progress belongs to the sortie too: metres along the planned path (`progress_m` of
`path_m`) and the percent published in VehicleStatus; it never falls during a mission
and is kept on the way home.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import Enum

from swarm_proto import MissionState

ID, PL, PM, M, R, PC, V = (
    MissionState.IDLE,
    MissionState.PLANNING,
    MissionState.PREMISSION,
    MissionState.MISSION,
    MissionState.REPLAN,
    MissionState.PARACHUTE,
    MissionState.VOTING,
)


class Trigger(Enum):
    PLAN = "plan"  # the state machine began planning a mission (BeginPlan)
    REPLAN = "replan"  # a member was lost: replan in flight
    RESUMED = "resumed"  # the replan left our share as it was: fly on
    RELEASED = "released"  # planned: upload, arm, take off
    STARTED = "started"  # the autopilot flies the mission
    RETURN = "return"  # fly the way home (the return-to-base mission)
    TAKE_OVER = "take over"  # the operator's RTL/LAND flies the vehicle
    PARACHUTE = "parachute"
    COMPLETE = "complete"  # the share is flown
    FAILED = "failed"  # planning or the autopilot refused
    LANDED = "landed"
    STOP = "stop"  # deactivated, emergency, operator holds the vehicle
    VOTE = "vote"  # a QUANTITY mission: the synchronised candidates vote
    ELECTED = "elected"  # chosen: plan the mission for the winners


#: (state, trigger) -> next state; anything else is a bug
TRANSITIONS: dict[tuple[MissionState, Trigger], MissionState] = {}


def _add(froms: tuple[MissionState, ...], trigger: Trigger, to: MissionState) -> None:
    for s in froms:
        TRANSITIONS[(s, trigger)] = to


_ALL = (ID, PL, PM, M, R, PC, V)
_add((ID, PL, PM, M, R, V), Trigger.PLAN, PL)
_add((PL,), Trigger.VOTE, V)
_add((V,), Trigger.ELECTED, PL)
_add((PM, M, R), Trigger.REPLAN, R)
_add((R,), Trigger.RESUMED, M)
_add((PL, R), Trigger.RELEASED, PM)
_add((PM,), Trigger.STARTED, M)
# the autopilot started the share while a replan runs (a member was lost between the
# StartMission and its answer): fly it meanwhile, stay in REPLAN until the outcome
_add((R,), Trigger.STARTED, R)
_add((ID, PL, PM, M, R, V), Trigger.RETURN, M)
_add((ID, PL, PM, M, R, V), Trigger.TAKE_OVER, M)
_add((ID, PL, PM, M, R, V), Trigger.PARACHUTE, PC)
# PLANNING: the plan gives this vehicle nothing to fly (an area's split); it stays down
_add((PL, M, R), Trigger.COMPLETE, ID)
_add((PL, PM, R, M, V), Trigger.FAILED, ID)
_add(_ALL, Trigger.LANDED, ID)
_add(_ALL, Trigger.STOP, ID)


class IllegalMove(AssertionError):
    pass


@dataclass(frozen=True)
class Move:
    before: MissionState
    trigger: Trigger
    after: MissionState


@dataclass
class Sortie:
    state: MissionState = MissionState.IDLE
    path_m: float = 0.0  # length of the share being flown (0: no share)
    progress_m: float = 0.0  # metres of it flown
    progress_pct: int = 0
    history: list[Move] = field(default_factory=list)

    def go(self, trigger: Trigger) -> MissionState:
        new = TRANSITIONS.get((self.state, trigger))
        if new is None:
            raise IllegalMove(f"no sortie transition from {self.state.name} on {trigger.value}")
        self.history.append(Move(self.state, trigger, new))
        del self.history[:-20]
        self.state = new
        return new

    def begin(self, *, keep_progress: bool) -> None:
        """A new mission (progress from 0) or the way home (progress kept)."""
        self.go(Trigger.PLAN)
        if not keep_progress:
            self.path_m = self.progress_m = 0.0
            self.progress_pct = 0

    def advance(self, progress_m: float) -> None:
        """Progress never falls within a mission; it is held while replanning (what
        this vehicle published on entering REPLAN is what the fleet replans from)."""
        if self.path_m <= 0.0 or self.state != MissionState.MISSION:
            return
        self.progress_m = min(self.path_m, max(self.progress_m, progress_m))
        self.progress_pct = max(self.progress_pct, int(100.0 * self.progress_m / self.path_m))

    def finish(self) -> None:
        self.progress_m = self.path_m
        self.progress_pct = 100


def mermaid() -> str:
    """The sortie diagram, generated from TRANSITIONS (docs/state-machine.md)."""
    lines = ["stateDiagram-v2", "    [*] --> IDLE"]
    for (s, t), to in TRANSITIONS.items():
        lines.append(f"    {s.name} --> {to.name}: {t.value}")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    print(mermaid(), end="")
