"""The node's declared state in its swarm database: what the operator
declared (zones, SET_BASE / SET_FLEET / CANCEL_MISSION commands, fleet assignments,
missions) and the share the node flies, one row of `node_declared` per declaration,
restored when the node starts.

    store = NodeStateStore(db, node_id)
    store.save(state, sortie)      # a Persist output of the node core (all or nothing)
    state, sortie, bad = store.load(now)

A row that does not decode (a file edited by hand, damage SQLite did not see) is
skipped and counted in `bad`, never a crash: the peers hold the same declarations.
A full disk or a read-only file is a `StorageError` from `save`, and the previous state
stays whole (one transaction).
"""

from __future__ import annotations

import msgspec

from swarm_node.core.declared import SortieRecord, command_key
from swarm_proto import (
    Command,
    DeclaredMission,
    DeclaredState,
    FleetAssignment,
    NoFlyZone,
    lan,
)
from swarm_proto.errors import DecodeError

from .repository import SwarmDatabase

Row = tuple[str, str, float, bytes]
_SORTIE = msgspec.msgpack.Encoder()
_SORTIE_DECODER = msgspec.msgpack.Decoder(SortieRecord)


def to_rows(state: DeclaredState, sortie: SortieRecord | None) -> list[Row]:
    rows: list[Row] = []
    for z in state.zones:
        rows.append(("zone", str(z.zone_id), z.time_unix_s, lan.encode(z)))
    for c in state.commands:
        rows.append(("command", command_key(c), c.time_unix_s, lan.encode(c)))
    for a in state.assignments:
        rows.append(("assignment", str(a.fleet_id), a.time_unix_s, lan.encode(a)))
    for m in state.missions:
        rows.append(("mission", str(m.mission.mission_id), m.changed_unix_s, lan.encode(m)))
    if sortie is not None:
        rows.append(("sortie", "current", sortie.updated_unix_s, _SORTIE.encode(sortie)))
    return rows


def from_rows(
    rows: list[Row], vehicle_id: int, now: float
) -> tuple[DeclaredState, SortieRecord | None, int]:
    zones: list[NoFlyZone] = []
    commands: list[Command] = []
    assignments: list[FleetAssignment] = []
    missions: list[DeclaredMission] = []
    sortie: SortieRecord | None = None
    bad = 0
    for kind, _key, _stamp, payload in rows:
        try:
            if kind == "zone":
                zones.append(lan.decode(payload, NoFlyZone))
            elif kind == "command":
                commands.append(lan.decode(payload, Command))
            elif kind == "assignment":
                assignments.append(lan.decode(payload, FleetAssignment))
            elif kind == "mission":
                missions.append(lan.decode(payload, DeclaredMission))
            elif kind == "sortie":
                sortie = _SORTIE_DECODER.decode(payload)
            else:
                bad += 1
        except (DecodeError, msgspec.DecodeError, msgspec.ValidationError, ValueError):
            bad += 1
    state = DeclaredState(
        vehicle_id=vehicle_id,
        time_unix_s=max(0.0, now),
        zones=tuple(zones),
        commands=tuple(commands),
        assignments=tuple(assignments),
        missions=tuple(missions),
    )
    return state, sortie, bad


class NodeStateStore:
    """The declared state of one node in its swarm database."""

    def __init__(self, db: SwarmDatabase, node_id: int) -> None:
        self.db = db
        self.node_id = node_id
        self.writes = 0
        self.failures = 0

    def save(self, state: DeclaredState, sortie: SortieRecord | None) -> None:
        try:
            self.db.write_node_state(self.node_id, to_rows(state, sortie))
        except Exception:
            self.failures += 1
            raise
        self.writes += 1

    def load(self, now: float) -> tuple[DeclaredState, SortieRecord | None, int]:
        return from_rows(self.db.node_state_rows(self.node_id), self.node_id, now)
