"""Checks: the paper's experiment 1 as `make demo` flies it (swarm_sim/story.py,
narrator.py, demo_report.py).

The default run flies the story (`StoryPlan.experiment_one`, the demo's distances) end
to end in fast time (FastFleet: simulated vehicles,
real MAVLink bytes, the six node cores) with the same script, recorder and report as
`swarm-sim demo`, and checks report.json and the pictures' content. The soak test flies
the story shortened (every distance 0.7 times the demo's) through the demo's real processes (`swarm-sim demo`'s
`experiment.run`: simulated vehicles on TCP, one `swarm-node run` each, Zenoh on
127.0.0.1).

Below 0.7 the story no longer holds together: the survey is flown before the last of
six close pads has launched (scale 0.6), and smaller fields put the vehicles' 50 m turns
near the zones."""

from __future__ import annotations

import io
import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from matplotlib.path import Path as PixelPath

from gcs_cli.plot import read_georeference, vehicle_colors
from swarm_proto import (
    Alert,
    AlertCode,
    FsmState,
    MissionState,
    Severity,
    VehicleInfo,
    VehicleStatus,
    VehicleType,
    geodesy,
)
from swarm_sim.core import SITL_HOME
from swarm_sim.demo_report import fast_report, replan_rows
from swarm_sim.narrator import Narrator
from swarm_sim.story import AREA_ID, Record, StoryPlan

# the story is flown once per worker (a session fixture: a module fixture is flown again
# whenever the scheduler runs another module's test between two of these), and every test
# here is on one worker
pytestmark = pytest.mark.xdist_group("demo-story")

MEMBERS = (1, 2, 3, 4, 5, 6)  # the seed database's six Albatross 250 VTOLs
SCALE = 0.7
STEPS = [
    "base",
    "zones",
    "area",
    "launch",
    "survey",
    "vote",
    "replan",
    "fail",
    "inherit",
    "finish",
    "home",
    "done",
]


FAST_SCALE = 1.0  # the fast-time story: the demo's own distances (see the xfail below)


def _plan(scale: float = SCALE) -> StoryPlan:
    return StoryPlan.experiment_one(MEMBERS, (SITL_HOME.lat_deg, SITL_HOME.lon_deg), scale=scale)


@pytest.fixture(scope="session")
def flown(tmp_path_factory: pytest.TempPathFactory, fleet_profiles: dict) -> tuple[Path, dict]:
    out = tmp_path_factory.mktemp("demo-out")
    fast_report(_plan(FAST_SCALE), {v: fleet_profiles[v] for v in MEMBERS}, out)
    report: dict[str, Any] = json.loads((out / "report.json").read_text())
    return out, report


def _check_report(report: dict[str, Any]) -> None:
    """What report.json must say after the whole story (the demo's exit 0)."""
    assert report["ok"], report["failures"]
    assert report["failures"] == []
    assert report["missions_completed"] == report["missions_total"] == 4
    assert {m["kind"] for m in report["missions"]} == {"area", "target", "perimeter", "route"}
    assert report["coverage"] >= 0.99
    sep = report["separation"]
    assert sep["near"] == 0 and sep["min_sep_m"] > 5.0
    assert len(sep["airborne"]["pairs"]) == 15  # every pair of six
    assert [s["step"] for s in report["timeline"]] == STEPS
    # the vote: everyone scored, two winners, the best two scores
    (vote,) = report["votes"]
    assert vote["decided"] and set(vote["voters"]) == set(MEMBERS)
    scores = {int(v): s for v, s in vote["scores"].items()}
    assert set(scores) == set(MEMBERS)
    best = sorted(scores, key=lambda v: -scores[v])[:2]
    assert sorted(vote["winners"]) == sorted(best) == sorted(report["winners"])
    stayers = sorted(set(MEMBERS) - set(best))
    # the two replans of the survey: the stayers re-split, then the survivors inherit
    (victim,) = (int(v) for v in report["failed"])
    assert victim in stayers
    causes = {e["cause"]: e for e in report["replans"] if e["mission_id"] == AREA_ID}
    assert causes["vote"]["vehicles"] == stayers
    assert causes["lost"]["vehicles"] == [v for v in stayers if v != victim]
    assert report["landed"] == sorted(set(MEMBERS) - {victim})
    area = next(m for m in report["missions"] if m["kind"] == "area")
    assert area["failed"] == [victim] and sorted(area["left_for_another"]) == sorted(best)
    target = next(m for m in report["missions"] if m["kind"] == "target")
    assert target["completed_by"]  # the second may be sent on 20 s after the first
    assert sorted(target["completed_by"] + target["left_for_another"]) == sorted(best)
    for kind in ("perimeter", "route"):
        m = next(m for m in report["missions"] if m["kind"] == kind)
        assert sorted(m["completed_by"]) == sorted(best), kind


