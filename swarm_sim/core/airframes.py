"""Airframe parameters of the simulated vehicles, with the named defaults every part of
bandada shares (the swarm database seeds the same values).

Units are in the field names. Speeds are true airspeed for fixed-wing flight and ground
speed for hovering and ground vehicles. Where ArduPilot has a parameter for a value its
name is given in the comment (e.g. WPNAV_SPEED), with the ArduPilot default unless the
airframe needs another value.
"""

from __future__ import annotations

from enum import StrEnum

import msgspec


class VehicleModel(StrEnum):
    """The kinematic model (and ArduPilot firmware) a simulated vehicle runs."""

    PLANE = "plane"  # ArduPlane, fixed-wing only
    VTOL = "vtol"  # ArduPlane QuadPlane: vertical take-off/landing, fixed-wing cruise
    COPTER = "copter"  # ArduCopter multirotor
    ROVER = "rover"  # ArduRover ground vehicle
    BOAT = "boat"  # ArduRover firmware, FRAME_CLASS=2 (MAV_TYPE_SURFACE_BOAT)


class CameraParams(msgspec.Struct, frozen=True):
    """A gimbal-stabilised camera payload."""

    model: str
    hfov_deg: float
    vfov_deg: float
    resolution_px: tuple[int, int]
    gimbal_axes: int  # stabilised axes (2: roll and pitch)
    pitch_min_deg: float = -90.0
    pitch_max_deg: float = 0.0


class BatteryParams(msgspec.Struct, frozen=True):
    cells: int
    capacity_mah: float
    idle_current_a: float  # armed or disarmed on the ground, avionics only
    hover_current_a: float = 0.0  # multirotor / VTOL lift motors at hover
    cruise_current_a: float = 0.0  # fixed-wing level cruise, or ground vehicle at cruise
    internal_resistance_ohm: float = 0.01


class AirframeParams(msgspec.Struct, frozen=True, kw_only=True):
    """Everything the kinematic models and the autopilot emulation need."""

    model: VehicleModel
    name: str
    mass_kg: float
    # horizontal motion
    cruise_speed_m_s: float  # fixed-wing: AIRSPEED_CRUISE; copter: WPNAV_SPEED; rover: CRUISE_SPEED
    max_speed_m_s: float  # fixed-wing: AIRSPEED_MAX; others: the top speed
    min_airspeed_m_s: float = 0.0  # fixed-wing: AIRSPEED_MIN (the controller never goes below)
    stall_speed_m_s: float = 0.0  # fixed-wing stall speed at `mass_kg`
    max_bank_deg: float = 45.0  # fixed-wing: ROLL_LIMIT_DEG
    accel_m_s2: float = 2.5  # horizontal acceleration limit (copter WPNAV_ACCEL)
    turn_rate_deg_s: float = 90.0  # rover/boat yaw rate limit; copter yaw rate
    # vertical motion
    climb_rate_m_s: float  # copter WPNAV_SPEED_UP; fixed-wing TECS_CLMB_MAX
    sink_rate_m_s: float  # copter WPNAV_SPEED_DN; fixed-wing TECS_SINK_MAX
    land_speed_m_s: float = 0.5  # copter LAND_SPEED, QuadPlane Q_LAND_SPEED: final descent
    land_final_alt_m: float = 10.0  # below this height the final land speed applies
    # VTOL (QuadPlane) lift system
    vtol_speed_m_s: float = 0.0  # Q_WP_SPEED: horizontal speed in VTOL flight
    vtol_climb_rate_m_s: float = 0.0  # Q_WP_SPEED_UP
    vtol_sink_rate_m_s: float = 0.0  # Q_WP_SPEED_DN
    transition_accel_m_s2: float = 3.0  # forward acceleration during a transition
    transition_time_s: float = 5.0  # Q_TRANSITION_MS: from transition airspeed to done
    # navigation defaults
    wp_radius_m: float = 2.0  # WP_RADIUS / WPNAV_RADIUS: waypoint acceptance
    loiter_radius_m: float = 0.0  # WP_LOITER_RAD (fixed-wing), 0 to hover on the spot
    rtl_alt_m: float = 15.0  # RTL_ALT (copter) / RTL_ALTITUDE (plane), above home
    takeoff_alt_m: float = 30.0  # TKOFF_ALT, for TAKEOFF mode
    # payload and safety
    battery: BatteryParams
    camera: CameraParams | None = None
    has_parachute: bool = False
    parachute_sink_m_s: float = 5.0
    parachute_min_alt_m: float = 10.0  # CHUTE_ALT_MIN
    max_altitude_m: float = 4000.0  # service ceiling, above sea level

    @property
    def is_fixed_wing(self) -> bool:
        return self.model in (VehicleModel.PLANE, VehicleModel.VTOL)

    @property
    def can_hover(self) -> bool:
        return self.model in (VehicleModel.COPTER, VehicleModel.VTOL)

    @property
    def is_ground(self) -> bool:
        return self.model in (VehicleModel.ROVER, VehicleModel.BOAT)


