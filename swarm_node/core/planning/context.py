"""What every planner plans from, in one object (`PlanContext`): the mission's geometry
and parameters, the vehicles (profile and pose), the no-fly zones in force at
`now_unix_s` (their altitudes taken above `home_alt_msl_m`, kept `zone_margin_m` clear)
and the local frame to plan in (default: the geometry's). plan_area, plan_target,
plan_perimeter, plan_route, plan_objective and plan_autoland take it first; what only
one planner needs stays a keyword of that planner."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from swarm_proto import Geometry, MissionParams, NoFlyZone

from .geo import LocalFrame
from .vehicles import DEFAULT_PARAMS, PlanVehicle
from .zones import ZoneSet


@dataclass(frozen=True)
class PlanContext:
    geometry: Geometry
    vehicles: Sequence[PlanVehicle]
    params: MissionParams = DEFAULT_PARAMS
    zones: Sequence[NoFlyZone] = ()
    now_unix_s: float = 0.0
    home_alt_msl_m: float = 0.0
    zone_margin_m: float = 0.0
    frame: LocalFrame | None = None

    def local_frame(self) -> LocalFrame:
        """The frame to plan in: the one given, else the geometry's."""
        return self.frame or LocalFrame.for_geometry(self.geometry)

    def zone_set(self, frame: LocalFrame) -> ZoneSet:
        """The zones in force, in `frame`, kept `zone_margin_m` clear."""
        return ZoneSet.from_messages(
            self.zones,
            frame,
            now_unix_s=self.now_unix_s,
            home_alt_msl_m=self.home_alt_msl_m,
            margin_m=self.zone_margin_m,
        )
