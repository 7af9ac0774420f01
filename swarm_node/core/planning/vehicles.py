"""What planners need to know about each vehicle: its profile and where it is now, and
the planned result per vehicle (geodetic waypoints the autopilot link uploads)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from swarm_node.core.autopilot.items import ItemKind, Waypoint
from swarm_node.core.profile import G_M_S2, VehicleProfile
from swarm_proto import MissionParams

from .errors import InfeasibleTimingError, InvalidParameterError, NoVehiclesError
from .geo import LocalFrame, VehiclePose
from .turns import TurnModel, turn_model_for

DEFAULT_PARAMS = MissionParams()


@dataclass(frozen=True, slots=True)
class PlanVehicle:
    profile: VehicleProfile
    pose: VehiclePose | None = None

    @property
    def vehicle_id(self) -> int:
        return self.profile.vehicle_id

    def speed_range(self) -> tuple[float, float]:
        """(min, max) commandable speed, m/s. Fixed-wing: stall * 1.1 (never below) to
        max; hover-capable: 0 to max. Max defaults to cruise."""
        p = self.profile
        hi = p.max_speed_m_s or p.cruise_speed_m_s
        lo = p.min_speed_m_s * 1.1 if p.is_fixed_wing else 0.0
        return lo, max(hi, lo)

    def speed(self, params: MissionParams) -> float:
        """The mission speed for this vehicle: the requested one clamped into its range,
        or its cruise speed."""
        lo, hi = self.speed_range()
        v = params.speed_m_s if params.speed_m_s is not None else self.profile.cruise_speed_m_s
        if not math.isfinite(v):
            raise InvalidParameterError(f"vehicle {self.vehicle_id}: speed is not finite")
        v = min(max(v, lo), hi)
        if v <= 0.0:
            raise InvalidParameterError(
                f"vehicle {self.vehicle_id}: no positive speed (cruise {self.profile.cruise_speed_m_s})"
            )
        return v

    def turns(self, speed_m_s: float) -> TurnModel:
        return turn_model_for(self.profile, speed_m_s)

    def max_speed_on_radius(self, radius_m: float) -> float:
        """The fastest speed at which this vehicle can fly a turn of `radius_m`: for a
        fixed-wing at its max bank, sqrt(R g tan(max bank)) (the inverse of
        R = v^2 / (g tan(max bank))); unbounded for vehicles that turn on the spot."""
        p = self.profile
        if not p.is_fixed_wing:
            return math.inf
        if not (math.isfinite(p.max_bank_deg) and 0.0 < p.max_bank_deg < 90.0):
            raise InvalidParameterError(
                f"vehicle {self.vehicle_id}: max bank must be in (0, 90) deg, got {p.max_bank_deg}"
            )
        if not (math.isfinite(radius_m) and radius_m >= 0.0):
            raise InvalidParameterError(f"turn radius must be >= 0, got {radius_m}")
        return math.sqrt(radius_m * G_M_S2 * math.tan(math.radians(p.max_bank_deg)))

    def speed_range_on(self, radius_m: float) -> tuple[float, float]:
        """(min, max) speed on a path whose tightest turn (or orbit) has `radius_m`: the
        speed range with the top capped by `max_speed_on_radius`, so a speed trim never
        asks for a turn tighter than the path was planned with. Raises
        `InfeasibleTimingError` if even the minimum speed needs a wider turn."""
        lo, hi = self.speed_range()
        cap = self.max_speed_on_radius(radius_m)
        if cap < lo - 1e-9:
            raise InfeasibleTimingError(
                f"vehicle {self.vehicle_id}: a {radius_m:.1f} m turn needs <= {cap:.1f} m/s, "
                f"below its minimum speed {lo:.1f} m/s"
            )
        return lo, max(min(hi, cap), lo)


def common_speed(vehicles: Sequence[PlanVehicle], params: MissionParams) -> float:
    """One speed every vehicle can fly (a formation that must keep its spacing): the
    slowest mission speed, raised to the highest minimum; `InfeasibleTimingError` if the
    speed ranges do not overlap."""
    lo = max(v.speed_range()[0] for v in vehicles)
    hi = min(v.speed_range()[1] for v in vehicles)
    if lo > hi:
        raise InfeasibleTimingError(
            f"no common speed: the vehicles' ranges do not overlap ({lo:.1f} > {hi:.1f} m/s)"
        )
    return min(max(min(v.speed(params) for v in vehicles), lo), hi)


def require_vehicles(vehicles: object) -> None:
    if not vehicles:
        raise NoVehiclesError("a plan needs at least one vehicle")
    ids = [v.vehicle_id for v in vehicles]  # type: ignore[attr-defined]
    if len(set(ids)) != len(ids):
        raise InvalidParameterError(f"duplicate vehicle ids: {sorted(ids)}")


@dataclass(frozen=True, slots=True)
class VehiclePlan:
    """One vehicle's share of a plan."""

    vehicle_id: int
    waypoints: tuple[Waypoint, ...]
    length_m: float = 0.0
    time_s: float = 0.0


def to_waypoints(
    frame: LocalFrame,
    points_xy: list[tuple[float, float]],
    alt_rel_m: float | list[float],
    *,
    speed_m_s: float | None = None,
) -> tuple[Waypoint, ...]:
    """Local points -> geodetic WAYPOINT items (a CHANGE_SPEED first if a speed is given)."""
    out: list[Waypoint] = []
    if speed_m_s is not None:
        out.append(Waypoint(ItemKind.CHANGE_SPEED, speed_m_s=speed_m_s))
    if not points_xy:
        return tuple(out)
    ll = frame.to_geodetic_many(points_xy)
    alts = alt_rel_m if isinstance(alt_rel_m, list) else [alt_rel_m] * len(points_xy)
    for (lat, lon), alt in zip(ll.tolist(), alts, strict=True):
        out.append(Waypoint(ItemKind.WAYPOINT, lat, lon, alt))
    return tuple(out)
