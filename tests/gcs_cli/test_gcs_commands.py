"""The ground station's commands against a real node process flying a simulated
quadcopter, over Zenoh on 127.0.0.1 (typer's CliRunner, in-process)."""

from __future__ import annotations

import json
import os
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from typer.testing import CliRunner

from gcs_cli.app import app
from gcs_cli.ground import FleetView, GroundStation
from swarm_proto import AlertCode, SystemClock
from swarm_proto.session import ZenohSettings
from swarm_sim.runtime import VehicleServer, VehicleSpec
from tests.conftest import free_tcp_port
from tests.swarm_node.processes import peers_of, plain_session, start_node, stop, wait_until

pytestmark = pytest.mark.network
runner = CliRunner()


@pytest.fixture
def node7(zenoh_router: str, swarm_db: Path, tmp_path: Path) -> Iterator[tuple[str, str]]:
    """Node 7 (a seed quadcopter) with its simulated autopilot; yields (router, swarm).
    The node's log is printed when a test fails (pytest shows captured output)."""
    swarm = f"g{os.getpid()}"
    spec = VehicleSpec("copter", port=free_tcp_port(), sysid=7)
    log = tmp_path / "node7.log"
    with VehicleServer([spec], SystemClock()):
        proc = start_node(
            7, zenoh_router, swarm, "--autopilot", f"tcp:127.0.0.1:{spec.tcp_port}", log=log
        )
        watcher = plain_session(zenoh_router)
        try:
            assert (
                wait_until(lambda: peers_of(watcher, swarm, 7) is not None, timeout=30) is not None
            )
            yield zenoh_router, swarm
        finally:
            watcher.close()
            code = stop(proc)
            print(log.read_text(errors="replace"))
            assert code == 0


def gcs(router: str, swarm: str, *args: str) -> object:
    return runner.invoke(app, ["--connect", router, "--swarm", swarm, *args])


def test_status_commands_missions_and_zones(node7: tuple[str, str]) -> None:
    router, swarm = node7
    # wait for the autopilot's position (the EKF takes a few simulated seconds)
    for _ in range(30):
        r = gcs(router, swarm, "status", "--json", "--wait", "1")
        rows = json.loads(r.stdout)  # type: ignore[attr-defined]
        if rows and rows[0].get("gps", "").startswith(("FIX_3D", "DGPS", "RTK")):
            break
    assert (
        rows[0]["id"] == 7
        and rows[0]["model"] == "Generic Quadcopter"
        and rows[0]["fsm"] == "INACTIVE"
    )

    r = gcs(router, swarm, "cmd", "set-base", "--point", "37.4112,-5.9889,10")
    assert r.exit_code == 0, r.stdout  # type: ignore[attr-defined]
    assert "SET_BASE" not in r.stdout and "OK" in r.stdout  # type: ignore[attr-defined]

    r = gcs(router, swarm, "cmd", "parachute", "--id", "7", "--yes")  # the quad has none
    assert r.exit_code == 1 and "UNSUPPORTED" in r.stdout  # type: ignore[attr-defined]

    r = gcs(router, swarm, "cmd", "warp-drive")
    assert r.exit_code == 2 and "unknown command" in r.stdout + str(r.stderr)  # type: ignore[attr-defined]

    r = gcs(
        router,
        swarm,
        "zone",
        "add",
        "3",
        "--circle",
        "37.43,-5.98,50",
        "--floor",
        "0",
        "--ceiling",
        "300",
    )
    assert r.exit_code == 0 and "zone 3: 1 accepted" in r.stdout  # type: ignore[attr-defined]

    r = gcs(
        router,
        swarm,
        "mission",
        "area",
        "--polygon",
        "37.41,-5.99 37.42,-5.98 37.41,-5.98 37.42,-5.99",
        "--id",
        "7",
    )
    assert r.exit_code == 2 and "Self-intersection" in r.stdout + str(r.stderr)  # type: ignore[attr-defined]

    # every vehicle answers a mission; a vehicle addressed that is not there is silent
    # (it said "addresses none" and named no one)
    r = gcs(
        router,
        swarm,
        "mission",
        "target",
        "--point",
        "37.4125,-5.9889",
        "--id",
        "8",
        "--timeout",
        "2",
        "--yes",
    )
    out = r.stdout  # type: ignore[attr-defined]
    assert r.exit_code == 1 and "not addressed: 7" in out, out  # type: ignore[attr-defined]
    assert "silent" in out and "not alive when sent" in out, out

    r = gcs(
        router,
        swarm,
        "mission",
        "target",
        "--point",
        "37.4125,-5.9889",
        "--id",
        "7",
        "--alt",
        "30",
        "--yes",
    )
    assert r.exit_code == 0, r.stdout  # type: ignore[attr-defined]
    assert "OK" in r.stdout  # type: ignore[attr-defined]

    # the ground station is a peer: with an operator's console open (a session that stays,
    # so a one-shot `gcs peers` does not race its own arrival), node 7 lists it
    console = GroundStation(ZenohSettings(connect=(router,)), swarm)
    try:
        watcher = plain_session(router)
        try:
            listed = wait_until(lambda: 900 in (peers_of(watcher, swarm, 7) or []), 10)
            assert listed is not None
        finally:
            watcher.close()
        # the node has just started planning the target mission (its planner process
        # starts with the first plan job): in the full suite one 3 s query went
        # unanswered twice in a row while the loop held the core's lock starting it. The
        # queryables answer from the loop's snapshot now, never waiting for it
        r = gcs(router, swarm, "peers", "7")
        assert r.exit_code == 0 and "GCS" in r.stdout  # type: ignore[attr-defined]

        # an operating area the vehicle is not in: the running node raises a geofence
        # breach (and loads the area into its autopilot as an inclusion fence)
        r = gcs(
            router, swarm, "zone", "add", "5", "--circle", "37.50,-5.90,300", "--operating-area"
        )
        assert r.exit_code == 0 and "operating area 5: 1 accepted" in r.stdout  # type: ignore[attr-defined]

        def breach(view: FleetView) -> bool:
            return any(
                a.vehicle_id == 7
                and a.code == AlertCode.GEOFENCE_BREACH
                and "left operating area 5" in a.text
                for a in view.alerts
            )

        assert console.wait_for(breach, 15.0), list(console.snapshot().alerts)
        r = gcs(router, swarm, "zone", "remove", "5")
        assert r.exit_code == 0 and "zone 5: 1 accepted" in r.stdout  # type: ignore[attr-defined]
    finally:
        console.close()


