"""`gcs`: the ground station command line (paper section 3): fleet status and every
operator command. Sub-command groups live in their own modules and are registered here.

Every command that talks to the swarm takes --connect (Zenoh endpoints, default the lab
router on tcp/127.0.0.1:7447) or --zenoh-config (a Zenoh JSON5 file), --swarm and --gcs-id.
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass
from pathlib import Path

import msgspec
import typer
from rich.console import Console

from swarm_proto import (
    Ack,
    AckReason,
    CommandArgs,
    CommandKind,
    Geometry,
    GeometryKind,
    GeoPoint,
    LatLon,
    Mission,
    MissionParams,
    MissionType,
    NoFlyZone,
    Selector,
    SelectorKind,
)
from swarm_proto.session import ZenohSettings
from swarm_proto.session import zenoh_config as zenoh_config_of

from .analyze import app as analyze_app
from .db import DbOption
from .db import app as db_app
from .declared import declared as declared_command
from .ground import DEFAULT_GCS_ID, GroundStation, new_seq
from .render import ack_table, fleet_rows, fleet_table

app = typer.Typer(help="bandada ground station.", no_args_is_help=True)
app.add_typer(db_app, name="db")
zone_app = typer.Typer(help="No-fly zones and operating areas.", no_args_is_help=True)
app.add_typer(zone_app, name="zone")
app.add_typer(analyze_app, name="analyze")
app.command(name="declared")(declared_command)  # declared.py (issue 16)
console = Console()


@dataclass
class Link:
    settings: ZenohSettings
    swarm: str
    gcs_id: int

    def open(self) -> GroundStation:
        try:
            return GroundStation(self.settings, self.swarm, self.gcs_id)
        except Exception as exc:
            console.print(f"[red]gcs: cannot open Zenoh: {exc}[/]")
            raise typer.Exit(2) from exc


@app.callback()
def _group(
    ctx: typer.Context,
    connect: list[str] = typer.Option(
        [], help="Zenoh endpoints to connect to (default tcp/127.0.0.1:7447, or the file's)"
    ),
    listen: list[str] = typer.Option([], help="Zenoh endpoints to listen on"),
    mode: str = typer.Option("peer", help="Zenoh mode: peer or client"),
    zenoh_config: str | None = typer.Option(
        None,
        "--zenoh-config",
        help="a Zenoh JSON5 config (deploy/zenoh/peer.json5, or gcs-<id>.json5 from "
        "`swarm-node certs make`); --connect/--listen/--mode override it",
    ),
    swarm: str = typer.Option("default", help="swarm name"),
    gcs_id: int = typer.Option(DEFAULT_GCS_ID, help="this ground station's node id"),
) -> None:
    """bandada ground station."""
    if mode not in ("peer", "client", "router"):
        raise typer.BadParameter("mode is peer, client or router", param_hint="--mode")
    if not connect and not zenoh_config:
        connect = ["tcp/127.0.0.1:7447"]
    settings = msgspec.convert(
        {"mode": mode, "connect": connect, "listen": listen, "config_file": zenoh_config},
        ZenohSettings,
    )
    if zenoh_config:
        try:
            zenoh_config_of(settings)
        except ValueError as exc:
            raise typer.BadParameter(str(exc), param_hint="--zenoh-config") from exc
    ctx.obj = Link(settings, swarm, gcs_id)


# --------------------------------------------------------------------------- parsing


def parse_point(text: str) -> tuple[float, float]:
    try:
        lat, lon = (float(x) for x in text.split(","))
    except ValueError as exc:
        raise typer.BadParameter(f"expected LAT,LON, got {text!r}") from exc
    return lat, lon


def parse_points(text: str) -> list[tuple[float, float]]:
    return [parse_point(p) for p in text.replace(";", " ").split()]


def geometry_from(
    polygon: str | None, point: str | None, circle: str | None, line: str | None, points: str | None
) -> Geometry:
    given = [x for x in (polygon, point, circle, line, points) if x]
    if len(given) != 1:
        raise typer.BadParameter(
            "give exactly one of --polygon, --point, --circle, --line, --points"
        )
    try:
        if polygon:
            return Geometry.polygon(parse_points(polygon))
        if point:
            return Geometry.point(*parse_point(point))
        if circle:
            lat, lon, r = (float(x) for x in circle.split(","))
            return Geometry.circle(lat, lon, r)
        if line:
            return Geometry(
                GeometryKind.POLYLINE, tuple(LatLon(a, b) for a, b in parse_points(line))
            )
        return Geometry(
            GeometryKind.POINTS, tuple(LatLon(a, b) for a, b in parse_points(points or ""))
        )
    except ValueError as exc:  # invalid polygon, NaN, out of range ...
        raise typer.BadParameter(str(exc)) from exc


def selector_from(ids: list[int], fleet: int, quantity: int, payload: str) -> Selector:
    if not 0 <= quantity <= 255:
        raise typer.BadParameter(f"--count must be 1..255, got {quantity}")
    if payload and not quantity:
        raise typer.BadParameter("--payload needs --count: voting picks a payload's vehicles")
    if quantity and ids:
        raise typer.BadParameter("--count and --id exclude each other: voting picks the ids")
    try:
        if quantity:
            return Selector(
                SelectorKind.QUANTITY, fleet_id=fleet, quantity=quantity, payload_model=payload
            )
        if ids:
            return Selector.ids(*ids)
        if fleet:
            return Selector.fleet(fleet)
        return Selector()
    except ValueError as exc:
        raise typer.BadParameter(str(exc)) from exc


# --------------------------------------------------------------------------- status


@app.command()
def status(
    ctx: typer.Context,
    wait: float = typer.Option(2.0, help="seconds to listen before printing"),
    watch: bool = typer.Option(False, help="keep the table live until Ctrl-C"),
    as_json: bool = typer.Option(False, "--json", help="print JSON rows"),
) -> None:
    """The fleet: state, mode, mission progress, battery, GPS, position, alerts."""
    with ctx.obj.open() as gs:
        time.sleep(wait)
        if as_json:
            typer.echo(json.dumps(fleet_rows(gs.snapshot()), indent=2))
            return
        if not watch:
            console.print(fleet_table(gs.snapshot(), title=f"swarm {gs.swarm}"))
            return
        from rich.live import Live

        with Live(fleet_table(gs.snapshot()), console=console, refresh_per_second=4) as live:
            try:
                while True:
                    time.sleep(0.25)
                    live.update(fleet_table(gs.snapshot(), title=f"swarm {gs.swarm}"))
            except KeyboardInterrupt:
                pass


@app.command()
def alerts(
    ctx: typer.Context,
    wait: float = typer.Option(5.0, help="seconds to listen"),
) -> None:
    """Alerts raised by the vehicles while listening."""
    with ctx.obj.open() as gs:
        time.sleep(wait)
        for a in gs.snapshot().alerts:
            console.print(f"{a.vehicle_id:>5} {a.severity.name:<9} {a.code.name:<20} {a.text}")


@app.command()
def peers(ctx: typer.Context, node: int = typer.Argument(..., help="node id")) -> None:
    """A node's own view of the swarm."""
    with ctx.obj.open() as gs:
        view = gs.peers_of(node, timeout_s=3.0)
        if view is None:
            console.print(f"[red]node {node} did not answer[/]")
            raise typer.Exit(1)
        for p in view.peers:
            console.print(
                f"{p.node_id:>5} {p.vehicle_type.name:<7} fleet {p.fleet_id:<3} {p.fsm_state.name:<10} heard {p.heard_age_s:.1f} s ago"
            )


