"""`gcs db` through typer's CliRunner: every command, its JSON output and its error
paths (exit 1 with a message on stderr, the file untouched; exit 2 for usage)."""

from __future__ import annotations

import json
import os
import shutil
import sqlite3
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any, NamedTuple

import pytest
from typer.testing import CliRunner, Result

from gcs_cli.app import app
from swarm_node.database import SwarmDatabase
from swarm_node.database.tables import table, tables_of

ALB_LAYOUT = "Albatross 250 VTOL + EO 1.5 Mpx"
EMPTY_DOC = '{"format": "bandada-swarm-db", "schema_version": 2, "groups": {}}'


@pytest.fixture
def db(tmp_path: Path) -> Path:
    return tmp_path / "swarm.db"


def run(
    db: Path | None, *args: str, env: dict[str, str] | None = None, stdin: str | None = None
) -> Result:
    argv = ["db", *args]
    if db is not None:
        argv += ["--db", str(db)]
    base = {"BANDADA_DB": None}
    return CliRunner().invoke(app, argv, env={**base, **(env or {})}, input=stdin)  # type: ignore[dict-item]


def ok(result: Result) -> Result:
    assert result.exit_code == 0, result.output
    return result


def as_json(result: Result) -> Any:
    return json.loads(ok(result).stdout)


def failed(result: Result, match: str, code: int = 1) -> Result:
    assert result.exit_code == code, result.output
    assert match in result.stderr, result.stderr
    return result


def one_line_error(result: Result, match: str, code: int = 1) -> Result:
    """Exit `code` with one line on stderr, `error: ...` naming the problem; no traceback."""
    failed(result, match, code)
    assert result.exception is None or isinstance(result.exception, SystemExit), result.exception
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), result.stderr
    return result


def export_doc(groups: dict[str, Any]) -> str:
    return json.dumps({"format": "bandada-swarm-db", "schema_version": 2, "groups": groups})


def listing(directory: Path) -> dict[str, tuple[bytes, int] | None]:
    """Every entry of a directory, with each file's bytes and modification time: what
    "left untouched" means (no file changed, none appeared or vanished)."""
    return {
        p.name: (p.read_bytes(), p.stat().st_mtime_ns) if p.is_file() else None
        for p in sorted(directory.iterdir())
    }


# ---------------------------------------------------------------------------- the file


def test_a_missing_file_is_created_with_the_seed_data(db: Path) -> None:
    r = ok(run(db, "list"))
    assert "created" in r.stderr and str(db) in r.stderr
    assert "systems" in r.stdout and "detection-classes" in r.stdout
    assert as_json(run(db, "list", "--json"))["systems"]["systems"] == 14
    assert "created" not in run(db, "list").stderr


def test_the_env_var_and_the_default_path(tmp_path: Path) -> None:
    env_db = tmp_path / "env.db"
    assert ok(run(None, "path", env={"BANDADA_DB": str(env_db)})).stdout.strip() == str(env_db)
    ok(run(None, "list", env={"BANDADA_DB": str(env_db)}))
    assert env_db.exists()
    flag_db = tmp_path / "flag.db"
    assert ok(run(flag_db, "path", env={"BANDADA_DB": str(env_db)})).stdout.strip() == str(flag_db)
    xdg = tmp_path / "xdg"
    r = ok(run(None, "list", env={"XDG_DATA_HOME": str(xdg)}))
    assert (xdg / "bandada" / "swarm.db").exists(), r.stderr
    home = tmp_path / "home"
    r = ok(run(None, "path", env={"XDG_DATA_HOME": "", "HOME": str(home)}))
    assert r.stdout.strip() == str(home / ".local" / "share" / "bandada" / "swarm.db")


def _make_wal(p: Path) -> None:
    """Another application's database in WAL mode (checkpointed: nothing beside it)."""
    conn = sqlite3.connect(p)
    conn.execute("PRAGMA journal_mode = WAL")
    conn.execute("CREATE TABLE notes (body TEXT)")
    conn.commit()
    conn.close()


@pytest.mark.parametrize(
    ("make", "match"),
    [
        (
            lambda p: p.write_bytes(b"\x89PNG\r\n\x1a\n" + bytes(range(256)) * 8),
            "not an SQLite database file",
        ),
        (lambda p: p.write_bytes(b"SQLite format 3\x00" + b"\xff" * 4000), "damaged SQLite file"),
        ("foreign", "another application"),
        (_make_wal, "another application (application_id 0x0, tables: notes)"),
        ("newer", "newer bandada"),
    ],
    ids=["random", "damaged", "foreign", "foreign-wal", "newer"],
)
def test_a_corrupt_or_foreign_file_is_refused_and_untouched(
    db: Path, make: Any, match: str
) -> None:
    if make == "foreign":
        conn = sqlite3.connect(db)
        conn.execute("CREATE TABLE notes (body TEXT)")
        conn.commit()
        conn.close()
    elif make == "newer":
        SwarmDatabase.open(db).close()
        conn = sqlite3.connect(db)
        conn.execute("PRAGMA user_version = 7")
        conn.commit()
        conn.close()
    else:
        make(db)
    before = listing(db.parent)
    for args in (["list"], ["add", "systems", "types", "name=X"], ["import", "-"], ["export", "-"]):
        r = one_line_error(run(db, *args, stdin=EMPTY_DOC), match)
        assert "left it untouched" in r.stderr
    assert listing(db.parent) == before


