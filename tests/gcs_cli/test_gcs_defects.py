"""Defects, each with its regression test: bad input is one line on stderr
and exit 2 with nothing sent (a subscriber on the router counts what arrives), `cmd
arm` with no selector refuses, a command that moves vehicles is not sent unconfirmed,
an unreachable --connect exits 1, `db query` uses the global --connect, endpoints in
either spelling."""

from __future__ import annotations

import threading
from pathlib import Path

import pytest

from gcs_cli.app import run
from swarm_proto.endpoints import mavlink_endpoint, zenoh_endpoint
from swarm_proto.session import SwarmBus, ZenohSettings
from swarm_proto.topics import COMMAND, MISSION, ZONE
from tests.conftest import free_tcp_port

DATA = Path(__file__).parent / "data"
BAD = [
    # (arguments, what the one line must say)
    (["cmd", "goto", "--point", "95,0", "--all"], "latitude 95 is out of range"),
    (["cmd", "goto", "--point", "nan,0", "--all"], "latitude is nan"),
    (["cmd", "goto", "--point", "37,200", "--all"], "longitude 200 is out of range"),
    (["cmd", "goto", "--point", "37,-5,nan", "--all"], "altitude is nan"),
    (["cmd", "goto", "--point", "abc", "--all"], "expected LAT,LON"),
    (["cmd", "set-speed", "--value", "nan", "--all"], "nan is not a number"),
    (["cmd", "set-speed", "--value", "inf", "--all"], "inf is not a number"),
    (["cmd", "set-fleet", "--fleet-id", "-1"], "--fleet-id"),
    (["cmd", "set-fleet", "--fleet-id", "256"], "--fleet-id"),
    (["cmd", "rtl", "--id", "0"], "--id"),
    (["cmd", "rtl", "--fleet", "0"], "--fleet"),
    (["cmd", "rtl", "--id", "3", "--all"], "exclude each other"),
    (["cmd", "arm"], "say which vehicles"),  # it armed the whole swarm
    (["cmd", "shutdown"], "say which vehicles"),  # it stopped the swarm logic everywhere
    (["cmd", "cancel-mission", "--mission-id", "5"], "say which vehicles"),
    (["cmd", "warp-drive", "--all"], "unknown command 'warp-drive'"),
    (["cmd", "rtl", "--all", "--timeout", "nan"], "--timeout"),
    (["cmd", "rtl", "--all", "--timeout", "-1"], "--timeout"),
    (["zone", "add", "3", "--circle", "nan,0,50"], "latitude is nan"),
    (["zone", "add", "3", "--circle", "37,-5,0"], "radius 0 m must be > 0"),
    (["zone", "add", "3", "--circle", "37,-5,-5"], "radius -5 m must be > 0"),
    (["zone", "add", "3", "--polygon", "37,-5 37.1,-5"], "at least 3 vertices"),
    (["zone", "add", "3", "--circle", "37,-5,50", "--floor", "nan"], "--floor"),
    (
        ["zone", "add", "3", "--circle", "37,-5,50", "--floor", "300", "--ceiling", "100"],
        "floor must be below its ceiling",
    ),
    (["zone", "add", "0", "--circle", "37,-5,50"], "zone_id"),
    (["zone", "remove", "0"], "zone_id"),
    (["mission", "area", "--polygon", "nan,0 1,1 1,0", "--all"], "latitude is nan"),  # GEOS
    (
        [
            "mission",
            "area",
            "--polygon",
            "37.41,-5.99 37.42,-5.98 37.41,-5.98 37.42,-5.99",
            "--all",
        ],
        "Self-intersection",
    ),
    (["mission", "target", "--circle", "37,-5,nan", "--all"], "radius is nan"),
    (["mission", "target", "--point", "37,-5", "--alt", "nan", "--all"], "--alt"),
    (["mission", "target", "--point", "37,-5", "--overlap", "2", "--all"], "--overlap"),
    (["mission", "target", "--point", "37,-5"], "say which vehicles"),
    (["mission", "warp", "--point", "37,-5", "--all"], "unknown mission type"),
    (["mission", "area", "--file", "/nonexistent/field.kml", "--all"], "cannot read"),
    (["status", "--wait", "-1"], "--wait"),
    (["status", "--wait", "nan"], "--wait"),
    (["alerts", "--wait", "inf"], "--wait"),
    (["vehicle", "0"], "'ID'"),
    (["watch", "--period", "0"], "--period"),
    (["status", "--bogus"], "No such option"),
    (["plot", "--out", "x.jpg", "--offline"], "the picture is a .png"),
    (["plot", "--out", "x.png", "--offline"], "nothing to draw"),
    (["load", "/nonexistent/state.json", "--yes"], "cannot read"),
    # sent and refused by each vehicle before; the option named is the one at fault
    (["cmd", "set-speed", "--value", "-3", "--all"], "set-speed needs --value, a speed in m/s"),
    (["cmd", "takeoff", "--id", "3"], "takeoff needs --value, an altitude in m above home"),
    (["cmd", "set-altitude", "--value", "-5", "--id", "3"], "(got -5)"),
    (["watch", "--period", "-1"], "Invalid value for --period"),
    (["watch", "--duration", "-3"], "Invalid value for --duration"),
    (["record", "x.csv", "--duration", "-3"], "Invalid value for --duration"),
    (["zone", "import", "/nonexistent/a.plan"], "cannot read"),
    (["zone", "import", "x.plan", "--floor", "nan"], "--floor"),
    (["zone", "import", str(DATA / "geojson-io.geojson"), "--base-from-file"], "no rally point"),
]


