"""`make demo`'s figures: the paper's experiment 1 flown by the real stack, as
`swarm-sim demo` flies it (six simulated Albatross VTOLs on TCP, one `swarm-node run`
process each, Zenoh on 127.0.0.1, the ground station's script, 5x real time), measured
from its report.json:

- `wall_s`, `sim_s`: wall seconds the whole story took (fleet start to report) and the
  simulated seconds from the base being set to the last landing;
- `coverage`: the survey area (less the zones grown by the planner's margin) under the
  flown tracks' camera swath; `missions_completed` (of `missions_total`: the survey,
  the target, the perimeter, the route);
- `near`, `danger`, `min_sep_m`: the paper's separation analysis once airborne
  (samples < 5 m, 5-10 m, the closest pair);
- `load_avg_1min`: the machine's load when the run ended (the demo shares it).

In the same run, the same story in fast time (`fast_time`: FastFleet, the node cores
and simulated vehicles in one process, deterministic) and, as the baseline, the same
fast-time story with the nodes' collision avoidance and pad sequencing off
(`baseline_no_avoidance`: what the demo would fly without them).
"""

from __future__ import annotations

import io
import tempfile
from pathlib import Path
from typing import Any

from rich.console import Console

from swarm_node.core.node import NodeSettings
from swarm_node.database import SwarmDatabase
from swarm_sim.core import SITL_HOME
from swarm_sim.demo_report import fast_report
from swarm_sim.experiment import DEFAULT_SPEEDUP, EXPERIMENT_FLEET
from swarm_sim.experiment import run as run_demo
from swarm_sim.story import StoryPlan

FIGURES = ("wall_s", "sim_s", "coverage", "missions_completed", "missions_total", "load_avg_1min")


def _figures(report: dict[str, Any]) -> dict[str, Any]:
    sep = report["separation"]
    out = {k: report.get(k) for k in FIGURES}
    out.update(
        near=sep["near"],
        danger=sep["danger"],
        risk=sep["risk"],
        min_sep_m=sep["min_sep_m"],
        ok=report["ok"],
        failures=report["failures"],
    )
    return out


def real(out: Path) -> dict[str, Any]:
    import json

    code = run_demo(
        EXPERIMENT_FLEET,
        speedup=DEFAULT_SPEEDUP,
        out=out,
        console=Console(file=io.StringIO(), width=140),
    )
    report: dict[str, Any] = json.loads((out / "report.json").read_text())
    return {**_figures(report), "exit_code": code}


def fast(out: Path, *, avoidance: bool = True) -> dict[str, Any]:
    with SwarmDatabase.memory() as db:
        profiles = {v: db.vehicle_profile(v) for v in EXPERIMENT_FLEET}
    plan = StoryPlan.experiment_one(EXPERIMENT_FLEET, (SITL_HOME.lat_deg, SITL_HOME.lon_deg))
    settings = NodeSettings(avoidance=avoidance)
    return _figures(fast_report(plan, profiles, out, pictures=False, settings=settings))


def run() -> dict[str, Any]:
    with tempfile.TemporaryDirectory(prefix="bench-demo-") as tmp:
        figures = real(Path(tmp) / "real")
        figures["fast_time"] = fast(Path(tmp) / "fast")
        figures["baseline_no_avoidance"] = fast(Path(tmp) / "off", avoidance=False)
    figures["setup"] = (
        f"swarm-sim demo: vehicles 1-6 (Albatross 250 VTOL), pads 30 m apart, "
        f"{DEFAULT_SPEEDUP:g}x real time, Zenoh on 127.0.0.1; fast_time and the "
        "baseline: the same story in FastFleet"
    )
    return figures
