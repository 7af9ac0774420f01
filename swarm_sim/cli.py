"""`swarm-sim`: simulated vehicles, the emulated radio channel and the demo."""

from __future__ import annotations

import typer

app = typer.Typer(
    help="bandada simulator: vehicles, radio channel, scenarios.", no_args_is_help=True
)


@app.callback()
def _group() -> None:
    """Always a command group, even with one command."""


@app.command()
def demo(
    vehicles: int = typer.Option(4, help="number of simulated vehicles"),
    speedup: float = typer.Option(10.0, help="simulated seconds per wall second"),
    duration: float = typer.Option(60.0, help="simulated seconds to run"),
) -> None:
    """Run the demo scenario on this machine (Zenoh on 127.0.0.1 only)."""
    from .demo import run_demo

    raise typer.Exit(run_demo(vehicles=vehicles, speedup=speedup, duration_s=duration))


@app.command()
def radio(
    nodes: int = typer.Option(4, help="number of emulated XTend modules (pseudo-terminals)"),
    rf_bps: int = typer.Option(115_200, help="RF data rate the modules are preset to"),
    loss: float = typer.Option(0.0, help="probability a receiver misses a packet"),
    ber: float = typer.Option(0.0, help="bit error rate of delivered packets"),
    sync_ms: float = typer.Option(6.0, help="sync preamble every packet pays"),
    latency_ms: float = typer.Option(0.5, help="receiving module latency"),
    seed: int = typer.Option(0),
    links: str | None = typer.Option(None, help="directory for radio0..radioN-1 symlinks"),
    factory: bool = typer.Option(
        False, help="modules at factory settings (9600 baud) instead of configured for bandada"
    ),
    stats_every: float = typer.Option(5.0, help="seconds between statistics lines"),
) -> None:
    """Emulate N XTend modules on one broadcast channel; prints the ports as JSON.

    Uses BANDADA_CLOCK (simulated time) when set. Stops on Ctrl-C / SIGTERM."""
    import json
    from pathlib import Path

    from radio_gateway.core.xtend import RadioSettings
    from swarm_proto.clock import clock_from_env
    from swarm_proto.shutdown import stop_event

    from .radio_channel.model import ChannelParams
    from .radio_channel.pty import PtyRadioChannel

    params = ChannelParams(
        sync_s=sync_ms / 1000,
        detect_s=sync_ms / 1000,
        latency_s=latency_ms / 1000,
        loss=loss,
        ber=ber,
        seed=seed,
    )
    registers = None if factory else RadioSettings(rf_bps=rf_bps).registers()
    stop = stop_event()
    clock = clock_from_env()
    with PtyRadioChannel(
        nodes, params, clock, registers=registers, link_dir=Path(links) if links else None
    ) as channel:
        typer.echo(json.dumps({"ports": channel.ports, "links": [str(p) for p in channel.links]}))
        while not stop.wait(stats_every):
            typer.echo(json.dumps(channel.stats()["channel"]))
    raise typer.Exit(0)


def main() -> None:
    app()
