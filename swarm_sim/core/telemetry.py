"""MAVLink telemetry built from the simulated vehicle's state, with ArduPilot's field
conventions (as seen in the recorded SITL streams): no position before the EKF has
one, SYSTEM_TIME.time_unix_usec 0 until GPS lock, MISSION_CURRENT.total excluding home,
EKF_STATUS_REPORT flags 1024 -> 167 -> 831 as the EKF converges."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from . import streams as S
from .geo import wrap_360
from .kinematics import VtolState

if TYPE_CHECKING:
    from .autopilot import SimAutopilot

# SYS_STATUS sensor bits (MAV_SYS_STATUS_SENSOR)
_GYRO, _ACCEL, _MAG, _ABS_PRESSURE, _DIFF_PRESSURE, _GPS = 1, 2, 4, 8, 16, 32
_RATE_CONTROL, _ATTITUDE, _YAW_POSITION, _Z_ALTITUDE, _XY_POSITION = 1024, 2048, 4096, 8192, 16384
_MOTOR_OUTPUTS, _RC_RECEIVER, _AHRS, _TERRAIN, _BATTERY = 32768, 65536, 2097152, 4194304, 33554432
_LOGGING, _PREARM, _GEOFENCE = 16777216, 268435456, 1048576
_BASE_SENSORS = (
    _GYRO
    | _ACCEL
    | _MAG
    | _ABS_PRESSURE
    | _GPS
    | _RATE_CONTROL
    | _ATTITUDE
    | _YAW_POSITION
    | _Z_ALTITUDE
    | _XY_POSITION
    | _MOTOR_OUTPUTS
    | _AHRS
    | _BATTERY
    | _LOGGING
    | _PREARM
)

# EKF_STATUS_REPORT flags (EKF_STATUS_FLAGS)
EKF_UNINITIALIZED = 1024
EKF_ATTITUDE_ONLY = 167  # attitude, velocities, vertical position, constant position mode
EKF_GPS = 831  # + horizontal position (relative/absolute) and predicted positions

# MAV_LANDED_STATE
LANDED_ON_GROUND, LANDED_IN_AIR, LANDED_TAKEOFF, LANDED_LANDING = 1, 2, 3, 4

# AUTOPILOT_VERSION.capabilities (MAV_PROTOCOL_CAPABILITY): mission float/int, param
# float, command int, set position target global int, fence, rally, mavlink2
CAPABILITIES = 1 | 2 | 4 | 8 | 256 | 8192 | 16384 | 32768 | 65536 | 4
FLIGHT_SW_VERSION = (4 << 24) | (7 << 16) | (0 << 8) | 0  # 4.7.0-dev, like the recordings


def _i32(value: float) -> int:
    """Clamped to int32 (a MAVLink field must never make packing fail)."""
    if not math.isfinite(value):
        return 0
    return max(-(2**31), min(2**31 - 1, round(value)))


def _deg_e7(value: float) -> int:
    return _i32(value * 1e7)


def heartbeat(ap: SimAutopilot) -> Any:
    return mavlink.MAVLink_heartbeat_message(
        ap.mav_type, 3, ap.base_mode, ap.mode, ap.system_status, 3
    )


def global_position_int(ap: SimAutopilot, now: float) -> Any:
    b = ap.body
    if not ap.ekf_position:
        return mavlink.MAVLink_global_position_int_message(
            ap.boot_ms(now), 0, 0, 0, 0, 0, 0, 0, ap.hdg_cdeg
        )
    lat, lon = ap.latlon
    return mavlink.MAVLink_global_position_int_message(
        ap.boot_ms(now),
        _deg_e7(lat),
        _deg_e7(lon),
        _i32(b.alt * 1000),
        _i32(ap.rel_alt_m * 1000),
        _i16(b.vn * 100),
        _i16(b.ve * 100),
        _i16(b.vd * 100),
        ap.hdg_cdeg,
    )


def _i16(v: float) -> int:
    return max(-32768, min(32767, round(v)))


def attitude(ap: SimAutopilot, now: float) -> Any:
    b = ap.body
    yaw = math.radians(b.heading_deg)
    if yaw > math.pi:
        yaw -= 2 * math.pi
    return mavlink.MAVLink_attitude_message(
        ap.boot_ms(now), b.roll_rad, b.pitch_rad, yaw, 0.0, 0.0, b.yaw_rate_rad_s
    )


def vfr_hud(ap: SimAutopilot) -> Any:
    b = ap.body
    return mavlink.MAVLink_vfr_hud_message(
        b.airspeed,
        b.groundspeed,
        round(b.heading_deg) % 360,
        round(b.throttle_pct),
        b.alt if ap.ekf_position else 0.0,
        b.climb_rate,
    )


def gps_raw_int(ap: SimAutopilot, now: float) -> Any:
    b = ap.body
    if not ap.gps_fix:
        fix = 1 if ap.gps_detected else 0
        return mavlink.MAVLink_gps_raw_int_message(
            0, fix, 0, 0, 0, 65535, 65535, 0, 0, 0, 0, 0, 0, 0, 0, 0
        )
    lat, lon = ap.latlon
    cog = round(b.course_deg * 100) % 36000 if b.groundspeed > 0.5 else 0
    return mavlink.MAVLink_gps_raw_int_message(
        int((now - ap.boot_time) * 1e6),
        ap.options.gps_fix_type,
        _deg_e7(lat),
        _deg_e7(lon),
        _i32(b.alt * 1000),
        121,
        200,
        min(65535, round(b.groundspeed * 100)),
        cog,
        ap.options.satellites,
        _i32(b.alt * 1000),
        300,
        300,
        40,
        0,
        0,
    )


def sys_status(ap: SimAutopilot) -> Any:
    # bits as in the recorded SITL streams: GEOFENCE present (copter, or with fence
    # items), enabled with FENCE_ENABLE, healthy unless breached (MAVProxy reports
    # "fence breach" when the health bit is missing)
    fence_present = ap.fence_present()  # AC_Fence::sys_status_present()
    present = (
        _BASE_SENSORS
        | _RC_RECEIVER
        | _TERRAIN
        | (_DIFF_PRESSURE if ap.airframe.is_fixed_wing else 0)
    )
    present |= _GEOFENCE if fence_present else 0
    enabled = present & ~_GEOFENCE
    if ap.params["FENCE_ENABLE"][0]:
        enabled |= _GEOFENCE
    if not ap.armed:
        enabled &= ~_MOTOR_OUTPUTS
    health = present | _GEOFENCE
    if ap.fence_breached:
        health &= ~_GEOFENCE
    if not ap.gps_fix:
        health &= ~_GPS
    if not ap.ekf_position:
        health &= ~(_XY_POSITION | _AHRS)
    if ap.prearm_failure() is not None:
        health &= ~_PREARM
    bat = ap.battery
    return mavlink.MAVLink_sys_status_message(
        present,
        enabled,
        health,
        0,
        round(bat.voltage * 1000),
        round(bat.current_a * 100),
        bat.remaining_pct,
        0,
        0,
        0,
        0,
        0,
        0,
        0,
        0,
        0,
    )


def battery_status(ap: SimAutopilot) -> Any:
    bat = ap.battery
    pct = bat.remaining_pct
    charge_state = 1 if pct >= 30 else 2 if pct >= 15 else 3
    voltages = [min(65534, round(bat.voltage * 1000))] + [65535] * 9
    return mavlink.MAVLink_battery_status_message(
        0,
        0,
        0,
        32767,
        voltages,
        round(bat.current_a * 100),
        int(bat.consumed_mah),
        int(bat.energy_wh * 36),
        pct,
        0,
        charge_state,
        [0, 0, 0, 0],
        0,
        0,
    )


def system_time(ap: SimAutopilot, now: float) -> Any:
    unix_us = int(now * 1e6) if ap.gps_fix else 0
    return mavlink.MAVLink_system_time_message(unix_us, ap.boot_ms(now))


def mission_current(ap: SimAutopilot) -> Any:
    seq, total, state, mode = ap.mission_current_fields()
    return mavlink.MAVLink_mission_current_message(seq, total, state, mode)


def ekf_status_report(ap: SimAutopilot, now: float) -> Any:
    if ap.ekf_position:
        flags, pos_var = EKF_GPS, 0.002
    elif now - ap.boot_time >= ap.ekf_init_s:
        flags, pos_var = EKF_ATTITUDE_ONLY, 0.0
    else:
        flags, pos_var = EKF_UNINITIALIZED, 0.0
    return mavlink.MAVLink_ekf_status_report_message(
        flags, 0.01 if ap.ekf_position else 0.0, pos_var, 0.005, 0.0002, 0.0, 0.0
    )


def home_position(ap: SimAutopilot, now: float) -> Any:
    lat, lon, alt = ap.home_latlon_alt
    hn, he = ap.home_ne
    nan = float("nan")
    return mavlink.MAVLink_home_position_message(
        _deg_e7(lat),
        _deg_e7(lon),
        _i32(alt * 1000),
        hn,
        he,
        -(alt - ap.origin_alt),
        [nan, nan, nan, nan],
        0.0,
        0.0,
        0.0,
        int((now - ap.boot_time) * 1e6),
    )


def gps_global_origin(ap: SimAutopilot, now: float) -> Any:
    lat, lon = ap.frame.lat0, ap.frame.lon0
    return mavlink.MAVLink_gps_global_origin_message(
        _deg_e7(lat),
        _deg_e7(lon),
        _i32(ap.origin_alt * 1000),
        int((now - ap.boot_time) * 1e6),
    )


def extended_sys_state(ap: SimAutopilot) -> Any:
    b = ap.body
    vtol = b.vtol_state if ap.airframe.model.value == "vtol" else VtolState.UNDEFINED
    if b.on_ground:
        landed = LANDED_ON_GROUND
    elif ap.taking_off:
        landed = LANDED_TAKEOFF
    elif ap.landing:
        landed = LANDED_LANDING
    else:
        landed = LANDED_IN_AIR
    return mavlink.MAVLink_extended_sys_state_message(int(vtol), landed)


def nav_controller_output(ap: SimAutopilot) -> Any:
    b = ap.body
    dest = ap.nav.destination
    if dest is None:
        return mavlink.MAVLink_nav_controller_output_message(
            math.degrees(b.roll_rad),
            math.degrees(b.pitch_rad),
            int(b.heading_deg),
            int(b.heading_deg),
            0,
            0.0,
            0.0,
            0.0,
        )
    n, e, alt = dest
    dist = math.hypot(n - b.n, e - b.e)
    bearing = round(wrap_360(math.degrees(math.atan2(e - b.e, n - b.n))))
    return mavlink.MAVLink_nav_controller_output_message(
        math.degrees(b.roll_rad),
        math.degrees(b.pitch_rad),
        bearing,
        bearing,
        min(65535, int(dist)),
        alt - b.alt if alt else 0.0,
        0.0,
        0.0,
    )


def wind(ap: SimAutopilot) -> Any:
    b = ap.body
    speed = math.hypot(b.wind_n, b.wind_e)
    direction = wrap_360(math.degrees(math.atan2(-b.wind_e, -b.wind_n))) if speed > 0 else 0.0
    if direction > 180:
        direction -= 360
    return mavlink.MAVLink_wind_message(direction, speed, 0.0)


def fence_status(ap: SimAutopilot) -> Any | None:
    """FENCE_STATUS, sent only while the fence is enabled (GCS_MAVLINK::send_fence_status)."""
    if not ap.params["FENCE_ENABLE"][0]:
        return None
    breach_type = 3 if ap.fence_breach_count else 0  # FENCE_BREACH_BOUNDARY
    return mavlink.MAVLink_fence_status_message(
        int(ap.fence_breached),
        min(65535, ap.fence_breach_count),
        breach_type,
        ap.fence_breach_ms,
        0,
    )


def timesync_request(now: float) -> Any:
    return mavlink.MAVLink_timesync_message(0, int(now * 1e9))


def autopilot_version(ap: SimAutopilot) -> Any:
    uid = 0x5EED0000 + ap.sysid
    return mavlink.MAVLink_autopilot_version_message(
        CAPABILITIES,
        FLIGHT_SW_VERSION,
        0,
        0,
        0,
        [0] * 8,
        [0] * 8,
        [0] * 8,
        0x1209,
        0x5741,
        uid,
        [0] * 18,
    )


def build(ap: SimAutopilot, msg_id: int, now: float) -> Any | None:
    """The message with id `msg_id`, or None when the vehicle has nothing to send (e.g.
    HOME_POSITION before home is set)."""
    if msg_id == S.HEARTBEAT:
        return heartbeat(ap)
    if msg_id == S.GLOBAL_POSITION_INT:
        return global_position_int(ap, now)
    if msg_id == S.ATTITUDE:
        return attitude(ap, now)
    if msg_id == S.VFR_HUD:
        return vfr_hud(ap)
    if msg_id == S.GPS_RAW_INT:
        return gps_raw_int(ap, now)
    if msg_id == S.SYS_STATUS:
        return sys_status(ap)
    if msg_id == S.BATTERY_STATUS:
        return battery_status(ap)
    if msg_id == S.SYSTEM_TIME:
        return system_time(ap, now)
    if msg_id == S.MISSION_CURRENT:
        return mission_current(ap)
    if msg_id == S.EKF_STATUS_REPORT:
        return ekf_status_report(ap, now)
    if msg_id == S.HOME_POSITION:
        return home_position(ap, now) if ap.home_set else None
    if msg_id == S.GPS_GLOBAL_ORIGIN:
        return gps_global_origin(ap, now) if ap.home_set else None
    if msg_id == S.EXTENDED_SYS_STATE:
        return extended_sys_state(ap)
    if msg_id == S.NAV_CONTROLLER_OUTPUT:
        return nav_controller_output(ap)
    if msg_id == S.WIND:
        return wind(ap)
    if msg_id == S.TIMESYNC:
        return timesync_request(now)
    if msg_id == S.FENCE_STATUS:
        return fence_status(ap)
    if msg_id == 148:  # AUTOPILOT_VERSION
        return autopilot_version(ap)
    return None


ONE_SHOT = frozenset(S.STREAMABLE | {148})
