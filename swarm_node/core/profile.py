"""What a node knows about a vehicle's airframe and payload: resolved from the swarm
database (swarm_node.database) and handed to the pure cores (planners, voting,
monitoring, avoidance) as plain data. Units in the names."""

from __future__ import annotations

import math

import msgspec

from swarm_proto import VehicleType

G_M_S2 = 9.80665


class CameraProfile(msgspec.Struct, frozen=True):
    hfov_deg: float
    vfov_deg: float
    resolution_px: tuple[int, int] = (0, 0)  # width, height
    gimbal_axes: int = 0


class PayloadClass(msgspec.Struct, frozen=True):
    """Where a payload model sits in the payload hierarchy (type -> subtype -> model):
    what the voting compares (paper section 2.3.6). Empty strings: no payload."""

    type: str = ""
    subtype: str = ""
    model: str = ""


class VehicleProfile(msgspec.Struct, frozen=True):
    """Airframe + payload parameters of one vehicle (paper section 2.3.1 tables)."""

    vehicle_id: int  # the database's internal system id = swarm node id
    user_id: str
    model: str
    vehicle_type: VehicleType
    system_type: str = ""  # e.g. "UAV", "UGV", "USV", "GCS"
    system_subtype: str = ""  # e.g. "fixed-wing", "multirotor"
    payload_model: str = ""
    payload_subtype: str = ""
    payload_type: str = ""
    cruise_speed_m_s: float = 0.0
    min_speed_m_s: float = 0.0  # stall speed for fixed-wing, 0 for hover-capable
    max_speed_m_s: float = 0.0
    max_bank_deg: float = 45.0
    climb_rate_m_s: float = 0.0
    sink_rate_m_s: float = 0.0
    loiter_radius_m: float = 0.0
    has_parachute: bool = False
    battery_low_pct: int = 30
    battery_critical_pct: int = 15
    max_tilt_deg: float = 60.0  # abnormal-attitude threshold (roll or pitch)
    camera: CameraProfile | None = None
    max_altitude_m: float = 0.0  # ceiling above mean sea level; 0 = unknown
    max_wind_m_s: float = 0.0  # wind the airframe is rated for; 0 = unknown
    wingspan_m: float = 0.0  # span (fixed-wing), frame diagonal (multirotor) or width
    battery_capacity_mah: float = 0.0  # 0 = unknown (no endurance limit in planning)
    cruise_current_a: float = 0.0  # drawn at cruise speed (level flight / driving)
    hover_current_a: float = 0.0  # drawn by the lift motors at hover (0: none)
    accel_m_s2: float = 0.0  # horizontal acceleration when stopping on waypoints; 0 = unknown

    @property
    def payload_class(self) -> PayloadClass:
        return PayloadClass(self.payload_type, self.payload_subtype, self.payload_model)

    @property
    def is_fixed_wing(self) -> bool:
        return self.vehicle_type in (VehicleType.PLANE, VehicleType.VTOL)

    @property
    def can_hover(self) -> bool:
        return self.vehicle_type in (
            VehicleType.COPTER,
            VehicleType.VTOL,
            VehicleType.ROVER,
            VehicleType.BOAT,
        )

    def turn_radius_m(self, speed_m_s: float | None = None) -> float:
        """Minimum turn radius at `speed_m_s` (default cruise): v^2 / (g tan(max bank)),
        and never below the loiter radius. 0 for vehicles that turn on the spot."""
        if not self.is_fixed_wing:
            return 0.0
        v = self.cruise_speed_m_s if speed_m_s is None else speed_m_s
        r = v * v / (G_M_S2 * math.tan(math.radians(self.max_bank_deg)))
        return max(r, self.loiter_radius_m)


def with_autopilot_battery(profile: VehicleProfile, capacity_mah: int) -> VehicleProfile:
    """The profile planning uses: the battery the vehicle's autopilot says it has (its
    BATT_CAPACITY, published in VehicleInfo.battery_capacity_mah) over the database's
    figure for the model; unchanged when the autopilot has not said (0)."""
    if capacity_mah <= 0 or float(capacity_mah) == profile.battery_capacity_mah:
        return profile
    return msgspec.structs.replace(profile, battery_capacity_mah=float(capacity_mah))


def published_capacity_mah(capacity_mah: float | None) -> int:
    """The autopilot's battery as VehicleInfo carries it (whole mAh; 0 = not known)."""
    if capacity_mah is None or not math.isfinite(capacity_mah) or capacity_mah <= 0:
        return 0
    return min(1_000_000, round(capacity_mah))
