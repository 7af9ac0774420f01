"""A running `swarm-node run` process, flying a simulated vehicle over MAVLink, serves
its swarm database on `bandada/<swarm>/db/<node_id>`: a plain zenoh-python get and
`gcs db query` read it, and what it serves is its file as it is now (a record that
`gcs db add` commits meanwhile is in the next answer)."""

from __future__ import annotations

import json
import os
import time
from pathlib import Path
from typing import Any

import msgspec
import pytest
import zenoh
from typer.testing import CliRunner

from gcs_cli.app import app
from swarm_node.core.profile import VehicleProfile
from swarm_node.database import LATEST_VERSION, QUADCOPTER, SwarmDatabase
from swarm_proto import SystemClock
from swarm_sim.runtime import VehicleServer, VehicleSpec
from tests.conftest import free_tcp_port
from tests.swarm_node.processes import plain_session, start_node, stop

pytestmark = pytest.mark.network

NODE = 7  # QUAD-01 in the seed data: a Generic Quadcopter


def _get(session: zenoh.Session, key: str, timeout_s: float = 60.0) -> Any:
    """The decoded answer to a plain zenoh get, asking again until the node answers."""
    deadline = time.monotonic() + timeout_s
    while True:
        for reply in session.get(key, timeout=2.0):
            if reply.ok is not None:
                assert str(reply.ok.encoding) == "application/msgpack"
                return msgspec.msgpack.decode(reply.ok.payload.to_bytes())
            raise AssertionError(f"{key}: error reply {reply.err!r}")
        if time.monotonic() > deadline:
            raise AssertionError(f"{key}: no answer within {timeout_s} s")
        time.sleep(0.2)


def _gcs(*args: str) -> Any:
    result = CliRunner().invoke(app, ["db", *args])
    assert result.exit_code == 0, result.output
    return json.loads(result.stdout) if result.stdout.strip().startswith(("[", "{")) else None


def test_a_running_node_serves_its_database(
    zenoh_router: str, swarm_db: Path, tmp_path: Path
) -> None:
    swarm = f"db{os.getpid()}"
    log = tmp_path / "node.log"
    spec = VehicleSpec("copter", port=free_tcp_port(), sysid=NODE)
    with VehicleServer([spec], SystemClock()), SwarmDatabase.open(swarm_db) as db:
        proc = start_node(
            NODE, zenoh_router, swarm, "--autopilot", f"tcp:127.0.0.1:{spec.tcp_port}", log=log
        )
        client = plain_session(zenoh_router)
        try:
            base = f"bandada/{swarm}/db/{NODE}"
            info = _get(client, base)
            assert info["node_id"] == NODE and info["schema_version"] == LATEST_VERSION
            assert info["tables"] == {k.replace(".", "/"): n for k, n in db.counts().items()}

            profile = msgspec.convert(_get(client, f"{base}/profile"), VehicleProfile)
            assert profile == db.vehicle_profile(NODE)
            assert (profile.user_id, profile.model) == ("QUAD-01", QUADCOPTER)

            replies = _gcs(
                "query", str(NODE), "profile", "--connect", zenoh_router, "--swarm", swarm
            )
            assert [r["key"] for r in replies] == [f"{base}/profile"]
            assert msgspec.convert(replies[0]["value"], VehicleProfile) == profile
            everyone = _gcs("query", "*", "--connect", zenoh_router, "--swarm", swarm)
            assert [r["value"]["node_id"] for r in everyone] == [NODE]

            # the node serves its file live: another process adds a system
            _gcs("add", "systems", "systems", "user_id=QUAD-04", "layout=Quadcopter + EO 1080p")
            added = _get(client, f"{base}/table/systems/systems?user_id=QUAD-04")
            assert added == [
                {"id": 14, "user_id": "QUAD-04", "layout": "Quadcopter + EO 1080p", "payload": None}
            ]
            replies = _gcs(
                "query",
                str(NODE),
                "table/systems/systems",
                "--connect",
                zenoh_router,
                "--swarm",
                swarm,
            )
            assert replies[0]["value"] == db.records("systems.systems")
            assert proc.poll() is None, log.read_text()
        finally:
            client.close()
            code = stop(proc)
        assert code == 0, log.read_text()
