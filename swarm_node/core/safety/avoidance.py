"""Collision avoidance (paper 2.3.6): a pure core, fed with the own vehicle's state, the
peers' telemetry and non-cooperative traffic, ticking at 5 Hz.

    inputs (handle)                          what it does with them
    VehicleStatus, vehicle_id == own_id      the own state (position, NED velocity, armed)
    VehicleStatus, another vehicle           a cooperative contact (it runs this same rule)
    VehicleInfo                              a contact's VehicleType (default: aircraft)
    Traffic                                  non-cooperative traffic (ADS-B): never manoeuvres
    PlannedAltitude                          the altitude to come back to (None: where the
                                             manoeuvre started)
    Ceiling                                  the zones' ceiling above home (None: config's)
    OwnUnknown                               no own position (a rebooted autopilot): no
                                             manoeuvre until the next own status
    Forget                                   a contact gone for good (it left the
                                             swarm): dropped now
    Silent                                   a member fallen silent: kept as a contact at
                                             its predicted position (silent.py) until heard
                                             again, seen landed or forgotten
    SilentRoute                              the rest of a silent member's share (the
                                             mission coordinator's): its prediction follows it
    OwnRoute                                 a multirotor's mission items ahead (AUTO): its
                                             own motion is predicted along them
    VehicleIntent                            a contact's next legs: it is predicted along
                                             them as well as straight on (until stale)

    outputs (on_timer)                       meaning for the node
    Manoeuvre(CLIMB | LEVEL | STOP)          submit `requests` as owner AVOIDANCE, suspend the
                                             mission
    Manoeuvre(RESUME)                        submit `requests`, give control back, resume
    Alert                                    publish (COLLISION_RISK / CONDITION_CLEARED)

Every tick, every known vehicle (own included) is extrapolated to `now` and the closest
point of approach of every pair is computed (`ttc.pairwise`); a pair is in conflict when
its predicted 3-D miss distance, less the staleness widening, is below `protect_m`
within `horizon_s`. Manoeuvres are upward only:

- Who climbs (the same rule in every vehicle, on the same reported numbers): of two
  cooperative aircraft, the higher one; within `tie_band_m` of each other, a fixed-wing
  (plane, VTOL) before a multirotor (it climbs faster, keeps its path and cannot stop),
  when both types are known from VehicleInfo (sent at 1 Hz from start-up, long before
  either flies), else the higher id. Against traffic that will not manoeuvre (ADS-B, a MANNED vehicle, anything
  below `min_active_alt_rel_m`, rovers and boats), an aircraft climbs if
  that traffic is not well above it. So the lower of a pair never climbs into the
  upper one. A disarmed aircraft on the ground (under 2 m) is not traffic for an
  aircraft (take-off and landing beside it are sequenced: pads.py).
- How high (three or more): targets stack in rank order, each `vertical_sep_m` above
  the target of every vehicle it gives way to (a fixed point over the conflict graph),
  capped by the ceiling. A climb target only rises until the conflict clears.
- The vehicle that keeps its altitude but is climbing into a conflict above it levels
  off (LEVEL); a fixed-wing keeps its path (DO_CHANGE_ALTITUDE), a multirotor holds
  position while it climbs (a GUIDED reposition over itself; the node's module flies
  either to the mission item it was flying to, higher, while in a mission); rovers and boats STOP
  (HOLD mode) when they give way (ground pairs: the higher id) or when something
  stands in their way.
- When: a fixed-wing at once; a multirotor in level flight when the loss of separation
  (`ttc.entry_time`) is within the time it needs (its climb, or its stop, whichever is
  longer, plus `act_margin_s`): it can stop and climb in seconds, and a survey lane's
  end turns it long before a 30 s straight line would meet anyone. Climbing or
  descending it acts at once. In its mission its own motion is predicted along its
  route (`OwnRoute`), the contacts' straight on and, for those that publish their
  next legs (`VehicleIntent`), along them too.
- Hysteresis: the manoeuvre ends only when, from the planned altitude (ground
  vehicles: with the velocity they had), every predicted miss is above `release_m`
  (> `protect_m`) for `clear_hold_s`; then RESUME, back to the planned altitude. A
  contact above that is not descending does not hold up a way back down that is no
  conflict with it and no closer to it than staying (two stacked vehicles would wait
  for each other for good). Nor does a still pair (both hovering) that is no conflict
  from the planned altitude: waiting cannot change it.

The core never reads a clock: `now` is the caller's. A report's age is measured on
that clock, never by comparing the sender's time with ours (VehicleStatus times are the
sender's autopilot's GPS time, which may run seconds off the receiver's clock: SITL's
ran 10 s behind its host's, and every report read as 10 s stale grew the margins to
hundreds of metres): when it was received, less how much later than usual it came
(its `time_unix_s` to reception, over the least seen from that sender in the last
`LATENCY_WINDOW_S`). A constant skew between the clocks cancels out; a report held up
on the way, or a sender repeating an old position (its autopilot link down), shows
its age. The own status is aged the same way.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from enum import StrEnum
from typing import Any

import numpy as np

from swarm_proto import (
    Alert,
    AlertCode,
    DetailCode,
    ReasonDetail,
    Severity,
    VehicleInfo,
    VehicleIntent,
    VehicleStatus,
    VehicleType,
)
from swarm_proto.messages import MAX_INTENT_LEGS
from swarm_proto.text import short_text

from ..autopilot.requests import ApRequest, ChangeAltitude, Goto, SetMode
from ..autopilot.state import AdsbReport
from ..autopilot.tracker import parse_adsb
from .silent import SilentAircraft
from .ttc import (
    BadTrackError,
    Frame,
    Kinematic,
    Legs,
    Track,
    along_intent,
    along_route,
    entry_time,
    kinematic,
    legs_approach,
    pairwise,
    route_approach,
    straight,
)

GROUND = frozenset({VehicleType.ROVER, VehicleType.BOAT})
MULTIROTOR = frozenset({VehicleType.COPTER})
NEVER_MANOEUVRES = frozenset({VehicleType.MANNED})
NOT_TRAFFIC = frozenset({VehicleType.GCS})
FIXED_WING = frozenset({VehicleType.PLANE, VehicleType.VTOL})

# how fast each kind could be going: the staleness widening is age * this
MAX_SPEED_M_S: dict[VehicleType, float] = {
    VehicleType.OTHER: 35.0,
    VehicleType.PLANE: 35.0,
    VehicleType.VTOL: 35.0,
    VehicleType.COPTER: 20.0,
    VehicleType.ROVER: 10.0,
    VehicleType.BOAT: 10.0,
    VehicleType.MANNED: 60.0,
}
TRAFFIC_MAX_SPEED_M_S = 60.0
# how long a sender's least latency (its time to our reception) is remembered: a clock
# that steps is followed within this
LATENCY_WINDOW_S = 30.0
PARKED_ALT_M = 2.0  # a disarmed aircraft lower than this above its home is on the ground


class ManoeuvreKind(StrEnum):
    CLIMB = "climb"  # give way upwards to target_alt_rel_m
    LEVEL = "level"  # stop climbing: hold target_alt_rel_m (the current altitude)
    STOP = "stop"  # rover / boat: stop (HOLD mode)
    RESUME = "resume"  # clear: back to the planned altitude, the mission resumes


@dataclass(frozen=True, slots=True)
class Manoeuvre:
    kind: ManoeuvreKind
    requests: tuple[ApRequest, ...]  # to submit as owner AVOIDANCE, in order
    target_alt_rel_m: float | None = None
    against: tuple[int, ...] = ()  # the contacts it is for (traffic: -1 - ICAO address)
    reason: str = ""


@dataclass(frozen=True, slots=True)
class Traffic:
    """A non-cooperative aircraft (ADS-B): it will not manoeuvre for us."""

    icao_address: int
    lat_deg: float
    lon_deg: float
    alt_msl_m: float
    vel_north_m_s: float = 0.0
    vel_east_m_s: float = 0.0
    vel_down_m_s: float = 0.0
    time_s: float = 0.0

    @property
    def contact_id(self) -> int:
        return -1 - self.icao_address

    @classmethod
    def from_adsb(cls, report: Mapping[str, Any], *, received_s: float) -> Traffic:
        """From a decoded ADSB_VEHICLE (pymavlink `to_dict()`; the autopilot link's
        parser, `parse_adsb`). Raises ValueError naming what is wrong."""
        return cls.from_report(parse_adsb(report, received_s=received_s))

    @classmethod
    def from_report(cls, r: AdsbReport) -> Traffic:
        """From the autopilot link's `AutopilotState.traffic`."""
        return cls(
            r.icao_address,
            r.lat_deg,
            r.lon_deg,
            r.alt_msl_m,
            r.vel_north_m_s,
            r.vel_east_m_s,
            r.vel_down_m_s,
            r.time_s,
        )


