"""`SwarmDatabase`: the swarm database on an SQLite file (or in memory).

Opening a file never harms it: a file that is not ours (random bytes, another
application's SQLite database, a newer bandada's schema, a damaged file) is inspected
read-only (immutable when in WAL mode, so that no -wal or -shm file appears beside it)
and refused with an `UnusableDatabaseError`, byte for byte untouched; a file that
cannot be read or written (permissions, a read-only filesystem) is a `StorageError`. A
missing or empty file becomes a new database with the seed data; an older bandada file
is copied to `<file>.v<N>.bak` and migrated, all in one transaction.

Two views of the same data:
- records (the CLI, the JSON export, the queryable): `records`, `get`, `add`,
  `remove`, `export`, `import_document`, where references are keys (names, ids);
- what a node needs: `vehicle_profile`, `profiles`, `payload_class`,
  `system_params`, `module_params`, `mission_defaults`.

One connection, guarded by a lock, so the Zenoh queryable may read from its own thread.
"""

from __future__ import annotations

import contextlib
import difflib
import functools
import os
import sqlite3
import stat
import threading
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any, TypeGuard

from swarm_node.core.profile import PayloadClass, VehicleProfile
from swarm_proto import MissionType

from . import seed as seed_data
from .document import FORMAT, Record, check_document
from .errors import (
    AmbiguousError,
    ConstraintError,
    CorruptDatabaseError,
    DuplicateError,
    ForeignDatabaseError,
    InterruptedWriteError,
    InUseError,
    InvalidValueError,
    NewerSchemaError,
    NotFoundError,
    ProfileError,
    RecordError,
    StorageError,
    SwarmDbError,
    UnknownReferenceError,
    UnusableDatabaseError,
    shown,
)
from .paths import resolve_db_path
from .resolve import PROFILE_SQL, profile_from_row
from .schema import APPLICATION_ID, LATEST_VERSION, MIGRATIONS, MIN_SQLITE, statements
from .tables import (
    BY_NAME,
    GROUPS,
    TABLES,
    WRITE_ORDER,
    Column,
    Table,
    check_fields,
    convert,
    referrers,
    show_enum,
    table,
    tables_of,
)

SQLITE_MAGIC = b"SQLite format 3\x00"
LOCK_TIMEOUT_S = 10.0


def _dict_row(cursor: sqlite3.Cursor, row: tuple[Any, ...]) -> dict[str, Any]:
    return {d[0]: v for d, v in zip(cursor.description, row, strict=True)}


def _refuse(path: Path, why: str) -> str:
    return (
        f"{path}: {why}. bandada refuses to use it and left it untouched; "
        "move it away or choose another file (--db PATH or BANDADA_DB)"
    )


def _why(exc: OSError | sqlite3.Error) -> str:
    if isinstance(exc, OSError):
        return exc.strerror or str(exc)
    return str(exc)


def _cannot(path: Path | str, what: str, exc: OSError | sqlite3.Error) -> StorageError:
    return StorageError(
        f"{path}: cannot {what} ({_why(exc)}); nothing was changed. Check the file's and "
        "its directory's permissions and free space, or choose another file "
        "(--db PATH or BANDADA_DB)"
    )


def _sidecar(path: Path, suffix: str) -> Path:
    return path.with_name(path.name + suffix)


def _sidecar_bytes(path: Path, suffix: str) -> int:
    try:
        return _sidecar(path, suffix).stat().st_size
    except OSError:
        return 0


def _read_meta(path: Path, *, immutable: bool) -> tuple[list[str], int, int, list[str]]:
    """quick_check, application_id, user_version and table names, through a read-only
    connection. `immutable` tells SQLite the file cannot change: it then takes no lock
    and opens no journal, WAL or shared-memory file beside it (a WAL-mode file opened
    merely read-only gets `-wal` and `-shm` files created next to it)."""
    uri = f"{path.resolve().as_uri()}?mode=ro" + ("&immutable=1" if immutable else "")
    conn = sqlite3.connect(uri, uri=True)
    try:
        check = [r[0] for r in conn.execute("PRAGMA quick_check").fetchall()]
        app_id = int(conn.execute("PRAGMA application_id").fetchone()[0])
        version = int(conn.execute("PRAGMA user_version").fetchone()[0])
        names = [
            r[0]
            for r in conn.execute(
                "SELECT name FROM sqlite_schema WHERE type = 'table' "
                "AND name NOT LIKE 'sqlite_%' ORDER BY name"
            )
        ]
    finally:
        conn.close()
    return check, app_id, version, names


