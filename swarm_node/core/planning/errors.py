"""Errors of the planning library. Every planner raises a `PlanningError` subclass (also
a `ValueError`) for input it cannot plan: the caller's misuse, never a crash deeper in."""

from __future__ import annotations

from swarm_proto import ReasonDetail


class PlanningError(ValueError):
    """Base class: the input cannot be planned. `detail`: the numbers behind it, for the
    ground station (an endurance budget), when there are any."""

    detail: ReasonDetail | None = None


class InvalidGeometryError(PlanningError):
    """Self-intersecting, degenerate, non-finite or wrong-kind geometry."""


class EmptyAreaError(PlanningError):
    """Nothing left to plan: zero area, or everything is cut out by holes and zones."""


class NoVehiclesError(PlanningError):
    """A planner was asked to plan for zero vehicles (or unknown vehicle ids)."""


class InvalidParameterError(PlanningError):
    """A parameter is out of range (NaN, negative spacing, speeds that do not fit...)."""


class TargetInZoneError(PlanningError):
    """A mission point (target, objective, landing base, route point) is inside a no-fly
    zone."""


class NoSafeRouteError(PlanningError):
    """No route avoids the no-fly zones within the vehicle's limits: replan the mission."""


class InfeasibleTimingError(PlanningError):
    """Simultaneous arrival or a landing sequence cannot be met within the speed ranges."""


class FieldTooBigError(PlanningError):
    """The area would take longer to fly than the vehicles can: refused before planning,
    with the estimated flight time."""

    def __init__(self, message: str, estimated_s: float) -> None:
        super().__init__(message)
        self.estimated_s = estimated_s