# ---------------------------------------------------------------------------- list / show


def test_list_a_group_and_a_table(db: Path) -> None:
    r = ok(run(db, "list", "payload"))
    assert "payload.gimbals" in r.stdout and "payload.motors" in r.stdout
    group = as_json(run(db, "list", "payload", "--json"))
    assert set(group) >= {"types", "subtypes", "models", "sensor-params", "detection-classes"}
    systems = as_json(run(db, "list", "systems", "systems", "--json"))
    assert [s["user_id"] for s in systems][:2] == ["ALB-01", "ALB-02"]
    r = ok(run(db, "list", "systems", "model-params"))
    assert "Albatross 250" in r.stdout and "26.0" in r.stdout
    for group in ("systems", "swarm", "payload", "common"):
        ok(run(db, "list", group))


def test_list_errors(db: Path) -> None:
    failed(run(db, "list", "fleet"), "unknown group 'fleet'", 2)
    failed(run(db, "list", "systems", "cars"), "unknown table 'cars' in group systems", 2)


def test_show(db: Path) -> None:
    assert as_json(run(db, "show", "systems", "systems", "ALB-03", "--json"))["id"] == 3
    assert as_json(run(db, "show", "systems", "systems", "900", "--json"))["user_id"] == "GCS-01"
    model = as_json(run(db, "show", "systems", "models", "Albatross 250 VTOL", "--json"))
    assert model["subtype"] == "VTOL"
    param = as_json(run(db, "show", "systems", "params", "1", "mav_sysid", "--json"))
    assert param["value"] == "1"
    assert (
        "cruise_speed_m_s" in ok(run(db, "show", "systems", "model-params", "Generic Boat")).stdout
    )
    failed(run(db, "show", "systems", "models", "Nope"), "no record with name='Nope'")
    failed(run(db, "show", "systems", "params", "1"), "named by system + name")
    ok(run(db, "add", "systems", "systems", "user_id=ALB-03", "layout=Rover + SDR"))
    failed(run(db, "show", "systems", "systems", "ALB-03"), "names several records")


# ---------------------------------------------------------------------------- add / remove


def test_add_records(db: Path) -> None:
    r = ok(run(db, "add", "systems", "systems", "user_id=ALB-07", f"layout={ALB_LAYOUT}"))
    assert "id=14" in r.stdout
    rec = as_json(run(db, "add", "systems", "models", "name=Sea Drone", "subtype=boat", "--json"))
    assert rec == {"name": "Sea Drone", "subtype": "boat", "description": ""}
    params = as_json(
        run(
            db,
            "add",
            "systems",
            "model-params",
            "--record",
            '{"model": "Sea Drone", "cruise_speed_m_s": 3, "max_speed_m_s": 6}',
            "has_parachute=no",
            "battery_low_pct=40",
            "--json",
        )
    )
    assert params["cruise_speed_m_s"] == 3.0 and params["has_parachute"] is False
    ok(
        run(
            db,
            "add",
            "systems",
            "layouts",
            "name=Sea Drone bare",
            "model=Sea Drone",
            "payload_layout=",
        )
    )
    ok(run(db, "add", "swarm", "missions", "name=search", "mission_type=8"))
    assert (
        as_json(run(db, "show", "systems", "subtypes", "boat", "--json"))["vehicle_type"] == "BOAT"
    )
    ok(
        run(
            db,
            "add",
            "common",
            "corrections",
            "bug_id=BND-7",
            "module=voting",
            "description=ties",
            "criticality=high",
        )
    )
    ok(run(db, "add", "payload", "detection-classes", "name=drone"))
    prof = as_json(run(db, "profile", "14", "--json"))
    assert prof["profile"]["user_id"] == "ALB-07" and prof["params"] == {}


@pytest.mark.parametrize(
    ("args", "match", "code"),
    [
        (
            ["systems", "systems", "user_id=X", "layout=Nope"],
            "layout 'Nope' not found in systems.layouts",
            1,
        ),
        (
            ["systems", "layouts", "name=L", "model=Albatros 250"],
            "did you mean 'Albatross 250 VTOL'",
            1,
        ),
        (
            ["systems", "systems", "user_id=ALB-01", f"layout={ALB_LAYOUT}"],
            "same user_id + layout exists",
            1,
        ),
        (["systems", "models", "name=Albatross 250 VTOL", "subtype=VTOL"], "same name exists", 1),
        (
            ["systems", "params", "system=99", "name=a", "value=b"],
            "system 99 not found in systems.systems",
            1,
        ),
        (
            ["systems", "model-params", "model=Generic Boat", "cruise_speed_m_s=fast"],
            "could not convert",
            1,
        ),
        (["systems", "types", "wheels=4"], "unknown field 'wheels'", 1),
        (["systems", "types", "description=x"], "field 'name' is required", 1),
        (["systems", "types", "name= padded"], "breaks the rule", 1),
        (["systems", "types", "name"], "expected FIELD=VALUE", 2),
        (["systems", "types", "--record", "{bad"], "--record: not valid JSON", 2),
        (["systems", "types", "--record", "[1]"], "expected a JSON object", 2),
        (["systems", "cars", "name=x"], "unknown table 'cars'", 2),
        (["swarm", "missions", "name=m", "mission_type=SURVEY"], "unknown MissionType 'SURVEY'", 1),
    ],
)
def test_add_errors(db: Path, args: list[str], match: str, code: int) -> None:
    ok(run(db, "list"))
    before = as_json(run(db, "list", "--json"))
    failed(run(db, "add", *args), match, code)
    assert as_json(run(db, "list", "--json")) == before