# --------------------------------------------------------------------------- commands


def _print_acks(acks: list[Ack], what: str) -> None:
    """The addressed vehicles' answers as a table (exit 1 if any refused); vehicles that
    answered NOT_ADDRESSED (every vehicle answers a mission) on one line."""
    answers = [a for a in acks if a.reason != AckReason.NOT_ADDRESSED]
    others = ", ".join(
        str(v) for v in sorted(a.vehicle_id for a in acks if a.reason == AckReason.NOT_ADDRESSED)
    )
    if not answers:
        if others:
            console.print(f"[yellow]{what}: addresses none of the vehicles ({others} answered)[/]")
        else:
            console.print(f"[yellow]{what}: no answer[/]")
        raise typer.Exit(1)
    console.print(ack_table(answers, what))
    if others:
        console.print(f"not addressed: {others}", style="dim")
    if not all(a.accepted for a in answers):
        raise typer.Exit(1)


@app.command()
def cmd(
    ctx: typer.Context,
    kind: str = typer.Argument(..., help="; ".join(k.name.lower() for k in CommandKind)),
    ids: list[int] = typer.Option([], "--id", help="vehicle ids (repeat)"),
    fleet: int = typer.Option(0, help="address a fleet"),
    value: float | None = typer.Option(None, help="altitude (m above home) or speed (m/s)"),
    text: str = typer.Option("", help="mode name, or what to calibrate"),
    point: str | None = typer.Option(
        None, help="LAT,LON[,ALT_MSL] for goto, set-base and emergency-land (where to land)"
    ),
    fleet_id: int = typer.Option(0, help="set-fleet: the new fleet id"),
    mission_id: int = typer.Option(0, help="cancel-mission / join-mission: the mission"),
    timeout: float = typer.Option(5.0, help="seconds to wait for acks"),
) -> None:
    """Send an operator command (rtl, land, emergency-land, abort-landing, parachute,
    set-base, calibrate, arm, disarm, takeoff, set-mode, goto, set-speed, set-altitude,
    set-fleet, cancel-mission, activate, shutdown) and show every vehicle's ack."""
    try:
        k = CommandKind[kind.upper().replace("-", "_")]
    except KeyError as exc:
        raise typer.BadParameter(f"unknown command {kind!r}", param_hint="KIND") from exc
    geo = None
    if point:
        parts = [float(x) for x in point.split(",")]
        if len(parts) not in (2, 3):
            raise typer.BadParameter("LAT,LON[,ALT_MSL]", param_hint="--point")
        geo = GeoPoint(parts[0], parts[1], parts[2] if len(parts) == 3 else 0.0)
    if k == CommandKind.EMERGENCY_LAND and geo is None:  # paper 3.5.1: ask for the route
        raise typer.BadParameter(
            "emergency-land needs --point LAT,LON: where the landing route ends",
            param_hint="--point",
        )
    args = CommandArgs(point=geo, value=value, text=text, fleet_id=fleet_id, mission_id=mission_id)
    with ctx.obj.open() as gs:
        # every vehicle named with --id (a fresh session hears a LAN's vehicles one by
        # one; the acks awaited are those of the vehicles known to be addressed)
        gs.wait_for(lambda v: set(ids) <= set(v.vehicle_ids()) and bool(v.vehicle_ids()), 3.0)
        acks = gs.command(k, selector_from(ids, fleet, 0, ""), args, timeout_s=timeout)
    _print_acks(acks, f"{k.name.lower()}")


