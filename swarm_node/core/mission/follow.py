"""MUM-T as the mission manager flies it: each follower holds its formation slot around
the lead (`MissionParams.lead_vehicle_id`, a swarm node whose VehicleStatus every node
hears: a manned aircraft or vehicle with a node, or any vehicle).

Slots without a leader: the fleet plan assigns them once from inputs every member has
(`plan_mumt` with the followers at their homes and the lead at the mission's point:
the nearest slots, the same on every node); in flight each follower plans only its own
slot, kept (`previous`), in the whole formation's vee (`vee_offsets` for every
follower), from the lead's last status: every UPDATE_S it is sent (Goto: GUIDED, the
autopilot flies to the point) to its slot where the lead will be LOOKAHEAD_S after now
(`plan_mumt`), at the speed that closes its along-track error to the slot where the
lead is now (the lead's speed plus the error over 20 s: against the slot ahead, a
follower would settle LOOKAHEAD_S ahead of its place).

It ends after `duration_s` following (none: until cancelled), or when the lead has not
been heard for LEAD_TIMEOUT_S (the follower then returns home with the fleet's rules).

Pure: no I/O, no clock. Planning one slot is light (one vehicle, no coverage): it runs
on the control loop, like the approach legs (`mission_manager._with_approach`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from swarm_proto import MissionParams, NoFlyZone, VehicleStatus

from ..autopilot.requests import ApRequest, ChangeSpeed, Goto
from ..autopilot.state import AutopilotState
from ..planning import LeadState, MumtPlan, Offset, PlanningError, PlanVehicle, VehiclePose
from ..planning.fleet_plan import FleetPlan
from ..planning.mumt import DEFAULT_SPACING_M, DEFAULT_STEP_M, plan_mumt, vee_offsets
from ..profile import VehicleProfile

UPDATE_S = 1.0  # a new slot this often
LOOKAHEAD_S = 5.0  # where the lead will be (plan_mumt's default)
LEAD_TIMEOUT_S = 10.0  # no news of the lead this long: the follow ends
MOVE_M = 3.0  # a slot that moved less is not sent again ...
SPEED_STEP_M_S = 0.3  # ... nor a speed that changed less


def formation(plan: FleetPlan) -> tuple[int, tuple[Offset, ...]] | None:
    """The vee of a MUM-T fleet plan: (its size, every slot's offset), as `plan_mumt`
    made it for all the followers."""
    detail = plan.detail
    if not isinstance(detail, MumtPlan):
        return None
    params = plan.mission.params
    r_max = max((v.profile.turn_radius_m() for v in plan.vehicles), default=0.0)
    spacing = max(params.radius_m or DEFAULT_SPACING_M, 2.0 * r_max)
    step = params.altitude_step_m or DEFAULT_STEP_M
    n = len(detail.slots)
    return n, tuple(vee_offsets(n, spacing, step))


@dataclass
class Follow:
    vehicle_id: int
    profile: VehicleProfile
    lead_id: int
    slot: int  # our slot's index in the vee
    offsets: tuple[Offset, ...]
    params: MissionParams
    duration_s: float | None = None
    lead: LeadState | None = None
    lead_heard_at: float | None = None
    started_at: float | None = None  # following since (climbed)
    sent: tuple[float, float, float] | None = None  # the last slot sent (lat, lon, speed)
    errors: int = 0  # slots that could not be planned (logged, counted)
    _next: float = 0.0

    @classmethod
    def of(cls, plan: FleetPlan, profile: VehicleProfile) -> Follow | None:
        detail = plan.detail
        vee = formation(plan)
        if not isinstance(detail, MumtPlan) or vee is None:
            return None
        mine = next((s for s in detail.slots if s.vehicle_id == profile.vehicle_id), None)
        if mine is None:
            return None
        p = plan.mission.params
        return cls(
            profile.vehicle_id,
            profile,
            p.lead_vehicle_id,
            mine.index,
            vee[1],
            p,
            p.duration_s or None,
        )

    def on_status(self, status: VehicleStatus, now: float) -> None:
        """The lead's telemetry (others' are ignored; a malformed one is counted)."""
        if status.vehicle_id != self.lead_id:
            return
        try:
            self.lead = LeadState.from_status(status)
        except PlanningError:
            self.errors += 1
            return
        self.lead_heard_at = now

    def begin(self, now: float) -> None:
        if self.started_at is None:
            self.started_at = now

    def over(self, now: float) -> str | None:
        """Why the follow ends now (None: it goes on)."""
        if self.started_at is None:
            return None
        if self.duration_s and now - self.started_at >= self.duration_s:
            return f"followed for {self.duration_s:g} s"
        heard = self.lead_heard_at if self.lead_heard_at is not None else self.started_at
        if now - heard >= LEAD_TIMEOUT_S:
            return f"lead {self.lead_id} not heard for {LEAD_TIMEOUT_S:g} s"
        return None

    def step(
        self, ap: AutopilotState, now: float, zones: Sequence[NoFlyZone], home_alt_msl_m: float
    ) -> list[ApRequest]:
        """Every UPDATE_S: our slot where the lead will be, and the speed to close on it
        (nothing when it barely moved; nothing without the lead or a position)."""
        if now < self._next or self.lead is None or ap.lat_deg is None or ap.lon_deg is None:
            return []
        self._next = now + UPDATE_S
        me = PlanVehicle(
            self.profile,
            VehiclePose(
                ap.lat_deg, ap.lon_deg, ap.alt_rel_m or 0.0, ap.heading_deg, ap.groundspeed_m_s
            ),
        )
        kw: dict[str, Any] = {
            "now_s": now,
            "previous": {self.vehicle_id: self.slot},
            "offsets": self.offsets,
            "zones": zones,
            "home_alt_msl_m": home_alt_msl_m,
        }
        try:  # steer for the slot where the lead will be, close on where it is now
            plan = plan_mumt(self.lead, [me], self.params, lookahead_s=LOOKAHEAD_S, **kw)
            now_plan = plan_mumt(self.lead, [me], self.params, lookahead_s=0.0, **kw)
        except (PlanningError, ValueError):
            self.errors += 1
            return []
        slot = now_plan.slot_of(self.vehicle_id)
        wp = plan.vehicles[0].waypoints[-1]
        if self.sent is not None:
            lat, lon, v = self.sent
            moved = math.hypot(
                (wp.lat_deg - lat) * 111_320.0,
                (wp.lon_deg - lon) * 111_320.0 * math.cos(math.radians(lat)),
            )
            if moved < MOVE_M and abs(slot.speed_m_s - v) < SPEED_STEP_M_S:
                return []
        self.sent = (wp.lat_deg, wp.lon_deg, slot.speed_m_s)
        return [
            Goto(lat_deg=wp.lat_deg, lon_deg=wp.lon_deg, alt_rel_m=wp.alt_rel_m),
            ChangeSpeed(speed_m_s=max(slot.speed_m_s, 0.5)),
        ]
