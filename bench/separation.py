"""Separation figures, with avoidance on (members' next legs shared: VehicleIntent), on
with straight-line prediction only (`on_no_intent`) and off, analysed as the paper
does (risk 10-40 m, danger 5-10 m, near-collision < 5 m samples over the whole flight):

- the paper's experiment 1 (`exp1_six_vtol`), experiment 2's simultaneous take-off
  (`exp2_takeoff_three_vtol`) and the stress case (`stress_eight_headon`, 8 fixed-wing
  converging head-on from a 1 km circle at one altitude), flown by FastFleet: simulated
  ArduPilot vehicles, the real autopilot link and node cores, real MAVLink bytes
  (`swarm_sim/separation.py`); each flight's trajectory goes through the flight
  recorder CSV and `gcs analyze separation`'s analysis. `airborne` counts only pairs
  with both vehicles in the air (pads 8 m apart are a danger-band pair on the ground);
- the paper's own figures beside them (tables 2 and 3);
- the avoidance core's cost per 5 Hz tick at 10 and 50 peers;
- the stress case again in the point-mass simulation (`swarm_sim.core.pointmass`:
  constant ground velocity, climb 5 m/s, sink 3 m/s, telemetry at 5 Hz), the baseline
  of the core alone.
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


def pointmass(avoid: bool) -> dict[str, Any]:
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


#: the paper's tables 2 (six VTOLs in SITL) and 3 (three VTOLs, real flight)
PAPER = {
    "exp1_six_vtol": {"min_sep_m": 8.09, "risk": 642, "danger": 4, "near": 0},
    "exp2_takeoff_three_vtol": {"min_sep_m": 2.04, "risk": 229, "danger": 616, "near": 210},
}
SETUP = {
    "exp1_six_vtol": "6 Albatross VTOL, pads 30 m apart; area by all six, re-tasked: "
    "target (1), perimeter (2, 3), route (4); no voting (listed vehicles)",
    "exp2_takeoff_three_vtol": "3 Albatross VTOL, pads 8 m apart in a line, one route "
    "mission released to all three at once",
    "stress_eight_headon": "8 fixed-wing (22 m/s), routes from a 1 km circle through its "
    "centre at 100 m, sent at once; the record ends when every route is flown",
}


def fleet_scenario(name: str) -> dict[str, Any]:
    from swarm_node.database import seed_fleet
    from swarm_sim.separation import RUNS

    profiles = {p.vehicle_id: p for p in seed_fleet()}
    out: dict[str, Any] = {}
    # avoidance on with the members' next legs shared (the default), on with
    # straight-line prediction only (no intent published or used), and off
    sides = (("on", True, True), ("on_no_intent", True, False), ("off", False, False))
    for side, avoid, intent in sides:
        r = RUNS[name](profiles, avoid=avoid, intent=intent)
        out[side] = {**r.figures(), "wall_s": round(r.wall_s, 1)}
    if name in PAPER:
        out["paper"] = PAPER[name]
    out["setup"] = SETUP[name]
    return out


def run() -> dict[str, Any]:
    return {
        "exp1_six_vtol": fleet_scenario("exp1_six_vtol"),
        "exp2_takeoff_three_vtol": fleet_scenario("exp2_takeoff_three_vtol"),
        "stress_eight_headon": fleet_scenario("stress_eight_headon"),
        "avoid_cpu_us_per_tick": {
            "peers_10": cpu_per_tick(10),
            "peers_50": cpu_per_tick(50),
        },
        "stress_eight_headon_pointmass": {
            "on": pointmass(True),
            "off": pointmass(False),
            "setup": "8 PLANE, radius 500 m, 20 m/s, 100 m, climb 5 m/s, 70 s, samples 0.2 s",
        },
    }
