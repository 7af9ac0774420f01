"""`gcs zone list | export | import`: the zones the vehicles hold, written to the
operators' files, and zones declared from them (formats: geofiles.py); and the file
side of `gcs mission --file/--save`.

An import never changes a zone the vehicles hold without being asked: zones the file
does not number take ids no vehicle holds; a file's own ids (a bandada export) or
`--first-id` ids that a zone in force already has are refused, naming them, unless
`--replace`; a zone the vehicles hold exactly as the file has it is left alone.
Everything in the file that is not imported (the planned home, rally points, a survey
area, a bare point, a no-fly zone's hole) is listed with why; `--base-from-file` makes
the file's first rally point the swarm's base; `--dry-run` prints all of it and sends
nothing.
"""

from __future__ import annotations

import dataclasses
import json
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import msgspec
import typer
from rich import box
from rich.console import Console
from rich.table import Table

from swarm_proto import (
    CommandArgs,
    CommandKind,
    Geometry,
    GeometryKind,
    GeoPoint,
    MissionType,
    NoFlyZone,
)
from swarm_proto.messages import Mission

from . import _clickx
from .answers import outcome_json, progress, report
from .common import Link, console, selector_from, timeout_option
from .core.exchange import Outcome
from .geofiles import (
    GeoFileError,
    ZoneFile,
    ZoneSpec,
    mission_from_file,
    param_words,
    save_mission,
    save_zones,
    zones_from_file,
)
from .ground import GroundStation
from .options import AllOption, FleetOption, IdsOption, JsonOption, checked, finite

zone_app = typer.Typer()  # zone list, export, import: app.py puts them in `gcs zone`

#: the zone's heights when neither the file nor an option gives them
FULL_FLOOR_M, FULL_CEILING_M = -1000.0, 8000.0


def held_zones(
    link: Link, timeout_s: float = 2.0
) -> tuple[dict[int, NoFlyZone], dict[int, list[int]]]:
    """Every zone some vehicle holds (its newest copy: the latest declaration) and who
    holds each: ({zone id: zone}, {zone id: [vehicle ids]})."""
    with link.open() as gs:
        gs.discover(1.0)
        per_vehicle = gs.all_zones(timeout_s)
    return newest_zones(per_vehicle)


def newest_zones(
    per_vehicle: dict[int, dict[int, NoFlyZone]],
) -> tuple[dict[int, NoFlyZone], dict[int, list[int]]]:
    zones: dict[int, NoFlyZone] = {}
    holders: dict[int, list[int]] = {}
    for vid, zs in sorted(per_vehicle.items()):
        for zid, z in zs.items():
            old = zones.get(zid)
            if old is None or _stamp(z) > _stamp(old):
                zones[zid] = z
            holders.setdefault(zid, []).append(vid)
    return zones, holders


def _stamp(z: NoFlyZone) -> tuple[float, float]:
    return (z.time_unix_s, z.valid_from_unix_s)


def where(z: NoFlyZone) -> str:
    """Where a zone is, for people ("-" once withdrawn: a withdrawal carries no shape)."""
    if not z.active:
        return "-"
    g = z.geometry
    c = g.points[0]
    if g.kind == GeometryKind.CIRCLE:
        return f"circle {c.lat_deg:.5f},{c.lon_deg:.5f} r {g.radius_m:g} m"
    return f"polygon of {len(g.points)} from {c.lat_deg:.5f},{c.lon_deg:.5f}"


def _state(z: NoFlyZone, now: float) -> str:
    if not z.active:
        return "withdrawn"
    return "in force" if z.in_force(now) else "not in force"


