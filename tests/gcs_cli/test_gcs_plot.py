"""`gcs plot` from a flight: two simulated quadcopters with their node cores fly a
survey around a no-fly zone in fast time (FastFleet: real MAVLink bytes); the flight
recorder CSV and the swarm state give the picture, checked for its content: each
vehicle's planned share is what its node planned, each vehicle's color, the zone and
the base are in the PNG, and the flown tracks add to it."""

from __future__ import annotations

from pathlib import Path

import msgspec
import numpy as np
import pytest

from gcs_cli.app import run
from gcs_cli.plot import plan_shares, vehicle_colors
from gcs_cli.recovery import SwarmState, VehicleState
from swarm_proto import (
    Command,
    CommandArgs,
    CommandKind,
    FsmState,
    Geometry,
    GeoPoint,
    Mission,
    MissionParams,
    MissionType,
    NoFlyZone,
    Selector,
)
from swarm_sim.core import SITL_HOME
from swarm_sim.demo import offset
from swarm_sim.fast_fleet import FastFleet
from swarm_sim.recording import status_rows, write_trajectory

GCS = 900
IDS = (7, 8)

# the tests share one flight (a module fixture): on one worker it is flown once
pytestmark = pytest.mark.xdist_group("gcs-plot")


@pytest.fixture(scope="module")
def flight(
    tmp_path_factory: pytest.TempPathFactory, fleet_profiles: dict
) -> tuple[Path, Path, dict]:
    tmp = tmp_path_factory.mktemp("plot")
    fleet = FastFleet.build(list(IDS), fleet_profiles)
    assert fleet.run_until(lambda: all(v.link.state.home for v in fleet.vehicles.values()), 60)
    base = GeoPoint(SITL_HOME.lat_deg, SITL_HOME.lon_deg, SITL_HOME.alt_m)
    fleet.broadcast(Command(GCS, 1, CommandKind.SET_BASE, Selector(), CommandArgs(point=base)))
    assert fleet.run_until(
        lambda: all(v.node.fsm.state != FsmState.INACTIVE for v in fleet.vehicles.values()), 60
    )
    lat0, lon0 = offset(SITL_HOME.lat_deg, SITL_HOME.lon_deg, 60.0, 0.0)
    field = Geometry.polygon(
        [offset(lat0, lon0, n, e) for n, e in ((0, -60), (0, 60), (100, 60), (100, -60))]
    )
    zlat, zlon = offset(lat0, lon0, 50.0, 0.0)
    zone = NoFlyZone(3, Geometry.circle(zlat, zlon, 15.0), -100.0, 500.0, issuer_id=GCS)
    fleet.broadcast(zone)
    mission = Mission(
        21,
        GCS,
        MissionType.AREA,
        field,
        MissionParams(altitude_rel_m=30.0, side_overlap=0.3),
        Selector.ids(*IDS),
    )
    fleet.broadcast(mission)
    fleet.run_for(150.0)  # simulated seconds: planned, took off, flew part of the survey
    v7 = fleet.vehicles[7]
    assert v7.node.manager.fleet_plan is not None and v7.node.mission_progress_pct > 0
    track = tmp / "flight.csv"
    assert write_trajectory(status_rows(fleet.published, t0=fleet.now - 150.0), track) > 100
    held = v7.node.manager.fleet_plan.mission  # as the nodes planned it (defaults filled)
    state = SwarmState(
        base=base,
        zones=[zone],
        missions=[held],
        saved_unix_s=fleet.now,
        vehicles=[
            VehicleState(
                vid,
                v.node.profile.vehicle_type,
                v.node.profile.model,
                home=v.node.autopilot.home,
                base=base,
                mission_id=21,
            )
            for vid, v in fleet.vehicles.items()
        ],
    )
    state_file = tmp / "state.json"
    state_file.write_bytes(msgspec.json.encode(state))
    nodes = {
        vid: [
            (w.lat_deg, w.lon_deg)
            for w in v.node.manager.fleet_plan.share(vid).waypoints  # type: ignore[union-attr]
            if w.lat_deg or w.lon_deg
        ]
        for vid, v in fleet.vehicles.items()
    }
    return state_file, track, nodes


def colored(png: Path, rgb: tuple[float, float, float], tol: float = 0.06) -> int:
    import matplotlib.image as mpimg

    img = np.asarray(mpimg.imread(png))[:, :, :3]
    return int((np.abs(img - np.array(rgb)).max(axis=2) < tol).sum())


def test_the_shares_drawn_are_what_the_nodes_planned(
    flight: tuple[Path, Path, dict], swarm_db: Path
) -> None:
    from gcs_cli.recovery import read_state

    state_file, _, nodes = flight
    state = read_state(state_file)
    shares = plan_shares(state, state.missions[0])
    assert set(shares) == set(IDS)
    for vid in IDS:
        flat = [x for p in shares[vid] for x in p]
        assert flat == pytest.approx([x for p in nodes[vid] for x in p], abs=1e-9), vid


def test_the_png_shows_plan_zone_base_and_tracks(
    flight: tuple[Path, Path, dict],
    swarm_db: Path,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    state_file, track, _ = flight
    plan_png, flown_png = tmp_path / "plan.png", tmp_path / "flown.png"
    assert run(["plot", "--offline", "--state", str(state_file), "--out", str(plan_png)]) == 0
    assert (
        run(
            [
                "plot",
                "--offline",
                "--state",
                str(state_file),
                "--track",
                str(track),
                "--out",
                str(flown_png),
            ]
        )
        == 0
    )
    out = " ".join(capsys.readouterr().out.split())
    assert "1 mission(s), 2 share(s), 1 zone(s), 2 track(s)" in out, out
    colors = vehicle_colors(IDS)
    for png in (plan_png, flown_png):
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        for vid in IDS:
            assert colored(png, colors[vid]) > 150, (png.name, vid)  # each vehicle's lines
        assert colored(png, (0.8, 0.0, 0.0)) > 30  # the zone's edge
        fill = colored(png, (0.8675, 0.5875, 0.5875), 0.05)  # its fill over the field's grey
        assert fill + colored(png, (0.965, 0.685, 0.685), 0.05) > 50
        assert colored(png, (1.0, 0.843, 0.0)) > 20  # the base's star
    for vid in IDS:  # the flown tracks (thicker, solid) add to each vehicle's color
        assert colored(flown_png, colors[vid]) > 1.3 * colored(plan_png, colors[vid]), vid


def test_tracks_alone_and_bad_tracks(
    flight: tuple[Path, Path, dict], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    _, track, _ = flight
    png = tmp_path / "t.png"
    assert run(["plot", "--offline", "--track", str(track), "--out", str(png)]) == 0
    assert all(colored(png, c) > 100 for c in vehicle_colors(IDS).values())
    bad = tmp_path / "bad.csv"
    bad.write_text("time_s,vehicle,lat,lon,alt_m\n1,7,nan,0,0\n")
    capsys.readouterr()
    assert run(["plot", "--offline", "--track", str(bad), "--out", str(png)]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "lat is nan" in err