def inspect_file(path: Path) -> int | None:
    """The schema version of a bandada database file, or None when the file is to be
    created (missing, empty, or an SQLite file with nothing in it). Reads only, and
    creates nothing beside the file. Raises CorruptDatabaseError,
    ForeignDatabaseError, NewerSchemaError, StorageError (cannot be read), or
    InterruptedWriteError for our file with a hot journal (`SwarmDatabase.open` lets
    SQLite roll that write back, as after any crash)."""
    try:
        st = path.stat()
    except (FileNotFoundError, NotADirectoryError):
        return None
    except OSError as exc:
        raise _cannot(path, "read it", exc) from None
    if stat.S_ISDIR(st.st_mode):
        raise UnusableDatabaseError(_refuse(path, "is a directory, not a database file"))
    if not stat.S_ISREG(st.st_mode):
        raise UnusableDatabaseError(
            _refuse(path, "is not a regular file (a device, a pipe or a socket)")
        )
    if st.st_size == 0:
        return None
    try:
        with path.open("rb") as f:
            header = f.read(100)
    except OSError as exc:
        raise _cannot(path, "read it", exc) from None
    if len(header) < 100 or not header.startswith(SQLITE_MAGIC):
        raise CorruptDatabaseError(_refuse(path, "is not an SQLite database file"))
    # Bytes 18-19: 1 = rollback journal (ours), 2 = WAL. A WAL-mode file is read as
    # immutable, so that no -wal/-shm file appears beside a file that is not ours.
    wal_mode = 2 in (header[18], header[19])
    try:
        check, app_id, version, names = _read_meta(path, immutable=wal_mode)
        if wal_mode and app_id == APPLICATION_ID and _sidecar_bytes(path, "-wal"):
            # ours, put in WAL mode by hand, with commits still in its -wal: read them
            check, app_id, version, names = _read_meta(path, immutable=False)
    except sqlite3.Error as exc:
        if getattr(exc, "sqlite_errorname", "") == "SQLITE_READONLY_ROLLBACK":
            # A write was interrupted (crash, power loss): a hot journal lies beside it.
            if int.from_bytes(header[68:72], "big", signed=True) == APPLICATION_ID:
                raise InterruptedWriteError(
                    _refuse(path, "has an interrupted write (a journal file beside it)")
                ) from None
            raise ForeignDatabaseError(
                _refuse(
                    path,
                    "is an SQLite database of another application with an interrupted "
                    "write (a journal file beside it)",
                )
            ) from None
        raise CorruptDatabaseError(_refuse(path, f"is a damaged SQLite file ({exc})")) from None
    if check != ["ok"]:
        detail = "; ".join(check[:3])
        raise CorruptDatabaseError(_refuse(path, f"is a damaged SQLite file ({detail})"))
    if app_id != APPLICATION_ID:
        if app_id == 0 and not names and version == 0:
            if wal_mode and _sidecar_bytes(path, "-wal"):
                raise ForeignDatabaseError(
                    _refuse(
                        path,
                        "is an SQLite database in WAL mode whose changes are still in its "
                        "-wal file (another program has it open, or crashed); bandada "
                        "cannot tell whose it is without writing to it",
                    )
                )
            return None
        shown = ", ".join(names[:8]) + (", ..." if len(names) > 8 else "")
        raise ForeignDatabaseError(
            _refuse(
                path,
                f"is an SQLite database of another application (application_id "
                f"{app_id:#x}, tables: {shown or 'none'}), not a bandada swarm database",
            )
        )
    if version > LATEST_VERSION:
        raise NewerSchemaError(
            _refuse(
                path,
                f"was written by a newer bandada (schema version {version}; this one "
                f"knows up to {LATEST_VERSION}): upgrade bandada to use it",
            )
        )
    if version < 1:
        raise CorruptDatabaseError(_refuse(path, "carries bandada's id but no schema version"))
    return int(version)


def _recover(path: Path) -> int | None:
    """Let SQLite roll back an interrupted write of our file (its crash recovery: the
    file returns to its last committed state), then inspect it again."""
    try:
        conn = sqlite3.connect(str(path), timeout=LOCK_TIMEOUT_S)
        try:
            conn.execute("PRAGMA quick_check").fetchall()
        finally:
            conn.close()
    except sqlite3.Error as exc:
        raise CorruptDatabaseError(
            _refuse(path, f"has an interrupted write SQLite could not roll back ({exc})")
        ) from None
    return inspect_file(path)


def _is_storage_failure(exc: BaseException) -> TypeGuard[sqlite3.DatabaseError]:
    """An SQLite error that is the file's or the system's fault, not a broken rule
    nor a bug (IntegrityError, ProgrammingError)."""
    return isinstance(exc, sqlite3.DatabaseError) and not isinstance(
        exc, (sqlite3.IntegrityError, sqlite3.ProgrammingError)
    )


def _check_sqlite() -> None:
    if sqlite3.sqlite_version_info < MIN_SQLITE:
        raise SwarmDbError(
            f"SQLite {sqlite3.sqlite_version} is too old: the swarm database needs "
            f"{'.'.join(map(str, MIN_SQLITE))} or newer (STRICT tables)"
        )


