"""The node's module for what the operator declared (the book: declared.py), this
vehicle's base and fleet among it, and their storage.

    inputs                          what it does
    NoFlyZone                       kept if newer (the zone book: `zones`); answered
    FleetAssignment                 kept if newer; this vehicle's fleet (out of it: the
                                    state machine's LeftFleet)
    Learned (database, a peer)      merged: newer zones, this vehicle's base and fleet
    StoreResult                     a failed store alerted once, its recovery noted
    Declared(command | mission)     a declaring command (SET_BASE, SET_FLEET,
                                    CANCEL_MISSION) or an accepted mission, kept
    Ended(mission id)               a mission no longer in force
    SetBase / SetFleet / LeftFleet  this vehicle's base and fleet (the operator's command,
                                    the state machine leaving the fleet)

Every change marks the book to store (`take_store`: the node's Persist).

Pure: no I/O; `now` is passed in.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from typing import assert_never

from swarm_proto import (
    Ack,
    AckReason,
    AckRef,
    Alert,
    AlertCode,
    Command,
    CommandKind,
    DeclaredState,
    FleetAssignment,
    GeoPoint,
    Mission,
    NoFlyZone,
    Severity,
)
from swarm_proto.text import short_text

from . import state_machine as fsm
from .declared import DeclaredBook
from .outputs import (
    Declared,
    Ended,
    LeftFleet,
    ModuleOutput,
    Note,
    Post,
    Publish,
    SetBase,
    SetFleet,
    ToDeclarations,
)
from .safety.zones import ZoneBook


@dataclass
class Declarations:
    vehicle_id: int
    book: DeclaredBook = field(default_factory=DeclaredBook)
    base: GeoPoint | None = None
    fleet_id: int = 0
    _base_stamp: float = 0.0  # the stamp of the declaration our base came from
    _fleet_stamp: float = 0.0
    _dirty: bool = False  # the declared state changed: store it
    _store_failing: bool = False

    # ------------------------------------------------------------------ views
    @property
    def zones(self) -> ZoneBook:
        """The node's one zone book (safety/zones.py)."""
        return self.book.zones

    @property
    def store_due(self) -> bool:
        return self._dirty

    def take_store(self) -> bool:
        """Whether the book changed since last asked (the node stores it then)."""
        due, self._dirty = self._dirty, False
        return due

    def snapshot(self, now: float, mission_id: int | None) -> DeclaredState:
        """What the operator declared, as this node holds it (the DECLARED queryable)."""
        return self.book.snapshot(
            self.vehicle_id,
            now,
            base=self.base,
            fleet_id=self.fleet_id,
            mission_id=mission_id if mission_id is not None and mission_id > 0 else 0,
        )

    def mission_on_record(self, mission_id: int) -> tuple[Mission | None, str]:
        """The mission kept for `mission_id` if still in force (else None and why)."""
        held = self.book.missions.get(mission_id)
        if held is None:
            return None, "restarted without the mission on record"
        if self.book.cancelled(mission_id) or not held.in_force:
            return None, f"mission {mission_id} no longer in force"
        return held.mission, ""

    # ------------------------------------------------------------------ inputs
    def on_zone(self, msg: NoFlyZone, now: float) -> list[ModuleOutput]:
        held = self.zones.get(msg.zone_id)
        if self.book.offer_zone(msg, now) is not None:
            self._dirty = True
        # else older than the declaration held: a withdrawal stays
        return self._zone_ack(msg, held)

    def on_assignment(self, msg: FleetAssignment, now: float) -> list[ModuleOutput]:
        held = self.book.offer_assignment(msg, now)
        if held is None:
            return []  # a repeat, or older than the assignment held
        self._dirty = True
        vid = self.vehicle_id
        if vid in msg.vehicle_ids or self.fleet_id == msg.fleet_id:
            self._fleet_stamp = max(self._fleet_stamp, held.time_unix_s)
        if vid in msg.vehicle_ids:
            self.fleet_id = msg.fleet_id
        elif self.fleet_id == msg.fleet_id:
            self.fleet_id = 0  # dropped from the fleet
            return [Post(fsm.LeftFleet("removed from the fleet"))]
        return []

    def learn(self, state: DeclaredState, source: str, now: float) -> list[ModuleOutput]:
        """Merge another book (ours from the database, a peer's): newer zones go to the
        zone book, a newer base or fleet for this vehicle is taken."""
        changed = self.book.merge(state, now)
        out: list[ModuleOutput] = []
        if changed.zones:
            ids = ",".join(str(z.zone_id) for z in changed.zones)
            out.append(Note(logging.INFO, f"zones {ids} learned from {source}"))
        out += self._take_resolved(source)
        if changed:
            self._dirty = True
        return out

    def take(self, o: ToDeclarations, now: float) -> None:
        """What other modules tell us (outputs.ToDeclarations)."""
        match o:
            case Declared(msg):
                self.declared(msg, now)
            case Ended(mission_id):
                self._dirty |= self.book.end_mission(mission_id, now) is not None
            case SetBase(point):
                self.base = point
            case SetFleet(fleet_id):
                self.fleet_id = fleet_id
            case LeftFleet():
                self.fleet_id = 0
            case _:
                assert_never(o)

    def declared(self, msg: Command | Mission, now: float) -> None:
        """A declaring command (every node keeps every one) or a mission accepted."""
        if isinstance(msg, Mission):
            self._dirty |= self.book.accept_mission(msg, now) is not None
            return
        held = self.book.offer_command(msg, now)
        if held is None:
            return
        self._dirty = True
        if msg.target.addresses(self.vehicle_id, self.fleet_id):
            if msg.kind == CommandKind.SET_BASE:
                self._base_stamp = held.time_unix_s
            elif msg.kind == CommandKind.SET_FLEET:
                self._fleet_stamp = held.time_unix_s

    def stored(self, ok: bool, error: str, now: float) -> list[ModuleOutput]:
        if ok:
            was, self._store_failing = self._store_failing, False
            return [Note(logging.INFO, "declared state stored again")] if was else []
        if self._store_failing:
            return []
        self._store_failing = True
        text = f"declared state not stored: {error}"
        alert = Alert(
            self.vehicle_id, max(0.0, now), Severity.WARNING, AlertCode.GENERIC, short_text(text)
        )
        return [
            Note(logging.WARNING, f"{text} (held in memory and by the peers; retried)"),
            Publish(alert),
        ]

    # ------------------------------------------------------------------ internals
    def _take_resolved(self, source: str) -> list[ModuleOutput]:
        """This vehicle's base and fleet as the book resolves them, when newer than what
        set ours."""
        base, base_at, fleet, fleet_at = self.book.resolve(self.vehicle_id)
        out: list[ModuleOutput] = []
        if base is not None and base_at > self._base_stamp:
            self.base, self._base_stamp = base, base_at
            text = f"base {base.lat_deg:.6f},{base.lon_deg:.6f} learned from {source}"
            out.append(Note(logging.INFO, text))
        if fleet_at > self._fleet_stamp:
            if fleet != self.fleet_id:
                out.append(Note(logging.INFO, f"fleet {fleet} learned from {source}"))
            self.fleet_id, self._fleet_stamp = fleet, fleet_at
        return out

    def _zone_ack(self, zone: NoFlyZone, held: NoFlyZone | None) -> list[ModuleOutput]:
        """Answer the zone's issuer (a repeat too): held, or for a withdrawal of a zone
        this vehicle never held, NOT_FOUND (the withdrawal is kept all the same)."""
        if not zone.issuer_id:
            return []
        if zone.active:
            ok, text = True, "operating area held" if zone.operating_area else "held"
        elif held is None:
            ok, text = False, f"zone {zone.zone_id} was not held"
        else:
            ok, text = True, "withdrawn" if held.active else "already withdrawn"
        reason = AckReason.OK if ok else AckReason.NOT_FOUND
        ack = Ack(self.vehicle_id, zone.issuer_id, AckRef.ZONE, zone.zone_id, ok, reason, text)
        return [Publish(ack)]
