"""How a simulated autopilot is started: its ids, sensor start-up times, physics step,
wind, battery charge, GPS and telemetry defaults."""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass(frozen=True)
class StartupTimes:
    """Seconds after boot (sim time) at which the simulated sensors come up. ArduPilot SITL
    took 20-40 s to use GPS in the recordings; the defaults are shorter."""

    ekf_init_s: float = 3.3  # EKF3 initialised: attitude only
    gps_detect_s: float = 3.0  # GPS 1: detected
    gps_fix_s: float = 4.0  # 3-D fix; SYSTEM_TIME carries UNIX time from here
    ekf_origin_s: float = 5.0  # origin and home set
    ekf_gps_s: float = 6.0  # EKF uses GPS: position estimate, modes and arming allowed


@dataclass(frozen=True)
class SimOptions:
    sysid: int = 1
    compid: int = 1
    startup: StartupTimes = field(default_factory=StartupTimes)
    physics_dt_s: float = 0.1
    wind_speed_m_s: float = 0.0
    wind_from_deg: float = 0.0  # direction the wind blows from
    battery_pct: float = 100.0
    gps_fix_type: int = 6  # SITL reports RTK fixed (6); a real GPS would report 3
    satellites: int = 10
    stream_defaults: dict[int, float] | None = None  # msg id -> interval s; None: defaults
    boot_texts: bool = True
    # SYSTEM_TIME's UNIX time minus the simulation clock: SITL's GPS time ran 7.5-10.5 s
    # behind the host's clock (seen by make sitl-fleet); 0: the shared clock
    gps_time_offset_s: float = 0.0