def test_the_shortened_story_is_flown_end_to_end(flown: tuple[Path, dict]) -> None:
    out, report = flown
    _check_report(report)
    assert report["files"] == {
        "flight": "flight.csv",
        "top": "top.png",
        "altitude": "altitude.png",
        "separation": "separation.png",
    }
    for name in report["files"].values():
        assert (out / name).stat().st_size > 1000, name
    header = (out / "flight.csv").read_text().splitlines()[0]
    assert header.startswith("time_s,vehicle,lat,lon,alt_m")


def _pixels(png: Path) -> np.ndarray:
    import matplotlib.image as mpimg

    return np.asarray(mpimg.imread(png))[:, :, :3]


def _near(img: np.ndarray, rgb: tuple[float, float, float], tol: float = 0.06) -> np.ndarray:
    return np.asarray(np.abs(img - np.array(rgb)).max(axis=2) < tol)


def test_the_top_view_has_the_tracks_inside_the_area_and_the_zone(flown: tuple[Path, dict]) -> None:
    """top.png, put back on the field by its georeference: every vehicle's color inside
    the survey area (its lanes), the field's no-fly zone filled in red, and no track
    drawn across the zone."""
    out, _ = flown
    plan = _plan(FAST_SCALE)
    png = out / "top.png"
    img = _pixels(png)
    rows, cols = np.mgrid[0 : img.shape[0], 0 : img.shape[1]]
    centres = np.column_stack([cols.ravel() + 0.5, rows.ravel() + 0.5])
    _, pixel = read_georeference(png)
    area = PixelPath([pixel(p.lat_deg, p.lon_deg) for p in plan.area.points])
    inside = area.contains_points(centres).reshape(img.shape[:2])
    assert inside.sum() > 20_000  # the field is a large part of the picture
    colors = vehicle_colors(MEMBERS)
    for vid in MEMBERS:
        mine = _near(img, colors[vid])
        assert (mine & inside).sum() > 300, vid  # its survey lanes
    # the zone: a disc of the zone's translucent red, inside the field
    zone = plan.zones[0].geometry
    lat, lon = zone.points[0].lat_deg, zone.points[0].lon_deg
    c, r = pixel(lat, lon)
    edge_c, edge_r = pixel(*geodesy.offset(lat, lon, 0.0, zone.radius_m or 0.0))
    radius_px = float(np.hypot(edge_c - c, edge_r - r))
    assert radius_px > 8
    disc = (cols + 0.5 - c) ** 2 + (rows + 0.5 - r) ** 2 < (0.7 * radius_px) ** 2
    assert inside[disc].all()  # the zone is in the field
    reddish = (img[:, :, 0] - img[:, :, 1] > 0.2) & (img[:, :, 1] - img[:, :, 2] < 0.05)
    assert reddish[disc].mean() > 0.6, reddish[disc].mean()
    ring = ((cols + 0.5 - c) ** 2 + (rows + 0.5 - r) ** 2 - radius_px**2) ** 2 < (
        2 * radius_px
    ) ** 2
    assert _near(img, (0.8, 0.0, 0.0), 0.1)[ring].sum() > 20  # its edge
    for vid in MEMBERS:  # no track across the zone (vehicle 4's red is not the zone's)
        assert _near(img, colors[vid], 0.04)[disc].sum() < 10, vid


