"""`gcs analyze`: offline analyses of recorded flights.

    gcs analyze separation LOG.csv [--json] [--png FILE] [--risk 40 --danger 10 --near 5]
                                   [--vehicles 1,2,3] [--step S] [--max-gap S] [--ground]

LOG.csv is a flight recorder trajectory (`time_s,vehicle,lat,lon,alt_m`, see
swarm_proto/trajectory.py). Pairs count only while both vehicles are airborne (more
than AIRBORNE_M above home, and armed) when the log says so (`gcs record` and the demo
write `alt_rel_m` and `armed`): vehicles parked on pads 10 m apart are not a risk.
Times are seconds from the log's first sample. Exit status: 0 ok, 2 bad input (one
line on stderr).
"""

from __future__ import annotations

import csv
import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import typer
from rich.console import Console
from rich.table import Table

from swarm_proto.trajectory import Trajectory, TrajectoryError, read_trajectory

from .separation import AnalysisError, SeparationReport, Thresholds, analyze

app = typer.Typer(help="Offline analyses of recorded flights.", no_args_is_help=True)

#: a vehicle more than this above its home (and armed, when the log says) is airborne
AIRBORNE_M = 1.0


def airborne_mask(path: Path, rows: int) -> tuple[np.ndarray | None, str]:
    """Which samples are airborne, from the log's `alt_rel_m` (and `armed`) columns,
    in the rows `read_trajectory` keeps; None (every sample) when the log has no
    height above home. The second value says which, for people."""
    with path.open(newline="", encoding="utf-8") as f:
        reader = csv.reader(f)
        header = [h.strip() for h in next(reader, [])]
        if "alt_rel_m" not in header:
            return None, "every sample (the log has no alt_rel_m column)"
        i_rel = header.index("alt_rel_m")
        i_armed = header.index("armed") if "armed" in header else None
        keep: list[bool] = []
        for line_no, row in enumerate(reader, start=2):
            if not row or all(not cell.strip() for cell in row):
                continue
            try:
                up = float(row[i_rel]) > AIRBORNE_M
            except (ValueError, IndexError):
                raise TrajectoryError(f"{path}:{line_no}: alt_rel_m is not a number") from None
            if i_armed is not None:
                up = up and row[i_armed].strip().lower() in ("1", "true", "yes")
            keep.append(up)
    if len(keep) != rows:
        raise TrajectoryError(f"{path}: {len(keep)} rows with alt_rel_m, {rows} samples")
    return np.array(keep, dtype=bool), (
        f"samples where both are airborne (more than {AIRBORNE_M:g} m above home"
        + (", armed)" if i_armed is not None else ")")
    )


def _masked(tr: Trajectory, mask: np.ndarray) -> Trajectory:
    return Trajectory(tr.time_s[mask], tr.vehicle[mask], tr.lat[mask], tr.lon[mask], tr.alt_m[mask])


def since(report: SeparationReport, t0: float) -> SeparationReport:
    """The report with its times in seconds from `t0` (the log's first sample)."""
    pairs = tuple(
        dataclasses.replace(p, times_s=p.times_s - t0, min_time_s=p.min_time_s - t0)
        for p in report.pairs
    )
    return dataclasses.replace(report, pairs=pairs)


def _fail(message: str) -> typer.Exit:
    typer.echo(f"error: {message}", err=True)
    return typer.Exit(2)


