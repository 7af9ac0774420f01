"""`gcs plot` piled every sortie's track into one picture, and an operating area around
the field zoomed a 30 m target orbit out of sight. Now it draws the last sortie of a
flight record (--all-sorties every one) and frames what is planned and flown, the
zones drawn where they fall in it (the picture's georeference says where it looks)."""

from __future__ import annotations

from pathlib import Path

import msgspec
import pytest

from gcs_cli.app import run
from gcs_cli.plot import EXTRA, read_georeference, sorties
from gcs_cli.recovery import SwarmState, VehicleState
from swarm_proto import (
    Geometry,
    GeoPoint,
    Mission,
    MissionParams,
    MissionType,
    NoFlyZone,
    VehicleType,
)
from swarm_proto.trajectory import TrajectoryWriter, read_trajectory

LAT, LON = 37.4112, -5.9889
M_LON = 1 / (111_320.0 * 0.7944)  # degrees of longitude per metre here


def record(path: Path, flights: list[tuple[float, float]]) -> None:
    """Vehicles 7 and 8 flying east `east_m` from t0 for 60 s each, on the ground
    (alt_rel_m 0, disarmed) 100 s before and between."""
    with TrajectoryWriter(path, EXTRA) as w:
        t = 1.7958e9
        for start, east in flights:
            for k in range(100):  # on the pads
                for vid in (7, 8):
                    w.write(
                        t + start - 100 + k,
                        vid,
                        LAT,
                        LON + vid * 1e-5,
                        10.0,
                        0.0,
                        0,
                        0,
                        90,
                        "A",
                        "B",
                        0,
                        0,
                    )
            for k in range(60):
                for vid in (7, 8):
                    lon = LON + (east * k / 60) * M_LON + vid * 1e-5
                    w.write(t + start + k, vid, LAT, lon, 40.0, 30.0, 5, 90, 80, "A", "B", 0, 1)


def view(png: Path) -> dict:
    import json

    from PIL import Image

    with Image.open(png) as img:
        return dict(json.loads(img.info["Description"]))


def test_sorties_are_the_airborne_stretches(tmp_path: Path) -> None:
    from gcs_cli.analyze import airborne_mask

    log = tmp_path / "two.csv"
    record(log, [(0.0, 500.0), (400.0, 50.0)])
    tr = read_trajectory(log)
    mask, _ = airborne_mask(log, len(tr.time_s))
    found = sorties(tr, mask)
    assert [round(b - a) for a, b in found] == [59, 59], found
    assert round(found[1][0] - found[0][0]) == 400
    assert len(sorties(tr)) == 2  # without heights: the record's gap of 240 s
    assert len(sorties(tr, mask & False)) == 0


def test_the_last_sortie_by_default_and_every_one_when_asked(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    log = tmp_path / "two.csv"
    record(log, [(0.0, 500.0), (400.0, 50.0)])
    last, every = tmp_path / "last.png", tmp_path / "all.png"
    assert run(["plot", "--offline", "--track", str(log), "--out", str(last)]) == 0
    assert "the last of 2 sorties (59 s); --all-sorties draws every one" in capsys.readouterr().out
    assert (
        run(["plot", "--offline", "--track", str(log), "--out", str(every), "--all-sorties"]) == 0
    )

    def width(png: Path) -> float:
        read_georeference(png)  # a picture `gcs plot` made: it says where it looks
        return view(png)["xlim_m"][1] - view(png)["xlim_m"][0]

    assert width(last) < 200.0 < 500.0 < width(every), (width(last), width(every))


def test_an_operating_area_does_not_zoom_an_orbit_out_of_sight(
    tmp_path: Path, swarm_db: Path
) -> None:
    orbit = Mission(
        5,
        900,
        MissionType.TARGET,
        Geometry.circle(LAT + 0.0005, LON, 30.0),
        MissionParams(altitude_rel_m=40.0),
    )
    area = NoFlyZone(
        9,
        Geometry.polygon([(37.39, -6.01), (37.39, -5.96), (37.43, -5.96), (37.43, -6.01)]),
        operating_area=True,
    )
    home = GeoPoint(LAT, LON, 10.0)
    state = SwarmState(
        base=home,
        zones=[area],
        missions=[orbit],
        vehicles=[VehicleState(7, VehicleType.COPTER, home=home, mission_id=0)],
    )
    f = tmp_path / "state.json"
    f.write_bytes(msgspec.json.encode(state))
    png = tmp_path / "orbit.png"
    assert run(["plot", "--offline", "--state", str(f), "--out", str(png)]) == 0
    g = view(png)
    span = max(g["xlim_m"][1] - g["xlim_m"][0], g["ylim_m"][1] - g["ylim_m"][0])
    assert span < 250.0, g  # the 4 km area would have made it 4,000 m
