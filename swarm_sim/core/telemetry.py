"""MAVLink telemetry built from the simulated vehicle's state, with ArduPilot's field
conventions (as seen in the recorded SITL streams): no position before the EKF has
one, SYSTEM_TIME.time_unix_usec 0 until GPS lock, MISSION_CURRENT.total excluding home,
EKF_STATUS_REPORT flags 1024 -> 167 -> 831 as the EKF converges."""

from __future__ import annotations

import math
from typing import Any

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from . import streams as S
from .fields import deg_e7, i16, i32
from .firmware import Behaviour
from .geo import wrap_360
from .kinematics import VtolState
from .vehicle import Vehicle

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


def latlon(v: Vehicle) -> tuple[float, float]:
    return v.frame.to_latlon(v.body.n, v.body.e)


def hdg_cdeg(v: Vehicle) -> int:
    return round(v.body.heading_deg * 100) % 36000


def heartbeat(v: Vehicle) -> Any:
    return v.modes.heartbeat()


def global_position_int(v: Vehicle, now: float) -> Any:
    b = v.body
    if not v.sensors.ekf_position:
        return mavlink.MAVLink_global_position_int_message(
            v.timeline.boot_ms(now), 0, 0, 0, 0, 0, 0, 0, hdg_cdeg(v)
        )
    lat, lon = latlon(v)
    return mavlink.MAVLink_global_position_int_message(
        v.timeline.boot_ms(now),
        deg_e7(lat),
        deg_e7(lon),
        i32(b.alt * 1000),
        i32((b.alt - v.home.alt) * 1000),
        i16(b.vn * 100),
        i16(b.ve * 100),
        i16(b.vd * 100),
        hdg_cdeg(v),
    )


def attitude(v: Vehicle, now: float) -> Any:
    b = v.body
    yaw = math.radians(b.heading_deg)
    if yaw > math.pi:
        yaw -= 2 * math.pi
    return mavlink.MAVLink_attitude_message(
        v.timeline.boot_ms(now), b.roll_rad, b.pitch_rad, yaw, 0.0, 0.0, b.yaw_rate_rad_s
    )


def vfr_hud(v: Vehicle) -> Any:
    b = v.body
    return mavlink.MAVLink_vfr_hud_message(
        b.airspeed,
        b.groundspeed,
        round(b.heading_deg) % 360,
        round(b.throttle_pct),
        b.alt if v.sensors.ekf_position else 0.0,
        b.climb_rate,
    )


def gps_raw_int(v: Vehicle, now: float) -> Any:
    b = v.body
    if not v.sensors.gps_fix:
        fix = 1 if v.sensors.gps_detected else 0
        return mavlink.MAVLink_gps_raw_int_message(
            0, fix, 0, 0, 0, 65535, 65535, 0, 0, 0, 0, 0, 0, 0, 0, 0
        )
    lat, lon = latlon(v)
    cog = round(b.course_deg * 100) % 36000 if b.groundspeed > 0.5 else 0
    return mavlink.MAVLink_gps_raw_int_message(
        int((now - v.timeline.boot_time) * 1e6),
        v.options.gps_fix_type,
        deg_e7(lat),
        deg_e7(lon),
        i32(b.alt * 1000),
        121,
        200,
        min(65535, round(b.groundspeed * 100)),
        cog,
        v.options.satellites,
        i32(b.alt * 1000),
        300,
        300,
        40,
        0,
        0,
    )


def sys_status(v: Vehicle) -> Any:
    # bits as in the recorded SITL streams: GEOFENCE present (copter, or with fence
    # items), enabled with FENCE_ENABLE, healthy unless breached (MAVProxy reports
    # "fence breach" when the health bit is missing)
    fence_present = v.fence.present()  # AC_Fence::sys_status_present()
    present = (
        _BASE_SENSORS
        | _RC_RECEIVER
        | _TERRAIN
        | (_DIFF_PRESSURE if v.airframe.is_fixed_wing else 0)
    )
    present |= _GEOFENCE if fence_present else 0
    enabled = present & ~_GEOFENCE
    if v.params.value("FENCE_ENABLE"):
        enabled |= _GEOFENCE
    if not v.arming.armed:
        enabled &= ~_MOTOR_OUTPUTS
    health = present | _GEOFENCE
    if v.fence.breached:
        health &= ~_GEOFENCE
    if not v.sensors.gps_fix:
        health &= ~_GPS
    if not v.sensors.ekf_position:
        health &= ~(_XY_POSITION | _AHRS)
    if v.arming.prearm_failure(v.modes.spec) is not None:
        health &= ~_PREARM
    bat = v.battery
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


def battery_status(v: Vehicle) -> Any:
    bat = v.battery
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


def system_time(v: Vehicle, now: float) -> Any:
    unix_us = int((now + v.options.gps_time_offset_s) * 1e6) if v.sensors.gps_fix else 0
    return mavlink.MAVLink_system_time_message(unix_us, v.timeline.boot_ms(now))


