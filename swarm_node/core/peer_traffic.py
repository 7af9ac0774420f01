"""Peers' telemetry, the node's hot path: every peer's VehicleStatus at 5 Hz (and, with
no mission, its VehicleInfo at 1 Hz) to the modules that keep it: membership (the usual
event: a known peer heard again, O(1)), collision avoidance (a contact) and the mission
manager (MUM-T's lead). NodeCore takes this route before its dispatch; a message that
changes nothing else (no peer joined) costs no more than that.

Pure: no I/O; `now` is passed in.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import msgspec

from swarm_proto import VehicleInfo, VehicleStatus

from .inputs import Input, Received
from .membership import PeerEvent, SwarmMembership
from .mission_manager import MissionManager
from .safety.module import AvoidanceModule
from .swarm.roster import Roster


@dataclass
class PeerTraffic:
    members: SwarmMembership
    avoid: AvoidanceModule
    manager: MissionManager
    roster: Roster

    def one(self, msg: msgspec.Struct, now: float) -> list[PeerEvent] | None:
        """A peer's telemetry and, with no mission, its info, to the modules that keep
        them: the membership's events (usually none). None: not such a message (it takes
        the dispatch)."""
        if type(msg) is VehicleStatus:
            self.manager.on_peer_status(msg, now)  # MUM-T: the lead's telemetry
            self.avoid.on_peer(msg, now)
            return self.members.on_status(msg, now)
        if type(msg) is VehicleInfo and self.roster.mission_id is None:
            self.avoid.on_peer(msg, now)  # no roster to answer: nothing else hears it
            return self.members.on_info(msg, now)
        return None

    def run(self, events: Sequence[Input], i: int, now: float) -> int:
        """From `events[i]`, the run of peers' statuses (and infos, with no mission: the
        messages `one` takes) that change nothing but what is kept of those peers (known
        peers heard again: the membership's usual event), taken together as `one` takes
        each; returns where the run ends."""
        run: list[VehicleStatus | VehicleInfo] = []
        statuses: list[VehicleStatus] = []
        infos = self.roster.mission_id is None
        for k in range(i, len(events)):
            event = events[k]
            if type(event) is not Received:
                break
            msg = event.msg
            if type(msg) is VehicleStatus:
                statuses.append(msg)
            elif type(msg) is not VehicleInfo or not infos:
                break
            run.append(msg)
        taken = self.members.heard_again(run, now) if run else 0
        if taken:
            if taken < len(run):
                run = run[:taken]
                statuses = [m for m in run if type(m) is VehicleStatus]
            if statuses:
                self.manager.on_peer_statuses(statuses, now)
            self.avoid.on_peers(run, now, len(statuses))
        return i + taken
