"""The node's output routes, NodeCore's other half (node.py routes the inputs and keeps
time): each output a module returns goes to the module that takes it (the table is in
outputs.py: ToArbiter, ToMission, ToDeclarations, ToOperator, ...) or to the shell,
and what that module answers is routed next, depth first; the arbiter's outcomes go
on to the owner of the request (a result, a suspension) or to the shell (a request to
send).

Pure: no I/O; `now` is passed in.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import assert_never

import msgspec

from . import outputs
from .arbiter import AutopilotArbiter, Outcome, Owner, Routed, Send, Suspended
from .declarations import Declarations
from .emergency import EmergencyProcedure
from .fences import Fences
from .mission.coordinator import SILENT, MissionCoordinator
from .monitoring import VehicleMonitor
from .operator import OperatorDesk
from .outputs import ModuleOutput, Output, Persist, Publish, Submit
from .passthrough import Passthrough
from .safety.module import AvoidanceModule
from .views import Views


@dataclass
class Routes:
    arbiter: AutopilotArbiter
    mission: MissionCoordinator
    declarations: Declarations
    operator: OperatorDesk
    avoid: AvoidanceModule
    emergency: EmergencyProcedure
    fences: Fences
    monitor: VehicleMonitor
    views: Views
    heard: Callable[[msgspec.Struct, float], list[ModuleOutput]]  # NodeCore's, for Heard
    passthrough: Passthrough  # the ground stations' MAVLink sessions (their results)

    def route(self, outs: list[ModuleOutput], now: float, sink: list[Output]) -> None:
        """Each output to the module that takes it, or to the shell (`sink`)."""
        if not outs:
            return
        todo = list(outs)
        while todo:
            o, back = todo.pop(0), []
            if isinstance(o, outputs.ToShell):
                sink.append(o)
            elif isinstance(o, outputs.ToArbiter):
                back = self._ruled(self.arbiter.rule(o), now, sink)
            elif isinstance(o, outputs.ToMission):
                back = self.mission.take(o, self.views.context, now)
            elif isinstance(o, outputs.ToDeclarations):
                self.declarations.take(o, now)
            elif isinstance(o, outputs.ToOperator):
                back = self.operator.take(o)
            elif isinstance(o, outputs.SilentShare):
                self.avoid.silent_route(o, now)
            elif isinstance(o, outputs.Stalled):
                self.monitor.note_stall(o.seconds)
            elif isinstance(o, outputs.PeerLost):
                if o.why in SILENT:  # still an aircraft: its predicted position
                    self.avoid.silent(o.vehicle_id, now)
                else:
                    self.avoid.forget(o.vehicle_id, now)
                back = self.mission.peer_lost(o.vehicle_id, o.why, self.views.context, now)
            elif isinstance(o, outputs.BeginEmergency):
                ap, d = self.monitor.state, self.declarations
                zones = d.zones.no_fly(now)
                back = self.emergency.start(o.code, o.severity, ap, d.base, zones, now)
            elif isinstance(o, outputs.Heard):
                back = self.heard(o.msg, now)
            elif isinstance(o, outputs.PublishInfo):
                sink.append(Publish(self.views.info()))
            elif isinstance(o, outputs.Recheck):
                back = self.fences.recheck(o.why, o.restore, now)
            else:
                assert_never(o)
            todo[0:0] = back

    def persist(self, sink: list[Output], now: float) -> None:
        """After a step: the share flown kept on record, and the declared state stored
        when it (or that record) changed."""
        changed = self.mission.keep_record(now)
        if self.declarations.take_store() or changed:
            state = self.declarations.snapshot(now, self.mission.fsm.mission_id)
            sink.append(Persist(state, self.mission.record))

    def result(self, routed: Routed, now: float) -> list[ModuleOutput]:
        """A result to the module that asked: the request's owner (arbiter.py)."""
        owner, result = routed.owner, routed.result
        match owner:
            case Owner.FENCE | Owner.BACKSTOP:
                return self.fences.on_result(owner, result, self.monitor.state, now)
            case Owner.MISSION | Owner.REATTACH:
                return self.mission.on_result(owner, result, now)
            case Owner.OPERATOR if self.passthrough.owns(result.request_id):
                return self.passthrough.on_result(result, self.views.node_view(), now)
            case Owner.OPERATOR:
                return self.operator.on_result(result, now)
            case Owner.AVOIDANCE:
                return self.avoid.on_result(result, now)
            case Owner.EMERGENCY:
                return self.emergency.on_result(result, now)
            case _:
                assert_never(owner)

    def _ruled(self, outcomes: list[Outcome], now: float, sink: list[Output]) -> list[ModuleOutput]:
        """The arbiter's outcomes: requests to send (to the shell), results and
        suspensions to their owners (whose answers are routed next)."""
        back: list[ModuleOutput] = []
        for oc in outcomes:
            if isinstance(oc, Send):
                sink.append(Submit(oc.request, oc.owner))
            elif isinstance(oc, Routed):
                back += self.result(oc, now)
            elif isinstance(oc, Suspended):
                back += self.mission.on_suspended(oc.on, now)  # the suspended owner's
            else:
                assert_never(oc)
        return back