def _exists(path: Path) -> bool:
    try:
        path.stat()
    except (FileNotFoundError, NotADirectoryError):
        return False
    except OSError as exc:
        raise _cannot(path, "read it", exc) from None
    return True


def _make_parents(path: Path) -> list[Path]:
    """Create the directories a new database file needs; returns those created, the
    deepest first (removed again if the database cannot be created)."""
    missing: list[Path] = []
    parent = path.parent
    while not _exists(parent):
        missing.append(parent)
        if parent.parent == parent:
            break
        parent = parent.parent
    if not _is_dir(parent):
        raise StorageError(
            f"{path}: cannot create it: {parent} is not a directory; nothing was changed"
        )
    made: list[Path] = []
    for d in reversed(missing):
        try:
            d.mkdir()
        except FileExistsError:  # another process made it meanwhile
            continue
        except OSError as exc:
            _remove_dirs(list(reversed(made)))
            raise _cannot(path, f"create the directory {d}", exc) from None
        made.append(d)
    return list(reversed(made))


def _is_dir(path: Path) -> bool:
    try:
        return stat.S_ISDIR(path.stat().st_mode)
    except OSError:
        return False


def _remove_dirs(dirs: list[Path]) -> None:
    for d in dirs:  # deepest first; only if still empty
        with contextlib.suppress(OSError):
            d.rmdir()


