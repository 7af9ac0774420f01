"""From database rows to the plain data the pure cores use (`VehicleProfile`,
`PayloadClass`). Pure: the repository runs the query (PROFILE_SQL) and hands each row
here as a mapping."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from swarm_node.core.profile import CameraProfile, VehicleProfile
from swarm_proto import VehicleType

from .errors import ProfileError

# One row per system: its identity, model parameters, payload hierarchy and camera.
PROFILE_SQL = """
SELECT s.id AS vehicle_id, s.user_id, sm.name AS model, st.name AS system_subtype,
       sty.name AS system_type, st.vehicle_type, mp.model_id AS params_model_id,
       mp.cruise_speed_m_s, mp.min_speed_m_s, mp.max_speed_m_s, mp.max_bank_deg,
       mp.climb_rate_m_s, mp.sink_rate_m_s, mp.loiter_radius_m, mp.has_parachute,
       mp.battery_low_pct, mp.battery_critical_pct, mp.max_tilt_deg, mp.max_altitude_m,
       mp.max_wind_m_s, mp.wingspan_m, mp.battery_capacity_mah, mp.cruise_current_a,
       mp.hover_current_a, mp.accel_m_s2,
       pm.name AS payload_model, ps.name AS payload_subtype, pt.name AS payload_type,
       sen.kind AS sensor_kind, sp.hfov_deg, sp.vfov_deg, sp.width_px, sp.height_px,
       (gc.pan_axis_id IS NOT NULL) + (gc.tilt_axis_id IS NOT NULL)
         + (gc.roll_axis_id IS NOT NULL) AS gimbal_axes
FROM systems s
JOIN system_layouts sl ON sl.id = s.layout_id
JOIN system_models sm ON sm.id = sl.model_id
JOIN system_subtypes st ON st.id = sm.subtype_id
JOIN system_types sty ON sty.id = st.type_id
LEFT JOIN system_model_params mp ON mp.model_id = sm.id
LEFT JOIN payload_layouts pl ON pl.id = sl.payload_layout_id
LEFT JOIN payload_models pm ON pm.id = pl.model_id
LEFT JOIN payload_subtypes ps ON ps.id = pm.subtype_id
LEFT JOIN payload_types pt ON pt.id = ps.type_id
LEFT JOIN sensors sen ON sen.id = pl.sensor_id
LEFT JOIN sensor_params sp ON sp.sensor_id = pl.sensor_id
LEFT JOIN gimbal_configs gc ON gc.id = pl.gimbal_id
"""

IMAGING_SENSORS = ("camera", "thermal")


def mav_sysid_of(params: Mapping[str, str], vehicle_id: int) -> int:
    """A system's MAVLink system id, from its `system_params` (`mav_sysid`; 0: none
    given). ProfileError when it is not one (1-255)."""
    text = str(params.get("mav_sysid", "")).strip()
    if not text:
        return 0
    if not text.isdigit() or not 1 <= int(text) <= 255:
        raise ProfileError(
            f"system {vehicle_id}: mav_sysid {text[:20]!r} is not a MAVLink system id (1-255)"
        )
    return int(text)


def profile_from_row(row: Mapping[str, Any]) -> VehicleProfile:
    """The VehicleProfile of one PROFILE_SQL row. Raises ProfileError when the model
    has no parameters or the subtype names an unknown vehicle type."""
    who = f"system {row['vehicle_id']} ({row['user_id']}, {row['model']})"
    if row["params_model_id"] is None:
        raise ProfileError(
            f"{who}: model {row['model']!r} has no parameters (add them to systems.model-params)"
        )
    try:
        vehicle_type = VehicleType(row["vehicle_type"])
    except ValueError:
        raise ProfileError(
            f"{who}: subtype {row['system_subtype']!r} names vehicle type "
            f"{row['vehicle_type']}, unknown to this bandada"
        ) from None
    camera = None
    if (
        row["sensor_kind"] in IMAGING_SENSORS
        and row["hfov_deg"] is not None
        and row["vfov_deg"] is not None
    ):
        camera = CameraProfile(
            hfov_deg=float(row["hfov_deg"]),
            vfov_deg=float(row["vfov_deg"]),
            resolution_px=(int(row["width_px"] or 0), int(row["height_px"] or 0)),
            gimbal_axes=int(row["gimbal_axes"] or 0),
        )
    return VehicleProfile(
        vehicle_id=int(row["vehicle_id"]),
        user_id=row["user_id"],
        model=row["model"],
        vehicle_type=vehicle_type,
        system_type=row["system_type"],
        system_subtype=row["system_subtype"],
        payload_model=row["payload_model"] or "",
        payload_subtype=row["payload_subtype"] or "",
        payload_type=row["payload_type"] or "",
        cruise_speed_m_s=float(row["cruise_speed_m_s"]),
        min_speed_m_s=float(row["min_speed_m_s"]),
        max_speed_m_s=float(row["max_speed_m_s"]),
        max_bank_deg=float(row["max_bank_deg"]),
        climb_rate_m_s=float(row["climb_rate_m_s"]),
        sink_rate_m_s=float(row["sink_rate_m_s"]),
        loiter_radius_m=float(row["loiter_radius_m"]),
        has_parachute=bool(row["has_parachute"]),
        battery_low_pct=int(row["battery_low_pct"]),
        battery_critical_pct=int(row["battery_critical_pct"]),
        max_tilt_deg=float(row["max_tilt_deg"]),
        camera=camera,
        max_altitude_m=float(row["max_altitude_m"]),
        max_wind_m_s=float(row["max_wind_m_s"]),
        wingspan_m=float(row["wingspan_m"]),
        battery_capacity_mah=float(row["battery_capacity_mah"]),
        cruise_current_a=float(row["cruise_current_a"]),
        hover_current_a=float(row["hover_current_a"]),
        accel_m_s2=float(row["accel_m_s2"]),
    )
