"""ArduPilot facts every process needs: flight-mode numbers per vehicle type (the
HEARTBEAT custom_mode carried in VehicleStatus.ap_mode) and MAV_TYPE -> VehicleType.

Mode names are MAVProxy's (pymavlink mavutil.mode_mapping_*). A QuadPlane reports
MAV_TYPE_FIXED_WING in its HEARTBEAT (seen in ../shared/data/ardupilot-sitl), so VTOL
is known from the swarm database, not from the autopilot.
"""

from __future__ import annotations

from .enums import VehicleType

PLANE_MODES: dict[int, str] = {
    0: "MANUAL",
    1: "CIRCLE",
    2: "STABILIZE",
    3: "TRAINING",
    4: "ACRO",
    5: "FBWA",
    6: "FBWB",
    7: "CRUISE",
    8: "AUTOTUNE",
    10: "AUTO",
    11: "RTL",
    12: "LOITER",
    13: "TAKEOFF",
    14: "AVOID_ADSB",
    15: "GUIDED",
    16: "INITIALISING",
    17: "QSTABILIZE",
    18: "QHOVER",
    19: "QLOITER",
    20: "QLAND",
    21: "QRTL",
    22: "QAUTOTUNE",
    23: "QACRO",
    24: "THERMAL",
    25: "LOITERALTQLAND",
    26: "AUTOLAND",
}
COPTER_MODES: dict[int, str] = {
    0: "STABILIZE",
    1: "ACRO",
    2: "ALT_HOLD",
    3: "AUTO",
    4: "GUIDED",
    5: "LOITER",
    6: "RTL",
    7: "CIRCLE",
    8: "POSITION",
    9: "LAND",
    10: "OF_LOITER",
    11: "DRIFT",
    13: "SPORT",
    14: "FLIP",
    15: "AUTOTUNE",
    16: "POSHOLD",
    17: "BRAKE",
    18: "THROW",
    19: "AVOID_ADSB",
    20: "GUIDED_NOGPS",
    21: "SMART_RTL",
    22: "FLOWHOLD",
    23: "FOLLOW",
    24: "ZIGZAG",
    25: "SYSTEMID",
    26: "AUTOROTATE",
    27: "AUTO_RTL",
    28: "TURTLE",
}
ROVER_MODES: dict[int, str] = {
    0: "MANUAL",
    1: "ACRO",
    2: "LEARNING",
    3: "STEERING",
    4: "HOLD",
    5: "LOITER",
    6: "FOLLOW",
    7: "SIMPLE",
    8: "DOCK",
    9: "CIRCLE",
    10: "AUTO",
    11: "RTL",
    12: "SMART_RTL",
    15: "GUIDED",
    16: "INITIALISING",
}

MODES: dict[VehicleType, dict[int, str]] = {
    VehicleType.PLANE: PLANE_MODES,
    VehicleType.VTOL: PLANE_MODES,
    VehicleType.COPTER: COPTER_MODES,
    VehicleType.ROVER: ROVER_MODES,
    VehicleType.BOAT: ROVER_MODES,
}

# MAV_TYPE values (common.xml)
_MAV_TYPE_TO_VEHICLE: dict[int, VehicleType] = {
    1: VehicleType.PLANE,  # FIXED_WING (also ArduPlane QuadPlanes)
    2: VehicleType.COPTER,  # QUADROTOR
    3: VehicleType.COPTER,  # COAXIAL
    4: VehicleType.COPTER,  # HELICOPTER
    6: VehicleType.GCS,
    10: VehicleType.ROVER,  # GROUND_ROVER
    11: VehicleType.BOAT,  # SURFACE_BOAT
    13: VehicleType.COPTER,  # HEXAROTOR
    14: VehicleType.COPTER,  # OCTOROTOR
    15: VehicleType.COPTER,  # TRICOPTER
    19: VehicleType.VTOL,  # VTOL_TAILSITTER_DUOROTOR
    20: VehicleType.VTOL,  # VTOL_TAILSITTER_QUADROTOR
    21: VehicleType.VTOL,  # VTOL_TILTROTOR
    22: VehicleType.VTOL,  # VTOL_FIXEDROTOR
    23: VehicleType.VTOL,  # VTOL_TAILSITTER
    24: VehicleType.VTOL,  # VTOL_TILTWING
    29: VehicleType.COPTER,  # DODECAROTOR
    35: VehicleType.COPTER,  # DECAROTOR
}


def vehicle_type_from_mav_type(mav_type: int) -> VehicleType:
    return _MAV_TYPE_TO_VEHICLE.get(mav_type, VehicleType.OTHER)


#: HEARTBEAT vehicle types an autopilot paired with a node of each identity may report
#: (a QuadPlane reports FIXED_WING, so a VTOL node takes a PLANE or a VTOL autopilot)
FITS: dict[VehicleType, frozenset[VehicleType]] = {
    VehicleType.PLANE: frozenset({VehicleType.PLANE}),
    VehicleType.VTOL: frozenset({VehicleType.PLANE, VehicleType.VTOL}),
    VehicleType.COPTER: frozenset({VehicleType.COPTER}),
    VehicleType.ROVER: frozenset({VehicleType.ROVER}),
    VehicleType.BOAT: frozenset({VehicleType.BOAT}),
}


def autopilot_mismatch(identity: VehicleType, mav_type: int) -> str | None:
    """Why an autopilot whose HEARTBEAT says `mav_type` does not fit a node whose
    identity (swarm database) is `identity`, or None when it fits or cannot be told
    (no HEARTBEAT yet, a MAV_TYPE this table does not know, a GCS or manned identity)."""
    seen = vehicle_type_from_mav_type(mav_type)
    allowed = FITS.get(identity)
    if mav_type == 0 or seen == VehicleType.OTHER or allowed is None or seen in allowed:
        return None
    return f"autopilot is {seen.name} (MAV_TYPE {mav_type}), identity {identity.name}"


def mode_name(vehicle_type: VehicleType, number: int) -> str:
    """The mode's name, or "MODE(n)" when this vehicle type has no such mode."""
    return MODES.get(vehicle_type, {}).get(number, f"MODE({number})")


def mode_number(vehicle_type: VehicleType, name: str) -> int:
    """The custom_mode number of a mode name (case-insensitive); ValueError if unknown."""
    table = MODES.get(vehicle_type)
    if table is None:
        raise ValueError(f"{vehicle_type.name} has no ArduPilot modes")
    wanted = name.strip().upper()
    for number, mode in table.items():
        if mode == wanted:
            return number
    raise ValueError(
        f"{vehicle_type.name} has no mode {name!r}; known: {', '.join(table.values())}"
    )
