"""The node's Zenoh and configuration features: the 2 s lease and multicast scouting off
by default (on when an interface is named), identity from a config file's [profile],
status/info rates from the file and the command line; and real processes on 127.0.0.1:
`swarm-node run --mode router` relaying for peers, `swarm-node router`, a node run from
a config file with its own [profile] and rates."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import msgspec
import pytest
import zenoh

from swarm_node.database import SwarmDatabase
from swarm_node.runtime.config import load_config, profile_from_config
from swarm_node.runtime.launch import open_database, resolve_profile
from swarm_node.runtime.node import node_settings
from swarm_proto import VehicleInfo, VehicleType
from swarm_proto.session import ZenohSettings, zenoh_config
from tests.conftest import free_tcp_port
from tests.swarm_node.processes import peers_of, plain_session, start_node, stop, wait_until

CONFIG = """
node_id = 42
swarm = "{swarm}"
status_hz = 10.0
info_hz = 4.0

[zenoh]
mode = "peer"
connect = ["{router}"]
lease_ms = 1500

[profile]
model = "Test Hexacopter"
user_id = "HEX-01"
vehicle_type = 3
cruise_speed_m_s = 9.5
battery_low_pct = 35
battery_critical_pct = 20
has_parachute = true
max_tilt_deg = 50.0
"""


def get(conf: zenoh.Config, key: str) -> object:
    return json.loads(conf.get_json(key))


# ----------------------------------------------------------------------- pure settings


def test_the_lease_is_2_s_and_multicast_scouting_off_by_default() -> None:
    ours = zenoh_config(ZenohSettings())
    assert get(ours, "transport/link/tx/lease") == 2000
    assert get(zenoh.Config(), "transport/link/tx/lease") == 10000  # Zenoh's own default
    assert get(ours, "scouting/multicast/enabled") is False
    assert get(ours, "mode") == "peer"
    named = zenoh_config(ZenohSettings(scouting_interface="eth1"))
    assert get(named, "scouting/multicast/enabled") is True  # an interface named: scout there
    assert get(named, "scouting/multicast/interface") == "eth1"
    assert get(zenoh_config(ZenohSettings(lease_ms=700)), "transport/link/tx/lease") == 700


def test_a_config_file_gives_identity_rates_and_zenoh_settings(tmp_path: Path) -> None:
    path = tmp_path / "node.toml"
    path.write_text(CONFIG.format(swarm="s1", router="tcp/127.0.0.1:7447"))
    cfg = load_config(path)
    assert (cfg.node_id, cfg.swarm, cfg.zenoh.lease_ms) == (42, "s1", 1500)
    assert cfg.zenoh.connect == ("tcp/127.0.0.1:7447",) and not cfg.zenoh.multicast_scouting
    settings = node_settings(cfg)
    assert (settings.status_period_s, settings.info_period_s) == (0.1, 0.25)
    # the command line wins over the file
    cli = load_config(path, status_hz=2.0, info_hz=None, zenoh_lease_ms=900)
    assert (cli.status_hz, cli.info_hz, cli.zenoh.lease_ms) == (2.0, 4.0, 900)
    # [profile]: the node's identity and parameters without a database (even if one exists)
    assert open_database(cfg) is None
    with SwarmDatabase.memory() as db:
        p = resolve_profile(cfg, db)
        from_db = resolve_profile(load_config(None, node_id=7), db)
    assert p == profile_from_config(cfg)
    assert (p.vehicle_id, p.model, p.user_id, p.vehicle_type) == (
        42,
        "Test Hexacopter",
        "HEX-01",
        VehicleType.COPTER,
    )
    assert (p.cruise_speed_m_s, p.battery_low_pct, p.battery_critical_pct) == (9.5, 35, 20)
    assert p.has_parachute and p.max_tilt_deg == 50.0
    assert from_db.model == "Generic Quadcopter"  # no [profile]: from the database
    with pytest.raises(ValueError, match="info_hz"):
        load_config(path, info_hz=100.0)


# ----------------------------------------------------------------------- processes


def node_cmd(*args: str) -> list[str]:
    return [sys.executable, "-m", "swarm_node.cli", *args]


def spawn(args: list[str], log: Path) -> subprocess.Popen[bytes]:
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    return subprocess.Popen(args, stdout=log.open("ab"), stderr=subprocess.STDOUT, env=env)


@pytest.mark.network
def test_a_node_run_from_a_config_file(zenoh_router: str, tmp_path: Path) -> None:
    """Identity from [profile], VehicleInfo at the file's 4 Hz (no database at all)."""
    swarm = f"cf{os.getpid()}"
    path = tmp_path / "node.toml"
    path.write_text(CONFIG.format(swarm=swarm, router=zenoh_router))
    log = tmp_path / "node.log"
    env_db = os.environ.pop("BANDADA_DB", None)  # the node must not need one
    proc = spawn(node_cmd("run", "--config", str(path)), log)
    client = plain_session(zenoh_router)
    heard: list[tuple[float, VehicleInfo]] = []
    sub = client.declare_subscriber(
        f"bandada/{swarm}/vehicle/42/info",
        lambda s: heard.append(
            (time.monotonic(), msgspec.msgpack.decode(s.payload.to_bytes(), type=VehicleInfo))
        ),
    )
    try:
        assert wait_until(lambda: len(heard) >= 2, timeout=60) is not None, log.read_text()
        t0 = time.monotonic()
        time.sleep(3.0)
        window = [info for t, info in heard if t0 <= t < t0 + 3.0]
    finally:
        sub.undeclare()
        client.close()
        code = stop(proc)
        if env_db is not None:
            os.environ["BANDADA_DB"] = env_db
    info = window[-1]
    assert (info.model, info.user_id, info.vehicle_type) == (
        "Test Hexacopter",
        "HEX-01",
        VehicleType.COPTER,
    )
    assert info.cruise_speed_m_s == pytest.approx(9.5)
    assert 8 <= len(window) <= 16, len(window)  # 4 Hz (the default 1 Hz would give 3)
    assert code == 0