@app.command()
def mission(
    ctx: typer.Context,
    mission_type: str = typer.Argument(
        ..., metavar="TYPE", help="area, target, perimeter, route, objective, autoland, mumt"
    ),
    polygon: str | None = typer.Option(None, help="'LAT,LON LAT,LON ...' (area, perimeter)"),
    point: str | None = typer.Option(None, help="LAT,LON (target, objective, autoland)"),
    circle: str | None = typer.Option(None, help="LAT,LON,RADIUS_M (target, perimeter)"),
    line: str | None = typer.Option(None, help="'LAT,LON LAT,LON ...' (route)"),
    points: str | None = typer.Option(None, help="'LAT,LON ...' (multi-objective)"),
    ids: list[int] = typer.Option([], "--id", help="vehicle ids (repeat)"),
    fleet: int = typer.Option(0, help="the fleet flies it"),
    quantity: int = typer.Option(
        0, "--count", "--quantity", help="this many vehicles, chosen by voting (with --fleet: of it)"
    ),
    payload: str = typer.Option(
        "", help="with --count: the payload model voting prefers (a swarm database model)"
    ),
    alt: float | None = typer.Option(None, help="altitude above home, m"),
    speed: float | None = typer.Option(None, help="m/s (default: each vehicle's cruise)"),
    overlap: float | None = typer.Option(None, help="area: camera side overlap"),
    radius: float | None = typer.Option(None, help="target/perimeter radius, m"),
    alt_step: float | None = typer.Option(None, help="vertical separation between vehicles, m"),
    duration: float | None = typer.Option(None, help="target/objective: how long to hold, s"),
    name: str = typer.Option("", help="a name for people"),
    mission_id: int = typer.Option(0, help="default: a fresh id"),
    timeout: float = typer.Option(5.0, help="seconds to wait for acks"),
    db_path: DbOption = None,
) -> None:
    """Send a mission and show every addressed vehicle's ack. Parameters not given come
    from the swarm database's defaults for the kind of mission (`gcs db list swarm
    mission-params`); the vehicles fill what is still unset from theirs."""
    try:
        mtype = MissionType[mission_type.upper()]
    except KeyError as exc:
        raise typer.BadParameter(
            f"unknown mission type {mission_type!r}", param_hint="TYPE"
        ) from exc
    geometry = geometry_from(polygon, point, circle, line, points)
    given = {
        "altitude_rel_m": alt,
        "speed_m_s": speed,
        "side_overlap": overlap,
        "radius_m": radius,
        "altitude_step_m": alt_step,
        "duration_s": duration,
    }
    if payload:
        check_payload_model(payload, db_path)
    values = {**mission_defaults(mtype, db_path, circle=circle is not None)}
    values.update({k: v for k, v in given.items() if v is not None})
    try:
        params = msgspec.convert(values, MissionParams, strict=False)
        m = Mission(mission_id or new_seq() or 1, ctx.obj.gcs_id, mtype, geometry, params,
                    selector_from(ids, fleet, quantity, payload), name, time.time())  # fmt: skip
    except (ValueError, msgspec.ValidationError) as exc:
        raise typer.BadParameter(str(exc)) from exc
    with ctx.obj.open() as gs:
        acks = gs.mission(m, timeout_s=timeout)
    _print_acks(acks, f"mission {m.mission_id} ({mtype.name.lower()})")


