"""One mission's fixed-wing members on one schedule (paper section 2.3.5): the
PREMISSION meet and the MISSION speed rule, as the mission manager flies them.

Who: the paper's PREMISSION "is not required ... when the aircraft is not of the
fixed-wing type, when there is only one vehicle involved". The sync group of a plan is
its fixed-wing members (PLANE, VTOL) when there are at least two of them, for the
mission types whose shares have an entry point (area, target, perimeter, route,
objective); hover-capable and ground members fly their shares as planned.

PREMISSION, with no leader: when the plan is made, each member of the group predicts
when it can be at its share's entry at the earliest (`FleetSync.begin`: launch and climb
from the ground, the leg's upload and start, a VTOL's forward transition, the Dubins
leg from where it is at its fastest speed, then ETA_MARGIN and ETA_MARGIN_S for what
the model misses) and publishes it (`VehicleInfo.entry_unix_s`). The meet time T is the
latest ETA of the group's members still in the mission (`meet_time`): a max, the same
on every node that heard the same ETAs, in any order. Once climbed and T known (every
member's ETA heard, or META_WAIT_S passed), each member plans its own leg from its real
pose and heading to arrive at T (`plan_leg`, `planning.premission`: the Dubins path,
the arrival speed, whole waiting orbits where needed), uploads it followed by its share
from the entry on, and in flight sets its airspeed every CONTROL_PERIOD_S to what brings
it to the entry at T (`premission_speed` on what is left of the leg). A member that
cannot make T after all publishes its new ETA: T only moves later, for everyone.

Watchdog: a member still on its leg well past the meet time (`overdue`: LEG_OVERDUE_S,
or LEG_OVERDUE_FRACTION of the leg's planned time if longer) gives up the meet and flies
its share from where it is, with an alert: an autopilot circling a waypoint it cannot
reach, or a leg started on items it had flown past while they were uploaded, would
otherwise fly until its battery is low, the node silent.

MISSION: past the entry, every member's lateness is measured against its share's
planned schedule from T (`Share.planned_s_at`, from the entry on); `sync_speed` speeds
up a member behind the group's mean lateness and slows one ahead, in proportion, within
the speeds its planned turns allow, with a dead band (`control`). The schedule past the
entry is the share's metres at its mission speed; the others' lateness comes from their
published progress in metres (VehicleInfo, 1 Hz).

Pure: no I/O, no clock (time comes in as `now`, absolute Unix seconds: the members'
clocks are GPS time).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Collection, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from swarm_proto import MissionType, NoFlyZone, VehicleType

from ..autopilot.items import ItemKind, Waypoint
from ..autopilot.state import AutopilotState
from ..planning import PlanningError, PlanVehicle, VehiclePose
from ..planning.endurance import transition_s
from ..planning.fleet_plan import FleetPlan, Share, flyable
from ..planning.premission import (
    PremissionLeg,
    entry_index,
    premission,
    premission_speed,
    sync_speed,
)
from ..profile import VehicleProfile

#: mission types whose shares have an entry the fleet can meet at
SYNC_TYPES = frozenset(
    {
        MissionType.AREA,
        MissionType.TARGET,
        MissionType.PERIMETER,
        MissionType.ROUTE,
        MissionType.OBJECTIVE,
    }
)
CONTROL_PERIOD_S = 1.0  # airspeed set this often (the bench's closed loop)
SPEED_STEP_M_S = 0.2  # smaller speed changes are not sent
START_DELAY_S = 1.0  # from the start command to flying the leg (mode change, ack)
UPLOAD_S = 2.0  # the leg's upload (counted in the first ETA)
RESEND_S = 5.0  # an airspeed the autopilot does not fly is commanded again after this
ETA_MARGIN = 0.02  # of the predicted time, for what the model misses ...
ETA_MARGIN_S = 2.0  # ... and a fixed part (an arming retry, a slow upload)
META_WAIT_S = 15.0  # climbed: wait at most this long for the others' ETAs
#: the PREMISSION watchdog: a leg not at its entry this long after the meet time (or
#: this fraction of the leg's planned time, if longer) makes no progress (a
#: demo VTOL circled its leg's first waypoint until BATTERY_LOW): the share is flown
#: from where the vehicle is, with an alert
LEG_OVERDUE_S = 30.0
LEG_OVERDUE_FRACTION = 0.5
#: switches for the benchmark's baselines: the fleet without a meet, and without the
#: MISSION speed rule (bench/mission.py)
PREMISSION = True
SPEED_RULE = True


def sync_group(plan: FleetPlan) -> tuple[int, ...]:
    """The members that meet at their entries together: the plan's fixed-wing members
    when there are at least two, for SYNC_TYPES; () otherwise."""
    if not PREMISSION or plan.mission.mission_type not in SYNC_TYPES:
        return ()
    ids = tuple(
        sorted(
            v.vehicle_id
            for v in plan.vehicles
            if v.profile.is_fixed_wing and v.vehicle_id in plan.shares
        )
    )
    return ids if len(ids) >= 2 else ()


def _pose(ap: AutopilotState, alt_rel_m: float | None = None) -> VehiclePose:
    assert ap.lat_deg is not None and ap.lon_deg is not None
    return VehiclePose(
        ap.lat_deg,
        ap.lon_deg,
        (ap.alt_rel_m or 0.0) if alt_rel_m is None else alt_rel_m,
        ap.heading_deg,
        ap.groundspeed_m_s if ap.armed else 0.0,
    )


@dataclass
class FleetSync:
    self_id: int
    profile: VehicleProfile
    group: tuple[int, ...] = ()
    plan: FleetPlan | None = None
    eta_unix_s: float = 0.0  # our published ETA at the entry (0: no PREMISSION)
    meet_unix_s: float = 0.0  # the meet time our leg was planned for (0: no leg yet)
    leg: PremissionLeg | None = None
    entry_seq: int = 0  # the uploaded item (seq, 0 = home) of our entry
    arrived_at: float | None = None  # when we reached the entry
    ready_at: float | None = None  # climbed, waiting for the meet time since
    depart_unix_s: float = 0.0  # when to start the leg
    entry_along_m: dict[int, float] = field(default_factory=dict)  # share metres at entries
    commands: int = 0  # airspeed commands sent (tests, logs)
    info_due: bool = False  # our ETA changed: publish VehicleInfo now
    _range: tuple[float, float] = (0.0, math.inf)
    _nominal_m_s: float = 0.0
    _commanded_m_s: float = 0.0
    _next_control: float = 0.0
    _sent_at: float = -math.inf

    @property
    def active(self) -> bool:
        """This vehicle flies a PREMISSION in the current plan."""
        return self.self_id in self.group

    @property
    def flying_leg(self) -> bool:
        """On the way to the entry (the sortie shows PREMISSION)."""
        return self.active and self.leg is not None and self.arrived_at is None

    def stop(self) -> None:
        if self.eta_unix_s:
            self.info_due = True
        self.group, self.plan, self.leg = (), None, None
        self.eta_unix_s = self.meet_unix_s = 0.0
        self.entry_seq, self.arrived_at, self.ready_at = 0, None, None
        self.depart_unix_s = 0.0
        self.entry_along_m = {}

    # ------------------------------------------------------------------ PREMISSION
    def begin(
        self,
        plan: FleetPlan,
        ap: AutopilotState,
        zones: Sequence[NoFlyZone],
        now: float,
        home_alt_msl_m: float,
        launch_s: float,
    ) -> bool:
        """At the plan: whether this vehicle flies a PREMISSION (then `eta_unix_s` is its
        first ETA, to publish). `launch_s`: from now to climbed (0 in the air). A leg
        that cannot be planned (no clear way, no position) leaves the PREMISSION out:
        the vehicle flies its share as planned."""
        self.stop()
        group = sync_group(plan)
        if self.self_id not in group or ap.lat_deg is None or ap.lon_deg is None:
            return False
        alt = plan.share(self.self_id).waypoints[entry_index(plan, self.self_id)].alt_rel_m
        try:
            pm = premission(
                plan,
                [PlanVehicle(self.profile, _pose(ap, alt))],
                zones=zones,
                now_unix_s=now,
                home_alt_msl_m=home_alt_msl_m,
            )
            along = {vid: plan.share(vid).along_m[entry_index(plan, vid)] for vid in group}
        except (PlanningError, ValueError):
            return False
        leg = pm.legs[self.self_id]
        t = launch_s + UPLOAD_S + START_DELAY_S + self._transition_s(ap, leg.speed_m_s)
        t += pm.arrival_s
        self.group, self.plan, self.entry_along_m = group, plan, along
        self.eta_unix_s = now + t * (1.0 + ETA_MARGIN) + ETA_MARGIN_S
        self.info_due = True
        return True

    def _transition_s(self, ap: AutopilotState, speed_m_s: float) -> float:
        """A VTOL in hover first transitions to forward flight."""
        return transition_s(self.profile, speed_m_s) if self._hovering(ap) else 0.0

    def meet_time(self, etas: Mapping[int, float], gone: Collection[int]) -> float | None:
        """T: the latest ETA of the group's members still in the mission, once every one
        is heard (None before); never earlier than the leg was planned for."""
        known = [self.eta_unix_s, self.meet_unix_s]
        missing = False
        for vid in self.group:
            if vid == self.self_id or vid in gone:
                continue
            t = etas.get(vid, 0.0)
            if t > 0.0:
                known.append(t)
            else:
                missing = True
        if missing and self.leg is None:
            return None
        return max(known)

    def ready(self, etas: Mapping[int, float], gone: Collection[int], now: float) -> float | None:
        """Climbed: the meet time to plan the leg for, or None to wait (for at most
        META_WAIT_S: then the ETAs heard are enough)."""
        if self.ready_at is None:
            self.ready_at = now
        t = self.meet_time(etas, gone)
        if t is None and now - self.ready_at >= META_WAIT_S:
            t = max([self.eta_unix_s, *(etas.get(v, 0.0) for v in self.group if v not in gone)])
        return t

    def plan_leg(
        self,
        ap: AutopilotState,
        zones: Sequence[NoFlyZone],
        now: float,
        home_alt_msl_m: float,
        meet_unix_s: float,
    ) -> tuple[Waypoint, ...]:
        """Our leg from where we are (position, heading, speed) to our entry, arriving
        at `meet_unix_s`; the items to upload: the leg, then our share from the entry on;
        `depart_unix_s`: when to start them. A VTOL in hover waits there and leaves in
        time to fly the leg at its mission speed (faster if it must); a vehicle in
        forward flight leaves at once and loses time in whole waiting orbits. If the
        leg cannot make it, our ETA moves (publish it). Raises PlanningError."""
        assert self.plan is not None
        if ap.lat_deg is None or ap.lon_deg is None:
            raise PlanningError("no position")
        share = self.plan.share(self.self_id)
        speed = share_speed(share, self.profile)
        me = [PlanVehicle(self.profile, _pose(ap))]
        kw: dict[str, Any] = {"zones": zones, "now_unix_s": now, "home_alt_msl_m": home_alt_msl_m}
        fv = PlanVehicle(flyable(self.profile))
        if self._hovering(ap):
            path = premission(self.plan, me, **kw).legs[self.self_id].path_m
            lo, hi = fv.speed_range_on(fv.profile.turn_radius_m())
            v = _leg_speed(
                lambda v: START_DELAY_S + transition_s(self.profile, v) + path / v,
                meet_unix_s - now,
                min(max(speed, lo), hi),
                hi,
            )
            pm = premission(self.plan, me, not_before_s=path / v, **kw)
            leg = pm.legs[self.self_id]
            need = START_DELAY_S + transition_s(self.profile, leg.speed_m_s) + leg.arrival_s
            depart = max(now, meet_unix_s - need)
        else:
            pm = premission(
                self.plan, me, not_before_s=max(meet_unix_s - now - START_DELAY_S, 0.0), **kw
            )
            leg = pm.legs[self.self_id]
            need, depart = START_DELAY_S + leg.arrival_s, now
        arrive = depart + need
        if arrive > meet_unix_s + 0.5:  # cannot make it: the fleet waits for us
            self.eta_unix_s, self.info_due = arrive, True
        self.meet_unix_s = max(meet_unix_s, arrive)
        self.depart_unix_s = depart
        self.leg = leg
        self.entry_seq = 1 + max(
            k for k, w in enumerate(leg.waypoints) if w.kind == ItemKind.WAYPOINT
        )
        r = max(leg.orbit_m / (2.0 * math.pi), fv.profile.turn_radius_m())
        self._range = fv.speed_range_on(r)
        self._nominal_m_s = speed
        self._commanded_m_s = leg.speed_m_s
        self._next_control = depart + CONTROL_PERIOD_S
        return pm.mission_waypoints(share)

    def _hovering(self, ap: AutopilotState) -> bool:
        """A VTOL not (yet) in forward flight: it can wait on the spot."""
        return self.profile.vehicle_type == VehicleType.VTOL and (
            not ap.armed or ap.groundspeed_m_s < self.profile.min_speed_m_s
        )

    # ------------------------------------------------------------------ in flight
    def overdue(self, now: float, meet_unix_s: float) -> float | None:
        """The PREMISSION watchdog: seconds past the meet time (the later of `meet_unix_s`
        and the one our leg was planned for) when our leg, flown, has still not reached
        the entry LEG_OVERDUE_S after it (or LEG_OVERDUE_FRACTION of the leg's planned
        time, if longer); else None."""
        if not self.flying_leg:
            return None
        meet = max(meet_unix_s, self.meet_unix_s)
        grace = max(LEG_OVERDUE_S, LEG_OVERDUE_FRACTION * max(meet - self.depart_unix_s, 0.0))
        late = now - meet
        return late if late > grace else None

    def control(
        self,
        ap: AutopilotState,
        now: float,
        reached_seq: int,
        progress_m: float,
        meet_unix_s: float,
        peers: Mapping[int, tuple[float, float]],
        gone: Collection[int],
    ) -> float | None:
        """The airspeed to command now, or None (no change). Before the entry: what
        reaches it at `meet_unix_s` over what is left of the leg; past it, the MISSION
        speed rule against the group (`peers`: their published (progress_m, path_m))."""
        if self.leg is None or self.plan is None or now < self._next_control:
            return None
        self._next_control = now + CONTROL_PERIOD_S
        if self.arrived_at is None and reached_seq >= self.entry_seq:
            self.arrived_at = now
        if self.arrived_at is None:
            if ap.lat_deg is None or ap.lon_deg is None:
                return None
            left = self.leg.remaining_m(reached_seq - 1, ap.lat_deg, ap.lon_deg)
            if left is None:  # a waiting orbit still to fly: its progress is not measured
                return None
            return self._command(premission_speed(left, meet_unix_s - now, self._range), ap, now)
        if not SPEED_RULE:
            return None
        own = self.lateness_s(self.self_id, progress_m, now - meet_unix_s)
        others: dict[int, float] = {}
        for vid in self.group:
            if vid == self.self_id or vid in gone or vid not in peers:
                continue
            done, _path = peers[vid]
            if done >= self.entry_along_m.get(vid, math.inf) - 1.0:  # past its entry
                others[vid] = self.lateness_s(vid, done, now - meet_unix_s)
        cmd = sync_speed(own, others, self._nominal_m_s, self._range)
        return self._command(cmd.speed_m_s, ap, now)

    def lateness_s(self, vid: int, progress_m: float, elapsed_s: float) -> float:
        """How late member `vid` is, `progress_m` along its share, `elapsed_s` after the
        meet time: its schedule from its entry is its share's metres at its mission
        speed (the same pace for every member: a share's planned time also holds its
        planned approach and waiting orbits, which the PREMISSION leg replaced)."""
        assert self.plan is not None
        share = self.plan.share(vid)
        entry = self.entry_along_m.get(vid, 0.0)
        profile = next((v.profile for v in self.plan.vehicles if v.vehicle_id == vid), self.profile)
        speed = share_speed(share, profile)
        return elapsed_s - max(progress_m - entry, 0.0) / speed

    def _command(self, v: float, ap: AutopilotState, now: float) -> float | None:
        """`v` if it differs from what was commanded, or if the autopilot does not fly
        what was commanded RESEND_S after it was sent (a mission's CHANGE_SPEED item or
        a VTOL's transition took over); else None."""
        if not math.isfinite(v):
            return None
        changed = abs(v - self._commanded_m_s) >= SPEED_STEP_M_S
        ignored = (
            abs(ap.airspeed_m_s - v) > 1.0
            and ap.airspeed_m_s >= self._range[0] - 1.0
            and now - self._sent_at >= RESEND_S
        )
        if not (changed or ignored):
            return None
        self._commanded_m_s, self._sent_at = v, now
        self.commands += 1
        return v


def _leg_speed(need_s: Callable[[float], float], have_s: float, cruise: float, top: float) -> float:
    """The speed in [cruise, top] whose time `need_s(v)` fits in `have_s`: cruise if it
    does, else the slowest that does (bisection: the time falls with the speed), else
    `top`."""
    if need_s(cruise) <= have_s or top <= cruise:
        return cruise
    if need_s(top) > have_s:
        return top
    a, b = cruise, top
    for _ in range(40):
        m = 0.5 * (a + b)
        a, b = (m, b) if need_s(m) > have_s else (a, m)
    return b


def share_speed(share: Share, profile: VehicleProfile) -> float:
    """The share's mission speed (its first CHANGE_SPEED), else the cruise speed."""
    return next(
        (w.speed_m_s for w in share.waypoints if w.kind == ItemKind.CHANGE_SPEED and w.speed_m_s),
        profile.cruise_speed_m_s,
    )
