"""`gcs zone import` never changes a zone the vehicles hold without being asked: with
zone 1 "pond" declared, importing QGroundControl's plan took ids 1 and 2 and turned
"pond" into an operating area, exit 0. Now the file's zones take ids no vehicle holds,
a clash is refused naming the ids, everything not imported is listed with why, the
plan's rally point can set the base, and --dry-run sends nothing. The vehicles here
are Zenoh sessions that hold zones, answer the zones queryable and acknowledge what
they are sent, on a router on 127.0.0.1 (the real ground station talks to them)."""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path

import msgspec
import pytest

from gcs_cli.app import run
from gcs_cli.files import fence_warnings, plan_import
from gcs_cli.geofiles import zones_from_file
from swarm_proto import Command, CommandKind, Geometry, NoFlyZone
from tests.gcs_cli.fake_vehicle import Vehicle

DATA = Path(__file__).parent / "data"
PLAN = DATA / "qgc-survey.plan"
POND = NoFlyZone(1, Geometry.circle(37.4119, -5.9899, 15.0), 0.0, 300.0, name="pond")

pytestmark = pytest.mark.network


# --------------------------------------------------------------------------- pure


def test_new_zones_take_ids_nobody_holds() -> None:
    zf = zones_from_file(PLAN)
    plan = plan_import(
        zf, {1: POND}, first_id=None, replace=False, floor=None, ceiling=None, issuer_id=900, now=0
    )
    assert [(p.zone.zone_id, p.action) for p in plan] == [
        (2, "declare"),
        (3, "declare"),
        (4, "declare"),
    ]
    assert [p.zone.operating_area for p in plan] == [True, False, False]
    # heights: the options, else the file's, else the whole airspace
    assert (plan[1].zone.floor_alt_msl_m, plan[1].zone.ceiling_alt_msl_m) == (-1000.0, 8000.0)
    plan = plan_import(
        zf, {}, first_id=None, replace=False, floor=0.0, ceiling=None, issuer_id=900, now=0
    )
    assert [p.zone.zone_id for p in plan] == [1, 2, 3] and plan[1].zone.floor_alt_msl_m == 0.0


def test_an_explicit_first_id_that_clashes_is_refused_naming_it() -> None:
    zf = zones_from_file(PLAN)
    with pytest.raises(ValueError, match=r"zone 1 'pond' is in force .* --replace .*--first-id"):
        plan_import(
            zf, {1: POND}, first_id=1, replace=False, floor=None, ceiling=None, issuer_id=9, now=0
        )
    plan = plan_import(
        zf, {1: POND}, first_id=1, replace=True, floor=None, ceiling=None, issuer_id=9, now=0
    )
    assert (plan[0].zone.zone_id, plan[0].action) == (1, "replace")
    assert plan[0].line().startswith("replace zone 1 'pond' with operating area 1")


def test_a_file_held_as_it_is_changes_nothing(tmp_path: Path) -> None:
    from gcs_cli.geofiles import save_zones

    path = tmp_path / "held.geojson"
    save_zones(path, [POND])
    plan = plan_import(
        zones_from_file(path),
        {1: msgspec.structs.replace(POND, time_unix_s=5.0, issuer_id=900)},
        first_id=None,
        replace=False,
        floor=None,
        ceiling=None,
        issuer_id=900,
        now=0,
    )
    assert [(p.zone.zone_id, p.action) for p in plan] == [(1, "unchanged")]


