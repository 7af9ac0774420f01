"""The one output vocabulary of the node's modules. A module returns a list of these;
NodeCore routes each to the module that owns what it is about (node.py, `_route`), or
to the shell. Modules talk to each other only this way.

To the shell (`Output`):

    Publish(msg)               a swarm message to publish
    Submit(request, owner)     an autopilot request, once the arbiter has ruled on it
    Note(level, text)          a log line
    PlanJob(request)           planning to run off the control loop (mission/share.py)
    Persist(state, sortie)     the declared state to store (it survives a restart)
    ToAutopilot(data)          a passthrough session's frames to write to the autopilot
    ToClient(session, data)    frames to a passthrough session's client (passthrough.py)
    Sessions(ids)              the passthrough sessions open: the autopilot's frames go to them
    StreamWish(rates)          the sessions' stream rates wanted of the autopilot link

Inside the node:

    Submit(request, owner)     an autopilot request of `owner`: the arbiter gives it its
                               id, rules on it and routes its result back to the owner
    Claim / Release / Suspend / Delegate
                               control of the autopilot (the arbiter's inputs, defined
                               in arbiter.py)
    Post(event)                an event for the swarm state machine (its owner: the
                               mission coordinator)
    Answer(ack)                an ack to publish that answers repeats of what it
                               answers (the operator desk remembers it)
    Declared(msg)              a declaration every node keeps (a declaring command, a
                               mission accepted), to the declarations
    Ended(mission_id)          a mission no longer in force, to the declarations
    Accepted(mission)          a mission that passed the acceptance checks: in force
    Candidacy(mission)         a QUANTITY mission that passed them: tasking answers it
    Regrouping(cmd)            JOIN_MISSION / SWAP_MISSION addressed to this vehicle
    Heard(msg)                 a message to take as if heard (a mission a target report
                               derived)
    SetBase, SetFleet, LeftFleet
                               this vehicle's base and fleet, to the declarations
    SetActive(active)          the operator's active flag (the state machine's Shutdown)
    TakeOver, StopLanding      the operator flies the vehicle: to the mission manager
    BeginEmergency             to the emergency procedure
    PeerLost(vid, why)         a peer left the swarm: avoidance, the roster
    SilentShare(vid, points)   the rest of a silent member's held share: avoidance
    Stalled(seconds)           the node's own stall: vehicle monitoring (not a link loss)
    PublishInfo()              publish our VehicleInfo now, not at the next second
    Recheck(why, restore)      a ground station changed the backstop's settings: the fences
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import msgspec

from swarm_proto import AlertCode, Command, GeoPoint, Mission, Severity

# the arbiter's inputs, re-exported: every module's output vocabulary is here
from .arbiter import Claim as Claim
from .arbiter import Delegate as Delegate
from .arbiter import Owner as Owner
from .arbiter import Release as Release
from .arbiter import Submit as Submit
from .arbiter import Suspend as Suspend
from .arbiter import ToArbiter
from .mission.phases import Phase
from .mission.share import PlanRequest

if TYPE_CHECKING:
    from swarm_proto import Ack, DeclaredState

    from . import state_machine as fsm
    from .declared import SortieRecord


# ----------------------------------------------------------------------- to the shell
@dataclass(frozen=True)
class Publish:
    msg: msgspec.Struct


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


@dataclass(frozen=True)
class ToAutopilot:
    """A passthrough session's frames, written to the autopilot as they came."""

    data: bytes


@dataclass(frozen=True)
class ToClient:
    """Frames for a passthrough session's client (the node answering for the autopilot)."""

    session_id: int
    data: bytes


@dataclass(frozen=True)
class Sessions:
    """The passthrough sessions open now: the shell relays the autopilot's frames to
    each (none: it stops keeping them)."""

    ids: tuple[int, ...]


@dataclass(frozen=True)
class StreamWish:
    """Message rates the sessions want of the autopilot (name, Hz): the link asks for the
    faster of its own and these; withdrawn ones go back to its own."""

    rates: tuple[tuple[str, float], ...]


# ----------------------------------------------------------------------- between modules
@dataclass(frozen=True)
class Post:
    event: fsm.Event


@dataclass(frozen=True)
class Answer:
    ack: Ack


@dataclass(frozen=True)
class Declared:
    msg: Command | Mission


@dataclass(frozen=True)
class Ended:
    mission_id: int


@dataclass(frozen=True)
class Accepted:
    mission: Mission


@dataclass(frozen=True)
class Candidacy:
    mission: Mission


@dataclass(frozen=True)
class Regrouping:
    command: Command


@dataclass(frozen=True)
class Heard:
    msg: msgspec.Struct


@dataclass(frozen=True)
class SetBase:
    point: GeoPoint


@dataclass(frozen=True)
class SetFleet:
    fleet_id: int


@dataclass(frozen=True)
class LeftFleet:
    """This vehicle left its fleet (the state machine's LeaveFleet): fleet 0."""


@dataclass(frozen=True)
class SetActive:
    active: bool


@dataclass(frozen=True)
class TakeOver:
    """The operator's command flies the vehicle out of its mission: the mission manager
    only watches for the landing (`phase`), the state machine gets `Recalled`."""

    reason: str
    phase: Phase


@dataclass(frozen=True)
class StopLanding:
    """ABORT_LANDING: the mission manager stops bringing the vehicle down."""


@dataclass(frozen=True)
class BeginEmergency:
    code: AlertCode
    severity: Severity


@dataclass(frozen=True)
class PeerLost:
    vehicle_id: int
    why: str


@dataclass(frozen=True)
class SilentShare:
    """What is left of a silent member's share (its held lanes), for avoidance to
    predict it along: (lat, lon, height above its home) in order, at `speed_m_s`."""

    vehicle_id: int
    points: tuple[tuple[float, float, float], ...]
    speed_m_s: float = 0.0


@dataclass(frozen=True)
class Stalled:
    seconds: float


@dataclass(frozen=True)
class PublishInfo:
    pass


@dataclass(frozen=True)
class Recheck:
    """A ground station changed what the backstop keeps (a fence or rally upload, a
    FENCE_* parameter) through passthrough: the fence and rally point are checked as
    after a reboot; `restore`: the fence is uploaded again first (a setting a download
    cannot see)."""

    why: str
    restore: bool = False


# the routing table: which module takes which output (NodeCore._route)
# to the shell (a Submit once ruled on)
Output = (
    Publish | Submit | Note | PlanJob | Persist | ToAutopilot | ToClient | Sessions | StreamWish
)
ToShell = Publish | Note | PlanJob | Persist | ToAutopilot | ToClient | Sessions | StreamWish
ToMission = Post | Accepted | Candidacy | Regrouping | TakeOver | StopLanding  # the coordinator
ToDeclarations = Declared | Ended | SetBase | SetFleet | LeftFleet
ToOperator = Answer | SetActive  # the operator desk
# and: PeerLost (avoidance and the roster), SilentShare (avoidance), Stalled (monitoring), BeginEmergency (the
# emergency procedure), Recheck (the fences), Heard, PublishInfo (NodeCore itself)
ModuleOutput = (
    ToShell
    | ToArbiter
    | ToMission
    | ToDeclarations
    | ToOperator
    | PeerLost
    | SilentShare
    | Stalled
    | BeginEmergency
    | Recheck
    | Heard
    | PublishInfo
)