ALBATROSS_CAMERA = CameraParams(
    model="2-axis gyrostabilised 1.5 Mpx camera",
    hfov_deg=62.0,
    vfov_deg=48.0,
    resolution_px=(1440, 1080),
    gimbal_axes=2,
)

# The paper's reference aircraft (Aerospace 2025, 12(8), 702, section 3): Albatross 250
# VTOL, 2.5 m span, 12.5 kg, 12S, cruise 26 m/s and stall 15.5 m/s at 12.5 kg, ceiling
# 4800 m, 2-axis gyrostabilised camera. The lift system figures are ArduPilot QuadPlane
# defaults (Q_WP_SPEED 5 m/s, Q_WP_SPEED_UP 2.5, Q_WP_SPEED_DN 1.5, Q_LAND_SPEED 0.5,
# Q_LAND_FINAL_ALT 6 m), which the recorded SITL sortie also shows.
ALBATROSS_250_VTOL = AirframeParams(
    model=VehicleModel.VTOL,
    name="Albatross 250 VTOL",
    mass_kg=12.5,
    cruise_speed_m_s=26.0,
    max_speed_m_s=32.0,
    min_airspeed_m_s=18.0,  # AIRSPEED_MIN above the 15.5 m/s stall; transition completes here
    stall_speed_m_s=15.5,
    max_bank_deg=45.0,
    climb_rate_m_s=5.0,
    sink_rate_m_s=5.0,
    land_speed_m_s=0.5,
    land_final_alt_m=6.0,
    vtol_speed_m_s=5.0,
    vtol_climb_rate_m_s=2.5,
    vtol_sink_rate_m_s=1.5,
    transition_accel_m_s2=3.0,
    transition_time_s=5.0,
    wp_radius_m=90.0,  # ArduPlane WP_RADIUS default
    loiter_radius_m=60.0,  # ArduPlane WP_LOITER_RAD default
    rtl_alt_m=100.0,  # ArduPlane RTL_ALTITUDE default
    takeoff_alt_m=50.0,
    battery=BatteryParams(
        cells=12,
        capacity_mah=22000.0,
        idle_current_a=1.0,
        hover_current_a=70.0,
        cruise_current_a=12.0,
        internal_resistance_ohm=0.02,
    ),
    camera=ALBATROSS_CAMERA,
    has_parachute=True,
    parachute_sink_m_s=5.0,
    max_altitude_m=4800.0,
)

# A generic fixed-wing (ArduPlane defaults where they exist), for runways and catapults.
GENERIC_PLANE = AirframeParams(
    model=VehicleModel.PLANE,
    name="generic fixed-wing",
    mass_kg=4.0,
    cruise_speed_m_s=22.0,
    max_speed_m_s=30.0,
    min_airspeed_m_s=12.0,
    stall_speed_m_s=10.0,
    max_bank_deg=45.0,
    climb_rate_m_s=5.0,
    sink_rate_m_s=5.0,
    land_final_alt_m=3.0,
    wp_radius_m=90.0,
    loiter_radius_m=60.0,
    rtl_alt_m=100.0,
    takeoff_alt_m=50.0,
    battery=BatteryParams(cells=4, capacity_mah=5000.0, idle_current_a=0.5, cruise_current_a=10.0),
    camera=None,
    has_parachute=True,
)