@zone_app.command("list")
def zone_list(
    ctx: typer.Context,
    withdrawn: bool = typer.Option(False, "--withdrawn", help="withdrawn zones too"),
    timeout: float = typer.Option(2.0, help="seconds to wait for the vehicles' answers"),
    as_json: JsonOption = False,
) -> None:
    """The zones and operating areas the vehicles hold (each vehicle's zones queryable,
    LAN only), with which vehicles hold each; with --withdrawn, the withdrawn ones too
    (the vehicles keep a withdrawal so that an older declaration never revives it).

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
                        "geometry": msgspec.to_builtins(z.geometry) if z.active else None,
                        "state": _state(z, now),
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
        t.add_row(
            str(z.zone_id),
            "-" if not z.active else ("area" if z.operating_area else "no-fly"),
            z.name,
            where(z),
            "-"
            if z.operating_area or not z.active
            else f"{z.floor_alt_msl_m:g}..{z.ceiling_alt_msl_m:g}",
            _state(z, now),
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
    QGroundControl .plan geofence, MAVLink fence items, or bandada JSON), ids, names and
    heights included where the format has room; what it has no room for is said in one
    line. Exit 1 if no vehicle holds a zone.

    Example: gcs zone export zones.kml
    """
    timeout_option(timeout)
    zones, _ = held_zones(ctx.obj, timeout)
    active = [z for z in sorted(zones.values(), key=lambda z: z.zone_id) if z.active]
    if not active:
        console.print("[yellow]no zone held by any vehicle: nothing written[/]")
        raise typer.Exit(1)
    try:
        lost = save_zones(file, active)
    except GeoFileError as exc:
        raise typer.BadParameter(str(exc), param_hint="FILE") from None
    console.print(
        f"{len(active)} zone(s) written to {file}: " + ", ".join(str(z.zone_id) for z in active)
    )
    warn_lost(file, lost, console)


def warn_lost(file: Path, lost: list[str], out: Console) -> None:
    """One line naming what a file's format could not carry."""
    if lost:
        out.print(
            f"warning: {file.name} cannot carry: {'; '.join(lost)}", style="yellow", highlight=False
        )


# --------------------------------------------------------------------------- mission files


def mission_file(
    file: Path, mtype: MissionType, feature: str | None, out: Console
) -> tuple[Geometry, dict[str, Any], str | None]:
    """`gcs mission --file`: the geometry, the parameters the file gives (altitude,
    overlap ...: the options given override them) and its name; says what it took from
    the file and what the file had that is not used."""
    try:
        fm = mission_from_file(file, mtype, feature)
    except GeoFileError as exc:
        raise typer.BadParameter(str(exc), param_hint="--file") from None
    if fm.params:
        took = ", ".join(param_words(k, v) for k, v in fm.params.items())
        out.print(f"from {file.name}: {took}", style="dim", highlight=False)
    for note in fm.notes:
        out.print(f"note: {file.name}: {note}", style="yellow", highlight=False)
    return fm.geometry, fm.params, fm.name


def save_mission_file(path: Path, m: Mission, out: Console) -> None:
    """`gcs mission --save`: write it, and say what the format cannot carry."""
    try:
        lost = save_mission(path, m)
    except GeoFileError as exc:
        raise typer.BadParameter(str(exc), param_hint="--save") from None
    out.print(f"mission {m.mission_id} written to {path}", style="dim")
    warn_lost(path, lost, out)


# --------------------------------------------------------------------------- fence limits


def fence_warnings(new: Sequence[NoFlyZone], held: Sequence[NoFlyZone] = ()) -> list[str]:
    """What the autopilots' fences cannot hold: ArduPilot keeps a few dozen fence items
    (a polygon vertex or a circle each; `swarm_node.core.fences.FENCE_MAX_ITEMS`); a
    node loads a zone that does not fit simplified (fewer vertices, on the permissive
    side) or leaves it out, and its planners avoid the zone as declared."""
    from swarm_node.core.fences import FENCE_MAX_ITEMS

    def items(z: NoFlyZone) -> int:
        return 1 if z.geometry.kind == GeometryKind.CIRCLE else len(z.geometry.points)

    out = [
        f"zone {z.zone_id} has {items(z):,} vertices; an autopilot's fence holds "
        f"{FENCE_MAX_ITEMS} items (ArduPilot on a Pixhawk: a vertex or a circle each): the "
        "vehicles load it simplified or leave it out of their fences (their planners avoid "
        "it as declared)"
        for z in new
        if items(z) > FENCE_MAX_ITEMS
    ]
    ids = {z.zone_id for z in new}
    total = sum(items(z) for z in new) + sum(
        items(z) for z in held if z.active and z.zone_id not in ids
    )
    if total > FENCE_MAX_ITEMS and not out:
        out.append(
            f"the zones in force need {total:,} fence items; an autopilot's fence holds "
            f"{FENCE_MAX_ITEMS}: the zones farthest from home are simplified or left out of "
            "the autopilots' fences (their planners avoid every zone as declared)"
        )
    return out


