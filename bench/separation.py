"""Separation figures (issue 14): the avoidance core's cost per 5 Hz tick, and the
stress scenario (8 fixed-wing converging head-on from a 1 km circle at one altitude)
with avoidance on and off, analysed as the paper does (risk 10-40 m, danger 5-10 m,
near-collision < 5 m samples over the whole flight).

The scenario runs in the point-mass simulation (`swarm_sim.core.pointmass`): constant
ground velocity, climb 5 m/s, sink 3 m/s, peers' telemetry at 5 Hz; its trajectory
goes through the flight recorder CSV and `gcs analyze separation`'s analysis.
"""

from __future__ import annotations

import math
import tempfile
from pathlib import Path
from typing import Any

import pymap3d

from gcs_cli.separation import analyze
from swarm_node.core.safety.avoidance import AvoidanceConfig, CollisionAvoider
from swarm_proto import VehicleStatus, VehicleType
from swarm_proto.trajectory import TrajectoryWriter, read_trajectory
from swarm_sim.core.pointmass import ORIGIN, stress_eight_headon
from swarm_sim.core.pointmass import run as simulate

from .common import time_us

T = 1_700_000_000.0


def _status(vid: int, e: float, n: float, up: float, ve: float, vn: float) -> VehicleStatus:
    lat0, lon0, h0 = ORIGIN
    lat, lon, h = pymap3d.enu2geodetic(e, n, up, lat0, lon0, h0)
    return VehicleStatus(
        vehicle_id=vid,
        time_unix_s=T,
        lat_deg=float(lat),
        lon_deg=float(lon),
        alt_msl_m=float(h),
        alt_rel_m=up,
        vel_north_m_s=vn,
        vel_east_m_s=ve,
        armed=True,
    )


def cpu_per_tick(peers: int) -> float:
    """Microseconds per on_timer with `peers` aircraft on a 1 km circle (diameter) converging on
    the own vehicle (every pair in conflict: the worst case for the stacking)."""
    av = CollisionAvoider(AvoidanceConfig(peers + 1, VehicleType.PLANE))
    av.handle(_status(peers + 1, 0, 0, 110, 0, 0), T)  # the highest: it climbs
    for i in range(peers):
        ang = 2 * math.pi * i / peers
        e, n = 500 * math.cos(ang), 500 * math.sin(ang)
        av.handle(_status(i + 1, e, n, 100 + (i % 7), -20 * math.cos(ang), -20 * math.sin(ang)), T)

    def tick() -> None:
        # the same instant every time: fresh data, every pair decided from scratch
        av._next, av._active = T, None
        av.on_timer(T)

    assert av.on_timer(T), "the bench geometry must be a conflict"
    return time_us(tick, repeat=5, number=50)


def scenario(avoid: bool) -> dict[str, Any]:
    result = simulate(stress_eight_headon(), duration_s=70.0, avoid=avoid)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "stress.csv"
        with TrajectoryWriter(path) as w:
            w.write_rows(result.samples)
        report = analyze(read_trajectory(path))
    tot = report.totals()
    return {
        "min_sep_m": round(report.min_sep_m, 2),
        "risk": tot["risk"],
        "danger": tot["danger"],
        "near": tot["near"],
        "pair_samples": tot["samples"],
        "manoeuvres": sum(len(v) for v in result.manoeuvres.values()),
    }


def run() -> dict[str, Any]:
    return {
        "avoid_cpu_us_per_tick": {
            "peers_10": cpu_per_tick(10),
            "peers_50": cpu_per_tick(50),
        },
        "stress_eight_headon": {
            "on": scenario(True),
            "off": scenario(False),
            "setup": "8 PLANE, radius 500 m, 20 m/s, 100 m, climb 5 m/s, 70 s, samples 0.2 s",
        },
        "not_measured": (
            "exp1_six_vtol and exp2_takeoff_three_vtol need the FastFleet scenarios and "
            "take-off deconfliction (issue 14 parts 3 and 6), not built yet"
        ),
    }
