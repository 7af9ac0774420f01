"""AutopilotState -> swarm_proto.VehicleStatus (the 5 Hz telemetry every node publishes).

The node adds what only it knows (its id, state machine and mission manager states,
fleet, alert flags); everything else comes from the autopilot. Values are clamped into
the message's declared ranges so a published status always validates.
"""

from __future__ import annotations

import math

from swarm_proto import AlertFlag, FsmState, GpsFix, MissionState, VehicleStatus

from .state import AutopilotState


def _clamp(v: float, lo: float, hi: float) -> float:
    return lo if v < lo else hi if v > hi else v


def mission_progress_pct(state: AutopilotState) -> int:
    """How far the autopilot is through its mission, from MISSION_CURRENT and
    MISSION_ITEM_REACHED: items before the current one, or up to the last reached, out
    of the items after home (item 0)."""
    last = state.mission_count - 1
    if last < 1:
        return 0
    done = max(state.mission_current - 1, state.mission_reached, 0)
    return int(_clamp(round(100.0 * done / last), 0, 100))


def to_vehicle_status(
    state: AutopilotState,
    *,
    vehicle_id: int,
    now_unix_s: float,
    fsm_state: FsmState = FsmState.INACTIVE,
    mission_state: MissionState = MissionState.IDLE,
    mission_progress: int | None = None,
    fleet_id: int = 0,
    alerts: AlertFlag = AlertFlag.NONE,
) -> VehicleStatus | None:
    """The status to publish, or None while the autopilot has no position yet.

    `time_unix_s` is the GPS time of the position sample (SYSTEM_TIME and the sample's
    time since boot) when the autopilot has GPS time, else `now_unix_s`; while the link
    is down without GPS time, the time of the last message from the autopilot (the link
    clock, which is the node's): the data's age shows, it never looks fresh.
    `mission_progress` None = computed from the autopilot's mission (see above).
    """
    if state.lat_deg is None or state.lon_deg is None:
        return None
    alt_msl = state.alt_msl_m if state.alt_msl_m is not None else 0.0
    alt_rel = state.alt_rel_m if state.alt_rel_m is not None else 0.0
    t = state.position_time_unix_s if state.position_time_unix_s is not None else now_unix_s
    if state.position_time_unix_s is None and not state.link_ok and state.last_message_s:
        t = min(now_unix_s, state.last_message_s)
    progress = mission_progress_pct(state) if mission_progress is None else mission_progress
    heading = state.heading_deg % 360.0 if math.isfinite(state.heading_deg) else 0.0
    return VehicleStatus(
        vehicle_id=vehicle_id,
        time_unix_s=_clamp(t, 0.0, 4.0e9),
        lat_deg=state.lat_deg,
        lon_deg=state.lon_deg,
        alt_msl_m=_clamp(alt_msl, -1000.0, 8000.0),
        alt_rel_m=_clamp(alt_rel, -1000.0, 8000.0),
        vel_north_m_s=_clamp(state.vel_north_m_s, -300.0, 300.0),
        vel_east_m_s=_clamp(state.vel_east_m_s, -300.0, 300.0),
        vel_down_m_s=_clamp(state.vel_down_m_s, -300.0, 300.0),
        heading_deg=heading if heading < 360.0 else 0.0,
        airspeed_m_s=_clamp(state.airspeed_m_s, 0.0, 300.0),
        battery_pct=int(_clamp(state.battery_pct, -1, 100)),
        battery_v=_clamp(state.battery_v, 0.0, 655.0),
        gps_fix=GpsFix(state.gps_fix),
        gps_sats=int(_clamp(state.gps_sats, 0, 255)),
        ap_mode=int(_clamp(state.mode_number, 0, 255)),
        armed=state.armed,
        fsm_state=fsm_state,
        mission_state=mission_state,
        mission_progress_pct=int(_clamp(progress, 0, 100)),
        fleet_id=fleet_id,
        alerts=alerts,
    )
