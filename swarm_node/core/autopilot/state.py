"""The autopilot as the node sees it: a snapshot maintained by the MAVLink tracker from
HEARTBEAT, GLOBAL_POSITION_INT, SYS_STATUS / BATTERY_STATUS, GPS_RAW_INT, ATTITUDE,
VFR_HUD, HOME_POSITION, SYSTEM_TIME, MISSION_CURRENT, MISSION_ITEM_REACHED, STATUSTEXT,
EKF_STATUS_REPORT and ADSB_VEHICLE. Units in the names; None = not received yet."""

from __future__ import annotations

import msgspec

from swarm_proto import GeoPoint, GpsFix, VehicleType


class AdsbReport(msgspec.Struct, frozen=True):
    """An aircraft the autopilot hears on ADS-B (ADSB_VEHICLE): non-cooperative traffic
    for collision avoidance. Position WGS84, altitude above mean sea level."""

    icao_address: int
    lat_deg: float
    lon_deg: float
    alt_msl_m: float
    vel_north_m_s: float = 0.0  # 0 when the report's velocity is not flagged valid
    vel_east_m_s: float = 0.0
    vel_down_m_s: float = 0.0
    time_s: float = 0.0  # when it was where it says (link clock: received less tslc)
    callsign: str = ""


class AutopilotState(msgspec.Struct, frozen=True):
    sysid: int = 0
    vehicle_type: VehicleType = VehicleType.OTHER
    link_ok: bool = False  # a HEARTBEAT within the link timeout
    last_heartbeat_s: float | None = None  # clock time of the last HEARTBEAT
    mode_number: int = 0  # HEARTBEAT custom_mode
    mode_name: str = ""
    armed: bool = False
    lat_deg: float | None = None
    lon_deg: float | None = None
    alt_msl_m: float | None = None
    alt_rel_m: float | None = None
    vel_north_m_s: float = 0.0
    vel_east_m_s: float = 0.0
    vel_down_m_s: float = 0.0
    heading_deg: float = 0.0
    roll_deg: float = 0.0
    pitch_deg: float = 0.0
    airspeed_m_s: float = 0.0
    groundspeed_m_s: float = 0.0
    battery_pct: int = -1
    battery_v: float = 0.0
    gps_fix: GpsFix = GpsFix.NO_GPS
    gps_sats: int = 0
    gps_time_unix_s: float | None = None  # SYSTEM_TIME.time_unix_usec once GPS is locked
    home: GeoPoint | None = None
    ekf_ok: bool = False  # EKF_STATUS_REPORT: attitude, velocity and position estimates good
    mission_count: int = 0  # items in the autopilot's mission
    mission_current: int = 0  # MISSION_CURRENT.seq
    mission_reached: int = -1  # last MISSION_ITEM_REACHED.seq
    landed: bool | None = None  # EXTENDED_SYS_STATE landed state, when sent
    bad_packets: int = 0  # garbage or invalid messages seen on the link
    # appended by the autopilot link
    compid: int = 0  # the autopilot's MAVLink component id
    mav_type: int = 0  # HEARTBEAT type (a QuadPlane reports 1, fixed wing)
    system_status: int = 0  # HEARTBEAT system_status (MAV_STATE: 3 standby, 4 active, 5 critical)
    ekf_flags: int = 0  # EKF_STATUS_REPORT.flags (EKF_STATUS_FLAGS bits)
    climb_m_s: float = 0.0  # VFR_HUD climb rate, up positive
    throttle_pct: int = 0  # VFR_HUD throttle
    position_time_unix_s: float | None = None  # GPS time of the GLOBAL_POSITION_INT sample
    boot_time_ms: int = 0  # the autopilot's time since boot, from its last timed message
    mission_state: int = 0  # MISSION_CURRENT.mission_state (MISSION_STATE: 3 active, 5 complete)
    last_message_s: float | None = None  # clock time of the last valid message from it
    link_losses: int = 0  # how many times the link was lost
    foreign_packets: int = 0  # valid MAVLink from other systems/components, ignored
    # appended for real ArduPilot SITL
    sensors_present: int = 0  # SYS_STATUS onboard_control_sensors_present (MAV_SYS_STATUS_SENSOR)
    sensors_enabled: int = 0  # SYS_STATUS onboard_control_sensors_enabled
    sensors_health: int = 0  # SYS_STATUS onboard_control_sensors_health
    autopilot_ready: bool = False  # booted: "ArduPilot Ready" or a HEARTBEAT in STANDBY or later
    position_trusted: bool = False  # a GPS fix (2-D or better) or an EKF absolute position was seen
    # appended for collision avoidance
    traffic: tuple[AdsbReport, ...] = ()  # ADSB_VEHICLE: the latest report per aircraft
    # appended for link loss judged from the autopilot's own data
    reboots: int = 0  # autopilot reboots seen (its time since boot went back)
    link_gap_s: float = 0.0  # the last link loss as the autopilot's own clock shows it
    host_stalls: int = 0  # times the node read the link late (its own stall, not the link's)
    host_stall_s: float = 0.0  # the last such stall, seconds
    # appended by the link's shell: why nothing is heard ("" while it is, or not known):
    # the connection cannot be opened, or it is open and silent
    link_problem: str = ""
    # appended: the autopilot's own figures, read from its parameters at link-up
    # (link.FIGURES); None = not read (yet), or the autopilot does not know it
    battery_capacity_mah: float | None = None  # BATT_CAPACITY, None without a monitor
    max_bank_deg: float | None = None  # ArduPlane ROLL_LIMIT_DEG, ArduCopter ANGLE_MAX

    @property
    def has_position(self) -> bool:
        return self.lat_deg is not None and self.lon_deg is not None

    @property
    def ekf_has_position(self) -> bool:
        """The EKF has an absolute horizontal position (what ArduPilot needs before it
        accepts GUIDED, AUTO, RTL, LOITER...)."""
        horiz_abs = self.ekf_flags & (EKF_POS_HORIZ_ABS | EKF_PRED_POS_HORIZ_ABS)
        return bool(horiz_abs) and not self.ekf_flags & (EKF_CONST_POS_MODE | EKF_UNINITIALIZED)


# MAV_SYS_STATUS_SENSOR bits (SYS_STATUS)
SENSOR_GEOFENCE = 1 << 20  # present: ArduPilot's AC_Fence::present() (a fence it has loaded)

# EKF_STATUS_FLAGS (common.xml)
EKF_ATTITUDE = 1
EKF_VELOCITY_HORIZ = 2
EKF_VELOCITY_VERT = 4
EKF_POS_HORIZ_REL = 8
EKF_POS_HORIZ_ABS = 16
EKF_POS_VERT_ABS = 32
EKF_POS_VERT_AGL = 64
EKF_CONST_POS_MODE = 128
EKF_PRED_POS_HORIZ_REL = 256
EKF_PRED_POS_HORIZ_ABS = 512
EKF_UNINITIALIZED = 1024
EKF_GPS_GLITCH = 32768
