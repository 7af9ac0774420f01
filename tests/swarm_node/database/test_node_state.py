"""The node's declared state in its swarm database (migration 4, database/state.py):
stored per node, restored whole; a row that does not decode is skipped and
counted; a full disk is a StorageError and leaves the previous state whole."""

from __future__ import annotations

import sqlite3
from pathlib import Path

import pytest

from swarm_node.core.declared import DeclaredBook, SortieRecord
from swarm_node.database import StorageError, SwarmDatabase
from swarm_node.database.state import NodeStateStore
from swarm_proto import (
    Command,
    CommandArgs,
    CommandKind,
    DeclaredMission,
    FleetAssignment,
    Geometry,
    GeoPoint,
    Mission,
    MissionType,
    NoFlyZone,
)

T = 1.8e9


def book() -> DeclaredBook:
    b = DeclaredBook()
    b.offer_zone(NoFlyZone(3, Geometry.circle(37.41, -5.99, 40.0), name="tower"), T)
    b.offer_zone(NoFlyZone(4, Geometry.circle(37.41, -5.99, 900.0), operating_area=True), T + 1)
    b.offer_command(
        Command(
            900,
            1,
            CommandKind.SET_BASE,
            args=CommandArgs(point=GeoPoint(37.41, -5.99, 10.0)),
            time_unix_s=T + 2,
        ),
        T,
    )
    b.offer_assignment(FleetAssignment(2, 0, (7, 8), 900, T + 3), T)
    b.offer_mission(
        DeclaredMission(
            Mission(11, 900, MissionType.AREA, Geometry.circle(37.41, -5.99, 100.0)), True, T + 4
        )
    )
    return b


SORTIE = SortieRecord(11, (1, 7), (1, 7), 0, 0x1234, 12, 10, 850.0, 120.0, T + 5)


def test_stored_per_node_and_restored_whole(tmp_path: Path) -> None:
    path = tmp_path / "swarm.db"
    with SwarmDatabase.open(path) as db:
        NodeStateStore(db, 7).save(book().snapshot(7, T), SORTIE)
        NodeStateStore(db, 8).save(DeclaredBook().snapshot(8, T), None)
    with SwarmDatabase.open(path) as db:  # a new process on the same file
        state, sortie, bad = NodeStateStore(db, 7).load(T + 10)
        other, none, _ = NodeStateStore(db, 8).load(T + 10)
    assert bad == 0 and sortie == SORTIE and none is None and other.zones == ()
    restored = DeclaredBook.of([state], T + 10)
    assert restored.zones == book().zones and restored.commands == book().commands
    assert restored.assignments == book().assignments and restored.missions == book().missions
    assert restored.resolve(7) == book().resolve(7)


def test_a_row_that_does_not_decode_is_skipped(tmp_path: Path) -> None:
    path = tmp_path / "swarm.db"
    with SwarmDatabase.open(path) as db:
        NodeStateStore(db, 7).save(book().snapshot(7, T), SORTIE)
    raw = sqlite3.connect(path)
    raw.execute("UPDATE node_declared SET payload = x'c1ff00' WHERE kind = 'zone' AND key = '3'")
    raw.commit()
    raw.close()
    with SwarmDatabase.open(path) as db:
        state, sortie, bad = NodeStateStore(db, 7).load(T)
    assert bad == 1 and [z.zone_id for z in state.zones] == [4] and sortie == SORTIE


def test_a_full_disk_keeps_the_previous_state_whole(tmp_path: Path) -> None:
    path = tmp_path / "swarm.db"
    with SwarmDatabase.open(path) as db:
        store = NodeStateStore(db, 7)
        store.save(book().snapshot(7, T), SORTIE)
        pages = db._conn.execute("PRAGMA page_count").fetchone()["page_count"]
        db._conn.execute(f"PRAGMA max_page_count = {pages}")  # no room to grow: disk full
        big = book()
        for k in range(40):  # more than fits in the pages there are
            big.offer_zone(
                NoFlyZone(
                    100 + k,
                    Geometry.polygon(
                        [(37.41 + 1e-4 * j, -5.99 + 1e-4 * (j % 7)) for j in range(3)]
                        + [(37.40, -5.98)]
                    ),
                    name=f"zone {k:02d} " + "x" * 30,
                ),
                T,
            )
        with pytest.raises(StorageError, match="full"):
            store.save(big.snapshot(7, T), SORTIE)
        assert store.failures == 1
        state, sortie, _ = store.load(T)
    assert sorted(z.zone_id for z in state.zones) == [3, 4] and sortie == SORTIE
