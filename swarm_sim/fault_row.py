"""One row of the fault campaign (swarm_sim/faults.py in FastFleet,
swarm_sim/fault_processes.py over real processes): what a fault did to one mission."""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass
class FaultRow:
    fault: str
    mission: str
    env: str  # "fast" (FastFleet) | "processes"
    recovered: bool
    recover_s: float | None  # simulated seconds, fault -> its recovery event
    coverage: float
    mission_completed: bool
    declared_state_lost: int
    false_emergencies: int  # emergencies whose condition did not hold (a link loss judged)
    # arms of a vehicle after its autopilot rebooted, with no operator declaration since
    unexpected_arms: int = 0
    # the closest two aircraft came, from the simulator's true positions (None: not
    # measured)
    min_true_sep_m: float | None = None
    emergencies: dict[str, int] = field(
        default_factory=dict
    )  # every STATE_EMERGENCY: code (vehicle)
    alerts: dict[str, int] = field(default_factory=dict)  # "SEVERITY CODE" -> count
    note: str = ""
    wall_s: float = 0.0