def test_emergency_land_asks_for_the_landing_point() -> None:
    r = runner.invoke(app, ["--connect", "tcp/127.0.0.1:1", "cmd", "emergency-land"])
    text = " ".join((r.stdout + str(r.stderr)).replace("│", " ").split())  # rich's box
    assert r.exit_code == 2 and "where the landing route ends" in text


def test_status_shows_how_old_the_autopilot_data_is() -> None:
    """After an autopilot link loss the node keeps sending its last
    state; `gcs status` showed it heard 0.1 s ago, as fresh. The `data s` column is the
    age of the autopilot's sample (VehicleStatus.time_unix_s), with the link-loss flag."""
    import time as _time

    from gcs_cli.render import COLUMNS, fleet_rows
    from swarm_proto import AlertFlag, VehicleStatus

    view = FleetView()
    now = _time.time()
    view.status[7] = VehicleStatus(
        7,
        now - 30.0,
        37.4,
        -5.9,
        70.0,
        60.0,
        armed=True,
        alerts=AlertFlag.AUTOPILOT_LINK_LOSS,
    )
    view.heard_at[7] = _time.monotonic()
    (row,) = fleet_rows(view)
    assert row["age_s"] is not None and row["age_s"] < 1.0  # heard just now...
    assert 29.0 <= row["data_age_s"] <= 31.0  # ...about 30 s old data
    assert row["alerts"] == "autopilot_link_loss"
    assert ("data_age_s", "data") in COLUMNS


def test_a_mission_the_fleet_cannot_fly_is_refused_with_its_budget(
    node7: tuple[str, str],
) -> None:
    """The mission's answer is the fleet's verdict on its plan: a 1.2 km square is
    beyond the seed quadcopter's battery, so the node refuses it (PLAN_FAILED) with the
    budget in full, and `gcs mission` exits 1 (it said "1 accepted", exit 0)."""
    router, swarm = node7
    for _ in range(30):  # the autopilot's home first (the simulated EKF's few seconds)
        r = gcs(router, swarm, "cmd", "set-base", "--point", "37.4112,-5.9889,10")
        if r.exit_code == 0:  # type: ignore[attr-defined]
            break
        time.sleep(1.0)
    d_lat, d_lon = 1200.0 / 111_320.0, 1200.0 / (111_320.0 * 0.7943)
    lat, lon = 37.4117, -5.9889
    square = f"{lat},{lon} {lat},{lon + d_lon} {lat + d_lat},{lon + d_lon} {lat + d_lat},{lon}"
    # HOME_NOT_SET / NOT_READY pass as the simulated autopilot settles: asked again each
    # second for up to a minute (its EKF takes longer on a loaded host)
    t_end = time.monotonic() + 60.0
    while True:
        r = gcs(router, swarm, "mission", "area", "--polygon", square, "--id", "7", "--yes")
        out = r.stdout  # type: ignore[attr-defined]
        if "PLAN_FAILED" in out or "plan cannot be flown" in out or time.monotonic() > t_end:
            break
        time.sleep(1.0)
    assert r.exit_code == 1, out  # type: ignore[attr-defined]
    assert "plan cannot be flown" in out and "needs" in out and "has" in out, out
