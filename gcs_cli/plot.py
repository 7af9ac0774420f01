"""Pictures and flight records: `gcs plot` draws a plan (each vehicle's share as the
nodes plan it, the zones, the base, the homes) and, from a flight recorder CSV, the
tracks flown, to a PNG (matplotlib); `gcs record` writes that CSV from the live
telemetry (swarm_proto/trajectory.py's format, so `gcs analyze separation` reads it
too).

The plan is recomputed here with the nodes' own planner (`plan_fleet`: the mission,
the members' database profiles sorted by id, their homes, the zones in force), which
is what every member computes and keeps its share of (docs/node.md); the ground
station uses the first member's home altitude for the zones' heights, as a node uses
its own."""

from __future__ import annotations

import json
import math
import queue
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import typer

from swarm_proto import GeometryKind, Mission, NoFlyZone, VehicleStatus
from swarm_proto.trajectory import Trajectory, TrajectoryError, TrajectoryWriter, read_trajectory

from .common import console, quit_on_signal, read_filter
from .options import AllOption, FleetOption, IdsOption, finite
from .recovery import StateFileError, SwarmState, collect, read_state

app = typer.Typer()  # plot, record: app.py puts them at the top level

R_EARTH_M = 6_371_008.8


@dataclass
class Frame:
    """A local east/north frame in metres around a centre (plenty for a field)."""

    lat0: float
    lon0: float

    def xy(self, lat: float, lon: float) -> tuple[float, float]:
        x = math.radians(lon - self.lon0) * R_EARTH_M * math.cos(math.radians(self.lat0))
        return x, math.radians(lat - self.lat0) * R_EARTH_M


def vehicle_colors(ids: Sequence[int]) -> dict[int, tuple[float, float, float]]:
    """One tab10 color per vehicle id (sorted), the same in every picture of a run."""
    import matplotlib

    cmap = matplotlib.colormaps["tab10"]
    return {vid: tuple(cmap(i % 10)[:3]) for i, vid in enumerate(sorted(ids))}  # type: ignore[misc]


def plan_shares(state: SwarmState, mission: Mission) -> dict[int, list[tuple[float, float]]]:
    """Each member's planned share (lat, lon points) of a mission in force, planned as
    the nodes plan it; {} when the members' profiles or homes are unknown."""
    from swarm_node.core.mission.share import Member, plan_fleet
    from swarm_node.database import SwarmDatabase
    from swarm_node.database.paths import resolve_db_path

    ids = state.members(mission.mission_id)
    homes = {v.vehicle_id: v.home for v in state.vehicles}
    with SwarmDatabase.open(resolve_db_path(None)) as db:
        members = [Member(db.vehicle_profile(vid), homes.get(vid)) for vid in ids]
    first_home = next((h for h in (homes.get(v) for v in ids) if h is not None), None)
    zones = [z for z in state.zones if z.active and not z.operating_area]
    plan = plan_fleet(
        mission,
        members,
        zones,
        state.saved_unix_s or time.time(),
        first_home.alt_msl_m if first_home else 0.0,
    )
    return {
        vid: [(w.lat_deg, w.lon_deg) for w in share.waypoints if w.lat_deg or w.lon_deg]
        for vid, share in plan.shares.items()
    }


