"""A file that is not a usable bandada database (random bytes, a damaged file, another
application's SQLite database, a newer schema) is refused with a clear error, never a
crash or a silent reset, and left byte for byte untouched."""

from __future__ import annotations

import os
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
    StorageError,
    SwarmDatabase,
    UnusableDatabaseError,
    inspect_file,
)
from tests.conftest import examples

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


@settings(max_examples=examples(30))
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


# ---------------------------------------------------------------------------- journal modes
# SQLite opens a WAL-mode file, even read-only, by creating `-wal` and `-shm` files beside
# it; a refused file is inspected as immutable instead, so nothing appears.


def _directory(path: Path) -> dict[str, tuple[bytes, int] | None]:
    """Every entry beside `path` (itself included), with each file's bytes and mtime."""
    return {p.name: snapshot(p) if p.is_file() else None for p in sorted(path.parent.iterdir())}


def _other_app(path: Path, journal_mode: str, *, checkpoint: bool = True) -> sqlite3.Connection:
    """Another application's database in `journal_mode`; returned open (its writer)."""
    conn = sqlite3.connect(path, isolation_level=None)
    assert conn.execute(f"PRAGMA journal_mode = {journal_mode}").fetchone()[0] == journal_mode
    if not checkpoint:
        conn.execute("PRAGMA wal_autocheckpoint = 0")
    conn.execute("CREATE TABLE notes (body TEXT)")
    conn.execute("INSERT INTO notes VALUES ('keep me')")
    return conn


@pytest.mark.parametrize("mode", ["wal", "persist", "truncate", "delete"])
def test_another_applications_file_in_any_journal_mode_is_untouched(
    tmp_path: Path, mode: str
) -> None:
    path = tmp_path / "app.db"
    _other_app(path, mode).close()  # WAL: the last close checkpoints, removes -wal/-shm
    before = _directory(path)
    with pytest.raises(ForeignDatabaseError, match=r"another application .*tables: notes"):
        SwarmDatabase.open(path)
    with pytest.raises(ForeignDatabaseError):
        inspect_file(path)
    assert _directory(path) == before, "the refused file or its directory changed"


def _copy_live(src: Path, dst: Path) -> None:
    """Copy a WAL database with its -wal and -shm files while its writer has it open:
    what another program, running or crashed, leaves on disk."""
    for suffix in ("", "-wal", "-shm"):
        Path(f"{dst}{suffix}").write_bytes(Path(f"{src}{suffix}").read_bytes())


def test_another_applications_live_wal_file_is_untouched(tmp_path: Path) -> None:
    src, path = tmp_path / "src" / "app.db", tmp_path / "app.db"
    src.parent.mkdir()
    conn = _other_app(src, "wal", checkpoint=False)
    conn.execute("PRAGMA application_id = 0x4d504258")  # committed into the -wal only
    try:
        _copy_live(src, path)
    finally:
        conn.close()
    assert Path(f"{path}-wal").stat().st_size > 0
    before = _directory(path)
    # the main file alone shows no tables and no id: its content is all in the -wal
    with pytest.raises(ForeignDatabaseError, match="WAL mode whose changes are still in its -wal"):
        SwarmDatabase.open(path)
    assert _directory(path) == before
    assert not (tmp_path / "app.db-journal").exists()


def test_our_file_in_wal_mode_opens_with_its_latest_commits(db_path: Path) -> None:
    conn = sqlite3.connect(db_path, isolation_level=None)
    conn.execute("PRAGMA journal_mode = WAL")
    conn.execute("PRAGMA wal_autocheckpoint = 0")
    conn.execute("INSERT INTO system_types (name) VALUES ('UUV')")  # in the -wal only
    copy = db_path.with_name("copy.db")
    try:
        _copy_live(db_path, copy)
    finally:
        conn.close()
    with SwarmDatabase.open(copy) as db:
        assert "UUV" in [r["name"] for r in db.records("systems.types")]
        db.add("systems.types", {"name": "UGV2"})
    with SwarmDatabase.open(copy) as db:
        assert db.counts()["systems.types"] == 6


def test_an_empty_wal_mode_file_becomes_a_database(tmp_path: Path) -> None:
    path = tmp_path / "swarm.db"
    conn = sqlite3.connect(path)
    conn.execute("PRAGMA journal_mode = WAL")
    conn.close()
    with SwarmDatabase.open(path) as db:
        assert db.created and db.counts()["systems.systems"] == 14


# ---------------------------------------------------------------------------- paths


@pytest.mark.parametrize(
    ("where", "match"),
    [
        ("a-file/swarm.db", "a-file is not a directory"),
        ("a-file/deeper/swarm.db", "a-file is not a directory"),
        ("a-fifo", "is not a regular file"),
        ("a-dir", "is a directory"),
    ],
)
def test_paths_that_cannot_hold_a_database(tmp_path: Path, where: str, match: str) -> None:
    (tmp_path / "a-file").write_text("notes")
    (tmp_path / "a-dir").mkdir()
    os.mkfifo(tmp_path / "a-fifo")
    before = sorted(p.name for p in tmp_path.iterdir())
    with pytest.raises(UnusableDatabaseError, match=match):
        SwarmDatabase.open(tmp_path / where)
    assert sorted(p.name for p in tmp_path.iterdir()) == before
    assert (tmp_path / "a-file").read_text() == "notes"


def test_a_directory_that_cannot_be_created(tmp_path: Path) -> None:
    if not Path("/proc/self").exists():
        pytest.skip("no /proc")
    with pytest.raises(StorageError, match=r"cannot create the directory /proc/bandada-nope"):
        SwarmDatabase.open("/proc/bandada-nope/deeper/swarm.db")