def test_fence_limits_are_said_with_the_limit() -> None:
    import math

    ring = [
        (37.41 + 0.01 * math.sin(a / 800), -5.99 + 0.01 * math.cos(a / 800)) for a in range(5000)
    ]
    big = NoFlyZone(7, Geometry.polygon(ring))
    (w,) = fence_warnings([big])
    assert "zone 7 has 5,000 vertices" in w and "holds 84 items" in w
    small = [NoFlyZone(i, Geometry.polygon(ring[:: 5000 // 30][:30])) for i in (1, 2, 3)]
    (w,) = fence_warnings(small)
    assert "need 90 fence items" in w and "holds 84" in w
    assert fence_warnings(small[:2]) == []


# --------------------------------------------------------------------------- a swarm


@pytest.fixture
def pond(zenoh_router: str) -> Iterator[Vehicle]:
    v = Vehicle(zenoh_router, "imp", 7, [POND])
    try:
        yield v
    finally:
        v.close()


def gcs(router: str, capsys: pytest.CaptureFixture[str], *args: str) -> tuple[int, str, str]:
    code = run(["--connect", router, "--swarm", "imp", *args])
    out, err = capsys.readouterr()
    return code, out, err


def test_dry_run_lists_what_would_be_declared_and_skipped_and_sends_nothing(
    zenoh_router: str, pond: Vehicle, capsys: pytest.CaptureFixture[str]
) -> None:
    code, out, _ = gcs(
        zenoh_router, capsys, "zone", "import", str(PLAN), "--dry-run", "--base-from-file"
    )
    assert code == 0, out
    assert "set the base at rally point 1: 37.410800,-5.989500" in out, out
    assert "declare operating area 2 'fence polygon 1'" in out, out
    assert (
        "declare no-fly zone 3 'fence polygon 2'" in out and "no-fly zone 4 'fence circle 1'" in out
    )
    assert "not imported:" in out and "rally point" not in out.split("not imported:")[1], out
    assert "area 'survey 2' (polygon): a survey area is a mission" in out, out
    assert "dry run: nothing sent" in out
    code, out, _ = gcs(zenoh_router, capsys, "zone", "import", str(PLAN), "--dry-run", "--json")
    data = json.loads(out)
    assert [z["zone_id"] for z in data["zones"]] == [2, 3, 4] and data[
        "ids_checked_against_the_vehicles"
    ]
    assert len(data["skipped"]) == 4 and pond.got == []


def test_a_clash_is_refused_and_nothing_sent(
    zenoh_router: str, pond: Vehicle, capsys: pytest.CaptureFixture[str]
) -> None:
    code, _, err = gcs(zenoh_router, capsys, "zone", "import", str(PLAN), "--first-id", "1")
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert "zone 1 'pond' is in force with another zone: add --replace" in err, err
    assert pond.got == [] and pond.zones[1] == POND


def test_import_next_to_a_zone_changes_none_and_sets_the_base(
    zenoh_router: str, pond: Vehicle, capsys: pytest.CaptureFixture[str]
) -> None:
    code, out, _ = gcs(
        zenoh_router, capsys, "zone", "import", str(PLAN), "--base-from-file", "--id", "7"
    )
    assert code == 0, out
    with pond.lock:
        got = list(pond.got)
    (base,) = [c for c in got if isinstance(c, Command)]
    assert base.kind == CommandKind.SET_BASE and base.args.point is not None
    assert (base.args.point.lat_deg, base.args.point.alt_msl_m) == (37.4108, 10.0)
    zones = [z for z in got if isinstance(z, NoFlyZone)]
    assert sorted(z.zone_id for z in zones) == [2, 3, 4]
    assert pond.zones[1] == POND  # untouched


def test_withdrawn_zones_list_as_withdrawn_and_an_id_never_held_is_not_removed(
    zenoh_router: str, capsys: pytest.CaptureFixture[str]
) -> None:
    """Withdrawn zones listed as "circle 0,0 r 1 m" (the withdrawal's placeholder), and
    removing an id never held left it "withdrawn, held by 7,8,9" on every vehicle."""
    gone = NoFlyZone(5, Geometry.circle(0.0, 0.0, 1.0), active=False, issuer_id=900)
    v = Vehicle(zenoh_router, "imp", 7, [POND, gone])
    try:
        code, out, _ = gcs(zenoh_router, capsys, "zone", "list", "--withdrawn")
        row = next(line for line in out.splitlines() if line.strip().startswith("5"))
        assert code == 0 and "withdrawn" in row and "0.00000" not in row and "r 1 m" not in row
        code, out, _ = gcs(zenoh_router, capsys, "zone", "list", "--withdrawn", "--json")
        z5 = next(z for z in json.loads(out) if z["zone_id"] == 5)
        assert z5["state"] == "withdrawn" and z5["geometry"] is None
        code, out, _ = gcs(zenoh_router, capsys, "zone", "remove", "77")
        assert code == 1 and "zone 77 is held by no vehicle (ids held: 1, 5)" in out, out
        code, out, _ = gcs(zenoh_router, capsys, "zone", "remove", "5")
        assert code == 0 and "zone 5 is already withdrawn" in out, out
        assert v.got == []  # nothing sent
    finally:
        v.close()