def test_the_altitude_and_separation_pictures_show_every_vehicle(flown: tuple[Path, dict]) -> None:
    out, _ = flown
    colors = vehicle_colors(MEMBERS)
    altitude = _pixels(out / "altitude.png")
    for vid in MEMBERS:
        assert _near(altitude, colors[vid]).sum() > 100, vid
    separation = _pixels(out / "separation.png")
    assert separation.std() > 0.05  # drawn, not blank
    assert _near(separation, (1.0, 1.0, 1.0)).mean() < 0.95


def test_replans_are_grouped_by_cause_not_by_the_story_step() -> None:
    """The stayers enter REPLAN within a second of each other while the story moves
    from VOTE to REPLAN: one event. A replan of another mission is not the vote's."""
    rec = Record(winners=(3, 6), failed={5: 280.0})
    rec.replans = [
        (253.7, AREA_ID, 1, "vote"),
        (253.7, AREA_ID, 4, "vote"),
        (253.8, AREA_ID, 2, "replan"),
        (253.8, AREA_ID, 5, "replan"),
        (282.9, AREA_ID, 1, "inherit"),
        (283.0, AREA_ID, 2, "inherit"),
        (283.0, AREA_ID, 4, "inherit"),
        (290.0, 77, 6, "inherit"),
    ]
    events = replan_rows(rec)
    assert [(e["cause"], e["vehicles"]) for e in events] == [
        ("vote", [1, 2, 4, 5]),
        ("lost", [1, 2, 4]),
        ("other", [6]),
    ]
    assert "3, 6 voted out" in events[0]["why"] and "vehicle 5 lost" in events[1]["why"]


def test_the_clock_never_reads_60_seconds() -> None:
    from rich.console import Console

    from swarm_sim.experiment import _say

    buf = io.StringIO()
    _say(Console(file=buf, width=100), 239.96, "vehicle 4", "flying its share")
    assert "4:00.0" in buf.getvalue() and "3:60.0" not in buf.getvalue()


def _status(state: MissionState, fsm: FsmState, alt: float, armed: bool = True) -> VehicleStatus:
    return VehicleStatus(
        4,
        1.8e9,
        37.4,
        -5.98,
        10.0 + alt,
        alt,
        armed=armed,
        fsm_state=fsm,
        mission_state=state,
        battery_pct=88,
    )


def _info(mission_id: int) -> VehicleInfo:
    return VehicleInfo(4, VehicleType.VTOL, "Albatross 250 VTOL", "ALB-04", mission_id=mission_id)


def test_the_narrator_says_returning_once_a_share_is_flown_and_never_mission_0() -> None:
    """A vehicle that has flown its share goes through STATE_PLAN for its way home: it
    is returning, not planning the survey again. A vehicle planning before its
    VehicleInfo shows the mission plans "a new mission"."""
    n = Narrator(0.0, {AREA_ID: "the survey"})
    n.handle(_info(0), 0.0)
    (line,) = n.handle(_status(MissionState.IDLE, FsmState.PLAN, 0.0, armed=False), 1.0)
    assert line.text.startswith("planning a new mission with its fleet"), line.text
    n.handle(_info(AREA_ID), 2.0)
    (line,) = n.handle(_status(MissionState.MISSION, FsmState.GO_MISSION, 80.0), 3.0)
    assert line.text == "flying its share of the survey at 80 m"
    alert = Alert(4, 1.8e9, Severity.INFO, AlertCode.MISSION_COMPLETE, "mission 101")
    (line,) = n.handle(alert, 4.0)
    assert line.text == "the survey: its share is flown (MISSION_COMPLETE)"
    (line,) = n.handle(_status(MissionState.PLANNING, FsmState.PLAN, 80.0), 4.1)
    assert line.text == "returning to its pad (88% battery)"


