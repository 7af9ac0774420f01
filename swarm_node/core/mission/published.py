"""What every member plans from: what a vehicle publishes, as its receivers hear it.

Every member of a fleet plans the whole fleet alone, so the plans agree only if the
inputs are the same on every node to the last bit: the area split is not continuous in
them (which lane a boundary cuts, which vehicle takes which block of lanes among
near-equal makespans), and a centimetre can tip it. A peer's progress and home arrive in
its VehicleInfo, over the radio at the radio's fixed-point resolution (`swarm_proto.radio`:
0.01 m for distances, 1e-7 degrees, 0.25 m). A node that used its own values at full
precision beside its peers' at radio resolution planned from other inputs than they did:
in a `--radio` demo the survivors of a loss each flew a share of a different plan (two of
them the same lanes, the middle of the field nobody's). So a vehicle publishes these
values on the radio's grid (its LAN receivers hear the same as its radio receivers) and
plans from what it publishes, with the formula its peers use (`along_share`). The
replan's inputs themselves (each member's metres along its share, each survivor's
modelled battery) are put on the grid of the `PlanLineage` that carries them, so a
vehicle that joins the fleet over the radio replays the fleet's plan exactly.

Pure: no I/O, no clock.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Mapping

from swarm_proto import GeoPoint, LineageBattery, LineageProgress, VehicleInfo
from swarm_proto.radio import on_air

#: the published distances' range (VehicleInfo's DistanceM)
MAX_DISTANCE_M = 1.0e6


def _distance(x: float) -> float:
    x = 0.0 if not math.isfinite(x) else min(max(x, 0.0), MAX_DISTANCE_M)
    return float(on_air(VehicleInfo, "mission_progress_m", x))


def published_progress(progress_m: float, path_m: float) -> tuple[float, float]:
    """A sortie's (progress_m, path_m) as VehicleInfo carries them (clamped to the
    field's range, NaN as 0, on the radio's grid): what every member hears."""
    return _distance(progress_m), _distance(path_m)


@functools.lru_cache(maxsize=64)
def published_home(home: GeoPoint | None) -> GeoPoint | None:
    """An autopilot home as VehicleInfo carries it (on the radio's grid)."""
    if home is None:
        return None
    out = on_air(VehicleInfo, "home", home)
    assert out is None or isinstance(out, GeoPoint)
    return out


def along_share(share_length_m: float, progress_m: float, path_m: float) -> tuple[float, float]:
    """A member's (metres along its share of the fleet plan, metres it flew before the
    plan's last replan) from its published progress and path (path = metres before the
    share + the share's length; (0, 0): nothing heard). The one formula for every member,
    this vehicle included."""
    if path_m <= 0.0:
        return 0.0, 0.0
    before = path_m - share_length_m
    done = min(max(progress_m - before, 0.0), share_length_m)
    return float(on_air(LineageProgress, "progress_m", done)), max(before, 0.0)


def lineage_battery(battery_pct: Mapping[int, float]) -> dict[int, float]:
    """The survivors' modelled battery as a `PlanLineage` carries it (on its grid)."""
    return {
        v: float(on_air(LineageBattery, "battery_pct", min(max(b, 0.0), 100.0)))
        for v, b in sorted(battery_pct.items())
        if math.isfinite(b)
    }


__all__ = [
    "MAX_DISTANCE_M",
    "along_share",
    "lineage_battery",
    "published_home",
    "published_progress",
]