def test_remove(db: Path) -> None:
    r = ok(run(db, "remove", "systems", "systems", "QUAD-03"))
    assert "removed from systems.systems" in r.stdout and "QUAD-03" in r.stdout
    failed(run(db, "show", "systems", "systems", "QUAD-03"), "no record with user id")
    rec = as_json(run(db, "remove", "payload", "payloads", "9", "--json"))
    assert rec["user_id"] == "TH640-01"
    failed(
        run(db, "remove", "systems", "models", "Generic Rover"),
        "still used by 1 record(s) of systems.layouts",
    )
    failed(run(db, "remove", "payload", "types", "optical"), "still used by")
    failed(run(db, "remove", "systems", "models", "Nope"), "no record with name='Nope'")
    ok(run(db, "remove", "systems", "params", "1", "mac_address"))


# ---------------------------------------------------------------------------- export / import


def _sorted(doc: dict[str, Any]) -> dict[str, Any]:
    return {
        g: {
            t: sorted(recs, key=lambda r: json.dumps(r, sort_keys=True))
            for t, recs in tables.items()
        }
        for g, tables in doc["groups"].items()
    }


def test_export_import_round_trip(db: Path, tmp_path: Path) -> None:
    out = tmp_path / "fleet.json"
    ok(run(db, "export", str(out)))
    doc = json.loads(out.read_text())
    assert doc["format"] == "bandada-swarm-db" and set(doc["groups"]) == {
        "systems",
        "swarm",
        "payload",
        "common",
    }
    other = tmp_path / "other.db"
    ok(run(other, "remove", "systems", "systems", "ALB-06"))
    r = ok(run(other, "import", str(out)))
    assert "imported" in r.stdout
    ok(run(other, "export", str(tmp_path / "again.json")))
    # the same records (re-added ones come last: compare in key order)
    assert _sorted(json.loads((tmp_path / "again.json").read_text())) == _sorted(doc)
    stdout_doc = as_json(run(db, "export", "-"))
    assert stdout_doc == doc
    part = as_json(run(db, "export", "-", "--group", "swarm", "-g", "common"))
    assert set(part["groups"]) == {"swarm", "common"}
    ok(run(other, "import", "-", stdin=json.dumps(part)))
    failed(run(db, "export", "-", "--group", "fleet"), "unknown group 'fleet'", 2)
    failed(run(db, "export", str(tmp_path / "no" / "dir" / "x.json")), "cannot write")


def test_import_replace(db: Path, tmp_path: Path) -> None:
    doc = as_json(run(db, "export", "-", "-g", "common"))
    doc["groups"]["common"]["comms"] = []
    f = tmp_path / "common.json"
    f.write_text(json.dumps(doc))
    ok(run(db, "import", str(f), "--replace"))
    assert as_json(run(db, "list", "--json"))["common"]["comms"] == 0


@pytest.mark.parametrize(
    ("content", "match"),
    [
        ("{not json", "not valid JSON"),
        ('{"format": "x"}', "not a bandada swarm database export"),
        ('{"format": "bandada-swarm-db", "schema_version": 9, "groups": {}}', "newer bandada"),
        (
            '{"format": "bandada-swarm-db", "schema_version": 2, "groups": {"systems": {"systems": '
            '[{"id": 50, "user_id": "N", "layout": "Gone"}]}}}',
            "systems.systems[0]: systems.systems: layout 'Gone' not found in systems.layouts",
        ),
        (
            '{"format": "bandada-swarm-db", "schema_version": 2, "groups": {"systems": {"systems": '
            '[{"id": 50, "user_id": "ALB-01", "layout": "Albatross 250 VTOL + EO 1.5 Mpx"}]}}}',
            "same user_id + layout exists",
        ),
        (
            '{"format": "bandada-swarm-db", "schema_version": 2, "groups": {"systems": {"models": '
            '[{"name": "X", "subtype": "hovercraft"}]}}}',
            "subtype 'hovercraft' not found in systems.subtypes",
        ),
    ],
    ids=["json", "format", "newer", "broken-reference", "duplicate", "unknown-subtype"],
)
def test_import_errors_write_nothing(db: Path, tmp_path: Path, content: str, match: str) -> None:
    ok(run(db, "list"))
    before = db.read_bytes()
    f = tmp_path / "in.json"
    f.write_text(content)
    r = failed(run(db, "import", str(f)), match)
    assert str(f) in r.stderr
    assert db.read_bytes() == before


def test_import_a_missing_file(db: Path, tmp_path: Path) -> None:
    failed(run(db, "import", str(tmp_path / "nope.json")), "cannot read")


# ---------------------------------------------------------------------------- every group


class GroupCase(NamedTuple):
    """What the CLI tests do in one group: a seed record to show, a record to add,
    show and remove, a seed record to remove (with what goes with it), and one in use."""

    table: str
    key: list[str]
    shown: dict[str, Any]  # fields of the seed record shown by `key`
    new: list[str]  # FIELD=VALUE of a record to add
    new_key: list[str]
    seed_removal: tuple[str, list[str], dict[str, int]]  # table, key, counts that drop
    in_use: tuple[str, list[str], str]  # table, key, who uses it