@dataclass(frozen=True, slots=True)
class PlannedAltitude:
    alt_rel_m: float | None  # above home; None: resume where the manoeuvre started


@dataclass(frozen=True, slots=True)
class Ceiling:
    alt_rel_m: float | None  # the lowest zone ceiling over us, above home; None: none


@dataclass(frozen=True, slots=True)
class Forget:
    """A peer gone from the swarm: no contact any more."""

    vehicle_id: int


@dataclass(frozen=True, slots=True)
class OwnUnknown:
    """The own position is unknown (its autopilot rebooted, no fix yet): the last own
    status is no ground to manoeuvre on; nothing is flown until the next one."""


@dataclass(frozen=True, slots=True)
class OwnRoute:
    """Where the own multirotor flies next in its mission (AUTO): the items ahead in
    order, (lat, lon, altitude above home), the last one held; `speed_m_s` the speed it
    flies them at (at least its ground speed is used). None: not flying a mission."""

    points: tuple[tuple[float, float, float], ...] | None
    speed_m_s: float = 0.0


@dataclass(frozen=True, slots=True)
class Silent:
    """A member lost by silence (its node's liveliness or telemetry gone): its aircraft
    flies on without its node."""

    vehicle_id: int


@dataclass(frozen=True, slots=True)
class SilentRoute:
    """What is left of a silent member's share: (lat, lon, height above its home) in
    order, flown at `speed_m_s` (0: its cruise speed)."""

    vehicle_id: int
    points: tuple[tuple[float, float, float], ...]
    speed_m_s: float = 0.0


Event = (
    VehicleStatus
    | VehicleInfo
    | VehicleIntent
    | Traffic
    | PlannedAltitude
    | Ceiling
    | Forget
    | OwnUnknown
    | OwnRoute
    | Silent
    | SilentRoute
)
Output = Manoeuvre | Alert


@dataclass(frozen=True, slots=True)
class AvoidanceConfig:
    own_id: int
    own_type: VehicleType
    protect_m: float = 20.0  # predicted miss (3-D) below which a pair is in conflict
    release_m: float = 30.0  # clear only when every miss from the planned altitude is above
    vertical_sep_m: float = 15.0  # a climb targets this much above who it gives way to
    tie_band_m: float = 5.0  # within this altitude difference: fixed-wing, then higher id climbs
    others_slack_m: float = 10.0  # the others' pairs count as in conflict with this much more
    horizon_s: float = 30.0  # how far ahead conflicts are looked for
    climb_rate_m_s: float = 5.0  # to tell whether a climb can be done in time
    ceiling_rel_m: float = 400.0  # never climb above this (above home)
    clear_hold_s: float = 3.0  # clear this long before resuming
    period_s: float = 0.2  # 5 Hz
    forget_after_s: float = 10.0  # a contact silent this long is dropped
    min_active_alt_rel_m: float = 10.0  # aircraft below this do not manoeuvre (take-off/land)
    level_climb_m_s: float = 0.5  # a stand-on vehicle climbing faster than this levels off
    still_m_s: float = 1.0  # hovering: a still pair's release needs only protect_m
    retarget_m: float = 1.0  # a new climb request only for a target this much higher
    own_max_speed_m_s: float = 0.0  # the own state is fresh; widen it by age * this
    # a multirotor starts a manoeuvre only when the loss of separation is within the time
    # it needs (to climb to its target, or to stop: whichever is longer) plus this margin
    act_margin_s: float = 5.0
    stop_accel_m_s2: float = 2.5  # how hard a multirotor brakes (ArduCopter WPNAV_ACCEL)
    # a contact that publishes its next legs (VehicleIntent) is predicted along them too
    # while its latest intent is younger than this (sent every 2 s); else straight on only
    intent: bool = True
    intent_stale_s: float = 5.0

    def __post_init__(self) -> None:
        if not (0 < self.protect_m < self.release_m):
            raise ValueError("need 0 < protect_m < release_m")
        if self.vertical_sep_m <= 0 or self.period_s <= 0 or self.horizon_s <= 0:
            raise ValueError("vertical_sep_m, period_s and horizon_s must be positive")
        if self.climb_rate_m_s <= 0 or self.tie_band_m < 0 or self.clear_hold_s < 0:
            raise ValueError("climb_rate_m_s must be positive, tie_band_m and clear_hold_s >= 0")
        if self.act_margin_s < 0 or self.stop_accel_m_s2 <= 0:
            raise ValueError("act_margin_s must be >= 0 and stop_accel_m_s2 positive")


