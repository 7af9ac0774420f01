"""`gcs mission ... --dry-run`: the checks the fleet will run, before anything is sent.

The mission is planned here as every addressed vehicle plans it (`plan_fleet`, the
nodes' own planner: their database profiles sorted by id, their homes and batteries as
their VehicleInfo says, the zones in force they hold), so a plan the fleet would refuse
(an area its batteries cannot fly, a target inside a zone) is refused here with the
same reason and its numbers, and a plan it would fly shows each vehicle's budget: what
its share and the way home take at cruise against what its battery allows after the
climb and the landing (`planning.endurance`). Nothing is sent: the swarm is only
listened to and asked (its zones queryables); with no swarm to ask, `--id` vehicles are
planned from the database alone (homes unknown: the way out and back not counted).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from pathlib import Path

import typer
from rich import box
from rich.console import Console
from rich.table import Table

from swarm_proto import GeoPoint, Mission, MissionType, NoFlyZone, SelectorKind, VehicleType

from . import _clickx
from .core.reasons import detail_text


@dataclass(frozen=True)
class Budget:
    """One vehicle's share of a plan against its battery."""

    vehicle_id: int
    share_m: float
    needs_s: float  # its share and the straight way home, at its mission speed
    has_s: float  # what its battery allows at cruise (inf: no battery figures)
    home_known: bool
    battery_pct: float | None

    @property
    def short(self) -> bool:
        return self.needs_s > self.has_s + 1e-6


@dataclass(frozen=True)
class Swarm:
    """What the ground station heard: vehicles alive with their fleet, home and
    battery, and the zones in force."""

    alive: dict[int, int]  # vehicle id -> fleet id
    homes: dict[int, GeoPoint]
    battery: dict[int, float]
    zones: list[NoFlyZone]


def members_of(m: Mission, swarm: Swarm | None) -> tuple[list[int], list[str]]:
    """Whom the mission addresses, as the fleet would plan it, and notes."""
    sel = m.selection
    if sel.kind == SelectorKind.IDS:
        return sorted(sel.vehicle_ids), []
    if swarm is None:
        return [], []
    ids = sorted(v for v, f in swarm.alive.items() if sel.addresses(v, f))
    if sel.kind == SelectorKind.QUANTITY and len(ids) > sel.quantity:
        chosen = ids[: sel.quantity]
        return chosen, [
            f"voting picks {sel.quantity} of {len(ids)} candidates: planned with "
            f"{', '.join(map(str, chosen))}"
        ]
    return ids, []


def budgets(
    m: Mission,
    ids: list[int],
    profiles: dict[int, object],
    swarm: Swarm | None,
    now: float,
) -> list[Budget]:
    """Plan `m` for `ids` as the nodes do; PlanningError when the fleet would refuse."""
    from swarm_node.core.mission.share import Member, plan_fleet
    from swarm_node.core.planning import PlanVehicle
    from swarm_node.core.planning.endurance import Endurance
    from swarm_node.core.planning.geo import LocalFrame

    homes = swarm.homes if swarm else {}
    battery = swarm.battery if swarm else {}
    zones = [z for z in (swarm.zones if swarm else []) if z.in_force(now)]
    members = [
        Member(profiles[v], homes.get(v), battery.get(v))  # type: ignore[arg-type]
        for v in ids
    ]
    first = next((homes[v] for v in ids if v in homes), None)
    plan = plan_fleet(m, members, zones, now, first.alt_msl_m if first else 0.0)
    out = []
    for v in ids:
        share = plan.shares.get(v)
        if share is None:
            continue
        prof = profiles[v]
        speed = PlanVehicle(prof).speed(m.params)  # type: ignore[arg-type]
        back_s = 0.0
        home = homes.get(v)
        pts = [w for w in share.waypoints if w.lat_deg or w.lon_deg]
        if home is not None and pts:
            x, y = LocalFrame(home.lat_deg, home.lon_deg).to_local(pts[-1].lat_deg, pts[-1].lon_deg)
            back_s = math.hypot(x, y) / speed
        e = Endurance.of(prof, m.params.altitude_rel_m)  # type: ignore[arg-type]
        pct = battery.get(v)
        has = e.cruise_budget_s if pct is None else e.ground_budget_s(pct, prof)  # type: ignore[arg-type]
        out.append(Budget(v, share.length_m, share.time_s + back_s, has, home is not None, pct))
    return out