GROUP_CASES = {
    "systems": GroupCase(
        "models",
        ["Generic Boat"],
        {"name": "Generic Boat", "subtype": "boat"},
        ["name=Sea Drone", "subtype=boat", "description=autonomous hull"],
        ["Sea Drone"],
        ("systems", ["QUAD-03"], {"systems.systems": 1, "systems.params": 2, "common.comms": 1}),
        ("models", ["Generic Rover"], "still used by 1 record(s) of systems.layouts (Rover + SDR)"),
    ),
    "swarm": GroupCase(
        "missions",
        ["area"],
        {"name": "area", "mission_type": "AREA"},
        ["name=search and rescue", "mission_type=255", "description=find people"],
        ["search and rescue"],
        ("missions", ["area"], {"swarm.missions": 1, "swarm.mission-params": 2}),
        ("modules", ["voting"], ""),  # nothing references a module but its own params
    ),
    "payload": GroupCase(
        "layouts",
        ["EO 1.5 Mpx 2-axis"],
        {"name": "EO 1.5 Mpx 2-axis", "model": "EO 1.5 Mpx 2-axis gimbal", "sensor": "EO 1.5 Mpx"},
        ["name=EO bare", "model=EO 1.5 Mpx 2-axis gimbal", "gimbal=", "sensor=EO 1.5 Mpx"],
        ["EO bare"],
        ("detection-classes", ["person"], {"payload.detection-classes": 1}),
        ("types", ["optical"], "used by 2 record(s) of payload.subtypes (visible camera, thermal"),
    ),
    "common": GroupCase(
        "pids",
        ["gimbal roll"],
        {"name": "gimbal roll", "p": 0.8, "anti_windup": True},
        ["name=winch", "p=1.5", "i=0.1", "d=0", "max_integral=5", "anti_windup=no"],
        ["winch"],
        ("comms", ["XTend GCS-01"], {"common.comms": 1}),
        (
            "computers",
            ["Jetson Orin Nano"],
            "still used by 1 record(s) of systems.layouts (Albatross 250 VTOL + EO 1.5 Mpx)",
        ),
    ),
}
GROUP_NAMES = list(GROUP_CASES)


def _counts(db: Path) -> dict[str, int]:
    return {
        f"{g}.{t}": n
        for g, tables in as_json(run(db, "list", "--json")).items()
        for t, n in tables.items()
    }


@pytest.mark.parametrize("group", GROUP_NAMES)
def test_list_every_group_with_and_without_json(db: Path, group: str) -> None:
    case = GROUP_CASES[group]
    counts = as_json(run(db, "list", "--json"))[group]
    assert set(counts) == {t.name for t in tables_of(group)}
    tables = as_json(run(db, "list", group, "--json"))
    assert {t: len(recs) for t, recs in tables.items()} == counts
    text = ok(run(db, "list", group)).stdout
    for t in tables_of(group):
        assert t.qualname in text  # the title (rich wraps it in narrow tables)
    records = as_json(run(db, "list", group, case.table, "--json"))
    assert records == tables[case.table] and len(records) == counts[case.table]
    text = ok(run(db, "list", group, case.table, env={"COLUMNS": "300"})).stdout  # no wrapping
    assert all(str(v) in text for v in case.shown.values())


@pytest.mark.parametrize("group", GROUP_NAMES)
def test_show_every_group_with_and_without_json(db: Path, group: str) -> None:
    case = GROUP_CASES[group]
    record = as_json(run(db, "show", group, case.table, *case.key, "--json"))
    assert record.items() >= case.shown.items()
    assert set(record) == set(table(group, case.table).field_names)
    text = ok(run(db, "show", group, case.table, *case.key)).stdout
    assert f"{group}.{case.table}" in text
    for field, value in case.shown.items():
        assert field in text and str(value) in text
    one_line_error(run(db, "show", group, case.table, "no such record"), "no record with")
    one_line_error(run(db, "show", group, "cars", "x"), f"unknown table 'cars' in group {group}", 2)


@pytest.mark.parametrize("group", GROUP_NAMES)
def test_add_show_remove_in_every_group(db: Path, group: str) -> None:
    case = GROUP_CASES[group]
    before = _counts(db)
    added = as_json(run(db, "add", group, case.table, *case.new, "--json"))
    assert as_json(run(db, "show", group, case.table, *case.new_key, "--json")) == added
    assert _counts(db) == {**before, f"{group}.{case.table}": before[f"{group}.{case.table}"] + 1}
    one_line_error(run(db, "add", group, case.table, *case.new), "a record with the same")
    r = ok(run(db, "remove", group, case.table, *case.new_key))
    assert r.stdout.startswith(f"removed from {group}.{case.table}: ")
    assert _counts(db) == before
    one_line_error(run(db, "remove", group, case.table, *case.new_key), "no record with")
    # a seed record, and what belongs to it (its parameters) with it
    t, key, drops = case.seed_removal
    removed = as_json(run(db, "remove", group, t, *key, "--json"))
    assert set(removed) == set(table(group, t).field_names)
    assert _counts(db) == {k: n - drops.get(k, 0) for k, n in before.items()}
    # a record in use by others is refused, nothing changes
    t, key, users = case.in_use
    if users:
        snapshot = db.read_bytes()
        one_line_error(run(db, "remove", group, t, *key), users)
        assert db.read_bytes() == snapshot
    else:
        ok(run(db, "remove", group, t, *key))


