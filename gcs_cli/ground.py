"""The ground station as a library: one Zenoh session that watches the fleet and
sends commands, missions and zones, waiting for the vehicles' acks. The `gcs` command
line and the demo are thin layers over it.

The ground station is a swarm node too (paper section 3): it declares its liveliness
token and publishes a VehicleInfo of type GCS, so vehicles list it among their peers.
It checks who speaks in each vehicle's name as the nodes do (swarm_node core/identity.py):
a vehicle heard from two sources is `untrusted` in its view, and only the source first
heard is shown for it.
"""

from __future__ import annotations

import logging
import queue
import threading
import time
from collections import deque
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from typing import Any, TypeVar

import msgspec

from swarm_node.core.identity import IdentityBook
from swarm_proto import (
    Ack,
    AckRef,
    Alert,
    AlertCode,
    AlertFlag,
    Command,
    CommandArgs,
    CommandKind,
    DeclaredState,
    FsmState,
    Mission,
    NoFlyZone,
    Selector,
    SelectorKind,
    SwarmView,
    VehicleInfo,
    VehicleStatus,
    VehicleType,
    lan,
    validate,
)
from swarm_proto.errors import DecodeError
from swarm_proto.intake import Source
from swarm_proto.session import SwarmBus, ZenohSettings
from swarm_proto.topics import ACK, ALERT, ALIVE, DECLARED, INFO, MISSIONS, PEERS, STATUS, ZONES

from .core.exchange import (
    Exchange,
    Finished,
    Heard,
    Known,
    Outcome,
    Request,
    Seen,
    Send,
    Verdict,
    known_from,
)

DEFAULT_GCS_ID = 900
T = TypeVar("T", bound=msgspec.Struct)


REPEAT_S = 1.0  # commands and missions are sent again this often until answered
DISCOVER_RETRY_S = 0.2  # an empty liveliness answer asked again after this
DISCOVER_S = 2.0  # a fresh ground station's window to hear the vehicles that are alive
HEARD_ALIVE_S = 5.0  # a vehicle heard this recently counts as alive (behind the radio)
RATE_WINDOW_S = 2.0  # packets per second are counted over this window


def stamp_zone(zone: NoFlyZone) -> NoFlyZone:
    """The zone with its declaration time (the ground station's clock) if it has none."""
    if zone.time_unix_s > 0.0:
        return zone
    return msgspec.structs.replace(zone, time_unix_s=max(0.0, time.time()))


def new_seq() -> int:
    """A command sequence number that increases across runs without stored state:
    milliseconds since 2024-01-01, modulo 2^32 (wraps after 49 days)."""
    return int((time.time() - 1_704_067_200) * 1000) % (1 << 32)


#: a mission's answer is the fleet's verdict on its plan: the members synchronise and
#: plan first (a large area takes seconds on a loaded companion computer); a vehicle's
#: plan timeout is 60 s. The exchange ends as soon as every addressed vehicle answered.
MISSION_TIMEOUT_S = 60.0


@dataclass
class FleetView:
    """The latest of everything heard from each vehicle."""

    status: dict[int, VehicleStatus] = field(default_factory=dict)
    info: dict[int, VehicleInfo] = field(default_factory=dict)
    heard_at: dict[int, float] = field(default_factory=dict)  # monotonic seconds
    alive: set[int] = field(default_factory=set)
    alerts: deque[Alert] = field(default_factory=lambda: deque(maxlen=200))
    acks: list[Ack] = field(default_factory=list)
    arrivals: dict[int, deque[float]] = field(default_factory=dict)  # monotonic, per vehicle
    untrusted: dict[int, str] = field(default_factory=dict)  # heard from two sources: why

    def packets_per_s(self, vid: int, now: float) -> float:
        """Messages heard from a vehicle per second over the last RATE_WINDOW_S (the
        paper's "packets received in the preceding second")."""
        times = self.arrivals.get(vid, ())
        return sum(now - t <= RATE_WINDOW_S for t in times) / RATE_WINDOW_S

    def vehicle_ids(self) -> list[int]:
        ids = set(self.status) | set(self.info) | self.alive
        return sorted(i for i in ids if self.type_of(i) != VehicleType.GCS)

    def type_of(self, vid: int) -> VehicleType:
        info = self.info.get(vid)
        return info.vehicle_type if info else VehicleType.OTHER

    def fsm_state(self, vid: int) -> FsmState:
        if vid in self.status:
            return self.status[vid].fsm_state
        info = self.info.get(vid)
        return info.fsm_state if info else FsmState.INACTIVE


