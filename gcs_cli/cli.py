"""`gcs`: the ground station command line. Sub-command groups live in their own modules
and are registered here."""

from __future__ import annotations

import typer

from .db import app as db_app

app = typer.Typer(help="bandada ground station.", no_args_is_help=True)
app.add_typer(db_app, name="db")


@app.callback()
def _group() -> None:
    """Always a command group, even with one command."""


@app.command()
def version() -> None:
    """Print the bandada version."""
    from importlib.metadata import version as v

    typer.echo(v("bandada"))


def main() -> None:
    app()