class SwarmDatabase:
    """The swarm database. Open with `SwarmDatabase.open(path)` or `.memory()`."""

    def __init__(self, conn: sqlite3.Connection, path: Path | None) -> None:
        self._conn = conn
        self._lock = threading.RLock()
        self.path = path
        self.created = False  # True when `open` created this database (with the seed data)

    # ------------------------------------------------------------------ opening
    @classmethod
    def open(
        cls,
        path: str | os.PathLike[str] | None = None,
        *,
        seed: bool = True,
        create: bool = True,
    ) -> SwarmDatabase:
        """Open (creating, seeding or migrating as needed) the database at `path`
        (default: `--db` / `$BANDADA_DB` / the per-user path, see `paths.py`)."""
        _check_sqlite()
        p = resolve_db_path(path)
        try:
            version = inspect_file(p)
        except InterruptedWriteError:  # ours: SQLite's own crash recovery
            version = _recover(p)
        if version is None and not create:
            raise NotFoundError(f"{p}: no swarm database here (and create=False)")
        existed = version is not None or _exists(p)
        made = [] if existed else _make_parents(p)
        if version is not None and version < LATEST_VERSION:
            backup = p.with_name(f"{p.name}.v{version}.bak")
            try:
                _backup(p, backup)
            except (OSError, sqlite3.Error) as exc:
                raise StorageError(
                    f"{p}: cannot write the backup {backup} before migrating ({_why(exc)}); "
                    "nothing was changed"
                ) from None
        try:
            conn = sqlite3.connect(
                str(p), timeout=LOCK_TIMEOUT_S, isolation_level=None, check_same_thread=False
            )
        except sqlite3.Error as exc:
            _remove_dirs(made)
            raise _cannot(p, "open it", exc) from None
        db = cls(conn, p)
        try:
            try:
                db._setup(seed=seed)
            except sqlite3.Error as exc:
                raise _cannot(p, "open it", exc) from None
        except BaseException:
            conn.close()
            if not existed:
                with contextlib.suppress(OSError):
                    if p.stat().st_size == 0:
                        p.unlink()
                _remove_dirs(made)
            raise
        db.created = version is None
        return db

    @classmethod
    def memory(cls, *, seed: bool = True) -> SwarmDatabase:
        """A private in-memory database (tests, the simulator), seeded by default."""
        _check_sqlite()
        conn = sqlite3.connect(":memory:", isolation_level=None, check_same_thread=False)
        db = cls(conn, None)
        db._setup(seed=seed)
        return db

    def _setup(self, *, seed: bool) -> None:
        conn = self._conn
        conn.row_factory = _dict_row
        conn.execute("PRAGMA foreign_keys = ON")
        if self._version() == LATEST_VERSION and self._app_id() == APPLICATION_ID:
            return  # the usual case: nothing to write
        try:
            conn.execute("BEGIN IMMEDIATE")
        except sqlite3.Error as exc:
            raise _cannot(self._name(), "lock it for writing", exc) from None
        try:
            version = self._version()  # again, under the write lock
            self._check_ours(version)
            for m in MIGRATIONS[version:]:
                try:
                    for stmt in statements(m.sql):
                        conn.execute(stmt)
                    conn.execute(f"PRAGMA user_version = {m.version:d}")
                except sqlite3.Error as exc:
                    raise UnusableDatabaseError(
                        f"{self.path or 'memory'}: migrating schema v{version} to v{m.version} "
                        f"failed ({exc}); nothing was changed"
                    ) from None
            if version == 0 and seed:
                self._import(check_document(seed_data.document(), "seed data"), replace=False)
            self._check_foreign_keys()
            conn.execute("COMMIT")
        except BaseException:
            self._rollback()
            raise

    def _check_ours(self, version: int) -> None:
        if version > LATEST_VERSION:
            raise NewerSchemaError(
                f"{self.path}: schema version {version} is newer than this bandada's "
                f"({LATEST_VERSION}): upgrade bandada"
            )
        app_id = self._app_id()
        if version == 0:
            tables = self._conn.execute(
                "SELECT name FROM sqlite_schema WHERE name NOT LIKE 'sqlite_%'"
            ).fetchall()
            if tables or app_id not in (0, APPLICATION_ID):
                raise ForeignDatabaseError(f"{self.path}: not a bandada swarm database")
        elif app_id != APPLICATION_ID:
            raise ForeignDatabaseError(f"{self.path}: not a bandada swarm database")

    def _version(self) -> int:
        return int(self._conn.execute("PRAGMA user_version").fetchone()["user_version"])

    def _app_id(self) -> int:
        return int(self._conn.execute("PRAGMA application_id").fetchone()["application_id"])

    def _check_foreign_keys(self) -> None:
        bad = self._conn.execute("PRAGMA foreign_key_check").fetchall()
        if bad:
            first = bad[0]
            raise UnknownReferenceError(
                f"{len(bad)} broken reference(s), e.g. {first['table']} row {first['rowid']} "
                f"-> {first['parent']}"
            )

    @property
    def schema_version(self) -> int:
        with self._reading():
            return self._version()

    def close(self) -> None:
        with self._lock:
            self._conn.close()

    def __enter__(self) -> SwarmDatabase:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    @contextmanager
    def _write(self) -> Iterator[sqlite3.Connection]:
        """One write transaction: all or nothing. An SQLite failure that is not a
        broken rule (a read-only file, a full disk, a lock held too long) rolls back
        and becomes a StorageError."""
        with self._lock:
            try:
                self._conn.execute("BEGIN IMMEDIATE")
            except sqlite3.Error as exc:
                raise _cannot(self._name(), "lock it for writing", exc) from None
            try:
                yield self._conn
                self._conn.execute("COMMIT")
            except BaseException as exc:
                self._rollback()
                if isinstance(exc, sqlite3.IntegrityError):
                    raise ConstraintError(f"{self._name()}: {exc}") from None
                if _is_storage_failure(exc):
                    raise _cannot(self._name(), "write to it", exc) from None
                raise

    @contextmanager
    def _reading(self) -> Iterator[sqlite3.Connection]:
        """The connection, for reads: a failure of the file (a lock held too long, an
        I/O error, damage found late) becomes a StorageError."""
        with self._lock:
            try:
                yield self._conn
            except sqlite3.Error as exc:
                if _is_storage_failure(exc):
                    raise _cannot(self._name(), "read it", exc) from None
                raise

    def _rollback(self) -> None:
        if self._conn.in_transaction:  # SQLite rolls back by itself after some errors
            with contextlib.suppress(sqlite3.Error):
                self._conn.execute("ROLLBACK")

    def _name(self) -> str:
        return str(self.path) if self.path else "in-memory database"

    # ------------------------------------------------------------------ node state
    def node_state_rows(self, node_id: int) -> list[tuple[str, str, float, bytes]]:
        """Node `node_id`'s stored declared state: (kind, key, stamp, payload) rows
        (`state.py` decodes them)."""
        with self._reading():
            rows = self._conn.execute(
                "SELECT kind, key, stamp_unix_s, payload FROM node_declared WHERE node_id = ? "
                "ORDER BY kind, key",
                (node_id,),
            ).fetchall()
        return [(r["kind"], r["key"], float(r["stamp_unix_s"]), bytes(r["payload"])) for r in rows]

    def write_node_state(self, node_id: int, rows: Sequence[tuple[str, str, float, bytes]]) -> None:
        """Replace node `node_id`'s stored declared state with `rows`, in one transaction
        (all or nothing: a full disk leaves the previous state whole; StorageError)."""
        with self._write() as conn:
            conn.execute("DELETE FROM node_declared WHERE node_id = ?", (node_id,))
            conn.executemany(
                "INSERT INTO node_declared (node_id, kind, key, stamp_unix_s, payload) "
                "VALUES (?, ?, ?, ?, ?)",
                [(node_id, k, key, max(0.0, st), p) for k, key, st, p in rows],
            )

    # ------------------------------------------------------------------ records
    def counts(self) -> dict[str, int]:
        """Number of records per table ("group.table")."""
        with self._reading():
            return {
                t.qualname: self._conn.execute(f"SELECT COUNT(*) AS n FROM {t.sql}").fetchone()["n"]
                for t in TABLES
            }

    def records(self, t: Table | str, **where: Any) -> list[Record]:
        """Every record of a table in insertion order; `where` keeps the records whose
        fields equal the given values."""
        t = _table(t)
        for name in where:
            t.column(name)
        with self._reading():
            rows = self._conn.execute(f"SELECT * FROM {t.sql} ORDER BY rowid").fetchall()
            out = self._to_records(t, rows)
        return [r for r in out if all(r[k] == v for k, v in where.items())]

    def group(self, group: str) -> dict[str, list[Record]]:
        return {t.name: self.records(t) for t in tables_of(group)}

    def get(self, t: Table | str, *key: Any, text: bool = False) -> Record:
        """One record by its key fields (or, for systems and payloads, by id or by user
        id alone when that is unambiguous). `text=True` parses command-line text."""
        t = _table(t)
        with self._reading():
            rowid = self._lookup(t, key, text)
            row = self._conn.execute(f"SELECT * FROM {t.sql} WHERE rowid = ?", (rowid,)).fetchall()
            return self._to_records(t, row)[0]

    def add(self, t: Table | str, record: Mapping[str, Any], *, text: bool = False) -> Record:
        """Insert one record; returns it as stored. A system or payload without an id
        gets the lowest free one."""
        t = _table(t)
        with self._write() as conn:
            values = self._to_sql(t, record, text)
            if t.auto_id and "id" not in values:
                values = {"id": self._free_id(t), **values}
            cols = ", ".join(values)
            marks = ", ".join("?" for _ in values)
            try:
                cur = conn.execute(
                    f"INSERT INTO {t.sql} ({cols}) VALUES ({marks})", tuple(values.values())
                )
            except sqlite3.IntegrityError as exc:
                raise _integrity_error(t, exc, record) from None
            row = conn.execute(
                f"SELECT * FROM {t.sql} WHERE rowid = ?", (cur.lastrowid,)
            ).fetchall()
            return self._to_records(t, row)[0]

    def remove(self, t: Table | str, *key: Any, text: bool = False) -> Record:
        """Delete one record (its own parameters go with it); refused while other
        records use it. Returns the removed record."""
        t = _table(t)
        with self._write() as conn:
            rowid = self._lookup(t, key, text)
            row = conn.execute(f"SELECT * FROM {t.sql} WHERE rowid = ?", (rowid,)).fetchall()
            record = self._to_records(t, row)[0]
            users = self._users(t, rowid)
            if users:
                raise InUseError(
                    f"{t.qualname} {_key_text(t, record)} is still used by {'; '.join(users)}: "
                    "remove or change those first"
                )
            try:
                conn.execute(f"DELETE FROM {t.sql} WHERE rowid = ?", (rowid,))
            except sqlite3.IntegrityError as exc:
                raise InUseError(f"{t.qualname} {_key_text(t, record)}: {exc}") from None
            return record

    def export(self, groups: Sequence[str] | None = None) -> dict[str, Any]:
        """The export document of every group (or of the given ones)."""
        chosen = list(GROUPS) if not groups else [g for g in GROUPS if g in groups]
        for g in groups or ():
            tables_of(g)  # unknown group -> UnknownTableError
        with self._reading():
            return {
                "format": FORMAT,
                "schema_version": self._version(),
                "groups": {g: self.group(g) for g in chosen},
            }

    def import_document(
        self, doc: Any, *, replace: bool = False, source: str = "document"
    ) -> dict[str, int]:
        """Write a document's records in one transaction: all or nothing. A record whose
        key exists replaces it; others are added. `replace=True` also removes, from every
        table the document holds, the records it does not hold (refused while records of
        other tables use them). Returns the number of records written per table."""
        items = check_document(doc, source)
        with self._write():
            return self._import(items, replace=replace, source=source)

    def _import(
        self, items: list[tuple[Table, list[Record]]], *, replace: bool, source: str = "document"
    ) -> dict[str, int]:
        by_table = {t.qualname: recs for t, recs in items}
        written: dict[str, int] = {}
        kept: dict[str, set[int]] = {}
        for t in WRITE_ORDER:
            for i, record in enumerate(by_table.get(t.qualname, ())):
                try:
                    rowid = self._upsert(t, record)
                except RecordError as exc:
                    raise type(exc)(f"{source}: {t.qualname}[{i}]: {exc}") from None
                kept.setdefault(t.qualname, set()).add(rowid)
                written[t.qualname] = written.get(t.qualname, 0) + 1
        if replace:  # then drop what the document does not hold, users first
            for t in reversed(WRITE_ORDER):
                if t.qualname not in by_table:
                    continue
                keep = kept.get(t.qualname, set())
                rows = self._conn.execute(f"SELECT rowid AS r FROM {t.sql}").fetchall()
                for rowid in (r["r"] for r in rows if r["r"] not in keep):
                    users = self._users(t, rowid)
                    if users:
                        raise InUseError(
                            f"{source}: cannot replace {t.qualname}: a record the document "
                            f"does not hold is still used by {'; '.join(users)}"
                        )
                    self._conn.execute(f"DELETE FROM {t.sql} WHERE rowid = ?", (rowid,))
        self._check_foreign_keys()
        return written

    # ------------------------------------------------------------------ node view
    def vehicle_profile(
        self,
        vehicle_id: int | None = None,
        *,
        user_id: str | None = None,
        model: str | None = None,
    ) -> VehicleProfile:
        """A system's identity and planning parameters: by node id, or by user id (and
        model, when the user id alone names several systems)."""
        args: list[Any]
        if vehicle_id is not None:
            where, args, what = "s.id = ?", [vehicle_id], f"id {shown(vehicle_id)}"
            if not isinstance(vehicle_id, int) or not 1 <= vehicle_id <= 65534:
                where, args = "0", []  # no node has it (and SQLite takes 64-bit ints only)
        elif user_id is not None:
            where, args, what = "s.user_id = ?", [user_id], f"user id {user_id!r}"
            if model is not None:
                where += " AND sm.name = ?"
                args.append(model)
                what += f" and model {model!r}"
        else:
            raise TypeError("vehicle_profile: give vehicle_id, or user_id (and model)")
        with self._reading():
            rows = self._conn.execute(f"{PROFILE_SQL} WHERE {where} ORDER BY s.id", args).fetchall()
        if not rows:
            raise ProfileError(f"no system with {what} in the swarm database{self._where()}")
        if len(rows) > 1:
            ids = ", ".join(f"{r['vehicle_id']} ({r['model']})" for r in rows)
            raise ProfileError(f"{what} names several systems: {ids}; give the model or the id")
        return profile_from_row(rows[0])

    def profiles(self) -> list[VehicleProfile]:
        """The profile of every system (ground stations included), by id."""
        with self._reading():
            rows = self._conn.execute(f"{PROFILE_SQL} ORDER BY s.id").fetchall()
        return [profile_from_row(r) for r in rows]

    def payload_class(self, model: str) -> PayloadClass:
        """Type and subtype of a payload model (what voting compares)."""
        classes = self.payload_classes()
        if model not in classes:
            raise ProfileError(f"unknown payload model {model!r}{_suggest(model, list(classes))}")
        return classes[model]

    def payload_classes(self) -> dict[str, PayloadClass]:
        """Every payload model's class, by model name."""
        with self._reading():
            rows = self._conn.execute(
                "SELECT pm.name AS model, ps.name AS subtype, pt.name AS type "
                "FROM payload_models pm JOIN payload_subtypes ps ON ps.id = pm.subtype_id "
                "JOIN payload_types pt ON pt.id = ps.type_id ORDER BY pm.id"
            ).fetchall()
        return {r["model"]: PayloadClass(r["type"], r["subtype"], r["model"]) for r in rows}

    def system_params(self, vehicle_id: int) -> dict[str, str]:
        """A system's own parameters (mav_sysid, mac_address, ...)."""
        with self._reading():
            rows = self._conn.execute(
                "SELECT name, value FROM system_params WHERE system_id = ? ORDER BY rowid",
                (vehicle_id,),
            ).fetchall()
        return {r["name"]: r["value"] for r in rows}

    def module_params(self, module: str) -> dict[str, float]:
        """A swarm module's parameters, e.g. module_params("voting")."""
        with self._reading():
            found = self._conn.execute(
                "SELECT id FROM modules WHERE name = ?", (module,)
            ).fetchone()
            if found is None:
                names = [r["name"] for r in self._conn.execute("SELECT name FROM modules")]
                raise ProfileError(f"unknown swarm module {module!r}{_suggest(module, names)}")
            rows = self._conn.execute(
                "SELECT name, value FROM module_params WHERE module_id = ? ORDER BY rowid",
                (found["id"],),
            ).fetchall()
        return {r["name"]: float(r["value"]) for r in rows}

    def mission_defaults(self, mission_type: MissionType) -> dict[str, float]:
        """Default parameters of a kind of mission (MissionParams field names); {} if
        the database has none."""
        with self._reading():
            rows = self._conn.execute(
                "SELECT p.name, p.value FROM mission_params p JOIN missions m ON m.id = p.mission_id "
                "WHERE m.mission_type = ? ORDER BY p.rowid",
                (int(mission_type),),
            ).fetchall()
        return {r["name"]: float(r["value"]) for r in rows}

    # ------------------------------------------------------------------ internals
    def _where(self) -> str:
        return f" ({self.path})" if self.path else ""

    def _to_records(self, t: Table, rows: list[dict[str, Any]]) -> list[Record]:
        maps = {c.ref: self._key_map(BY_NAME[c.ref]) for c in t.columns if c.ref}
        out = []
        for row in rows:
            rec: Record = {}
            for c in t.columns:
                v = row[c.sql]
                if c.ref and v is not None:
                    v = maps[c.ref].get(v, v)
                rec[c.name] = show_enum(c, v)
            out.append(rec)
        return out

    def _key_map(self, target: Table) -> dict[int, Any]:
        kcol = target.by_column[target.key[0]]
        rows = self._conn.execute(f"SELECT id, {kcol.sql} AS k FROM {target.sql}").fetchall()
        return {r["id"]: r["k"] for r in rows}

    def _ref_id(self, t: Table, col: Column, value: Any) -> int:
        assert col.ref is not None
        target = BY_NAME[col.ref]
        kcol = target.by_column[target.key[0]]
        row = self._conn.execute(
            f"SELECT id FROM {target.sql} WHERE {kcol.sql} = ?", (value,)
        ).fetchone()
        if row is None:
            known = [
                r["k"]
                for r in self._conn.execute(
                    f"SELECT {kcol.sql} AS k FROM {target.sql} ORDER BY rowid"
                ).fetchall()
            ]
            raise UnknownReferenceError(
                f"{t.qualname}: {col.name} {shown(value)} not found in {target.qualname}"
                f"{_suggest(value, known)}"
            )
        return int(row["id"])

    def _to_sql(self, t: Table, record: Mapping[str, Any], text: bool) -> dict[str, Any]:
        if not isinstance(record, Mapping):
            raise InvalidValueError(f"{t.qualname}: a record must be an object of fields")
        check_fields(t, record)
        out: dict[str, Any] = {}
        for c in t.columns:
            if c.name in record:
                v = convert(t, c, record[c.name], text=text)
            elif c.required:
                raise InvalidValueError(
                    f"{t.qualname}: field {c.name!r} is required "
                    f"(fields: {', '.join(t.field_names)})"
                )
            else:
                v = c.default
            if c.name == "id" and t.auto_id and v is None:
                continue  # SQLite assigns the next id
            if c.ref and v is not None:
                v = self._ref_id(t, c, v)
            if c.kind == "bool" and v is not None:
                v = int(v)
            out[c.sql] = v
        return out

    def _free_id(self, t: Table) -> int:
        """The lowest unused id (node ids stay small and dense: ground stations and
        vehicles added later do not push them up)."""
        row = self._conn.execute(
            f"SELECT MIN(id + 1) AS free FROM (SELECT 0 AS id UNION ALL SELECT id FROM {t.sql}) "
            f"WHERE id + 1 NOT IN (SELECT id FROM {t.sql})"
        ).fetchone()
        return int(row["free"])

    def _lookup(self, t: Table, key: Sequence[Any], text: bool) -> int:
        """The rowid of the record with this key (see `get`)."""
        if t.auto_id and len(key) == 1 and isinstance(key[0], str) and not key[0].strip().isdigit():
            rows = self._conn.execute(
                f"SELECT rowid AS r, id FROM {t.sql} WHERE user_id = ? ORDER BY id", (key[0],)
            ).fetchall()
            if not rows:
                raise NotFoundError(f"{t.qualname}: no record with user id {shown(key[0])}")
            if len(rows) > 1:
                ids = ", ".join(str(r["id"]) for r in rows)
                raise AmbiguousError(
                    f"{t.qualname}: user id {shown(key[0])} names several records (ids {ids}); give the id"
                )
            return int(rows[0]["r"])
        if len(key) != len(t.key):
            raise InvalidValueError(f"{t.qualname}: a record is named by {' + '.join(t.key)}")
        clauses, args = [], []
        for name, value in zip(t.key, key, strict=True):
            c = t.column(name)
            v = convert(t, c, value, text=text)
            if c.ref:
                target = BY_NAME[c.ref]
                kcol = target.by_column[target.key[0]]
                found = self._conn.execute(
                    f"SELECT id FROM {target.sql} WHERE {kcol.sql} = ?", (v,)
                ).fetchone()
                if found is None:
                    raise NotFoundError(
                        f"{t.qualname}: {name} {shown(v)} not found in {target.qualname}"
                    )
                v = found["id"]
            clauses.append(f"{c.sql} = ?")
            args.append(v)
        row = self._conn.execute(
            f"SELECT rowid AS r FROM {t.sql} WHERE {' AND '.join(clauses)}", args
        ).fetchone()
        if row is None:
            keys = ", ".join(f"{n}={shown(v)}" for n, v in zip(t.key, key, strict=True))
            raise NotFoundError(f"{t.qualname}: no record with {keys}")
        return int(row["r"])

    def _users(self, t: Table, rowid: int) -> list[str]:
        users = []
        for rt, rc in referrers(t):
            if rc.cascade:
                continue
            rows = self._conn.execute(
                f"SELECT * FROM {rt.sql} WHERE {rc.sql} = ? ORDER BY rowid", (rowid,)
            ).fetchall()
            if rows:
                recs = self._to_records(rt, rows[:3])
                shown = ", ".join(_key_text(rt, r) for r in recs)
                more = f" and {len(rows) - 3} more" if len(rows) > 3 else ""
                users.append(f"{len(rows)} record(s) of {rt.qualname} ({shown}{more})")
        return users

    def _upsert(self, t: Table, record: Mapping[str, Any]) -> int:
        """Insert or replace one record by its key; returns its rowid."""
        values = self._to_sql(t, record, text=False)
        if t.auto_id and "id" not in values:
            values = {"id": self._free_id(t), **values}
        key_sql = [t.by_column[k].sql for k in t.key]
        existing = None
        if all(k in values for k in key_sql):
            existing = self._conn.execute(
                f"SELECT rowid AS r FROM {t.sql} WHERE {' AND '.join(f'{k} = ?' for k in key_sql)}",
                [values[k] for k in key_sql],
            ).fetchone()
        try:
            if existing is None:
                cols = ", ".join(values)
                marks = ", ".join("?" for _ in values)
                cur = self._conn.execute(
                    f"INSERT INTO {t.sql} ({cols}) VALUES ({marks})", tuple(values.values())
                )
                return int(cur.lastrowid or 0)
            else:
                rest = {k: v for k, v in values.items() if k not in key_sql}
                if rest:
                    sets = ", ".join(f"{k} = ?" for k in rest)
                    self._conn.execute(
                        f"UPDATE {t.sql} SET {sets} WHERE rowid = ?",
                        (*rest.values(), existing["r"]),
                    )
                return int(existing["r"])
        except sqlite3.IntegrityError as exc:
            raise _integrity_error(t, exc, record) from None


