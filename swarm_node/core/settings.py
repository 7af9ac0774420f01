"""The node core's settings (NodeCore's; the runtime reads them from its configuration)."""

from __future__ import annotations

from dataclasses import dataclass

from .failsafe import COMPANION_TIMEOUT_S
from .fences import FENCE_MAX_ITEMS
from .monitoring import Thresholds


@dataclass(frozen=True)
class NodeSettings:
    status_period_s: float = 0.2  # 5 Hz
    info_period_s: float = 1.0  # 1 Hz
    plan_timeout_s: float = 60.0
    stale_after_s: float = 2.0
    info_stale_after_s: float = 5.0  # peers that send only VehicleInfo (ground stations)
    thresholds: Thresholds | None = None  # default: from the profile
    fence_max_items: int = FENCE_MAX_ITEMS  # what the autopilot's fence storage takes
    avoidance: bool = True  # collision avoidance (safety/module.py); off: compare without it
    # publish the own next legs (VehicleIntent) and predict peers along theirs; off:
    # straight-line prediction only (compare without it)
    intent: bool = True
    mav_sysid: int = 0  # the autopilot's MAVLink system id, from the database (0: not checked)
    # a member fallen silent keeps its share this long (its aircraft may fly it on
    # until its failsafe takes it home): docs/reliability.md
    silent_hold_s: float = COMPANION_TIMEOUT_S + 5.0