# --------------------------------------------------------------------------- import


@dataclass(frozen=True)
class Planned:
    """One zone of an import: what is sent, and what it does to the zone held."""

    zone: NoFlyZone
    source: str
    action: str  # "declare", "replace", "unchanged"
    held: NoFlyZone | None = None

    def line(self) -> str:
        z = self.zone
        kind = "operating area" if z.operating_area else "no-fly zone"
        name = f" {z.name!r}" if z.name else ""
        what = f"{kind} {z.zone_id}{name} ({where(z)}"
        if not z.operating_area:
            what += f", {z.floor_alt_msl_m:g}..{z.ceiling_alt_msl_m:g} m above sea level"
        what += "" if self.source == z.name else f"; from {self.source}"
        what += ")"
        if self.action == "replace" and self.held is not None:
            old = f" {self.held.name!r}" if self.held.name else ""
            return f"replace zone {z.zone_id}{old} with {what}"
        if self.action == "unchanged":
            return f"unchanged: {what}, held as the file has it"
        return f"declare {what}"


def _same(a: NoFlyZone, b: NoFlyZone) -> bool:
    """The same declaration but for its stamps and issuer."""
    keep = ("geometry", "floor_alt_msl_m", "ceiling_alt_msl_m", "active", "name", "operating_area")
    return all(getattr(a, k) == getattr(b, k) for k in keep) and b.valid_until_unix_s is None


def plan_import(
    zf: ZoneFile,
    held: dict[int, NoFlyZone],
    *,
    first_id: int | None,
    replace: bool,
    floor: float | None,
    ceiling: float | None,
    issuer_id: int,
    now: float,
) -> list[Planned]:
    """Every zone of the file with its id and what it does (pure). Ids: the file's own,
    then from `first_id`, else the lowest no vehicle holds (in force or withdrawn). A
    file or `first_id` id whose zone in force differs is a clash: ValueError naming
    them, unless `replace`."""
    taken = set(held)
    file_ids = [z.zone_id for z in zf.zones if z.zone_id is not None]
    used: set[int] = set()
    out: list[Planned] = []
    clashes: list[str] = []
    nxt = first_id if first_id is not None else 1
    for spec in zf.zones:
        zid = spec.zone_id
        if zid is None or zid in used:
            while nxt in used or nxt in file_ids or (first_id is None and nxt in taken):
                nxt += 1
            zid = nxt
            nxt += 1
        used.add(zid)
        zone = _zone(spec, zid, floor, ceiling, issuer_id, now)
        old = held.get(zid)
        if old is None or not old.active:
            out.append(Planned(zone, spec.source, "declare"))
        elif _same(old, zone):
            out.append(Planned(zone, spec.source, "unchanged", old))
        else:
            if not replace:
                clashes.append(f"{zid}" + (f" {old.name!r}" if old.name else ""))
            out.append(Planned(zone, spec.source, "replace", old))
    if clashes:
        many = len(clashes) > 1
        raise ValueError(
            f"zone{'s' if many else ''} {', '.join(clashes)} {'are' if many else 'is'} in force "
            f"with another zone: add --replace to replace {'them' if many else 'it'} with the "
            "file's" + ("" if first_id is None else ", or leave out --first-id for free ids")
        )
    return out


def _zone(
    spec: ZoneSpec,
    zid: int,
    floor: float | None,
    ceiling: float | None,
    issuer_id: int,
    now: float,
) -> NoFlyZone:
    lo = floor if floor is not None else spec.floor_alt_msl_m
    hi = ceiling if ceiling is not None else spec.ceiling_alt_msl_m
    return NoFlyZone(
        zid,
        spec.geometry,
        FULL_FLOOR_M if lo is None else lo,
        FULL_CEILING_M if hi is None else hi,
        now,
        None,
        True,
        spec.name[:48],
        spec.operating_area,
        issuer_id,
    )


