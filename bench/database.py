"""Swarm database: opening, resolving profiles, export/import, and a profile fetched over
Zenoh, beside a plain SQLite select and a plain Zenoh query of fixed bytes measured in
the same run (the baselines)."""

from __future__ import annotations

import json
import sqlite3
import statistics
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from bench.common import time_us
from swarm_node.database import SwarmDatabase
from swarm_node.database.document import decode_json, encode_json
from swarm_node.database.queryable import DatabaseQueryable, fetch_profile


def _ms(fn: Callable[[], object], repeat: int = 15) -> float:
    samples = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        samples.append((time.perf_counter() - t0) * 1e3)
    return round(statistics.median(samples), 3)


def _zenoh(figures: dict[str, Any]) -> None:
    from swarm_proto.session import ZenohSettings, open_session
    from tests.conftest import free_tcp_port

    endpoint = f"tcp/127.0.0.1:{free_tcp_port()}"
    server = open_session(ZenohSettings(listen=(endpoint,)))
    client = open_session(ZenohSettings(connect=(endpoint,)))
    db = SwarmDatabase.memory()
    payload = b"x" * 400
    plain = server.declare_queryable("bench/plain", lambda q: q.reply("bench/plain", payload))
    try:
        with DatabaseQueryable(server, db, node_id=3, swarm="bench"):
            fetch_profile(client, "bench", 3, timeout_s=10.0)  # discovery
            for _ in range(50):
                if list(client.get("bench/plain", timeout=2.0)):
                    break
                time.sleep(0.1)
            figures["fetch_profile_zenoh_us"] = time_us(
                lambda: fetch_profile(client, "bench", 3), repeat=5, number=200
            )
            figures["plain_zenoh_get_400b_us"] = time_us(
                lambda: list(client.get("bench/plain", timeout=2.0)), repeat=5, number=200
            )
    finally:
        plain.undeclare()
        db.close()
        client.close()
        server.close()


def run() -> dict[str, Any]:
    figures: dict[str, Any] = {}
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "swarm.db"

        def create() -> None:
            path.unlink(missing_ok=True)
            SwarmDatabase.open(path).close()

        figures["create_seeded_file_ms"] = _ms(create)
        figures["open_current_file_ms"] = _ms(lambda: SwarmDatabase.open(path).close())
        figures["file_bytes"] = path.stat().st_size
        figures["memory_seeded_ms"] = _ms(lambda: SwarmDatabase.memory().close())

        with SwarmDatabase.open(path) as db:
            figures["vehicle_profile_us"] = time_us(lambda: db.vehicle_profile(3), number=500)
            figures["profiles_14_systems_us"] = time_us(db.profiles, number=100)
            raw = sqlite3.connect(path)
            figures["baseline_sqlite_select_system_us"] = time_us(
                lambda: raw.execute("SELECT * FROM systems WHERE id = ?", (3,)).fetchone(),
                number=500,
            )
            raw.close()
            doc = db.export()
            data = encode_json(doc)
            figures["export_json_bytes"] = len(data)
            figures["export_json_compact_bytes"] = len(json.dumps(doc, separators=(",", ":")))
            figures["export_ms"] = _ms(lambda: encode_json(db.export()))

        def restore() -> None:
            with SwarmDatabase.memory(seed=False) as fresh:
                fresh.import_document(decode_json(data))

        figures["import_into_empty_ms"] = _ms(restore)
    _zenoh(figures)
    return figures
