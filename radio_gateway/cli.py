"""`radio-gateway`: bridges local Zenoh to the broadcast radio."""

from __future__ import annotations

import typer

app = typer.Typer(help="bandada radio gateway: Zenoh <-> 900 MHz TDM radio.", no_args_is_help=True)


@app.callback()
def _group() -> None:
    """Always a command group, even with one command."""


@app.command()
def run() -> None:
    """Run the gateway on a serial port."""
    typer.echo("radio-gateway run: not implemented yet (issue 6)", err=True)
    raise typer.Exit(2)


@app.command()
def version() -> None:
    """Print the bandada version."""
    from importlib.metadata import version as v

    typer.echo(v("bandada"))


def main() -> None:
    app()