# A generic quadcopter with ArduCopter defaults: WPNAV_SPEED 10 m/s (the recorded SITL
# quad flew its waypoints at 10 m/s), WPNAV_SPEED_UP 2.5, WPNAV_SPEED_DN 1.5,
# LAND_SPEED 0.5 below 10 m, WPNAV_RADIUS 2 m, RTL_ALT 15 m, 3S battery as in SITL.
GENERIC_QUADCOPTER = AirframeParams(
    model=VehicleModel.COPTER,
    name="generic quadcopter",
    mass_kg=1.5,
    cruise_speed_m_s=10.0,
    max_speed_m_s=15.0,
    accel_m_s2=2.5,
    turn_rate_deg_s=90.0,
    climb_rate_m_s=2.5,
    sink_rate_m_s=1.5,
    land_speed_m_s=0.5,
    land_final_alt_m=10.0,
    wp_radius_m=2.0,
    loiter_radius_m=0.0,
    rtl_alt_m=15.0,
    takeoff_alt_m=10.0,
    battery=BatteryParams(cells=3, capacity_mah=3300.0, idle_current_a=0.3, hover_current_a=30.0),
    camera=CameraParams(
        model="2-axis gimbal camera",
        hfov_deg=78.0,
        vfov_deg=62.0,
        resolution_px=(1920, 1080),
        gimbal_axes=2,
    ),
    has_parachute=False,
)

# A generic rover (ArduRover defaults: CRUISE_SPEED 2 m/s, WP_RADIUS 2 m).
GENERIC_ROVER = AirframeParams(
    model=VehicleModel.ROVER,
    name="generic rover",
    mass_kg=5.0,
    cruise_speed_m_s=2.0,
    max_speed_m_s=5.0,
    accel_m_s2=1.0,
    turn_rate_deg_s=90.0,
    climb_rate_m_s=0.0,
    sink_rate_m_s=0.0,
    wp_radius_m=2.0,
    rtl_alt_m=0.0,
    takeoff_alt_m=0.0,
    battery=BatteryParams(cells=4, capacity_mah=10000.0, idle_current_a=0.3, cruise_current_a=5.0),
    camera=None,
)

# A generic boat (ArduRover firmware with FRAME_CLASS=2).
GENERIC_BOAT = AirframeParams(
    model=VehicleModel.BOAT,
    name="generic boat",
    mass_kg=15.0,
    cruise_speed_m_s=3.0,
    max_speed_m_s=6.0,
    accel_m_s2=0.5,
    turn_rate_deg_s=30.0,
    climb_rate_m_s=0.0,
    sink_rate_m_s=0.0,
    wp_radius_m=3.0,
    rtl_alt_m=0.0,
    takeoff_alt_m=0.0,
    battery=BatteryParams(cells=6, capacity_mah=20000.0, idle_current_a=0.3, cruise_current_a=8.0),
    camera=None,
)

DEFAULT_AIRFRAMES: dict[VehicleModel, AirframeParams] = {
    VehicleModel.PLANE: GENERIC_PLANE,
    VehicleModel.VTOL: ALBATROSS_250_VTOL,
    VehicleModel.COPTER: GENERIC_QUADCOPTER,
    VehicleModel.ROVER: GENERIC_ROVER,
    VehicleModel.BOAT: GENERIC_BOAT,
}


def default_airframe(model: VehicleModel | str) -> AirframeParams:
    """The default airframe of a model ("plane", "vtol", "copter", "rover", "boat")."""
    return DEFAULT_AIRFRAMES[VehicleModel(model)]
