"""Collision avoidance as a node module: the `CollisionAvoider` fed at 5 Hz, and its
manoeuvres carried out through the arbiter as owner AVOIDANCE while the mission waits.

    inputs (from NodeCore)                      what it does with them
    on_peer(VehicleStatus | VehicleInfo)        a cooperative contact (its type from info)
    forget(vehicle_id)                          a peer lost (membership)
    on_submit(Submit)                           sees the mission uploaded (item positions);
                                                holds the mission's flight requests while
                                                suspended (returns True: held)
    tick(now, own status, autopilot, ...)       feeds the own state, ADS-B traffic
                                                (`AutopilotState.traffic`), the planned
                                                altitude, the zones' ceiling and a
                                                multirotor's route ahead; runs the
                                                avoider's 5 Hz tick; answers with Submits
                                                (owner AVOIDANCE) and Alerts
    on_result(ApResult)                         results of its requests
    release_due / take_held()                   the node gives control back (arbiter) and
                                                routes the held mission requests

Suspending the mission. On the first manoeuvre the module remembers what the vehicle
was doing (its mode, the mission item it was flying to, who held the autopilot) and
takes the autopilot (owner AVOIDANCE: EMERGENCY still pre-empts; OPERATOR and MISSION
requests are refused meanwhile, except the mission's own, which are held here, not
refused, so the sortie never fails for it). The manoeuvre is flown as:

    vehicle                   doing            manoeuvre (to the avoider's target altitude)
    fixed-wing, VTOL flying   AUTO mission     ChangeAltitude: the mission flown on along
                                               its flyable, zone-safe path at the new
                                               altitude (asked again at each new item);
                                               the mission's requests go on under it
    fixed-wing, VTOL flying   anything else    ChangeAltitude (keeps RTL, LOITER, GUIDED)
    multirotor, VTOL hovering AUTO mission     Goto the item it was flying to, higher
                                               (GUIDED): on its zone-safe leg, stopping
                                               there; the mission is suspended
    multirotor, VTOL hovering anything else    Goto over itself (GUIDED: holds, climbs)
    rover, boat               anything         HOLD mode (stops)

When the avoider says clear (RESUME), the vehicle goes back to what it was doing: the
mission's held requests if it asked where to go meanwhile (its newest intent) and one
of them will reach the autopilot (`_goes_on`: not a speed, not a Land the pad landing
answers itself, not one the arbiter will refuse; those go on after the resume); else a fixed-wing
changes altitude back to its mission item's (or the planned one), and the others go
back by the mode they were in: AUTO -> StartMission(first_item = the item they were
flying to), RTL -> ReturnToLaunch, QRTL, LOITER and the like -> that mode again,
LAND/QLAND -> Land, GUIDED (a take-off climb, an operator's Goto) -> Goto over itself
at the planned altitude. Once those requests are answered, control goes back to
whoever held it before (`release_due`).

The wire MissionState has no SUSPENDED (adding one would change every node's radio
decoder): a suspended vehicle keeps publishing MISSION (or PREMISSION), its progress
held, with AlertFlag.COLLISION_RISK set in its status; the Alerts say what it does.

Pure: no I/O; `now` is passed in.
"""

from __future__ import annotations

import itertools
import logging
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field

import msgspec

from swarm_proto import (
    Alert,
    AlertCode,
    GeoPoint,
    NoFlyZone,
    Severity,
    VehicleInfo,
    VehicleStatus,
    VehicleType,
)
from swarm_proto.geodesy import distance_m
from swarm_proto.text import short_text

from ..arbiter import Routed, flies
from ..autopilot.items import ItemKind, Waypoint
from ..autopilot.requests import (
    ApRequest,
    ApResult,
    Arm,
    ChangeAltitude,
    ChangeSpeed,
    Goto,
    Land,
    ReturnToLaunch,
    SetMode,
    StartMission,
    UploadMission,
)
from ..autopilot.state import AutopilotState
from ..outputs import ModuleOutput, Note, Owner, Publish, Submit
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
    PlannedAltitude,
    Traffic,
)
from .pads import PadConfig, hold_layer, may_move
from .zones import ceiling_msl