@pytest.mark.parametrize("group", GROUP_NAMES)
def test_export_import_every_group(db: Path, tmp_path: Path, group: str) -> None:
    case = GROUP_CASES[group]
    out = tmp_path / f"{group}.json"
    ok(run(db, "add", group, case.table, *case.new))
    ok(run(db, "export", str(out), "--group", group))
    doc = json.loads(out.read_text())
    assert list(doc["groups"]) == [group]
    assert doc["groups"][group] == as_json(run(db, "list", group, "--json"))
    assert as_json(run(db, "export", "-", "-g", group)) == doc
    # into a fresh database (seed data), replacing the group's tables: same records
    other = tmp_path / "other.db"
    ok(run(other, "remove", group, case.seed_removal[0], *case.seed_removal[1]))
    r = ok(run(other, "import", str(out), "--replace"))
    assert f"from {out}" in r.stdout
    assert _sorted(as_json(run(other, "export", "-", "-g", group))) == _sorted(doc)
    assert as_json(run(other, "show", group, case.table, *case.new_key, "--json")) == as_json(
        run(db, "show", group, case.table, *case.new_key, "--json")
    )


# Clear errors, exit 1, nothing written: unknown models, duplicate user id + layout,
# broken references, broken rules; in every group where they apply.
ADD_ERRORS = [
    pytest.param(
        ["systems", "layouts", "name=L", "model=Albatros 250"],
        "systems.layouts: model 'Albatros 250' not found in systems.models; "
        "did you mean 'Albatross 250 VTOL'?",
        id="systems-unknown-model",
    ),
    pytest.param(
        ["systems", "model-params", "model=Nope", "cruise_speed_m_s=1", "max_speed_m_s=2"],
        "systems.model-params: model 'Nope' not found in systems.models",
        id="systems-unknown-model-params",
    ),
    pytest.param(
        ["systems", "systems", "user_id=ALB-01", f"layout={ALB_LAYOUT}"],
        "systems.systems: a record with the same user_id + layout exists (user_id='ALB-01'",
        id="systems-duplicate-user-id-layout",
    ),
    pytest.param(
        ["systems", "systems", "user_id=X", "layout=Nope"],
        "systems.systems: layout 'Nope' not found in systems.layouts",
        id="systems-broken-layout",
    ),
    pytest.param(
        ["systems", "systems", "user_id=X", f"layout={ALB_LAYOUT}", "payload=999"],
        "systems.systems: payload 999 not found in payload.payloads",
        id="systems-broken-payload",
    ),
    pytest.param(
        ["systems", "systems", "user_id=X", f"layout={ALB_LAYOUT}", "payload=10"],
        "system payload",  # an SDR on a camera layout: a trigger
        id="systems-payload-of-another-layout",
    ),
    pytest.param(
        ["swarm", "modules", "name=m", "subtype=hovercraft"],
        "swarm.modules: subtype 'hovercraft' not found in systems.subtypes",
        id="swarm-broken-subtype",
    ),
    pytest.param(
        ["swarm", "module-params", "module=nope", "name=a", "value=1"],
        "swarm.module-params: module 'nope' not found in swarm.modules",
        id="swarm-broken-module",
    ),
    pytest.param(
        ["swarm", "mission-params", "mission=area", "name=altitude_rel_m", "value=50"],
        "swarm.mission-params: a record with the same mission + name exists",
        id="swarm-duplicate-param",
    ),
    pytest.param(
        ["swarm", "missions", "name=again", "mission_type=AREA"],
        "swarm.missions: a record with the same mission_type exists",
        id="swarm-duplicate-mission-type",
    ),
    pytest.param(
        ["payload", "layouts", "name=L", "model=EO 1.5 Mpx"],
        "payload.layouts: model 'EO 1.5 Mpx' not found in payload.models; known: 'EO 1.5 Mpx 2-axis",
        id="payload-unknown-model",
    ),
    pytest.param(
        ["payload", "payloads", "user_id=CAM-01", "layout=EO 1.5 Mpx 2-axis"],
        "payload.payloads: a record with the same user_id + layout exists (user_id='CAM-01'",
        id="payload-duplicate-user-id-layout",
    ),
    pytest.param(
        ["payload", "gimbals", "name=g", "baud_rate=9600", "period_ms=20", "pan_axis=nope"],
        "payload.gimbals: pan_axis 'nope' not found in payload.gimbal-axes",
        id="payload-broken-axis",
    ),
    pytest.param(
        ["payload", "gimbals", "name=g", "baud_rate=9600", "period_ms=20", "pan_axis=roll +-45"],
        "gimbal axis kind",
        id="payload-axis-of-another-kind",
    ),
    pytest.param(
        ["payload", "params", "payload=99", "name=a", "value=b"],
        "payload.params: payload 99 not found in payload.payloads",
        id="payload-broken-payload",
    ),
    pytest.param(
        ["common", "comms", "name=radio", "kind=wifi", "system=4242"],
        "common.comms: system 4242 not found in systems.systems",
        id="common-broken-system",
    ),
    pytest.param(
        ["common", "pids", "name=gimbal roll", "p=1", "i=0", "d=0", "max_integral=1"],
        "common.pids: a record with the same name exists",
        id="common-duplicate-name",
    ),
    pytest.param(
        ["common", "corrections", "bug_id=B-1", "module=m", "description=d", "criticality=urgent"],
        "common.corrections: the record breaks the rule",
        id="common-unknown-criticality",
    ),
    pytest.param(
        ["common", "pids", "name=p", "p=nan", "i=0", "d=0", "max_integral=1"],
        "common.pids.p: expected a finite number",
        id="common-nan",
    ),
]


