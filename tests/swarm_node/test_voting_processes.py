"""Voting over real processes: four `swarm-node` processes on loopback Zenoh, each
flying a simulated vehicle over MAVLink, and the real `gcs` command line sending
`mission target --count 2 --payload MODEL`. The idle candidates synchronise, vote with
no leader, the two with the payload asked for go, the other two stand down; `gcs`
prints every score and who goes. Then `gcs cmd join-mission` adds one of the others to
the winners' fleet (add, with the plan lineage over Zenoh)."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import msgspec
import pytest

from swarm_proto import FsmState, VehicleInfo
from swarm_sim.core import SITL_HOME
from tests.swarm_node.processes import nodes, plain_session, wait_until
from tests.swarm_node.test_mission_processes import Watch, activate, swarm, vehicles

pytestmark = pytest.mark.network
__all__ = ["swarm", "vehicles"]  # fixtures

PAYLOAD = "EO 1080p 2-axis gimbal"  # what quadcopters 7 and 8 carry (seed database)


@pytest.mark.parametrize(
    "vehicles", [{1: "vtol", 7: "copter", 8: "copter", 9: "copter"}], indirect=True
)
def test_gcs_count_2_with_a_payload_to_four_nodes(
    zenoh_router: str, swarm: str, vehicles: dict[int, str], swarm_db: Path
) -> None:
    client = plain_session(zenoh_router)
    watch = Watch(client, swarm)
    infos: dict[int, VehicleInfo] = {}
    sub = client.declare_subscriber(
        f"bandada/{swarm}/vehicle/*/info",
        lambda s: infos.__setitem__(
            (i := msgspec.msgpack.decode(s.payload.to_bytes(), type=VehicleInfo)).vehicle_id, i
        ),
    )
    ids = sorted(vehicles)
    try:
        with nodes(ids, zenoh_router, swarm, autopilots=vehicles):
            activate(client, swarm, watch, ids)
            target = f"{SITL_HOME.lat_deg + 0.002},{SITL_HOME.lon_deg}"
            gcs = [
                sys.executable,
                "-m",
                "gcs_cli.app",
                "--connect",
                zenoh_router,
                "--swarm",
                swarm,
                "mission",
                "target",
                "--point",
                target,
                "--count",
                "2",
                "--payload",
                PAYLOAD,
                "--alt",
                "30",
                "--duration",
                "30",
                "--mission-id",
                "77",
                "--timeout",
                "15",
                "--vote-wait",
                "20",
                "--yes",
            ]
            t0 = time.monotonic()
            done = subprocess.run(
                gcs,
                capture_output=True,
                text=True,
                timeout=90,
                env={**os.environ, "COLUMNS": "120"},
            )
            took = time.monotonic() - t0
            out = done.stdout + done.stderr
            assert done.returncode == 0, out
            # the vote as gcs shows it: every vehicle's score, winners 7 and 8
            assert "vote decided" in out and "winners: 7, 8" in out, out
            for vid in ids:
                assert f"│ {vid:>7} │" in out or f"{vid}" in out
            # and as the vehicles do: 7 and 8 fly mission 77, 1 and 9 stood down
            went = wait_until(
                lambda: all(infos.get(v) and infos[v].mission_id == 77 for v in (7, 8)), 20
            )
            assert went is not None, {v: (i.mission_id, i.fsm_state) for v, i in infos.items()}
            # the losers' next info (1 Hz) says they stood down
            stood = wait_until(
                lambda: all(
                    infos[v].mission_id == 0 and infos[v].fsm_state == FsmState.GO_MISSION
                    for v in (1, 9)
                ),
                10,
            )
            assert stood is not None, {v: (i.mission_id, i.fsm_state) for v, i in infos.items()}
            print(out)
            print(f"gcs mission --count 2: answered, voted and shown in {took:.1f} s")
            # add: vehicle 1 (stood down) joins the winners' fleet; they replan with it
            # and send it their plan's lineage (over Zenoh), it flies its share of it
            join = [
                sys.executable,
                "-m",
                "gcs_cli.app",
                "--connect",
                zenoh_router,
                "--swarm",
                swarm,
                "cmd",
                "join-mission",
                "--id",
                "1",
                "--mission-id",
                "77",
                "--yes",
            ]
            done = subprocess.run(join, capture_output=True, text=True, timeout=60)
            assert done.returncode == 0, done.stdout + done.stderr
            joined = wait_until(
                lambda: (
                    all(
                        infos[v].mission_id == 77 and infos[v].fsm_state == FsmState.GO_MISSION
                        for v in (1, 7, 8)
                    )
                    and len({infos[v].members_hash for v in (1, 7, 8)}) == 1
                ),
                30,
            )
            assert joined is not None, {
                v: (i.mission_id, i.fsm_state, i.members_hash) for v, i in infos.items()
            }
            print(f"join-mission: vehicle 1 flies mission 77 with 7 and 8 after {joined:.1f} s")
    finally:
        sub.undeclare()
        watch.close()
        client.close()