def mission_defaults(mtype: MissionType, db_path: Path | None, *, circle: bool) -> dict[str, float]:
    """The database's default parameters for a kind of mission ({} when the database
    cannot be read: the message's own defaults then apply). A circle's radius is its own."""
    from swarm_node.database import SwarmDatabase
    from swarm_node.database.errors import SwarmDbError
    from swarm_node.database.paths import resolve_db_path

    try:
        with SwarmDatabase.open(resolve_db_path(db_path)) as db:
            found = db.mission_defaults(mtype)
    except (SwarmDbError, OSError) as exc:
        console.print(f"[yellow]gcs: no mission defaults from the database: {exc}[/]")
        return {}
    known = {k: v for k, v in found.items() if k in MissionParams.__struct_fields__}
    if circle:
        known.pop("radius_m", None)
    return known


def check_payload_model(model: str, db_path: Path | None) -> None:
    """Refuse a payload model the swarm database does not know (with suggestions): the
    vehicles score it against their payload hierarchy. Unchecked (with a warning) when
    the database cannot be read."""
    from swarm_node.database import SwarmDatabase
    from swarm_node.database.errors import ProfileError, SwarmDbError
    from swarm_node.database.paths import resolve_db_path

    try:
        with SwarmDatabase.open(resolve_db_path(db_path)) as db:
            db.payload_class(model)
    except ProfileError as exc:
        raise typer.BadParameter(str(exc), param_hint="--payload") from exc
    except (SwarmDbError, OSError) as exc:
        console.print(f"[yellow]gcs: payload model not checked, no database: {exc}[/]")