def _vehicles(text: str | None) -> list[int] | None:
    if not text:
        return None
    try:
        return [int(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise _fail(f"--vehicles wants ids separated by commas, got {text!r}") from None


@app.command()
def separation(
    log: Path = typer.Argument(..., help="trajectory CSV: time_s,vehicle,lat,lon,alt_m"),
    as_json: bool = typer.Option(False, "--json", help="print JSON"),
    png: Path | None = typer.Option(None, "--png", help="draw event timeline and distances"),
    risk: float = typer.Option(40.0, help="risk band upper bound, m"),
    danger: float = typer.Option(10.0, help="danger band upper bound, m"),
    near: float = typer.Option(5.0, help="near-collision distance, m"),
    vehicles: str | None = typer.Option(None, help="only these ids, e.g. 1,2,5"),
    step: float | None = typer.Option(None, help="resample on a uniform grid of this step, s"),
    max_gap: float = typer.Option(2.0, help="interpolate over sample gaps up to this, s"),
    ground: bool = typer.Option(
        False, "--ground", help="count samples on the ground too (default: airborne pairs)"
    ),
) -> None:
    """Pairwise 3-D separation, minimum and risk / danger / near-collision counts
    (the paper's tables 2 and 3), while both vehicles of a pair are airborne when the
    log has their height above home (`gcs record` writes it); times in seconds from
    the log's first sample.

    Example: gcs analyze separation flight.csv --png separation.png
    """
    try:
        for name, v in (("risk", risk), ("danger", danger), ("near", near), ("max-gap", max_gap)):
            if not math.isfinite(v):
                raise AnalysisError(f"--{name} must be finite")
        th = Thresholds(risk_m=risk, danger_m=danger, near_m=near)
        tr = read_trajectory(log)
        t0 = float(tr.time_s.min())
        counted = "every sample (--ground)"
        if not ground:
            mask, counted = airborne_mask(log, len(tr.time_s))
            if mask is not None:
                tr = _masked(tr, mask)
                if len(set(tr.vehicle.tolist())) < 2:
                    raise AnalysisError(
                        f"{log}: fewer than two vehicles airborne (--ground counts the samples "
                        "on the ground too)"
                    )
        report = since(
            analyze(tr, th, vehicles=_vehicles(vehicles), step_s=step, max_gap_s=max_gap), t0
        )
    except (TrajectoryError, AnalysisError) as exc:
        raise _fail(str(exc)) from None
    except OSError as exc:
        raise _fail(f"{log}: cannot read: {exc.strerror or exc}") from None
    if png is not None:
        try:
            draw(report, png)
        except (OSError, ValueError) as exc:
            raise _fail(f"{png}: cannot write: {exc}") from None
    if as_json:
        typer.echo(json.dumps({**report.as_dict(), "t0_s": t0, "counted": counted}, indent=2))
        return
    Console().print(table(report, log.name, counted))


def table(report: SeparationReport, title: str, counted: str = "") -> Table:
    th = report.thresholds
    t = Table(
        title=f"separation: {title}",
        caption=(
            f"risk {th.danger_m:g}-{th.risk_m:g} m, danger {th.near_m:g}-{th.danger_m:g} m, "
            f"near-collision < {th.near_m:g} m (samples); Time_s from the log's first sample"
            + (f"; {counted}" if counted else "")
        ),
    )
    for name in ("Pair", "MinDistance_m", "Time_s", "Risk", "Danger", "Near", "Samples"):
        t.add_column(name, justify="left" if name == "Pair" else "right", no_wrap=True)
    for p in report.pairs:
        t.add_row(
            f"{p.a}-{p.b}",
            "-" if not p.samples else f"{p.min_m:.2f}",
            "-" if not p.samples else f"{p.min_time_s:.2f}",
            str(p.risk),
            str(p.danger),
            str(p.near),
            str(p.samples),
        )
    tot = report.totals()
    t.add_row(
        "all",
        f"{report.min_sep_m:.2f}",
        "",
        str(tot["risk"]),
        str(tot["danger"]),
        str(tot["near"]),
        str(tot["samples"]),
        style="bold",
    )
    return t


def draw(report: SeparationReport, path: Path) -> None:
    """Top: per pair, when each sample was in the risk / danger / near band (as the
    paper's event maps). Bottom: every pair's distance over time with the bands."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    th = report.thresholds
    pairs = report.pairs
    rows_in = max(1.2, 0.16 * len(pairs))
    fig, (top, bottom) = plt.subplots(
        2, 1, figsize=(10, rows_in + 4.5), height_ratios=(rows_in, 3.5), sharex=True
    )
    colours = {"risk": "#f2c14e", "danger": "#f08a24", "near": "#d62828"}
    for row, p in enumerate(pairs):
        d, t = p.distances_m, p.times_s
        for band, mask in (
            ("risk", (d >= th.danger_m) & (d < th.risk_m)),
            ("danger", (d >= th.near_m) & (d < th.danger_m)),
            ("near", d < th.near_m),
        ):
            if mask.any():
                top.scatter(t[mask], [row] * int(mask.sum()), s=12, c=colours[band], marker="|")
        bottom.plot(t, np.maximum(d, 0.1), linewidth=0.8, label=f"{p.a}-{p.b}")
    top.set_yticks(range(len(pairs)), [f"{p.a}-{p.b}" for p in pairs])
    top.set_title("events per pair (risk / danger / near-collision)")
    for band, c in colours.items():
        top.scatter([], [], c=c, marker="s", label=band)
    top.legend(loc="upper right", fontsize="small")
    for y, c in ((th.risk_m, "risk"), (th.danger_m, "danger"), (th.near_m, "near")):
        bottom.axhline(y, color=colours[c], linestyle="--", linewidth=0.8)
    bottom.set_yscale("log")  # distances under 0.1 m drawn at 0.1
    bottom.set_xlabel("time from the log's first sample, s")
    bottom.set_ylabel("3-D distance, m")
    if len(pairs) <= 15:
        bottom.legend(fontsize="x-small", ncol=3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