def draw(
    out: Path,
    state: SwarmState | None,
    track: Trajectory | None,
    *,
    shares: dict[int, list[tuple[float, float]]] | None = None,
    title: str = "",
) -> dict[str, int]:
    """Draw and save the picture; returns what was drawn (for the command's summary)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Circle, Polygon

    pts: list[tuple[float, float]] = []
    zones: list[NoFlyZone] = [z for z in (state.zones if state else []) if z.active]
    missions = list(state.missions) if state else []
    shares = shares or {}
    for m in missions:
        pts += _outline(m.geometry)
    for s in shares.values():
        pts += s
    if track is not None:
        pts += list(zip(track.lat.tolist(), track.lon.tolist(), strict=True))
    if state is not None:
        pts += [(v.home.lat_deg, v.home.lon_deg) for v in state.vehicles if v.home]
        if state.base:
            pts.append((state.base.lat_deg, state.base.lon_deg))
    # the view is what is planned and flown; zones are drawn where they fall in it (an
    # operating area around the field would zoom a 30 m orbit out of sight)
    focus = list(pts) or [p for z in zones for p in _outline(z.geometry)]
    if not focus:
        raise ValueError("nothing to draw")
    frame = Frame(sum(p[0] for p in focus) / len(focus), sum(p[1] for p in focus) / len(focus))
    ids = sorted(
        set(shares)
        | set(track.vehicles if track is not None else [])
        | {v.vehicle_id for v in (state.vehicles if state else [])}
    )
    colors = vehicle_colors(ids)
    fig, ax = plt.subplots(figsize=(8, 8), dpi=100)
    drawn = {"zones": 0, "missions": 0, "shares": 0, "tracks": 0}
    for m in missions:
        g = m.geometry
        xy = [frame.xy(p.lat_deg, p.lon_deg) for p in g.points]
        label = f"mission {m.mission_id} ({m.mission_type.name.lower()})"
        if g.kind == GeometryKind.POLYGON:
            ax.add_patch(
                Polygon(
                    xy,
                    closed=True,
                    facecolor=(0.85, 0.85, 0.85),
                    edgecolor="black",
                    linestyle="--",
                    linewidth=1.0,
                    zorder=1,
                    label=label,
                )
            )
        elif g.kind == GeometryKind.CIRCLE:
            ax.add_patch(
                Circle(
                    xy[0],
                    g.radius_m or 0.0,
                    fill=False,
                    edgecolor="black",
                    linestyle="--",
                    zorder=1,
                    label=label,
                )
            )
        else:
            ax.plot(*zip(*xy, strict=True), "k--", marker="x", zorder=1, label=label)
        drawn["missions"] += 1
    for z in zones:
        if not z.active:
            continue
        g = z.geometry
        area = z.operating_area
        style = dict(
            facecolor="none" if area else (0.9, 0.1, 0.1, 0.35),
            edgecolor=(0.1, 0.6, 0.1) if area else (0.8, 0.0, 0.0),
            linestyle="--" if area else "-",
            linewidth=2.0,
            zorder=2,
            label=f"{'operating area' if area else 'no-fly zone'} {z.zone_id}",
        )
        if g.kind == GeometryKind.CIRCLE:
            ax.add_patch(
                Circle(
                    frame.xy(g.points[0].lat_deg, g.points[0].lon_deg), g.radius_m or 0.0, **style
                )
            )
        else:
            ax.add_patch(
                Polygon([frame.xy(p.lat_deg, p.lon_deg) for p in g.points], closed=True, **style)
            )
        drawn["zones"] += 1
    for vid, s in sorted(shares.items()):
        if len(s) < 1:
            continue
        xs, ys = zip(*(frame.xy(a, b) for a, b in s), strict=True)
        ax.plot(
            xs,
            ys,
            color=colors[vid],
            linestyle=(0, (4, 2)),
            linewidth=1.5,
            zorder=3,
            label=f"vehicle {vid} plan",
        )
        drawn["shares"] += 1
    if track is not None:
        for vid in track.vehicles:
            sel = track.vehicle == vid
            xs, ys = zip(
                *(frame.xy(a, b) for a, b in zip(track.lat[sel], track.lon[sel], strict=True)),
                strict=True,
            )
            ax.plot(
                xs, ys, color=colors[vid], linewidth=2.5, zorder=4, label=f"vehicle {vid} flown"
            )
            drawn["tracks"] += 1
    if state is not None:
        for v in state.vehicles:
            if v.home:
                ax.plot(
                    *frame.xy(v.home.lat_deg, v.home.lon_deg),
                    marker="^",
                    markersize=9,
                    color=colors.get(v.vehicle_id, "black"),
                    markeredgecolor="black",
                    zorder=5,
                )
        if state.base:
            ax.plot(
                *frame.xy(state.base.lat_deg, state.base.lon_deg),
                marker="*",
                markersize=18,
                color="gold",
                markeredgecolor="black",
                zorder=6,
                label="base",
            )
    xy = [frame.xy(a, b) for a, b in focus]
    x0, x1 = min(x for x, _ in xy), max(x for x, _ in xy)
    y0, y1 = min(y for _, y in xy), max(y for _, y in xy)
    half = max(x1 - x0, y1 - y0) / 2 + max(VIEW_MARGIN_M, 0.08 * max(x1 - x0, y1 - y0))
    cx, cy = (x0 + x1) / 2, (y0 + y1) / 2
    ax.set_xlim(cx - half, cx + half)  # square, as the figure: metres equal both ways
    ax.set_ylim(cy - half, cy + half)
    ax.set_aspect("equal", adjustable="box")
    ax.set_xlabel(f"east of {frame.lat0:.5f}, {frame.lon0:.5f} (m)")
    ax.set_ylabel("north (m)")
    ax.grid(True, linewidth=0.3)
    ax.set_title(title or "bandada plan" + (" and flight" if track is not None else ""))
    ax.legend(loc="best", fontsize=7, framealpha=0.8)
    fig.tight_layout()
    try:
        fig.savefig(out, format="png", metadata={"Description": _georeference(fig, ax, frame)})
    finally:
        plt.close(fig)
    return drawn


#: the least margin around what is planned and flown in a picture
VIEW_MARGIN_M = 20.0


def _outline(g: Any) -> list[tuple[float, float]]:
    """A geometry's points, a circle's as its bounding square's corners."""
    pts = [(p.lat_deg, p.lon_deg) for p in g.points]
    if g.kind == GeometryKind.CIRCLE and g.radius_m:
        lat, lon = pts[0]
        dlat = math.degrees(g.radius_m / R_EARTH_M)
        dlon = dlat / max(math.cos(math.radians(lat)), 1e-6)
        pts = [(lat + a * dlat, lon + b * dlon) for a in (-1, 1) for b in (-1, 1)]
    return pts


