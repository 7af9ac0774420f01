"""Device configuration through AT command mode against emulated XTends on pseudo-terminals
(guard times counted on a fast simulated clock), refusal to run on a mismatch, the CLIs."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import threading
from pathlib import Path

import pytest

from radio_gateway.core import xtend
from radio_gateway.runtime.gateway import GatewayConfig, run_gateway
from radio_gateway.runtime.xtend_config import configure, verify
from swarm_proto.clock import ScaledClock
from swarm_sim.radio_channel.pty import PtyRadioChannel

FAST = 4.0  # simulated seconds per wall second: 1 s guard times, and the 1 s an answer may take,
# take 250 ms (an emulator thread descheduled on a loaded host must still answer in time)
FAST_ALONE = 20.0  # the same in 50 ms, for the test that runs alone (marked `timing`)
REPO = Path(__file__).resolve().parents[2]
BIN = Path(sys.executable).parent


def test_settings_map_to_at_registers() -> None:
    regs = xtend.RadioSettings(address=7, channel=3).registers()
    assert regs["BD"] == 8 and regs["BR"] == 1 and regs["DT"] == 0xFFFF and regs["MY"] == 7
    assert regs["MT"] == 0 and regs["RR"] == 0 and regs["PK"] == regs["RB"] == 0x800
    assert xtend.RadioSettings(rf_bps=9600).registers()["PK"] == 0x100
    with pytest.raises(ValueError, match="serial_baud"):
        xtend.RadioSettings(serial_baud=12345).registers()
    with pytest.raises(ValueError, match="ATHP"):
        xtend.RadioSettings(channel=12).registers()
    assert xtend.command("BD", 8) == b"ATBD 8\r" and xtend.command("WR") == b"ATWR\r"
    assert xtend.mismatches({"BD": 8}, {"BD": 3}) == [
        "ATBD is 3, want 8 (interface (serial) data rate: 3 = 9600, 7 = 115200, 8 = 230400)"
    ]


@pytest.mark.timing  # AT guard times in real time on an emulator thread: run alone
def test_configure_a_factory_module_then_verify_it() -> None:
    clock = ScaledClock(FAST)
    settings = xtend.RadioSettings(address=12, channel=4, power_level=2)
    with PtyRadioChannel(1, clock=clock) as channel:  # factory: 9600 baud
        port = channel.ports[0]
        problems = verify(port, settings, clock=clock)
        assert problems and "no OK" in problems[0]  # it does not answer at 230,400
        report = configure(port, settings, clock=clock)
        assert report.found_baud == 9600 and report.written
        assert set(report.changed) >= {"BD", "DT", "MY", "HP", "PL", "RR"}
        assert verify(port, settings, clock=clock) == []
        channel.power_cycle(0)  # written to flash: survives
        assert verify(port, settings, clock=clock) == []
        assert verify(port, xtend.RadioSettings(address=13), clock=clock) == [
            "ATPL is 2, want 4 (power level: 0 = 1 mW, 1 = 10 mW, 2 = 100 mW, 3 = 500 mW, 4 = 1 W)",
            "ATHP is 4, want 0 (hopping channel)",
            "ATMY is C, want D (source address)",
        ]


def test_the_gateway_refuses_to_run_on_a_mismatch(tmp_path: Path) -> None:
    clock = ScaledClock(FAST)
    key = tmp_path / "swarm.key"
    key.write_text("00" * 32)
    with PtyRadioChannel(1, clock=clock) as channel:
        cfg = GatewayConfig(node_id=3, port=channel.ports[0], key_file=str(key))
        assert run_gateway(cfg, threading.Event(), clock) == 3


def test_a_taken_endpoint_is_told_before_the_radio_is_touched(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """Another process listens on the gateway's endpoint: exit 4 with the endpoint and
    Zenoh's reason, at once (the serial port, which does not exist, is never opened)."""
    import socket

    from radio_gateway.runtime.gateway import EXIT_ZENOH
    from swarm_proto.session import ZenohSettings

    key = tmp_path / "swarm.key"
    key.write_text("00" * 32)
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        endpoint = f"tcp/127.0.0.1:{taken.getsockname()[1]}"
        cfg = GatewayConfig(
            node_id=3,
            port=str(tmp_path / "no-such-tty"),
            key_file=str(key),
            zenoh=ZenohSettings(listen=(endpoint,)),
            configure_radio=True,
        )
        with caplog.at_level("ERROR"):
            assert run_gateway(cfg, threading.Event(), ScaledClock(FAST)) == EXIT_ZENOH
    said = caplog.text
    assert f"cannot open the Zenoh session (listen {endpoint})" in said
    assert "in use" in said and "no-such-tty" not in said