def _base(zf: ZoneFile, file: Path) -> tuple[GeoPoint, str]:
    """The swarm's base from the file's first rally point (at the planned home's height
    above sea level when the file has one: a rally point's own altitude is above home,
    and every node keeps its rally point at a safe height above its home)."""
    if not zf.rally:
        raise typer.BadParameter(f"{file}: no rally point in it", param_hint="--base-from-file")
    lat, lon, _alt = zf.rally[0]
    ground = zf.home[2] if zf.home is not None and zf.home[2] is not None else 0.0
    base = GeoPoint(lat, lon, ground)
    more = f" (rally points 2-{len(zf.rally)} not used)" if len(zf.rally) > 1 else ""
    return checked(base), f"set the base at rally point 1: {lat:.6f},{lon:.6f}{more}"


@zone_app.command("import")
def zone_import(
    ctx: typer.Context,
    file: Path = typer.Argument(..., dir_okay=False, help="GeoJSON, KML, .plan, waypoints or JSON"),
    first_id: int | None = typer.Option(
        None,
        "--first-id",
        min=1,
        max=2**32 - 1,
        help="ids from here on for zones the file does not number (default: ids no vehicle holds)",
    ),
    replace: bool = typer.Option(
        False, "--replace", help="replace zones in force that have the file's ids"
    ),
    base_from_file: bool = typer.Option(
        False, "--base-from-file", help="the file's first rally point becomes the swarm's base"
    ),
    dry_run: bool = typer.Option(
        False, "--dry-run", help="print what would be declared and skipped; send nothing"
    ),
    floor: float | None = typer.Option(
        None, help="floor, m above mean sea level (default: the file's, else -1000)"
    ),
    ceiling: float | None = typer.Option(
        None, help="ceiling, m above mean sea level (default: the file's, else 8000)"
    ),
    ids: IdsOption = [],  # noqa: B006
    fleet: FleetOption = None,
    all_: AllOption = False,
    timeout: float = typer.Option(10.0, help="seconds to wait for each zone's answers"),
    as_json: JsonOption = False,
) -> None:
    """Declare every fence polygon and circle of a file as a zone (exclusion: a no-fly
    zone; inclusion: an operating area), each acknowledged by every vehicle. Zones the
    file does not number take ids no vehicle holds; a zone in force is replaced only
    with --replace. Everything not imported is listed with why. The file is read and
    every zone checked before anything is sent.

    Example: gcs zone import field.plan --base-from-file --dry-run
    """
    for opt, v in (("--floor", floor), ("--ceiling", ceiling)):
        finite(v, opt, -1000.0, 8000.0)
    timeout_option(timeout)
    try:
        zf = zones_from_file(file)
    except GeoFileError as exc:
        raise typer.BadParameter(str(exc), param_hint="FILE") from None
    if not zf.zones and not base_from_file:
        has = "; ".join(str(s) for s in zf.skipped[:6])
        raise typer.BadParameter(
            f"{file}: no fence polygon or circle in it ({has})", param_hint="FILE"
        )
    base = _base(zf, file) if base_from_file else None
    if base is not None:  # the first rally point is imported: as the base
        first = next(i for i, s in enumerate(zf.skipped) if s.role == "rally")
        zf = dataclasses.replace(zf, skipped=zf.skipped[:first] + zf.skipped[first + 1 :])
    sel = selector_from(ids, fleet, 0, "", all_)
    link: Link = ctx.obj
    now = time.time()

    def planned(held: dict[int, NoFlyZone]) -> list[Planned]:
        try:
            out = plan_import(
                zf,
                held,
                first_id=first_id,
                replace=replace,
                floor=floor,
                ceiling=ceiling,
                issuer_id=link.gcs_id,
                now=now,
            )
        except ValueError as exc:
            raise typer.BadParameter(f"{file}: {exc}", param_hint="FILE") from None
        for p in out:
            try:
                checked(p.zone)
            except typer.BadParameter as exc:
                raise typer.BadParameter(
                    f"{file}: {p.source}: {exc.message}", param_hint="FILE"
                ) from None
        return out

    planned({})  # every zone checked before a session is opened
    if dry_run:
        try:
            with link.open() as gs:
                held, checked_against = _held(gs), True
        except _clickx.ClickException:  # no swarm to ask: the plan without its zones
            held, checked_against = {}, False
        plan = planned(held)
        warnings = fence_warnings([p.zone for p in plan], list(held.values()))
        _show_plan(plan, zf, base, warnings, True, checked_against, as_json)
        return
    failed = 0
    answers: dict[str, Any] = {"base": None, "zones": []}
    with link.open() as gs:
        held = _held(gs)
        plan = planned(held)
        warnings = fence_warnings([p.zone for p in plan], list(held.values()))
        _show_plan(plan, zf, base, warnings, False, True, as_json)
        if base is not None:
            with progress(not as_json) as show:
                out = gs.send_command(
                    CommandKind.SET_BASE,
                    sel,
                    CommandArgs(point=base[0]),
                    timeout_s=timeout,
                    progress=show,
                )
            failed += _shown(out, as_json)
            answers["base"] = outcome_json(out)
        for p in plan:
            entry: dict[str, Any] = {"zone_id": p.zone.zone_id, "action": p.action}
            answers["zones"].append(entry)
            if p.action == "unchanged":
                continue
            with progress(not as_json) as show:
                out = gs.send_zone(p.zone, sel, timeout_s=timeout, progress=show)
            failed += _shown(out, as_json)
            entry["answers"] = outcome_json(out)
    if as_json:
        answers["skipped"] = [{"what": s.what, "why": s.why} for s in zf.skipped]
        answers["warnings"] = warnings
        answers["ok"] = not failed
        typer.echo(json.dumps(answers, indent=2))
    if failed:
        if not as_json:
            console.print(f"[red]{failed} of the file's declarations not held by every vehicle[/]")
        raise typer.Exit(1)


