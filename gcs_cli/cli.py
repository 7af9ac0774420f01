"""The ground station's own commands (paper section 3): fleet status (`status`,
`alerts`, `peers`), operator commands (`cmd`), missions (`mission`), zones declared and
withdrawn (`zone add | remove`) and `version`. `app.py` assembles them with the
command groups of the other modules.

Every command that talks to the swarm takes --connect (Zenoh endpoints, default the lab
router on tcp/127.0.0.1:7447) or --zenoh-config (a Zenoh JSON5 file), --swarm and --gcs-id.
Bad input is one line on stderr and exit 2, before anything is sent (`app.run`).
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import msgspec
import typer

from swarm_proto import (
    Command,
    CommandArgs,
    CommandKind,
    Geometry,
    GeoPoint,
    Mission,
    MissionParams,
    MissionType,
    NoFlyZone,
    Selector,
)

from . import _clickx, lost_store
from .answers import progress, report
from .common import (
    Link,
    ask,
    console,
    geometry_from,
    read_filter,
    selector_from,
    timeout_option,
    wait_option,
)
from .core.exchange import Verdict
from .core.lost import NotLostError, finite_id
from .core.reasons import alert_text
from .db import DbOption
from .ground import MISSION_TIMEOUT_S, new_seq
from .options import (
    AllOption,
    FleetOption,
    IdsOption,
    JsonOption,
    YesOption,
    checked,
    finite,
    parse_geopoint,
)
from .render import fleet_rows, fleet_table
from .tasking import VoteWatch, show_vote

#: the top-level commands and the `zone` commands of this module (app.py places them)
app = typer.Typer()
zone_app = typer.Typer()


# --------------------------------------------------------------------------- status


@app.command()
def status(
    ctx: typer.Context,
    wait: float = typer.Option(2.0, help="seconds to listen before printing"),
    watch: bool = typer.Option(False, help="keep the table live until Ctrl-C (see `gcs watch`)"),
    as_json: JsonOption = False,
    ids: IdsOption = [],  # noqa: B006 (typer reads the default)
    fleet: FleetOption = None,
    all_: AllOption = False,
) -> None:
    """The fleet in 100 columns: state, mode, mission progress, battery, GPS, position,
    altitude, speed, alerts, how long since each vehicle was heard.

    Example: gcs status --fleet 2 --json
    """
    wait_option(wait)
    shown = read_filter(ids, fleet, all_)
    with ctx.obj.open() as gs:
        time.sleep(wait)
        view = gs.snapshot()
        lost = lost_store.update(gs.swarm, view)
        if as_json:
            rows = [r for r in fleet_rows(view, lost) if _in(shown, r)]
            typer.echo(json.dumps(rows, indent=2))
            return
        if not watch:
            if not view.vehicle_ids() and not lost:
                console.print(f"no vehicle heard in {wait:g} s", style="yellow")
                return
            show(fleet_table(view, title=f"swarm {gs.swarm}", shown=shown, lost=lost))
            return
        from .monitor import live_watch

        live_watch(gs, console, shown)


@app.command()
def dismiss(
    ctx: typer.Context,
    vehicle: str = typer.Argument(..., help="the lost vehicle's id"),
) -> None:
    """Take a LOST vehicle off the ground station's list (`gcs status`, the map) once
    it is accounted for (found on the ground, recovered). A vehicle heard again, or
    whose last report says it landed, leaves the list by itself.

    Example: gcs dismiss 8
    """
    swarm = ctx.obj.swarm
    book = lost_store.load(swarm)
    try:
        book.dismiss(finite_id(vehicle), time.time())
    except NotLostError as exc:
        err = _clickx.ClickException(str(exc))
        err.exit_code = 2  # type: ignore[attr-defined]  # bad input: usage
        raise err from None
    lost_store.save(swarm, book)
    console.print(f"vehicle {vehicle.strip()} dismissed from the lost list")


def show(renderable: object) -> None:
    console.print(renderable)


def _in(shown: Selector, row: dict) -> bool:
    return shown.addresses(row["id"], row.get("fleet") or 0)


@app.command()
def alerts(
    ctx: typer.Context,
    wait: float = typer.Option(5.0, help="seconds to listen"),
    as_json: JsonOption = False,
    ids: IdsOption = [],  # noqa: B006
    fleet: FleetOption = None,
    all_: AllOption = False,
) -> None:
    """Alerts raised by the vehicles while listening, each with its full meaning (the
    vehicle's own text after the colon); the conditions active now are in `gcs status`.

    Example: gcs alerts --wait 30 --id 7
    """
    wait_option(wait)
    shown = read_filter(ids, fleet, all_)
    with ctx.obj.open() as gs:
        time.sleep(wait)
        view = gs.snapshot()
    fleets = {v: st.fleet_id for v, st in view.status.items()}
    got = [a for a in view.alerts if shown.addresses(a.vehicle_id, fleets.get(a.vehicle_id, 0))]
    if as_json:
        typer.echo(
            json.dumps(
                [
                    {
                        **msgspec.to_builtins(a),
                        "severity": a.severity.name,
                        "code": a.code.name,
                        "meaning": alert_text(a.code, a.text, a.detail),
                    }
                    for a in got
                ],
                indent=2,
            )
        )
        return
    for a in got:
        style = "red" if a.severity >= 2 else ("yellow" if a.severity == 1 else None)
        console.print(
            f"{a.vehicle_id:>5} {a.severity.name:<9} {a.code.name:<20} "
            f"{alert_text(a.code, a.text, a.detail)}",
            style=style,
            highlight=False,
        )
    if not got:
        console.print(f"no alert in {wait:g} s", style="dim")


@app.command()
def peers(
    ctx: typer.Context,
    node: int = typer.Argument(..., min=1, max=65534, help="node id"),
    as_json: JsonOption = False,
) -> None:
    """A node's own view of the swarm (its live peers, the untrusted ones marked), its
    identity conflict if any, and what it dropped of its input (by topic and reason),
    as its peers queryable answers.

    Example: gcs peers 7
    """
    with ctx.obj.open() as gs:
        view = gs.peers_of(node, timeout_s=3.0)
        if view is None:
            console.print(f"[red]node {node} did not answer[/]")
            raise typer.Exit(1)
        if as_json:
            typer.echo(json.dumps(msgspec.to_builtins(view), indent=2))
            return
        if view.identity_conflict:
            console.print(f"[red]identity conflict: {view.identity_conflict}[/]", highlight=False)
        for p in view.peers:
            console.print(
                f"{p.node_id:>5} {p.vehicle_type.name:<7} fleet {p.fleet_id:<3} {p.fsm_state.name:<10} heard {p.heard_age_s:.1f} s ago"
                + (" UNTRUSTED (two sources)" if p.untrusted else ""),
                style="red" if p.untrusted else None,
                highlight=False,
            )
        for d in view.dropped:
            console.print(f"dropped {d.count} on {d.key_expr}: {d.reason}", style="yellow")


# --------------------------------------------------------------------------- commands

#: commands that move or arm vehicles, or take them out of the swarm logic (shutdown,
#: cancel-mission): a selector is required and they are confirmed
MOVING = frozenset(
    {
        CommandKind.ARM,
        CommandKind.DISARM,
        CommandKind.TAKEOFF,
        CommandKind.SET_MODE,
        CommandKind.GOTO,
        CommandKind.SET_SPEED,
        CommandKind.SET_ALTITUDE,
        CommandKind.RTL,
        CommandKind.LAND,
        CommandKind.EMERGENCY_LAND,
        CommandKind.ABORT_LANDING,
        CommandKind.PARACHUTE,
        CommandKind.CANCEL_MISSION,
        CommandKind.JOIN_MISSION,
        CommandKind.SWAP_MISSION,
        CommandKind.SHUTDOWN,
    }
)
COMMAND_NAMES = [k.name.lower().replace("_", "-") for k in CommandKind]
#: --value of the commands that need one: (lowest, highest, lowest allowed, what)
VALUE_RANGES: dict[CommandKind, tuple[float, float, bool, str]] = {
    CommandKind.SET_SPEED: (0.0, 300.0, False, "--value, a speed in m/s"),
    CommandKind.TAKEOFF: (0.0, 8000.0, False, "--value, an altitude in m above home"),
    CommandKind.SET_ALTITUDE: (0.0, 8000.0, True, "--value, an altitude in m above home"),
}


def name_of(k: CommandKind) -> str:
    return k.name.lower().replace("_", "-")


def _complete_kind(incomplete: str) -> list[str]:
    return [k for k in COMMAND_NAMES if k.startswith(incomplete)]


@app.command()
def cmd(
    ctx: typer.Context,
    kind: str = typer.Argument(..., help="; ".join(COMMAND_NAMES), autocompletion=_complete_kind),
    ids: IdsOption = [],  # noqa: B006
    fleet: FleetOption = None,
    all_: AllOption = False,
    value: float | None = typer.Option(None, help="altitude (m above home) or speed (m/s)"),
    text: str = typer.Option("", help="mode name, or what to calibrate"),
    point: str | None = typer.Option(
        None, help="LAT,LON[,ALT_MSL] for goto, set-base and emergency-land (where to land)"
    ),
    fleet_id: int = typer.Option(0, min=0, max=255, help="set-fleet: the new fleet id"),
    mission_id: int = typer.Option(
        0, min=0, max=2**32 - 1, help="cancel-mission / join-mission: the mission"
    ),
    other_mission_id: int = typer.Option(
        0, min=0, max=2**32 - 1, help="swap-mission: the other fleet's mission"
    ),
    timeout: float = typer.Option(5.0, help="seconds to wait for every answer"),
    yes: YesOption = False,
    as_json: JsonOption = False,
) -> None:
    """Send an operator command and show every addressed vehicle's answer: accepted,
    rejected with its full reason, or silent. Exit 1 unless all accepted.

    Commands that move or arm vehicles or take them out of the swarm logic (arm, disarm,
    takeoff, set-mode, goto, set-speed, set-altitude, rtl, land, emergency-land,
    abort-landing, parachute, cancel-mission, join-mission, swap-mission, shutdown) need
    --id, --fleet or --all and are confirmed unless --yes; the others (set-base,
    calibrate, set-fleet, activate) go to every vehicle when no selector is given. A
    vehicle shut down in the air is sent home first (RTL) and shuts down once landed.

    Example: gcs cmd rtl --fleet 2 --yes
    """
    try:
        k = CommandKind[kind.upper().replace("-", "_")]
    except KeyError as exc:
        raise typer.BadParameter(
            f"unknown command {kind!r}; one of {', '.join(COMMAND_NAMES)}", param_hint="KIND"
        ) from exc
    timeout_option(timeout)
    finite(value, "--value", -1.0e6, 1.0e6)
    if k in VALUE_RANGES:  # what the vehicles would refuse, refused here (nothing sent)
        lo, hi, zero_ok, what = VALUE_RANGES[k]
        if value is None or not (lo <= value <= hi) or (value == lo and not zero_ok):
            shown = "none given" if value is None else f"got {value:g}"
            bounds = f"{lo:g} to {hi:g}" if zero_ok else f"above {lo:g}, at most {hi:g}"
            raise typer.BadParameter(
                f"{name_of(k)} needs {what}, {bounds} ({shown})", param_hint="--value"
            )
    geo = GeoPoint(*parse_geopoint(point)) if point else None
    if k == CommandKind.EMERGENCY_LAND and geo is None:  # paper 3.5.1: ask for the route
        raise typer.BadParameter(
            "emergency-land needs --point LAT,LON: where the landing route ends",
            param_hint="--point",
        )
    sel = selector_from(ids, fleet, 0, "", all_, required=k in MOVING)
    args = CommandArgs(
        point=geo,
        value=value,
        text=text,
        fleet_id=fleet_id,
        mission_id=mission_id,
        other_mission_id=other_mission_id,
    )
    checked(Command(ctx.obj.gcs_id, 1, k, sel, args))  # everything checked before sending
    name = k.name.lower().replace("_", "-")
    with ctx.obj.open() as gs:
        if k in MOVING:
            ask(gs, name, sel, yes)
        with progress(not as_json) as show:
            out = gs.send_command(k, sel, args, timeout_s=timeout, progress=show)
    report(out, console, as_json=as_json)


@app.command()
def mission(
    ctx: typer.Context,
    mission_type: str = typer.Argument(
        ...,
        metavar="TYPE",
        help="area, target, perimeter, route, objective, autoland, mumt",
        autocompletion=lambda incomplete: [
            t.name.lower() for t in MissionType if t.name.lower().startswith(incomplete)
        ],
    ),
    polygon: str | None = typer.Option(None, help="'LAT,LON LAT,LON ...' (area, perimeter)"),
    point: str | None = typer.Option(None, help="LAT,LON (target, objective, autoland)"),
    circle: str | None = typer.Option(None, help="LAT,LON,RADIUS_M (target, perimeter)"),
    line: str | None = typer.Option(None, help="'LAT,LON LAT,LON ...' (route)"),
    points: str | None = typer.Option(None, help="'LAT,LON ...' (multi-objective)"),
    file: Path | None = typer.Option(
        None,
        "--file",
        help="the geometry from a file: GeoJSON, KML, QGroundControl .plan or "
        "MAVLink waypoints (docs/ground-station.md, 'Files')",
        dir_okay=False,
    ),
    feature: str | None = typer.Option(
        None, help="with --file: which feature (its name, or its number from 1)"
    ),
    ids: IdsOption = [],  # noqa: B006
    fleet: FleetOption = None,
    all_: AllOption = False,
    quantity: int = typer.Option(
        0,
        "--count",
        "--quantity",
        help="this many vehicles, chosen by voting (with --fleet: of it)",
    ),
    payload: str = typer.Option(
        "", help="with --count: the payload model voting prefers (a swarm database model)"
    ),
    vote_wait: float = typer.Option(15.0, help="with --count: seconds to wait for the vote"),
    alt: float | None = typer.Option(None, help="altitude above home, m"),
    speed: float | None = typer.Option(None, help="m/s (default: each vehicle's cruise)"),
    overlap: float | None = typer.Option(None, help="area: camera side overlap"),
    radius: float | None = typer.Option(None, help="target/perimeter radius, m"),
    alt_step: float | None = typer.Option(None, help="vertical separation between vehicles, m"),
    duration: float | None = typer.Option(None, help="target/objective: how long to hold, s"),
    name: str | None = typer.Option(None, help="a name for people (default: the file's)"),
    mission_id: int = typer.Option(0, min=0, max=2**32 - 1, help="default: a fresh id"),
    timeout: float = typer.Option(
        MISSION_TIMEOUT_S,
        help="seconds to wait for every answer (the fleet answers once its plan is made)",
    ),
    save: Path | None = typer.Option(
        None,
        "--save",
        help="also write the mission to this file (.geojson, .kml, .plan, "
        ".waypoints or .json: the format by its extension)",
        dir_okay=False,
    ),
    dry_run: bool = typer.Option(False, "--dry-run", help="check and --save, send nothing"),
    yes: YesOption = False,
    as_json: JsonOption = False,
    db_path: DbOption = None,
) -> None:
    """Send a mission and show every addressed vehicle's answer (every vehicle answers a
    mission; those it does not address are listed apart). Parameters not given come
    from the swarm database's defaults for the kind of mission (`gcs db list swarm
    mission-params`); the vehicles fill what is still unset from theirs. Needs --id,
    --fleet, --all or --count; confirmed unless --yes.

    Example: gcs mission area --file field.kml --fleet 1 --alt 60 --save field.plan --yes
    """
    try:
        mtype = MissionType[mission_type.upper()]
    except KeyError as exc:
        raise typer.BadParameter(
            f"unknown mission type {mission_type!r}", param_hint="TYPE"
        ) from exc
    timeout_option(timeout)
    from_file: dict[str, object] = {}
    if file is not None:
        if any((polygon, point, circle, line, points)):
            raise typer.BadParameter("--file and --polygon/--point/... exclude each other")
        from .files import mission_file

        geometry, from_file, file_name = mission_file(file, mtype, feature, console)
        name = file_name if name is None else name
    else:
        geometry = geometry_from(polygon, point, circle, line, points)
    for opt, v, lo, hi in (
        ("--alt", alt, 0.0, 8000.0),
        ("--speed", speed, 0.0, 300.0),
        ("--overlap", overlap, 0.0, 0.95),
        ("--radius", radius, 0.0, 1.0e6),
        ("--alt-step", alt_step, 0.0, 8000.0),
        ("--duration", duration, 0.0, 1.0e7),
    ):
        finite(v, opt, lo, hi)
    if not 0.0 <= vote_wait < 3600.0:
        raise typer.BadParameter("must be in [0, 3600) s", param_hint="--vote-wait")
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
    values: dict[str, object] = {
        **mission_defaults(mtype, db_path, circle=geometry.radius_m is not None)
    }
    values.update(from_file)  # the file's values, then the options given
    values.update({k: v for k, v in given.items() if v is not None})
    sel = selector_from(ids, fleet, quantity, payload, all_, required=not dry_run)
    try:
        params = msgspec.convert(values, MissionParams, strict=False)
        m = Mission(
            mission_id or new_seq() or 1,
            ctx.obj.gcs_id,
            mtype,
            geometry,
            params,
            sel,
            name or "",
            time.time(),
        )
    except (ValueError, msgspec.ValidationError) as exc:
        raise typer.BadParameter(str(exc)) from exc
    checked(m)
    if save is not None:
        from .files import save_mission_file

        save_mission_file(save, m, console)
    if dry_run:
        from .budgets import dry_run_check

        dry_run_check(ctx.obj, m, db_path, console)
        return
    with ctx.obj.open() as gs:
        ask(gs, f"mission {m.mission_id} ({mtype.name.lower()})", sel, yes)
        watch = VoteWatch(gs) if quantity else None  # subscribed before the mission goes out
        with progress(not as_json) as show:
            out = gs.send_mission(m, timeout_s=timeout, progress=show)
        voters = {r.vehicle_id for r in out.rows if r.verdict == Verdict.ACCEPTED}
        if watch is not None and voters and not as_json:  # then every score, who goes
            try:
                report(out, console)
            finally:
                show_vote(gs, watch, m.mission_id, voters, quantity, vote_wait)
            return
    report(out, console, as_json=as_json)


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
    zone_id: int = typer.Argument(..., min=1, max=2**32 - 1, help="zone id"),
    polygon: str | None = typer.Option(None, help="'LAT,LON LAT,LON ...'"),
    circle: str | None = typer.Option(None, help="LAT,LON,RADIUS_M"),
    floor: float = typer.Option(-1000.0, help="floor, m above mean sea level"),
    ceiling: float = typer.Option(8000.0, help="ceiling, m above mean sea level"),
    minutes: float | None = typer.Option(None, help="valid for this long (default: until removed)"),
    name: str = typer.Option("", help="a name for people"),
    operating_area: bool = typer.Option(
        False,
        "--operating-area",
        help="an operating area the vehicles must stay inside (2-D: no floor or ceiling)",
    ),
    ids: IdsOption = [],  # noqa: B006
    fleet: FleetOption = None,
    all_: AllOption = False,
    timeout: float = typer.Option(10.0, help="seconds to wait for the vehicles to hold it"),
    as_json: JsonOption = False,
) -> None:
    """Declare a no-fly zone, or with --operating-area the area the vehicles must not
    leave. Both also become the autopilots' fences (docs/node.md, "Fences"). Every
    vehicle holds every zone and acknowledges it; the command waits for every vehicle
    alive (or each --id, or --fleet's) and exits 1 unless all hold it. A node started
    later learns it from the others. Zones from a file: `gcs zone import`.

    Example: gcs zone add 3 --circle 37.412,-5.988,50 --floor 0 --ceiling 300
    """
    geometry = geometry_from(polygon, None, circle, None, None)
    for opt, v in (("--floor", floor), ("--ceiling", ceiling)):
        finite(v, opt, -1000.0, 8000.0)
    finite(minutes, "--minutes", 0.0, 1.0e6)
    timeout_option(timeout)
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
            ctx.obj.gcs_id,
        )
    except ValueError as exc:
        raise typer.BadParameter(str(exc)) from exc
    sel = selector_from(ids, fleet, 0, "", all_)
    from .files import fence_warnings

    for w in fence_warnings([checked(zone)]):
        console.print(f"warning: {w}", style="yellow", highlight=False)
    _declare(ctx.obj, zone, sel, timeout, as_json)


def _declare(link: Link, zone: NoFlyZone, sel: Selector, timeout: float, as_json: bool) -> None:
    """Send a zone until the vehicles hold it; exit 1 unless every one expected does."""
    with link.open() as gs, progress(not as_json) as show:
        out = gs.send_zone(zone, sel, timeout_s=timeout, progress=show)
    report(out, console, as_json=as_json)


@zone_app.command("remove")
def zone_remove(
    ctx: typer.Context,
    zone_id: int = typer.Argument(..., min=1, max=2**32 - 1, help="zone id"),
    ids: IdsOption = [],  # noqa: B006
    fleet: FleetOption = None,
    all_: AllOption = False,
    timeout: float = typer.Option(10.0, help="seconds to wait for the vehicles to drop it"),
    force: bool = typer.Option(
        False, "--force", help="send it even if no vehicle answers holding the id (radio)"
    ),
    as_json: JsonOption = False,
) -> None:
    """Withdraw a no-fly zone or operating area (republished inactive: the vehicles
    drop it by id; the geometry sent is a placeholder) and show each vehicle's answer;
    a vehicle that never held it answers NOT_FOUND (exit 1). An id no vehicle holds is
    refused before anything is sent (exit 1), unless --force.

    Example: gcs zone remove 3
    """
    timeout_option(timeout)
    if not force:
        from .files import check_removal

        check_removal(ctx.obj, zone_id)
    placeholder = Geometry.circle(0.0, 0.0, 1.0)
    zone = NoFlyZone(zone_id, placeholder, active=False, issuer_id=ctx.obj.gcs_id)
    _declare(ctx.obj, zone, selector_from(ids, fleet, 0, "", all_), timeout, as_json)


@app.command()
def version() -> None:
    """Print the bandada version.

    Example: gcs version
    """
    from importlib.metadata import version as v

    typer.echo(v("bandada"))
