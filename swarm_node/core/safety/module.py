"""Collision avoidance as a node module: the `CollisionAvoider` fed at 5 Hz, and its
manoeuvres flown as owner AVOIDANCE, the mission suspended meanwhile by the arbiter.

    inputs (from NodeCore)                      what it does with them
    on_peer(VehicleStatus | VehicleInfo)        a cooperative contact (its type from info)
    on_intent(VehicleIntent)                    a peer's next legs (the avoider predicts
                                                along them)
    forget(vehicle_id)                          a peer gone (it left the swarm)
    silent(vehicle_id)                          a peer lost by silence: kept as a contact
                                                at its predicted position (silent.py)
    silent_route(SilentShare)                   the rest of its share (the mission
                                                coordinator's): the prediction follows it
    tick(now, own status, autopilot, ...)       feeds the own state, ADS-B traffic
                                                (`AutopilotState.traffic`), the planned
                                                altitude, the zones' ceiling and a
                                                multirotor's route ahead (the mission the
                                                mission manager uploaded, `items`); runs
                                                the avoider's 5 Hz tick; answers with
                                                Suspend, Submits (owner AVOIDANCE),
                                                Release, Alerts and the own next legs
                                                (VehicleIntent, `_own_intent`)
    on_result(ApResult)                         results of its requests

Suspending the mission. On the first manoeuvre the module remembers what the vehicle
was doing (its mode, the mission item it was flying to) and asks the arbiter to suspend
the mission (`Suspend`): the arbiter gives AVOIDANCE control (EMERGENCY still
pre-empts; the operator's flight requests are refused meanwhile) and holds the mission's
flight requests instead of refusing them, so the sortie never fails for it. The
manoeuvre is flown as:

    vehicle                   doing            manoeuvre (to the avoider's target altitude)
    fixed-wing, VTOL flying   AUTO mission     ChangeAltitude: the mission flown on along
                                               its flyable, zone-safe path at the new
                                               altitude (asked again at each new item);
                                               the mission's requests go on under it
                                               (`Suspend(passing=True)`)
    fixed-wing, VTOL flying   anything else    ChangeAltitude (keeps RTL, LOITER, GUIDED)
    multirotor, VTOL hovering AUTO mission     Goto the item it was flying to, higher
                                               (GUIDED): on its zone-safe leg, stopping
                                               there; the mission is suspended
    multirotor, VTOL hovering anything else    Goto over itself (GUIDED: holds, climbs)
    rover, boat               anything         HOLD mode (stops)

When the avoider says clear (RESUME), the vehicle goes back to what it was doing: the
mission's held requests if one of them will reach the autopilot and say where to go (its
newest intent: `AutopilotArbiter.will_steer`, asked through `will_steer`); else a
fixed-wing changes altitude back to its mission item's (or the planned one), and the
others go back by the mode they were in: AUTO -> StartMission(first_item = the item
they were flying to), RTL -> ReturnToLaunch, QRTL, LOITER and the like -> that mode
again, LAND/QLAND -> Land, GUIDED (a take-off climb, an operator's Goto) -> Goto over
itself at the planned altitude. Once those requests are answered, the module releases
control (`Release(AVOIDANCE)`): the arbiter gives it back to whoever held it before and
lets the held requests go on. A higher owner taking control (an emergency) ends it all.

The wire MissionState has no SUSPENDED (adding one would change every node's radio
decoder): a suspended vehicle keeps publishing MISSION (or PREMISSION), its progress
held, with AlertFlag.COLLISION_RISK set in its status; the Alerts say what it does.

Take-off and landing at close pads are the mission manager's (safety/pad_sequence.py),
ticked at this module's 5 Hz.

Pure: no I/O; `now` is passed in.
"""

from __future__ import annotations

import itertools
import logging
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

import msgspec