def _env(**extra: str) -> dict[str, str]:
    env = dict(os.environ)
    env.update(extra)
    return env


@pytest.mark.timing  # AT command guard times on an emulated radio, in real time: run alone
def test_cli_emulator_and_gateway_refusal(tmp_path: Path) -> None:
    """`swarm-sim radio` prints its ports; `radio-gateway run` on a factory-set module
    refuses to start, and with --configure it sets the module up and runs."""
    spec = f"scaled:{FAST_ALONE}:{1.75e9}:{__import__('time').monotonic()}"
    env = _env(BANDADA_CLOCK=spec)
    sim = subprocess.Popen(
        [BIN / "swarm-sim", "radio", "--nodes", "1", "--factory", "--stats-every", "100"],
        stdout=subprocess.PIPE,
        text=True,
        env=env,
    )
    try:
        assert sim.stdout is not None
        ports = json.loads(sim.stdout.readline())["ports"]
        key = tmp_path / "k"
        subprocess.run([BIN / "radio-gateway", "keygen", str(key)], check=True, env=env)
        assert len(key.read_text().strip()) == 64 and (key.stat().st_mode & 0o777) == 0o600
        base = [BIN / "radio-gateway", "run", "--port", ports[0], "--node-id", "4"]
        base += ["--key-file", str(key), "--connect", "tcp/127.0.0.1:9"]
        bad = subprocess.run(base, capture_output=True, text=True, env=env, timeout=120)
        assert bad.returncode == 3
        assert "refusing to run" in bad.stderr
        ok = subprocess.Popen([*base, "--configure"], stderr=subprocess.PIPE, text=True, env=env)
        try:
            assert ok.stderr is not None
            for line in ok.stderr:
                if "bridging" in line:
                    break
                assert "refusing" not in line and "Traceback" not in line, line
            else:
                raise AssertionError("the gateway never started bridging")
        finally:
            ok.terminate()
            assert ok.wait(timeout=30) == 0  # clean shutdown on SIGTERM
    finally:
        sim.terminate()
        sim.wait(timeout=30)


@pytest.mark.parametrize(
    "args, why",
    [
        (["--status-mode", "sometimes"], "status_mode"),
        (["--min-level", "4"], "min_level"),
        (["--min-level", "-1"], "min_level"),
    ],
)
def test_the_gateway_cli_refuses_bad_send_on_error_settings(args: list[str], why: str) -> None:
    """A bad setting is a one-line error and exit code 2, before any port is opened."""
    from typer.testing import CliRunner

    from radio_gateway.cli import app

    result = CliRunner().invoke(
        app, ["run", "--node-id", "7", "--port", "/nonexistent", "--key-file", "k", *args]
    )
    assert result.exit_code == 2, result.output
    assert "bad configuration" in result.output and why in result.output
    assert "Traceback" not in result.output


def test_bad_send_on_error_numbers_in_a_config_file_are_refused(tmp_path: Path) -> None:
    from radio_gateway.runtime.gateway import load_config

    cfg = tmp_path / "radio.toml"
    for bad in ("threshold_m = 0.0", "heartbeat_s = -1.0", "republish_hz = 0.0"):
        cfg.write_text(f'node_id = 7\nport = "/dev/x"\nkey_file = "k"\n{bad}\n')
        with pytest.raises(Exception, match="> 0"):
            load_config(cfg, {})
    cfg.write_text('node_id = 7\nport = "/dev/x"\nkey_file = "k"\nstatus_mode = "every"\n')
    c = load_config(cfg, {})
    assert c.node_config().send_on_error is None and c.bridge().predictor is None
    on = load_config(cfg, {"status_mode": "on_error"}).node_config()
    assert on.send_on_error is not None and on.tdm.min_payload >= 88
