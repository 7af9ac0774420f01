"""`swarm-node`: the vehicle node process."""

from __future__ import annotations

import json

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
    mode: str | None = typer.Option(
        None, help="Zenoh mode: peer (default), client (of a router, which routes) or router"
    ),
    connect: list[str] = typer.Option([], help="Zenoh endpoints to connect to"),
    listen: list[str] = typer.Option([], help="Zenoh endpoints to listen on"),
    lease_ms: int | None = typer.Option(None, help="Zenoh lease: how soon a frozen peer is lost"),
    zenoh_config: str | None = typer.Option(
        None,
        "--zenoh-config",
        help="a Zenoh JSON5 config (deploy/zenoh/peer.json5, or one from `certs make`); "
        "--mode/--connect/--listen/--lease-ms override it",
    ),
    link_timeout: float | None = typer.Option(
        None, help="autopilot silence (s) that counts as link loss"
    ),
    plan_timeout: float | None = typer.Option(
        None, help="how long (s, on the node's clock) the fleet may take to plan (default 60)"
    ),
    status_hz: float | None = typer.Option(None, help="VehicleStatus rate (default 5)"),
    info_hz: float | None = typer.Option(None, help="VehicleInfo rate (default 1)"),
    avoidance: bool | None = typer.Option(
        None,
        "--avoidance/--no-avoidance",
        help="collision avoidance and take-off/landing sequencing at close pads (default on)",
    ),
    log_level: str = typer.Option("INFO", help="DEBUG, INFO, WARNING, ERROR"),
    record: str | None = typer.Option(
        None, "--record", help="flight recorder: every VehicleStatus heard to this CSV"
    ),
) -> None:
    """Run the node: autopilot link, monitoring, swarm manager, state machine."""
    import logging

    import zenoh

    from swarm_proto import clock_from_env
    from swarm_proto.clock import steady
    from swarm_proto.session import zenoh_reason
    from swarm_proto.shutdown import stop_event

    from .runtime.config import load_config
    from .runtime.launch import build_node

    logging.basicConfig(
        level=log_level.upper(), format="%(asctime)s %(levelname)s %(name)s: %(message)s"
    )
    try:  # one endpoint syntax: Zenoh's and MAVLink's spellings both read
        from swarm_proto.endpoints import mavlink_endpoint, zenoh_endpoint

        connect = [zenoh_endpoint(e) for e in connect]
        listen = [zenoh_endpoint(e) for e in listen]
        if autopilot and autopilot.startswith("tcp/"):
            autopilot = mavlink_endpoint(autopilot)
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
            zenoh_config_file=zenoh_config,
            link_timeout_s=link_timeout,
            plan_timeout_s=plan_timeout,
            status_hz=status_hz,
            info_hz=info_hz,
            avoidance=avoidance,
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
        node = build_node(cfg, steady(clock_from_env()))  # never steps
    except (ValueError, OSError) as exc:
        typer.echo(f"swarm-node: {exc}", err=True)
        raise typer.Exit(2) from exc
    except zenoh.ZError as exc:  # a client whose router is not (yet) there, a bad endpoint
        hint = " (a client needs its router running)" if cfg.zenoh.mode == "client" else ""
        typer.echo(f"swarm-node: cannot open Zenoh: {zenoh_reason(exc)}{hint}", err=True)
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
    listen: list[str] = typer.Option(
        [], help="Zenoh endpoints to listen on (default tcp/0.0.0.0:7447, or the file's)"
    ),
    connect: list[str] = typer.Option([], help="other routers to connect to"),
    config: str | None = typer.Option(
        None,
        "--config",
        "--zenoh-config",
        help="a Zenoh JSON5 config (deploy/zenoh/router.json5, or one from `certs make`); "
        "everything it says is kept, --listen/--connect override its endpoints",
    ),
    log_denied: bool = typer.Option(
        False,
        "--log-denied",
        help="log access-control decisions (Zenoh trace level: denied and allowed messages)",
    ),
) -> None:
    """Run a Zenoh router (the lab router, or a multi-hop relay) until SIGINT/SIGTERM."""
    import zenoh

    from swarm_proto.session import ZenohSettings, open_session, zenoh_config
    from swarm_proto.shutdown import stop_event

    acl_log = "zenoh::net::routing::interceptor::access_control=trace"
    zenoh.init_log_from_env_or("info," + acl_log if log_denied else "warn")
    stop = stop_event()
    if not listen and not config:
        listen = ["tcp/0.0.0.0:7447"]
    settings = ZenohSettings(
        mode="router", listen=tuple(listen), connect=tuple(connect), config_file=config
    )
    try:
        conf = zenoh_config(settings)
        session = open_session(settings)
    except Exception as exc:  # a bad file, an endpoint in use, a missing certificate
        typer.echo(f"swarm-node router: {exc}", err=True)
        raise typer.Exit(2) from exc
    endpoints = ", ".join(json.loads(conf.get_json("listen/endpoints") or "[]"))
    scouting = json.loads(conf.get_json("scouting/multicast/enabled") or "false")
    typer.echo(
        f"zenoh router {session.zid()} listening on {endpoints}; multicast scouting "
        f"{'on' if scouting else 'off'}",
        err=True,
    )
    try:
        stop.wait()
    finally:
        session.close()


certs_app = typer.Typer(
    help="A swarm's CA, certificates and mutual-TLS / access-control Zenoh configs.",
    no_args_is_help=True,
)
app.add_typer(certs_app, name="certs")


@certs_app.command("make")
def certs_make(
    out: str = typer.Option(..., "--out", help="directory to write the CA, certificates, configs"),
    vehicles: str = typer.Option(..., help="vehicle ids: 1,2,5-7"),
    gcs: str = typer.Option("900", help="ground station ids"),
    router_host: list[str] = typer.Option(
        ..., help="the router's address or host name as clients dial it (repeat)"
    ),
    swarm: str = typer.Option("default", help="swarm name"),
    install_dir: str | None = typer.Option(
        None, help="where the files will live on the hosts (paths in the JSON5 configs)"
    ),
    days: int = typer.Option(825, help="certificate validity"),
) -> None:
    """Make a swarm's CA, one certificate per vehicle, ground station and router, the
    router's Zenoh config with mutual TLS and access control, and each host's config."""
    from pathlib import Path

    from .certs import make_swarm_certs, parse_ids

    try:
        written = make_swarm_certs(
            Path(out),
            swarm,
            parse_ids(vehicles),
            parse_ids(gcs),
            router_host,
            install_dir=Path(install_dir) if install_dir else None,
            days=days,
        )
    except ValueError as exc:
        typer.echo(f"swarm-node certs make: {exc}", err=True)
        raise typer.Exit(2) from exc
    for path in written:
        typer.echo(str(path))


@app.command()
def version() -> None:
    """Print the bandada version."""
    from importlib.metadata import version as v

    typer.echo(v("bandada"))


def main() -> None:
    app()


if __name__ == "__main__":
    main()
