"""ArduPilot firmware facts as data: which modes exist per firmware, what each mode does
in the simulator, whether it needs a position estimate, whether it allows arming, the
HEARTBEAT base_mode flags, MAV_TYPE, and the exact STATUSTEXT wording.

Mode numbers and names come from `swarm_proto.ardupilot`. The base_mode values, texts
and boot sequence match the recorded ArduPilot SITL sorties in
../shared/data/ardupilot-sitl (master of 2025-07-21).
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import IntEnum

from swarm_proto.ardupilot import COPTER_MODES, PLANE_MODES, ROVER_MODES

from .airframes import VehicleModel


class Firmware(IntEnum):
    PLANE = 1
    COPTER = 2
    ROVER = 3


FIRMWARE_OF: dict[VehicleModel, Firmware] = {
    VehicleModel.PLANE: Firmware.PLANE,
    VehicleModel.VTOL: Firmware.PLANE,
    VehicleModel.COPTER: Firmware.COPTER,
    VehicleModel.ROVER: Firmware.ROVER,
    VehicleModel.BOAT: Firmware.ROVER,
}

# HEARTBEAT.type. A QuadPlane reports MAV_TYPE_FIXED_WING (recorded); a boat is Rover
# firmware with FRAME_CLASS=2.
MAV_TYPE_OF: dict[VehicleModel, int] = {
    VehicleModel.PLANE: 1,  # MAV_TYPE_FIXED_WING
    VehicleModel.VTOL: 1,
    VehicleModel.COPTER: 2,  # MAV_TYPE_QUADROTOR
    VehicleModel.ROVER: 10,  # MAV_TYPE_GROUND_ROVER
    VehicleModel.BOAT: 11,  # MAV_TYPE_SURFACE_BOAT
}

MAV_AUTOPILOT_ARDUPILOTMEGA = 3

# MAV_MODE_FLAG bits
SAFETY_ARMED = 128
MANUAL_INPUT = 64
STABILIZE = 16
GUIDED = 8
CUSTOM_MODE = 1


class Behaviour(IntEnum):
    """What a mode makes the simulated vehicle do (there is no pilot in the simulator)."""

    MANUAL = 0  # no autonomous navigation: hold height and heading, or stop
    HOLD = 1  # hold position (copter LOITER/POSHOLD/BRAKE, rover HOLD/LOITER, Q hover)
    GUIDED = 2  # fly to the guided target, then hold there
    AUTO = 3  # run the mission
    RTL = 4  # return to launch (firmware-specific)
    LAND = 5  # land here (copter LAND, QuadPlane QLAND)
    CIRCLE = 6  # circle around a point
    LOITER = 7  # fixed-wing: loiter around here
    TAKEOFF = 8  # fixed-wing TAKEOFF mode
    QRTL = 9  # QuadPlane: return, then land vertically
    INITIALISING = 10  # plane/rover boot mode; not selectable


@dataclass(frozen=True, slots=True)
class ModeSpec:
    number: int
    name: str
    behaviour: Behaviour
    requires_position: bool = False
    armable: bool = True  # ArduCopter allows_arming(), ArduPlane Mode::pre_arm_checks()
    vtol: bool = False  # QuadPlane Q-mode: flown on the lift motors
    selectable: bool = True


def _table(names: dict[int, str], specs: dict[str, dict[str, object]]) -> dict[int, ModeSpec]:
    table: dict[int, ModeSpec] = {}
    for number, name in names.items():
        kw = specs.get(name)
        if kw is None:
            continue  # in the name table but not built into this firmware: "No such mode"
        table[number] = ModeSpec(number=number, name=name, **kw)  # type: ignore[arg-type]
    return table


_M, _H, _G, _A, _R = (
    Behaviour.MANUAL,
    Behaviour.HOLD,
    Behaviour.GUIDED,
    Behaviour.AUTO,
    Behaviour.RTL,
)

COPTER: dict[int, ModeSpec] = _table(
    COPTER_MODES,
    {
        "STABILIZE": {"behaviour": _M},
        "ACRO": {"behaviour": _M},
        "ALT_HOLD": {"behaviour": _M},
        "AUTO": {"behaviour": _A, "requires_position": True, "armable": False},
        "GUIDED": {"behaviour": _G, "requires_position": True},
        "LOITER": {"behaviour": _H, "requires_position": True},
        "RTL": {"behaviour": _R, "requires_position": True, "armable": False},
        "CIRCLE": {"behaviour": Behaviour.CIRCLE, "requires_position": True, "armable": False},
        "LAND": {"behaviour": Behaviour.LAND, "armable": False},
        "DRIFT": {"behaviour": _M, "requires_position": True},
        "SPORT": {"behaviour": _M},
        "FLIP": {"behaviour": _M, "armable": False},
        "AUTOTUNE": {"behaviour": _H, "armable": False},
        "POSHOLD": {"behaviour": _H, "requires_position": True},
        "BRAKE": {"behaviour": _H, "requires_position": True, "armable": False},
        "THROW": {"behaviour": _H, "requires_position": True},
        "AVOID_ADSB": {"behaviour": _G, "requires_position": True, "armable": False},
        "GUIDED_NOGPS": {"behaviour": _M},
        "SMART_RTL": {"behaviour": _R, "requires_position": True, "armable": False},
        "FLOWHOLD": {"behaviour": _H},
        "FOLLOW": {"behaviour": _H, "requires_position": True, "armable": False},
        "ZIGZAG": {"behaviour": _H, "requires_position": True},
        "SYSTEMID": {"behaviour": _M, "armable": False},
        "AUTO_RTL": {"behaviour": _R, "requires_position": True, "armable": False},
        "TURTLE": {"behaviour": _M, "armable": False},
    },
)

PLANE: dict[int, ModeSpec] = _table(
    PLANE_MODES,
    {
        "MANUAL": {"behaviour": _M},
        "CIRCLE": {"behaviour": Behaviour.CIRCLE},
        "STABILIZE": {"behaviour": _M},
        "TRAINING": {"behaviour": _M},
        "ACRO": {"behaviour": _M},
        "FBWA": {"behaviour": _M},
        "FBWB": {"behaviour": _M},
        "CRUISE": {"behaviour": _M},
        "AUTOTUNE": {"behaviour": _M},
        "AUTO": {"behaviour": _A, "requires_position": True},
        "RTL": {"behaviour": _R, "requires_position": True, "armable": False},
        "LOITER": {"behaviour": Behaviour.LOITER, "requires_position": True},
        "TAKEOFF": {"behaviour": Behaviour.TAKEOFF, "requires_position": True},
        "AVOID_ADSB": {"behaviour": _G, "requires_position": True},
        "GUIDED": {"behaviour": _G, "requires_position": True},
        "INITIALISING": {
            "behaviour": Behaviour.INITIALISING,
            "armable": False,
            "selectable": False,
        },
        "QSTABILIZE": {"behaviour": _H, "vtol": True},
        "QHOVER": {"behaviour": _H, "vtol": True},
        "QLOITER": {"behaviour": _H, "requires_position": True, "vtol": True},
        "QLAND": {"behaviour": Behaviour.LAND, "armable": False, "vtol": True},
        "QRTL": {
            "behaviour": Behaviour.QRTL,
            "requires_position": True,
            "armable": False,
            "vtol": True,
        },
        "QAUTOTUNE": {"behaviour": _H, "vtol": True},
        "QACRO": {"behaviour": _H, "vtol": True},
        "THERMAL": {"behaviour": Behaviour.LOITER, "requires_position": True},
        "LOITERALTQLAND": {"behaviour": Behaviour.LAND, "requires_position": True, "vtol": True},
    },
)

ROVER: dict[int, ModeSpec] = _table(
    ROVER_MODES,
    {
        "MANUAL": {"behaviour": _M},
        "ACRO": {"behaviour": _M},
        "STEERING": {"behaviour": _M},
        "HOLD": {"behaviour": _H},
        "LOITER": {"behaviour": _H, "requires_position": True},
        "FOLLOW": {"behaviour": _H, "requires_position": True},
        "SIMPLE": {"behaviour": _M},
        "DOCK": {"behaviour": _H, "requires_position": True},
        "CIRCLE": {"behaviour": Behaviour.CIRCLE, "requires_position": True},
        "AUTO": {"behaviour": _A, "requires_position": True},
        "RTL": {"behaviour": _R, "requires_position": True},
        "SMART_RTL": {"behaviour": _R, "requires_position": True},
        "GUIDED": {"behaviour": _G, "requires_position": True},
        "INITIALISING": {
            "behaviour": Behaviour.INITIALISING,
            "armable": False,
            "selectable": False,
        },
    },
)

MODES: dict[Firmware, dict[int, ModeSpec]] = {
    Firmware.PLANE: PLANE,
    Firmware.COPTER: COPTER,
    Firmware.ROVER: ROVER,
}


def mode_number(firmware: Firmware, name: str) -> int:
    for number, spec in MODES[firmware].items():
        if spec.name == name:
            return number
    raise KeyError(f"{firmware.name} has no mode {name}")


# Boot: the mode before the vehicle is ready, and the one it settles in (the recorded
# QuadPlane went INITIALISING -> MANUAL -> FBWA, its RC mode switch position; the quad
# booted in STABILIZE; Rover's INITIAL_MODE default is MANUAL).
BOOT_MODE: dict[Firmware, int] = {Firmware.PLANE: 16, Firmware.COPTER: 0, Firmware.ROVER: 16}
INITIAL_MODE: dict[Firmware, int] = {Firmware.PLANE: 5, Firmware.COPTER: 0, Firmware.ROVER: 0}

_COPTER_POS_MODES_ALWAYS = {
    "GUIDED",
    "LAND",
    "LOITER",
    "POSHOLD",
    "BRAKE",
    "CIRCLE",
    "FOLLOW",
    "AVOID_ADSB",
    "ZIGZAG",
    "THROW",
}
_COPTER_POS_MODES_ARMED = {"AUTO", "RTL", "SMART_RTL", "AUTO_RTL"}
_PLANE_GUIDED_FLAG = {
    "AUTO",
    "RTL",
    "LOITER",
    "THERMAL",
    "AVOID_ADSB",
    "GUIDED",
    "CIRCLE",
    "TAKEOFF",
    "QRTL",
    "LOITERALTQLAND",
    "AUTOLAND",
}
_ROVER_MANUAL_INPUT = {"MANUAL", "ACRO", "STEERING", "SIMPLE"}
_ROVER_AUTOPILOT = {"AUTO", "GUIDED", "RTL", "SMART_RTL", "LOITER", "FOLLOW", "DOCK", "CIRCLE"}


def base_mode(firmware: Firmware, spec: ModeSpec, armed: bool) -> int:
    """HEARTBEAT.base_mode as ArduPilot computes it (values seen in the recordings:
    copter 81/89/217, plane 17/81/89/209/217)."""
    armed_bit = SAFETY_ARMED if armed else 0
    if firmware == Firmware.COPTER:
        # GUIDED_ENABLED while the position controller runs
        pos = spec.name in _COPTER_POS_MODES_ALWAYS or (
            armed and spec.name in _COPTER_POS_MODES_ARMED
        )
        return CUSTOM_MODE | STABILIZE | MANUAL_INPUT | (GUIDED if pos else 0) | armed_bit
    if firmware == Firmware.PLANE:
        if spec.behaviour == Behaviour.INITIALISING:
            return CUSTOM_MODE | STABILIZE
        flag = GUIDED if spec.name in _PLANE_GUIDED_FLAG else 0
        return CUSTOM_MODE | STABILIZE | MANUAL_INPUT | flag | armed_bit
    flags = CUSTOM_MODE
    if spec.name in _ROVER_MANUAL_INPUT:
        flags |= MANUAL_INPUT
    if spec.name in _ROVER_AUTOPILOT:
        flags |= GUIDED
    return flags | armed_bit


# STATUSTEXT wording (recorded or from the ArduPilot sources)
ARM_TEXT: dict[Firmware, str] = {
    Firmware.COPTER: "Arming motors",
    Firmware.PLANE: "Throttle armed",
    Firmware.ROVER: "Throttle armed",
}
DISARM_TEXT: dict[Firmware, str] = {
    Firmware.COPTER: "Disarming motors",
    Firmware.PLANE: "Throttle disarmed",
    Firmware.ROVER: "Throttle disarmed",
}

# (seconds after boot, severity, text); the copter and plane sequences as recorded (at
# SITL speed-up 4), with GPS and EKF use moved earlier: see `StartupTimes`.
BOOT_TEXTS: dict[Firmware, tuple[tuple[float, int, str], ...]] = {
    Firmware.COPTER: (
        (0.8, 6, "Barometer 1 calibration complete"),
        (0.8, 6, "Barometer 2 calibration complete"),
        (1.3, 6, "ArduPilot Ready"),
        (1.3, 6, "AHRS: DCM active"),
        (3.3, 6, "EKF3 IMU0 initialised"),
        (3.3, 6, "EKF3 IMU1 initialised"),
        (3.3, 6, "AHRS: EKF3 active"),
        (4.6, 6, "EKF3 IMU1 tilt alignment complete"),
        (4.6, 6, "EKF3 IMU0 tilt alignment complete"),
        (4.8, 6, "EKF3 IMU1 MAG0 initial yaw alignment complete"),
        (4.8, 6, "EKF3 IMU0 MAG0 initial yaw alignment complete"),
    ),
    Firmware.PLANE: (
        (1.2, 6, "Barometer 1 calibration complete"),
        (1.2, 6, "Barometer 2 calibration complete"),
        (1.2, 6, "Airspeed 1 calibration started"),
        (1.2, 6, "ArduPilot Ready"),
        (1.2, 6, "AHRS: DCM active"),
        (2.8, 6, "Airspeed 1 calibrated"),
        (3.3, 6, "EKF3 IMU0 initialised"),
        (3.3, 6, "EKF3 IMU1 initialised"),
        (4.6, 6, "EKF3 IMU1 tilt alignment complete"),
        (4.6, 6, "EKF3 IMU0 tilt alignment complete"),
        (4.8, 6, "EKF3 IMU1 MAG0 initial yaw alignment complete"),
        (4.8, 6, "EKF3 IMU0 MAG0 initial yaw alignment complete"),
    ),
    Firmware.ROVER: (
        (0.8, 6, "Barometer 1 calibration complete"),
        (1.3, 6, "ArduPilot Ready"),
        (1.3, 6, "AHRS: DCM active"),
        (3.3, 6, "EKF3 IMU0 initialised"),
        (3.3, 6, "EKF3 IMU1 initialised"),
        (3.3, 6, "AHRS: EKF3 active"),
        (4.6, 6, "EKF3 IMU1 tilt alignment complete"),
        (4.6, 6, "EKF3 IMU0 tilt alignment complete"),
        (4.8, 6, "EKF3 IMU1 MAG0 initial yaw alignment complete"),
        (4.8, 6, "EKF3 IMU0 MAG0 initial yaw alignment complete"),
    ),
}
GPS_DETECTED_TEXTS = ("GPS 1: probing for u-blox at 230400 baud", "GPS 1: detected u-blox")
EKF_ORIGIN_TEXTS = (
    "EKF3 IMU1 origin set",
    "Field Elevation Set: {alt:.0f}m",
    "EKF3 IMU0 origin set",
)
EKF_GPS_TEXTS = ("EKF3 IMU0 is using GPS", "EKF3 IMU1 is using GPS")

# MAV_SEVERITY
SEV_CRITICAL = 2
SEV_WARNING = 4
SEV_NOTICE = 5
SEV_INFO = 6

# AP_Mission::Mission_Command::type()
MISSION_CMD_NAMES: dict[int, str] = {
    16: "WP",
    82: "SplineWP",
    20: "RTL",
    17: "LoitUnlim",
    19: "LoitTime",
    92: "GuidedEnable",
    18: "LoitTurns",
    31: "LoitAltitude",
    213: "SetYawSpd",
    112: "CondDelay",
    114: "CondDist",
    178: "ChangeSpeed",
    179: "SetHome",
    183: "SetServo",
    181: "SetRelay",
    184: "RepeatServo",
    182: "RepeatRelay",
    200: "CtrlVideo",
    202: "DigiCamCfg",
    203: "DigiCamCtrl",
    206: "SetCamTrigDst",
    201: "SetROI",
    194: "SetReverse",
    215: "SetRepeatDist",
    222: "GuidedLimits",
    22: "Takeoff",
    21: "Land",
    30: "ContinueAndChangeAlt",
    83: "AltitudeWait",
    84: "VTOLTakeoff",
    85: "VTOLLand",
    210: "InvertedFlight",
    207: "FenceEnable",
    212: "AutoTuneEnable",
    3000: "VTOLTransition",
    223: "EngineControl",
    115: "CondYaw",
    189: "LandStart",
    93: "Delay",
    211: "Gripper",
    94: "PayloadPlace",
    208: "Parachute",
    216: "Sprayer",
    218: "AuxFunction",
    205: "MountControl",
    42600: "Winch",
    217: "Scripting",
    177: "Jump",
    191: "Go Around",
    42702: "NavScriptTime",
    42703: "NavAttitudeTime",
    193: "PauseContinue",
    1000: "GimbalPitchYaw",
}