@pytest.mark.network
def test_run_in_router_mode_relays_for_peers(swarm_db: Path, tmp_path: Path) -> None:
    """Node 1 is the only router (`run --mode router`); nodes 2 and 3 and a plain client
    connect to it alone, and everyone lists everyone."""
    swarm = f"rm{os.getpid()}"
    endpoint = f"tcp/127.0.0.1:{free_tcp_port()}"
    log = tmp_path / "nodes.log"
    router = spawn(
        node_cmd("run", "--id", "1", "--swarm", swarm, "--mode", "router", "--listen", endpoint),
        log,
    )
    peers = [start_node(i, endpoint, swarm, log=log) for i in (2, 3)]
    client = None
    try:
        assert wait_until(lambda: router.poll() is None and _connectable(endpoint), 60) is not None
        client = plain_session(endpoint)
        # what listens there is a router (Zenoh says so in the transport's "whatami")
        assert wait_until(lambda: len(list(client.info.routers_zid())) == 1, 10) is not None
        ids = [1, 2, 3]
        seen = wait_until(
            lambda: all(peers_of(client, swarm, i) == [j for j in ids if j != i] for i in ids),
            timeout=60,
        )
        assert seen is not None, log.read_text()
    finally:
        if client is not None:
            client.close()
        codes = [stop(p) for p in (*peers, router)]
    assert codes == [0, 0, 0]


@pytest.mark.network
def test_the_router_command_joins_nodes_and_exits_cleanly(swarm_db: Path, tmp_path: Path) -> None:
    swarm = f"rc{os.getpid()}"
    endpoint = f"tcp/127.0.0.1:{free_tcp_port()}"
    log = tmp_path / "router.log"
    router = spawn(node_cmd("router", "--listen", endpoint), log)
    nodes = []
    client = None
    try:
        assert wait_until(lambda: _connectable(endpoint), 60) is not None, log.read_text()
        nodes = [start_node(i, endpoint, swarm) for i in (4, 5)]
        client = plain_session(endpoint)
        assert wait_until(lambda: len(list(client.info.routers_zid())) == 1, 10) is not None
        assert (
            wait_until(
                lambda: peers_of(client, swarm, 4) == [5] and peers_of(client, swarm, 5) == [4],
                timeout=60,
            )
            is not None
        )
    finally:
        if client is not None:
            client.close()
        node_codes = [stop(p) for p in nodes]
        router.send_signal(signal.SIGINT)
        router_code = router.wait(timeout=20)
    assert node_codes == [0, 0] and router_code == 0
    assert "zenoh router" in log.read_text() and endpoint in log.read_text()


