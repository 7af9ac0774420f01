"""`gcs mission` takes the parameters it is not given from the swarm database's mission
defaults (not constants of its own): a plain responder on 127.0.0.1 captures what the
ground station sends."""

from __future__ import annotations

import threading
from pathlib import Path

import pytest
from typer.testing import CliRunner

from gcs_cli.app import app
from swarm_node.database import SwarmDatabase
from swarm_proto import Ack, AckRef, Mission, SelectorKind, VehicleInfo, VehicleType
from swarm_proto.session import SwarmBus, ZenohSettings
from swarm_proto.topics import MISSION

pytestmark = pytest.mark.network
runner = CliRunner()


def send_mission(router: str, swarm: str, *args: str, announce: bool = True) -> tuple[Mission, str]:
    """Run `gcs mission ...` against a vehicle 5 that answers OK (and, with `announce`,
    says what it is); what it received."""
    got: list[Mission] = []
    done = threading.Event()
    with SwarmBus.open(ZenohSettings(mode="client", connect=(router,)), swarm) as vehicle:

        def on_mission(m: Mission, key: str) -> None:
            got.append(m)
            vehicle.publish(Ack(5, m.issuer_id, AckRef.MISSION, m.mission_id, True))
            done.set()

        vehicle.subscribe(MISSION, on_mission)
        stop = threading.Event()

        def announcer() -> None:
            while announce and not stop.wait(0.2):
                vehicle.publish(VehicleInfo(5, VehicleType.COPTER, "Generic Quadcopter", "Q5"))

        t = threading.Thread(target=announcer, daemon=True)
        t.start()
        try:
            r = runner.invoke(
                app, ["--connect", router, "--swarm", swarm, "mission", *args, "--yes"]
            )
        finally:
            stop.set()
            t.join()
    assert done.is_set() and r.exit_code == 0, r.stdout
    return got[0], r.stdout


def test_unset_parameters_come_from_the_database(zenoh_router: str, swarm_db: Path) -> None:
    m, _ = send_mission(zenoh_router, "md1", "target", "--point", "37.41,-5.99", "--id", "5")
    p = m.params
    assert (p.altitude_rel_m, p.radius_m, p.altitude_step_m) == (100.0, 150.0, 10.0)  # seed
    m, _ = send_mission(
        zenoh_router,
        "md2",
        "target",
        "--point",
        "37.41,-5.99",
        "--id",
        "5",
        "--alt",
        "40",
        "--radius",
        "60",
    )
    assert (m.params.altitude_rel_m, m.params.radius_m, m.params.altitude_step_m) == (
        40.0,
        60.0,
        10.0,
    )
    # a circle target: its radius is the circle's, not the database's
    m, _ = send_mission(zenoh_router, "md3", "target", "--circle", "37.41,-5.99,70", "--id", "5")
    assert m.params.radius_m is None
    # the database changed: the ground station follows it
    with SwarmDatabase.open(swarm_db) as db:
        db.remove("swarm.mission-params", "area", "side_overlap")
        db.add(
            "swarm.mission-params",
            {"mission": "area", "name": "side_overlap", "value": 0.55, "unit": ""},
        )
    m, _ = send_mission(
        zenoh_router, "md4", "area", "--polygon", "37.41,-5.99 37.41,-5.98 37.42,-5.98", "--id", "5"
    )
    assert (m.params.altitude_rel_m, m.params.side_overlap) == (100.0, 0.55)


def test_count_and_payload_set_the_quantity_selector(zenoh_router: str, swarm_db: Path) -> None:
    """`--count N --payload MODEL`: a QUANTITY selector (the vehicles vote; until the
    node wiring lands they answer UNSUPPORTED, docs/node.md). The responder holds no
    liveliness token and says nothing of itself (a vehicle heard without the payload
    is not addressed: nobody would be), so the ground station knows nobody it must wait
    for and listens for its whole --timeout: 1 s here; the responder accepts, and no vote
    follows: --vote-wait 0 (what is sent is checked, not the waiting)."""
    m, _ = send_mission(
        zenoh_router,
        "md5",
        "target",
        "--point",
        "37.41,-5.99",
        "--count",
        "2",
        "--payload",
        "EO 1080p 2-axis gimbal",
        "--timeout",
        "1",
        "--vote-wait",
        "0",
        announce=False,
    )
    sel = m.selection
    assert (sel.kind, sel.quantity, sel.payload_model, sel.fleet_id) == (
        SelectorKind.QUANTITY,
        2,
        "EO 1080p 2-axis gimbal",
        0,
    )
    m, _ = send_mission(
        zenoh_router,
        "md6",
        "target",
        "--point",
        "37.41,-5.99",
        "--quantity",
        "1",
        "--fleet",
        "3",
        "--timeout",
        "1",
        "--vote-wait",
        "0",
        announce=False,
    )
    assert (m.selection.kind, m.selection.quantity, m.selection.fleet_id) == (
        SelectorKind.QUANTITY,
        1,
        3,
    )


@pytest.mark.parametrize(
    ("args", "says"),
    [
        (["--payload", "EO 1080p 2-axis gimbal"], "--payload needs --count"),
        (["--count", "2", "--id", "5"], "exclude each other"),
        (["--count", "300"], "1..255"),
        (["--count", "2", "--payload", "EO 1080p gimbal"], "unknown payload model"),
    ],
)
def test_count_and_payload_errors_before_sending(
    swarm_db: Path, args: list[str], says: str
) -> None:
    r = runner.invoke(app, ["mission", "target", "--point", "37.41,-5.99", *args])
    assert r.exit_code == 2
    assert says in " ".join(r.output.replace("│", " ").split())
