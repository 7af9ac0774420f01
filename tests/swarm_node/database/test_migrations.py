"""Migrations: from nothing (a missing file, an empty file, an empty SQLite file) and from
the previous schema version (a frozen v1 file, and v1 built by the migrations list),
all in one transaction, with a backup; a current file is opened without a write."""

from __future__ import annotations

import sqlite3
from pathlib import Path

import pytest

from swarm_node.database import (
    ALBATROSS,
    LATEST_VERSION,
    SwarmDatabase,
    UnusableDatabaseError,
    inspect_file,
)
from swarm_node.database import repository as repo
from swarm_node.database.schema import APPLICATION_ID, MIGRATIONS, Migration, statements

from .conftest import snapshot

V1_DUMP = Path(__file__).parent / "data" / "swarm_v1.sql"


def _version(path: Path) -> tuple[int, int]:
    conn = sqlite3.connect(path)
    try:
        return (
            conn.execute("PRAGMA user_version").fetchone()[0],
            conn.execute("PRAGMA application_id").fetchone()[0],
        )
    finally:
        conn.close()


def _v1_from_dump(path: Path) -> None:
    conn = sqlite3.connect(path)
    conn.executescript(V1_DUMP.read_text())
    conn.close()


def _v1_from_migrations(path: Path) -> None:
    conn = sqlite3.connect(path, isolation_level=None)
    conn.execute("PRAGMA foreign_keys = ON")
    conn.execute("BEGIN")
    for stmt in statements(MIGRATIONS[0].sql):
        conn.execute(stmt)
    conn.execute("PRAGMA user_version = 1")
    conn.execute("INSERT INTO system_types (name) VALUES ('UAV')")
    conn.execute("INSERT INTO system_subtypes (type_id, name, vehicle_type) VALUES (1, 'VTOL', 2)")
    conn.execute(f"INSERT INTO system_models (subtype_id, name) VALUES (1, '{ALBATROSS}')")
    conn.execute(
        "INSERT INTO system_model_params (model_id, cruise_speed_m_s, min_speed_m_s, "
        "max_speed_m_s, loiter_radius_m) VALUES (1, 26, 15.5, 32, 80)"
    )
    conn.execute("INSERT INTO system_layouts (name, model_id) VALUES ('plain', 1)")
    conn.execute("INSERT INTO systems (id, user_id, layout_id) VALUES (4, 'ALB-04', 1)")
    conn.execute("COMMIT")
    conn.close()


@pytest.mark.parametrize("make", ["missing", "missing-dir", "empty-file", "empty-sqlite"])
def test_a_new_database_is_created_at_the_latest_version_with_seed_data(
    tmp_path: Path, make: str
) -> None:
    path = tmp_path / "swarm.db"
    if make == "missing-dir":
        path = tmp_path / "a" / "b" / "swarm.db"
    elif make == "empty-file":
        path.write_bytes(b"")
    elif make == "empty-sqlite":
        conn = sqlite3.connect(path)
        conn.execute("VACUUM")  # a valid SQLite file holding nothing
        conn.close()
        assert path.stat().st_size > 0
    with SwarmDatabase.open(path) as db:
        assert db.schema_version == LATEST_VERSION
        assert db.vehicle_profile(vehicle_id=1).model == ALBATROSS
    assert _version(path) == (LATEST_VERSION, APPLICATION_ID)
    assert inspect_file(path) == LATEST_VERSION


def test_open_without_seed_gives_an_empty_schema(tmp_path: Path) -> None:
    with SwarmDatabase.open(tmp_path / "x.db", seed=False) as db:
        assert sum(db.counts().values()) == 0


@pytest.mark.parametrize(
    "make_v1", [_v1_from_dump, _v1_from_migrations], ids=["frozen-dump", "migrations"]
)
def test_migrating_from_the_previous_version_keeps_every_record(
    tmp_path: Path, make_v1: object
) -> None:
    path = tmp_path / "swarm.db"
    make_v1(path)  # type: ignore[operator]
    assert inspect_file(path) == 1
    conn = sqlite3.connect(path)
    before = {
        t: conn.execute(f"SELECT COUNT(*) FROM {t}").fetchone()[0]
        for (t,) in conn.execute(
            "SELECT name FROM sqlite_schema WHERE type = 'table' AND name NOT LIKE 'sqlite_%'"
        ).fetchall()
    }
    conn.close()

    with SwarmDatabase.open(path) as db:
        assert db.schema_version == LATEST_VERSION
        counts = {t.sql: n for t, n in zip(repo.TABLES, db.counts().values(), strict=True)}
        for table, n in before.items():
            assert counts[table] == n, table  # nothing lost, nothing seeded on top
        assert counts["autodetection_classes"] == 0  # new in v2, empty
        profiles = db.profiles()
        assert profiles, "the migrated systems resolve"
        alb = next(p for p in profiles if p.model == ALBATROSS)
        assert (alb.cruise_speed_m_s, alb.min_speed_m_s) == (26.0, 15.5)
        # v2 columns take their defaults
        assert (alb.battery_low_pct, alb.battery_critical_pct, alb.max_tilt_deg) == (30, 15, 60.0)
        assert all(r["payload"] is None for r in db.records("systems.systems"))
    backup = tmp_path / "swarm.db.v1.bak"
    assert inspect_file(backup) == 1  # the copy taken before migrating
    assert _version(path) == (LATEST_VERSION, APPLICATION_ID)


def test_each_migration_applies_on_top_of_the_one_before(tmp_path: Path) -> None:
    """Every prefix of the migrations list is a valid database that opens to latest."""
    for n in range(1, len(MIGRATIONS)):
        path = tmp_path / f"v{n}.db"
        conn = sqlite3.connect(path, isolation_level=None)
        conn.execute("BEGIN")
        for m in MIGRATIONS[:n]:
            for stmt in statements(m.sql):
                conn.execute(stmt)
        conn.execute(f"PRAGMA user_version = {n}")
        conn.execute("COMMIT")
        conn.close()
        with SwarmDatabase.open(path) as db:
            assert db.schema_version == LATEST_VERSION


def test_a_failing_migration_changes_nothing(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = tmp_path / "swarm.db"
    _v1_from_dump(path)
    before = path.read_bytes()
    broken = (
        *MIGRATIONS,
        Migration(
            LATEST_VERSION + 1,
            "broken",
            "CREATE TABLE x (a INTEGER);\nSELECT nonsense FROM nowhere;",
        ),
    )
    monkeypatch.setattr(repo, "MIGRATIONS", broken)
    monkeypatch.setattr(repo, "LATEST_VERSION", LATEST_VERSION + 1)
    with pytest.raises(
        UnusableDatabaseError,
        match=rf"migrating schema v1 to v{LATEST_VERSION + 1} failed .*nothing was changed",
    ):
        SwarmDatabase.open(path)
    assert path.read_bytes() == before
    assert _version(path) == (1, APPLICATION_ID)


def test_opening_a_current_database_writes_nothing(db_path: Path) -> None:
    before = snapshot(db_path)
    with SwarmDatabase.open(db_path) as db:
        db.profiles()
        db.export()
    assert snapshot(db_path) == before
    assert not list(db_path.parent.glob("*.bak"))


def test_two_processes_creating_the_same_file_seed_it_once(tmp_path: Path) -> None:
    """The second opener finds the schema already there (re-checked under the lock)."""
    path = tmp_path / "swarm.db"
    first = SwarmDatabase.open(path)
    second = SwarmDatabase.open(path)
    try:
        assert first.counts() == second.counts()
        assert second.counts()["systems.systems"] == 14
    finally:
        first.close()
        second.close()
