"""What the operator declared, held by every node so that none of it is silently lost:
zones and operating areas, bases, fleets and missions.

A declaration carries a stamp, the ground station's clock when the operator made it
(`time_unix_s` of the NoFlyZone, Command, FleetAssignment, Mission): a node that gets a
declaration without one stamps it with its own time when it first hears it and keeps
that stamp. The newest stamp wins, wherever a declaration comes from: live from the
ground station, restored from the node's own database at start, or read from a peer
when the two meet (`merge`), so every node converges on the same book whatever the
order it hears things in, and a withdrawal (a zone re-declared with active=False, a
mission cancelled) stays withdrawn when a node that missed it rejoins. Equal stamps
are ordered by the declaration's bytes, so ties too resolve the same everywhere.

What is kept:

    zones        zone id -> the newest NoFlyZone (withdrawn ones too): the node's one
                 zone book (safety/zones.py), which monitoring, the fence keeper, the
                 planners and collision avoidance read
    commands     SET_BASE, SET_FLEET and CANCEL_MISSION commands, by kind and selector:
                 the newest per (kind, selector); older ones a newer command to ALL of
                 the same kind supersedes are dropped
    assignments  fleet id -> the newest FleetAssignment
    missions     mission id -> the Mission this node accepted, in force or not (a peer's
                 missions are taken only when unknown: a peer that finished its part
                 does not end the mission for this node; the operator's CANCEL_MISSION,
                 a declaration, does)

Any vehicle's base and fleet follow from the commands and assignments in stamp order
(`base_of`, `fleet_of`), so a node can tell a restarted peer its base.

Pure: no I/O; `now` is passed in.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field

import msgspec

from swarm_proto import (
    Command,
    CommandKind,
    DeclaredMission,
    DeclaredState,
    FleetAssignment,
    GeoPoint,
    Mission,
    NoFlyZone,
    SelectorKind,
    lan,
)

from .safety.zones import ZoneBook

#: Commands that declare state (the others act and are done).
DECLARING = frozenset({CommandKind.SET_BASE, CommandKind.SET_FLEET, CommandKind.CANCEL_MISSION})
MAX_COMMANDS = 64  # kept per node (the oldest go first)
MAX_MISSIONS = 32

Stamp = tuple[float, bytes]


def _stamp(msg: msgspec.Struct) -> Stamp:
    return (float(getattr(msg, "time_unix_s", 0.0)), lan.encode(msg))


def stamped(msg: msgspec.Struct, now: float) -> msgspec.Struct:
    """The declaration with a stamp: its own, or `now` when it carries none."""
    if getattr(msg, "time_unix_s", 0.0) > 0.0:
        return msg
    return msgspec.structs.replace(msg, time_unix_s=max(0.0, now))


def _mission_order(dm: DeclaredMission) -> tuple[bool, float, bytes]:
    """Withdrawn outranks in force (final), then the newer change, then the bytes."""
    return (not dm.in_force, dm.changed_unix_s, lan.encode(dm))


def selector_key(cmd: Command) -> str:
    t = cmd.target
    if t.kind == SelectorKind.IDS:
        return "ids:" + ",".join(str(i) for i in sorted(set(t.vehicle_ids)))
    if t.kind == SelectorKind.FLEET:
        return f"fleet:{t.fleet_id}"
    if t.kind == SelectorKind.QUANTITY:
        return f"quantity:{t.fleet_id}:{t.quantity}:{t.payload_model}"
    return "all"


def command_key(cmd: Command) -> str:
    extra = f":{cmd.args.mission_id}" if cmd.kind == CommandKind.CANCEL_MISSION else ""
    return f"{cmd.kind.name}{extra}/{selector_key(cmd)}"


class SortieRecord(msgspec.Struct, frozen=True):
    """The share this node was flying, kept in its database so that a node restarted in
    flight can reattach to its vehicle (reattach.py): the mission, the roster it was
    planned with, what it uploaded to the autopilot."""

    mission_id: int
    members: tuple[int, ...]  # the frozen roster
    planned: tuple[int, ...]  # the members the current plan was made for
    generation: int  # replans of the roster
    members_hash: int
    items: int  # mission items uploaded (home included)
    last_item: int  # reaching it completes the share
    path_m: float
    progress_m: float
    updated_unix_s: float


@dataclass
class Changed:
    """What a merge or an offer changed."""

    zones: list[NoFlyZone] = field(default_factory=list)
    commands: list[Command] = field(default_factory=list)
    assignments: list[FleetAssignment] = field(default_factory=list)
    missions: list[DeclaredMission] = field(default_factory=list)

    def __bool__(self) -> bool:
        return bool(self.zones or self.commands or self.assignments or self.missions)

    def add(self, other: Changed) -> None:
        self.zones += other.zones
        self.commands += other.commands
        self.assignments += other.assignments
        self.missions += other.missions


@dataclass
class DeclaredBook:
    zones: ZoneBook = field(default_factory=ZoneBook)
    commands: dict[str, Command] = field(default_factory=dict)
    assignments: dict[int, FleetAssignment] = field(default_factory=dict)
    missions: dict[int, DeclaredMission] = field(default_factory=dict)
    stale: int = 0  # declarations offered that were older than the one held (ignored)

    # ------------------------------------------------------------------ offers
    def offer_zone(self, zone: NoFlyZone, now: float) -> NoFlyZone | None:
        """The zone now held for its id if this one is newer (None: ours is newer)."""
        z = stamped(zone, now)
        assert isinstance(z, NoFlyZone)
        held = self.zones.get(z.zone_id)
        if held is not None and _stamp(held) >= _stamp(z):
            self.stale += held != z
            return None
        self.zones[z.zone_id] = z
        return z

    def offer_command(self, cmd: Command, now: float) -> Command | None:
        """Record a declaring command (SET_BASE, SET_FLEET, CANCEL_MISSION); None when
        it changes nothing (not declaring, a repeat, or older than the one held)."""
        if cmd.kind not in DECLARING:
            return None
        c = stamped(cmd, now)
        assert isinstance(c, Command)
        key = command_key(c)
        held = self.commands.get(key)
        if held is not None and _stamp(held) >= _stamp(c):
            self.stale += held != c
            return None
        superseded = c.kind != CommandKind.CANCEL_MISSION and any(
            o.kind == c.kind and o.target.kind == SelectorKind.ALL and _stamp(o) > _stamp(c)
            for o in self.commands.values()
        )
        if superseded:
            return None
        self.commands[key] = c
        if c.target.kind == SelectorKind.ALL and c.kind != CommandKind.CANCEL_MISSION:
            for k, o in list(self.commands.items()):  # everything older of its kind
                if o.kind == c.kind and _stamp(o) < _stamp(c):
                    del self.commands[k]
        while len(self.commands) > MAX_COMMANDS:
            oldest = min(self.commands, key=lambda k: _stamp(self.commands[k]))
            del self.commands[oldest]
        return c

    def offer_assignment(self, a: FleetAssignment, now: float) -> FleetAssignment | None:
        s = stamped(a, now)
        assert isinstance(s, FleetAssignment)
        held = self.assignments.get(s.fleet_id)
        if held is not None and _stamp(held) >= _stamp(s):
            self.stale += held != s
            return None
        self.assignments[s.fleet_id] = s
        return s

    def offer_mission(self, dm: DeclaredMission) -> DeclaredMission | None:
        """A mission record: a new mission, or a newer change of its in-force flag (a
        withdrawal is final: a mission no longer in force never comes back in force)."""
        mid = dm.mission.mission_id
        held = self.missions.get(mid)
        if held is not None and _mission_order(held) >= _mission_order(dm):
            return None
        self.missions[mid] = dm
        while len(self.missions) > MAX_MISSIONS:
            oldest = min(self.missions, key=lambda m: self.missions[m].changed_unix_s)
            del self.missions[oldest]
        return dm

    def accept_mission(self, mission: Mission, now: float) -> DeclaredMission | None:
        return self.offer_mission(DeclaredMission(mission, True, max(0.0, now)))

    def end_mission(self, mission_id: int, now: float) -> DeclaredMission | None:
        held = self.missions.get(mission_id)
        if held is None or not held.in_force:
            return None
        return self.offer_mission(DeclaredMission(held.mission, False, max(0.0, now)))

    def cancelled(self, mission_id: int) -> bool:
        return any(
            c.kind == CommandKind.CANCEL_MISSION and c.args.mission_id == mission_id
            for c in self.commands.values()
        )

    # ------------------------------------------------------------------ merge
    def merge(self, state: DeclaredState, now: float) -> Changed:
        """Take what is newer in another node's (or our stored) book."""
        ch = Changed()
        for z in state.zones:
            got = self.offer_zone(z, now)
            if got is not None:
                ch.zones.append(got)
        for c in sorted(state.commands, key=_stamp):
            cmd = self.offer_command(c, now)
            if cmd is not None:
                ch.commands.append(cmd)
        for a in state.assignments:
            fa = self.offer_assignment(a, now)
            if fa is not None:
                ch.assignments.append(fa)
        for m in state.missions:  # another node's missions: known ones are its own business
            if m.mission.mission_id not in self.missions and self.offer_mission(m) is not None:
                ch.missions.append(m)
        return ch

    # ------------------------------------------------------------------ views
    def _ordered(self) -> list[Command | FleetAssignment]:
        items: list[Command | FleetAssignment] = [
            *(c for c in self.commands.values() if c.kind != CommandKind.CANCEL_MISSION),
            *self.assignments.values(),
        ]
        return sorted(items, key=_stamp)

    def resolve(self, vehicle_id: int) -> tuple[GeoPoint | None, float, int, float]:
        """(base, its stamp, fleet id, its stamp) of a vehicle, from the declarations in
        stamp order (a FLEET selector addresses the fleet the vehicle was in then)."""
        base: GeoPoint | None = None
        base_at = fleet_at = 0.0
        fleet = 0
        for d in self._ordered():
            if isinstance(d, FleetAssignment):
                if vehicle_id in d.vehicle_ids:
                    fleet, fleet_at = d.fleet_id, d.time_unix_s
                elif fleet == d.fleet_id:
                    fleet, fleet_at = 0, d.time_unix_s
                continue
            if not d.target.addresses(vehicle_id, fleet):
                continue
            if d.kind == CommandKind.SET_BASE and d.args.point is not None:
                base, base_at = d.args.point, d.time_unix_s
            elif d.kind == CommandKind.SET_FLEET:
                fleet, fleet_at = d.args.fleet_id, d.time_unix_s
        return base, base_at, fleet, fleet_at

    def snapshot(
        self,
        vehicle_id: int,
        now: float,
        *,
        base: GeoPoint | None = None,
        fleet_id: int = 0,
        mission_id: int = 0,
    ) -> DeclaredState:
        return DeclaredState(
            vehicle_id=vehicle_id,
            time_unix_s=max(0.0, now),
            zones=tuple(self.zones[k] for k in sorted(self.zones)),
            commands=tuple(sorted(self.commands.values(), key=_stamp)),
            assignments=tuple(self.assignments[k] for k in sorted(self.assignments)),
            missions=tuple(self.missions[k] for k in sorted(self.missions)),
            base=base,
            fleet_id=fleet_id,
            mission_id=max(0, mission_id),
        )

    @classmethod
    def of(cls, states: Iterable[DeclaredState], now: float) -> DeclaredBook:
        book = cls()
        for s in states:
            book.merge(s, now)
        return book