from swarm_proto import (
    Alert,
    AlertCode,
    IntentPoint,
    NoFlyZone,
    Severity,
    VehicleInfo,
    VehicleIntent,
    VehicleStatus,
    VehicleType,
)
from swarm_proto.geodesy import distance_m
from swarm_proto.messages import MAX_INTENT_LEGS
from swarm_proto.text import short_text

from ..autopilot.items import ItemKind, Waypoint
from ..autopilot.requests import (
    ApRequest,
    ApResult,
    ChangeAltitude,
    Goto,
    Land,
    ReturnToLaunch,
    SetMode,
    StartMission,
)
from ..autopilot.state import AutopilotState
from ..outputs import ModuleOutput, Note, Owner, Publish, Release, SilentShare, Submit, Suspend
from ..profile import VehicleProfile
from .avoidance import (
    GROUND,
    AvoidanceConfig,
    Ceiling,
    CollisionAvoider,
    Forget,
    Manoeuvre,
    ManoeuvreKind,
    OwnRoute,
    OwnUnknown,
    PlannedAltitude,
    Silent,
    SilentRoute,
    Traffic,
)
from .pads import hovering
from .zones import ceiling_msl

INTENT_PERIOD_S = 2.0  # the own intent again this often while it has legs (else on change)
REASSERT_S = 2.0  # a Goto manoeuvre's mode lost (another request won the race): asked again
RESUME_TRIES = 3
#: modes a vehicle is sent back to as they are
RESUME_BY_MODE = frozenset(
    {
        "LOITER",
        "QLOITER",
        "QHOVER",
        "POSHOLD",
        "ALT_HOLD",
        "BRAKE",
        "CIRCLE",
        "CRUISE",
        "FBWA",
        "FBWB",
        "HOLD",
        "MANUAL",
        "STABILIZE",
        "QSTABILIZE",
    }
)


@dataclass(slots=True)
class Suspension:
    """What the vehicle was doing when avoidance took the autopilot."""

    mode: str
    item: int  # MISSION_CURRENT then (the item it was flying to)
    planned_rel_m: float | None
    via_goto: bool = False  # the manoeuvre flies Goto (GUIDED), not ChangeAltitude
    last: tuple[ApRequest, ...] = ()
    last_sent_s: float = 0.0
    resuming: bool = False
    resume_tries: int = 0
    item_seen: int = 0  # a ChangeAltitude is asked again when the mission item moves on