#: a gap this long with no vehicle airborne ends a sortie (a gap in the record, when the
#: record has no height above home)
SORTIE_GAP_S = 30.0


def sorties(tr: Trajectory, airborne: Any = None) -> list[tuple[float, float]]:
    """The sorties of a flight record, in time order: (start, end) of each stretch with
    some vehicle airborne (`airborne`, a mask of the samples; None: every sample), two
    stretches less than SORTIE_GAP_S apart being one."""
    import numpy as np

    t = tr.time_s if airborne is None else tr.time_s[np.asarray(airborne, dtype=bool)]
    times = sorted(set(t.tolist()))
    out: list[tuple[float, float]] = []
    for x in times:
        if out and x - out[-1][1] < SORTIE_GAP_S:
            out[-1] = (out[-1][0], x)
        else:
            out.append((x, x))
    return out


def in_window(tr: Trajectory, start: float, end: float) -> Trajectory:
    m = (tr.time_s >= start) & (tr.time_s <= end)
    return Trajectory(tr.time_s[m], tr.vehicle[m], tr.lat[m], tr.lon[m], tr.alt_m[m])


def _georeference(fig: Any, ax: Any, frame: Frame) -> str:
    """Where the map is in the picture, as JSON in the PNG's Description: the local
    frame's centre, the axes' limits in metres and their box in image pixels (origin top
    left), so that a reader (the demo's tests) can put a point of the field on a pixel."""
    fig.canvas.draw()  # the final layout (equal aspect, tight layout) before reading it
    box = ax.get_window_extent()
    height = fig.get_size_inches()[1] * fig.dpi
    return json.dumps(
        {
            "frame_lat_lon": [frame.lat0, frame.lon0],
            "xlim_m": list(ax.get_xlim()),
            "ylim_m": list(ax.get_ylim()),
            "axes_px": [box.x0, height - box.y1, box.x1, height - box.y0],
        }
    )


def read_georeference(png: Path) -> tuple[Frame, Callable[[float, float], tuple[float, float]]]:
    """A picture `draw` made: its frame and a function (lat, lon) -> (column, row) in
    image pixels. ValueError when the picture has no georeference."""
    from PIL import Image

    with Image.open(png) as img:
        text = img.info.get("Description")
    if not text:
        raise ValueError(f"{png}: no georeference")
    g = json.loads(text)
    frame = Frame(*g["frame_lat_lon"])
    (x0, x1), (y0, y1) = g["xlim_m"], g["ylim_m"]
    c0, r0, c1, r1 = g["axes_px"]

    def pixel(lat: float, lon: float) -> tuple[float, float]:
        x, y = frame.xy(lat, lon)
        return c0 + (x - x0) / (x1 - x0) * (c1 - c0), r1 - (y - y0) / (y1 - y0) * (r1 - r0)

    return frame, pixel


