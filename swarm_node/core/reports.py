"""What the node publishes about itself: its VehicleStatus at 5 Hz and its VehicleInfo
at 1 Hz (`Beacon` keeps the schedule; NodeCore fills them from the modules that own
each value: the autopilot's state, the state machine and the mission, the fleet, the
alerts of vehicle monitoring and avoidance).

Pure: no I/O, no clock.
"""

from __future__ import annotations

from dataclasses import dataclass

from swarm_proto import AlertCode, FsmState, GeoPoint, VehicleInfo

from .autopilot.state import AutopilotState
from .mission.published import published_home
from .profile import VehicleProfile, published_capacity_mah


@dataclass(frozen=True)
class MissionReport:
    """The mission's part of our VehicleInfo (the mission coordinator's)."""

    mission_id: int | None
    fsm_state: FsmState
    members_hash: int
    progress_m: float  # on the radio's grid (mission/published.py)
    path_m: float
    entry_unix_s: float  # our PREMISSION ETA at our entry
    battery_pct: int


@dataclass
class Beacon:
    """When the next VehicleStatus and VehicleInfo are due (late: no catch-up burst)."""

    status_period_s: float
    info_period_s: float
    next_status: float
    next_info: float

    def status_due(self, now: float) -> bool:
        if now < self.next_status:
            return False
        self.next_status = max(self.next_status + self.status_period_s, now)
        return True

    def info_due(self, now: float) -> bool:
        if now < self.next_info:
            return False
        self.next_info = max(self.next_info + self.info_period_s, now)
        return True

    def next_deadline(self) -> float:
        return min(self.next_status, self.next_info)


def vehicle_info(
    profile: VehicleProfile,
    ap: AutopilotState,
    mission: MissionReport,
    *,
    base: GeoPoint | None,
    fleet_id: int,
    errors: tuple[AlertCode, ...],
) -> VehicleInfo:
    p, mid = profile, mission.mission_id
    return VehicleInfo(
        vehicle_id=p.vehicle_id,
        vehicle_type=p.vehicle_type,
        model=p.model[:48],
        user_id=p.user_id[:48],
        mav_sysid=ap.sysid & 0xFF,
        payload_model=p.payload_model[:48],
        payload_subtype=p.payload_subtype[:48],
        payload_type=p.payload_type[:48],
        cruise_speed_m_s=clamp(p.cruise_speed_m_s, 0.0, 300.0),
        home=published_home(ap.home),
        base=base,
        fleet_id=fleet_id,
        mission_id=mid if mid is not None and mid > 0 else 0,
        fsm_state=mission.fsm_state,
        errors=errors,
        members_hash=mission.members_hash,
        # on the radio's grid: what every member hears and plans from, we too
        mission_progress_m=mission.progress_m,
        mission_path_m=mission.path_m,
        roll_deg=clamp(ap.roll_deg, -180.0, 180.0),
        pitch_deg=clamp(ap.pitch_deg, -180.0, 180.0),
        sensors_present=ap.sensors_present & 0xFFFFFFFF,
        sensors_health=ap.sensors_health & 0xFFFFFFFF,
        mav_type=ap.mav_type & 0xFF,
        entry_unix_s=clamp(mission.entry_unix_s, 0.0, 4.0e9),
        battery_pct=mission.battery_pct,
        battery_capacity_mah=published_capacity_mah(ap.battery_capacity_mah),
    )


def clamp(x: float, lo: float, hi: float) -> float:
    if x != x:  # NaN from a broken value: report the low bound, never crash
        return lo
    return min(max(x, lo), hi)
