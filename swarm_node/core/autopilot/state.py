"""The autopilot as the node sees it: a snapshot maintained by the MAVLink tracker from
HEARTBEAT, GLOBAL_POSITION_INT, SYS_STATUS / BATTERY_STATUS, GPS_RAW_INT, ATTITUDE,
VFR_HUD, HOME_POSITION, SYSTEM_TIME, MISSION_CURRENT, MISSION_ITEM_REACHED, STATUSTEXT
and EKF_STATUS_REPORT. Units in the names; None = not received yet."""

from __future__ import annotations

import msgspec

from swarm_proto import GeoPoint, GpsFix, VehicleType


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

    @property
    def has_position(self) -> bool:
        return self.lat_deg is not None and self.lon_deg is not None
