"""The autopilot's parameters (AP_Param): name -> (value, MAV_PARAM_TYPE), only the ones the
simulator uses, with ArduPilot's defaults per firmware and airframe, and the PARAM_VALUE
answers of the parameter protocol."""

from __future__ import annotations

import math
from typing import Any

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from .airframes import AirframeParams, VehicleModel
from .firmware import Firmware

#: parameters a PARAM_SET does not change (the vehicle answers with the value it keeps)
READ_ONLY = frozenset({"MIS_TOTAL", "SYSID_THISMAV", "Q_ENABLE", "FRAME_CLASS"})


class Parameters(dict[str, tuple[float, int]]):
    """The parameter table. A dict (`params["FENCE_ENABLE"] == (0.0, 2)`), with the
    lookups and answers the autopilot needs."""

    def value(self, name: str) -> float:
        return self[name][0]

    def set_value(self, name: str, value: float) -> None:
        """Set a known parameter, keeping its type."""
        self[name] = (value, self[name][1])

    def value_message(self, name: str) -> Any:
        """PARAM_VALUE for `name`, indexed as in PARAM_REQUEST_LIST (sorted names)."""
        names = sorted(self)
        return self.value_message_at(names.index(name), names)

    def value_message_at(self, index: int, names: list[str] | None = None) -> Any:
        names = sorted(self) if names is None else names
        value, ptype = self[names[index]]
        return mavlink.MAVLink_param_value_message(
            names[index].encode(), value, ptype, len(names), index
        )

    def set_from_gcs(self, name: str, value: float) -> bool:
        """PARAM_SET: False (and nothing changes) for an unknown name or a value that is
        not finite; a read-only parameter keeps its value."""
        if name not in self or not math.isfinite(value):
            return False
        if name not in READ_ONLY:
            self.set_value(name, value)
        return True


def defaults(
    firmware: Firmware,
    model: VehicleModel,
    af: AirframeParams,
    *,
    sysid: int,
    wind: tuple[float, float],
) -> Parameters:
    """The table a vehicle boots with; `wind` is (speed m/s, direction it blows from)."""
    fw = firmware
    p = Parameters(
        {
            "SYSID_THISMAV": (float(sysid), 2),
            "ARMING_CHECK": (1.0, 6),
            "FENCE_ENABLE": (0.0, 2),
            # AP_Rally: ArduPlane 0 (the recorded QuadPlane), ArduCopter and Rover 1
            "RALLY_INCL_HOME": (0.0 if fw == Firmware.PLANE else 1.0, 2),
            "FENCE_ACTION": (1.0, 2),
            # ArduPilot's defaults: Copter ALT_MAX|CIRCLE|POLYGON, Plane POLYGON, Rover
            # CIRCLE|POLYGON; the simulator enforces the POLYGON bit (polygon/circle items)
            "FENCE_TYPE": ({Firmware.COPTER: 7.0, Firmware.PLANE: 4.0}.get(fw, 6.0), 2),
            "CHUTE_ENABLED": (1.0 if af.has_parachute else 0.0, 2),
            "BATT_CAPACITY": (af.battery.capacity_mah, 6),
            "BATT_MONITOR": (4.0, 2),  # analog voltage and current, as SITL's copter.parm
            "SIM_WIND_SPD": (wind[0], 9),
            "SIM_WIND_DIR": (wind[1], 9),
            "MIS_TOTAL": (0.0, 4),
            "SYSID_MYGCS": (255.0, 4),
        }
    )
    if fw == Firmware.COPTER:
        p |= {
            "WPNAV_SPEED": (af.cruise_speed_m_s * 100, 9),
            "WPNAV_SPEED_UP": (af.climb_rate_m_s * 100, 9),
            "WPNAV_SPEED_DN": (af.sink_rate_m_s * 100, 9),
            "WPNAV_RADIUS": (af.wp_radius_m * 100, 9),
            "WPNAV_ACCEL": (af.accel_m_s2 * 100, 9),
            "RTL_ALT": (af.rtl_alt_m * 100, 9),
            "LAND_SPEED": (af.land_speed_m_s * 100, 4),
            "DISARM_DELAY": (10.0, 2),
            "ANGLE_MAX": (3000.0, 4),  # ArduCopter's default lean limit, cdeg
            # the GCS failsafe (failsafes.py), ArduCopter's defaults: off, 5 s
            "FS_GCS_ENABLE": (0.0, 2),
            "FS_GCS_TIMEOUT": (5.0, 9),
            "FS_OPTIONS": (0.0, 6),
        }
    elif fw == Firmware.PLANE:
        p |= {
            "AIRSPEED_CRUISE": (af.cruise_speed_m_s, 9),
            "AIRSPEED_MIN": (af.min_airspeed_m_s, 4),
            "AIRSPEED_MAX": (af.max_speed_m_s, 4),
            "WP_RADIUS": (af.wp_radius_m, 4),
            "WP_LOITER_RAD": (af.loiter_radius_m, 4),
            "RTL_ALTITUDE": (af.rtl_alt_m, 9),
            "TKOFF_ALT": (af.takeoff_alt_m, 9),
            "RTL_AUTOLAND": (0.0, 2),
            # the GCS failsafe (failsafes.py), ArduPlane's defaults: off, 5 s long,
            # 1.5 s short, no change in AUTO
            "FS_GCS_ENABL": (0.0, 2),
            "FS_LONG_ACTN": (0.0, 2),
            "FS_LONG_TIMEOUT": (5.0, 9),
            "FS_SHORT_ACTN": (0.0, 2),
            "FS_SHORT_TIMEOUT": (1.5, 9),
            "Q_ENABLE": (1.0 if model == VehicleModel.VTOL else 0.0, 2),
            "ROLL_LIMIT_DEG": (af.max_bank_deg, 9),
        }
        if model == VehicleModel.VTOL:
            p |= {
                "Q_WP_SPEED": (af.vtol_speed_m_s * 100, 9),
                "Q_WP_SPEED_UP": (af.vtol_climb_rate_m_s * 100, 9),
                "Q_WP_SPEED_DN": (af.vtol_sink_rate_m_s * 100, 9),
                "Q_LAND_SPEED": (af.land_speed_m_s * 100, 4),
                "Q_LAND_FINAL_ALT": (af.land_final_alt_m, 9),
                "Q_TRANSITION_MS": (af.transition_time_s * 1000, 4),
                "Q_RTL_MODE": (0.0, 2),  # 0: RTL circles its point; 1: then QRTL, lands
            }
    else:
        p |= {
            "WP_SPEED": (af.cruise_speed_m_s, 9),
            "CRUISE_SPEED": (af.cruise_speed_m_s, 9),
            "WP_RADIUS": (af.wp_radius_m, 9),
            "FRAME_CLASS": (2.0 if model == VehicleModel.BOAT else 1.0, 2),
        }
    return p