def _listen(link: object, ids: list[int] | None) -> Swarm | None:
    """The swarm as heard (nothing sent): None when nothing answers at --connect."""
    try:
        gs = link.open()  # type: ignore[attr-defined]
    except _clickx.ClickException:
        return None
    with gs:
        alive = gs.discover(1.0)
        want = set(ids) if ids is not None else alive
        gs.wait_for(lambda v: all(i in v.info for i in want & alive), 1.0)
        view = gs.snapshot()
        held = gs.all_zones(2.0) if alive else {}
    from .files import newest_zones

    zones = list(newest_zones(held)[0].values())
    fleets = {v: s.fleet_id for v, s in view.status.items()}
    fleets.update({v: i.fleet_id for v, i in view.info.items() if v not in fleets})
    return Swarm(
        {v: fleets.get(v, 0) for v in alive if view.type_of(v) != VehicleType.GCS},
        {v: i.home for v, i in view.info.items() if i.home is not None},
        {v: float(i.battery_pct) for v, i in view.info.items() if i.battery_pct >= 0},
        zones,
    )


def dry_run_check(link: object, m: Mission, db_path: Path | None, out: Console) -> None:
    """Plan the mission as the fleet would and print each vehicle's budget; exit 1
    when the fleet would refuse it. Sends nothing."""
    from swarm_node.core.planning import PlanningError
    from swarm_node.database import SwarmDatabase
    from swarm_node.database.errors import ProfileError, SwarmDbError
    from swarm_node.database.paths import resolve_db_path

    wanted = list(m.selection.vehicle_ids) if m.selection.kind == SelectorKind.IDS else None
    swarm = _listen(link, wanted)
    ids, notes = members_of(m, swarm)
    what = f"mission {m.mission_id} ({m.mission_type.name.lower()})"
    if not ids:
        why = "no vehicle answered" if swarm is None else "no vehicle it addresses is alive"
        out.print(f"dry run: {what}: the fleet's checks not run ({why})", style="yellow")
        return
    profiles: dict[int, object] = {}
    try:
        with SwarmDatabase.open(resolve_db_path(db_path)) as db:
            for v in ids:
                try:
                    profiles[v] = db.vehicle_profile(v)
                except ProfileError:
                    notes.append(f"vehicle {v} is not in the swarm database: it cannot fly it")
    except (SwarmDbError, OSError) as exc:
        out.print(
            f"dry run: {what}: the fleet's checks not run (no database: {exc})", style="yellow"
        )
        return
    ids = [v for v in ids if v in profiles]
    if swarm is None:
        notes.append(
            "no swarm answered: homes, batteries and zones unknown (planned from "
            "the database; the way out and back not counted)"
        )
    for n in notes:
        out.print(f"note: {n}", style="yellow", highlight=False)
    if not ids:
        raise typer.Exit(1)
    try:
        found = budgets(m, ids, profiles, swarm, time.time())
    except (PlanningError, ValueError) as exc:
        words = detail_text(getattr(exc, "detail", None))
        text = " ".join(str(exc).split())
        out.print(
            f"dry run: {what}: the fleet would refuse it: {words + ': ' if words else ''}{text}",
            style="bold red",
            highlight=False,
        )
        raise typer.Exit(1) from None
    out.print(budget_table(found, what))
    short = [b.vehicle_id for b in found if b.short]
    if short and m.mission_type == MissionType.AREA:
        out.print(f"dry run: {what}: vehicles {short} short of battery", style="bold red")
        raise typer.Exit(1)
    if short:
        out.print(
            f"warning: {what}: vehicles {short} cannot fly their share and come home on one "
            "battery (the fleet checks endurance for area missions only)",
            style="yellow",
            highlight=False,
        )
    out.print(f"dry run: {what}: the fleet's checks pass; nothing sent", style="dim")


def budget_table(found: list[Budget], title: str) -> Table:
    t = Table(title=f"{title}: planned as the nodes plan it", box=box.SIMPLE_HEAD)
    for col in ("vehicle", "share m", "needs s", "has s", "battery", "home", ""):
        t.add_column(col, justify="right" if col not in ("", "home") else "left")
    for b in found:
        t.add_row(
            str(b.vehicle_id),
            f"{b.share_m:.0f}",
            f"{b.needs_s:.0f}",
            "no limit" if math.isinf(b.has_s) else f"{b.has_s:.0f}",
            "full" if b.battery_pct is None else f"{b.battery_pct:.0f} %",
            "heard" if b.home_known else "unknown",
            "SHORT" if b.short else "ok",
            style="red" if b.short else None,
        )
    t.caption = (
        "needs: its share and the way home at its mission speed; has: what its "
        "battery allows at cruise after the climb and the landing"
    )
    return t
