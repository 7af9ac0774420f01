"""Simulator flight recording: a FastFleet's published statuses and a point-mass run
become trajectory CSVs that `gcs analyze separation` reads."""

from __future__ import annotations

from pathlib import Path

from gcs_cli.separation import analyze
from swarm_proto import VehicleStatus
from swarm_proto.trajectory import read_trajectory
from swarm_sim.core.pointmass import run, stress_eight_headon
from swarm_sim.fast_fleet import FastFleet
from swarm_sim.recording import status_rows, write_trajectory


def test_fast_fleet_statuses_are_recorded(fleet_profiles: dict, tmp_path: Path) -> None:
    fleet = FastFleet.build([7, 8], fleet_profiles, spacing_m=40.0)
    fleet.run_until(lambda: all(v.link.state.ekf_has_position for v in fleet.vehicles.values()), 60)
    t0 = fleet.now
    fleet.published.clear()
    fleet.run_for(3.0)
    rows = status_rows(fleet.published, t0=t0)
    statuses = [m for _, _, m in fleet.published if isinstance(m, VehicleStatus)]
    assert len(rows) == len(statuses) > 10
    path = tmp_path / "fleet.csv"
    assert write_trajectory(rows, path) == len(rows)
    tr = read_trajectory(path)
    assert tr.vehicles == [7, 8] and tr.time_s.min() >= 0.0 and tr.time_s.max() <= 3.0
    (pair,) = analyze(tr, step_s=0.2).pairs
    assert 35.0 < pair.min_m < 45.0  # homes 40 m apart, on the ground


def test_point_mass_runs_are_recorded(tmp_path: Path) -> None:
    result = run(stress_eight_headon(), duration_s=2.0, avoid=False)
    path = tmp_path / "pm.csv"
    write_trajectory(result.samples, path)
    tr = read_trajectory(path)
    assert tr.vehicles == list(range(1, 9)) and len(tr.time_s) == 8 * 11
