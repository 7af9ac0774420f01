"""Vehicle monitoring (paper section 2.3.2): watches the autopilot state and raises
alerts with severities when a safety parameter leaves its expected range.

Pure: `update(state, now, ...)` returns the alerts raised or cleared this step; the
active conditions are `flags` (VehicleStatus.alerts), `emergency` (the most severe
condition at CRITICAL or above, which drives the state machine to STATE_EMERGENCY)
and `ready` (the vehicle has started correctly: link, GPS, EKF and home).

Each condition has hysteresis in time: it is raised after holding for `raise_after_s`
and cleared after being absent for `clear_after_s`, so a voltage sag or one late
packet does not flap alerts. Autopilot link loss is raised at once (the link itself
already waited its timeout), as a WARNING: it becomes an EMERGENCY (CRITICAL on the
ground) only when the loss lasts `link_emergency_after_s` (on a loaded host
one 0.8 s gap, back 0.4 s later, ended a mission ArduPilot was flying fine). That is
5 s, ArduPilot's own convention for a lost ground link (Copter FS_GCS_TIMEOUT, Plane
FS_LONG_TIMEOUT: both 5 s by default; docs/reliability.md), and the node's own stalls
(`note_stall`: its loop not served, a loaded host) do not count toward it.
A link that never came up is not a loss: "no autopilot yet" is a WARNING after
`link_grace_s`, never an emergency (a slow start on a loaded host raised it CRITICAL
91 ms after the link opened); its text says why, as the link reports it.

The vehicle's identity: an autopilot that is not the vehicle the swarm database says
(another HEARTBEAT type, or another MAVLink system id than `mav_sysid`) is
AUTOPILOT_MISMATCH, and another source speaking in this vehicle's name
(`on_identity`, from core/identity.py) is a CRITICAL IDENTITY_CONFLICT. Either makes
the vehicle not ready (missions are refused with the reason); neither is an emergency
(an impostor on the LAN must not be able to bring a flying vehicle down).

The autopilot's own figures win (read from its parameters at link-up: AutopilotState
`max_bank_deg`, `battery_capacity_mah`): the attitude alarm is its roll (ArduPlane
ROLL_LIMIT_DEG) or lean (ArduCopter ANGLE_MAX) limit plus `tilt_margin_deg`, not the
database's `max_tilt_deg` (a QuadPlane banked 61 degrees, within ArduPlane's 65, was
declared abnormal at the database's 60); where the database disagrees (that alarm
inside the autopilot's limit, a battery capacity more than `capacity_tolerance` off) a
WARNING DATABASE_MISMATCH says so once per link-up.

Clocks: the autopilot's GPS time (the time of its position samples, which the node
publishes) and the node's clock may differ (SITL's ran 9.4-10.5 s behind the host's):
a skew over `clock_skew_s` is a WARNING CLOCK_SKEW, once, not a reason to treat fresh
data as stale (peers measure a report's age on their own clock: safety/avoidance.py).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

from swarm_proto import (
    Alert,
    AlertCode,
    AlertFlag,
    GpsFix,
    NoFlyZone,
    Severity,
    VehicleType,
)
from swarm_proto.ardupilot import autopilot_mismatch
from swarm_proto.text import short_text

from .autopilot.state import AutopilotState
from .profile import VehicleProfile
from .safety.zones import ZoneBook, breach
from .safety.zones import inside as inside  # re-exported (was defined here)
from .state_machine import Emergency


@dataclass(frozen=True)
class Thresholds:
    battery_low_pct: int = 30
    battery_critical_pct: int = 15
    max_tilt_deg: float = 60.0
    min_sats: int = 6
    raise_after_s: float = 1.0
    clear_after_s: float = 3.0
    link_grace_s: float = 10.0  # at start, the autopilot link may take this long to come up
    # a link loss lasting this long is an emergency: ArduPilot's FS_GCS_TIMEOUT (Copter)
    # and FS_LONG_TIMEOUT (Plane) default, 5 s (it was 2 s)
    link_emergency_after_s: float = 5.0
    # the attitude alarm above the autopilot's own limit (it overshoots it briefly)
    tilt_margin_deg: float = 10.0
    database_capacity_mah: float = 0.0  # the swarm database's battery (0: unknown)
    capacity_tolerance: float = 0.1  # the database's battery this far off is a mismatch
    clock_skew_s: float = 2.0  # the autopilot's GPS time this far from the node's clock

    @classmethod
    def from_profile(cls, profile: VehicleProfile) -> Thresholds:
        return cls(
            battery_low_pct=profile.battery_low_pct,
            battery_critical_pct=profile.battery_critical_pct,
            max_tilt_deg=profile.max_tilt_deg,
            database_capacity_mah=profile.battery_capacity_mah,
        )

    def tilt_limit_deg(self, s: AutopilotState) -> float:
        """The attitude alarm: the autopilot's limit plus the margin, else the database's."""
        if s.max_bank_deg is not None:
            return s.max_bank_deg + self.tilt_margin_deg
        return self.max_tilt_deg


@dataclass(frozen=True)
class ConditionSpec:
    code: AlertCode
    flag: AlertFlag
    armed_severity: Severity  # while armed
    ground_severity: Severity  # while disarmed
    immediate: bool = False


SPECS: dict[AlertCode, ConditionSpec] = {
    s.code: s
    for s in (
        ConditionSpec(
            AlertCode.BATTERY_LOW, AlertFlag.BATTERY_LOW, Severity.WARNING, Severity.WARNING
        ),
        ConditionSpec(
            AlertCode.BATTERY_CRITICAL,
            AlertFlag.BATTERY_CRITICAL,
            Severity.CRITICAL,
            Severity.WARNING,
        ),
        ConditionSpec(AlertCode.GPS_LOSS, AlertFlag.GPS_LOSS, Severity.CRITICAL, Severity.WARNING),
        ConditionSpec(
            AlertCode.EKF_FAILURE, AlertFlag.EKF_FAILURE, Severity.CRITICAL, Severity.WARNING
        ),
        ConditionSpec(
            AlertCode.AUTOPILOT_LINK_LOSS,
            AlertFlag.AUTOPILOT_LINK_LOSS,
            Severity.EMERGENCY,
            Severity.CRITICAL,
            immediate=True,
        ),
        # the autopilot is not the vehicle the swarm database says (a quadcopter's node
        # on a QuadPlane): not ready, so every mission is refused with the reason
        ConditionSpec(
            AlertCode.AUTOPILOT_MISMATCH,
            AlertFlag.AUTOPILOT_MISMATCH,
            Severity.WARNING,
            Severity.WARNING,
            immediate=True,
        ),
        ConditionSpec(
            AlertCode.GEOFENCE_BREACH,
            AlertFlag.GEOFENCE_BREACH,
            Severity.CRITICAL,
            Severity.WARNING,
        ),
        ConditionSpec(
            AlertCode.ATTITUDE_ABNORMAL,
            AlertFlag.ATTITUDE_ABNORMAL,
            Severity.CRITICAL,
            Severity.INFO,
        ),
    )
}


@dataclass
class _Tracked:
    since: float | None = None  # condition observed continuously since
    clear_since: float | None = None  # absent continuously since
    active: bool = False
    severity: Severity = Severity.INFO


@dataclass
class VehicleMonitor:
    vehicle_id: int
    thresholds: Thresholds = field(default_factory=Thresholds)
    # and operating areas: the node's one zone book, read (the declared book keeps it)
    zones: Mapping[int, NoFlyZone] = field(default_factory=ZoneBook)
    _tracked: dict[AlertCode, _Tracked] = field(default_factory=dict)
    _had_gps: bool = False
    _had_ekf: bool = False
    _had_link: bool = False
    _started: float | None = None
    _breach_text: str | None = None
    _never_up: bool = False  # the link loss seen is "never came up" (a WARNING only)
    stalled_s: float = 0.0  # the node's own stalls, seconds (not counted as link loss)
    ready: bool = False
    vehicle_type: VehicleType | None = None  # the node's identity (None: not checked)
    mav_sysid: int = 0  # the autopilot's MAVLink system id, from the database (0: not checked)
    _mismatch_text: str | None = None
    state: AutopilotState = field(default_factory=AutopilotState)  # the latest reported
    _identity: str = ""  # another source speaks in this vehicle's name ("": none)
    _figures_told: tuple[float | None, float | None] | None = None  # DATABASE_MISMATCH said
    _skew_told = False

    def note_stall(self, seconds: float) -> None:
        """The node was not served for `seconds` (its own stall, a loaded host): a link
        loss being timed does not count that time toward its escalation."""
        if not seconds > 0.0:
            return
        self.stalled_s += seconds
        tr = self._tracked.get(AlertCode.AUTOPILOT_LINK_LOSS)
        if tr is not None and tr.since is not None:
            tr.since += seconds

    # ------------------------------------------------------------------ conditions
    def _observe(self, s: AutopilotState, now: float) -> set[AlertCode]:
        t = self.thresholds
        seen: set[AlertCode] = set()
        if self._started is None:
            self._started = now
        self._had_link |= s.link_ok
        self._never_up = not self._had_link
        if not s.link_ok:
            # lost after it was up; or never up within the grace period after start
            if self._had_link or now - self._started >= t.link_grace_s:
                seen.add(AlertCode.AUTOPILOT_LINK_LOSS)
            return seen  # everything else is stale while the link is down
        self._mismatch_text = (
            autopilot_mismatch(self.vehicle_type, s.mav_type) if self.vehicle_type else None
        ) or self._sysid_mismatch(s)
        if self._mismatch_text:
            seen.add(AlertCode.AUTOPILOT_MISMATCH)
        if 0 <= s.battery_pct <= t.battery_critical_pct:
            seen.add(AlertCode.BATTERY_CRITICAL)
        elif 0 <= s.battery_pct <= t.battery_low_pct:
            seen.add(AlertCode.BATTERY_LOW)
        gps_good = s.gps_fix >= GpsFix.FIX_3D and s.gps_sats >= t.min_sats
        self._had_gps |= gps_good
        if self._had_gps and not gps_good:
            seen.add(AlertCode.GPS_LOSS)
        self._had_ekf |= s.ekf_ok
        if self._had_ekf and not s.ekf_ok:
            seen.add(AlertCode.EKF_FAILURE)
        tilt = t.tilt_limit_deg(s)
        if s.armed and (abs(s.roll_deg) > tilt or abs(s.pitch_deg) > tilt):
            seen.add(AlertCode.ATTITUDE_ABNORMAL)
        self._breach_text = (
            self._breach(s, now)
            if self.zones and s.lat_deg is not None and s.lon_deg is not None
            else None
        )
        if self._breach_text:
            seen.add(AlertCode.GEOFENCE_BREACH)
        return seen

    def _sysid_mismatch(self, s: AutopilotState) -> str | None:
        if self.mav_sysid and s.sysid and s.sysid != self.mav_sysid:
            return f"autopilot is MAVLink system {s.sysid}, the database says {self.mav_sysid}"
        return None

    def on_identity(self, conflict: str, now: float) -> list[Alert]:
        """Another source speaks in this vehicle's name (`conflict` names it; "": no
        longer): raised CRITICAL at once (again when another source is named), cleared
        at once; not ready meanwhile."""
        was, self._identity = self._identity, conflict
        if conflict == was:
            return []
        if conflict:
            self.ready = False
            return [self._alert(now, Severity.CRITICAL, AlertCode.IDENTITY_CONFLICT, conflict)]
        return [
            self._alert(
                now, Severity.INFO, AlertCode.CONDITION_CLEARED, "IDENTITY_CONFLICT cleared"
            )
        ]

    def _breach(self, s: AutopilotState, now: float) -> str | None:
        """What is breached ("left operating area 2", "in no-fly zone 3"), or None
        (the zone book's geometry, safety/zones.py)."""
        assert s.lat_deg is not None and s.lon_deg is not None
        alt = s.alt_msl_m if s.alt_msl_m is not None else 0.0
        return breach(self.zones.values(), s.lat_deg, s.lon_deg, alt, now)

    def update(self, s: AutopilotState, now: float) -> list[Alert]:
        """The vehicle's latest state: alerts raised (with their severity) or cleared
        (CONDITION_CLEARED) now."""
        self.state = s
        seen = self._observe(s, now)
        out: list[Alert] = self._figures(s, now) + self._clock(s, now)
        tracked = self._tracked
        if (
            seen
            or len(tracked) < len(SPECS)
            or any(tr.active or tr.since is not None for tr in tracked.values())
        ):
            out += self._escalate(s, seen, now)
        self.ready = (
            s.link_ok
            and s.gps_fix >= GpsFix.FIX_3D
            and s.ekf_ok
            and s.home is not None
            and AlertCode.AUTOPILOT_MISMATCH not in seen
            and not self._identity
            and all(tr.severity < Severity.CRITICAL for tr in tracked.values() if tr.active)
        )
        return out

    def _figures(self, s: AutopilotState, now: float) -> list[Alert]:
        """Once per new reading of the autopilot's figures: where the swarm database
        disagrees with them (a WARNING; the autopilot's figures are used)."""
        figures = (s.battery_capacity_mah, s.max_bank_deg)
        if figures == (None, None) or figures == self._figures_told:
            return []
        self._figures_told = figures
        t, said = self.thresholds, []
        ap_mah, db_mah = s.battery_capacity_mah, t.database_capacity_mah
        if ap_mah is not None and abs(ap_mah - db_mah) > t.capacity_tolerance * ap_mah:
            db = f"{db_mah:.0f} mAh" if db_mah > 0 else "none"
            said.append(f"BATT_CAPACITY {ap_mah:.0f} mAh, database {db}: planned with it")
        if s.max_bank_deg is not None and t.max_tilt_deg < s.max_bank_deg:
            said.append(
                f"attitude limit {s.max_bank_deg:.0f} deg, database alarm "
                f"{t.max_tilt_deg:.0f}: alarm at {t.tilt_limit_deg(s):.0f}"
            )
        return [self._alert(now, Severity.WARNING, AlertCode.DATABASE_MISMATCH, x) for x in said]

    def _clock(self, s: AutopilotState, now: float) -> list[Alert]:
        """Once: the autopilot's GPS time (of its latest position, just received) far
        from the node's clock."""
        sample, heard = s.position_time_unix_s, s.last_message_s
        if self._skew_told or sample is None or heard is None or not s.link_ok:
            return []
        if now - heard > 0.5:
            return []  # nothing fresh: the sample's age is not the clocks' skew
        skew = now - sample
        if abs(skew) <= self.thresholds.clock_skew_s:
            return []
        self._skew_told = True
        ahead = "behind" if skew > 0 else "ahead of"
        text = f"autopilot GPS time {abs(skew):.1f} s {ahead} this node's clock"
        return [self._alert(now, Severity.WARNING, AlertCode.CLOCK_SKEW, text)]

    def _escalate(self, s: AutopilotState, seen: set[AlertCode], now: float) -> list[Alert]:
        """Each alert's escalation and clearing (nothing to do when nothing is seen and
        nothing is raised or being timed: the usual tick)."""
        out: list[Alert] = []
        t = self.thresholds
        for code, spec in SPECS.items():
            tr = self._tracked.setdefault(code, _Tracked())
            severity = spec.armed_severity if s.armed else spec.ground_severity
            if (
                code == AlertCode.AUTOPILOT_LINK_LOSS
                and code in seen
                and (
                    self._never_up or tr.since is None or now - tr.since < t.link_emergency_after_s
                )
            ):
                severity = Severity.WARNING  # a short gap (or none yet): the mission goes on
            if code in seen:
                tr.clear_since = None
                if tr.since is None:
                    tr.since = now
                due = spec.immediate or now - tr.since >= t.raise_after_s
                if due and (not tr.active or severity > tr.severity):
                    tr.active, tr.severity = True, severity
                    text = _describe(code, s)
                    if code == AlertCode.AUTOPILOT_MISMATCH and self._mismatch_text:
                        text = self._mismatch_text
                    if code == AlertCode.GEOFENCE_BREACH and self._breach_text:
                        text = f"{self._breach_text} at {s.lat_deg:.6f},{s.lon_deg:.6f} {s.alt_msl_m or 0:.0f} m"
                    out.append(self._alert(now, severity, code, text))
            else:
                tr.since = None
                if tr.active:
                    if tr.clear_since is None:
                        tr.clear_since = now
                    if spec.immediate or now - tr.clear_since >= t.clear_after_s:
                        tr.active, tr.clear_since = False, None
                        out.append(
                            self._alert(
                                now,
                                Severity.INFO,
                                AlertCode.CONDITION_CLEARED,
                                f"{code.name} cleared",
                            )
                        )
        return out

    def not_ready_text(self, s: AutopilotState) -> str:
        """Why the vehicle is not ready (the first reason, for people: the text of a
        NOT_READY answer), or "" when it is."""
        if self._identity:
            return f"identity conflict: {self._identity}"
        if not s.link_ok:
            return "autopilot link down"
        if self._mismatch_text:
            return self._mismatch_text
        if s.gps_fix < GpsFix.FIX_3D:
            return f"no 3-D GPS fix ({s.gps_fix.name}, {s.gps_sats} sats)"
        if not s.ekf_ok:
            return "EKF estimate not good yet"
        if s.home is None:
            return "autopilot has no home yet"
        critical = [
            c.name
            for c, tr in self._tracked.items()
            if tr.active and tr.severity >= Severity.CRITICAL
        ]
        return f"critical: {', '.join(critical)}" if critical else ""

    def _alert(self, now: float, severity: Severity, code: AlertCode, text: str) -> Alert:
        return Alert(self.vehicle_id, max(0.0, now), severity, code, short_text(text))

    # ------------------------------------------------------------------ views
    @property
    def flags(self) -> AlertFlag:
        f = AlertFlag.NONE
        for code, tr in self._tracked.items():
            if tr.active:
                f |= SPECS[code].flag
        if self._identity:
            f |= AlertFlag.IDENTITY_CONFLICT
        return f

    @property
    def active_codes(self) -> tuple[AlertCode, ...]:
        codes = {c for c, tr in self._tracked.items() if tr.active}
        if self._identity:
            codes.add(AlertCode.IDENTITY_CONFLICT)
        return tuple(sorted(codes))

    @property
    def emergency(self) -> Emergency | None:
        worst: Emergency | None = None
        for code, tr in self._tracked.items():
            if (
                tr.active
                and tr.severity >= Severity.CRITICAL
                and (worst is None or tr.severity > worst.severity)
            ):
                worst = Emergency(code, tr.severity)
        return worst


def _describe(code: AlertCode, s: AutopilotState) -> str:
    if code in (AlertCode.BATTERY_LOW, AlertCode.BATTERY_CRITICAL):
        return f"battery {s.battery_pct}% {s.battery_v:.1f} V"
    if code == AlertCode.GPS_LOSS:
        return f"GPS fix {s.gps_fix.name} sats {s.gps_sats}"
    if code == AlertCode.ATTITUDE_ABNORMAL:
        return f"roll {s.roll_deg:.0f} pitch {s.pitch_deg:.0f} deg"
    if code == AlertCode.AUTOPILOT_LINK_LOSS:
        if s.last_message_s:
            return "no HEARTBEAT from the autopilot"
        return f"no autopilot yet: {s.link_problem}" if s.link_problem else "no autopilot yet"
    if code == AlertCode.EKF_FAILURE:
        return "EKF position/velocity estimate bad"
    if code == AlertCode.GEOFENCE_BREACH:
        return "outside the operating area or inside a no-fly zone"
    return code.name
