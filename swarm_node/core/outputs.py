"""The one output vocabulary of the node's modules (and of NodeCore itself):

    Publish(msg)               a swarm message to publish
    Submit(owner, request)     an autopilot request on behalf of `owner` (the arbiter
                               gives it its id and routes its result back to the owner)
    Post(event)                an event for the swarm state machine
    Note(level, text)          a log line
    PlanJob(request)           planning to run off the control loop (mission/share.py)
    Persist(state, sortie)     the declared state to store (it survives a restart)

A module returns a list of these; NodeCore routes them: `Post` to the state machine,
`Submit` through the `AutopilotArbiter`, the rest to the shell.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import IntEnum
from typing import TYPE_CHECKING

import msgspec

from .autopilot.requests import ApRequest
from .mission.share import PlanRequest

if TYPE_CHECKING:
    from swarm_proto import DeclaredState

    from . import state_machine as fsm
    from .declared import SortieRecord


class Owner(IntEnum):
    """Who asks the autopilot, in precedence order (higher wins control)."""

    FENCE = 1
    MISSION = 2
    OPERATOR = 3
    AVOIDANCE = 4
    EMERGENCY = 5


@dataclass(frozen=True)
class Publish:
    msg: msgspec.Struct


@dataclass(frozen=True)
class Submit:
    """`owner` ranks the request (precedence); `route` (default: the owner) is the
    module its result goes back to: the mission manager landing a vehicle the operator
    recalled asks with the operator's rank and gets the answer itself."""

    request: ApRequest
    owner: Owner = Owner.OPERATOR
    route: Owner | None = None


@dataclass(frozen=True)
class Post:
    event: fsm.Event


@dataclass(frozen=True)
class Note:
    """Something worth a log line (membership changes, transitions, rejections)."""

    level: int
    text: str


@dataclass(frozen=True)
class PlanJob:
    """Planning to run off the control loop (`mission.share.run_plan`); the shell hands
    the outcome back as the node input `PlanDone`."""

    request: PlanRequest


@dataclass(frozen=True)
class Persist:
    """What the operator declared as this node holds it, and the share it flies, for
    the shell to store in the node's database (restored at start; a store
    that fails comes back as the node input `StoreResult`)."""

    state: DeclaredState
    sortie: SortieRecord | None = None


ModuleOutput = Publish | Submit | Post | Note | PlanJob | Persist
