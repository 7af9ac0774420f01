"""The node's inbound message table, NodeCore's input half for swarm messages: each
message kind to the module that owns what it says (the router in node.py hands every
`Received` here). A message no route takes is counted in `unhandled` and logged once,
never dropped silently.

Pure: no I/O; `now` is passed in.
"""

from __future__ import annotations

import logging
from collections import Counter
from dataclasses import dataclass, field

import msgspec

import swarm_proto as proto
from swarm_proto import VehicleInfo, VehicleStatus
from swarm_proto.messages import MavlinkCommand, MavlinkSession

from .declarations import Declarations
from .membership import SwarmMembership
from .mission.coordinator import MissionCoordinator
from .operator import OperatorDesk
from .outputs import ModuleOutput, Note
from .passthrough import Passthrough
from .peer_traffic import PeerTraffic
from .safety.module import AvoidanceModule
from .stalls import StallGuard
from .views import Views


@dataclass
class Inbound:
    members: SwarmMembership
    traffic: PeerTraffic
    stalls: StallGuard
    avoid: AvoidanceModule
    mission: MissionCoordinator
    operator: OperatorDesk
    declarations: Declarations
    passthrough: Passthrough
    views: Views
    unhandled: Counter[str] = field(default_factory=Counter)  # counted, logged once

    def message(self, msg: msgspec.Struct, now: float) -> list[ModuleOutput]:
        match msg:
            case VehicleStatus():
                return self.stalls.peer_events(self.traffic.one(msg, now) or [], now)
            case VehicleInfo():  # (with a mission: the roster hears it too)
                self.avoid.on_peer(msg, now)
                out = self.stalls.peer_events(self.members.on_info(msg, now), now)
                return out + self.mission.on_info(msg, self.views.context, now)
            case proto.VehicleIntent():  # a peer's next legs: its avoidance prediction
                self.avoid.on_intent(msg, now)
                return []
            case proto.Command():
                return self.operator.on_command(
                    msg, self.views.node_view(), self.declarations.zones.no_fly(now), now
                )
            case proto.Mission():
                self.mission.heard_mission(msg)  # a vehicle may be told to join it later
                return self.operator.on_mission(msg, self.views.node_view())
            case proto.NoFlyZone():  # (a new zone: fenced once routed)
                return self.declarations.on_zone(msg, now)
            case proto.FleetAssignment():
                return self.declarations.on_assignment(msg, now)
            case (
                proto.Ack() | proto.Vote() | proto.TargetReport() | proto.PlanLineage()
            ):  # roster, tasking, regroup
                return self.mission.on_message(msg, self.views.context, now)
            case MavlinkSession():
                return self.passthrough.on_session(msg, now)
            case MavlinkCommand():  # a radio passthrough session's
                return self.passthrough.on_radio(msg, self.views.node_view(), now)
            case proto.Alert() | proto.SwarmView():
                self.unhandled[type(msg).__name__] += 1  # declared: not for the node yet
                return []
            case _:
                kind = type(msg).__name__
                return self.no_route(kind, f"message {kind}")

    def no_route(self, kind: str, what: str) -> list[ModuleOutput]:
        self.unhandled[kind] += 1
        if self.unhandled[kind] == 1:
            return [Note(logging.WARNING, f"no route for {what} (counted in unhandled)")]
        return []
