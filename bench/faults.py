"""The fault campaign: `make faults` or `make bench BENCH=faults`.

Every fault of `swarm_sim.faults` x every mission in FastFleet (simulated time), and
the faults that need a real process, clock or file over real processes at 1x
(`swarm_sim.fault_processes`). One row per fault and mission: `recovered`, `recover_s`,
`coverage`, `declared_state_lost` (must be 0), `false_emergencies` (must be 0), the
emergencies and alerts raised, a note. The baseline is the row of fault "none" of each
mission, flown in the same run. `BANDADA_FAULTS=fast` (or `processes`) runs one part.
"""

from __future__ import annotations

import dataclasses
import os
from typing import Any


def run() -> dict[str, Any]:
    from swarm_node.database import seed_fleet
    from swarm_sim.fault_processes import campaign_processes
    from swarm_sim.faults import campaign_fast

    which = os.environ.get("BANDADA_FAULTS", "all")
    profiles = {p.vehicle_id: p for p in seed_fleet()}
    rows = []
    if which in ("all", "fast"):
        rows += campaign_fast(profiles)
    if which in ("all", "processes"):
        rows += campaign_processes()
    table = [dataclasses.asdict(r) for r in rows]
    faulty = [r for r in table if r["fault"] != "none"]
    return {
        "rows": table,
        "baseline": [r for r in table if r["fault"] == "none"],
        "faults": len(faulty),
        "recovered": sum(r["recovered"] for r in faulty),
        "declared_state_lost": sum(r["declared_state_lost"] for r in table),
        "false_emergencies": sum(r["false_emergencies"] for r in table),
        "coverage_min": min((r["coverage"] for r in table), default=0.0),
        # from the simulator's true positions: the closest two vehicles came in any row
        "min_true_sep_m": min(
            (r["min_true_sep_m"] for r in table if r["min_true_sep_m"] is not None),
            default=None,
        ),
        "unexpected_arms": sum(r["unexpected_arms"] for r in table),
    }