LOWERED_M = 5.0  # a fixed-wing circling down to its lowest layer is there within this
HOVER_SPEED_M_S = 8.0  # a VTOL slower than this is hovering (it manoeuvres as a multirotor)
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


#: how long after the mission's StartMission the autopilot's state may still show the
#: mode before it (the command's ack, then the next heartbeat; simulated seconds)
START_SEEN_S = 3.0


def steers(req: ApRequest) -> bool:
    """Whether a held mission request says where the vehicle goes (a new mission, a
    mode, a return...): it then replaces the module's own resume. A speed does not: the
    PREMISSION and MISSION speed rule's ChangeSpeed, held while suspended, goes on after
    the mission is resumed (measured: taken for the mission's newest intent, it left two
    VTOLs circling their avoidance Goto in GUIDED for good)."""
    return not isinstance(req, ChangeSpeed)


@dataclass(slots=True)
class Suspension:
    """What the vehicle was doing when avoidance took the autopilot."""

    mode: str
    item: int  # MISSION_CURRENT then (the item it was flying to)
    planned_rel_m: float | None
    holder: Owner | None  # who held the autopilot before
    via_goto: bool = False  # the manoeuvre flies Goto (GUIDED), not ChangeAltitude
    last: tuple[ApRequest, ...] = ()
    last_sent_s: float = 0.0
    resuming: bool = False
    resume_tries: int = 0
    item_seen: int = 0  # a ChangeAltitude is asked again when the mission item moves on


@dataclass(slots=True)
class PadLanding:
    """Landing on the own pad: the return flown to above it at the holding layer, a hold
    there (`hold_seq`) until the pad is clear, then the landing item (`land_seq`)."""

    pad: GeoPoint
    hold_seq: int
    land_seq: int
    hold_alt_rel_m: float
    owner: Owner
    descending: bool = False
    lowering: bool = False  # a fixed-wing circles down to the lowest layer first
    waited_since: float | None = None
    upload_id: int | None = None  # the mission's return upload it was made of


Intercepted = tuple[list[ModuleOutput], Routed | None]  # replacement requests, an answer


