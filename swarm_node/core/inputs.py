"""What the shell feeds the node core (`NodeCore.handle`): one type per kind of input."""

from __future__ import annotations

from dataclasses import dataclass

import msgspec

from swarm_proto import DeclaredState

from .autopilot.requests import ApResult
from .autopilot.state import AutopilotState
from .declared import SortieRecord
from .identity import IdentityNews
from .mission.share import PlanOutcome


@dataclass(frozen=True)
class AutopilotUpdate:
    state: AutopilotState


@dataclass(frozen=True)
class AutopilotResult:
    result: ApResult


@dataclass(frozen=True)
class PeerAlive:
    node_id: int
    alive: bool


@dataclass(frozen=True)
class Received:
    msg: msgspec.Struct


@dataclass(frozen=True)
class BadInput:
    key: str
    error: str


@dataclass(frozen=True)
class MavlinkUp:
    """Raw MAVLink frames from a passthrough session's client (passthrough.py)."""

    session_id: int
    data: bytes


@dataclass(frozen=True)
class PlanDone:
    """A plan job's outcome (the shell ran the node's PlanJob)."""

    outcome: PlanOutcome


@dataclass(frozen=True)
class Learned:
    """Declared state from the node's own database at start (`sortie`: the share it
    was flying) or from a peer: merged, the newest stamp wins."""

    state: DeclaredState
    sortie: SortieRecord | None = None
    source: str = "peer"


@dataclass(frozen=True)
class StoreResult:
    """The shell stored (or failed to store) the last `Persist`."""

    ok: bool
    error: str = ""


Input = (
    AutopilotUpdate
    | AutopilotResult
    | PeerAlive
    | Received
    | BadInput
    | MavlinkUp
    | PlanDone
    | Learned
    | StoreResult
    | IdentityNews
)
