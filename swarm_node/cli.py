"""`swarm-node`: the vehicle node process."""

from __future__ import annotations

import typer

app = typer.Typer(
    help="bandada vehicle node: one per vehicle companion computer.", no_args_is_help=True
)


@app.callback()
def _group() -> None:
    """Always a command group, even with one command."""


@app.command()
def run() -> None:
    """Run the node (autopilot link, monitoring, swarm manager, state machine)."""
    typer.echo("swarm-node run: not implemented yet (issue 4)", err=True)
    raise typer.Exit(2)


@app.command()
def router(
    listen: list[str] = typer.Option(["tcp/0.0.0.0:7447"], help="Zenoh endpoints to listen on"),
    connect: list[str] = typer.Option([], help="other routers to connect to"),
    config: str | None = typer.Option(None, help="a Zenoh JSON5 config file applied first"),
) -> None:
    """Run a Zenoh router (the lab router, or a multi-hop relay) until SIGINT/SIGTERM."""
    from swarm_proto.session import ZenohSettings, open_session
    from swarm_proto.shutdown import stop_event

    stop = stop_event()
    settings = ZenohSettings(
        mode="router", listen=tuple(listen), connect=tuple(connect), config_file=config
    )
    session = open_session(settings)
    typer.echo(f"zenoh router {session.zid()} listening on {', '.join(listen)}", err=True)
    try:
        stop.wait()
    finally:
        session.close()


@app.command()
def version() -> None:
    """Print the bandada version."""
    from importlib.metadata import version as v

    typer.echo(v("bandada"))


def main() -> None:
    app()
