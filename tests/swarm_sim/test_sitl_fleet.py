"""`make sitl-fleet` (swarm_sim/sitl_fleet.py): its command line, and the figures it
gives from ArduPilot's positions (sitl_figures.py) on tracks whose answers are known.
The whole run against swarm-sim vehicles is a soak test; against real SITL it is
`make sitl-fleet` (docs/sitl.md)."""

from __future__ import annotations

import itertools
import json
import math
from pathlib import Path

import pytest
from shapely.geometry import Polygon

from swarm_sim import sitl_figures as fig
from swarm_sim import sitl_fleet


def line(
    vid_alt: float, pts: list[tuple[float, float]], t0: float = 0.0, speed: float = 10.0
) -> list[fig.Fix]:
    """A track through `pts` at `speed` m/s, 10 fixes a second, armed at `vid_alt`."""
    out: list[fig.Fix] = []
    t = t0
    for (e0, n0), (e1, n1) in itertools.pairwise(pts):
        d = math.hypot(e1 - e0, n1 - n0)
        steps = max(1, int(d / speed * 10))
        for k in range(steps):
            f = k / steps
            out.append(
                fig.Fix(t, e0 + f * (e1 - e0), n0 + f * (n1 - n0), vid_alt, 10.0 + vid_alt, True)
            )
            t += 0.1
    out.append(fig.Fix(t, *pts[-1], vid_alt, 10.0 + vid_alt, True))
    return out


def lawnmower(
    e0: float, e1: float, n0: float, n1: float, spacing: float
) -> list[tuple[float, float]]:
    pts, e, up = [], e0 + spacing / 2, True
    while e < e1:
        pts += [(e, n0), (e, n1)] if up else [(e, n1), (e, n0)]
        e, up = e + spacing, not up
    return pts


def test_the_command_line_says_what_is_wrong(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.delenv("ARDUPILOT_SITL_BIN", raising=False)
    out = str(tmp_path / "f.json")
    assert sitl_fleet.main(["--out", out]) == 2
    assert "ARDUPILOT_SITL_BIN" in capsys.readouterr().out
    for bad, says in (
        ("copter:7,copter:8", "at least 3"),
        ("copter:7,copter:8,copter:1", "a copter is one of the seed's systems 7-9"),
        ("plane:1,copter:7,copter:8", "quadplane:ID or copter:ID"),
        ("copter:7,copter:7,quadplane:1", "each vehicle once"),
    ):
        assert sitl_fleet.main(["--sim", "--vehicles", bad, "--out", out]) == 2
        assert says in capsys.readouterr().out
    assert sitl_fleet.main(["--sim", "--head-on", "1,9", "--out", out]) == 2
    assert "--head-on" in capsys.readouterr().out
    assert not Path(out).exists()


def test_coverage_of_a_field_swept_lane_by_lane() -> None:
    """Lanes one footprint apart cover the field; every other lane left out, about half."""
    field = Polygon([(0, 0), (200, 0), (200, 100), (0, 100)])
    zone = [(100.0, 50.0, 20.0)]
    region = fig.coverable(field, zone)
    assert region.area == pytest.approx(20000 - math.pi * 400, rel=0.01)
    # 60 m up, HFOV 60 deg: a footprint 69 m wide; lanes 40 m apart overlap
    full = {1: [line(60.0, lawnmower(-20, 220, -10, 110, 40.0))]}
    assert fig.coverage(full, {1: 60.0}, region) > 0.99
    gaps = {1: [line(60.0, lawnmower(-20, 220, -10, 110, 160.0))]}
    assert 0.3 < fig.coverage(gaps, {1: 60.0}, region) < 0.8
    assert fig.coverage({}, {}, region) == 0.0


def test_flown_twice_tells_a_split_from_two_vehicles_on_the_same_lanes() -> None:
    west = line(60.0, lawnmower(0, 100, 0, 100, 20.0))
    east = line(70.0, lawnmower(100, 200, 0, 100, 20.0))
    assert fig.flown_twice({1: [west], 2: [east]}, 20.0) < 0.05
    same = line(70.0, lawnmower(0, 100, 0, 100, 20.0))
    assert fig.flown_twice({1: [west], 2: [same]}, 20.0) > 0.95


def test_separation_of_a_head_on_pair_and_only_while_both_fly() -> None:
    a = line(40.0, [(-200.0, 0.0), (200.0, 0.0)], speed=20.0)
    b = [
        fig.Fix(f.t, -f.e, 6.0, f.alt_rel + 8.0, f.alt_msl + 8.0, True) for f in a
    ]  # the other way, 6 m aside, 8 m above: they pass 10 m apart
    (s,) = fig.separations({1: a, 2: b}, 0.0, a[-1].t)
    assert s.min_m == pytest.approx(10.0, abs=0.5)
    assert s.horizontal_m == pytest.approx(6.0, abs=0.5) and s.vertical_m == pytest.approx(8.0)
    parked = [replace_fix(f, armed=False) for f in b]
    (s,) = fig.separations({1: a, 2: parked}, 0.0, a[-1].t)
    assert math.isinf(s.min_m)  # one on the ground, disarmed: no airborne pair


def replace_fix(f: fig.Fix, **kw: object) -> fig.Fix:
    from dataclasses import replace

    return replace(f, **kw)  # type: ignore[arg-type]


def test_zone_clearance_and_breaches_from_the_airborne_track() -> None:
    zone = [(0.0, 100.0, 35.0)]
    passing = line(60.0, [(-100.0, 50.0), (100.0, 50.0)])
    assert fig.zone_clearance(passing, zone) == pytest.approx(15.0, abs=0.1)
    assert fig.inside_zones(passing, zone) == 0
    through = line(60.0, [(-100.0, 100.0), (100.0, 100.0)])
    assert fig.zone_clearance(through, zone) == pytest.approx(-35.0, abs=0.1)
    assert fig.inside_zones(through, zone) > 0
    on_ground = [replace_fix(f, alt_rel=0.0) for f in through]
    assert fig.zone_clearance(on_ground, zone) is None


def test_landings_at_neighbouring_pads_together_are_seen() -> None:
    pads = {1: (0.0, 0.0), 2: (30.0, 0.0), 3: (300.0, 0.0)}

    def descent(pad: tuple[float, float], t0: float) -> list[fig.Fix]:
        return [
            fig.Fix(t0 + k * 0.1, *pad, 30.0 - k * 0.1, 40.0 - k * 0.1, True) for k in range(299)
        ]

    together = {1: descent(pads[1], 0.0), 2: descent(pads[2], 0.0), 3: descent(pads[3], 0.0)}
    (pair,) = fig.simultaneous_low(together, pads, 0.0, 30.0)
    assert pair[:2] == (1, 2) and pair[2] > 10.0  # the far pad is no neighbour
    in_turn = {1: descent(pads[1], 0.0), 2: descent(pads[2], 40.0)}
    assert fig.simultaneous_low(in_turn, pads, 0.0, 70.0) == []


@pytest.mark.soak
def test_the_fleet_against_swarm_sim_vehicles(tmp_path: Path) -> None:
    """The whole run against the simulator (`make sitl-fleet SITL_ARGS=--sim`)."""
    out = tmp_path / "fleet.json"
    sitl_fleet.main(["--sim", "--speedup", "5", "--first-instance", "41", "--out", str(out)])
    got = json.loads(out.read_text())
    assert got["target"] == "swarm-sim"
    assert set(got["steps"]) == set(sitl_fleet.ROWS)
    assert all(s["detail"] != "not run" for s in got["steps"].values()), got["steps"]
