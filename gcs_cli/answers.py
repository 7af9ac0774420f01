"""Every answer shown: one row per addressed vehicle (accepted, rejected with its full
reason, or silent with why it may be), the vehicles not addressed and those absent on
one line each, a summary line, and the exit code (0 only when every addressed vehicle
accepted). A progress line on the terminal while the ground station waits."""

from __future__ import annotations

import json
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

import msgspec
import typer
from rich import box
from rich.console import Console
from rich.table import Table

from .core.exchange import Exchange, Outcome, Verdict
from .core.reasons import reason_text

err_console = Console(stderr=True)


def outcome_table(out: Outcome) -> Table:
    table = Table(
        title=out.request.what or None, box=box.SIMPLE_HEAD, pad_edge=False, title_justify="left"
    )
    table.add_column("vehicle", justify="right", no_wrap=True)
    table.add_column("answer", no_wrap=True)
    table.add_column("reason", no_wrap=True)
    table.add_column("why", overflow="fold", max_width=70)
    for r in out.rows:
        notes = "; ".join(r.notes)
        if r.ack is None:
            why = f"no answer in {out.elapsed_s:.1f} s" + (f" ({notes})" if notes else "")
            table.add_row(str(r.vehicle_id), "silent", "-", why, style="yellow")
            continue
        why = reason_text(r.ack.reason, r.ack.text, r.ack.detail)
        if notes:
            why = f"{why} ({notes})" if why else notes
        ok = r.verdict == Verdict.ACCEPTED
        table.add_row(
            str(r.vehicle_id),
            "yes" if ok else "NO",
            r.ack.reason.name,
            why,
            style=None if ok else "red",
        )
    return table


def summary(out: Outcome) -> str:
    n = len(out.rows)
    what = out.request.what or "request"
    if not n:
        return f"{what}: no vehicle addressed answered or is alive"
    parts = [f"{out.count(Verdict.ACCEPTED)} accepted"]
    if out.count(Verdict.REJECTED):
        parts.append(f"{out.count(Verdict.REJECTED)} rejected")
    if out.count(Verdict.SILENT):
        parts.append(f"{out.count(Verdict.SILENT)} silent")
    return f"{what}: {', '.join(parts)} of {n} addressed ({out.elapsed_s:.1f} s)"


def outcome_json(out: Outcome) -> dict[str, Any]:
    return {
        "what": out.request.what,
        "ok": out.ok,
        "elapsed_s": out.elapsed_s,
        "copies_sent": out.copies,
        "vehicles": [
            {
                "id": r.vehicle_id,
                "answer": r.verdict.value,
                "reason": r.ack.reason.name if r.ack else None,
                "text": r.ack.text if r.ack else "",
                "why": reason_text(r.ack.reason, r.ack.text, r.ack.detail) if r.ack else "",
                "detail": msgspec.to_builtins(r.ack.detail) if r.ack and r.ack.detail else None,
                "notes": list(r.notes),
            }
            for r in out.rows
        ],
        "not_addressed": list(out.not_addressed),
        "absent": list(out.absent),
        "undetermined": list(out.undetermined),
    }


def report(out: Outcome, console: Console, *, as_json: bool = False) -> None:
    """Print the outcome and exit 1 unless every addressed vehicle accepted."""
    if as_json:
        typer.echo(json.dumps(outcome_json(out), indent=2))
    else:
        if out.rows:
            console.print(outcome_table(out))
        if out.not_addressed:
            console.print(f"not addressed: {', '.join(map(str, out.not_addressed))}", style="dim")
        if out.absent:
            console.print(
                "in the swarm database, not alive: " + ", ".join(map(str, out.absent)), style="dim"
            )
        if out.undetermined:
            console.print(
                "alive, fleet never heard (may be addressed): "
                + ", ".join(map(str, out.undetermined)),
                style="yellow",
            )
        console.print(summary(out), style=None if out.ok else "bold red")
    if not out.ok:
        raise typer.Exit(out.exit_code)


@contextmanager
def progress(enabled: bool = True) -> Iterator[Callable[[Exchange, float], None]]:
    """A status line on the terminal (stderr) while waiting: who answered, who is
    awaited, time left. Nothing when stderr is not a terminal."""
    if not enabled or not err_console.is_terminal:
        yield lambda ex, now: None
        return
    with err_console.status("sending") as status:

        def update(ex: Exchange, now: float) -> None:
            waiting = ex.waiting_for()
            shown = ", ".join(map(str, waiting[:12])) + (" ..." if len(waiting) > 12 else "")
            status.update(
                f"{ex.request.what}: {len(ex.answers)} answered"
                + (f", waiting for {shown}" if waiting else "")
                + f" ({max(0.0, ex.end - now):.0f} s left, copy {ex.copies})"
            )

        yield update