@pytest.mark.parametrize(("args", "match"), ADD_ERRORS)
def test_add_errors_in_every_group(db: Path, args: list[str], match: str) -> None:
    ok(run(db, "list"))
    before = listing(db.parent)
    one_line_error(run(db, "add", *args), match)
    assert listing(db.parent) == before


IMPORT_ERRORS = [
    pytest.param(
        {"systems": {"layouts": [{"name": "L", "model": "Gone"}]}},
        "systems.layouts[0]: systems.layouts: model 'Gone' not found in systems.models",
        id="systems-unknown-model",
    ),
    pytest.param(
        {"systems": {"systems": [{"id": 50, "user_id": "ALB-01", "layout": ALB_LAYOUT}]}},
        "systems.systems[0]: systems.systems: a record with the same user_id + layout exists",
        id="systems-duplicate-user-id-layout",
    ),
    pytest.param(
        {"swarm": {"module-params": [{"module": "Gone", "name": "a", "value": 1.0}]}},
        "swarm.module-params[0]: swarm.module-params: module 'Gone' not found in swarm.modules",
        id="swarm-broken-module",
    ),
    pytest.param(
        {"payload": {"layouts": [{"name": "L", "model": "Gone"}]}},
        "payload.layouts[0]: payload.layouts: model 'Gone' not found in payload.models",
        id="payload-unknown-model",
    ),
    pytest.param(
        {"payload": {"payloads": [{"id": 60, "user_id": "CAM-01", "layout": "EO 1.5 Mpx 2-axis"}]}},
        "payload.payloads[0]: payload.payloads: a record with the same user_id + layout exists",
        id="payload-duplicate-user-id-layout",
    ),
    pytest.param(
        {"common": {"comms": [{"name": "r", "kind": "wifi", "system": 4242}]}},
        "common.comms[0]: common.comms: system 4242 not found in systems.systems",
        id="common-broken-system",
    ),
    pytest.param(  # valid records first, the broken one last: none is written
        {
            "common": {
                "corrections": [
                    {"bug_id": "B-1", "module": "m", "description": "d", "criticality": "low"}
                ]
            },
            "swarm": {"missions": [{"name": "new", "mission_type": 200}]},
            "systems": {
                "types": [{"name": "UUV"}],
                "subtypes": [{"name": "sub", "type": "UUV", "vehicle_type": "Gone"}],
            },
        },
        "systems.subtypes[0]: systems.subtypes.vehicle_type: unknown VehicleType 'Gone'",
        id="all-or-nothing",
    ),
]


@pytest.mark.parametrize(("groups", "match"), IMPORT_ERRORS)
def test_import_errors_in_every_group(
    db: Path, tmp_path: Path, groups: dict[str, Any], match: str
) -> None:
    ok(run(db, "list"))
    f = tmp_path / "in.json"
    f.write_text(export_doc(groups))
    before = listing(tmp_path)
    r = one_line_error(run(db, "import", str(f)), match)
    assert r.stderr.startswith(f"error: {f}: ")
    one_line_error(run(db, "import", "-", stdin=export_doc(groups)), match)
    assert listing(tmp_path) == before


# ---------------------------------------------------------------------------- bad input


DEEP = "[" * 2000 + "]" * 2000


def test_deeply_nested_json_is_a_clear_error(db: Path, tmp_path: Path) -> None:
    deep = tmp_path / "deep.json"
    deep.write_text(DEEP)
    # the document is refused before the database is opened: a missing one stays missing
    one_line_error(run(db, "import", str(deep)), f"{deep}: not usable JSON (arrays or objects")
    assert not db.exists()
    ok(run(db, "list"))
    before = listing(tmp_path)
    one_line_error(run(db, "import", str(deep)), "nested too deeply")
    one_line_error(run(db, "import", "-", stdin=DEEP), "-: not usable JSON")
    one_line_error(run(db, "add", "systems", "types", "--record", DEEP), "--record: not usable", 2)
    # deep, but not too deep to decode: the value is refused, and shown shortened
    value = "[" * 900 + "]" * 900
    one_line_error(
        run(
            db,
            "import",
            "-",
            stdin=export_doc({"systems": {"types": [{"name": json.loads(value)}]}}),
        ),
        "systems.types[0]: systems.types.name: expected text, got [[[[...]]]]",
    )
    one_line_error(
        run(db, "add", "systems", "types", "--record", '{"name": ' + value + "}"),
        "systems.types.name: expected text, got [[[[...]]]]",
    )
    assert listing(tmp_path) == before


