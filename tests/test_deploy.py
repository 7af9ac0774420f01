"""The shipped deployment files are valid for the tools that read them."""

from __future__ import annotations

import configparser
import json
import re
import shutil
import subprocess
from pathlib import Path

import msgspec
import pytest
import zenoh

from swarm_proto.session import ZenohSettings, zenoh_config
from tests.conftest import REPO

ZENOH_FILES = {
    "router.json5": "router",
    "peer.json5": "peer",
    "client.json5": "client",
    "scouting-peer.json5": "peer",
}
UNITS = sorted((REPO / "deploy" / "systemd").glob("*.service"))


@pytest.mark.parametrize("name", sorted(ZENOH_FILES))
def test_zenoh_configs_load(name: str) -> None:
    conf = zenoh.Config.from_file(str(REPO / "deploy" / "zenoh" / name))
    assert json.loads(conf.get_json("mode")) == ZENOH_FILES[name]
    assert conf.get_json("transport/link/tx/lease") == "2000"


@pytest.mark.parametrize("name", sorted(ZENOH_FILES))
def test_a_zenoh_file_is_kept_unless_overridden(name: str) -> None:
    """What the file says stands (the router's multicast scouting, a client's mode);
    only settings given with a non-default value override it."""
    path = str(REPO / "deploy" / "zenoh" / name)
    file = zenoh.Config.from_file(path)
    ours = zenoh_config(ZenohSettings(config_file=path))
    for key in ("mode", "scouting/multicast/enabled", "connect/endpoints", "listen/endpoints"):
        assert json.loads(ours.get_json(key)) == json.loads(file.get_json(key)), key
    over = zenoh_config(
        ZenohSettings(config_file=path, connect=("tcp/10.77.1.1:7447",), lease_ms=700)
    )
    assert json.loads(over.get_json("connect/endpoints")) == ["tcp/10.77.1.1:7447"]
    assert over.get_json("transport/link/tx/lease") == "700"


def test_router_command_keeps_the_files_multicast_scouting() -> None:
    path = str(REPO / "deploy" / "zenoh" / "router.json5")
    conf = zenoh_config(ZenohSettings(mode="router", config_file=path))
    assert json.loads(conf.get_json("scouting/multicast/enabled")) is True
    assert json.loads(conf.get_json("listen/endpoints")) == ["tcp/0.0.0.0:7447"]


def test_node_and_gcs_take_a_zenoh_config_file(tmp_path: Path) -> None:
    from typer.testing import CliRunner

    from gcs_cli.app import app as gcs_app
    from swarm_node.cli import app as node_app
    from swarm_node.runtime.config import load_config

    client = str(REPO / "deploy" / "zenoh" / "client.json5")
    cfg = load_config(REPO / "deploy" / "config" / "node.toml", zenoh_config_file=client)
    assert cfg.zenoh.config_file == client
    assert json.loads(zenoh_config(cfg.zenoh).get_json("mode")) == "client"
    # a relative config_file in node.toml is relative to the TOML file
    (tmp_path / "z.json5").write_text('{ mode: "client" }')
    (tmp_path / "node.toml").write_text('node_id = 2\n[zenoh]\nconfig_file = "z.json5"\n')
    assert load_config(tmp_path / "node.toml").zenoh.config_file == str(tmp_path / "z.json5")
    # a broken or missing file: one clear line, exit 2, from both commands
    (tmp_path / "bad.json5").write_text("{ mode: ")
    for bad in (tmp_path / "bad.json5", tmp_path / "missing.json5"):
        with pytest.raises(ValueError, match="cannot load Zenoh config"):
            load_config(None, node_id=1, zenoh_config_file=str(bad))
        r = CliRunner().invoke(node_app, ["run", "--id", "1", "--zenoh-config", str(bad)])
        assert r.exit_code == 2 and "cannot load Zenoh config" in r.output
        r = CliRunner().invoke(gcs_app, ["--zenoh-config", str(bad), "status"])
        assert r.exit_code == 2 and "cannot load Zenoh config" in r.output


def test_peer_json5_instructions_name_an_option_that_exists() -> None:
    text = (REPO / "deploy" / "zenoh" / "peer.json5").read_text()
    assert "--zenoh-config" in text
    from typer.testing import CliRunner

    from gcs_cli.app import app as gcs_app
    from swarm_node.cli import app as node_app

    assert "--zenoh-config" in CliRunner().invoke(node_app, ["run", "--help"]).output
    assert "--zenoh-config" in CliRunner().invoke(gcs_app, ["--help"]).output


def _unit(path: Path) -> configparser.ConfigParser:
    cp = configparser.ConfigParser(strict=False, interpolation=None)
    cp.optionxform = str  # type: ignore[assignment,method-assign]
    cp.read(path)
    return cp


@pytest.mark.parametrize("unit", UNITS, ids=lambda p: p.name)
def test_service_units_parse_and_stop_cleanly(unit: Path) -> None:
    s = _unit(unit)["Service"]
    assert s["ExecStart"].startswith("/opt/bandada/.venv/bin/")
    assert s["KillSignal"] == "SIGINT"
    assert s["Restart"] == "always" and s["User"] == "bandada"
    assert s["StateDirectory"].startswith("bandada")
    for key in ("NoNewPrivileges", "ProtectSystem", "ProtectHome", "PrivateTmp"):
        assert s[key] in ("yes", "strict"), key
    assert s["CapabilityBoundingSet"] == ""
    assert _unit(unit)["Unit"]["StartLimitIntervalSec"] == "0"  # restart for ever