def _table(t: Table | str) -> Table:
    return t if isinstance(t, Table) else table(t)


def _key_text(t: Table, record: Mapping[str, Any]) -> str:
    if t.auto_id:
        return f"{record['id']} ({record['user_id']})"
    return " / ".join(str(record[k]) for k in t.key)


def _suggest(value: Any, known: list[Any]) -> str:
    if not known:
        return " (there are none)"
    close = difflib.get_close_matches(str(value), [str(k) for k in known], n=3)
    if close:
        return f"; did you mean {' or '.join(repr(c) for c in close)}?"
    shown = ", ".join(repr(k) for k in known[:10]) + (", ..." if len(known) > 10 else "")
    return f"; known: {shown}"


def _integrity_error(
    t: Table, exc: sqlite3.IntegrityError, record: Mapping[str, Any]
) -> RecordError:
    msg = str(exc)
    by_sql = {c.sql: c.name for c in t.columns}
    if msg.startswith("UNIQUE constraint failed:"):
        cols = [c.strip().split(".")[-1] for c in msg.split(":", 1)[1].split(",")]
        names = [by_sql.get(c, c) for c in cols]
        values = ", ".join(f"{n}={shown(record.get(n))}" for n in names)
        return DuplicateError(
            f"{t.qualname}: a record with the same {' + '.join(names)} exists ({values})"
        )
    if msg.startswith("NOT NULL constraint failed:"):
        col = msg.rsplit(".", 1)[-1]
        return InvalidValueError(f"{t.qualname}: field {by_sql.get(col, col)!r} needs a value")
    if msg.startswith("CHECK constraint failed:"):
        rule = msg.split(":", 1)[1].strip()
        return ConstraintError(f"{t.qualname}: the record breaks the rule {rule!r}")
    if "FOREIGN KEY" in msg:
        return UnknownReferenceError(f"{t.qualname}: a field names a record that does not exist")
    if msg.startswith("cannot store"):
        return InvalidValueError(f"{t.qualname}: {msg}")
    return ConstraintError(f"{t.qualname}: {msg}")


