"""A file that is not a usable bandada database (random bytes, a damaged file, another
application's SQLite database, a newer schema) is refused with a clear error, never a
crash or a silent reset, and left byte for byte untouched."""

from __future__ import annotations

import random
import sqlite3
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from swarm_node.database import (
    CorruptDatabaseError,
    ForeignDatabaseError,
    InterruptedWriteError,
    NewerSchemaError,
    SwarmDatabase,
    UnusableDatabaseError,
    inspect_file,
)

from .conftest import snapshot


def _assert_refused(path: Path, error: type[Exception], match: str) -> None:
    before = snapshot(path)
    siblings = sorted(p.name for p in path.parent.iterdir())
    with pytest.raises(error, match=match) as info:
        SwarmDatabase.open(path)
    assert str(path) in str(info.value)
    assert "left it untouched" in str(info.value) or error is UnusableDatabaseError
    assert snapshot(path) == before, "the refused file was modified"
    assert sorted(p.name for p in path.parent.iterdir()) == siblings, "files appeared beside it"


@pytest.mark.parametrize("seed", range(5))
def test_random_bytes_are_refused(tmp_path: Path, seed: int) -> None:
    path = tmp_path / "swarm.db"
    rng = random.Random(seed)
    path.write_bytes(bytes(rng.getrandbits(8) for _ in range(rng.randint(1, 9000))))
    _assert_refused(path, CorruptDatabaseError, "not an SQLite database file")


@settings(max_examples=30)
@given(data=st.binary(min_size=1, max_size=5000))
def test_any_bytes_are_refused_or_opened_never_crash(
    tmp_path_factory: pytest.TempPathFactory, data: bytes
) -> None:
    path = tmp_path_factory.mktemp("any") / "swarm.db"
    path.write_bytes(data)
    before = snapshot(path)
    with pytest.raises(UnusableDatabaseError):
        SwarmDatabase.open(path)
    assert snapshot(path) == before


def test_an_sqlite_header_over_garbage_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "swarm.db"
    rng = random.Random(7)
    path.write_bytes(b"SQLite format 3\x00" + bytes(rng.getrandbits(8) for _ in range(8192)))
    _assert_refused(path, CorruptDatabaseError, "damaged SQLite file")


def test_a_truncated_database_is_refused(db_path: Path) -> None:
    data = db_path.read_bytes()
    db_path.write_bytes(data[: len(data) // 2])
    _assert_refused(db_path, CorruptDatabaseError, "damaged SQLite file")


def test_a_damaged_page_is_refused(db_path: Path) -> None:
    data = bytearray(db_path.read_bytes())
    page = int.from_bytes(data[16:18], "big")
    for i in range(page * 3, page * 4):  # overwrite the fourth page with noise
        data[i] = (i * 131) & 0xFF
    db_path.write_bytes(bytes(data))
    _assert_refused(db_path, CorruptDatabaseError, "damaged SQLite file")


def test_another_applications_sqlite_file_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "places.sqlite"
    conn = sqlite3.connect(path)
    conn.execute("CREATE TABLE moz_places (id INTEGER PRIMARY KEY, url TEXT)")
    conn.execute("INSERT INTO moz_places (url) VALUES ('https://example.org')")
    conn.commit()
    conn.close()
    _assert_refused(path, ForeignDatabaseError, r"another application .*tables: moz_places")


def test_a_file_with_another_application_id_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "tiles.mbtiles"
    conn = sqlite3.connect(path)
    conn.execute("PRAGMA application_id = 0x4d504258")  # MBTiles
    conn.commit()
    conn.close()
    _assert_refused(path, ForeignDatabaseError, "application_id 0x4d504258")


def test_a_newer_schema_is_refused(db_path: Path) -> None:
    conn = sqlite3.connect(db_path)
    conn.execute("PRAGMA user_version = 99")
    conn.commit()
    conn.close()
    _assert_refused(db_path, NewerSchemaError, "newer bandada .*schema version 99.*upgrade bandada")


def test_our_id_without_a_version_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "swarm.db"
    conn = sqlite3.connect(path)
    conn.execute("PRAGMA application_id = 1111576132")
    conn.commit()
    conn.close()
    _assert_refused(path, CorruptDatabaseError, "no schema version")


def test_a_directory_is_refused(tmp_path: Path) -> None:
    with pytest.raises(UnusableDatabaseError, match="is a directory"):
        SwarmDatabase.open(tmp_path)


def test_refusals_are_unusable_database_errors() -> None:
    for e in (CorruptDatabaseError, ForeignDatabaseError, NewerSchemaError):
        assert issubclass(e, UnusableDatabaseError)


def _interrupted_copy(src: Path, dst: Path, table: str) -> None:
    """Copy `src` with the journal of a write in progress: what a crash leaves behind."""
    conn = sqlite3.connect(src, isolation_level=None)
    conn.execute("PRAGMA cache_size = 1")  # spill pages into the file mid-transaction
    conn.execute("BEGIN")
    for i in range(2000):
        conn.execute(f"INSERT INTO {table} (name, description) VALUES (?, ?)", (f"T{i}", "x" * 500))
    dst.write_bytes(src.read_bytes())
    Path(f"{dst}-journal").write_bytes(Path(f"{src}-journal").read_bytes())
    conn.execute("ROLLBACK")
    conn.close()


def test_our_file_after_a_crash_mid_write_is_rolled_back_not_refused(db_path: Path) -> None:
    crashed = db_path.with_name("crashed.db")
    _interrupted_copy(db_path, crashed, "system_types")
    with pytest.raises(InterruptedWriteError):
        inspect_file(crashed)
    with SwarmDatabase.open(crashed) as db:  # SQLite's crash recovery: last commit
        assert db.counts()["systems.types"] == 4
    assert not Path(f"{crashed}-journal").exists()


def test_another_applications_file_after_a_crash_is_refused_untouched(tmp_path: Path) -> None:
    src = tmp_path / "app.db"
    conn = sqlite3.connect(src)
    conn.execute("CREATE TABLE things (name TEXT, description TEXT)")
    conn.commit()
    conn.close()
    crashed = tmp_path / "crashed.db"
    _interrupted_copy(src, crashed, "things")
    journal = Path(f"{crashed}-journal")
    before = snapshot(crashed), journal.read_bytes()
    with pytest.raises(ForeignDatabaseError, match="interrupted write"):
        SwarmDatabase.open(crashed)
    assert (snapshot(crashed), journal.read_bytes()) == before
