"""Enumerations carried in messages. Values are part of the wire contract: append only."""

from __future__ import annotations

from enum import IntEnum, IntFlag


class VehicleType(IntEnum):
    """What kind of node this is (drives mode numbers, planners and avoidance)."""

    OTHER = 0
    PLANE = 1  # fixed-wing
    VTOL = 2  # QuadPlane: vertical take-off and landing, fixed-wing cruise
    COPTER = 3  # multirotor
    ROVER = 4
    BOAT = 5
    GCS = 6  # ground control station
    MANNED = 7  # manned lead aircraft or vehicle (MUM-T), seen via telemetry or ADS-B


class GpsFix(IntEnum):
    """GPS fix type (MAVLink GPS_FIX_TYPE 0..7; PPP (8) is reported as FIX_3D)."""

    NO_GPS = 0
    NO_FIX = 1
    FIX_2D = 2
    FIX_3D = 3
    DGPS = 4
    RTK_FLOAT = 5
    RTK_FIXED = 6
    STATIC = 7


class FsmState(IntEnum):
    """Swarm state machine state (paper section 2.3.4)."""

    INACTIVE = 0  # not active, or no base defined: no transitions
    PLAN = 1  # STATE_PLAN
    GO_MISSION = 2  # STATE_GO_MISSION
    EMERGENCY = 3  # STATE_EMERGENCY


class MissionState(IntEnum):
    """Mission manager state (paper section 2.3.5)."""

    IDLE = 0
    PLANNING = 1
    VOTING = 2
    PREMISSION = 3
    MISSION = 4
    PARACHUTE = 5
    SENDING_MISSION = 6
    WAITING_MISSION = 7
    REPLAN = 8


class AlertFlag(IntFlag):
    """Conditions currently active on a vehicle (VehicleStatus.alerts, uint16)."""

    NONE = 0
    BATTERY_LOW = 1 << 0
    BATTERY_CRITICAL = 1 << 1
    GPS_LOSS = 1 << 2
    EKF_FAILURE = 1 << 3
    AUTOPILOT_LINK_LOSS = 1 << 4
    GEOFENCE_BREACH = 1 << 5
    ATTITUDE_ABNORMAL = 1 << 6
    COLLISION_RISK = 1 << 7
    SWARM_LINK_LOSS = 1 << 8
    NO_FLY_ZONE = 1 << 9
    AUTOPILOT_MISMATCH = 1 << 10  # the autopilot is not the vehicle the database says
    IDENTITY_CONFLICT = 1 << 11  # another source publishes in this vehicle's name


class Severity(IntEnum):
    """Alert severity, ordered: a larger value is more severe."""

    INFO = 0
    WARNING = 1
    CRITICAL = 2
    EMERGENCY = 3


class AlertCode(IntEnum):
    """What an Alert is about."""

    GENERIC = 0
    BATTERY_LOW = 1
    BATTERY_CRITICAL = 2
    GPS_LOSS = 3
    EKF_FAILURE = 4
    AUTOPILOT_LINK_LOSS = 5
    GEOFENCE_BREACH = 6
    ATTITUDE_ABNORMAL = 7
    COLLISION_RISK = 8
    SWARM_LINK_LOSS = 9
    NO_FLY_ZONE = 10
    PLAN_FAILED = 11
    PLAN_TIMEOUT = 12
    MISSION_FAILED = 13
    MISSION_COMPLETE = 14
    AUTOPILOT_TEXT = 15  # a STATUSTEXT relayed from the autopilot
    MALFORMED_INPUT = 16  # a peer sent something we could not decode
    CONDITION_CLEARED = 17
    MISSION_CANCELLED = 18  # the operator cancelled the mission (not a failure)
    AUTOPILOT_MISMATCH = 19  # the autopilot's HEARTBEAT type or system id is not the database's
    ROSTER_MISMATCH = 20  # a member flies the mission with another roster (members hash)
    IDENTITY_CONFLICT = 21  # another Zenoh session or airframe speaks in this vehicle's name
    DATABASE_MISMATCH = 22  # the swarm database disagrees with the autopilot's own figures
    CLOCK_SKEW = 23  # the autopilot's GPS time and the node's clock differ
    AUTOPILOT_REFUSED = 24  # the autopilot refused a step of a mission (with its reason)


class CommandKind(IntEnum):
    """Operator commands (paper section 3.5)."""

    ARM = 1
    DISARM = 2
    TAKEOFF = 3  # args.value: altitude above home, m
    SET_MODE = 4  # args.text: ArduPilot mode name, e.g. "GUIDED"
    GOTO = 5  # args.point
    SET_SPEED = 6  # args.value: m/s
    SET_ALTITUDE = 7  # args.value: altitude above home, m
    RTL = 8
    LAND = 9
    EMERGENCY_LAND = 10
    ABORT_LANDING = 11
    PARACHUTE = 12
    SET_BASE = 13  # args.point
    CALIBRATE = 14  # args.text: what to calibrate ("gyro", "baro", "airspeed", ...)
    SET_FLEET = 15  # args.fleet_id
    CANCEL_MISSION = 16  # args.mission_id
    JOIN_MISSION = 17  # paper "Add": args.mission_id
    SWAP_MISSION = 18  # paper "Swap": args.mission_id <-> args.other_mission_id
    ACTIVATE = 19  # state machine active flag on
    SHUTDOWN = 20  # state machine active flag off


class SelectorKind(IntEnum):
    """How a command or mission names the vehicles it addresses (paper section 3.5.2)."""

    ALL = 0
    IDS = 1
    FLEET = 2
    QUANTITY = 3  # missions only: `quantity` vehicles chosen by voting


class MissionType(IntEnum):
    AREA = 1
    TARGET = 2
    PERIMETER = 3
    ROUTE = 4
    OBJECTIVE = 5
    AUTOLAND = 6
    MUMT = 7


class GeometryKind(IntEnum):
    POINT = 1  # points[0]
    POINTS = 2  # one or more points (objective / multi-objective)
    POLYLINE = 3  # >= 2 points (route)
    POLYGON = 4  # shell >= 3 points, open ring (no repeated first point), optional holes
    CIRCLE = 5  # points[0] is the centre, radius_m


class AckRef(IntEnum):
    """What an Ack answers."""

    COMMAND = 1
    MISSION = 2
    ZONE = 3
    FLEET = 4


class AckReason(IntEnum):
    """Why an Ack accepted or rejected (paper section 2.3.3 acceptance checks first)."""

    OK = 0
    HOME_NOT_SET = 1
    NOT_READY = 2
    NOT_ADDRESSED = 3
    NO_BASE = 4
    BUSY = 5
    INVALID = 6
    UNSUPPORTED = 7
    AUTOPILOT_REJECTED = 8
    TIMEOUT = 9
    EMERGENCY = 10
    NOT_FOUND = 11
    DUPLICATE = 12
    IN_NO_FLY_ZONE = 13
    PREEMPTED = 14  # the node refused it: a module of higher priority holds the autopilot
    PLAN_FAILED = 15  # the fleet's plan cannot be flown: every addressed vehicle refuses it


class DetailCode(IntEnum):
    """What the numbers of a ReasonDetail are (which of its fields are used)."""

    NONE = 0
    ENDURANCE = 1  # vehicle_id (0: each vehicle), needed_s, available_s
    COLLISION = (
        2  # vehicle_id (the other; 0: several or not a swarm node), distance_m, in_s, altitude_m
    )


class TargetSource(IntEnum):
    PAYLOAD = 1  # detected by an onboard payload
    OPERATOR = 2  # marked by the operator
    ADSB = 3  # a manned aircraft seen by ADS-B
