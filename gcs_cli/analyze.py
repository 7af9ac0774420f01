"""`gcs analyze`: offline analyses of recorded flights.

    gcs analyze separation LOG.csv [--json] [--png FILE] [--risk 40 --danger 10 --near 5]
                                   [--vehicles 1,2,3] [--step S] [--max-gap S]

LOG.csv is a flight recorder trajectory (`time_s,vehicle,lat,lon,alt_m`, see
swarm_proto/trajectory.py). Exit status: 0 ok, 2 bad input (one line on stderr).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import typer
from rich.console import Console
from rich.table import Table

from swarm_proto.trajectory import TrajectoryError, read_trajectory

from .separation import AnalysisError, SeparationReport, Thresholds, analyze

app = typer.Typer(help="Offline analyses of recorded flights.", no_args_is_help=True)


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
) -> None:
    """Pairwise 3-D separation, minimum and risk / danger / near-collision counts
    (the paper's tables 2 and 3).

    Example: gcs analyze separation flight.csv --png separation.png
    """
    try:
        for name, v in (("risk", risk), ("danger", danger), ("near", near), ("max-gap", max_gap)):
            if not math.isfinite(v):
                raise AnalysisError(f"--{name} must be finite")
        th = Thresholds(risk_m=risk, danger_m=danger, near_m=near)
        report = analyze(
            read_trajectory(log), th, vehicles=_vehicles(vehicles), step_s=step, max_gap_s=max_gap
        )
    except (TrajectoryError, AnalysisError) as exc:
        raise _fail(str(exc)) from None
    if png is not None:
        try:
            draw(report, png)
        except (OSError, ValueError) as exc:
            raise _fail(f"{png}: cannot write: {exc}") from None
    if as_json:
        typer.echo(json.dumps(report.as_dict(), indent=2))
        return
    Console().print(table(report, log.name))


def table(report: SeparationReport, title: str) -> Table:
    th = report.thresholds
    t = Table(
        title=f"separation: {title}",
        caption=(
            f"risk {th.danger_m:g}-{th.risk_m:g} m, danger {th.near_m:g}-{th.danger_m:g} m, "
            f"near-collision < {th.near_m:g} m (samples)"
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
    bottom.set_xlabel("time, s")
    bottom.set_ylabel("3-D distance, m")
    if len(pairs) <= 15:
        bottom.legend(fontsize="x-small", ncol=3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
