"""A node that starts while its vehicle flies: the node process restarted
(a crash, kill -9, a watchdog), the vehicle flew on under ArduPilot with the share the
node had uploaded. The node reattaches without sending the vehicle anywhere and
without arming anything:

1. it waits for its autopilot (a HEARTBEAT: armed or not) and, if the vehicle is armed
   and its database holds the share it was flying (`SortieRecord`), reads the
   autopilot's mission back (DownloadMission) and waits `settle_s` to hear its peers;
2. it decides (`decide`, pure):

   - CONTINUE: the autopilot still holds that share (same item count) in AUTO, and no
     peer flies the mission with a roster that left this vehicle out: it takes the
     share up again where the autopilot is (the state machine's `Reattached`, the
     mission manager's `reattach`), completes it and flies home as usual; a share
     already flown (the autopilot past its last item) completes at once;
   - HAND_ON: a peer flies the mission with a newer roster without this vehicle (they
     noticed its loss and inherited its share), or the vehicle left AUTO:
     it leaves the fleet and flies the zone-safe way home (`LeftFleet`);
   - with no share on record (a new database, a disk that was full), or a share of ours
     on the autopilot other than the one on record (a replan uploaded as the node
     died), a share of ours on the autopilot (it ends on the unlimited loiter every
     share ends on) in a mode the node flies it in (AUTO, or GUIDED: an avoidance
     manoeuvre) while peers fly a mission: they took it over since the node vanished,
     HAND_ON;
   - LEAVE: the vehicle is flying something that is not a share of ours (a different
     mission on the autopilot, no peer on a mission): nothing is commanded, the
     operator is told.

The same hand-on applies to a node that was stopped (SIGSTOP, a frozen host) long
enough for its fleet to replan without it: `dropped` tells it from a peer's members
hash (the next roster generation without this vehicle).

Pure: inputs and `now` in, `ModuleOutput`s out (requests as `Submit(owner REATTACH)`:
downloads never take control of the vehicle).
"""

from __future__ import annotations

import itertools
import logging
from collections.abc import Iterable
from dataclasses import dataclass, field
from enum import Enum

import msgspec

from swarm_proto import Alert, AlertCode, FsmState, Severity, VehicleInfo
from swarm_proto.text import short_text

from .autopilot.mission_item import MavCmd, MissionItem
from .autopilot.requests import ApResult, DownloadMission, MissionKind
from .autopilot.state import AutopilotState
from .declared import SortieRecord
from .outputs import ModuleOutput, Note, Owner, Publish, Submit
from .swarm.roster import members_hash

SETTLE_S = 2.5  # hear every peer's VehicleInfo (1 Hz) before deciding
GIVE_UP_S = 60.0  # no state machine ready by then: leave the vehicle to the operator
RETRY_S = 3.0
AUTO_MODES = frozenset({"AUTO"})
# the modes a node flies its share in: its mission, an avoidance manoeuvre (a pilot's
# modes, LOITER or STABILIZE, are the operator's)
OWN_MODES = frozenset({"AUTO", "GUIDED"})


class Decision(Enum):
    CONTINUE = "continue"
    HAND_ON = "hand on"
    LEAVE = "leave"


def dropped(
    self_id: int, mission_id: int, planned: Iterable[int], generation: int, theirs: int
) -> bool:
    """Whether a peer's members hash is the next roster generation without this vehicle
    (the fleet replanned its share away while it was gone)."""
    rest = [m for m in planned if m != self_id]
    return bool(rest) and theirs == members_hash(mission_id, rest, generation + 1)


def ends_on_a_loiter(held: tuple[MissionItem, ...]) -> bool:
    """The signature of a share a bandada node uploaded: it ends on an unlimited loiter
    over its last waypoint (mission_manager.py)."""
    return len(held) > 2 and held[-1].command == MavCmd.NAV_LOITER_UNLIM


def decide(
    self_id: int,
    record: SortieRecord | None,
    held: tuple[MissionItem, ...],
    ap: AutopilotState,
    peers: Iterable[VehicleInfo],
) -> tuple[Decision, str]:
    """What to do with a vehicle found flying, and why (pure)."""
    peers = list(peers)
    flying = [
        i.vehicle_id
        for i in peers
        if i.vehicle_id != self_id
        and i.mission_id
        and i.fsm_state in (FsmState.PLAN, FsmState.GO_MISSION)
    ]
    # a share of ours on the autopilot, flown as the node flies it, while peers fly a
    # mission: they have taken it over since we vanished
    ours = ap.mode_name in OWN_MODES and ends_on_a_loiter(held) and bool(flying)
    if record is None:
        if ours:
            return Decision.HAND_ON, (
                f"no share on record; its share's signature on the autopilot "
                f"({ap.mode_name}) while {flying[0]} flies a mission"
            )
        return Decision.LEAVE, "flying, with no share of ours on record"
    if len(held) != record.items:
        if ours:
            return Decision.HAND_ON, (
                f"a share of ours on the autopilot ({len(held)} items, not the "
                f"{record.items} on record) while {flying[0]} flies a mission"
            )
        return Decision.LEAVE, (
            f"the autopilot holds {len(held)} mission items, not the share of mission "
            f"{record.mission_id} ({record.items})"
        )
    for info in peers:
        if info.vehicle_id == self_id or info.mission_id != record.mission_id:
            continue
        if info.fsm_state not in (FsmState.PLAN, FsmState.GO_MISSION):
            continue
        if info.members_hash and info.members_hash != record.members_hash:
            return Decision.HAND_ON, f"vehicle {info.vehicle_id} flies a newer roster"
    if ap.mode_name not in AUTO_MODES:
        return Decision.HAND_ON, f"the vehicle is in {ap.mode_name or 'an unknown mode'}"
    return Decision.CONTINUE, "nobody took its share over"


