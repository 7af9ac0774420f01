"""Turn models: how a vehicle gets from the end of one leg to the start of the next.

The coverage and route planners take a `TurnModel`, so the turn behaviour is chosen per
vehicle type: fixed-wing aircraft fly Dubins curves at their minimum turn radius;
multirotors, rovers and boats turn on the spot and fly straight.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from swarm_node.core.profile import VehicleProfile

from .dubins import FloatArray, Pose, batch_lengths, shortest_path
from .errors import InvalidParameterError


class TurnModel(Protocol):
    @property
    def radius_m(self) -> float: ...

    def length(self, a: Pose, b: Pose) -> float:
        """Length (m) of the transition from pose `a` to pose `b`."""
        ...

    def cost_matrix(self, ends: FloatArray, starts: FloatArray) -> FloatArray:
        """Transition lengths from each (x, y, yaw) row of `ends` to each row of
        `starts`: an (n, m) matrix."""
        ...

    def points(self, a: Pose, b: Pose) -> list[Pose]:
        """Poses to hand a waypoint follower between `a` (excluded) and `b` (included)."""
        ...


@dataclass(frozen=True, slots=True)
class DubinsTurns:
    """Forward-only turns at a minimum radius (fixed-wing)."""

    radius_m: float

    def __post_init__(self) -> None:
        if not (math.isfinite(self.radius_m) and self.radius_m > 0.0):
            raise InvalidParameterError(f"turn radius must be > 0, got {self.radius_m}")

    def length(self, a: Pose, b: Pose) -> float:
        return shortest_path(a, b, self.radius_m).length_m

    def cost_matrix(self, ends: FloatArray, starts: FloatArray) -> FloatArray:
        out = batch_lengths(ends[:, None, :], starts[None, :, :], self.radius_m)
        assert isinstance(out, np.ndarray)
        return out

    def points(self, a: Pose, b: Pose) -> list[Pose]:
        return shortest_path(a, b, self.radius_m).waypoints()


@dataclass(frozen=True, slots=True)
class PointTurns:
    """Turn on the spot, fly straight (multirotor, rover, boat)."""

    @property
    def radius_m(self) -> float:
        return 0.0

    def length(self, a: Pose, b: Pose) -> float:
        return math.hypot(b.x - a.x, b.y - a.y)

    def cost_matrix(self, ends: FloatArray, starts: FloatArray) -> FloatArray:
        return np.hypot(
            ends[:, None, 0] - starts[None, :, 0], ends[:, None, 1] - starts[None, :, 1]
        )

    def points(self, a: Pose, b: Pose) -> list[Pose]:
        return [b]


def turn_model_for(profile: VehicleProfile, speed_m_s: float | None = None) -> TurnModel:
    """Dubins turns at the profile's minimum radius for fixed-wing, point turns otherwise."""
    r = profile.turn_radius_m(speed_m_s)
    return DubinsTurns(r) if r > 0.0 else PointTurns()
