"""What the node's modules read of one another, and what the node publishes about
itself, assembled from the modules that own each value. Read-only: it owns nothing.

    node_view()     the operator desk's NodeView (commands, the acceptance checks)
    context()       the mission coordinator's Context
    facts()         the state machine's facts that other modules own
    status(now)     this vehicle's VehicleStatus (5 Hz)
    info()          this vehicle's VehicleInfo (1 Hz)
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from swarm_proto import AlertFlag, VehicleInfo, VehicleStatus

from .autopilot.status import to_vehicle_status
from .commands import NodeView
from .declarations import Declarations
from .membership import SwarmMembership
from .mission.coordinator import Context, MissionCoordinator
from .monitoring import VehicleMonitor
from .operator import OperatorDesk
from .profile import VehicleProfile
from .reports import vehicle_info
from .safety.module import AvoidanceModule
from .state_machine import Facts


@dataclass
class Views:
    profile: VehicleProfile
    monitor: VehicleMonitor  # the autopilot's latest state, readiness, alerts
    declarations: Declarations  # base, fleet, zones
    members: SwarmMembership  # the peers
    operator: OperatorDesk  # the active flag
    mission: MissionCoordinator  # the state machine, the sortie
    avoid: AvoidanceModule  # a manoeuvre flown

    def node_view(self) -> NodeView:
        fsm, m, d, mon = self.mission.fsm, self.mission.manager, self.declarations, self.monitor
        ap = mon.state
        return NodeView(
            self.profile.vehicle_id,
            d.fleet_id,
            self.profile,
            ap,
            fsm.state,
            fsm.mission_id,
            d.base,
            mon.ready,
            landing=m.landing,
            touching_down=m.touching_down,
            not_ready=mon.not_ready_text(ap),
        )

    def context(self) -> Context:
        d, mon = self.declarations, self.monitor
        return Context(
            mon.state,
            self.members.peers,
            d.base,
            d.fleet_id,
            self.operator.active,
            mon.ready,
            d.zones,
            d.mission_on_record,
        )

    def facts(self) -> Facts:
        mon = self.monitor
        return Facts(
            active=self.operator.active,
            base_set=self.declarations.base is not None,
            vehicle_ready=mon.ready,
            emergency=mon.emergency,
            armed=mon.state.armed,
        )

    def status(self, now: float) -> VehicleStatus | None:
        """This vehicle's VehicleStatus (None until the autopilot has a position)."""
        mon, sortie = self.monitor, self.mission.manager.sortie
        return to_vehicle_status(
            mon.state,
            vehicle_id=self.profile.vehicle_id,
            now_unix_s=now,
            fsm_state=self.mission.fsm.state,
            mission_state=sortie.state,
            mission_progress=sortie.progress_pct,
            fleet_id=self.declarations.fleet_id,
            alerts=mon.flags | (AlertFlag.COLLISION_RISK if self.avoid.active else 0),
        )

    def info(self) -> VehicleInfo:
        ap, d = self.monitor.state, self.declarations
        return vehicle_info(
            self.profile,
            ap,
            self.mission.report(ap),
            base=d.base,
            fleet_id=d.fleet_id,
            errors=self.monitor.active_codes,
        )


def module_view(path: str) -> Any:
    """A read-only property reaching a module's public state from the node
    (`mission.fsm`): what the shells and tests read, without keeping it themselves."""
    names = path.split(".")

    def get(self: object) -> object:
        for n in names:
            self = getattr(self, n)
        return self

    return property(get, doc=f"read-only: {path}")
