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
def run(
    config: str | None = typer.Option(None, "--config", "-c", help="node TOML file"),
    node_id: int | None = typer.Option(
        None, "--id", help="this node's id (the database system id)"
    ),
    autopilot: str | None = typer.Option(
        None,
        help="MAVLink connection: tcp:127.0.0.1:5760, udpin:0.0.0.0:14550, /dev/ttyACM0,115200",
    ),
    swarm: str | None = typer.Option(None, help="swarm name (default: default)"),
    db: str | None = typer.Option(None, help="swarm database file (else $BANDADA_DB)"),
    mode: str | None = typer.Option(None, help="Zenoh mode: peer (default) or router (multi-hop)"),
    connect: list[str] = typer.Option([], help="Zenoh endpoints to connect to"),
    listen: list[str] = typer.Option([], help="Zenoh endpoints to listen on"),
    lease_ms: int | None = typer.Option(None, help="Zenoh lease: how soon a frozen peer is lost"),
    link_timeout: float | None = typer.Option(
        None, help="autopilot silence (s) that counts as link loss"
    ),
    status_hz: float | None = typer.Option(None, help="VehicleStatus rate (default 5)"),
    info_hz: float | None = typer.Option(None, help="VehicleInfo rate (default 1)"),
    log_level: str = typer.Option("INFO", help="DEBUG, INFO, WARNING, ERROR"),
    record: str | None = typer.Option(
        None, "--record", help="flight recorder: every VehicleStatus heard to this CSV"
    ),
) -> None:
    """Run the node: autopilot link, monitoring, swarm manager, state machine."""
    import logging

    from swarm_proto import clock_from_env
    from swarm_proto.shutdown import stop_event

    from .runtime.config import load_config
    from .runtime.launch import build_node

    logging.basicConfig(
        level=log_level.upper(), format="%(asctime)s %(levelname)s %(name)s: %(message)s"
    )
    try:
        cfg = load_config(
            config,
            node_id=node_id,
            autopilot=autopilot,
            swarm=swarm,
            db=db,
            zenoh_mode=mode,
            zenoh_connect=tuple(connect),
            zenoh_listen=tuple(listen),
            zenoh_lease_ms=lease_ms,
            link_timeout_s=link_timeout,
            status_hz=status_hz,
            info_hz=info_hz,
        )
    except ValueError as exc:
        typer.echo(f"swarm-node: {exc}", err=True)
        raise typer.Exit(2) from exc
    recorder = None
    if record:
        from .runtime.recorder import StatusRecorder

        try:
            recorder = StatusRecorder(record)
        except OSError as exc:
            typer.echo(f"swarm-node: --record {record}: {exc.strerror or exc}", err=True)
            raise typer.Exit(2) from exc
    stop = stop_event()
    try:
        node = build_node(cfg, clock_from_env())
    except (ValueError, OSError) as exc:
        typer.echo(f"swarm-node: {exc}", err=True)
        raise typer.Exit(2) from exc
    if recorder is not None:
        recorder.attach(node.bus)
    try:
        node.run(stop)
    finally:
        if recorder is not None:
            recorder.close()


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


if __name__ == "__main__":
    main()