@pytest.mark.soak
@pytest.mark.network
@pytest.mark.timeout(900)
def test_the_shortened_story_through_the_real_processes(tmp_path: Path) -> None:
    """`swarm-sim demo` as `make demo` runs it (real node processes, simulated vehicles
    on TCP, Zenoh on 127.0.0.1), the story shortened, at the demo's speed-up: exit 0 and
    report.json."""
    from rich.console import Console

    from swarm_sim.experiment import DEFAULT_SPEEDUP, run

    out = tmp_path / "demo-out"
    code = run(
        MEMBERS,
        speedup=DEFAULT_SPEEDUP,
        timeout_s=900.0,
        out=out,
        console=Console(file=io.StringIO(), width=140),
        plan_kw={"scale": SCALE},
    )
    report = json.loads((out / "report.json").read_text())
    assert code == 0, report["failures"]
    _check_report(report)
    assert report["sim_s"] > 300 and report["speedup"] == DEFAULT_SPEEDUP


@pytest.mark.soak
@pytest.mark.timeout(900)
def test_the_mixed_story_is_flown_in_fast_time(tmp_path: Path, fleet_profiles: dict) -> None:
    """`swarm-sim demo --mixed`'s fleet (six VTOLs, three quadcopters, a rover, a boat)
    through the whole story in fast time (about 90 s of wall time): the split gives the
    field 1 km away to the VTOLs; the others stay on their pads (none reaches
    BATTERY_CRITICAL hovering with an empty share, as before) and land, and the
    VTOLs fly the rest of the story as the six-VTOL demo does."""
    from swarm_sim.experiment import EXPERIMENT_FLEET, MIXED_EXTRA

    members = EXPERIMENT_FLEET + MIXED_EXTRA
    plan = StoryPlan.experiment_one(members, (SITL_HOME.lat_deg, SITL_HOME.lon_deg))
    report = fast_report(plan, {v: fleet_profiles[v] for v in members}, tmp_path, pictures=False)
    assert report["ok"], report["failures"]
    assert report["missions_completed"] == report["missions_total"] == 4
    assert report["coverage"] >= 0.99 and report["separation"]["near"] == 0
    area = next(m for m in report["missions"] if m["kind"] == "area")
    assert set(MIXED_EXTRA) <= set(area["completed_by"])  # on the ground, at once
    assert not any(int(v) in MIXED_EXTRA for v in report["failed"])
    assert set(report["landed"]) >= set(MIXED_EXTRA)


def test_the_pair_flies_the_perimeter_and_route_layered_beyond_a_conflict() -> None:
    """Layered 10 m apart, the pair flew its whole route as an avoidance conflict and,
    stacked over the route's last loiter, was held there for good (a demo run)."""
    from swarm_node.core.safety.avoidance import AvoidanceConfig

    plan = _plan()
    for m in (plan.perimeter_mission((2, 6), 0.0), plan.route_mission((2, 6), 0.0)):
        assert m.params.altitude_step_m > AvoidanceConfig(1, VehicleType.VTOL).protect_m + 5.0