def mission_current_fields(v: Vehicle) -> tuple[int, int, int, int]:
    """MISSION_CURRENT's seq, total (without home), mission_state, mission_mode."""
    in_auto = v.modes.behaviour == Behaviour.AUTO
    return v.stores.progress.current_fields(v.stores.mission_total, in_auto)


def mission_current(v: Vehicle) -> Any:
    seq, total, state, mode = mission_current_fields(v)
    return mavlink.MAVLink_mission_current_message(seq, total, state, mode)


def ekf_status_report(v: Vehicle, now: float) -> Any:
    if v.sensors.ekf_position:
        flags, pos_var = EKF_GPS, 0.002
    elif now - v.timeline.boot_time >= v.options.startup.ekf_init_s:
        flags, pos_var = EKF_ATTITUDE_ONLY, 0.0
    else:
        flags, pos_var = EKF_UNINITIALIZED, 0.0
    return mavlink.MAVLink_ekf_status_report_message(
        flags, 0.01 if v.sensors.ekf_position else 0.0, pos_var, 0.005, 0.0002, 0.0, 0.0
    )


def extended_sys_state(v: Vehicle) -> Any:
    b = v.body
    vtol = b.vtol_state if v.airframe.model.value == "vtol" else VtolState.UNDEFINED
    if b.on_ground:
        landed = LANDED_ON_GROUND
    elif v.navigator.taking_off:
        landed = LANDED_TAKEOFF
    elif v.navigator.landing:
        landed = LANDED_LANDING
    else:
        landed = LANDED_IN_AIR
    return mavlink.MAVLink_extended_sys_state_message(int(vtol), landed)


def nav_controller_output(v: Vehicle) -> Any:
    b = v.body
    dest = v.navigator.task.destination
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


def wind(v: Vehicle) -> Any:
    b = v.body
    speed = math.hypot(b.wind_n, b.wind_e)
    direction = wrap_360(math.degrees(math.atan2(-b.wind_e, -b.wind_n))) if speed > 0 else 0.0
    if direction > 180:
        direction -= 360
    return mavlink.MAVLink_wind_message(direction, speed, 0.0)


def fence_status(v: Vehicle) -> Any | None:
    """FENCE_STATUS, sent only while the fence is enabled (GCS_MAVLINK::send_fence_status)."""
    if not v.params.value("FENCE_ENABLE"):
        return None
    breach_type = 3 if v.fence.breach_count else 0  # FENCE_BREACH_BOUNDARY
    return mavlink.MAVLink_fence_status_message(
        int(v.fence.breached),
        min(65535, v.fence.breach_count),
        breach_type,
        v.fence.breach_ms,
        0,
    )


def timesync_request(now: float) -> Any:
    return mavlink.MAVLink_timesync_message(0, int(now * 1e9))


def autopilot_version(v: Vehicle) -> Any:
    uid = 0x5EED0000 + v.sysid
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


def build(v: Vehicle, msg_id: int, now: float) -> Any | None:
    """The message with id `msg_id`, or None when the vehicle has nothing to send (e.g.
    HOME_POSITION before home is set)."""
    if msg_id == S.HEARTBEAT:
        return heartbeat(v)
    if msg_id == S.GLOBAL_POSITION_INT:
        return global_position_int(v, now)
    if msg_id == S.ATTITUDE:
        return attitude(v, now)
    if msg_id == S.VFR_HUD:
        return vfr_hud(v)
    if msg_id == S.GPS_RAW_INT:
        return gps_raw_int(v, now)
    if msg_id == S.SYS_STATUS:
        return sys_status(v)
    if msg_id == S.BATTERY_STATUS:
        return battery_status(v)
    if msg_id == S.SYSTEM_TIME:
        return system_time(v, now)
    if msg_id == S.MISSION_CURRENT:
        return mission_current(v)
    if msg_id == S.EKF_STATUS_REPORT:
        return ekf_status_report(v, now)
    if msg_id == S.HOME_POSITION:
        return v.home.position_message(now) if v.home.is_set else None
    if msg_id == S.GPS_GLOBAL_ORIGIN:
        return v.home.origin_message(now) if v.home.is_set else None
    if msg_id == S.EXTENDED_SYS_STATE:
        return extended_sys_state(v)
    if msg_id == S.NAV_CONTROLLER_OUTPUT:
        return nav_controller_output(v)
    if msg_id == S.WIND:
        return wind(v)
    if msg_id == S.TIMESYNC:
        return timesync_request(now)
    if msg_id == S.FENCE_STATUS:
        return fence_status(v)
    if msg_id == 148:  # AUTOPILOT_VERSION
        return autopilot_version(v)
    return None


ONE_SHOT = frozenset(S.STREAMABLE | {148})
