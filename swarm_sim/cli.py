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


def main() -> None:
    app()
