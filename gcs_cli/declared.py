"""`gcs declared [NODE] [--json]`: what the operator declared, as a node holds it.
Every node keeps every declaration (zones and operating areas, withdrawn
ones too; SET_BASE, SET_FLEET and CANCEL_MISSION commands; fleet assignments; the
missions it accepted) with its stamp, in its database, and nodes exchange them when
they meet, so any node can be asked: they converge on the newest declarations.
"""

from __future__ import annotations

import time

import msgspec
import typer
from rich.console import Console
from rich.table import Table

from swarm_proto import CommandKind, DeclaredState, GeometryKind

console = Console()


def _when(stamp: float) -> str:
    if stamp <= 0.0:
        return "-"
    return time.strftime("%Y-%m-%d %H:%M:%S", time.gmtime(stamp)) + "Z"


def _selector(cmd: object) -> str:
    t = cmd.target  # type: ignore[attr-defined]
    if t.vehicle_ids:
        return "ids " + ",".join(str(i) for i in t.vehicle_ids)
    if t.fleet_id:
        return f"fleet {t.fleet_id}"
    return "all"


def declared_tables(state: DeclaredState) -> list[Table]:
    """The declared state as tables (zones, commands, fleets, missions)."""
    zones = Table(title=f"zones held by node {state.vehicle_id}")
    for col in ("id", "name", "kind", "shape", "state", "declared"):
        zones.add_column(col)
    for z in state.zones:
        shape = (
            f"circle r={z.geometry.radius_m:g} m"
            if z.geometry.kind == GeometryKind.CIRCLE
            else f"polygon {len(z.geometry.points)} vertices"
        )
        zones.add_row(
            str(z.zone_id),
            z.name,
            "operating area" if z.operating_area else "no-fly zone",
            shape,
            "in force" if z.active else "withdrawn",
            _when(z.time_unix_s),
        )
    cmds = Table(title="bases, fleets and cancellations (commands, oldest first)")
    for col in ("command", "addresses", "value", "declared"):
        cmds.add_column(col)
    for c in state.commands:
        a = c.args
        if c.kind == CommandKind.SET_BASE and a.point is not None:
            value = f"{a.point.lat_deg:.6f}, {a.point.lon_deg:.6f}, {a.point.alt_msl_m:g} m"
        elif c.kind == CommandKind.SET_FLEET:
            value = f"fleet {a.fleet_id}"
        else:
            value = f"mission {a.mission_id}"
        cmds.add_row(
            c.kind.name.lower().replace("_", "-"), _selector(c), value, _when(c.time_unix_s)
        )
    for f in state.assignments:
        cmds.add_row(
            "fleet-assignment",
            ",".join(str(i) for i in f.vehicle_ids),
            f"fleet {f.fleet_id}",
            _when(f.time_unix_s),
        )
    missions = Table(title="missions")
    for col in ("id", "type", "name", "state", "changed"):
        missions.add_column(col)
    for m in state.missions:
        missions.add_row(
            str(m.mission.mission_id),
            m.mission.mission_type.name.lower(),
            m.mission.name,
            "in force" if m.in_force else "ended",
            _when(m.changed_unix_s),
        )
    return [zones, cmds, missions]


def declared(
    ctx: typer.Context,
    node: int | None = typer.Argument(None, help="node id (default: the first vehicle alive)"),
    as_json: bool = typer.Option(False, "--json", help="print the node's reply as JSON"),
    timeout: float = typer.Option(3.0, help="seconds to wait for the answer"),
) -> None:
    """What the operator declared (zones, bases, fleets, missions), as a node holds it:
    any node can be asked, they converge on the newest declarations.

    Example: gcs declared 3 --json"""
    if not timeout > 0:
        raise typer.BadParameter("must be > 0", param_hint="--timeout")
    with ctx.obj.open() as gs:
        ids = [node] if node is not None else sorted(gs.discover())
        if not ids:
            console.print("[red]no vehicle alive to ask[/]")
            raise typer.Exit(1)
        state = None
        for vid in ids:
            state = gs.declared_state(vid, timeout_s=timeout)
            if state is not None:
                break
        if state is None:
            console.print(f"[red]node {ids[0] if len(ids) == 1 else ids} did not answer[/]")
            raise typer.Exit(1)
    if as_json:
        print(msgspec.json.encode(state).decode())
        return
    base = state.base
    console.print(
        f"node {state.vehicle_id}: base "
        + (f"{base.lat_deg:.6f}, {base.lon_deg:.6f}, {base.alt_msl_m:g} m" if base else "none")
        + f"; fleet {state.fleet_id or '-'}; mission {state.mission_id or '-'}"
    )
    for table in declared_tables(state):
        if table.row_count:
            console.print(table)
