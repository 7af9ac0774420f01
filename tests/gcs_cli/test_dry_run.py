"""`gcs mission ... --dry-run` runs the checks the fleet will run, endurance included:
the mission planned with the nodes' planner for the vehicles it addresses (their
homes and batteries as they publish them), each vehicle's budget printed (needs X s,
has Y s), a plan the fleet would refuse refused with its numbers (exit 1), and nothing
sent. The seed database's quadcopters: QGroundControl's survey at 50 m is covered; a
field they cannot cover is not, and the dry run says by how much."""

from __future__ import annotations

import time
from collections.abc import Iterator
from pathlib import Path

import msgspec
import pytest

from gcs_cli.app import run
from gcs_cli.budgets import Swarm, budgets
from gcs_cli.geofiles import mission_from_file
from swarm_node.core.planning import PlanningError
from swarm_node.database import seed_profiles
from swarm_proto import (
    DetailCode,
    Geometry,
    GeoPoint,
    Mission,
    MissionParams,
    MissionType,
)
from tests.gcs_cli.fake_vehicle import Vehicle

pytestmark = pytest.mark.network

PLAN = Path(__file__).parent / "data" / "qgc-survey.plan"
IDS = (7, 8, 9)
HOMES = {v: GeoPoint(37.4112, -5.9889 + 0.000113 * k, 10.0) for k, v in enumerate(IDS)}
QUAD = seed_profiles()["Generic Quadcopter"]
PROFILES = {v: msgspec.structs.replace(QUAD, vehicle_id=v) for v in IDS}
#: a 600 m square north of the homes: more than three seed quadcopters fly on a battery
BIG = Geometry.polygon(
    [(37.4120, -5.9900), (37.4120, -5.9832), (37.4174, -5.9832), (37.4174, -5.9900)]
)


def test_the_plan_files_survey_is_within_every_battery() -> None:
    fm = mission_from_file(PLAN, MissionType.AREA)
    m = Mission(1, 900, MissionType.AREA, fm.geometry, MissionParams(**fm.params))
    found = budgets(m, list(IDS), PROFILES, Swarm(dict.fromkeys(IDS, 0), HOMES, {}, []), 0.0)
    assert [b.vehicle_id for b in found] == list(IDS)
    for b in found:
        assert 0.0 < b.needs_s < b.has_s and not b.short, b
    # a battery half used leaves less
    half = budgets(m, list(IDS), PROFILES, Swarm(dict.fromkeys(IDS, 0), HOMES, {7: 50.0}, []), 0.0)
    assert half[0].has_s < found[0].has_s and half[0].battery_pct == 50.0


def test_a_field_too_big_is_refused_with_the_budgets() -> None:
    m = Mission(2, 900, MissionType.AREA, BIG, MissionParams(altitude_rel_m=100.0))
    with pytest.raises(PlanningError) as info:
        budgets(m, list(IDS), PROFILES, Swarm(dict.fromkeys(IDS, 0), HOMES, {}, []), 0.0)
    d = info.value.detail
    assert d is not None and d.code == DetailCode.ENDURANCE and d.vehicle_id == 0
    assert round(d.available_s) == 148 and d.needed_s > 2 * d.available_s


@pytest.fixture
def quads(zenoh_router: str, swarm_db: Path) -> Iterator[dict[int, Vehicle]]:
    vs = {v: Vehicle(zenoh_router, "dry", v, [], home=HOMES[v], battery_pct=100) for v in IDS}
    try:
        yield vs
    finally:
        for v in vs.values():
            v.close()


def gcs(router: str, capsys: pytest.CaptureFixture[str], *args: str) -> tuple[int, str, str]:
    code = run(["--connect", router, "--swarm", "dry", *args])
    out, err = capsys.readouterr()
    return code, out, err


def test_dry_run_prints_each_vehicles_budget_and_sends_nothing(
    zenoh_router: str, quads: dict[int, Vehicle], capsys: pytest.CaptureFixture[str]
) -> None:
    time.sleep(0.5)  # their first VehicleInfo out
    code, out, _ = gcs(
        zenoh_router, capsys, "mission", "area", "--file", str(PLAN), "--all", "--dry-run"
    )
    assert code == 0, out
    assert "from qgc-survey.plan: altitude 50 m, side overlap 0.6" in out, out
    assert "planned as the nodes plan it" in out and "needs s" in out and "has s" in out, out
    rows = [line.split() for line in out.splitlines() if line.strip()[:1] in ("7", "8", "9")]
    assert [r[0] for r in rows] == ["7", "8", "9"] and all(r[-1] == "ok" for r in rows), out
    assert all(r[3] == "192" for r in rows), out  # has: 192 s at 50 m on a full battery
    assert "the fleet's checks pass; nothing sent" in out, out
    # an option given overrides the file's altitude: less battery left after a climb to 100 m
    code, out, _ = gcs(
        zenoh_router,
        capsys,
        "mission",
        "area",
        "--file",
        str(PLAN),
        "--all",
        "--alt",
        "100",
        "--dry-run",
    )
    rows = [line.split() for line in out.splitlines() if line.strip()[:1] in ("7", "8", "9")]
    assert code == 0 and rows and all(r[3] == "148" for r in rows), out
    # a fleet nobody is in: nothing to plan with, said
    code, out, _ = gcs(
        zenoh_router, capsys, "mission", "area", "--file", str(PLAN), "--fleet", "1", "--dry-run"
    )
    assert code == 0 and "no vehicle it addresses is alive" in out, out
    assert all(v.got == [] for v in quads.values())


def test_dry_run_refuses_what_the_fleet_would_refuse(
    zenoh_router: str, quads: dict[int, Vehicle], capsys: pytest.CaptureFixture[str]
) -> None:
    time.sleep(0.5)
    ring = " ".join(f"{p.lat_deg},{p.lon_deg}" for p in BIG.points)
    code, out, _ = gcs(
        zenoh_router,
        capsys,
        "mission",
        "area",
        "--polygon",
        ring,
        "--id",
        "7",
        "--id",
        "8",
        "--id",
        "9",
        "--alt",
        "100",
        "--dry-run",
    )
    assert code == 1, out
    line = " ".join(out.split())
    assert "the fleet would refuse it: needs" in line and "s per vehicle at cruise" in line, out
    assert "has 148 s" in line, out
    assert all(v.got == [] for v in quads.values())
