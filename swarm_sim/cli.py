"""`swarm-sim`: simulated vehicles, the emulated radio channel and the demo."""

from __future__ import annotations

from pathlib import Path

import typer

DEMO_OUT = Path("demo-out")

app = typer.Typer(
    help="bandada simulator: vehicles, radio channel, scenarios.", no_args_is_help=True
)


@app.callback()
def _group() -> None:
    """Always a command group, even with one command."""


@app.command()
def demo(
    vehicle_ids: str | None = typer.Option(
        None,
        "--vehicles",
        help="seed database ids (default 1-6: the six Albatross VTOLs; "
        "7-9 quadcopters, 10-11 rovers, 12-13 boats); at least 4",
    ),
    mixed: bool = typer.Option(
        False, "--mixed", help="add three quadcopters (7-9), a rover (10) and a boat (12)"
    ),
    speedup: float | None = typer.Option(
        None, help="simulated seconds per wall second (default 3, or 1 with --radio)"
    ),
    timeout: float = typer.Option(1800.0, help="wall seconds the whole story may take"),
    keep: bool = typer.Option(False, help="keep the node logs"),
    radio: bool = typer.Option(
        False, "--radio", help="vehicles and ground station talk only over the emulated radio"
    ),
    out: Path = typer.Option(DEMO_OUT, "--out", file_okay=False, help="the report's directory"),
    avoidance: bool = typer.Option(
        True,
        "--avoidance/--no-avoidance",
        help="the nodes' collision avoidance and the close pads' take-off and landing "
        "sequencing (docs/avoidance.md)",
    ),
) -> None:
    """The paper's experiment 1, flown by the real stack (simulated MAVLink vehicles, one
    swarm-node process each, Zenoh on 127.0.0.1, the ground station): base and zones, a
    simultaneous take-off, a survey split across the fleet, a target reported and two
    vehicles voted out to it, the others re-split the survey, one vehicle fails and its
    share is inherited, a perimeter and a route flown with simultaneous arrival, return
    and landing. Narrated live; report.json, the flight CSV and pictures in --out. Exit 1
    if a mission was not completed, airborne vehicles came within 5 m or the survey
    covered under 99 %. With --radio, every message between vehicles and the ground
    station crosses the emulated 900 MHz TDM radio instead."""
    from .experiment import DEFAULT_SPEEDUP, EXPERIMENT_FLEET, MIXED_EXTRA, run

    if vehicle_ids is not None and mixed:
        raise typer.BadParameter("give --vehicles or --mixed, not both", param_hint="--mixed")
    if vehicle_ids is not None:
        try:
            members = tuple(int(x) for x in vehicle_ids.split(","))
        except ValueError as exc:
            raise typer.BadParameter("comma-separated ids", param_hint="--vehicles") from exc
        if len(set(members)) != len(members) or len(members) < 4:
            raise typer.BadParameter("at least 4 distinct ids", param_hint="--vehicles")
    else:
        members = EXPERIMENT_FLEET + (MIXED_EXTRA if mixed else ())
    if speedup is None:
        speedup = 1.0 if radio else DEFAULT_SPEEDUP
    if not (speedup > 0 and speedup <= 100):
        raise typer.BadParameter("must be in (0, 100]", param_hint="--speedup")
    if not (timeout > 0):
        raise typer.BadParameter("must be positive", param_hint="--timeout")
    if radio and speedup > 2.0:
        # TDM slots are a few milliseconds of wall time at high speed-ups; a shared
        # laptop cannot write the serial ports that precisely
        typer.echo(f"warning: --radio at {speedup:g}x leaves the slots little margin", err=True)
    code = run(
        members,
        speedup=speedup,
        timeout_s=timeout,
        keep=keep,
        radio=radio,
        out=out,
        avoidance=avoidance,
    )
    raise typer.Exit(code)


@app.command()
def vehicle(
    model: str = typer.Option(
        "copter", help="plane|vtol|copter|rover|boat; a comma list is cycled over --count"
    ),
    instance: int = typer.Option(0, help="first instance; listens on tcp:HOST:5760+10*instance"),
    count: int = typer.Option(1, min=1, help="vehicles in this process (instances I..I+N-1)"),
    home: str = typer.Option(
        "37.4112,-5.9889,10,90", help="LAT,LON,ALT,HDG of the first vehicle (as SITL --home)"
    ),
    spacing: float = typer.Option(10.0, help="metres between the homes of --count vehicles"),
    speedup: float = typer.Option(1.0, help="simulated seconds per wall second"),
    sysid: int | None = typer.Option(None, help="system id of the first vehicle (default I+1)"),
    host: str = typer.Option("127.0.0.1", help="address to listen on"),
    wind: str = typer.Option("0,0", help="SPEED_M_S,FROM_DEG (also params SIM_WIND_SPD/DIR)"),
) -> None:
    """Simulated ArduPilot vehicles speaking MAVLink on TCP, like ArduPilot SITL.

    Time: the clock in BANDADA_CLOCK if set (shared by every process of a simulation),
    else a clock running --speedup times faster than real time.
    """
    import logging

    from swarm_proto.clock import ScaledClock, SystemClock, clock_from_env
    from swarm_proto.shutdown import stop_event

    from .core import Home, SimOptions, VehicleModel
    from .runtime import VehicleServer, VehicleSpec, spread_homes

    logging.basicConfig(level=logging.WARNING)
    try:
        models = [VehicleModel(m.strip().lower()) for m in model.split(",") if m.strip()]
        first_home = Home.parse(home)
        wind_speed, wind_from = (float(v) for v in wind.split(","))
    except ValueError as exc:
        raise typer.BadParameter(str(exc)) from exc
    if not models:
        raise typer.BadParameter("--model is empty")
    if not speedup > 0:
        raise typer.BadParameter("--speedup must be positive")
    default_clock = SystemClock() if speedup == 1.0 else ScaledClock(speedup)
    clock = clock_from_env(default_clock)
    first_sysid = sysid if sysid is not None else instance + 1
    if first_sysid + count - 1 > 255:
        raise typer.BadParameter("system ids would exceed 255")
    homes = spread_homes(first_home, count, spacing)
    specs = [
        VehicleSpec(
            model=models[k % len(models)],
            instance=instance + k,
            home=homes[k],
            sysid=first_sysid + k,
            options=SimOptions(
                sysid=first_sysid + k, wind_speed_m_s=wind_speed, wind_from_deg=wind_from
            ),
        )
        for k in range(count)
    ]
    stop = stop_event()
    server = VehicleServer(specs, clock, host=host)
    try:
        server.start()
    except OSError as exc:
        typer.echo(f"swarm-sim vehicle: cannot listen: {exc}", err=True)
        raise typer.Exit(1) from exc
    for spec in specs:
        typer.echo(
            f"{VehicleModel(spec.model).value} instance {spec.instance} sysid {spec.system_id} "
            f"on tcp:{host}:{spec.tcp_port}",
            err=True,
        )
    typer.echo(f"clock {clock.spec()}", err=True)
    try:
        server.serve(stop)
    finally:
        server.close()


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
