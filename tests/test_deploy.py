"""The shipped deployment files are valid for the tools that read them."""

from __future__ import annotations

import configparser

import pytest
import zenoh

from tests.conftest import REPO


@pytest.mark.parametrize("name", ["router.json5", "peer.json5"])
def test_zenoh_configs_load(name: str) -> None:
    conf = zenoh.Config.from_file(str(REPO / "deploy" / "zenoh" / name))
    assert '"' + name.split(".")[0] + '"' in conf.get_json("mode")
    assert conf.get_json("transport/link/tx/lease") == "2000"


@pytest.mark.parametrize(
    "unit", sorted((REPO / "deploy" / "systemd").glob("*.service")), ids=lambda p: p.name
)
def test_service_units_parse_and_stop_cleanly(unit: object) -> None:
    cp = configparser.ConfigParser(strict=False, interpolation=None)
    cp.read(unit)  # type: ignore[arg-type]
    assert cp["Service"]["ExecStart"].startswith("/opt/bandada/.venv/bin/")
    assert cp["Service"]["KillSignal"] == "SIGINT"


def test_the_radio_gateway_runs_before_everything_else() -> None:
    cp = configparser.ConfigParser(strict=False, interpolation=None)
    cp.read(REPO / "deploy" / "systemd" / "radio-gateway.service")
    assert int(cp["Service"]["Nice"]) < 0  # its slot timing matters most


def test_udev_rules_name_the_devices() -> None:
    text = (REPO / "deploy" / "udev" / "99-bandada.rules").read_text()
    assert 'SYMLINK+="bandada-radio"' in text and 'SYMLINK+="bandada-autopilot"' in text


def test_example_node_config_loads() -> None:
    from swarm_node.runtime.config import load_config

    cfg = load_config(REPO / "deploy" / "config" / "node.toml")
    assert cfg.node_id == 1 and cfg.zenoh.connect == ("tcp/192.168.1.10:7447",)
    assert cfg.link_timeout_s == 0.6


def test_example_radio_config_loads() -> None:
    from radio_gateway.runtime.gateway import load_config

    cfg = load_config(REPO / "deploy" / "config" / "radio.toml", {})
    assert cfg.port == "/dev/bandada-radio" and cfg.time_source.startswith("mavlink:")