@dataclass(slots=True)
class _Contact:
    track: Track
    received_s: float
    cooperative: bool
    vehicle_type: VehicleType | None = None
    armed: bool = True
    alt_rel_m: float = math.inf


@dataclass(slots=True)
class _Active:
    kind: ManoeuvreKind
    planned_rel_m: float
    target_rel_m: float | None
    resume_vel: tuple[float, float, float]
    against: tuple[int, ...]
    clear_since: float | None = None


@dataclass(slots=True)
class _Decision:
    kind: ManoeuvreKind | None
    target_msl_m: float | None
    against: tuple[int, ...]
    soonest_s: float = math.inf
    closest_m: float = math.inf
    loss_s: float = math.inf  # when the separation is first lost (inside protect_m)


@dataclass
class CollisionAvoider:
    config: AvoidanceConfig
    _own: VehicleStatus | None = None
    _own_received: float = 0.0
    _contacts: dict[int, _Contact] = field(default_factory=dict)
    # peers' latest statuses since the last tick, made contacts at the tick: a peer
    # reports at 5 Hz and the decision runs at 5 Hz, so a status is one dict store
    # (many peers report more often than the tick runs, and most never conflict)
    _heard: dict[int, tuple[VehicleStatus, float]] = field(default_factory=dict)
    _types: dict[int, VehicleType] = field(default_factory=dict)
    _infos: dict[int, VehicleInfo] = field(default_factory=dict)  # a peer's home, base, speed
    # members fallen silent, predicted (silent.py): made contacts at every tick
    _silent: dict[int, SilentAircraft] = field(default_factory=dict)
    _planned_rel: float | None = None
    _zone_ceiling_rel: float | None = None
    _route: OwnRoute | None = None
    _active: _Active | None = None
    _next: float | None = None
    counters: dict[str, int] = field(default_factory=dict)
    # per sender: (received, latency) with latencies increasing, the window's least first
    _latency: dict[int, deque[tuple[float, float]]] = field(default_factory=dict)
    _own_t: float = 0.0  # when the own status's position was true (our clock)
    # peers' latest intents with legs, and when each was received (our clock)
    _intents: dict[int, tuple[VehicleIntent, float]] = field(default_factory=dict)

    # ------------------------------------------------------------------ inputs
    def handle(self, ev: Event, now: float) -> list[Output]:
        if self._next is None:
            self._next = now
        match ev:
            case VehicleStatus():
                self.heard(ev, now)
            case VehicleIntent():
                self._intent(ev, now)
            case VehicleInfo():
                if ev.vehicle_id != self.config.own_id:
                    self._info(ev)
            case Traffic():
                self._traffic(ev, now)
            case PlannedAltitude():
                self._planned_rel = ev.alt_rel_m
            case Ceiling():
                self._zone_ceiling_rel = ev.alt_rel_m
            case OwnUnknown():
                self._own = None
            case Forget():
                self._contacts.pop(ev.vehicle_id, None)
                self._heard.pop(ev.vehicle_id, None)
                self._silent.pop(ev.vehicle_id, None)
                self._intents.pop(ev.vehicle_id, None)
            case Silent():
                self._fell_silent(ev.vehicle_id)
            case SilentRoute():
                self._silent_route(ev)
            case OwnRoute():
                self._route = ev if ev.points else None
        return []

    def heard(self, s: VehicleStatus, now: float) -> None:
        """A peer's status: what `handle` does with it, without the dispatch (the hot
        path, 5 Hz per peer): kept, the latest per peer, until the next tick."""
        if self._next is None:
            self._next = now
        if s.vehicle_id == self.config.own_id:
            self._own, self._own_received = s, now
        else:
            self._heard[s.vehicle_id] = (s, now)

    def heard_all(
        self, msgs: Sequence[VehicleStatus | VehicleInfo], now: float, statuses_only: bool = False
    ) -> None:
        """`heard` for each status of `msgs`, `handle` for each info, in turn, at once (a
        run a node hears together; `statuses_only`: the caller knows it has no info)."""
        if not msgs:
            return
        if self._next is None:
            self._next = now
        own, heard = self.config.own_id, self._heard
        if statuses_only:  # (the usual run) the latest of each peer
            latest = {s.vehicle_id: (s, now) for s in msgs}
            mine = latest.pop(own, None)
            if mine is not None:
                self._own, self._own_received = mine  # type: ignore[assignment]
            heard.update(latest)  # type: ignore[arg-type]
            return
        for m in msgs:
            vid = m.vehicle_id
            if isinstance(m, VehicleStatus):
                if vid == own:
                    self._own, self._own_received = m, now
                else:
                    heard[vid] = (m, now)
            elif vid != own:  # a VehicleInfo, as `handle` takes it
                self._info(m)

    def _info(self, m: VehicleInfo) -> None:
        vid = m.vehicle_id
        self._types[vid] = m.vehicle_type
        self._infos[vid] = m
        if m.vehicle_type in NOT_TRAFFIC:
            self._contacts.pop(vid, None)
            self._heard.pop(vid, None)
            self._silent.pop(vid, None)

    # ------------------------------------------------------------------ silent members
    def _fell_silent(self, vid: int) -> None:
        """Its last report becomes a prediction (silent.py); nothing heard of it yet
        (or parked, not an aircraft in the air): nothing to predict."""
        late = self._heard.pop(vid, None)
        if late is not None:
            self._peer(*late)
        c = self._contacts.get(vid)
        if c is None or not c.cooperative or vid in self._silent or c.alt_rel_m < PARKED_ALT_M:
            return  # never heard flying; on the ground its failsafe disarms it
        info = self._infos.get(vid)
        vtype = self._types.get(vid)
        home_msl = c.track.alt_msl_m - c.alt_rel_m if math.isfinite(c.alt_rel_m) else 0.0
        self._silent[vid] = SilentAircraft.of(c.track, vtype, info, home_msl)
        self._count("silent")

    def _silent_route(self, ev: SilentRoute) -> None:
        a = self._silent.get(ev.vehicle_id)
        if a is None or not ev.points:
            return
        speed = ev.speed_m_s if ev.speed_m_s > 0 else a.speed_m_s
        try:
            ok = all(math.isfinite(x) for p in ev.points for x in p)
        except TypeError:
            ok = False
        if not ok or not (speed >= 0 and math.isfinite(speed)):
            self._count("bad_track")
            return
        self._silent[ev.vehicle_id] = a.with_route(ev.points, speed)

    @property
    def silent(self) -> tuple[int, ...]:
        """The silent members kept as contacts at their predicted positions."""
        return tuple(sorted(self._silent))

    def predicted(self, vehicle_id: int, now: float) -> Track | None:
        """A silent member's predicted track at `now` (None: not silent)."""
        a = self._silent.get(vehicle_id)
        return a.predict(now).track if a is not None else None

    def _predict_silent(self, now: float) -> None:
        """Every silent member a contact at its predicted position, that never
        manoeuvres; a multirotor predicted landed on its rally point is parked."""
        for vid, a in list(self._silent.items()):
            p = a.predict(now)
            if p.phase == "landed" and self.config.own_type not in GROUND:
                self._contacts.pop(vid, None)
                continue
            alt_rel = p.track.alt_msl_m - a.home_msl_m
            self._contacts[vid] = _Contact(p.track, now, False, a.vehicle_type, True, alt_rel)

    def _intent(self, it: VehicleIntent, now: float) -> None:
        """A peer's published next legs: kept (the latest) for its prediction; one that
        cannot be used (too many legs, a non-finite value, a vehicle never heard) is
        counted and ignored; one without legs drops the peer's intent (straight on)."""
        vid = it.vehicle_id
        if vid == self.config.own_id or not self.config.intent:
            return
        if vid not in self._contacts and vid not in self._heard and vid not in self._types:
            self._count("intent_unknown")
            return
        if self._types.get(vid) in NOT_TRAFFIC:
            return
        if len(it.legs) > MAX_INTENT_LEGS:
            self._count("intent_bad")
            return
        values = [it.speed_m_s, it.turn_radius_m]
        values += [v for p in it.legs for v in (p.lat_deg, p.lon_deg, p.alt_msl_m)]
        if not (
            math.isfinite(sum(values))
            and 0.0 <= it.speed_m_s <= 300.0
            and 0.0 <= it.turn_radius_m <= 8000.0
            and all(abs(p.lat_deg) <= 90.0 and abs(p.lon_deg) <= 180.0 for p in it.legs)
        ):
            self._count("intent_bad")
            return
        if not it.legs:
            self._intents.pop(vid, None)
            return
        self._intents[vid] = (it, now)

    def _count(self, what: str) -> None:
        self.counters[what] = self.counters.get(what, 0) + 1

    def _absorb(self) -> None:
        """The statuses heard since the last tick become contacts (or drop them)."""
        heard, self._heard = self._heard, {}
        for s, received in heard.values():
            if self._silent and s.vehicle_id in self._silent:
                del self._silent[s.vehicle_id]  # heard again (or seen landed: parked)
                self._count("silent_heard")
            self._peer(s, received)

    def _peer(self, s: VehicleStatus, now: float) -> None:
        vtype = self._types.get(s.vehicle_id)
        if vtype in NOT_TRAFFIC:
            return
        if (
            not s.armed
            and s.alt_rel_m < PARKED_ALT_M
            and self.config.own_type not in GROUND
            and vtype not in GROUND
        ):
            # parked on its pad, motors off: not traffic for an aircraft flying above
            # `min_active_alt_rel_m` (take-off and landing next to it: pads.py)
            self._contacts.pop(s.vehicle_id, None)
            return
        t = self._sample_time(s.vehicle_id, s.time_unix_s, now)
        speed = MAX_SPEED_M_S.get(vtype or VehicleType.OTHER, 35.0)
        try:
            track = Track.from_status(s, time_s=t, max_speed_m_s=speed)
        except BadTrackError:
            self._count("bad_track")
            return
        self._contacts[s.vehicle_id] = _Contact(
            track, now, True, vtype, armed=s.armed, alt_rel_m=s.alt_rel_m
        )

    def _sample_time(self, sender: int, sent_s: float, received: float) -> float:
        """When a report's position was true, on our clock: `received` less how much
        later than the least seen from `sender` lately it came (a sliding-window
        minimum of `received - sent_s`); `received` for a report without a time."""
        if not (sent_s > 0.0 and math.isfinite(sent_s)):
            return received
        latency = received - sent_s
        window = self._latency.get(sender)
        if window is None:
            window = self._latency[sender] = deque()
        while window and window[-1][1] >= latency:
            window.pop()
        window.append((received, latency))
        while received - window[0][0] > LATENCY_WINDOW_S:
            window.popleft()
        return received - (latency - window[0][1])

    def _traffic(self, tr: Traffic, now: float) -> None:
        t = tr.time_s if tr.time_s <= now else now
        try:
            track = Track(
                tr.contact_id,
                tr.lat_deg,
                tr.lon_deg,
                tr.alt_msl_m,
                tr.vel_north_m_s,
                tr.vel_east_m_s,
                tr.vel_down_m_s,
                t,
                TRAFFIC_MAX_SPEED_M_S,
            )
        except BadTrackError:
            self._count("bad_track")
            return
        self._contacts[tr.contact_id] = _Contact(track, now, False)

    # ------------------------------------------------------------------ timer
    def next_deadline(self) -> float | None:
        return self._next

    def on_timer(self, now: float) -> list[Output]:
        if self._next is None or now < self._next:
            return []
        nxt = self._next + self.config.period_s
        self._next = nxt if nxt > now else now + self.config.period_s  # late: no catch-up burst
        self._count("ticks")
        own = self._own
        if own is None or not self._can_act(own):
            if self._active is not None:  # landed, disarmed: nothing to come back to
                self._active = None
                return [self._alert(own, now, Severity.INFO, "avoidance: off (not flying)", True)]
            return []  # the statuses heard wait (the latest per peer) until it flies
        self._absorb()
        self._own_t = self._sample_time(own.vehicle_id, own.time_unix_s, self._own_received)
        stale = [
            k for k, c in self._contacts.items() if now - c.received_s > self.config.forget_after_s
        ]
        for k in stale:
            del self._contacts[k]
        if self._silent:
            self._predict_silent(now)
        decision = self._decide(own, now, planned=False)
        if self._active is None:
            return self._start(own, decision, now)
        return self._continue(own, decision, now)

    def abandon(self) -> None:
        """The manoeuvre was taken from us (a higher owner flies the vehicle): forget it
        without a RESUME; a conflict still there starts a new one at the next tick."""
        self._active = None

    @property
    def manoeuvring(self) -> ManoeuvreKind | None:
        return self._active.kind if self._active else None

    def _can_act(self, own: VehicleStatus) -> bool:
        if not own.armed:
            return False
        if self.config.own_type in GROUND:
            return True
        return own.alt_rel_m >= self.config.min_active_alt_rel_m

    # ------------------------------------------------------------------ geometry
    def _own_track(self, own: VehicleStatus, now: float, planned: bool) -> Track:
        t = self._own_t or self._own_received
        vn, ve, vd = own.vel_north_m_s, own.vel_east_m_s, own.vel_down_m_s
        alt = own.alt_msl_m
        if self._active is not None:
            vd = 0.0  # our own manoeuvre: not a conflict, not a resolution
        if planned and self._active is not None:
            if self.config.own_type in GROUND:
                vn, ve, vd = self._active.resume_vel
            else:
                alt = self._active.planned_rel_m + (own.alt_msl_m - own.alt_rel_m)
                vd = 0.0
        return Track(
            own.vehicle_id,
            own.lat_deg,
            own.lon_deg,
            alt,
            vn,
            ve,
            vd,
            t,
            self.config.own_max_speed_m_s,
        )

    def _decide(self, own: VehicleStatus, now: float, planned: bool) -> _Decision:
        cfg = self.config
        contacts = list(self._contacts.values())
        if not contacts:
            return _Decision(None, None, ())
        tracks = [self._own_track(own, now, planned), *(c.track for c in contacts)]
        k = kinematic(tracks, now)
        near = self._within_reach(k)
        if near is not None:  # the others cannot touch our decision: left out
            if len(near) == 1:
                return _Decision(None, None, ())
            tracks = [tracks[i] for i in near]
            contacts = [contacts[i - 1] for i in near[1:]]
            k = Kinematic(
                tuple(k.ids[i] for i in near),
                k.pos[near],
                k.vel[near],
                k.age_s[near],
                k.margin_m[near],
            )
        a = pairwise(k, cfg.horizon_s)
        # a climb or a descent is not trusted to resolve anything before it is done: a
        # pair conflicts if it does with the vertical rates or without them
        level_k = replace(k, vel=k.vel * np.array([1.0, 1.0, 0.0]))
        a0 = pairwise(level_k, cfg.horizon_s)
        n = len(tracks)
        miss = np.minimum(a.miss_m, a0.miss_m) - a.margin_m
        radius = cfg.protect_m + a.margin_m[0, 1:]
        if not planned:
            # the own row: when the closest approach comes, how close, when the
            # separation is first lost (with the vertical rates or without them)
            t_row = np.minimum(a.t_cpa_s, a0.t_cpa_s)[0, 1:]
            miss_row = np.minimum(a.miss_m, a0.miss_m)[0, 1:]
            rel_p = k.pos[1:] - k.pos[0]
            loss_row = np.minimum(
                entry_time(rel_p, k.vel[1:] - k.vel[0], radius, cfg.horizon_s),
                entry_time(rel_p, level_k.vel[1:] - level_k.vel[0], radius, cfg.horizon_s),
            )
            own_legs: tuple[Legs, Legs] | None = None
            if self._follows_route(own):
                t_row, miss_row, loss_row, own_legs = self._route_row(
                    own, tracks[0], k, level_k, radius
                )
                miss[0, 1:] = miss[1:, 0] = miss_row - a.margin_m[0, 1:]
            self._intent_rows(
                contacts, tracks[0], k, level_k, radius, own_legs, now, (t_row, miss_row, loss_row)
            )
            miss[0, 1:] = miss[1:, 0] = miss_row - a.margin_m[0, 1:]
        else:
            t_p, m_p, l_p = (
                np.zeros(n - 1),
                np.minimum(a.miss_m, a0.miss_m)[0, 1:],
                np.zeros(n - 1),
            )
            if self._intent_rows(
                contacts, tracks[0], k, level_k, radius, None, now, (t_p, m_p, l_p)
            ):
                miss[0, 1:] = miss[1:, 0] = m_p - a.margin_m[0, 1:]
        if planned:
            clear = miss[0, 1:] >= cfg.release_m
            if not clear.all():
                # coming back down from a climb, away from a contact above that is not
                # descending (one stacked over the climb, which waits for it in turn):
                # that contact does not hold it up when the way back is no conflict with
                # it and no closer to it than staying, or two stacked vehicles would each
                # wait for the other for good
                k_here = kinematic([self._own_track(own, now, False), *tracks[1:]], now)
                level_here = replace(k_here, vel=k_here.vel * np.array([1.0, 1.0, 0.0]))
                here = pairwise(k_here, cfg.horizon_s)
                here0 = pairwise(level_here, cfg.horizon_s)
                stay = np.minimum(here.miss_m, here0.miss_m)[0, 1:] - here.margin_m[0, 1:]
                back = miss[0, 1:]
                above = (k_here.pos[1:, 2] > k_here.pos[0, 2]) & (
                    k_here.vel[1:, 2] >= -cfg.level_climb_m_s
                )
                down = tracks[0].alt_msl_m < own.alt_msl_m - 0.5  # the planned track's
                clear |= down & above & (back > stay) & (back >= cfg.protect_m)
                # a still pair (both hovering) that is no conflict from the planned
                # altitude does not hold it up either: waiting cannot change it (two
                # VTOLs hovering over pads 30 m apart, a radio peer's error bound of up to
                # 8 m: once inside 20 m, each held the other under the 30 m release for
                # good, and the climb held the one's PREMISSION leg)
                speed = np.hypot(k_here.vel[:, 0], k_here.vel[:, 1])
                still = (speed < cfg.still_m_s) & (np.abs(k_here.vel[:, 2]) < cfg.level_climb_m_s)
                released = still[0] & still[1:] & (back >= cfg.protect_m) & ~clear
                if released.any():
                    self._count("still_release")
                clear |= released
            return _Decision(
                None,
                None,
                tuple(c.track.vehicle_id for c, ok in zip(contacts, clear, strict=True) if not ok),
            )
        # pairs of others count as in conflict with `others_slack_m` more: each vehicle
        # sees the others' pairs from its own (slightly different) reports, and a climb
        # it stacks over must not be one it failed to expect
        threshold = np.full((n, n), cfg.protect_m + cfg.others_slack_m)
        threshold[0, :] = threshold[:, 0] = cfg.protect_m
        conflict = (miss < threshold) & ~np.eye(n, dtype=bool)
        if not conflict[0].any():
            return _Decision(None, None, ())
        against_idx = np.flatnonzero(conflict[0])
        against = tuple(tracks[i].vehicle_id for i in against_idx)
        soonest = float(t_row[against_idx - 1].min())
        closest = float(miss_row[against_idx - 1].min())
        loss = float(loss_row[against_idx - 1].min())

        # who can manoeuvre, what kind each is, the reported altitudes the rule compares
        types = [cfg.own_type, *(c.vehicle_type or VehicleType.OTHER for c in contacts)]
        ground = np.array([t in GROUND for t in types])
        coop_air = np.array(
            [True]
            + [
                c.cooperative
                and c.armed
                and c.vehicle_type not in GROUND | NEVER_MANOEUVRES
                and c.alt_rel_m >= cfg.min_active_alt_rel_m
                for c in contacts
            ]
        )
        coop_air[0] = cfg.own_type not in GROUND
        alt = np.array([t.alt_msl_m for t in tracks])
        ids = np.array([t.vehicle_id for t in tracks])

        if cfg.own_type in GROUND:
            # a rover or boat gives way to every aircraft and non-cooperative contact,
            # to ground vehicles with a lower id, and never drives into a stopped one
            speed = np.linalg.norm(k.vel[:, :2], axis=1)
            gives = ~ground | (ids < ids[0]) | (speed < 0.5)
            gives[0] = False
            hit = conflict[0] & gives
            if hit.any():
                return _Decision(ManoeuvreKind.STOP, None, against, soonest, closest, loss)
            return _Decision(None, None, against, soonest, closest, loss)

        # i gives way to j (i climbs above j): j is not a cooperative aircraft and not
        # well above i, or both are, and i is higher; within the band a fixed-wing before
        # a multirotor (it climbs faster, keeps its path and cannot stop) when both types
        # are known (VehicleInfo), else the higher id
        dz = alt[:, None] - alt[None, :]
        known = np.array(
            [cfg.own_type is not None] + [c.vehicle_type is not None for c in contacts]
        )
        fw = np.array([t in FIXED_WING for t in types])
        by_type = known[:, None] & known[None, :] & (fw[:, None] != fw[None, :])
        in_band = np.where(by_type, fw[:, None], ids[:, None] > ids[None, :])
        by_rank = (dz > cfg.tie_band_m) | ((np.abs(dz) <= cfg.tie_band_m) & in_band)
        # what each stands at: its altitude or where it is going, whichever is higher
        alt_cpa = alt[None, :] + k.vel[None, :, 2] * a.t_cpa_s
        level = np.maximum(alt[None, :], alt_cpa) + k.margin_m[None, :]
        target = self._stack(by_rank, coop_air, conflict, dz, alt, level)
        if target is None:
            # the band made a cycle (A over B over C over A by id and altitude): rank
            # this cluster by altitude then id alone, which cannot cycle
            lexical = (dz > 0) | ((dz == 0) & (ids[:, None] > ids[None, :]))
            target = self._stack(lexical, coop_air, conflict, dz, alt, level)
            assert target is not None
        if target[0] > alt[0] + 0.5:
            return _Decision(ManoeuvreKind.CLIMB, float(target[0]), against, soonest, closest, loss)
        # stand-on: level off if climbing into a conflict above
        above = conflict[0] & (alt > alt[0])
        if above.any() and own.vel_down_m_s < -cfg.level_climb_m_s:
            return _Decision(ManoeuvreKind.LEVEL, float(alt[0]), against, soonest, closest, loss)
        return _Decision(None, None, against, soonest, closest, loss)

    def _within_reach(self, k: Kinematic) -> np.ndarray | None:
        """The tracks (indices, the own first) that can take part in our decision: the
        own vehicle's cluster, grown from it through every pair that could come within
        the largest threshold (`protect_m` + `others_slack_m`, or `release_m`) inside
        the horizon, by a bound that cannot miss one: the horizontal distance now, less
        what both can fly in the horizon at their speed (3D; the own at its route's
        speed if higher) and their staleness margins. A contact outside the cluster is
        in conflict with nothing in it, so the conflicts, the give-way stacking and the
        release among the cluster are the same without it. None: every track (a swarm
        in one cluster). Grows with the cluster, not with the swarm squared."""
        n = len(k.ids)
        if n <= 8:
            return None  # a small swarm: the whole decision costs no more
        cfg = self.config
        thr = max(cfg.protect_m + cfg.others_slack_m, cfg.release_m)
        speed = np.linalg.norm(k.vel, axis=1)
        if self._route is not None:
            speed[0] = max(float(speed[0]), self._route.speed_m_s)
        reach = cfg.horizon_s * speed + k.margin_m
        xy = k.pos[:, :2]
        keep = np.zeros(n, dtype=bool)
        keep[0] = True
        frontier = np.array([0])
        while frontier.size:
            d = np.linalg.norm(xy[None, :, :] - xy[frontier][:, None, :], axis=2)
            may = (d - reach[frontier][:, None] - reach[None, :] <= thr).any(axis=0)
            new = may & ~keep
            keep |= new
            frontier = np.flatnonzero(new)
        if keep.all():
            return None
        return np.flatnonzero(keep)

    def _follows_route(self, own: VehicleStatus) -> bool:
        """The own multirotor flies its mission's route in level flight, not manoeuvring:
        its own motion is predicted along the route, not straight on."""
        return (
            self._route is not None
            and self.config.own_type in MULTIROTOR
            and self._active is None
            and abs(own.vel_down_m_s) <= self.config.level_climb_m_s
        )

    def _route_row(
        self,
        own: VehicleStatus,
        own_track: Track,
        k: Kinematic,
        level_k: Kinematic,
        radius: np.ndarray,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, tuple[Legs, Legs]]:
        """The own row (t_cpa, miss, loss of separation against every contact) with
        the own vehicle flying its route's legs: ArduCopter flies to its item, turns
        there onto the next leg (a survey lane's end), holds at the last one; the
        contacts keep their velocity, with their vertical rates or without."""
        route = self._route
        assert route is not None and route.points is not None
        cfg = self.config
        home = own.alt_msl_m - own.alt_rel_m
        pts = np.array(route.points, dtype=float)
        frame = Frame(own_track.lat_deg, own_track.lon_deg, own_track.alt_msl_m)
        enu = frame.positions(pts[:, 0], pts[:, 1], pts[:, 2] + home)
        speed = max(math.hypot(own.vel_north_m_s, own.vel_east_m_s), route.speed_m_s)
        legs = along_route(k.pos[0], enu, speed, cfg.horizon_s)
        t1, m1, e1 = route_approach(legs, k.pos[1:], k.vel[1:], radius, cfg.horizon_s)
        t0, m0, e0 = route_approach(legs, level_k.pos[1:], level_k.vel[1:], radius, cfg.horizon_s)
        return np.where(m0 < m1, t0, t1), np.minimum(m0, m1), np.minimum(e0, e1), (legs, legs)

    def _intent_rows(
        self,
        contacts: list[_Contact],
        own_track: Track,
        k: Kinematic,
        level_k: Kinematic,
        radius: np.ndarray,
        own_legs: tuple[Legs, Legs] | None,
        now: float,
        rows: tuple[np.ndarray, np.ndarray, np.ndarray],
    ) -> bool:
        """The own row's entries (t_cpa, miss, loss of separation; updated in place) for
        the contacts that publish their next legs, predicted along them as well (their
        path at their speed, turning no tighter than their turn radius), with their
        vertical rate and level, the own vehicle on its route or straight on: the closer
        approach and the earlier loss of the two predictions count (a contact leaving
        its legs before it says so is still seen straight on). A contact's intent older
        than `intent_stale_s` is not used. Whether any was."""
        cfg = self.config
        if not cfg.intent or not self._intents:
            return False
        t_row, miss_row, loss_row = rows
        frame: Frame | None = None
        used = False
        # how fast the own vehicle can close in over the horizon (its route's speed)
        own_speed = float(np.hypot(k.vel[0, 0], k.vel[0, 1]))
        if own_legs is not None:
            own_speed = max(own_speed, float(np.hypot(*own_legs[0][2][:, :2].T).max()))
        for j, c in enumerate(contacts, start=1):
            vid = c.track.vehicle_id
            held = self._intents.get(vid)
            if held is None:
                continue
            it, received = held
            if now - received > cfg.intent_stale_s:
                self._intents.pop(vid, None)
                self._count("intent_stale")
                continue
            r = float(radius[j - 1])
            speed = max(it.speed_m_s, float(np.hypot(k.vel[j, 0], k.vel[j, 1])))
            gap = float(np.hypot(*(k.pos[j, :2] - k.pos[0, :2])))
            if gap - cfg.horizon_s * (own_speed + speed) > cfg.release_m + r - cfg.protect_m:
                continue  # beyond reach on any path: its legs cannot make it a conflict
            if frame is None:
                frame = Frame(own_track.lat_deg, own_track.lon_deg, own_track.alt_msl_m)
            pts = np.array([(p.lat_deg, p.lon_deg, p.alt_msl_m) for p in it.legs], dtype=float)
            enu = frame.positions(pts[:, 0], pts[:, 1], pts[:, 2])
            # its path is the intent's, its altitude its own: level, or keeping its
            # vertical rate (a climb it gives way with is not in its legs)
            enu[:, 2] = level_k.pos[j, 2]
            best = (math.inf, math.inf, math.inf)
            level_legs = along_intent(
                level_k.pos[j],
                level_k.vel[j],
                enu,
                it.speed_m_s,
                it.turn_radius_m,
                cfg.horizon_s,
                hold_at_end=it.hold_at_end,
            )
            vz = float(k.vel[j, 2])
            times, starts, vels = level_legs
            up = np.array([0.0, 0.0, vz])
            climbing = (times, starts + np.outer(times, up), vels + up)
            for ki, theirs, own_j in ((k, climbing, 0), (level_k, level_legs, 1)):
                ours = own_legs[own_j] if own_legs is not None else straight(ki.pos[0], ki.vel[0])
                t, m, e = legs_approach(ours, theirs, r, cfg.horizon_s)
                best = (t if m < best[1] else best[0], min(m, best[1]), min(e, best[2]))
            if best[1] < miss_row[j - 1]:
                t_row[j - 1], miss_row[j - 1] = best[0], best[1]
            loss_row[j - 1] = min(loss_row[j - 1], best[2])
            used = True
            self._count("intent_rows")
        return used

    def _stack(
        self,
        by_rank: np.ndarray,
        coop_air: np.ndarray,
        conflict: np.ndarray,
        dz: np.ndarray,
        alt: np.ndarray,
        level: np.ndarray,
    ) -> np.ndarray | None:
        """Every aircraft's target: `vertical_sep_m` above the target (or, for traffic
        that will not manoeuvre, the level) of each vehicle it gives way to, as a fixed
        point; None if the give-way relation has a cycle (no fixed point)."""
        cfg = self.config
        # i gives way to j (i climbs above j): both cooperative aircraft and i ranks
        # higher, or j will not manoeuvre and is not well above i
        gives = np.where(coop_air[None, :], by_rank, dz >= -cfg.tie_band_m)
        gives &= conflict & coop_air[:, None]
        target = alt.copy()
        for _ in range(len(alt) + 1):
            ref = np.where(coop_air[None, :], target[None, :], level)
            need = np.where(gives, ref + cfg.vertical_sep_m, -np.inf).max(axis=1)
            new = np.maximum(alt, need)
            if np.array_equal(new, target):
                return target
            target = new
        return None

    # ------------------------------------------------------------------ transitions
    def _ceiling_rel(self) -> float:
        c = self.config.ceiling_rel_m
        if self._zone_ceiling_rel is not None:
            c = min(c, self._zone_ceiling_rel)
        return c

    def time_to_act_s(self, own: VehicleStatus, target_msl_m: float | None) -> float:
        """How long before the loss of separation a multirotor must start its manoeuvre:
        the climb to `target_msl_m` or the stop from its ground speed, whichever takes
        longer (both are flown at once), plus `act_margin_s`."""
        cfg = self.config
        climb = 0.0 if target_msl_m is None else max(0.0, target_msl_m - own.alt_msl_m)
        stop = math.hypot(own.vel_north_m_s, own.vel_east_m_s) / cfg.stop_accel_m_s2
        return max(climb / cfg.climb_rate_m_s, stop) + cfg.act_margin_s

    def _start(self, own: VehicleStatus, d: _Decision, now: float) -> list[Output]:
        if d.kind is None:
            return []
        if (
            self.config.own_type in MULTIROTOR
            and d.kind in (ManoeuvreKind.CLIMB, ManoeuvreKind.LEVEL)
            and abs(own.vel_down_m_s) <= self.config.level_climb_m_s
            and d.loss_s > self.time_to_act_s(own, d.target_msl_m)
        ):
            # a multirotor in level flight can stop and climb in seconds: it does not
            # react to a constant-velocity prediction further ahead than it needs (a
            # survey lane's end turns it long before), it watches it at every tick
            # instead. Climbing or descending (a take-off, a landing) it acts at once.
            self._count("deferred_ticks")
            return []
        planned = own.alt_rel_m if self._planned_rel is None else self._planned_rel
        self._active = _Active(
            d.kind,
            planned,
            None,
            (own.vel_north_m_s, own.vel_east_m_s, own.vel_down_m_s),
            d.against,
        )
        self._count("manoeuvres")
        return self._command(own, d, now)

    def _continue(self, own: VehicleStatus, d: _Decision, now: float) -> list[Output]:
        act = self._active
        assert act is not None
        if d.kind is None:
            # clear from where we would be without the manoeuvre, for long enough?
            if self._decide(own, now, planned=True).against:
                act.clear_since = None
                return []
            if act.clear_since is None:
                act.clear_since = now
            if now - act.clear_since < self.config.clear_hold_s:
                return []
            return self._resume(own, now)
        act.clear_since = None
        if d.kind is ManoeuvreKind.CLIMB and act.kind is ManoeuvreKind.CLIMB:
            assert d.target_msl_m is not None and act.target_rel_m is not None
            target_rel = d.target_msl_m - (own.alt_msl_m - own.alt_rel_m)
            if target_rel < act.target_rel_m + self.config.retarget_m:
                return []  # a target only rises, and not by dithering steps
        elif d.kind is act.kind:
            return []
        return self._command(own, d, now)

    def _command(self, own: VehicleStatus, d: _Decision, now: float) -> list[Output]:
        act = self._active
        assert act is not None and d.kind is not None
        act.kind, act.against = d.kind, d.against
        who = ", ".join(str(i) if i >= 0 else f"ICAO {(-1 - i):06X}" for i in d.against)
        when = f"in {d.soonest_s:.0f} s at {d.closest_m:.0f} m"
        out: list[Output] = []
        if d.kind is ManoeuvreKind.STOP:
            act.target_rel_m = None
            reqs: tuple[ApRequest, ...] = (SetMode(mode="HOLD"),)
            text = f"avoid: stop for {who} {when}"
            out.append(Manoeuvre(d.kind, reqs, None, d.against, text))
            out.append(self._alert(own, now, Severity.WARNING, text, detail=_detail(d, 0.0)))
            return out
        assert d.target_msl_m is not None
        home = own.alt_msl_m - own.alt_rel_m
        target_rel = d.target_msl_m - home
        ceiling = self._ceiling_rel()
        capped = target_rel > ceiling
        target_rel = max(own.alt_rel_m, min(target_rel, ceiling))
        act.target_rel_m = target_rel
        if self.config.own_type in MULTIROTOR:
            reqs = (Goto(lat_deg=own.lat_deg, lon_deg=own.lon_deg, alt_rel_m=target_rel),)
        else:
            reqs = (ChangeAltitude(alt_rel_m=target_rel),)
        verb = "climb to" if d.kind is ManoeuvreKind.CLIMB else "level at"
        climb_s = (target_rel - own.alt_rel_m) / self.config.climb_rate_m_s
        severity, why = Severity.WARNING, ""
        if capped:
            severity, why = Severity.CRITICAL, " (ceiling)"
        elif d.kind is ManoeuvreKind.CLIMB and climb_s > d.soonest_s:
            # CRITICAL only when the miss it cannot climb out of in time is a danger
            # (under half the protection distance: the paper's 10 m)
            danger = d.closest_m < 0.5 * self.config.protect_m
            severity = Severity.CRITICAL if danger else Severity.WARNING
            why = f" (too slow: {climb_s:.0f} s to climb)"
        text = f"avoid: {verb} {target_rel:.0f} m{why} for {who} {when}"
        out.append(Manoeuvre(d.kind, reqs, target_rel, d.against, text))
        out.append(self._alert(own, now, severity, text, detail=_detail(d, target_rel)))
        return out

    def _resume(self, own: VehicleStatus, now: float) -> list[Output]:
        act = self._active
        assert act is not None
        self._active = None
        if self.config.own_type in GROUND:
            reqs: tuple[ApRequest, ...] = ()
            target: float | None = None
            text = "avoid: clear, resuming"
        else:
            target = act.planned_rel_m
            reqs = (ChangeAltitude(alt_rel_m=target),)
            text = f"avoid: clear, back to {target:.0f} m"
        return [
            Manoeuvre(ManoeuvreKind.RESUME, reqs, target, (), text),
            self._alert(own, now, Severity.INFO, text, cleared=True),
        ]

    def _alert(
        self,
        own: VehicleStatus | None,
        now: float,
        severity: Severity,
        text: str,
        cleared: bool = False,
        detail: ReasonDetail | None = None,
    ) -> Alert:
        return Alert(
            vehicle_id=self.config.own_id,
            time_unix_s=max(0.0, now),
            severity=severity,
            code=AlertCode.CONDITION_CLEARED if cleared else AlertCode.COLLISION_RISK,
            text=short_text(text),
            detail=detail,
        )


def _detail(d: _Decision, altitude_rel_m: float) -> ReasonDetail:
    """A manoeuvre's numbers for the ground station: the other aircraft (a swarm node
    alone; 0 for several or ADS-B traffic), the closest approach, when, and the altitude
    above home it goes to (0: it stops)."""
    other = d.against[0] if len(d.against) == 1 and d.against[0] > 0 else 0
    return ReasonDetail(
        DetailCode.COLLISION,
        other if other <= 65534 else 0,
        distance_m=min(max(d.closest_m, 0.0), 1.0e6) if math.isfinite(d.closest_m) else 0.0,
        in_s=min(max(d.soonest_s, 0.0), 1.0e7) if math.isfinite(d.soonest_s) else 0.0,
        altitude_m=min(max(altitude_rel_m, 0.0), 8000.0),
    )
