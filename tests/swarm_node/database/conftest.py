"""Fixtures for the swarm database tests: seeded databases on files and in memory, and
a raw sqlite3 connection that bypasses bandada (to show SQLite itself keeps the rules)."""

from __future__ import annotations

import sqlite3
from collections.abc import Iterator
from pathlib import Path

import pytest

from swarm_node.database import SwarmDatabase


@pytest.fixture
def seeded() -> Iterator[SwarmDatabase]:
    with SwarmDatabase.memory() as db:
        yield db


@pytest.fixture
def db_path(tmp_path: Path) -> Path:
    """A seeded database file (closed)."""
    path = tmp_path / "swarm.db"
    SwarmDatabase.open(path).close()
    return path


@pytest.fixture
def raw(db_path: Path) -> Iterator[sqlite3.Connection]:
    """A plain sqlite3 connection to a seeded file, as any other writer would open it
    (foreign keys are a per-connection switch in SQLite: turned on, as bandada does)."""
    conn = sqlite3.connect(db_path, isolation_level=None)
    conn.execute("PRAGMA foreign_keys = ON")
    try:
        yield conn
    finally:
        conn.close()


def snapshot(path: Path) -> tuple[bytes, int]:
    """A file's bytes and modification time, to prove it was left untouched."""
    return path.read_bytes(), path.stat().st_mtime_ns
