"""The one output vocabulary of the node's modules (and of NodeCore itself):

    Publish(msg)               a swarm message to publish
    Submit(request, owner)     an autopilot request of `owner` (the arbiter gives it its
                               id, rules on it and routes its result back to the owner)
    Claim / Release / Suspend / Delegate
                               control of the autopilot, to the arbiter (arbiter.py)
    Post(event)                an event for the swarm state machine
    Note(level, text)          a log line
    PlanJob(request)           planning to run off the control loop (mission/share.py)
    Persist(state, sortie)     the declared state to store (it survives a restart)

A module returns a list of these; NodeCore routes them: `Post` to the state machine's
owner, `Submit` and control through the `AutopilotArbiter`, the rest to the shell.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import msgspec

from .arbiter import Owner
from .autopilot.requests import ApRequest
from .mission.share import PlanRequest

if TYPE_CHECKING:
    from swarm_proto import DeclaredState

    from . import state_machine as fsm
    from .declared import SortieRecord


@dataclass(frozen=True)
class Publish:
    msg: msgspec.Struct


@dataclass(frozen=True)
class Submit:
    """An autopilot request of `owner`: the arbiter ranks it by its owner (or the rank
    delegated to it) and routes its result back to it."""

    request: ApRequest
    owner: Owner


@dataclass(frozen=True)
class Claim:
    """`owner` takes control of the autopilot (an emergency begins)."""

    owner: Owner


@dataclass(frozen=True)
class Release:
    """`owner` gives control back (to whoever held it before a suspension it began)."""

    owner: Owner


@dataclass(frozen=True)
class Suspend:
    """Avoidance takes control and suspends the mission; `passing`: the mission's
    requests go on under the manoeuvre (flown on its path) instead of being held."""

    passing: bool


@dataclass(frozen=True)
class Delegate:
    """`to` asks with `rank`'s precedence until `rank` releases control."""

    to: Owner
    rank: Owner


Control = Claim | Release | Suspend | Delegate


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


ModuleOutput = (
    Publish | Submit | Claim | Release | Suspend | Delegate | Post | Note | PlanJob | Persist
)