@dataclass
class AvoidanceModule:
    profile: VehicleProfile
    enabled: bool = True
    config: AvoidanceConfig | None = None
    suspension: Suspension | None = None
    items: tuple[Waypoint, ...] = ()  # the mission the autopilot holds (items 1..)
    next_tick: float = 0.0  # the first tick at once (NodeCore: when it starts)
    counters: dict[str, int] = field(default_factory=dict)
    _pending: dict[int, ApRequest] = field(default_factory=dict)
    _resume_ids: set[int] = field(default_factory=set)
    _traffic_seen: dict[int, float] = field(default_factory=dict)
    _blocked_noted: bool = False
    _ids: itertools.count[int] = field(default_factory=lambda: itertools.count(1))
    _will_steer: Callable[[], bool] = bool  # the arbiter's: a held mission request steers
    intent: bool = True  # publish the own next legs and predict peers along theirs
    _intent_sent: tuple[object, ...] | None = None  # what the last intent said
    _intent_at: float = -1e18

    def __post_init__(self) -> None:
        p = self.profile
        self.cfg = self.config or AvoidanceConfig(
            own_id=p.vehicle_id,
            own_type=p.vehicle_type,
            climb_rate_m_s=p.climb_rate_m_s if p.climb_rate_m_s > 0 else 5.0,
            intent=self.intent,
        )
        self.avoider = CollisionAvoider(self.cfg)

    # ------------------------------------------------------------------ views
    @property
    def active(self) -> bool:
        """Avoidance holds (or is giving back) the autopilot."""
        return self.suspension is not None

    def next_deadline(self) -> float | None:
        """The next 5 Hz tick (None: the module is off)."""
        return self.next_tick if self.enabled else None

    # ------------------------------------------------------------------ inputs
    def on_peer(self, msg: VehicleStatus | VehicleInfo, now: float) -> None:
        if self.enabled and msg.vehicle_id != self.profile.vehicle_id:
            if type(msg) is VehicleStatus:  # 5 Hz per peer: the avoider's hot path
                self.avoider.heard(msg, now)
                return
            self.avoider.handle(msg, now)

    def on_peers(
        self, msgs: Sequence[VehicleStatus | VehicleInfo], now: float, statuses: int
    ) -> None:
        """`on_peer` for each of peers' `msgs` (none of them ours; `statuses` of them
        are VehicleStatus), at once."""
        if self.enabled:
            self.avoider.heard_all(msgs, now, statuses_only=statuses == len(msgs))

    def on_intent(self, msg: VehicleIntent, now: float) -> None:
        """A peer's next legs (the avoider keeps the latest, counts bad ones)."""
        if self.enabled and msg.vehicle_id != self.profile.vehicle_id:
            self.avoider.handle(msg, now)

    def forget(self, vehicle_id: int, now: float) -> None:
        if self.enabled:
            self.avoider.handle(Forget(vehicle_id), now)

    def silent(self, vehicle_id: int, now: float) -> None:
        """A peer lost by silence is still an aircraft: its predicted position stays a
        contact until it is heard again, seen landed or forgotten."""
        if self.enabled and vehicle_id != self.profile.vehicle_id:
            self.avoider.handle(Silent(vehicle_id), now)

    def silent_route(self, share: SilentShare, now: float) -> None:
        if self.enabled:
            self.avoider.handle(SilentRoute(share.vehicle_id, share.points, share.speed_m_s), now)

    def _on_path(self, s: Suspension) -> bool:
        """The manoeuvre is an altitude flown on what the vehicle flies (a fixed-wing's
        ChangeAltitude), not a Goto that suspends it: the mission's requests go on under
        it. Held instead, a fleet stacked at one point (a route's end) would hold its way
        home for ever: the conflict never clears while it circles there."""
        return not s.via_goto and self.profile.vehicle_type not in GROUND and not s.resuming

    # ------------------------------------------------------------------ tick
    def tick(
        self,
        now: float,
        own: VehicleStatus | None,
        ap: AutopilotState,
        *,
        zones: Mapping[int, NoFlyZone] | None = None,
        climb_target_rel_m: float | None = None,
        holder: Owner | None = None,
        items: tuple[Waypoint, ...] | None = None,
        will_steer: Callable[[], bool] | None = None,
    ) -> list[ModuleOutput]:
        """The 5 Hz tick (when `next_deadline` is due). `climb_target_rel_m`: the
        take-off altitude while the mission manager climbs to it; `holder`: who holds
        the autopilot now (the arbiter's); `items`: the mission the mission manager
        uploaded; `will_steer`: whether a mission request the arbiter holds will say
        where the vehicle goes once control is given back (asked at a resume)."""
        if not self.enabled or now < self.next_tick:
            return []
        period = self.cfg.period_s
        nxt = self.next_tick + period
        self.next_tick = nxt if nxt > now else now + period  # late: no catch-up burst
        if items is not None:
            self.items = items
        if will_steer is not None:
            self._will_steer = will_steer
        av = self.avoider
        if own is not None:
            av.handle(own, now)
            av.handle(PlannedAltitude(self._planned(ap, climb_target_rel_m)), now)
            av.handle(Ceiling(self._ceiling(own, zones, now)), now)
            av.handle(self._route(ap), now)
        else:  # no own position (a rebooted autopilot has no fix yet): nothing to fly
            av.handle(OwnUnknown(), now)
        for r in ap.traffic:
            if self._traffic_seen.get(r.icao_address) != r.time_s:
                self._traffic_seen[r.icao_address] = r.time_s
                av.handle(Traffic.from_report(r), now)
        self._count("ticks")
        blocked = holder is not None and holder > Owner.AVOIDANCE
        out: list[ModuleOutput] = []
        for o in av.on_timer(now):
            if isinstance(o, Alert):
                out.append(Publish(o))
            elif blocked:
                out += self._blocked(o, holder)
            else:
                out += self._manoeuvre(o, ap, now)
        if blocked and self.suspension is not None:
            out += self._give_up(f"pre-empted by {holder.name if holder else '?'}")
        elif not blocked:
            self._blocked_noted = False
        s = self.suspension
        if s is not None and not s.resuming and av.manoeuvring is None:
            out += self._end("not flying any more")  # landed or disarmed: nothing to resume
        elif (
            s is not None
            and not s.resuming
            and not s.via_goto
            and not self._pending
            and ap.mode_name == "AUTO"
            and ap.mission_current != s.item_seen
        ):
            # the next mission item brings its own altitude: the manoeuvre's again
            s.item_seen = ap.mission_current
            out += self._submit(s.last, now)
            self._count("reasserted")
        elif (
            s is not None
            and not s.resuming
            and s.via_goto
            and not self._pending
            and ap.mode_name != "GUIDED"
            and now - s.last_sent_s >= REASSERT_S
        ):
            out += self._submit(s.last, now)  # another request took the mode back
            self._count("reasserted")
        return out + self._own_intent(own, ap, now)  # (after: a manoeuvre drops it)

    def _route(self, ap: AutopilotState) -> OwnRoute:
        """A multirotor's way ahead in its mission (AUTO, not suspended): the items from
        the one it flies to, up to a hold, a landing or a return (None otherwise)."""
        if (
            self.profile.vehicle_type != VehicleType.COPTER
            or ap.mode_name != "AUTO"
            or self.suspension is not None
        ):
            return OwnRoute(None)
        points: list[tuple[float, float, float]] = []
        for w in self.items[max(0, ap.mission_current - 1) :]:
            if w.kind in (ItemKind.LAND, ItemKind.RTL, ItemKind.TAKEOFF):
                break
            if w.kind == ItemKind.CHANGE_SPEED or (w.lat_deg == 0.0 and w.lon_deg == 0.0):
                continue
            points.append((w.lat_deg, w.lon_deg, w.alt_rel_m))
            if w.kind != ItemKind.WAYPOINT:
                break  # a loiter: it stays there
        return OwnRoute(tuple(points) or None, self.profile.cruise_speed_m_s)

    def _own_intent(
        self, own: VehicleStatus | None, ap: AutopilotState, now: float
    ) -> list[ModuleOutput]:
        """The own next legs for the peers' avoidance (VehicleIntent): while flying a
        mission (AUTO, armed, airborne), up to MAX_INTENT_LEGS items from the one it
        flies to, to a hold, a landing or a return; published when they change and every
        INTENT_PERIOD_S; once empty when it stops following them."""
        if not self.intent or own is None:
            return []
        points: list[IntentPoint] = []
        stops = False
        if (
            own.armed
            and ap.mode_name == "AUTO"
            and own.alt_rel_m >= self.cfg.min_active_alt_rel_m
            and self.suspension is None
        ):
            # (giving way, it flies what its legs do not say: its peers predict it
            # straight on, with its climb)
            home = own.alt_msl_m - own.alt_rel_m
            for w in self.items[max(0, ap.mission_current - 1) :]:
                if w.kind in (ItemKind.LAND, ItemKind.RTL, ItemKind.TAKEOFF):
                    stops = True
                    break
                if w.kind == ItemKind.CHANGE_SPEED or (w.lat_deg == 0.0 and w.lon_deg == 0.0):
                    continue
                points.append(IntentPoint(w.lat_deg, w.lon_deg, w.alt_rel_m + home))
                if w.kind != ItemKind.WAYPOINT:
                    stops = True  # a loiter: it stays there
                    break
                if len(points) == MAX_INTENT_LEGS:
                    break
        if not points and not self._intent_sent:
            return []  # nothing to say, and nothing said
        p = self.profile
        radius = 0.0 if self._hovering(ap) else p.turn_radius_m()
        hold = stops and radius == 0.0  # a fixed-wing circles at its last point
        said = (tuple(points), round(radius, 1), hold)
        if said == self._intent_sent and (not points or now - self._intent_at < INTENT_PERIOD_S):
            return []
        self._intent_sent, self._intent_at = said, now
        speed = p.cruise_speed_m_s if p.cruise_speed_m_s > 0 else ap.groundspeed_m_s
        msg = VehicleIntent(
            p.vehicle_id,
            max(0.0, own.time_unix_s),
            min(max(speed, 0.0), 300.0),
            min(round(radius, 1), 8000.0),
            hold,
            tuple(points),
        )
        self._count("intents")
        return [Publish(msg)]

    def _planned(self, ap: AutopilotState, climb_target: float | None) -> float | None:
        """The altitude to come back to: the mission item's (AUTO), the take-off
        altitude while climbing to it, else where the manoeuvre starts (None)."""
        if ap.mode_name == "AUTO":
            w = self._item(ap.mission_current)
            if w is not None and w.kind != ItemKind.LAND:
                return w.alt_rel_m
            if w is not None:
                return None  # landing: where the manoeuvre starts
        return climb_target

    def _ceiling(
        self, own: VehicleStatus, zones: Mapping[int, NoFlyZone] | None, now: float
    ) -> float | None:
        """The lowest of the zones' floors above (within a turn or two) and the
        airframe's ceiling, above home."""
        home_msl = own.alt_msl_m - own.alt_rel_m
        best: float | None = None
        if zones:  # (none held: no floor above)
            reach = 2.0 * self.profile.turn_radius_m() + 2.0 * self.cfg.protect_m
            floor = ceiling_msl(zones.values(), own.lat_deg, own.lon_deg, own.alt_msl_m, now, reach)
            if floor is not None:
                best = floor - home_msl - 5.0  # stay 5 m under it
        if self.profile.max_altitude_m > 0.0:
            top = self.profile.max_altitude_m - home_msl
            best = top if best is None else min(best, top)
        return best

    def _item(self, seq: int) -> Waypoint | None:
        """The first item with a position at or after mission item `seq` (1 = the first
        uploaded waypoint)."""
        for w in self.items[max(0, seq - 1) :]:
            if w.kind in (ItemKind.CHANGE_SPEED, ItemKind.RTL) or (
                w.lat_deg == 0.0 and w.lon_deg == 0.0
            ):
                continue
            return w
        return None

    # ------------------------------------------------------------------ manoeuvres
    def _hovering(self, ap: AutopilotState) -> bool:
        return hovering(self.profile.vehicle_type, ap.mode_name, ap.groundspeed_m_s)

    def _manoeuvre(self, m: Manoeuvre, ap: AutopilotState, now: float) -> list[ModuleOutput]:
        if m.kind is ManoeuvreKind.RESUME:
            return self._resume(m, ap, now)
        s = self.suspension
        if s is None:
            w = self._item(ap.mission_current) if ap.mode_name == "AUTO" else None
            s = self.suspension = Suspension(
                ap.mode_name,
                ap.mission_current,
                w.alt_rel_m if w is not None and w.kind != ItemKind.LAND else None,
            )
            self._count("suspensions")
        s.resuming = False  # a new conflict while going back: the manoeuvre goes on
        s.resume_tries = 0
        reqs = self._requests(m, ap, s)
        s.last = reqs
        note = Note(logging.WARNING, f"{m.reason} (mode {s.mode}, item {s.item})")
        return [note, Suspend(passing=self._on_path(s)), *self._submit(reqs, now)]

    def _requests(self, m: Manoeuvre, ap: AutopilotState, s: Suspension) -> tuple[ApRequest, ...]:
        if m.kind is ManoeuvreKind.STOP or m.target_alt_rel_m is None:
            return m.requests
        target = m.target_alt_rel_m
        if not self._hovering(ap) or ap.lat_deg is None or ap.lon_deg is None:
            # a fixed-wing keeps flying what it flies, higher: in AUTO its mission's
            # flyable, zone-safe path and schedule, the altitude asked again at each new
            # item. A Goto to its item (as before) cut the turns, circled the item, was
            # resumed past it (a survey's lane skipped) and put a PREMISSION fleet 18 s
            # late at its entries; near a zone it flew into it (measured, both).
            s.via_goto = False
            s.item_seen = ap.mission_current
            return (ChangeAltitude(alt_rel_m=target),)
        s.via_goto = True
        if s.mode == "AUTO":
            w = self._item(s.item)
            if w is not None and w.kind != ItemKind.LAND:
                # on to the item it flew to (its zone-safe leg), higher, and it stops
                # there: braking where it is could overshoot a lane's end towards a zone
                return (Goto(lat_deg=w.lat_deg, lon_deg=w.lon_deg, alt_rel_m=target),)
        return (Goto(lat_deg=ap.lat_deg, lon_deg=ap.lon_deg, alt_rel_m=target),)

    def _resume_item(self, ap: AutopilotState, s: Suspension) -> int:
        """The item to resume the mission at: the one it was flying to, or, for a
        fixed-wing that got there and circled it (inside its turning circle it could
        never come within the acceptance radius again), the next one."""
        item = max(1, s.item)
        w = self._item(item)
        if (
            w is None
            or self.profile.vehicle_type not in (VehicleType.PLANE, VehicleType.VTOL)
            or item >= len(self.items)
            or ap.lat_deg is None
            or ap.lon_deg is None
        ):
            return item
        r = self.profile.turn_radius_m()
        near = max(self.profile.loiter_radius_m, r) + r
        if distance_m(ap.lat_deg, ap.lon_deg, w.lat_deg, w.lon_deg) <= near:
            return item + 1
        return item

    def _resume(self, m: Manoeuvre, ap: AutopilotState, now: float) -> list[ModuleOutput]:
        s = self.suspension
        if s is None:
            return []
        s.resuming = True
        s.resume_tries += 1
        reqs = self._resume_requests(m, ap, s)
        if not reqs:
            return self._end("clear")
        s.last = reqs
        return [
            Note(logging.INFO, f"{m.reason}: {type(reqs[0]).__name__}"),
            Suspend(passing=False),  # the mission's requests wait for the resume
            *self._submit(reqs, now, resume=True),
        ]

    def _resume_requests(
        self, m: Manoeuvre, ap: AutopilotState, s: Suspension
    ) -> tuple[ApRequest, ...]:
        if self._will_steer():
            # the mission asked for somewhere to go meanwhile: that goes next. Not a
            # request that will not reach the autopilot: deferring to one (a Land the
            # pad landing answers, one the holder given control back outranks) left a
            # quadcopter in its manoeuvre's GUIDED for good (test_retasking)
            return ()
        planned = m.target_alt_rel_m
        if not s.via_goto and self.profile.vehicle_type not in GROUND:
            w = self._item(ap.mission_current) if ap.mode_name == "AUTO" else None
            if w is not None and w.kind != ItemKind.LAND:
                return (ChangeAltitude(alt_rel_m=w.alt_rel_m),)  # the item it flies to now
            return m.requests  # ChangeAltitude(planned): it never left what it was doing
        if s.mode == "AUTO":
            return (StartMission(first_item=self._resume_item(ap, s)),)
        if self.profile.vehicle_type in GROUND:
            return (SetMode(mode=s.mode),) if s.mode else ()
        if s.mode in ("RTL", "SMART_RTL"):
            return (ReturnToLaunch(),)
        if s.mode in ("LAND", "QLAND"):
            return (Land(),)
        if s.mode in RESUME_BY_MODE or s.mode in ("QRTL",):
            return (SetMode(mode=s.mode),)
        if planned is not None and ap.lat_deg is not None and ap.lon_deg is not None:
            return (Goto(lat_deg=ap.lat_deg, lon_deg=ap.lon_deg, alt_rel_m=planned),)
        return ()

    def _submit(
        self, reqs: tuple[ApRequest, ...], now: float, resume: bool = False
    ) -> list[ModuleOutput]:
        """Our requests (results come back to `on_result`)."""
        out: list[ModuleOutput] = []
        if self.suspension is not None:
            self.suspension.last_sent_s = now
        for r in reqs:
            rid = next(self._ids)
            req = msgspec.structs.replace(r, request_id=rid)
            self._pending[rid] = req
            if resume:
                self._resume_ids.add(rid)
            out.append(Submit(req, Owner.AVOIDANCE))
        self._count("requests")
        return out

    def on_result(self, result: ApResult, now: float) -> list[ModuleOutput]:
        req = self._pending.pop(result.request_id, None)
        if req is None:
            return []
        was_resume = result.request_id in self._resume_ids
        self._resume_ids.discard(result.request_id)
        s = self.suspension
        out: list[ModuleOutput] = []
        if not result.ok:
            self._count("failed")
            if result.reason.startswith("preempted"):
                return self._give_up(result.reason)
            text = f"avoid: {type(req).__name__} failed: {result.reason}"
            out.append(self._alert(now, Severity.WARNING, text))
            if s is not None and was_resume and s.resuming:
                if s.resume_tries < RESUME_TRIES:
                    s.resume_tries += 1
                    return out + self._submit(s.last, now, resume=True)
                out.append(self._alert(now, Severity.CRITICAL, "avoid: could not resume"))
                return out + self._end("resume failed")
            return out
        if s is not None and s.resuming and not self._resume_ids:
            out += self._end("resumed")
        return out

    def _blocked(self, m: Manoeuvre, holder: Owner | None) -> list[ModuleOutput]:
        if self._blocked_noted or m.kind is ManoeuvreKind.RESUME:
            return []
        self._blocked_noted = True
        name = holder.name if holder is not None else "?"
        return [Note(logging.WARNING, f"{m.reason}: not flown, {name} holds the autopilot")]

    def _give_up(self, why: str) -> list[ModuleOutput]:
        """A higher owner took the autopilot (an emergency): the manoeuvre is dropped
        (the arbiter dropped the suspension and what it held: the emergency stopped the
        mission)."""
        self.avoider.abandon()
        self.suspension = None
        self._pending.clear()
        self._resume_ids.clear()
        return [Note(logging.WARNING, f"avoidance: manoeuvre abandoned ({why})")]

    def _end(self, why: str) -> list[ModuleOutput]:
        """Control given back: the arbiter returns it to whoever held it before and lets
        the mission's held requests go on."""
        s = self.suspension
        self.suspension = None
        self._resume_ids.clear()
        out: list[ModuleOutput] = [Note(logging.INFO, f"avoidance: control given back ({why})")]
        return [Release(Owner.AVOIDANCE), *out] if s is not None else out

    def _alert(self, now: float, severity: Severity, text: str) -> Publish:
        vid = self.profile.vehicle_id
        return Publish(
            Alert(vid, max(0.0, now), severity, AlertCode.COLLISION_RISK, short_text(text))
        )

    def _count(self, what: str) -> None:
        self.counters[what] = self.counters.get(what, 0) + 1
