"""The stress gate: `make test-stress` or `make bench BENCH=test_stress`.

`make test` five times in a row, each from a fresh clone of the committed HEAD (its own
`.venv`, so the install is part of every run), with one core kept busy all along by a
background process (`python3 -c 'while True: pass'`, at this process's priority). What
it measures is what CI runs: the Makefile's own steps. Each clone has ../shared linked
beside it, as in a checkout. Per run: the exit code, the wall and CPU time, each step's
wall time (install, lint, typecheck, the suite, the timing tests), the load average at
its end and, if it failed, the tests that failed (the clone's output is kept in a log
whose path is printed). Figures: `failures` (runs that failed, must be 0) and
the median wall time (at most 6 minutes). STRESS_RUNS=n changes the number of runs.
"""

from __future__ import annotations

import os
import re
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parents[1]
SHARED = Path(os.environ.get("BANDADA_SHARED", REPO.parent / "shared"))
BUSY = "while True: pass"
# make test's milestones, each known by the line make echoes for it (whole lines: pip's own
# output names the packages it installs, ruff and mypy among them). The checks (ruff,
# mypy) run beside the suite, from "lint" to "checked"; the suite waits for nothing
MARKS = (
    ("lint", b"/bin/ruff check "),
    ("checked", b"checks passed\n"),
    ("collect", b"--collect-only"),
    ("suite", b'-m "not soak and not scale and not timing"'),
    ("timing", b'-m "timing and not soak and not scale"'),
)
FAILED = re.compile(r"^(?:FAILED|ERROR) (\S+)", re.MULTILINE)


def _children_cpu_s() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def _steps(at: dict[str, float], wall: float) -> dict[str, float]:
    """Each step's wall time from the milestones seen (a step whose ends were not both
    seen, as in a run that failed early, is left out)."""
    spans = {
        "install": (0.0, min(at.get("lint", wall), at.get("collect", wall))),
        "checks": (at.get("lint"), at.get("checked")),  # beside the collection and suite
        "collect": (at.get("collect"), at.get("suite")),
        "suite": (at.get("suite"), at.get("timing")),
        "timing": (at.get("timing"), wall if "timing" in at else None),
    }
    return {k: round(b - a, 1) for k, (a, b) in spans.items() if a is not None and b is not None}


def _one_run(commit: str, base: Path, i: int) -> dict[str, Any]:
    """A fresh clone of `commit` in `base`, `make test` in it; the clone removed after."""
    work = base / f"run{i}"
    checkout = work / "bandada"
    work.mkdir()
    (work / "shared").symlink_to(SHARED)
    subprocess.run(
        ["git", "clone", "--quiet", "--no-checkout", str(REPO), str(checkout)], check=True
    )
    subprocess.run(["git", "-C", str(checkout), "checkout", "--quiet", commit], check=True)
    log = base / f"run{i}.log"
    # CI's environment: no outer venv or make, and bytecode written (with
    # PYTHONDONTWRITEBYTECODE set, every node and gcs process the suite starts compiles
    # its imports again: pymavlink's dialects, numpy, the project)
    drop = ("VIRTUAL_ENV", "MAKEFLAGS", "MAKELEVEL", "PYTHONDONTWRITEBYTECODE")
    env = {k: v for k, v in os.environ.items() if k not in drop}
    cpu0, t0 = _children_cpu_s(), time.monotonic()
    at: dict[str, float] = {}
    with log.open("wb") as out:
        proc = subprocess.Popen(
            ["make", "test"],
            cwd=checkout,
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            env=env,
        )
        assert proc.stdout is not None
        for line in proc.stdout:  # each milestone: the line make echoes for it
            out.write(line)
            for name, marker in MARKS:
                if name not in at and marker in line:
                    at[name] = time.monotonic() - t0
        code = proc.wait()
    wall, cpu = time.monotonic() - t0, _children_cpu_s() - cpu0
    steps_s = _steps(at, wall)
    load = os.getloadavg()
    text = log.read_text(errors="replace")
    shutil.rmtree(work, ignore_errors=True)  # its .venv is over a gigabyte
    row = {
        "run": i + 1,
        "exit": code,
        "wall_s": round(wall, 1),
        "cpu_s": round(cpu, 1),
        "load_1_5_15": [round(x, 2) for x in load],
        "steps_s": steps_s,
        "failed": sorted(set(FAILED.findall(text))),
        "log": str(log),
    }
    print(
        f"run {i + 1}: exit {code}, {wall:.0f} s wall, {cpu:.0f} s CPU, load {load[0]:.1f}",
        flush=True,
    )
    return row


def run() -> dict[str, Any]:
    if not SHARED.is_dir():
        raise SystemExit(f"../shared not found at {SHARED}")
    runs = int(os.environ.get("STRESS_RUNS", "5"))
    commit = subprocess.run(
        ["git", "-C", str(REPO), "rev-parse", "HEAD"], check=True, capture_output=True, text=True
    ).stdout.strip()
    dirty = subprocess.run(
        ["git", "-C", str(REPO), "status", "--porcelain", "--untracked-files=no"],
        check=True,
        capture_output=True,
        text=True,
    ).stdout.strip()
    if dirty:
        print("note: uncommitted changes are not in the clones (HEAD is tested)", flush=True)
    base = Path(tempfile.mkdtemp(prefix="bandada-stress-"))
    print(f"logs in {base}", flush=True)
    busy = subprocess.Popen([sys.executable, "-c", BUSY])
    try:
        rows = [_one_run(commit, base, i) for i in range(runs)]
    finally:
        busy.kill()
        busy.wait()
    walls = [r["wall_s"] for r in rows]
    return {
        "command": "make test-stress",
        "what": "make test from a fresh clone (install included), one core kept busy",
        "background": f"{Path(sys.executable).name} -c '{BUSY}'",
        "commit": commit,
        "cpus": os.cpu_count(),
        "runs": runs,
        "failures": sum(r["exit"] != 0 for r in rows),
        "wall_s": walls,
        "median_wall_s": round(statistics.median(walls), 1),
        "max_wall_s": max(walls),
        "cpu_s": [r["cpu_s"] for r in rows],
        "median_steps_s": {
            step: statistics.median(r["steps_s"].get(step, 0.0) for r in rows)
            for step in ("install", "checks", "collect", "suite", "timing")
        },
        "load_1_5_15": [r["load_1_5_15"] for r in rows],
        "per_run": rows,
    }