@dataclass
class AvoidanceModule:
    profile: VehicleProfile
    enabled: bool = True
    config: AvoidanceConfig | None = None
    suspension: Suspension | None = None
    held: list[Submit] = field(default_factory=list)
    items: tuple[Waypoint, ...] = ()  # the mission the autopilot holds (items 1..)
    release_due: bool = False  # the node releases AVOIDANCE, gives `restore` control back
    restore: Owner | None = None
    pad_config: PadConfig = field(default_factory=PadConfig)
    pads_on: bool = True  # take-off and landing deconfliction (pads.py)
    launch: Submit | None = None  # the mission's Arm, held until the pad is clear
    landing: PadLanding | None = None
    # every known vehicle's home, asked for when a pad rule needs it (not at every tick)
    _pads_of: Callable[[], Mapping[int, GeoPoint]] = dict
    _types: dict[int, VehicleType] = field(default_factory=dict)  # from VehicleInfo
    _zones: list[NoFlyZone] = field(default_factory=list)  # the no-fly zones in force
    _peers_of: Callable[[], Iterable[tuple[VehicleStatus, GeoPoint | None]]] = list
    _launch_waited: float | None = None
    _next_tick: float = 0.0  # the first tick at once
    counters: dict[str, int] = field(default_factory=dict)
    _pending: dict[int, ApRequest] = field(default_factory=dict)
    _resume_ids: set[int] = field(default_factory=set)
    _pad_ids: set[int] = field(default_factory=set)
    _traffic_seen: dict[int, float] = field(default_factory=dict)
    _blocked_noted: bool = False
    _ids: itertools.count[int] = field(default_factory=lambda: itertools.count(1))
    #: the mission's last StartMission passed on, and when: a manoeuvre that begins
    #: before the autopilot shows AUTO must go back to it, not to the mode it saw
    _started: tuple[Submit, float] | None = None

    def __post_init__(self) -> None:
        p = self.profile
        self.cfg = self.config or AvoidanceConfig(
            own_id=p.vehicle_id,
            own_type=p.vehicle_type,
            climb_rate_m_s=p.climb_rate_m_s if p.climb_rate_m_s > 0 else 5.0,
        )
        self.avoider = CollisionAvoider(self.cfg)

    # ------------------------------------------------------------------ views
    @property
    def active(self) -> bool:
        """Avoidance holds (or is giving back) the autopilot."""
        return self.suspension is not None

    def next_deadline(self) -> float | None:
        """The next 5 Hz tick (None: the module is off)."""
        return self._next_tick if self.enabled else None

    # ------------------------------------------------------------------ inputs
    def on_peer(self, msg: VehicleStatus | VehicleInfo, now: float) -> None:
        if self.enabled and msg.vehicle_id != self.profile.vehicle_id:
            if type(msg) is VehicleStatus:  # 5 Hz per peer: the avoider's hot path
                self.avoider.heard(msg, now)
                return
            self.avoider.handle(msg, now)
            if isinstance(msg, VehicleInfo):
                self._types[msg.vehicle_id] = msg.vehicle_type

    def on_peers(
        self, msgs: Sequence[VehicleStatus | VehicleInfo], now: float, statuses: int
    ) -> None:
        """`on_peer` for each of peers' `msgs` (none of them ours; `statuses` of them
        are VehicleStatus), at once."""
        if self.enabled:
            only = statuses == len(msgs)
            self.avoider.heard_all(msgs, now, statuses_only=only)
            if not only:
                for m in msgs:
                    if type(m) is VehicleInfo:
                        self._types[m.vehicle_id] = m.vehicle_type

    def forget(self, vehicle_id: int, now: float) -> None:
        if self.enabled:
            self.avoider.handle(Forget(vehicle_id), now)

    def on_submit(self, o: Submit, ap: AutopilotState, now: float) -> Intercepted | None:
        """Every request the node is about to pass to the arbiter. None: pass it on.
        Otherwise (replacement requests, an answer to route to the asker now): the
        mission's launch held until the pad is clear, its return turned into a landing
        on the own pad, its flight requests held while avoidance flies."""
        if not self.enabled:
            return None
        if o.owner == Owner.AVOIDANCE and o.route == Owner.MISSION:
            return None  # the mission's, passed on under a manoeuvre flown on its path
        mine = (o.route or o.owner) == Owner.MISSION
        req = original = o.request
        if isinstance(req, UploadMission) and mine:
            if (
                self.pads_on
                and self._lands_on_pad()
                and req.items
                and req.items[-1].kind == ItemKind.RTL
            ):
                o = self._pad_return(o, req, ap, now)  # zone-safe legs home, then the pad
                req = o.request
                assert isinstance(req, UploadMission)
            elif self.landing is not None and req.request_id not in (
                *self._pad_ids,
                self.landing.upload_id,
            ):
                # a new mission replaces the return (a vehicle sent on again on its way
                # home): its landing is over. Kept, its gate fired in the new mission at
                # the old hold's item number (measured in the demo: the route's leg was
                # sent down towards 30 m, and once below 35 m it would have been sent to
                # the old landing's item)
                self.landing = None
            self.items = req.items
        s = self.suspension
        if s is not None and mine and flies(req) and self._on_path(s):
            # a fixed-wing flies its manoeuvre on its mission's path (ChangeAltitude): what
            # the mission asks goes on at once, ranked as the manoeuvre (the arbiter would
            # refuse MISSION), and the manoeuvre's altitude is asked again at its next
            # item. Held instead, a fleet stacked at one point (a route's end) would hold
            # its way home for ever: the conflict never clears while it circles there.
            self._count("passed")
            took = self._mission_request(o, req, ap, now)
            subs, answer = took if took is not None else ([o], None)
            return [self._ranked(x) for x in subs], answer
        if s is not None and mine and flies(req):
            if isinstance(req, ChangeSpeed):
                # the speed rule asks every second: only its newest goes on (a
                # superseded one is not answered; the manager does not wait on them)
                self.held = [h for h in self.held if not isinstance(h.request, ChangeSpeed)]
            self.held.append(o)
            self._count("held")
            return [], None
        if mine and s is None and isinstance(req, StartMission):
            self._started = (o, now)
        if not mine or not self.pads_on or self.suspension is not None:
            return ([o], None) if o.request is not original else None
        took = self._mission_request(o, req, ap, now)
        if took is not None:
            return took
        return ([o], None) if o.request is not original else None

    def _on_path(self, s: Suspension) -> bool:
        """The manoeuvre is an altitude flown on what the vehicle flies (a fixed-wing's
        ChangeAltitude), not a Goto that suspends it."""
        return not s.via_goto and self._aircraft() and not s.resuming

    def _ranked(self, o: ModuleOutput) -> ModuleOutput:
        """A request of the mission (or of its landing on the pad) passed on while a
        manoeuvre holds the autopilot: ranked as AVOIDANCE, its result still routed to
        whoever asked."""
        if isinstance(o, Submit) and o.owner == Owner.MISSION:
            return Submit(o.request, Owner.AVOIDANCE, o.route or Owner.MISSION)
        return o

    def _mission_request(
        self, o: Submit, req: ApRequest, ap: AutopilotState, now: float
    ) -> Intercepted | None:
        """The pads' handling of the mission's launch, return and landing (None: as
        asked)."""
        if not self.pads_on:
            return None
        if isinstance(req, Arm) and self._aircraft() and not ap.armed:
            if self._launch_blockers(ap):
                self.launch = o
                self._launch_waited = now
                self._count("launch_held")
                return [Note(logging.INFO, f"take-off: waiting ({self._launch_why})")], None
            return None
        if isinstance(req, ReturnToLaunch) and self._lands_on_pad() and ap.armed:
            return self._pad_rtl(o, ap, now)
        if self._answered_here(req):
            # the landing on the pad is already on its way: answered at once
            return [], Routed(
                o.route or o.owner, ApResult(req.request_id, True, "landing on its pad")
            )
        return None

    def _answered_here(self, req: ApRequest) -> bool:
        """A mission request this module answers itself, sending nothing to the
        autopilot: the mission manager's Land while the landing on the pad flies."""
        return isinstance(req, Land) and self.landing is not None

    def _goes_on(self, h: Submit, s: Suspension) -> bool:
        """Whether a held mission request, passed on once control is given back, will
        reach the autopilot and say where the vehicle goes: then it replaces the
        module's own resume. Not a speed (`steers`), not a request this module answers
        itself (a Land during the landing on the pad), not one the arbiter will refuse
        (the holder given control back outranks it). Deferring to one of those left a
        quadcopter in its manoeuvre's GUIDED for good (test_retasking)."""
        return (
            steers(h.request)
            and not self._answered_here(h.request)
            and not (s.holder is not None and s.holder > h.owner)
        )

    # ------------------------------------------------------------------ pads
    def _aircraft(self) -> bool:
        return self.profile.vehicle_type not in GROUND

    def _lands_on_pad(self) -> bool:
        return self.profile.vehicle_type in (VehicleType.COPTER, VehicleType.VTOL)

    def _launch_blockers(self, ap: AutopilotState) -> bool:
        pad = ap.home
        if pad is None:
            return False
        blockers = may_move(
            self.profile.vehicle_id, pad, self._peers_of(), taking_off=True, config=self.pad_config
        )
        self._launch_why = ", ".join(b.why for b in blockers)
        return bool(blockers)

    def _hold_alt(self, pad: GeoPoint) -> float:
        pads = dict(self._pads_of())
        pads[self.profile.vehicle_id] = pad
        types = {**self._types, self.profile.vehicle_id: self.profile.vehicle_type}
        wings = {v for v, t in types.items() if t in (VehicleType.PLANE, VehicleType.VTOL)}
        hover = {v for v, t in types.items() if t == VehicleType.COPTER}
        return hold_layer(self.profile.vehicle_id, pad, pads, self.pad_config, wings, hover)

    def _pad_items(self, pad: GeoPoint, hold: float) -> tuple[Waypoint, Waypoint]:
        return (
            Waypoint(ItemKind.LOITER_UNLIMITED, pad.lat_deg, pad.lon_deg, hold),
            Waypoint(ItemKind.LAND, pad.lat_deg, pad.lon_deg, 0.0),
        )

    def _pad_return(self, o: Submit, req: UploadMission, ap: AutopilotState, now: float) -> Submit:
        """The mission manager's zone-safe way home (legs, then RTL): the legs, then a
        hold over the own pad at the holding layer and the landing there."""
        pad = ap.home
        if pad is None:
            return o
        hold = self._hold_alt(pad)
        legs = req.items[:-1]
        items = (*legs, *self._pad_items(pad, hold))
        self.landing = PadLanding(
            pad, len(legs) + 1, len(legs) + 2, hold, o.owner, upload_id=req.request_id
        )
        self._count("pad_returns")
        return Submit(msgspec.structs.replace(req, items=items), o.owner, o.route)

    def _pad_rtl(self, o: Submit, ap: AutopilotState, now: float) -> Intercepted:
        """The mission manager's plain RTL (nothing in the way home): flown as a mission
        to above the own pad at the holding layer, a hold there and the landing; the RTL
        is answered at once."""
        pad = ap.home
        if pad is None or ap.lat_deg is None or ap.lon_deg is None:
            return [o], None
        hold = self._hold_alt(pad)
        there = Waypoint(ItemKind.WAYPOINT, pad.lat_deg, pad.lon_deg, hold)
        items = (there, *self._pad_items(pad, hold))
        self.landing = PadLanding(pad, 2, 3, hold, o.owner)
        self.items = items
        self._count("pad_returns")
        reqs = (UploadMission(items=items), StartMission(first_item=1))
        answer = Routed(o.route or o.owner, ApResult(o.request.request_id, True, "home to its pad"))
        note = Note(logging.INFO, f"return: to its pad, holding at {hold:.0f} m")
        return [note, *self._submit(reqs, now, owner=o.owner)], answer

    def _pads_tick(self, ap: AutopilotState, now: float) -> list[ModuleOutput]:
        out: list[ModuleOutput] = []
        if self.launch is not None and not self._launch_blockers(ap):
            waited = now - (self._launch_waited or now)
            out += [Note(logging.INFO, f"take-off: pad clear after {waited:.1f} s"), self.launch]
            self.launch = None
        ld = self.landing
        if ld is None:
            return out
        if not ap.armed and (ap.alt_rel_m or 0.0) < self.pad_config.airborne_m:
            self.landing = None  # down
            return out
        low = self.pad_config.hold_alt_rel_m + LOWERED_M
        if ld.lowering and self.suspension is None and (ap.alt_rel_m or 0.0) <= low:
            ld.lowering = False
            out.append(Note(logging.INFO, "landing: down to the lowest layer, on to the pad"))
            return out + self._submit((StartMission(first_item=ld.land_seq),), now, owner=ld.owner)
        if (
            ld.descending
            or self.suspension is not None
            or ap.mode_name != "AUTO"
            or ap.mission_current != ld.hold_seq
            or ap.lat_deg is None
            or ap.lon_deg is None
        ):
            return out
        blockers = may_move(
            self.profile.vehicle_id,
            ld.pad,
            self._peers_of(),
            taking_off=False,
            config=self.pad_config,
            own_alt_msl_m=ap.alt_msl_m,
            own_circles=not self._hovering(ap),
        )
        if blockers:
            if ld.waited_since is None:
                ld.waited_since = now
                why = ", ".join(b.why for b in blockers)
                out.append(
                    Note(logging.INFO, f"landing: holding at {ld.hold_alt_rel_m:.0f} m ({why})")
                )
            return out
        ld.descending = True
        waited = now - ld.waited_since if ld.waited_since is not None else 0.0
        out.append(Note(logging.INFO, f"landing: on its pad (waited {waited:.1f} s)"))
        if not self._hovering(ap) and (ap.alt_rel_m or 0.0) > low:
            # a fixed-wing circles down in its hold first (a landing leg started high
            # would dive at it)
            ld.lowering = True
            step = ChangeAltitude(alt_rel_m=self.pad_config.hold_alt_rel_m)
            return out + self._submit((step,), now, owner=ld.owner)
        return out + self._submit((StartMission(first_item=ld.land_seq),), now, owner=ld.owner)

    def take_held(self) -> list[ModuleOutput]:
        held, self.held = self.held, []
        return list(held)

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
        pads: Mapping[int, GeoPoint] | Callable[[], Mapping[int, GeoPoint]] | None = None,
        peers: Iterable[tuple[VehicleStatus, GeoPoint | None]]
        | Callable[[], Iterable[tuple[VehicleStatus, GeoPoint | None]]] = (),
    ) -> list[ModuleOutput]:
        """The 5 Hz tick (when `next_deadline` is due). `climb_target_rel_m`: the
        take-off altitude while the mission manager climbs to it; `holder`: who holds
        the autopilot now (the arbiter's); `pads`: every known vehicle's home; `peers`:
        the peers' latest statuses with their homes. Each of the last two may be a
        function giving it, asked only when a take-off or landing needs it (a swarm's
        size is not walked at 5 Hz)."""
        if not self.enabled or now < self._next_tick:
            return []
        period = self.cfg.period_s
        nxt = self._next_tick + period
        self._next_tick = nxt if nxt > now else now + period  # late: no catch-up burst
        if callable(pads):
            self._pads_of = pads
        else:
            held_pads = dict(pads or {})
            self._pads_of = lambda: held_pads
        if callable(peers):
            self._peers_of = peers
        else:
            held_peers = list(peers)
            self._peers_of = lambda: held_peers
        self._zones = [
            z for z in (zones or {}).values() if z.in_force(now) and not z.operating_area
        ]
        pad_out = self._pads_tick(ap, now) if self.pads_on else []
        av = self.avoider
        if own is not None:
            av.handle(own, now)
            av.handle(PlannedAltitude(self._planned(ap, climb_target_rel_m)), now)
            av.handle(Ceiling(self._ceiling(own, zones, now)), now)
            av.handle(self._route(ap), now)
        for r in ap.traffic:
            if self._traffic_seen.get(r.icao_address) != r.time_s:
                self._traffic_seen[r.icao_address] = r.time_s
                av.handle(Traffic.from_report(r), now)
        self._count("ticks")
        blocked = holder is not None and holder > Owner.AVOIDANCE
        out: list[ModuleOutput] = pad_out
        for o in av.on_timer(now):
            if isinstance(o, Alert):
                out.append(Publish(o))
            elif blocked:
                out += self._blocked(o, holder)
            else:
                out += self._manoeuvre(o, ap, now, holder)
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
        return out

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
        """A multirotor, or a VTOL hovering outside its mission (a take-off climb, QLOITER):
        in AUTO a VTOL counts as the fixed-wing it flies as (slow only in a transition)."""
        vt = self.profile.vehicle_type
        if vt == VehicleType.COPTER:
            return True
        return (
            vt == VehicleType.VTOL
            and ap.mode_name != "AUTO"
            and ap.groundspeed_m_s < HOVER_SPEED_M_S
        )

    def _manoeuvre(
        self, m: Manoeuvre, ap: AutopilotState, now: float, holder: Owner | None
    ) -> list[ModuleOutput]:
        if m.kind is ManoeuvreKind.RESUME:
            return self._resume(m, ap, now)
        s = self.suspension
        if s is None:
            w = self._item(ap.mission_current) if ap.mode_name == "AUTO" else None
            s = self.suspension = Suspension(
                ap.mode_name,
                ap.mission_current,
                w.alt_rel_m if w is not None and w.kind != ItemKind.LAND else None,
                holder if holder not in (None, Owner.AVOIDANCE) else None,
            )
            self._count("suspensions")
            started, self._started = self._started, None
            if started is not None and now - started[1] <= START_SEEN_S and ap.mode_name != "AUTO":
                # the mission was just started, and the autopilot's state does not show
                # it yet (a PREMISSION leg, sent as a VTOL's climb was levelled at its
                # pad): the resume would put it back in GUIDED over the pad for good
                # (a mixed demo's VTOL hovered there until the story timed out)
                self.held.append(started[0])
        s.resuming = False  # a new conflict while going back: the manoeuvre goes on
        s.resume_tries = 0
        reqs = self._requests(m, ap, s)
        s.last = reqs
        note = Note(logging.WARNING, f"{m.reason} (mode {s.mode}, item {s.item})")
        return [note, *self._submit(reqs, now)]

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
            *self._submit(reqs, now, resume=True),
        ]

    def _resume_requests(
        self, m: Manoeuvre, ap: AutopilotState, s: Suspension
    ) -> tuple[ApRequest, ...]:
        if any(self._goes_on(h, s) for h in self.held):
            return ()  # the mission asked for something else meanwhile: that goes next
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
        self,
        reqs: tuple[ApRequest, ...],
        now: float,
        resume: bool = False,
        owner: Owner = Owner.AVOIDANCE,
    ) -> list[ModuleOutput]:
        """Our requests (results come back to `on_result`), ranked as `owner`."""
        out: list[ModuleOutput] = []
        if self.suspension is not None and owner == Owner.AVOIDANCE:
            self.suspension.last_sent_s = now
        for r in reqs:
            rid = next(self._ids)
            req = msgspec.structs.replace(r, request_id=rid)
            self._pending[rid] = req
            if resume:
                self._resume_ids.add(rid)
            rank = owner
            if owner != Owner.AVOIDANCE:
                self._pad_ids.add(rid)
                if self.suspension is not None:
                    rank = Owner.AVOIDANCE  # the arbiter would refuse MISSION meanwhile
            out.append(Submit(req, rank, Owner.AVOIDANCE))
        self._count("requests")
        return out

    def on_result(self, result: ApResult, now: float) -> list[ModuleOutput]:
        req = self._pending.pop(result.request_id, None)
        if req is None:
            return []
        if result.request_id in self._pad_ids:
            return self._pad_result(req, result, now)
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

    def _pad_result(self, req: ApRequest, result: ApResult, now: float) -> list[ModuleOutput]:
        """A request of the landing on the pad: a failure falls back to plain RTL."""
        self._pad_ids.discard(result.request_id)
        if result.ok:
            return []
        self._count("failed")
        ld, self.landing = self.landing, None
        text = f"landing on pad: {type(req).__name__} failed, RTL ({result.reason})"
        out: list[ModuleOutput] = [self._alert(now, Severity.WARNING, text)]
        if ld is not None:
            rtl = msgspec.structs.replace(ReturnToLaunch(), request_id=next(self._ids))
            out.append(Submit(rtl, ld.owner, Owner.AVOIDANCE))  # its result is not tracked
        return out

    def _blocked(self, m: Manoeuvre, holder: Owner | None) -> list[ModuleOutput]:
        if self._blocked_noted or m.kind is ManoeuvreKind.RESUME:
            return []
        self._blocked_noted = True
        name = holder.name if holder is not None else "?"
        return [Note(logging.WARNING, f"{m.reason}: not flown, {name} holds the autopilot")]

    def _give_up(self, why: str) -> list[ModuleOutput]:
        """A higher owner took the autopilot (an emergency): the manoeuvre and the held
        mission requests are dropped (the emergency stopped the mission)."""
        self.avoider.abandon()
        self.suspension, self.held = None, []
        self._pending.clear()
        self._resume_ids.clear()
        return [Note(logging.WARNING, f"avoidance: manoeuvre abandoned ({why})")]

    def _end(self, why: str) -> list[ModuleOutput]:
        s = self.suspension
        ld = self.landing
        if s is not None and ld is not None:
            # a manoeuvre during the landing took it off its way down: the pad's gate
            # starts the descent again (a fixed-wing would circle its hold layer for good)
            ld.descending = ld.lowering = False
            ld.waited_since = None
        self.release_due = s is not None
        self.restore = s.holder if s is not None else None
        self.suspension = None
        self._resume_ids.clear()
        return [Note(logging.INFO, f"avoidance: control given back ({why})")]

    def _alert(self, now: float, severity: Severity, text: str) -> Publish:
        vid = self.profile.vehicle_id
        return Publish(
            Alert(vid, max(0.0, now), severity, AlertCode.COLLISION_RISK, short_text(text))
        )

    def _count(self, what: str) -> None:
        self.counters[what] = self.counters.get(what, 0) + 1