def test_a_picture_without_a_georeference_is_refused(tmp_path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, _ = plt.subplots()
    fig.savefig(tmp_path / "plain.png")
    plt.close(fig)
    with pytest.raises(ValueError, match="no georeference"):
        read_georeference(tmp_path / "plain.png")


def test_a_vehicle_in_an_emergency_ends_the_story_at_once_with_its_alert() -> None:
    """Run 6 of the first series waited 10 minutes of wall time for a phase's timeout
    after vehicle 4 entered the field's zone; the story now ends there, failed, and
    says why."""
    from swarm_proto import GeoPoint as Point
    from swarm_proto import GpsFix
    from swarm_sim.story import Finished, Phase, Send, Story

    plan = _plan()
    story = Story(plan, 0.0)
    home = Point(SITL_HOME.lat_deg, SITL_HOME.lon_deg, 10.0)
    actions: list[object] = []
    for v in MEMBERS:
        story.handle(
            VehicleInfo(v, VehicleType.VTOL, "Albatross 250 VTOL", f"ALB-0{v}", home=home), 1.0
        )
        actions += story.handle(
            VehicleStatus(v, 1.8e9, home.lat_deg, home.lon_deg, 10.0, 0.0, gps_fix=GpsFix.FIX_3D),
            1.0,
        )
    assert story.phase == Phase.BASE and any(isinstance(a, Send) for a in actions)
    story.handle(
        Alert(
            4,
            1.8e9,
            Severity.CRITICAL,
            AlertCode.GEOFENCE_BREACH,
            "in no-fly zone 1 at 37.420525,-5.985487 89 m",
        ),
        2.0,
    )
    out = story.handle(
        VehicleStatus(
            4,
            1.8e9,
            home.lat_deg,
            home.lon_deg,
            99.0,
            89.0,
            armed=True,
            fsm_state=FsmState.EMERGENCY,
        ),
        2.1,
    )
    (done,) = [a for a in out if isinstance(a, Finished)]
    assert not done.ok and story.phase == Phase.DONE
    assert (
        done.why == "base: vehicle 4 in an emergency: in no-fly zone 1 at 37.420525,-5.985487 89 m"
    )
    assert story.record.outcome == done.why


def test_the_perimeter_waits_for_the_second_of_the_pair_at_most_20_s() -> None:
    """Without avoidance's holding layers the first of the pair was in its final
    descent 40 s after it finished the target, and refused the perimeter BUSY."""
    from swarm_sim.story import TARGET_WAIT_S, MissionRecord, Story

    plan = _plan()
    story = Story(plan, 0.0)
    story.record.t0, story.record.winners = 0.0, (3, 6)
    assert not story._target_watched(500.0)
    target = MissionRecord(plan.target_mission_id, "target", completed={3: 400.0})
    story.record.missions[plan.target_mission_id] = target
    assert not story._target_watched(400.0 + TARGET_WAIT_S - 1.0)
    assert story._target_watched(400.0 + TARGET_WAIT_S)
    target.completed[6] = 405.0
    assert story._target_watched(405.0)


@pytest.mark.parametrize(
    ("args", "says"),
    [
        (["--vehicles", "1,2"], "at least 4 distinct ids"),
        (["--vehicles", "1,2,3,3"], "at least 4 distinct ids"),
        (["--vehicles", "1,x,3,4"], "comma-separated ids"),
        (["--vehicles", "1,2,3,4", "--mixed"], "not both"),
        (["--speedup", "0"], "must be in (0, 100]"),
        (["--speedup", "nan"], "must be in (0, 100]"),
        (["--timeout", "-1"], "must be positive"),
    ],
)
def test_bad_demo_options_are_one_line_and_exit_2(args: list[str], says: str) -> None:
    from typer.testing import CliRunner

    from swarm_sim.cli import app

    result = CliRunner().invoke(app, ["demo", *args])
    assert result.exit_code == 2, result.output
    assert says in " ".join(result.output.split())


@pytest.mark.soak
def test_the_shortened_story_keeps_5_m_between_a_returning_vtol_and_a_turning_one(
    tmp_path: Path, fleet_profiles: dict
) -> None:
    """Was a strict xfail, a known weakness reproduced: in the story shortened to 0.7,
    vehicle 5, its target watched, turned for home at 100 m across the field while
    vehicle 3 made its lane-end turn at 100 m: each predicted the other straight on and
    they passed 3.7 m apart. The story's timing has moved on since (it kept 10.7 m at
    the closest, 1-2 at take-off, in the run that lifted the xfail): the weakness
    itself, a turning aircraft predicted straight on, remains (docs/avoidance.md, known
    limits); this keeps the shortened story's 5 m."""
    report = fast_report(
        _plan(0.7), {v: fleet_profiles[v] for v in MEMBERS}, tmp_path, pictures=False
    )
    assert report["separation"]["near"] == 0, report["separation"]["min_sep_m"]