def _connectable(endpoint: str) -> bool:
    import socket

    host, port = endpoint.split("/", 1)[1].rsplit(":", 1)
    with socket.socket() as s:
        s.settimeout(0.5)
        return s.connect_ex((host, int(port))) == 0


@pytest.mark.parametrize("bad", [0.0, -5.0, float("nan"), 1e9])
def test_a_bad_plan_timeout_is_refused(bad: float) -> None:
    """`--plan-timeout` (the demo scales it with its speed-up: planning is wall-clock
    work) is checked like the other settings: a clear error, never a node that gives
    up at once or waits forever."""
    from swarm_node.runtime.config import load_config

    with pytest.raises(ValueError, match="plan_timeout_s"):
        load_config(None, node_id=1, plan_timeout_s=bad)
    assert load_config(None, node_id=1, plan_timeout_s=300.0).plan_timeout_s == 300.0


def test_the_demo_gives_planning_its_wall_time() -> None:
    from swarm_sim.demo import plan_timeout_s

    assert plan_timeout_s(5.0) == 300.0 and plan_timeout_s(1.0) == 60.0
    # the demo's nodes share the machine's cores, each planning the whole fleet at once:
    # the 60 s a node has on its own computer, stretched by nodes per core
    assert plan_timeout_s(3.0, 11, cpus=2) == 990.0
    assert plan_timeout_s(3.0, 6, cpus=2) == 540.0
    assert plan_timeout_s(3.0, 2, cpus=2) == plan_timeout_s(3.0, 1, cpus=8) == 180.0
    assert plan_timeout_s(100.0, 11, cpus=1) == 3600.0  # the node's config bound


def test_avoidance_is_on_by_default_and_can_be_switched_off(tmp_path: Path) -> None:
    """`--avoidance/--no-avoidance` and `avoidance = false` in the TOML reach
    the core (NodeSettings.avoidance); a value that is not a boolean is refused."""
    from typer.testing import CliRunner

    from swarm_node.cli import app

    assert node_settings(load_config(None, node_id=1)).avoidance is True
    assert node_settings(load_config(None, node_id=1, avoidance=False)).avoidance is False
    toml = tmp_path / "node.toml"
    toml.write_text("node_id = 3\navoidance = false\n")
    assert node_settings(load_config(toml)).avoidance is False
    assert node_settings(load_config(toml, avoidance=True)).avoidance is True
    toml.write_text('node_id = 3\navoidance = "sometimes"\n')
    with pytest.raises(ValueError, match="avoidance"):
        load_config(toml)
    runner = CliRunner()  # the flag parses (the bad id stops the node before it starts)
    bad_id = runner.invoke(app, ["run", "--id", "0", "--no-avoidance"])
    assert bad_id.exit_code == 2 and "node_id" in bad_id.output
    assert runner.invoke(app, ["run", "--id", "0", "--avoidance=maybe"]).exit_code == 2


@pytest.mark.parametrize("address", ["garbage", "tcp:999.0.0.1:5760", "/dev/nonexistent"])
def test_an_autopilot_address_that_cannot_work_stops_the_node_at_start(address: str) -> None:
    from typer.testing import CliRunner

    from swarm_node.cli import app

    result = CliRunner().invoke(app, ["run", "--id", "7", "--autopilot", address])
    assert result.exit_code == 2
    assert result.output.startswith(f"swarm-node: autopilot {address!r}: ")
    assert len(result.output.strip().splitlines()) == 1, result.output


def test_a_client_whose_router_is_not_there_gets_a_clear_error(swarm_db: Path) -> None:
    """`--mode client` with the router down: exit 2 and a sentence, no traceback (the
    service unit restarts the node until the router is up)."""
    r = subprocess.run(
        node_cmd(
            "run",
            "--id",
            "1",
            "--mode",
            "client",
            "--connect",
            "tcp/127.0.0.1:9",
            "--autopilot",
            "tcp:127.0.0.1:9",
        ),
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )
    assert r.returncode == 2, r.stderr
    assert "cannot open Zenoh" in r.stderr and "router" in r.stderr, r.stderr
    assert "Traceback" not in r.stderr + r.stdout