def _held(gs: GroundStation) -> dict[int, NoFlyZone]:
    gs.discover(1.0)
    return newest_zones(gs.all_zones(2.0))[0]


def _shown(out: Outcome, as_json: bool) -> int:
    """Show one answer (as JSON: gathered by the caller); 1 when it failed."""
    if as_json:
        return 0 if out.ok else 1
    try:
        report(out, console)
    except typer.Exit:
        return 1
    return 0


def _show_plan(
    plan: list[Planned],
    zf: ZoneFile,
    base: tuple[GeoPoint, str] | None,
    warnings: list[str],
    dry_run: bool,
    checked_against: bool,
    as_json: bool,
) -> None:
    if as_json and dry_run:
        typer.echo(
            json.dumps(
                {
                    "zones": [
                        {"action": p.action, "source": p.source, **msgspec.to_builtins(p.zone)}
                        for p in plan
                    ],
                    "base": msgspec.to_builtins(base[0]) if base else None,
                    "skipped": [{"what": s.what, "why": s.why} for s in zf.skipped],
                    "warnings": warnings,
                    "ids_checked_against_the_vehicles": checked_against,
                },
                indent=2,
            )
        )
        return
    if as_json:
        return
    head = "would" if dry_run else "will"
    console.print(f"{head}:", style="bold", highlight=False)
    if base is not None:
        console.print(f"  {base[1]}", highlight=False, soft_wrap=True)
    for p in plan:
        console.print(f"  {p.line()}", highlight=False, soft_wrap=True)
    if zf.skipped:
        console.print("not imported:", style="bold", highlight=False)
        for s in zf.skipped:
            console.print(f"  {s}", highlight=False, soft_wrap=True)
    for w in warnings:
        console.print(f"warning: {w}", style="yellow", highlight=False, soft_wrap=True)
    if not checked_against:
        console.print(
            "ids not checked against the vehicles' zones (nothing answered)",
            style="yellow",
            highlight=False,
        )
    if dry_run:
        console.print("dry run: nothing sent", style="dim")


def check_removal(link: Link, zone_id: int, timeout_s: float = 2.0) -> None:
    """`gcs zone remove`: refuse an id no vehicle holds (nothing sent: a withdrawal of
    a zone never declared would be kept by every vehicle as a withdrawn zone)."""
    zones, holders = held_zones(link, timeout_s)
    if zone_id not in zones:
        held = ", ".join(str(z) for z in sorted(zones)) or "none"
        console.print(
            f"[red]zone {zone_id} is held by no vehicle (ids held: {held}): nothing to remove[/]"
        )
        raise typer.Exit(1)
    if not zones[zone_id].active:
        console.print(f"zone {zone_id} is already withdrawn (on {len(holders[zone_id])} vehicles)")
        raise typer.Exit(0)