def _backup(src: Path, dst: Path) -> None:
    """A consistent copy of an SQLite file (the SQLite backup API) before a migration."""
    if dst.exists():
        return
    source = sqlite3.connect(f"{src.resolve().as_uri()}?mode=ro", uri=True)
    try:
        target = sqlite3.connect(str(dst))
        try:
            source.backup(target)
        finally:
            target.close()
    finally:
        source.close()


# ---------------------------------------------------------------------------- seed views


@functools.cache
def _seed_snapshot() -> tuple[tuple[VehicleProfile, ...], tuple[tuple[str, PayloadClass], ...]]:
    with SwarmDatabase.memory() as db:
        return tuple(db.profiles()), tuple(db.payload_classes().items())


def seed_profiles() -> dict[str, VehicleProfile]:
    """The seed data's profiles by model name (the first system of each model): the
    parameters planning and voting tests use. Built once per process."""
    out: dict[str, VehicleProfile] = {}
    for p in _seed_snapshot()[0]:
        out.setdefault(p.model, p)
    return out


def seed_fleet() -> list[VehicleProfile]:
    """Every seed system's profile, by id (ground station included)."""
    return list(_seed_snapshot()[0])


def seed_payload_classes() -> dict[str, PayloadClass]:
    """The seed data's payload hierarchy, by payload model name."""
    return dict(_seed_snapshot()[1])