@pytest.fixture
def listener(zenoh_router: str) -> object:
    """What reaches the router's swarm while the test runs (nothing, it should be)."""
    got: list[object] = []
    lock = threading.Lock()
    bus = SwarmBus.open(ZenohSettings(mode="client", connect=(zenoh_router,)), "bad")

    def keep(msg: object, key: str) -> None:
        with lock:
            got.append(msg)

    for topic in (COMMAND, MISSION, ZONE):
        bus.subscribe(topic, keep)
    try:
        yield got
    finally:
        bus.close()


def test_bad_input_is_one_line_exit_2_and_nothing_sent(
    zenoh_router: str, listener: list[object], capsys: pytest.CaptureFixture[str]
) -> None:
    for args, says in BAD:
        code = run(["--connect", zenoh_router, "--swarm", "bad", *args])
        out, err = capsys.readouterr()
        lines = err.strip().splitlines()
        assert code == 2, (args, out, err)
        assert len(lines) == 1 and says in lines[0], (args, err)
        assert "--wait" not in lines[0] or "--wait" in args, (args, err)  # the right option
        assert "Traceback" not in out + err
    assert listener == []  # nothing was sent, whatever the mistake


def test_a_command_that_moves_vehicles_is_not_sent_unconfirmed(
    zenoh_router: str, listener: list[object], capsys: pytest.CaptureFixture[str]
) -> None:
    """`gcs cmd arm` armed the whole swarm without asking. With no terminal
    to ask on and no --yes it refuses (exit 2) and sends nothing."""
    code = run(["--connect", zenoh_router, "--swarm", "bad", "cmd", "arm", "--all"])
    err = capsys.readouterr().err
    assert code == 2 and "add --yes to confirm" in err and "every vehicle alive" in err, err
    # shutdown takes vehicles out of the swarm logic: asked too
    code = run(["--connect", zenoh_router, "--swarm", "bad", "cmd", "shutdown", "--all"])
    err = capsys.readouterr().err
    assert code == 2 and "shutdown to every vehicle alive" in err and "--yes" in err, err
    assert listener == []


def test_an_unreachable_router_exits_1(capsys: pytest.CaptureFixture[str]) -> None:
    """An unreachable --connect printed an empty table and exited 0."""
    port = free_tcp_port()
    assert run(["--connect", f"tcp/127.0.0.1:{port}", "status", "--wait", "0"]) == 1
    err = capsys.readouterr().err
    assert f"nothing answers at tcp/127.0.0.1:{port}" in err and len(err.strip().splitlines()) == 1