class Stage(Enum):
    WAITING = "waiting for the autopilot"
    READING = "reading the autopilot's mission"
    DECIDING = "hearing the peers"
    DONE = "done"


@dataclass
class Reattacher:
    vehicle_id: int
    record: SortieRecord | None = None
    stage: Stage = Stage.DONE
    decision: Decision | None = None
    why: str = ""
    held: tuple[MissionItem, ...] = ()
    _due: float = 0.0
    _give_up_at: float = 0.0
    _in_flight: int | None = None
    _ids: itertools.count[int] = field(default_factory=lambda: itertools.count(1))

    def start(self, record: SortieRecord | None, now: float) -> None:
        """The node started (its database read): reattach if the vehicle flies."""
        self.record, self.stage, self.decision = record, Stage.WAITING, None
        self._give_up_at = now + GIVE_UP_S

    @property
    def active(self) -> bool:
        return self.stage != Stage.DONE

    def on_autopilot(self, ap: AutopilotState, now: float) -> list[ModuleOutput]:
        if self.stage != Stage.WAITING or not ap.link_ok or ap.last_heartbeat_s is None:
            return []
        if not ap.armed:  # on the ground: a normal start
            self.stage = Stage.DONE
            return []
        self.stage = Stage.READING
        return self._read(now)

    def _read(self, now: float) -> list[ModuleOutput]:
        rid = next(self._ids)
        self._in_flight = rid
        return [Submit(DownloadMission(kind=MissionKind.MISSION, request_id=rid), Owner.REATTACH)]

    def on_result(self, result: ApResult, now: float) -> list[ModuleOutput]:
        if result.request_id != self._in_flight:
            return []
        self._in_flight = None
        if not result.ok:
            self._due = now + RETRY_S  # read it again
            return [Note(logging.INFO, f"reattach: mission not read ({result.reason})")]
        self.held = result.items
        self.stage, self._due = Stage.DECIDING, now + SETTLE_S
        return []

    def on_timer(
        self,
        ap: AutopilotState,
        peers: Iterable[VehicleInfo],
        fsm_state: FsmState,
        now: float,
    ) -> tuple[Decision | None, list[ModuleOutput]]:
        """The decision once it is due and the state machine can take it (GO_MISSION)."""
        if self.stage == Stage.READING and self._in_flight is None and now >= self._due:
            return None, self._read(now)
        if self.stage != Stage.DECIDING or now < self._due:
            return None, []
        if fsm_state != FsmState.GO_MISSION:
            if now >= self._give_up_at:
                why = f"not ready to fly ({fsm_state.name})"
                return Decision.LEAVE, self._finish(Decision.LEAVE, why, now)
            return None, []
        decision, why = decide(self.vehicle_id, self.record, self.held, ap, peers)
        return decision, self._finish(decision, why, now)

    def _finish(self, decision: Decision, why: str, now: float) -> list[ModuleOutput]:
        self.stage, self.decision, self.why = Stage.DONE, decision, why
        mid = self.record.mission_id if self.record else 0
        text = {
            Decision.CONTINUE: f"reattached: continues its share of mission {mid}",
            Decision.HAND_ON: f"reattached: hands its share of mission {mid} on, returns",
            Decision.LEAVE: "reattached: flying, left to the operator",
        }[decision]
        severity = Severity.INFO if decision == Decision.CONTINUE else Severity.WARNING
        return [
            Note(logging.WARNING, f"{text} ({why})"),
            Publish(
                Alert(self.vehicle_id, max(0.0, now), severity, AlertCode.GENERIC, short_text(text))
            ),
        ]

    def next_deadline(self) -> float | None:
        if self.stage in (Stage.READING, Stage.DECIDING) and self._in_flight is None:
            return self._due
        return None


def sortie_record(
    *,
    mission_id: int | None,
    flying: bool,
    members: tuple[int, ...],
    planned: tuple[int, ...],
    generation: int,
    members_hash_: int,
    items: int,
    last_item: int,
    path_m: float,
    progress_m: float,
    now: float,
) -> SortieRecord | None:
    """The record of the share flown now (None: not flying a share)."""
    if not flying or mission_id is None or mission_id <= 0 or items <= 1:
        return None
    return SortieRecord(
        mission_id,
        members,
        planned,
        generation,
        members_hash_,
        items,
        last_item,
        path_m,
        progress_m,
        max(0.0, now),
    )


def same_share(a: SortieRecord | None, b: SortieRecord | None) -> bool:
    """Equal but for progress and time (what is worth storing again)."""
    if a is None or b is None:
        return a is b
    keep = {"progress_m": 0.0, "updated_unix_s": 0.0}
    return msgspec.structs.replace(a, **keep) == msgspec.structs.replace(b, **keep)
