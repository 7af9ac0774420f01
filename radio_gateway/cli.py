"""`radio-gateway`: bridges local Zenoh to the broadcast radio."""

from __future__ import annotations

import json
import logging
import os
import secrets
from pathlib import Path

import typer

app = typer.Typer(help="bandada radio gateway: Zenoh <-> 900 MHz TDM radio.", no_args_is_help=True)


@app.callback()
def _group() -> None:
    """Always a command group, even with one command."""


def _logging(verbose: bool) -> None:
    logging.basicConfig(
        level=logging.DEBUG if verbose else logging.INFO,
        format="%(asctime)s %(levelname)s %(name)s: %(message)s",
    )


@app.command()
def run(
    config: Path | None = typer.Option(None, help="TOML file with GatewayConfig fields"),
    port: str | None = typer.Option(None, help="serial port of the XTend, e.g. /dev/ttyUSB0"),
    node_id: int | None = typer.Option(None, help="this node's id (vehicle or ground station)"),
    key_file: str | None = typer.Option(None, help="the swarm key: 32 bytes or 64 hex digits"),
    swarm: str | None = typer.Option(None, help="swarm name (bandada/<swarm>/...)"),
    connect: list[str] = typer.Option([], help="Zenoh endpoint to connect to (repeatable)"),
    listen: list[str] = typer.Option([], help="Zenoh endpoint to listen on (repeatable)"),
    members: str | None = typer.Option(None, help="initial members, e.g. 1,2,3,900"),
    local_id: list[int] = typer.Option([], help="ids whose messages go on air (default: node id)"),
    guard_ms: float | None = typer.Option(None, help="TDM guard time per slot"),
    status_mode: str | None = typer.Option(
        None, help="on_error (send on error, peers predicted; default) | every"
    ),
    min_level: int | None = typer.Option(
        None, help="lowest need level of the adaptive schedule, 0-3 (a ground station: 2)"
    ),
    time_source: str | None = typer.Option(
        None, help="clock | clock-free | mavlink:URL | nmea:PORT[:BAUD]"
    ),
    configure_radio: bool = typer.Option(
        False, "--configure", help="write the radio settings before verifying them"
    ),
    no_verify: bool = typer.Option(False, "--no-verify", help="skip the AT settings check"),
    verbose: bool = typer.Option(False, "--verbose", "-v"),
) -> None:
    """Run the gateway: verify the radio, then bridge Zenoh and the air until stopped."""
    from swarm_proto.session import ZenohSettings
    from swarm_proto.shutdown import stop_event

    from .runtime.gateway import load_config, members_option, run_gateway

    _logging(verbose)
    overrides: dict[str, object] = {
        "port": port,
        "node_id": node_id,
        "key_file": key_file,
        "swarm": swarm,
        "initial_members": members_option(members),
        "local_ids": tuple(local_id) or None,
        "guard_s": guard_ms / 1000.0 if guard_ms is not None else None,
        "status_mode": status_mode,
        "min_level": min_level,
        "time_source": time_source,
        "configure_radio": True if configure_radio else None,
        "verify_radio": False if no_verify else None,
    }
    if connect or listen:
        overrides["zenoh"] = ZenohSettings(connect=tuple(connect), listen=tuple(listen))
    try:
        cfg = load_config(config, overrides)
    except Exception as exc:  # msgspec validation, TOML syntax, missing fields
        typer.echo(f"radio-gateway: bad configuration: {exc}", err=True)
        raise typer.Exit(2) from None
    raise typer.Exit(run_gateway(cfg, stop_event()))


@app.command()
def configure(
    port: str = typer.Option(..., help="serial port of the XTend"),
    node_id: int = typer.Option(..., help="this node's id (becomes the module's MY address)"),
    serial_baud: int = typer.Option(230_400),
    rf_bps: int = typer.Option(115_200),
    power_level: int = typer.Option(4, help="0 = 1 mW .. 4 = 1 W"),
    channel: int = typer.Option(0, help="hopping channel (HP), 0-9"),
    network_id: int = typer.Option(0x3332, help="modem VID (ID)"),
    write: bool = typer.Option(True, help="save to flash (ATWR)"),
    verbose: bool = typer.Option(False, "--verbose", "-v"),
) -> None:
    """Set up an XTend for bandada through AT command mode."""
    from .core.xtend import RadioSettings
    from .runtime.xtend_config import XTendError, verify
    from .runtime.xtend_config import configure as do_configure

    _logging(verbose)
    settings = RadioSettings(serial_baud, rf_bps, power_level, channel, network_id, node_id)
    try:
        report = do_configure(port, settings, write=write)
    except (XTendError, ValueError) as exc:
        typer.echo(f"radio-gateway: {exc}", err=True)
        raise typer.Exit(3) from None
    problems = verify(port, settings)
    typer.echo(
        json.dumps(
            {
                "found_baud": report.found_baud,
                "changed": {k: list(v) for k, v in report.changed.items()},
                "written": report.written,
                "problems": problems,
            }
        )
    )
    raise typer.Exit(3 if problems else 0)


@app.command()
def keygen(path: Path = typer.Argument(..., help="where to write the new swarm key")) -> None:
    """Write a new random swarm key (64 hex digits, mode 0600). Copy it to every node."""
    if path.exists():
        typer.echo(f"radio-gateway: {path} exists; not overwriting", err=True)
        raise typer.Exit(2)
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    with os.fdopen(fd, "w") as f:
        f.write(secrets.token_hex(32) + "\n")
    typer.echo(str(path))


@app.command()
def limits(
    rf_bps: int = typer.Option(115_200),
    guard_ms: float = typer.Option(5.0),
    sync_ms: float = typer.Option(6.0),
    payload: int = typer.Option(42, help="record bytes each slot must carry"),
) -> None:
    """Print the slot table for 1..N nodes: slot length, bytes per slot, rate."""
    from rich.console import Console
    from rich.table import Table

    from .core.airtime import LinkTiming
    from .core.slots import SlotLayout, TdmConfig, physical_limit

    timing = LinkTiming(
        rf_bps=rf_bps, sync_s=sync_ms / 1000, max_packet=2048 if rf_bps > 9600 else 256
    )
    tdm = TdmConfig(guard_s=guard_ms / 1000, min_payload=payload)
    limit = physical_limit(timing, tdm)
    table = Table(title=f"{rf_bps} bps, guard {guard_ms} ms: {limit} nodes at 5 Hz")
    for col in ("nodes", "slot ms", "bytes/slot", "join slot", "rate Hz"):
        table.add_column(col, justify="right")
    for n in range(1, limit + 4):
        lay = SlotLayout.build(tuple(range(1, n + 1)), timing, tdm)
        table.add_row(
            str(n),
            f"{lay.slot_s * 1000:.1f}",
            str(lay.budget),
            "yes" if lay.join_slot else f"every {lay.join_every}",
            f"{lay.rate_hz:.2f}",
        )
    Console().print(table)


@app.command()
def version() -> None:
    """Print the bandada version."""
    from importlib.metadata import version as v

    typer.echo(v("bandada"))


def main() -> None:
    app()


if __name__ == "__main__":
    main()
