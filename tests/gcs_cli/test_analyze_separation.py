"""`gcs analyze separation` and the trajectory CSV: counts and minima against distances
computed here independently (ECEF by hand from the WGS84 constants), and bad input."""

from __future__ import annotations

import itertools
import json
import math
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner, Result

from gcs_cli.app import app
from gcs_cli.separation import AnalysisError, Thresholds, analyze
from swarm_proto import VehicleStatus
from swarm_proto.trajectory import HEADER, TrajectoryError, TrajectoryWriter, parse_trajectory

A, F = 6378137.0, 1 / 298.257223563  # WGS84


def ecef(lat: float, lon: float, h: float) -> np.ndarray:
    e2 = F * (2 - F)
    la, lo = math.radians(lat), math.radians(lon)
    n = A / math.sqrt(1 - e2 * math.sin(la) ** 2)
    return np.array(
        [
            (n + h) * math.cos(la) * math.cos(lo),
            (n + h) * math.cos(la) * math.sin(lo),
            (n * (1 - e2) + h) * math.sin(la),
        ]
    )


def cli(*argv: str) -> Result:
    return CliRunner().invoke(app, ["analyze", "separation", *argv])


def three_vehicles(path: Path) -> list[tuple[float, int, float, float, float]]:
    """1 and 2 converge in latitude at one altitude, 3 far off and climbing."""
    rows = []
    for k in range(101):
        t = k * 0.5
        rows.append((t, 1, 40.0 + 0.0004 * (1 - t / 25), -3.0, 700.0))
        rows.append((t, 2, 40.0 - 0.0004 * (1 - t / 25), -3.0, 703.0))
        rows.append((t, 3, 40.01, -3.01, 700.0 + t))
    with TrajectoryWriter(path) as w:
        w.write_rows(rows)
    return rows


def independent(
    rows: list[tuple[float, int, float, float, float]],
) -> dict[tuple[int, int], list[float]]:
    by_t: dict[float, dict[int, np.ndarray]] = {}
    for t, v, lat, lon, h in rows:
        by_t.setdefault(t, {})[v] = ecef(lat, lon, h)
    out: dict[tuple[int, int], list[float]] = {}
    for pts in by_t.values():
        for a, b in itertools.combinations(sorted(pts), 2):
            out.setdefault((a, b), []).append(float(np.linalg.norm(pts[a] - pts[b])))
    return out


def test_counts_and_minima_match_an_independent_computation(tmp_path: Path) -> None:
    log = tmp_path / "log.csv"
    rows = three_vehicles(log)
    rows = [(t, v, round(la, 8), round(lo, 8), round(h, 3)) for t, v, la, lo, h in rows]
    ref = independent(rows)
    result = cli(str(log), "--json")
    assert result.exit_code == 0, result.output
    data = json.loads(result.output)
    for pair in data["pairs"]:
        d = np.array(ref[(pair["a"], pair["b"])])
        assert pair["min_m"] == pytest.approx(d.min(), abs=1e-3)
        assert pair["near"] == int((d < 5).sum())
        assert pair["danger"] == int(((d >= 5) & (d < 10)).sum())
        assert pair["risk"] == int(((d >= 10) & (d < 40)).sum())
        assert pair["samples"] == 101
    one_two = data["pairs"][0]
    assert one_two["pair"] == "1-2" and one_two["min_m"] == pytest.approx(3.0, abs=0.01)
    assert one_two["min_time_s"] == 25.0 and one_two["near"] > 0
    assert data["min_sep_m"] == one_two["min_m"] and data["min_pair"] == "1-2"


def test_thresholds_are_configurable(tmp_path: Path) -> None:
    log = tmp_path / "log.csv"
    ref = independent(three_vehicles(log))
    data = json.loads(
        cli(str(log), "--json", "--near", "2", "--danger", "20", "--risk", "100").output
    )
    d = np.array(ref[(1, 2)])
    assert data["pairs"][0]["near"] == int((d < 2).sum()) == 0
    assert data["pairs"][0]["danger"] == int(((d >= 2) & (d < 20)).sum())


def test_table_and_png(tmp_path: Path) -> None:
    log = tmp_path / "log.csv"
    three_vehicles(log)
    png = tmp_path / "sep.png"
    result = cli(str(log), "--png", str(png))
    assert result.exit_code == 0, result.output
    assert "MinDistance_m" in result.output and "1-2" in result.output and "3.00" in result.output
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_vehicles_selects_pairs(tmp_path: Path) -> None:
    log = tmp_path / "log.csv"
    three_vehicles(log)
    data = json.loads(cli(str(log), "--json", "--vehicles", "1,3").output)
    assert [p["pair"] for p in data["pairs"]] == ["1-3"]


def test_unsynchronised_samples_are_interpolated() -> None:
    text = (
        HEADER
        + "\n"
        + "\n".join(
            [
                "0.0,1,40.0,-3.0,700",
                "1.0,1,40.0,-3.0,710",
                "0.5,2,40.0,-3.0,700",
            ]
        )
    )
    rep = analyze(parse_trajectory(text))
    (p,) = rep.pairs
    assert p.samples == 1 and p.min_m == pytest.approx(5.0, abs=1e-6)  # 1 at 705 m at t=0.5


def test_gaps_longer_than_max_gap_are_not_bridged() -> None:
    text = HEADER + "\n0,1,40,-3,700\n10,1,40,-3,700\n5,2,40,-3,700\n"
    assert analyze(parse_trajectory(text)).pairs[0].samples == 0
    assert analyze(parse_trajectory(text), max_gap_s=20).pairs[0].samples == 1