def test_a_taken_router_port_is_one_line(
    zenoh_router: str, capsys: pytest.CaptureFixture[str]
) -> None:
    assert run(["--mode", "router", "--listen", zenoh_router, "status", "--wait", "0"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("gcs: cannot open Zenoh") and "Address already in use" in err
    assert len(err.strip().splitlines()) == 1 and ".rs:" not in err


def test_db_query_takes_the_global_connect(
    zenoh_router: str, swarm_db: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """`gcs --connect R db query ...` ignored R (and found no node)."""
    from swarm_node.database import SwarmDatabase
    from swarm_node.database.queryable import DatabaseQueryable
    from swarm_proto.session import open_session

    session = open_session(ZenohSettings(mode="client", connect=(zenoh_router,)))
    db = SwarmDatabase.open(swarm_db)
    try:
        with DatabaseQueryable(session, db, 7, "dbq"):
            code = run(
                ["--connect", zenoh_router, "--swarm", "dbq", "db", "query", "7", "--timeout", "5"]
            )
            out = capsys.readouterr().out
    finally:
        db.close()
        session.close()
    assert (code == 0 and "Generic Quadcopter" in out) or '"node_id": 7' in out, out


def test_endpoints_in_either_spelling() -> None:
    assert zenoh_endpoint("tcp/127.0.0.1:7447") == "tcp/127.0.0.1:7447"
    assert zenoh_endpoint("tcp:127.0.0.1:7447") == "tcp/127.0.0.1:7447"  # MAVLink's spelling
    assert zenoh_endpoint("10.0.0.1:7447") == "tcp/10.0.0.1:7447"
    assert zenoh_endpoint("udp/[::1]:7447") == "udp/[::1]:7447"
    assert zenoh_endpoint("tls/router.lab:7447") == "tls/router.lab:7447"
    assert zenoh_endpoint("tcp/127.0.0.1:0") == "tcp/127.0.0.1:0"  # listen on any free port
    for bad in ("foo", "tcp/127.0.0.1", "tcp/127.0.0.1:70000", "http://x:1"):
        with pytest.raises(ValueError, match=r"e\.g\. tcp/127\.0\.0\.1:7447"):
            zenoh_endpoint(bad)
    assert mavlink_endpoint("tcp:127.0.0.1:5760") == "tcp:127.0.0.1:5760"
    assert mavlink_endpoint("tcp/127.0.0.1:5760") == "tcp:127.0.0.1:5760"  # Zenoh's spelling
    assert mavlink_endpoint("/dev/ttyACM0,115200") == "/dev/ttyACM0,115200"
    with pytest.raises(ValueError, match="tcp:HOST:PORT"):
        mavlink_endpoint("127.0.0.1:5760")


def test_the_connect_option_takes_either_spelling(
    zenoh_router: str, capsys: pytest.CaptureFixture[str]
) -> None:
    host_port = zenoh_router.split("/", 1)[1]
    for spelling in (f"tcp:{host_port}", host_port):
        assert run(["--connect", spelling, "status", "--wait", "0"]) == 0
        assert "no vehicle heard" in capsys.readouterr().out


def test_every_command_has_an_example_in_its_help(capsys: pytest.CaptureFixture[str]) -> None:
    from gcs_cli.app import app
    from tests.gcs_cli.cli_walk import commands

    paths = commands(app)
    assert len(paths) >= 25
    for path in paths:
        assert run([*path, "--help"]) == 0, path
        out = capsys.readouterr().out
        assert "Example: gcs" in out, (path, out)


def test_shell_completion_is_offered() -> None:
    """As a user asks for it: the installed `gcs` typed in bash (in-process, or under
    make's `sh`, Typer found no shell it supports: 'Shell sh not supported')."""
    import shutil
    import subprocess
    import sys

    gcs = shutil.which("gcs", path=str(Path(sys.executable).parent))
    bash = shutil.which("bash")
    assert gcs is not None and bash is not None
    # from bash, as a user types it (Typer detects the shell from the parent process)
    # ('; exit': bash would exec a lone command in its place, and the parent be make's sh)
    done = subprocess.run(
        [bash, "-c", f"'{gcs}' --show-completion; exit $?"],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert done.returncode == 0, done.stderr
    assert "complete" in done.stdout


def test_status_fits_100_columns_with_positions() -> None:
    """`gcs status` needed ~150 columns and showed no position. Worst-case rows
    (long mode names, every alert, a 3-digit fleet, negative coordinates) fit 100
    columns with every cell whole; the alerts wrap within their column."""
    import time as _time

    from rich.console import Console

    from gcs_cli.ground import FleetView
    from gcs_cli.render import fleet_table
    from swarm_proto import (
        AlertFlag,
        FsmState,
        GpsFix,
        MissionState,
        VehicleInfo,
        VehicleStatus,
        VehicleType,
    )

    view = FleetView()
    now = _time.time()
    for vid, vt, mode in ((65534, VehicleType.VTOL, 25), (7, VehicleType.COPTER, 21)):
        view.status[vid] = VehicleStatus(
            vid,
            now - 31.0,
            -37.4123456,
            -125.9876543,
            7999.0,
            4321.0,
            29.9,
            -29.9,
            heading_deg=359.4,
            battery_pct=100,
            gps_fix=GpsFix.RTK_FIXED,
            gps_sats=31,
            ap_mode=mode,
            armed=True,
            fsm_state=FsmState.EMERGENCY,
            mission_state=MissionState.REPLAN,
            mission_progress_pct=100,
            fleet_id=255,
            alerts=AlertFlag(0xFFF),
        )
        view.info[vid] = VehicleInfo(vid, vt, "Albatross 250 VTOL", "U", mav_type=2)
        view.heard_at[vid] = _time.monotonic() - 123.4
    view.untrusted[7] = "heard from session 3f2a9c1d and a foreign publisher"
    console = Console(width=100, record=True)
    console.print(fleet_table(view, title="swarm default"))
    text = console.export_text()
    assert max(len(line.rstrip()) for line in text.splitlines()) <= 100, text
    assert "-37.41235,-125.98765" in text and "LOITERALTQLAND"[:9] in text, text
    assert "…" not in text, text  # no cell cut
    assert "7 ! untrusted: heard from session 3f2a9c1d and a foreign publisher" in text, text
    assert "65534 ! batt,BATT!,gps,ekf,aplink,fence,att,coll,swarm,nfz,AP≠db,ID!" in text, text


def test_a_mission_over_the_size_cap_is_refused_before_sending() -> None:
    import math

    import typer

    from gcs_cli.options import checked
    from swarm_proto import Geometry, Mission, MissionType

    def ring(n: int) -> list[tuple[float, float]]:
        return [
            (
                37.4 + 0.01 * math.sin(2 * math.pi * i / n),
                -5.9 + 0.01 * math.cos(2 * math.pi * i / n),
            )
            for i in range(n)
        ]

    assert checked(Mission(5, 900, MissionType.AREA, Geometry.polygon(ring(4000))))
    with pytest.raises(typer.BadParameter, match="more than the 262144 mission takes"):
        checked(Mission(5, 900, MissionType.AREA, Geometry.polygon(ring(15000))))
