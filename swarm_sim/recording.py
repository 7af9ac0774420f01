"""Flight recorder for simulations: trajectory rows (`time_s,vehicle,lat,lon,alt_m`, see
swarm_proto/trajectory.py) from what a FastFleet's nodes published, or from a
point-mass run, written with the same writer the node uses.

    rows = status_rows(fleet.published, t0=start_unix_s)
    write_trajectory(rows, "flight.csv")      # then: gcs analyze separation flight.csv
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from pathlib import Path

import msgspec

from swarm_proto import VehicleStatus
from swarm_proto.trajectory import TrajectoryWriter

Row = tuple[float, int, float, float, float]  # time_s, vehicle, lat, lon, alt_m


AIRBORNE_M = 1.0  # a vehicle higher than this above its home (and armed) is airborne


def status_rows(
    published: Iterable[tuple[float, int, msgspec.Struct]],
    *,
    t0: float = 0.0,
    airborne_only: bool = False,
) -> list[Row]:
    """One row per VehicleStatus published, at the simulated time it was published
    (seconds since `t0`), the vehicle's own report of where it was. `airborne_only`:
    only while armed and more than AIRBORNE_M above its home (pairs with a vehicle on
    the ground are then not counted: "once airborne")."""
    return [
        (now - t0, msg.vehicle_id, msg.lat_deg, msg.lon_deg, msg.alt_msl_m)
        for now, _vid, msg in published
        if isinstance(msg, VehicleStatus)
        and now >= t0
        and (not airborne_only or (msg.armed and msg.alt_rel_m > AIRBORNE_M))
    ]


def write_trajectory(rows: Sequence[Row], path: Path | str) -> int:
    """Write rows to a trajectory CSV; returns how many."""
    with TrajectoryWriter(path) as w:
        w.write_rows(rows)
        return w.rows
