"""`gcs zone list | export | import`: the zones the vehicles hold, written to the
operators' files, and zones declared from them (formats: geofiles.py)."""

from __future__ import annotations

import json
import time
from pathlib import Path

import msgspec
import typer
from rich import box
from rich.table import Table

from swarm_proto import GeometryKind, NoFlyZone

from .answers import progress, report
from .common import Link, console, selector_from, timeout_option
from .geofiles import GeoFileError, save_zones, zone_features
from .options import AllOption, FleetOption, IdsOption, JsonOption, checked, finite

zone_app = typer.Typer()  # zone list, export, import: app.py puts them in `gcs zone`


def held_zones(
    link: Link, timeout_s: float = 2.0
) -> tuple[dict[int, NoFlyZone], dict[int, list[int]]]:
    """Every zone some vehicle holds (its newest copy: the latest valid_from) and who
    holds each: ({zone id: zone}, {zone id: [vehicle ids]})."""
    with link.open() as gs:
        gs.discover(1.0)
        per_vehicle = gs.all_zones(timeout_s)
    zones: dict[int, NoFlyZone] = {}
    holders: dict[int, list[int]] = {}
    for vid, zs in sorted(per_vehicle.items()):
        for zid, z in zs.items():
            old = zones.get(zid)
            if old is None or z.valid_from_unix_s > old.valid_from_unix_s:
                zones[zid] = z
            holders.setdefault(zid, []).append(vid)
    return zones, holders


def _where(z: NoFlyZone) -> str:
    g = z.geometry
    if g.kind == GeometryKind.CIRCLE:
        c = g.points[0]
        return f"circle {c.lat_deg:.5f},{c.lon_deg:.5f} r {g.radius_m:g} m"
    c = g.points[0]
    return f"polygon of {len(g.points)} from {c.lat_deg:.5f},{c.lon_deg:.5f}"


@zone_app.command("list")
def zone_list(
    ctx: typer.Context,
    withdrawn: bool = typer.Option(False, "--withdrawn", help="withdrawn zones too"),
    timeout: float = typer.Option(2.0, help="seconds to wait for the vehicles' answers"),
    as_json: JsonOption = False,
) -> None:
    """The zones and operating areas the vehicles hold (each vehicle's zones queryable,
    LAN only), with which vehicles hold each.

    Example: gcs zone list --json
    """
    timeout_option(timeout)
    zones, holders = held_zones(ctx.obj, timeout)
    now = time.time()
    shown = [z for z in sorted(zones.values(), key=lambda z: z.zone_id) if withdrawn or z.active]
    if as_json:
        typer.echo(
            json.dumps(
                [
                    {
                        **msgspec.to_builtins(z),
                        "in_force": z.in_force(now),
                        "held_by": holders[z.zone_id],
                    }
                    for z in shown
                ],
                indent=2,
            )
        )
        return
    t = Table(title="zones", box=box.SIMPLE_HEAD, title_justify="left")
    for col in ("id", "kind", "name", "where", "floor-ceiling m", "state", "held by"):
        t.add_column(col)
    for z in shown:
        state = "in force" if z.in_force(now) else ("withdrawn" if not z.active else "not in force")
        t.add_row(
            str(z.zone_id),
            "area" if z.operating_area else "no-fly",
            z.name,
            _where(z),
            "-" if z.operating_area else f"{z.floor_alt_msl_m:g}..{z.ceiling_alt_msl_m:g}",
            state,
            ", ".join(map(str, holders[z.zone_id])),
        )
    console.print(t if shown else "no zone held by any vehicle")


@zone_app.command("export")
def zone_export(
    ctx: typer.Context,
    file: Path = typer.Argument(
        ..., dir_okay=False, help="FILE.geojson, .kml, .plan, .waypoints or .json"
    ),
    timeout: float = typer.Option(2.0, help="seconds to wait for the vehicles' answers"),
) -> None:
    """Write the zones in force that the vehicles hold to a file (GeoJSON, KML,
    QGroundControl .plan geofence, MAVLink fence items, or bandada JSON). Exit 1 if no
    vehicle holds a zone.

    Example: gcs zone export zones.kml
    """
    timeout_option(timeout)
    zones, _ = held_zones(ctx.obj, timeout)
    active = [z for z in sorted(zones.values(), key=lambda z: z.zone_id) if z.active]
    if not active:
        console.print("[yellow]no zone held by any vehicle: nothing written[/]")
        raise typer.Exit(1)
    try:
        save_zones(file, active)
    except GeoFileError as exc:
        raise typer.BadParameter(str(exc), param_hint="FILE") from None
    console.print(
        f"{len(active)} zone(s) written to {file}: " + ", ".join(str(z.zone_id) for z in active)
    )


@zone_app.command("import")
def zone_import(
    ctx: typer.Context,
    file: Path = typer.Argument(..., dir_okay=False, help="GeoJSON, KML, .plan, waypoints or JSON"),
    first_id: int = typer.Option(
        1,
        "--first-id",
        min=1,
        max=2**32 - 1,
        help="ids from here on, for zones the file does not number",
    ),
    floor: float = typer.Option(-1000.0, help="floor, m above mean sea level (no-fly zones)"),
    ceiling: float = typer.Option(8000.0, help="ceiling, m above mean sea level"),
    ids: IdsOption = [],  # noqa: B006
    fleet: FleetOption = None,
    all_: AllOption = False,
    timeout: float = typer.Option(10.0, help="seconds to wait for each zone's answers"),
    as_json: JsonOption = False,
) -> None:
    """Declare every fence polygon and circle of a file as a zone (exclusion: a no-fly
    zone; inclusion: an operating area), each acknowledged by every vehicle. The file
    is read and every zone checked before anything is sent.

    Example: gcs zone import field.plan --first-id 10
    """
    for opt, v in (("--floor", floor), ("--ceiling", ceiling)):
        finite(v, opt, -1000.0, 8000.0)
    timeout_option(timeout)
    try:
        feats = zone_features(file)
    except GeoFileError as exc:
        raise typer.BadParameter(str(exc), param_hint="FILE") from None
    now = time.time()
    zones = []
    used: set[int] = set()
    next_id = first_id
    for f in feats:
        zid = f.props.get("zone_id")
        if not isinstance(zid, int) or zid in used:
            while next_id in used:
                next_id += 1
            zid = next_id
        used.add(zid)
        area = f.role == "inclusion"
        lo = float(f.props.get("floor_alt_msl_m", floor))
        hi = float(f.props.get("ceiling_alt_msl_m", ceiling))
        try:
            zones.append(
                checked(
                    NoFlyZone(
                        zid, f.geometry, lo, hi, now, None, True, f.name[:48], area, ctx.obj.gcs_id
                    )
                )
            )
        except ValueError as exc:
            raise typer.BadParameter(f"{file}: {f.describe()}: {exc}", param_hint="FILE") from None
    sel = selector_from(ids, fleet, 0, "", all_)
    failed = 0
    with ctx.obj.open() as gs:
        for z in zones:
            with progress(not as_json) as show:
                out = gs.send_zone(z, sel, timeout_s=timeout, progress=show)
            try:
                report(out, console, as_json=as_json)
            except typer.Exit:
                failed += 1
    if failed:
        console.print(f"[red]{failed} of {len(zones)} zone(s) not held by every vehicle[/]")
        raise typer.Exit(1)