@app.command()
def plot(
    ctx: typer.Context,
    out: Path = typer.Option(..., "--out", "-o", dir_okay=False, help="the PNG to write"),
    state_file: Path | None = typer.Option(
        None, "--state", dir_okay=False, help="a `gcs save` file (default: ask the swarm now)"
    ),
    track: Path | None = typer.Option(
        None,
        "--track",
        dir_okay=False,
        help="a flight recorder CSV (gcs record, swarm-node "
        "run --record, the simulator) to draw the flown tracks",
    ),
    no_plan: bool = typer.Option(False, "--no-plan", help="do not compute the shares"),
    offline: bool = typer.Option(False, "--offline", help="only the files: ask no vehicle"),
    all_sorties: bool = typer.Option(
        False, "--all-sorties", help="every sortie of --track (default: the last)"
    ),
) -> None:
    """Draw the plan (each vehicle's share of every mission in force, the zones, the
    base and the homes) and the flown tracks to a PNG. The plan comes from a `gcs save`
    file or from the swarm now; the tracks from a flight recorder CSV, its last sortie
    unless --all-sorties. The picture shows what is planned and flown; zones are drawn
    where they fall in it.

    Example: gcs plot --state saved.json --track flight.csv --out flight.png
    """
    if out.suffix.lower() != ".png":
        raise typer.BadParameter(f"{out}: the picture is a .png", param_hint="--out")
    state: SwarmState | None = None
    if state_file is not None:
        try:
            state = read_state(state_file)
        except StateFileError as exc:
            raise typer.BadParameter(str(exc), param_hint="--state") from None
    trajectory = None
    if track is not None:
        from .analyze import airborne_mask

        try:
            trajectory = read_trajectory(track)
            mask, _ = airborne_mask(track, len(trajectory.time_s))
        except TrajectoryError as exc:
            raise typer.BadParameter(str(exc), param_hint="--track") from None
        found = sorties(trajectory, mask) or sorties(trajectory)
        if len(found) > 1 and not all_sorties:
            start, end = found[-1]
            trajectory = in_window(trajectory, start, end)
            console.print(
                f"{track.name}: the last of {len(found)} sorties ({end - start:.0f} s); "
                "--all-sorties draws every one",
                style="dim",
            )
    if state is None and not offline:
        with ctx.obj.open() as gs:
            state, warnings = collect(gs)
        for w in warnings:
            console.print(f"[yellow]{w}[/]")
    if state is None and trajectory is None:
        raise typer.BadParameter("nothing to draw: give --state or --track (or drop --offline)")
    shares: dict[int, list[tuple[float, float]]] = {}
    if state is not None and not no_plan:
        for m in state.missions:
            try:
                shares.update(plan_shares(state, m))
            except Exception as exc:  # planning or database: the picture goes on without it
                console.print(f"[yellow]mission {m.mission_id}: no shares drawn: {exc}[/]")
    try:
        drawn = draw(out, state, trajectory, shares=shares)
    except (ValueError, OSError) as exc:
        raise typer.BadParameter(f"{out}: {exc}", param_hint="--out") from None
    console.print(
        f"{out}: {drawn['missions']} mission(s), {drawn['shares']} share(s), "
        f"{drawn['zones']} zone(s), {drawn['tracks']} track(s)"
    )


EXTRA = (
    "alt_rel_m",
    "groundspeed_m_s",
    "heading_deg",
    "battery_pct",
    "fsm",
    "mission",
    "progress_pct",
    "armed",
)


def write_status(w: TrajectoryWriter, s: VehicleStatus) -> None:
    w.write(
        s.time_unix_s,
        s.vehicle_id,
        s.lat_deg,
        s.lon_deg,
        s.alt_msl_m,
        f"{s.alt_rel_m:.2f}",
        f"{s.groundspeed_m_s:.2f}",
        f"{s.heading_deg:.1f}",
        s.battery_pct,
        s.fsm_state.name,
        s.mission_state.name,
        s.mission_progress_pct,
        int(s.armed),
    )


@app.command()
def record(
    ctx: typer.Context,
    out: Path = typer.Argument(..., dir_okay=False, help="the flight CSV to write"),
    duration: float | None = typer.Option(
        None, help="stop after this many seconds (default: Ctrl-C)"
    ),
    ids: IdsOption = [],  # noqa: B006
    fleet: FleetOption = None,
    all_: AllOption = False,
) -> None:
    """Record the flight from the live telemetry: one CSV row per VehicleStatus heard
    (time_s = the sample's GPS UNIX time, vehicle, lat, lon, alt_m above mean sea
    level, then alt_rel_m, groundspeed_m_s, heading_deg, battery_pct, fsm, mission,
    progress_pct, armed). `gcs plot --track` and `gcs analyze separation` read it. Exit 1 if
    nothing was heard.

    Example: gcs record flight.csv --duration 600
    """
    finite(duration, "--duration", 0.0, 1.0e7)
    shown = read_filter(ids, fleet, all_)
    rows = 0
    last: dict[int, float] = {}
    try:
        writer = TrajectoryWriter(out, EXTRA, flush_every=25)
    except OSError as exc:
        raise typer.BadParameter(f"{out}: cannot write: {exc.strerror or exc}") from None
    with writer, ctx.obj.open() as gs:
        statuses = gs.status_feed()
        end = None if duration is None else time.monotonic() + duration
        console.print(
            f"recording to {out} ({'Ctrl-C stops' if end is None else f'{duration:g} s'})",
            style="dim",
        )
        with quit_on_signal() as quit_:
            while (end is None or time.monotonic() < end) and not quit_.is_set():
                left = 0.5 if end is None else max(0.0, min(0.5, end - time.monotonic()))
                try:
                    s = statuses.get(timeout=left)
                except queue.Empty:
                    continue
                if not shown.addresses(s.vehicle_id, s.fleet_id):
                    continue
                if last.get(s.vehicle_id) == s.time_unix_s:
                    continue  # the same sample again (an autopilot link loss repeats it)
                last[s.vehicle_id] = s.time_unix_s
                write_status(writer, s)
                rows += 1
    console.print(
        f"{out}: {rows} row(s) from vehicle(s) {', '.join(map(str, sorted(last))) or 'none'}"
    )
    if not rows:
        raise typer.Exit(1)
