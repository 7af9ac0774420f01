"""The ground station as a library: one Zenoh session that watches the fleet and
sends commands, missions and zones, waiting for the vehicles' acks. The `gcs` command
line and the demo are thin layers over it.

The ground station is a swarm node too (paper section 3): it declares its liveliness
token and publishes a VehicleInfo of type GCS, so vehicles list it among their peers.
"""

from __future__ import annotations

import threading
import time
from collections import deque
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field

import msgspec

from swarm_proto import (
    Ack,
    AckRef,
    Alert,
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
from swarm_proto.session import SwarmBus, ZenohSettings
from swarm_proto.topics import ACK, ALERT, ALIVE, DECLARED, INFO, PEERS, STATUS, ZONES

DEFAULT_GCS_ID = 900


REPEAT_S = 1.0  # commands and missions are sent again this often until answered
DISCOVER_S = 2.0  # a fresh ground station's window to hear the vehicles that are alive


def stamp_zone(zone: NoFlyZone) -> NoFlyZone:
    """The zone with its declaration time (the ground station's clock) if it has none."""
    if zone.time_unix_s > 0.0:
        return zone
    return msgspec.structs.replace(zone, time_unix_s=max(0.0, time.time()))


def new_seq() -> int:
    """A command sequence number that increases across runs without stored state:
    milliseconds since 2024-01-01, modulo 2^32 (wraps after 49 days)."""
    return int((time.time() - 1_704_067_200) * 1000) % (1 << 32)


@dataclass
class FleetView:
    """The latest of everything heard from each vehicle."""

    status: dict[int, VehicleStatus] = field(default_factory=dict)
    info: dict[int, VehicleInfo] = field(default_factory=dict)
    heard_at: dict[int, float] = field(default_factory=dict)  # monotonic seconds
    alive: set[int] = field(default_factory=set)
    alerts: deque[Alert] = field(default_factory=lambda: deque(maxlen=200))
    acks: list[Ack] = field(default_factory=list)

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
    ) -> None:
        self.gcs_id = gcs_id
        self.repeat_s = REPEAT_S
        self.swarm = swarm
        self.view = FleetView()
        self._lock = threading.Lock()
        self._changed = threading.Condition(self._lock)
        self.bus = SwarmBus.open(settings, swarm)
        self.bus.subscribe(STATUS, self._on_status)
        self.bus.subscribe(INFO, self._on_info)
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
        self.view.heard_at[vid] = time.monotonic()
        self._changed.notify_all()

    def _on_status(self, msg: VehicleStatus, key: str) -> None:
        with self._lock:
            self.view.status[msg.vehicle_id] = msg
            self._touch(msg.vehicle_id)

    def _on_info(self, msg: VehicleInfo, key: str) -> None:
        with self._lock:
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
            except RuntimeError:  # closed
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
            )

    # ------------------------------------------------------------------ sending
    def _send_and_wait(
        self,
        msg: msgspec.Struct,
        ref: AckRef,
        ref_id: int,
        expect: Iterable[int] | None,
        timeout_s: float,
    ) -> list[Ack]:
        validate(msg)
        expected = set(expect) if expect is not None else None

        def answered(view: FleetView) -> bool:
            got = {a.vehicle_id for a in view.acks if a.ref == ref and a.ref_id == ref_id}
            return expected is not None and expected <= got

        # Repeated, unchanged, until every addressed vehicle answers: a frame lost on the
        # radio (or published before a fresh session's routes are up) is sent again, and a
        # vehicle answers a repeat with its first answer instead of acting twice.
        end = time.monotonic() + timeout_s
        while True:
            self.bus.publish(msg)
            left = end - time.monotonic()
            if self.wait_for(answered, min(self.repeat_s, max(left, 0.0))) or left <= self.repeat_s:
                break
        with self._lock:
            first: dict[int, Ack] = {}  # a repeat may be answered twice: one row per vehicle
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
        """Publish a command and collect the acks of the vehicles it addresses (the
        listed ids, or the vehicles discovered alive that it addresses; or whatever
        arrives within the timeout when none is known)."""
        cmd = Command(
            self.gcs_id,
            new_seq(),
            kind,
            target or Selector(),
            args or CommandArgs(),
            max(0.0, time.time()),
        )
        return self._send_and_wait(
            cmd, AckRef.COMMAND, cmd.seq, self.expected(cmd.target), timeout_s
        )

    def mission(self, mission: Mission, *, timeout_s: float = 5.0) -> list[Ack]:
        """Publish a mission and collect the answers: every vehicle answers a mission,
        those it does not address with NOT_ADDRESSED. Waits for the addressed vehicles:
        the listed ids, or (fleet, all) the vehicles discovered alive that it addresses
        (if none is known, for every vehicle discovered)."""
        expect = self.expected(mission.selection)
        if expect is None:
            with self._lock:
                expect = set(self.view.vehicle_ids()) or None
        return self._send_and_wait(mission, AckRef.MISSION, mission.mission_id, expect, timeout_s)

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
        try:
            replies = self.bus.session.liveliness().get(
                ALIVE.wildcard(self.swarm), timeout=window_s
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
        self.wait_for(lambda v: all(i in v.status or i in v.info for i in found), window_s)
        with self._lock:
            return {i for i in found if self.view.type_of(i) != VehicleType.GCS}

    def zone(self, zone: NoFlyZone) -> NoFlyZone:
        """Publish a zone once, stamped with the declaration time if it has none (the
        newest declaration of a zone id wins on every node); returns it as published
        (see `declare_zone` to know who holds it)."""
        zone = stamp_zone(zone)
        validate(zone)
        self.bus.publish(zone)
        return zone

    def declare_zone(
        self, zone: NoFlyZone, *, expect: Iterable[int] | None = None, timeout_s: float = 10.0
    ) -> set[int]:
        """Publish a zone, again every `repeat_s`, until every expected vehicle (default:
        the vehicles discovered alive) holds it, as each one's zones queryable shows;
        returns the ids of the vehicles that confirmed holding it (this very zone, or
        its withdrawal)."""
        zone = stamp_zone(zone)  # repeats carry the same stamp: one declaration
        validate(zone)
        given = expect is not None
        expected = set(expect) if expect is not None else self.discover()
        end = time.monotonic() + timeout_s
        confirmed: set[int] = set()
        while True:
            if not given:  # vehicles heard since (a slow discovery on a loaded host)
                with self._lock:
                    expected |= set(self.view.vehicle_ids())
            self.bus.publish(zone)
            left = end - time.monotonic()
            wait_end = time.monotonic() + min(self.repeat_s, max(left, 0.0))
            while True:
                confirmed |= self.holders(zone, timeout_s=1.0)
                if expected and expected <= confirmed:
                    return confirmed
                if time.monotonic() >= wait_end:
                    break
                time.sleep(0.1)
            if time.monotonic() >= end:
                return confirmed

    def holders(self, zone: NoFlyZone, timeout_s: float = 1.0) -> set[int]:
        """The vehicles whose zones queryable answers with exactly this zone."""
        return {vid for vid, z in self.zones_held(zone.zone_id, timeout_s).items() if z == zone}

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

    def declared_state(self, node_id: int, timeout_s: float = 3.0) -> DeclaredState | None:
        """What the operator declared, as node `node_id` holds it (its DECLARED
        queryable; issue 16). None: it did not answer."""
        for reply in self.bus.session.get(
            DECLARED.key(self.swarm, vehicle_id=node_id), timeout=timeout_s
        ):
            if reply.ok is not None:
                try:
                    return lan.decode(reply.ok.payload.to_bytes(), DeclaredState)
                except Exception:
                    return None
        return None

    def peers_of(self, node_id: int, timeout_s: float = 2.0) -> SwarmView | None:
        for reply in self.bus.session.get(
            PEERS.key(self.swarm, vehicle_id=node_id), timeout=timeout_s
        ):
            if reply.ok is not None:
                try:
                    return lan.decode(reply.ok.payload.to_bytes(), SwarmView)
                except Exception:
                    return None
        return None

    def close(self) -> None:
        self._stop.set()
        self.bus.close()
        if self._announcer is not None:
            self._announcer.join(2.0)

    def __enter__(self) -> GroundStation:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