@zone_app.command("add")
def zone_add(
    ctx: typer.Context,
    zone_id: int = typer.Argument(..., help="zone id"),
    polygon: str | None = typer.Option(None, help="'LAT,LON LAT,LON ...'"),
    circle: str | None = typer.Option(None, help="LAT,LON,RADIUS_M"),
    floor: float = typer.Option(-1000.0, help="floor, m above mean sea level"),
    ceiling: float = typer.Option(8000.0, help="ceiling, m above mean sea level"),
    minutes: float | None = typer.Option(None, help="valid for this long (default: until removed)"),
    name: str = typer.Option(""),
    operating_area: bool = typer.Option(
        False,
        "--operating-area",
        help="an operating area the vehicles must stay inside (2-D: no floor or ceiling)",
    ),
    ids: list[int] = typer.Option(
        [], "--id", help="vehicles that must hold it (default: all alive)"
    ),
    timeout: float = typer.Option(10.0, help="seconds to wait for the vehicles to hold it"),
) -> None:
    """Declare a no-fly zone, or with --operating-area the area the vehicles must not
    leave. Both also become the autopilots' fences (docs/node.md, "Fences"). It is sent
    again until every vehicle alive (or each --id) holds it, and says which do; a node
    started later learns it from the others."""
    geometry = geometry_from(polygon, None, circle, None, None)
    now = time.time()
    try:
        zone = NoFlyZone(
            zone_id,
            geometry,
            floor,
            ceiling,
            now,
            now + minutes * 60 if minutes else None,
            True,
            name,
            operating_area,
        )
    except ValueError as exc:
        raise typer.BadParameter(str(exc)) from exc
    what = f"{'operating area' if operating_area else 'zone'} {zone_id}"
    _declare(ctx.obj, zone, what, "declared", ids, timeout)


def _declare(
    link: Link, zone: NoFlyZone, what: str, done: str, ids: list[int], timeout: float
) -> None:
    """Send a zone until the vehicles hold it; exit 1 unless every one expected does."""
    with link.open() as gs:  # default: the vehicles discovered alive, or heard meanwhile
        confirmed = gs.declare_zone(zone, expect=set(ids) if ids else None, timeout_s=timeout)
        expected = set(ids) if ids else set(gs.snapshot().vehicle_ids()) | confirmed
    held = ", ".join(str(v) for v in sorted(confirmed)) or "none"
    console.print(f"{what} {done}; held by vehicles: {held}")
    missing = sorted(expected - confirmed)
    if missing:
        console.print(f"[yellow]{what}: not confirmed by {', '.join(map(str, missing))}[/]")
    if not expected:
        console.print(f"[yellow]{what}: no vehicle is alive to hold it[/]")
    if missing or not expected:
        raise typer.Exit(1)


@zone_app.command("remove")
def zone_remove(
    ctx: typer.Context,
    zone_id: int = typer.Argument(..., help="zone id"),
    ids: list[int] = typer.Option(
        [], "--id", help="vehicles that must drop it (default: all alive)"
    ),
    timeout: float = typer.Option(10.0, help="seconds to wait for the vehicles to drop it"),
) -> None:
    """Withdraw a no-fly zone or operating area (republished inactive: the vehicles
    drop it by id; the geometry sent is a placeholder), and say which vehicles did."""
    placeholder = Geometry.circle(0.0, 0.0, 1.0)
    zone = NoFlyZone(zone_id, placeholder, active=False)
    _declare(ctx.obj, zone, f"zone {zone_id}", "withdrawn", ids, timeout)


@app.command()
def version() -> None:
    """Print the bandada version."""
    from importlib.metadata import version as v

    typer.echo(v("bandada"))


def main() -> None:
    app()


if __name__ == "__main__":
    main()