class GroundStation:
    def __init__(
        self,
        settings: ZenohSettings,
        swarm: str = "default",
        gcs_id: int = DEFAULT_GCS_ID,
        *,
        announce: bool = True,
        database_ids: Iterable[int] | None = None,
    ) -> None:
        self.gcs_id = gcs_id
        # the systems of the swarm database (None: no database read): whom --all may miss
        self.database_ids = frozenset(database_ids) if database_ids is not None else None
        self.repeat_s = REPEAT_S
        self.swarm = swarm
        self.view = FleetView()
        self._lock = threading.Lock()
        self._changed = threading.Condition(self._lock)
        self._feeds: list[queue.SimpleQueue[VehicleStatus]] = []
        self.bus = SwarmBus.open(settings, swarm)
        self.identity = IdentityBook(gcs_id, self.bus.zid)
        self.bus.subscribe_sourced(STATUS, self._on_status)
        self.bus.subscribe_sourced(INFO, self._on_info)
        self.bus.subscribe(ALERT, self._on_alert)
        self.bus.subscribe(ACK, self._on_ack)
        self.bus.watch_alive(self._on_alive)
        self._stop = threading.Event()
        self._announcer: threading.Thread | None = None
        if announce:
            self.bus.declare_alive(gcs_id)
            self._announcer = threading.Thread(target=self._announce, name="gcs-info", daemon=True)
            self._announcer.start()

    # ------------------------------------------------------------------ inputs
    def _touch(self, vid: int) -> None:
        now = time.monotonic()
        self.view.heard_at[vid] = now
        times = self.view.arrivals.setdefault(vid, deque(maxlen=200))
        times.append(now)
        self._changed.notify_all()

    def _trusted(
        self, msg: VehicleStatus | VehicleInfo, source: Source, now: float, *, sysid: int = 0
    ) -> bool:
        """The identity book's verdict on a vehicle's telemetry (under the lock)."""
        book = self.identity
        if isinstance(msg, VehicleStatus):
            conflict = bool(msg.alerts & AlertFlag.IDENTITY_CONFLICT)
            ground = False
        else:
            conflict = AlertCode.IDENTITY_CONFLICT in msg.errors
            ground = msg.vehicle_type == VehicleType.GCS
        due = book.next_deadline()
        if due is not None and now >= due:
            book.on_timer(now)
        keep, _ = book.heard(
            msg.vehicle_id, source, now, sysid=sysid, reports_conflict=conflict, ground=ground
        )
        self.view.untrusted = {v: book.why(v) for v in book.untrusted}
        return keep

    def _on_status(self, msg: VehicleStatus, key: str, source: Source) -> None:
        with self._lock:
            if not self._trusted(msg, source, time.monotonic()):
                return
            self.view.status[msg.vehicle_id] = msg
            self._touch(msg.vehicle_id)
            for feed in self._feeds:
                feed.put(msg)

    def status_feed(self) -> queue.SimpleQueue[VehicleStatus]:
        """Every VehicleStatus heard from now on, in order (a flight recorder)."""
        feed: queue.SimpleQueue[VehicleStatus] = queue.SimpleQueue()
        with self._lock:
            self._feeds.append(feed)
        return feed

    def _on_info(self, msg: VehicleInfo, key: str, source: Source) -> None:
        with self._lock:
            if not self._trusted(msg, source, time.monotonic(), sysid=msg.mav_sysid):
                return
            self.view.info[msg.vehicle_id] = msg
            self._touch(msg.vehicle_id)

    def _on_alert(self, msg: Alert, key: str) -> None:
        with self._lock:
            self.view.alerts.append(msg)
            self._changed.notify_all()

    def _on_ack(self, msg: Ack, key: str) -> None:
        with self._lock:
            if msg.issuer_id == self.gcs_id:
                self.view.acks.append(msg)
                self._changed.notify_all()

    def _on_alive(self, node_id: int, alive: bool) -> None:
        if node_id == self.gcs_id:
            return  # our own token: not a vehicle to wait for
        with self._lock:
            (self.view.alive.add if alive else self.view.alive.discard)(node_id)
            self._changed.notify_all()

    def _announce(self) -> None:
        info = VehicleInfo(self.gcs_id, VehicleType.GCS, "Ground Station", f"GCS-{self.gcs_id}")
        while not self._stop.wait(1.0):
            try:
                self.bus.publish(info)
            except Exception as exc:  # the session closed (zenoh.ZError) under it
                if not self._stop.is_set():
                    logging.getLogger(__name__).warning("ground station info stopped: %s", exc)
                return

    # ------------------------------------------------------------------ waiting
    def wait_for(self, predicate: Callable[[FleetView], bool], timeout_s: float) -> bool:
        """Block until predicate(view) holds (checked on every update), or timeout."""
        end = time.monotonic() + timeout_s
        with self._lock:
            while not predicate(self.view):
                left = end - time.monotonic()
                if left <= 0:
                    return False
                self._changed.wait(min(left, 0.5))
            return True

    def snapshot(self) -> FleetView:
        with self._lock:
            return FleetView(
                dict(self.view.status),
                dict(self.view.info),
                dict(self.view.heard_at),
                set(self.view.alive),
                deque(self.view.alerts, maxlen=200),
                list(self.view.acks),
                {v: deque(t, maxlen=200) for v, t in self.view.arrivals.items()},
                dict(self.view.untrusted),
            )

    # ------------------------------------------------------------------ the fleet known
    def known(self) -> list[Known]:
        """Every vehicle the ground station knows of (exchange.py): alive by its
        liveliness token or heard in the last `HEARD_ALIVE_S` (a vehicle behind the
        radio is heard, its token may not cross), its fleet from its telemetry, and
        every system of the swarm database (`database_ids`)."""
        now = time.monotonic()
        with self._lock:
            v = self.view
            heard = {i for i, t in v.heard_at.items() if now - t <= HEARD_ALIVE_S}
            alive = {i for i in (v.alive | heard) if v.type_of(i) != VehicleType.GCS}
            fleets = {i: s.fleet_id for i, s in v.status.items()}
            fleets.update({i: info.fleet_id for i, info in v.info.items() if i not in fleets})
            ground = {i for i in v.info if v.type_of(i) == VehicleType.GCS}
        db = set(self.database_ids or ()) - ground
        return [
            k
            for k in known_from(alive, fleets, db)
            if k.vehicle_id not in ground and k.vehicle_id != self.gcs_id
        ]

    # ------------------------------------------------------------------ sending
    def exchange(
        self,
        msg: msgspec.Struct,
        request: Request,
        timeout_s: float,
        progress: Callable[[Exchange, float], None] | None = None,
    ) -> Outcome:
        """Send `msg` and account for every answer (the pure `Exchange` decides whom it
        addresses, when to send again and when it is over; this shell publishes,
        feeds it the acks and the membership news, and waits)."""
        validate(msg)
        with self._lock:
            cursor = len(self.view.acks)
        now = time.monotonic()
        known = {k.vehicle_id: k for k in self.known()}
        ex = Exchange(
            request,
            known.values(),
            now,
            timeout_s=timeout_s,
            repeat_s=self.repeat_s,
            database_known=self.database_ids is not None,
        )
        while True:
            now = time.monotonic()
            outs = ex.on_timer(now)
            with self._lock:
                fresh = self.view.acks[cursor:]
                cursor = len(self.view.acks)
            for a in fresh:
                outs += ex.handle(Heard(a), now)
            for k in self.known():  # membership news: joined, lost, a fleet now known
                if known.get(k.vehicle_id) != k:
                    known[k.vehicle_id] = k
                    outs += ex.handle(Seen(k), now)
            for o in outs:
                if isinstance(o, Send):
                    self.bus.publish(msg)
                elif isinstance(o, Finished):
                    if progress is not None:
                        progress(ex, now)
                    return o.outcome
            if progress is not None:
                progress(ex, now)
            deadline = ex.next_deadline()
            wait = 0.25 if deadline is None else min(max(deadline - now, 0.0), 0.25)
            with self._lock:
                if len(self.view.acks) == cursor:
                    self._changed.wait(wait)

    def send_command(
        self,
        kind: CommandKind,
        target: Selector | None = None,
        args: CommandArgs | None = None,
        *,
        timeout_s: float = 5.0,
        progress: Callable[[Exchange, float], None] | None = None,
    ) -> Outcome:
        cmd = Command(
            self.gcs_id,
            new_seq(),
            kind,
            target or Selector(),
            args or CommandArgs(),
            max(0.0, time.time()),
        )
        validate(cmd)
        if cmd.target.kind != SelectorKind.IDS:
            self.discover()
        request = Request(
            AckRef.COMMAND,
            cmd.seq,
            self.gcs_id,
            cmd.target,
            what=kind.name.lower().replace("_", "-"),
        )
        return self.exchange(cmd, request, timeout_s, progress)

    def send_mission(
        self,
        mission: Mission,
        *,
        timeout_s: float = 5.0,
        progress: Callable[[Exchange, float], None] | None = None,
    ) -> Outcome:
        """Every vehicle answers a mission (NOT_ADDRESSED when it is not for it)."""
        validate(mission)
        if mission.selection.kind != SelectorKind.IDS:
            self.discover()
        what = f"mission {mission.mission_id} ({mission.mission_type.name.lower()})"
        request = Request(
            AckRef.MISSION,
            mission.mission_id,
            mission.issuer_id,
            mission.selection,
            everyone_answers=True,
            what=what,
        )
        return self.exchange(mission, request, timeout_s, progress)

    def send_zone(
        self,
        zone: NoFlyZone,
        target: Selector | None = None,
        *,
        timeout_s: float = 10.0,
        progress: Callable[[Exchange, float], None] | None = None,
    ) -> Outcome:
        """Every vehicle holds every zone and acknowledges it to its issuer; `target`
        says whose answers must come (default: every vehicle alive)."""
        zone = stamp_zone(zone)  # repeats carry the same stamp: one declaration
        if zone.issuer_id != self.gcs_id:
            zone = msgspec.structs.replace(zone, issuer_id=self.gcs_id)
        validate(zone)
        target = target or Selector()
        if target.kind != SelectorKind.IDS:
            self.discover()
        kind = "operating area" if zone.operating_area else "zone"
        request = Request(
            AckRef.ZONE,
            zone.zone_id,
            self.gcs_id,
            target,
            everyone_answers=True,
            what=f"{kind} {zone.zone_id}",
        )
        return self.exchange(zone, request, timeout_s, progress)

    # the library's older calls (the demo, sitl-check): the acks, first one per vehicle
    def _acks(self, ref: AckRef, ref_id: int) -> list[Ack]:
        with self._lock:
            first: dict[int, Ack] = {}
            for a in self.view.acks:
                if a.ref == ref and a.ref_id == ref_id:
                    first.setdefault(a.vehicle_id, a)
            return list(first.values())

    def command(
        self,
        kind: CommandKind,
        target: Selector | None = None,
        args: CommandArgs | None = None,
        *,
        timeout_s: float = 5.0,
    ) -> list[Ack]:
        """Publish a command and return the answers of the vehicles it addresses
        (`send_command` for the whole outcome, silences included)."""
        out = self.send_command(kind, target, args, timeout_s=timeout_s)
        return [r.ack for r in out.rows if r.ack is not None]

    def mission(self, mission: Mission, *, timeout_s: float = MISSION_TIMEOUT_S) -> list[Ack]:
        """Publish a mission and return every answer (NOT_ADDRESSED ones too)."""
        self.send_mission(mission, timeout_s=timeout_s)
        return self._acks(AckRef.MISSION, mission.mission_id)

    def expected(self, target: Selector) -> set[int] | None:
        """Who must answer: a list of ids is taken as given (a fresh ground station
        need not have heard them); otherwise the vehicles alive now (discovered first)
        that the selector addresses. None: nobody known."""
        if target.kind == SelectorKind.IDS:
            return set(target.vehicle_ids)
        self.discover()
        return self._addressed(target)

    def discover(self, window_s: float = DISCOVER_S) -> set[int]:
        """The vehicles alive now: ask Zenoh for every liveliness token (a reply from
        the router or peers, not only what this session happened to hear yet), then wait
        up to `window_s` until each of them has been heard (its type and fleet known).
        Returns the ids of the vehicles among them (ground stations left out)."""
        found: set[int] = set()
        end = time.monotonic() + window_s
        while True:
            try:
                replies = self.bus.session.liveliness().get(
                    ALIVE.wildcard(self.swarm), timeout=max(0.1, end - time.monotonic())
                )
                for reply in replies:
                    if reply.ok is None:
                        continue
                    params = ALIVE.parse(self.swarm, str(reply.ok.key_expr))
                    if params is not None and params["node_id"].isdigit():
                        found.add(int(params["node_id"]))
            except Exception:  # a closed session: nothing more to discover
                return set()
            with self._lock:
                found |= self.view.alive  # and what the liveliness subscriber has seen
                found.discard(self.gcs_id)
                self.view.alive |= found
            # a fresh client session under load can get an empty answer at once (its
            # router had not matched it yet: `gcs declared` found "no vehicle alive"
            # right after a node restart): asked again within the window
            if found or time.monotonic() + DISCOVER_RETRY_S >= end:
                break
            time.sleep(DISCOVER_RETRY_S)
        self.wait_for(lambda v: all(i in v.status or i in v.info for i in found), window_s)
        with self._lock:
            return {i for i in found if self.view.type_of(i) != VehicleType.GCS}

    def zone(self, zone: NoFlyZone) -> NoFlyZone:
        """Publish a zone once, stamped with the declaration time if it has none (the
        newest declaration of a zone id wins on every node); returns it as published
        (see `send_zone` for every vehicle's answer)."""
        zone = stamp_zone(zone)
        if zone.issuer_id != self.gcs_id:
            zone = msgspec.structs.replace(zone, issuer_id=self.gcs_id)
        validate(zone)
        self.bus.publish(zone)
        return zone

    def declare_zone(
        self, zone: NoFlyZone, *, expect: Iterable[int] | None = None, timeout_s: float = 10.0
    ) -> set[int]:
        """Publish a zone until every expected vehicle (default: every vehicle alive)
        acknowledged it; returns the ids of the vehicles that hold it."""
        target = Selector.ids(*sorted(set(expect))) if expect else None
        out = self.send_zone(zone, target, timeout_s=timeout_s)
        return {r.vehicle_id for r in out.rows if r.verdict == Verdict.ACCEPTED}

    def holders(self, zone: NoFlyZone, timeout_s: float = 1.0) -> set[int]:
        """The vehicles whose zones queryable answers with this zone (issuer aside)."""
        want = msgspec.structs.replace(zone, issuer_id=0)
        return {
            vid
            for vid, z in self.zones_held(zone.zone_id, timeout_s).items()
            if msgspec.structs.replace(z, issuer_id=0) == want
        }

    def zones_held(self, zone_id: int, timeout_s: float = 1.0) -> dict[int, NoFlyZone]:
        """Each vehicle's copy of one zone, as its zones queryable answers."""
        held: dict[int, NoFlyZone] = {}
        key = ZONES.key(self.swarm, zone_id=zone_id)
        try:
            replies = list(self.bus.session.get(key, timeout=timeout_s))
        except Exception:  # a closed session
            return held
        for reply in replies:
            if reply.ok is None:
                continue
            params = ZONES.parse(self.swarm, str(reply.ok.key_expr))
            if params is None or not params["vehicle_id"].isdigit():
                continue
            try:
                z = lan.decode(reply.ok.payload.to_bytes(), NoFlyZone)
            except DecodeError:
                continue
            held[int(params["vehicle_id"])] = z
        return held

    def _addressed(self, target: Selector) -> set[int] | None:
        with self._lock:
            ids = self.view.vehicle_ids()
            fleets = {v: self.view.status[v].fleet_id for v in self.view.status}
        found = {v for v in ids if target.addresses(v, fleets.get(v, 0))}
        return found or None

    def reachable(self, timeout_s: float = 3.0) -> bool:
        """Whether this session reached any other Zenoh node (a router or a peer)
        within `timeout_s`: an unreachable --connect must not look like an empty
        swarm."""
        end = time.monotonic() + timeout_s
        while True:
            info = self.bus.session.info
            if list(info.routers_zid()) or list(info.peers_zid()):
                return True
            if time.monotonic() >= end:
                return False
            time.sleep(0.05)

    def all_zones(self, timeout_s: float = 2.0) -> dict[int, dict[int, NoFlyZone]]:
        """Every vehicle's zones (withdrawn ones too), as their zones queryables answer:
        {vehicle id: {zone id: zone}}."""
        return self._held(ZONES.key(self.swarm), ZONES, "zone_id", NoFlyZone, timeout_s)

    def missions_held(self, timeout_s: float = 2.0) -> dict[int, dict[int, Mission]]:
        """Every vehicle's accepted missions, as their missions queryables answer."""
        return self._held(MISSIONS.key(self.swarm), MISSIONS, "mission_id", Mission, timeout_s)

    def _held(
        self, key: str, topic: Any, id_name: str, kind: type[T], timeout_s: float
    ) -> dict[int, dict[int, T]]:
        """Every vehicle's replies on a queryable. A fresh session learns the peers'
        queryables within a moment: asked again (every 0.2 s) until every vehicle alive
        has answered, or `timeout_s`."""
        held: dict[int, dict[int, T]] = {}
        answered: set[int] = set()
        end = time.monotonic() + timeout_s
        while True:
            left = end - time.monotonic()
            alive = {k.vehicle_id for k in self.known() if k.alive}
            self._held_once(key, topic, id_name, kind, max(0.2, min(left, 1.0)), held, answered)
            if (alive and alive <= answered) or time.monotonic() >= end:
                return held
            time.sleep(0.2)

    def _held_once(
        self,
        key: str,
        topic: Any,
        id_name: str,
        kind: type[T],
        timeout_s: float,
        held: dict[int, dict[int, T]],
        answered: set[int],
    ) -> None:
        try:
            replies = list(self.bus.session.get(key, timeout=timeout_s))
        except Exception:  # a closed session
            return
        for reply in replies:
            if reply.ok is None:
                continue
            params = topic.parse(self.swarm, str(reply.ok.key_expr))
            if params is None or not params["vehicle_id"].isdigit():
                continue
            try:
                item = lan.decode(reply.ok.payload.to_bytes(), kind)
            except DecodeError:
                continue
            held.setdefault(int(params["vehicle_id"]), {})[int(getattr(item, id_name))] = item
            answered.add(int(params["vehicle_id"]))

    def declared_state(self, node_id: int, timeout_s: float = 3.0) -> DeclaredState | None:
        """What the operator declared, as node `node_id` holds it (its DECLARED
        queryable). None: it did not answer."""
        return self._ask_one(DECLARED.key(self.swarm, vehicle_id=node_id), DeclaredState, timeout_s)

    def peers_of(self, node_id: int, timeout_s: float = 2.0) -> SwarmView | None:
        """Node `node_id`'s view of the swarm (its PEERS queryable); None: no answer."""
        return self._ask_one(PEERS.key(self.swarm, vehicle_id=node_id), SwarmView, timeout_s)

    def _ask_one(self, key: str, kind: type[T], timeout_s: float) -> T | None:
        """One node's queryable, asked again every 0.2 s until it answers or `timeout_s`:
        a fresh session (a router that has not told it of the queryable yet) gets no
        reply at once rather than after the timeout. None: no answer, or a bad one."""
        end = time.monotonic() + timeout_s
        while True:
            left = end - time.monotonic()
            try:
                replies = list(self.bus.session.get(key, timeout=max(0.2, min(left, 1.0))))
            except Exception:  # a closed session
                return None
            for reply in replies:
                if reply.ok is not None:
                    try:
                        return lan.decode(reply.ok.payload.to_bytes(), kind)
                    except DecodeError:
                        return None
            if time.monotonic() >= end:
                return None
            time.sleep(0.2)

    def close(self) -> None:
        self._stop.set()
        if self._announcer is not None:  # it stops before its session closes under it
            self._announcer.join(2.0)
        self.bus.close()

    def __enter__(self) -> GroundStation:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