@pytest.mark.parametrize(
    ("content", "message"),
    [
        ("", "empty file"),
        ("time_s,vehicle,lat,lon\n0,1,40,-3\n", "missing column(s) alt_m"),
        (HEADER + "\n", "no samples"),
        (HEADER + "\n0,1,40,-3,nan\n0,2,40,-3,700\n", "alt_m is nan"),
        (HEADER + "\n0,1,40,-3,abc\n", "not a number"),
        (HEADER + "\n0,1.5,40,-3,700\n", "not an id"),
        (HEADER + "\n0,1,95,-3,700\n", "out of range"),
        (HEADER + "\n0,1,40\n", "fields"),
        (HEADER + "\n0,1,40,-3,700\n", "two vehicles or more"),
    ],
)
def test_bad_input_is_one_line_and_exit_2(tmp_path: Path, content: str, message: str) -> None:
    log = tmp_path / "bad.csv"
    log.write_text(content)
    result = cli(str(log))
    assert result.exit_code == 2
    assert message in result.output
    assert "Traceback" not in result.output
    assert len(result.output.strip().splitlines()) == 1


def test_unknown_vehicle_missing_file_and_bad_thresholds(tmp_path: Path) -> None:
    log = tmp_path / "log.csv"
    three_vehicles(log)
    for argv, message in (
        ((str(log), "--vehicles", "1,9"), "vehicle(s) 9 not in the log"),
        ((str(tmp_path / "nope.csv"),), "cannot read"),
        ((str(log), "--near", "20"), "thresholds must be"),
        ((str(log), "--vehicles", "x"), "--vehicles"),
        ((str(log), "--step", "0"), "step must be positive"),
    ):
        result = cli(*argv)
        assert result.exit_code == 2, (argv, result.output)
        assert message in result.output and "Traceback" not in result.output


def test_thresholds_must_be_ordered() -> None:
    with pytest.raises(AnalysisError):
        Thresholds(risk_m=5, danger_m=10, near_m=1)


def test_writer_round_trips_and_takes_statuses(tmp_path: Path) -> None:
    path = tmp_path / "rec.csv"
    s = VehicleStatus(
        vehicle_id=4, time_unix_s=1.7e9, lat_deg=40.1, lon_deg=-3.2, alt_msl_m=812.5, alt_rel_m=90
    )
    with TrajectoryWriter(path, extra_columns=("alt_rel_m",)) as w:
        w.write_status(s)
        w.write(1.7e9 + 0.2, 5, 40.2, -3.3, 700.0, 88.0)
        with pytest.raises(ValueError):
            w.write(0, 1, 0, 0, 0)  # the extra column is missing
    lines = path.read_text().splitlines()
    assert lines[0] == HEADER + ",alt_rel_m"
    tr = parse_trajectory(path.read_text())
    assert list(tr.vehicle) == [4, 5] and tr.alt_m[0] == 812.5 and tr.lat[1] == 40.2
    with pytest.raises(TrajectoryError):
        parse_trajectory("")


def test_only_airborne_pairs_count_and_times_are_from_the_start(tmp_path: Path) -> None:
    """82,005 "risk" samples came from vehicles parked 10 m apart on their pads, and the
    plot's axis read "+1.7958e9": a `gcs record` log (UNIX times, alt_rel_m, armed)
    counts pairs only while both are airborne, in seconds from the log's start."""
    from gcs_cli.plot import EXTRA

    log = tmp_path / "record.csv"
    t0 = 1.7958e9
    with TrajectoryWriter(log, EXTRA) as w:
        for k in range(200):
            t = t0 + 0.2 * k
            flying = k >= 100  # on the pads for 20 s, then both up, 60 m apart
            for vid, east in ((7, 0.0), (8, 10.0 if not flying else 60.0)):
                rel = 30.0 if flying else 0.0
                w.write(
                    t,
                    vid,
                    40.0,
                    -3.0 + east / 85_000,
                    700.0 + rel,
                    rel,
                    0,
                    0,
                    100,
                    "X",
                    "Y",
                    0,
                    int(flying),
                )
    data = json.loads(cli(str(log), "--json").output)
    (pair,) = data["pairs"]
    assert pair["samples"] == 100 and pair["risk"] == 0 and pair["min_m"] > 55.0, pair
    assert 20.0 <= pair["min_time_s"] <= 40.0 and data["t0_s"] == t0, data
    assert data["counted"].startswith("samples where both are airborne"), data
    parked = json.loads(cli(str(log), "--json", "--ground").output)["pairs"][0]
    assert parked["samples"] == 200 and parked["risk"] == 100 and parked["min_time_s"] < 20.0
    png = tmp_path / "sep.png"
    result = cli(str(log), "--png", str(png))
    assert result.exit_code == 0 and "1.79" not in result.output, result.output
    # parked the whole time: nothing airborne to analyse, said in one line (exit 2)
    with TrajectoryWriter(tmp_path / "parked.csv", EXTRA) as w:
        for k in range(10):
            for vid in (7, 8):
                w.write(t0 + k, vid, 40.0, -3.0 + vid / 1e5, 700.0, 0.0, 0, 0, 100, "X", "Y", 0, 0)
    result = cli(str(tmp_path / "parked.csv"))
    assert result.exit_code == 2 and "fewer than two vehicles airborne" in result.output
