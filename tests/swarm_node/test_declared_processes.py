"""over real node processes (Zenoh on 127.0.0.1, the swarm database file):
a node killed and started again holds the base and zones the operator declared (from
its database), a zone withdrawn while it was down is withdrawn for it too (its peers
tell it), and `gcs declared` reads any node's declared state."""

from __future__ import annotations

import json
import os
import signal
from pathlib import Path

import pytest
from typer.testing import CliRunner

from gcs_cli.app import app
from gcs_cli.ground import GroundStation
from swarm_proto import CommandArgs, CommandKind, Geometry, GeoPoint, NoFlyZone
from swarm_proto.session import ZenohSettings
from tests.swarm_node.processes import peers_of, plain_session, start_node, stop, wait_until

pytestmark = pytest.mark.network
runner = CliRunner()
BASE = GeoPoint(37.4115, -5.9889, 12.0)


def test_a_restarted_node_keeps_what_was_declared_and_gcs_reads_it(
    zenoh_router: str, swarm_db: Path, tmp_path: Path
) -> None:
    swarm = f"d{os.getpid()}"
    logs = {i: tmp_path / f"node{i}.log" for i in (1, 2)}
    procs = {i: start_node(i, zenoh_router, swarm, log=logs[i]) for i in (1, 2)}
    watcher = plain_session(zenoh_router)
    gs = GroundStation(ZenohSettings(connect=(zenoh_router,)), swarm)
    try:

        def sees(i: int, j: int) -> bool:
            return j in (peers_of(watcher, swarm, i) or [])

        assert wait_until(lambda: sees(1, 2) and sees(2, 1), 40) is not None
        acks = gs.command(CommandKind.SET_BASE, args=CommandArgs(point=BASE), timeout_s=10)
        assert {a.vehicle_id for a in acks if a.accepted} == {1, 2}
        zone = NoFlyZone(3, Geometry.circle(37.42, -5.99, 40.0), name="tower")
        area = NoFlyZone(4, Geometry.circle(37.41, -5.99, 3000.0), operating_area=True)
        assert gs.declare_zone(zone, timeout_s=10) == {1, 2}
        assert gs.declare_zone(area, timeout_s=10) == {1, 2}
        # a node answers from what it acknowledged: asked at once, it holds the zone
        assert set(gs.zones_held(area.zone_id, timeout_s=2)) == {1, 2}

        os.kill(procs[2].pid, signal.SIGKILL)  # its database holds zone 3 in force
        procs[2].wait(10)
        withdrawn = NoFlyZone(3, Geometry.circle(0.0, 0.0, 1.0), active=False)
        assert gs.declare_zone(withdrawn, expect=[1], timeout_s=10) == {1}

        procs[2] = start_node(2, zenoh_router, swarm, log=logs[2])
        assert wait_until(lambda: sees(2, 1), 40) is not None

        seen: list[dict] = []

        def holds() -> bool:
            r = runner.invoke(
                app, ["--connect", zenoh_router, "--swarm", swarm, "declared", "2", "--json"]
            )
            if r.exit_code != 0:
                return False
            doc = json.loads(r.stdout)
            seen.append(doc)
            zones = {z["zone_id"]: z for z in doc["zones"]}
            return 3 in zones and not zones[3]["active"]

        assert wait_until(holds, 15, period=0.5) is not None, seen[-1:]
        doc = seen[-1]
        assert doc["base"] == {
            "lat_deg": BASE.lat_deg,
            "lon_deg": BASE.lon_deg,
            "alt_msl_m": BASE.alt_msl_m,
        }, doc
        assert {z["zone_id"] for z in doc["zones"]} == {3, 4}, doc
        # node 1 holds the same declarations
        one = gs.declared_state(1)
        assert one is not None, "node 1 did not answer"
        assert {(z.zone_id, z.active) for z in one.zones} == {(3, False), (4, True)}, one
        # the table form, asking whichever vehicle answers first
        r = runner.invoke(
            app, ["--connect", zenoh_router, "--swarm", swarm, "declared"], env={"COLUMNS": "200"}
        )
        assert r.exit_code == 0, r.stdout
        assert "withdrawn" in r.stdout and "operating" in r.stdout, r.stdout
        r = runner.invoke(
            app, ["--connect", zenoh_router, "--swarm", swarm, "declared", "77", "--timeout", "0.5"]
        )
        assert r.exit_code == 1 and "did not answer" in r.stdout, r.stdout
        r = runner.invoke(
            app, ["--connect", zenoh_router, "--swarm", swarm, "declared", "1", "--timeout", "0"]
        )
        assert r.exit_code == 2, r.stdout
    finally:
        gs.close()
        watcher.close()
        codes = [stop(p) for p in procs.values()]
        for i, log in logs.items():
            print(f"--- node {i}\n" + log.read_text(errors="replace")[-3000:])
        assert codes == [0, 0]
