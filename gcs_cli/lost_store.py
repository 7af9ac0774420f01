"""The lost list kept between `gcs` runs (core/lost.py): an SQLite file, one row per
swarm and vehicle last heard flying (its last VehicleStatus and VehicleInfo, msgpack,
and when it was heard). `$BANDADA_GCS_STATE` names the file, else
`~/.local/share/bandada/gcs-lost.db` (XDG). A file that cannot be read or written is
a one-line warning: the ground station shows what it hears now.
"""

from __future__ import annotations

import logging
import os
import sqlite3
import time
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

import msgspec

from swarm_proto import VehicleInfo, VehicleStatus

from .core.lost import LostBook, Seen

if TYPE_CHECKING:
    from .ground import FleetView

ENV_VAR = "BANDADA_GCS_STATE"
FILE_NAME = "gcs-lost.db"
log = logging.getLogger(__name__)

_SCHEMA = """CREATE TABLE IF NOT EXISTS last_heard (
    swarm TEXT NOT NULL, vehicle_id INTEGER NOT NULL, status BLOB NOT NULL, info BLOB,
    heard_unix_s REAL NOT NULL, PRIMARY KEY (swarm, vehicle_id))"""


def state_path(env: Mapping[str, str] | None = None) -> Path:
    env = os.environ if env is None else env
    if env.get(ENV_VAR):
        return Path(env[ENV_VAR]).expanduser()
    data = env.get("XDG_DATA_HOME") or ""
    base = Path(data) if data and Path(data).is_absolute() else Path.home() / ".local" / "share"
    return base / "bandada" / FILE_NAME


def _connect(path: Path) -> sqlite3.Connection:
    path.parent.mkdir(parents=True, exist_ok=True)
    db = sqlite3.connect(path, timeout=5.0)
    db.execute(_SCHEMA)
    return db


def load(swarm: str, path: Path | None = None) -> LostBook:
    """The book kept for `swarm` (empty if none, or unreadable: warned)."""
    book = LostBook()
    p = path or state_path()
    if not p.exists():
        return book
    try:
        with _connect(p) as db:
            rows = db.execute(
                "SELECT status, info, heard_unix_s FROM last_heard WHERE swarm = ?", (swarm,)
            ).fetchall()
    except sqlite3.Error as exc:
        log.warning("lost vehicles not read from %s: %s", p, exc)
        return book
    for status, info, heard in rows:
        try:
            st = msgspec.msgpack.decode(status, type=VehicleStatus)
            inf = msgspec.msgpack.decode(info, type=VehicleInfo) if info else None
        except msgspec.DecodeError:
            continue  # a row of another version: skipped
        book.seen[st.vehicle_id] = Seen(st, inf, float(heard))
    return book


def save(swarm: str, book: LostBook, path: Path | None = None) -> None:
    """Replace what is kept for `swarm` with `book`."""
    p = path or state_path()
    try:
        with _connect(p) as db:
            db.execute("DELETE FROM last_heard WHERE swarm = ?", (swarm,))
            db.executemany(
                "INSERT INTO last_heard VALUES (?, ?, ?, ?, ?)",
                [
                    (
                        swarm,
                        vid,
                        msgspec.msgpack.encode(s.status),
                        msgspec.msgpack.encode(s.info) if s.info is not None else None,
                        s.heard_unix_s,
                    )
                    for vid, s in sorted(book.seen.items())
                ],
            )
    except (sqlite3.Error, OSError) as exc:
        log.warning("lost vehicles not kept in %s: %s", p, exc)


def update(swarm: str, view: FleetView, path: Path | None = None) -> dict[int, dict[str, Any]]:
    """The kept list updated with what `view` heard (a `gcs status` run, a `gcs watch`
    ending): the vehicles lost and not heard in it, by id (`LostBook.lost`)."""
    now, now_unix = time.monotonic(), time.time()
    book = load(swarm, path)
    for vid, st in view.status.items():
        at = now_unix - (now - view.heard_at.get(vid, now))
        book.heard(st, view.info.get(vid), at)
    save(swarm, book, path)
    return {v: f for v, f in book.lost(now_unix).items() if v not in view.status}