@pytest.mark.parametrize(
    ("where", "match"),
    [
        ("/proc/bandada-nope/swarm.db", "cannot create the directory /proc/bandada-nope"),
        ("{tmp}/a-file/swarm.db", "cannot create it: {tmp}/a-file is not a directory"),
        ("{tmp}/a-file/deeper/swarm.db", "cannot create it: {tmp}/a-file is not a directory"),
        ("{tmp}/a-dir", "{tmp}/a-dir: is a directory, not a database file"),
        ("{tmp}/a-fifo", "{tmp}/a-fifo: is not a regular file"),
    ],
    ids=["parent-cannot-be-created", "parent-is-a-file", "ancestor-is-a-file", "dir", "fifo"],
)
def test_a_path_that_cannot_hold_a_database(tmp_path: Path, where: str, match: str) -> None:
    if where.startswith("/proc") and not Path("/proc/self").exists():
        pytest.skip("no /proc")
    (tmp_path / "a-file").write_text("notes")
    (tmp_path / "a-dir").mkdir()
    os.mkfifo(tmp_path / "a-fifo")  # reading it would block: never opened
    before = listing(tmp_path)
    path = where.format(tmp=tmp_path)
    for args in (["list"], ["add", "systems", "types", "name=X"], ["import", "-"], ["export", "-"]):
        one_line_error(run(Path(path), *args, stdin=EMPTY_DOC), match.format(tmp=tmp_path))
    assert listing(tmp_path) == before
    assert not Path("/proc/bandada-nope").exists()


def test_a_failed_export_leaves_no_temporary_file(db: Path, tmp_path: Path) -> None:
    ok(run(db, "list"))
    (tmp_path / "out").mkdir()
    before = listing(tmp_path)
    one_line_error(run(db, "export", str(tmp_path / "out")), f"cannot write {tmp_path / 'out'}")
    one_line_error(run(db, "export", str(tmp_path / "no" / "dir" / "x.json")), "cannot write")
    assert listing(tmp_path) == before and listing(tmp_path / "out") == {}


def _gcs(*args: str, prefix: list[str] | None = None) -> subprocess.CompletedProcess[str]:
    """`gcs db ...` in a child process (optionally under a wrapper command)."""
    cmd = [sys.executable, "-c", "from gcs_cli.app import main; main()", "db", *args]
    env = {k: v for k, v in os.environ.items() if k != "BANDADA_DB"}
    return subprocess.run(
        [*(prefix or []), *cmd], capture_output=True, text=True, timeout=120, env=env
    )


def _one_line_error(r: subprocess.CompletedProcess[str], match: str) -> None:
    assert r.returncode == 1, (r.stdout, r.stderr)
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and match in lines[0], r.stderr


@pytest.fixture
def unprivileged() -> list[str]:
    """A command prefix under which file permissions apply: none for a normal user; for
    root, setpriv drops the capabilities that override them (CAP_DAC_*)."""
    if os.geteuid() != 0:
        return []
    setpriv = shutil.which("setpriv")
    if setpriv is None:
        pytest.skip("running as root without setpriv: permissions do not apply")
    prefix = [setpriv, "--bounding-set=-dac_override,-dac_read_search"]
    probe = subprocess.run([*prefix, "true"], capture_output=True, timeout=30)
    if probe.returncode != 0:
        pytest.skip(f"setpriv cannot drop capabilities here: {probe.stderr!r}")
    return prefix


def test_permission_denied(tmp_path: Path, unprivileged: list[str]) -> None:
    readonly, unreadable = tmp_path / "readonly.db", tmp_path / "unreadable.db"
    SwarmDatabase.open(readonly).close()
    unreadable.write_bytes(readonly.read_bytes())
    readonly.chmod(0o444)
    unreadable.chmod(0o000)
    locked = tmp_path / "locked"
    locked.mkdir(mode=0o555)
    shut = tmp_path / "shut"
    shut.mkdir(mode=0o000)
    try:
        before = listing(tmp_path)
        assert "systems" in _gcs("list", "--db", str(readonly), prefix=unprivileged).stdout
        _one_line_error(
            _gcs("add", "systems", "types", "name=X", "--db", str(readonly), prefix=unprivileged),
            f"{readonly}: cannot write to it (attempt to write a readonly database)",
        )
        _one_line_error(
            _gcs("list", "--db", str(unreadable), prefix=unprivileged),
            f"{unreadable}: cannot read it (Permission denied)",
        )
        _one_line_error(
            _gcs("list", "--db", str(locked / "swarm.db"), prefix=unprivileged),
            f"{locked / 'swarm.db'}: cannot open it",
        )
        _one_line_error(
            _gcs("list", "--db", str(locked / "sub" / "swarm.db"), prefix=unprivileged),
            f"cannot create the directory {locked / 'sub'} (Permission denied)",
        )
        _one_line_error(
            _gcs("list", "--db", str(shut / "swarm.db"), prefix=unprivileged),
            f"{shut / 'swarm.db'}: cannot read it (Permission denied)",
        )
        assert listing(tmp_path) == before
        assert sorted(p.name for p in locked.iterdir()) == []
    finally:
        shut.chmod(0o755)
        locked.chmod(0o755)
        unreadable.chmod(0o644)