@pytest.mark.skipif(shutil.which("systemd-analyze") is None, reason="no systemd-analyze")
@pytest.mark.parametrize("unit", UNITS, ids=lambda p: p.name)
def test_service_units_are_rated_safe(unit: Path) -> None:
    r = subprocess.run(
        ["systemd-analyze", "security", "--offline=true", "--no-pager", str(unit)],
        capture_output=True,
        text=True,
        timeout=60,
    )
    m = re.search(r"Overall exposure level for \S+: ([0-9.]+)", r.stdout + r.stderr)
    if m is None:
        pytest.skip(f"systemd-analyze gave no rating: {r.stderr.strip()[:200]}")
    assert float(m.group(1)) <= 5.0, r.stdout[-2000:]


def test_mavlink_fanout_unit_feeds_the_node_and_the_radio_gateway() -> None:
    fan = _unit(REPO / "deploy" / "systemd" / "bandada-mavlink.service")["Service"]["ExecStart"]
    assert "--master=/dev/bandada-autopilot" in fan and "--streamrate=-1" in fan
    node = msgspec.toml.decode((REPO / "deploy" / "config" / "radio.toml").read_bytes())
    assert "--out=" + node["time_source"].removeprefix("mavlink:").replace("udpin", "udpout") in fan
    assert "--out=udpout:127.0.0.1:14550" in fan
    assert "udpin:127.0.0.1:14550" in (REPO / "deploy" / "config" / "node.toml").read_text()


def test_the_radio_gateway_runs_before_everything_else() -> None:
    cp = configparser.ConfigParser(strict=False, interpolation=None)
    cp.read(REPO / "deploy" / "systemd" / "radio-gateway.service")
    assert int(cp["Service"]["Nice"]) < 0  # its slot timing matters most


def test_udev_rules_name_the_devices() -> None:
    text = (REPO / "deploy" / "udev" / "99-bandada.rules").read_text()
    assert 'SYMLINK+="bandada-radio"' in text and 'SYMLINK+="bandada-autopilot"' in text


def test_udev_rules_match_one_device_not_a_vendor() -> None:
    """Every rule (active or commented example) that names a bandada device matches a
    serial number, a port path or a kernel name: a vendor id alone matches any adapter."""
    lines = (REPO / "deploy" / "udev" / "99-bandada.rules").read_text().splitlines()
    rules = [ln.lstrip("# ") for ln in lines if 'SYMLINK+="bandada-' in ln]
    assert rules
    for rule in rules:
        assert re.search(r"(ID_SERIAL_SHORT|ATTRS\{serial\}|ID_PATH|KERNEL)}?==", rule), rule


def test_example_node_config_loads() -> None:
    from swarm_node.runtime.config import load_config

    cfg = load_config(REPO / "deploy" / "config" / "node.toml")
    assert cfg.node_id == 1 and cfg.zenoh.connect == ("tcp/192.168.1.10:7447",)
    assert cfg.link_timeout_s == 0.6


def test_example_radio_config_loads() -> None:
    from radio_gateway.runtime.gateway import load_config

    cfg = load_config(REPO / "deploy" / "config" / "radio.toml", {})
    assert cfg.port == "/dev/bandada-radio" and cfg.time_source.startswith("mavlink:")


def test_radio_vehicle_node_config_loads_and_pairs_with_the_gateway() -> None:
    from radio_gateway.runtime.gateway import load_config as gateway_config
    from swarm_node.runtime.config import load_config

    node = load_config(REPO / "deploy" / "config" / "node-radio.toml")
    gateway = gateway_config(REPO / "deploy" / "config" / "radio.toml", {})
    assert node.autopilot == "udpin:127.0.0.1:14550"
    assert gateway.zenoh.connect == node.zenoh.listen == ("tcp/127.0.0.1:7447",)


def test_router_command_refuses_a_broken_config_in_one_line(tmp_path: Path) -> None:
    from typer.testing import CliRunner

    from swarm_node.cli import app as node_app

    (tmp_path / "bad.json5").write_text("{ mode: ")
    r = CliRunner().invoke(node_app, ["router", "--config", str(tmp_path / "bad.json5")])
    assert r.exit_code == 2 and "cannot load Zenoh config" in r.output


def test_certs_command_writes_a_swarm(tmp_path: Path) -> None:
    from typer.testing import CliRunner

    from swarm_node.cli import app as node_app

    args = [
        "certs",
        "make",
        "--out",
        str(tmp_path / "c"),
        "--vehicles",
        "1-3",
        "--router-host",
        "10.0.0.1",
    ]
    r = CliRunner().invoke(node_app, args)
    assert r.exit_code == 0, r.output
    names = {Path(line).name for line in r.output.split()}
    assert {"ca.pem", "router.json5", "vehicle-3.json5", "gcs-900.json5"} <= names
    r = CliRunner().invoke(node_app, args)  # the CA exists: refused, nothing overwritten
    assert r.exit_code == 2 and "exists" in r.output