@pytest.fixture
def read_only_mount() -> list[str]:
    """A command prefix that runs the command with its first argument (a directory)
    bind-mounted read-only, in a private mount namespace (unshare); skips where user
    namespaces are not allowed."""
    unshare = shutil.which("unshare")
    if unshare is None or not sys.platform.startswith("linux"):
        pytest.skip("no unshare")
    script = 'mount --bind -o ro "$1" "$1" || exit 97; shift; exec "$@"'
    prefix = [unshare, "--user", "--map-root-user", "--mount", "sh", "-c", script, "sh"]
    with tempfile.TemporaryDirectory() as d:
        probe = subprocess.run([*prefix, d, "touch", f"{d}/x"], capture_output=True, timeout=30)
        if probe.returncode == 0 or b"Read-only file system" not in probe.stderr:
            pytest.skip(f"cannot mount read-only here: {probe.stderr!r}")
    return prefix


def test_a_read_only_filesystem(tmp_path: Path, read_only_mount: list[str]) -> None:
    ro = tmp_path / "ro"
    ro.mkdir()
    db = ro / "swarm.db"
    SwarmDatabase.open(db).close()
    before = listing(ro)

    def gcs(*args: str) -> subprocess.CompletedProcess[str]:
        return _gcs(*args, prefix=[*read_only_mount, str(ro)])

    assert gcs("list", "--json", "--db", str(db)).returncode == 0  # reading needs no write
    _one_line_error(
        gcs("add", "systems", "types", "name=X", "--db", str(db)),
        f"{db}: cannot write to it (attempt to write a readonly database)",
    )
    _one_line_error(gcs("list", "--db", str(ro / "new.db")), f"{ro / 'new.db'}: cannot open it")
    _one_line_error(
        gcs("list", "--db", str(ro / "sub" / "new.db")),
        f"cannot create the directory {ro / 'sub'} (Read-only file system)",
    )
    _one_line_error(
        gcs("export", str(ro / "out.json"), "--db", str(db)),
        f"cannot write {ro / 'out.json'}: Read-only file system",
    )
    assert listing(ro) == before


@pytest.mark.parametrize(
    ("args", "match"),
    [
        (
            ["5", "--connect", "nonsense"],
            "'nonsense' is not a Zenoh endpoint: write PROTOCOL/HOST:PORT",
        ),
        (["5", "--timeout", "nan"], "--timeout must be a positive number of seconds, got nan"),
        (["5", "--timeout", "-1"], "--timeout must be a positive number"),
        (["a/b"], "node must be a node id (1..65534) or '*', got 'a/b'"),
        (["65535"], "node must be a node id"),
        (["5", "--swarm", "bad swarm"], "swarm name"),
    ],
    ids=["endpoint", "nan-timeout", "negative-timeout", "node-key", "node-range", "swarm"],
)
def test_query_usage_errors(args: list[str], match: str) -> None:
    """Refused before any query (a NaN timeout used to loop forever; a bad endpoint
    printed Zenoh's Rust debug text in a traceback)."""
    one_line_error(run(None, "query", *args), match, 2)


# ---------------------------------------------------------------------------- profile


def test_profile(db: Path) -> None:
    r = ok(run(db, "profile", "ALB-01"))
    assert "VTOL (2)" in r.stdout and "turn radius" in r.stdout and "68.9" in r.stdout
    data = as_json(run(db, "profile", "7", "--json"))
    assert data["profile"]["model"] == "Generic Quadcopter"
    assert data["profile"]["camera"]["resolution_px"] == [1920, 1080]
    assert data["params"]["mav_sysid"] == "7"
    failed(run(db, "profile", "4242"), "no system with id 4242")
    ok(run(db, "add", "systems", "systems", "user_id=ALB-01", "layout=Rover + SDR"))
    failed(run(db, "profile", "ALB-01"), "names several systems")
    assert (
        as_json(run(db, "profile", "ALB-01", "--model", "Generic Rover", "--json"))["profile"][
            "vehicle_id"
        ]
        == 14
    )


# ---------------------------------------------------------------------------- query


@pytest.mark.network
def test_query_a_peer_over_zenoh(zenoh_router: str) -> None:
    import time

    from swarm_node.database.queryable import DatabaseQueryable
    from swarm_proto.session import ZenohSettings, open_session

    session = open_session(ZenohSettings(connect=(zenoh_router,)))
    db = SwarmDatabase.memory()
    q = DatabaseQueryable(session, db, node_id=5, swarm="clitest")
    try:
        deadline = time.monotonic() + 20
        while True:
            r = run(
                None,
                "query",
                "5",
                "profile",
                "--connect",
                zenoh_router,
                "--swarm",
                "clitest",
                "--timeout",
                "2",
            )
            if r.exit_code == 0 or time.monotonic() > deadline:
                break
        replies = as_json(r)
        assert replies[0]["key"] == "bandada/clitest/db/5/profile"
        assert replies[0]["value"]["user_id"] == "ALB-05"
        failed(
            run(None, "query", "5", "nope", "--connect", zenoh_router, "--swarm", "clitest"),
            "no such resource",
        )
        failed(
            run(
                None,
                "query",
                "6",
                "--connect",
                zenoh_router,
                "--swarm",
                "clitest",
                "--timeout",
                "0.5",
            ),
            "no reply",
        )
        failed(run(None, "query", "5", "--swarm", "bad swarm"), "swarm name", 2)
    finally:
        q.close()
        db.close()
        session.close()
