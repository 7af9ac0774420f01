"""Every bad record the repository can be given (NaN and infinities, negative speeds,
empty or padded names, wrong types, references to records that do not exist, broken
rules) is a RecordError naming the table and the field or rule, through `add` and
through `import_document` alike, and leaves no partial state: the file is byte for
byte what it was. SQLite failures that are no broken rule (a lock held too long) are
a StorageError, also with nothing written."""

from __future__ import annotations

import math
import re
import sqlite3
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from swarm_node.database import (
    ConstraintError,
    DocumentError,
    DuplicateError,
    InvalidValueError,
    RecordError,
    StorageError,
    SwarmDatabase,
    UnknownReferenceError,
    repository,
)
from swarm_node.database.document import FORMAT, decode_json
from swarm_node.database.tables import BY_NAME

ALB_LAYOUT = "Albatross 250 VTOL + EO 1.5 Mpx"
SPEEDS = {"cruise_speed_m_s": 10.0, "max_speed_m_s": 20.0}

# (table, record, error, message) -- for a new record (add, or import of a new key)
BAD: list[Any] = [
    # numbers
    (
        "systems.model-params",
        {"model": "M", **SPEEDS, "cruise_speed_m_s": math.nan},
        InvalidValueError,
        "cruise_speed_m_s: expected a finite number, got nan",
    ),
    (
        "systems.model-params",
        {"model": "M", **SPEEDS, "max_speed_m_s": math.inf},
        InvalidValueError,
        "max_speed_m_s: expected a finite number, got inf",
    ),
    (
        "systems.model-params",
        {"model": "M", **SPEEDS, "min_speed_m_s": -math.inf},
        InvalidValueError,
        "expected a finite number, got -inf",
    ),
    (
        "systems.model-params",
        {"model": "M", "cruise_speed_m_s": -5.0, "max_speed_m_s": 20.0},
        ConstraintError,
        "cruise_speed_m_s BETWEEN 0 AND 300",
    ),
    (
        "systems.model-params",
        {"model": "M", **SPEEDS, "min_speed_m_s": -1.0},
        ConstraintError,
        "min_speed_m_s BETWEEN 0 AND 300",
    ),
    (
        "systems.model-params",
        {"model": "M", **SPEEDS, "climb_rate_m_s": -2.0},
        ConstraintError,
        "climb_rate_m_s BETWEEN 0 AND 100",
    ),
    (
        "systems.model-params",
        {"model": "M", "cruise_speed_m_s": 30.0, "max_speed_m_s": 20.0},
        ConstraintError,
        "speeds_ordered",
    ),
    (
        "systems.model-params",
        {"model": "M", **SPEEDS, "max_bank_deg": 90.0},
        ConstraintError,
        "max_bank_deg",
    ),
    (
        "systems.model-params",
        {"model": "M", **SPEEDS, "battery_low_pct": 20, "battery_critical_pct": 20},
        ConstraintError,
        "battery_critical_pct",
    ),
    (
        "systems.model-params",
        {"model": "M", **SPEEDS, "battery_low_pct": 2.5},
        InvalidValueError,
        "battery_low_pct: expected an integer, got 2.5",
    ),
    (
        "systems.model-params",
        {"model": "M", **SPEEDS, "has_parachute": "yes"},
        InvalidValueError,
        "has_parachute: expected true or false",
    ),
    (
        "systems.model-params",
        {"model": "M", **SPEEDS, "mass_kg": True},
        InvalidValueError,
        "mass_kg: expected a number, got True",
    ),
    (
        "systems.model-params",
        {"model": "M", **SPEEDS, "mass_kg": "12"},
        InvalidValueError,
        "mass_kg: expected a number, got '12'",
    ),
    (
        "systems.model-params",
        {"model": "M", "cruise_speed_m_s": 10.0},
        InvalidValueError,
        "field 'max_speed_m_s' is required",
    ),
    (
        "payload.sensor-params",
        {"sensor": "S", "hfov_deg": math.nan},
        InvalidValueError,
        "hfov_deg: expected a finite number",
    ),
    ("payload.sensor-params", {"sensor": "S", "hfov_deg": 180.0}, ConstraintError, "hfov_deg"),
    ("payload.sensor-params", {"sensor": "S", "width_px": 0}, ConstraintError, "width_px"),
    (
        "payload.sensor-params",
        {"sensor": "S", "width_px": 2**64},
        InvalidValueError,
        "out of range",
    ),
    (
        "payload.gimbal-axes",
        {"name": "a", "axis": "roll", "min_angle_deg": 10.0, "max_angle_deg": -10.0},
        ConstraintError,
        "axis_range_ordered",
    ),
    (
        "payload.gimbal-axes",
        {"name": "a", "axis": "yaw", "min_angle_deg": 0.0, "max_angle_deg": 1.0},
        ConstraintError,
        "axis IN",
    ),
    (
        "payload.gimbals",
        {"name": "g", "baud_rate": 0, "period_ms": 20.0},
        ConstraintError,
        "baud_rate",
    ),
    (
        "payload.gimbals",
        {"name": "g", "baud_rate": 9600, "period_ms": -1.0},
        ConstraintError,
        "period_ms",
    ),
    (
        "common.pids",
        {"name": "p", "p": math.nan, "i": 0.0, "d": 0.0, "max_integral": 1.0},
        InvalidValueError,
        "common.pids.p: expected a finite number",
    ),
    (
        "common.pids",
        {"name": "p", "p": 1.0, "i": 0.0, "d": 0.0, "max_integral": -1.0},
        ConstraintError,
        "max_integral",
    ),
    (
        "swarm.mission-params",
        {"mission": "area", "name": "x", "value": math.inf},
        InvalidValueError,
        "value: expected a finite number",
    ),
    (
        "swarm.module-params",
        {"module": "voting", "name": "x", "value": 1e13},
        ConstraintError,
        "value BETWEEN",
    ),
    ("swarm.missions", {"name": "m", "mission_type": 0}, ConstraintError, "mission_type"),
    (
        "swarm.missions",
        {"name": "m", "mission_type": "SURVEY"},
        InvalidValueError,
        "unknown MissionType 'SURVEY'",
    ),
    (
        "systems.subtypes",
        {"name": "s", "type": "UAV", "vehicle_type": 999},
        ConstraintError,
        "vehicle_type",
    ),
    ("systems.systems", {"id": 0, "user_id": "X", "layout": ALB_LAYOUT}, ConstraintError, "id"),
    (
        "systems.systems",
        {"id": 65535, "user_id": "X", "layout": ALB_LAYOUT},
        ConstraintError,
        "id BETWEEN 1 AND 65534",
    ),
    (
        "systems.systems",
        {"id": "seven", "user_id": "X", "layout": ALB_LAYOUT},
        InvalidValueError,
        "id: expected an integer",
    ),
    # names and text
    ("systems.types", {"name": ""}, ConstraintError, "length(name) BETWEEN 1 AND 48"),
    ("systems.types", {"name": "  UUV"}, ConstraintError, "name = trim(name)"),
    ("systems.types", {"name": "x" * 49}, ConstraintError, "length(name) BETWEEN 1 AND 48"),
    ("systems.types", {"name": "a\x00b"}, InvalidValueError, "NUL"),
    ("systems.types", {"name": "\ud800"}, InvalidValueError, "lone surrogate"),
    ("systems.types", {"name": 5}, InvalidValueError, "name: expected text, got 5"),
    ("systems.types", {"name": ["UUV"]}, InvalidValueError, "name: expected text, got ['UUV']"),
    ("systems.types", {"name": None}, InvalidValueError, "name: a value is required"),
    ("systems.types", {"description": "x"}, InvalidValueError, "field 'name' is required"),
    ("systems.types", {"name": "T", "wheels": 4}, InvalidValueError, "unknown field 'wheels'"),
    ("systems.systems", {"user_id": "", "layout": ALB_LAYOUT}, ConstraintError, "user_id"),
    (
        "common.corrections",
        {"bug_id": "B-1", "module": "m", "description": "", "criticality": "low"},
        ConstraintError,
        "length(description) >= 1",
    ),
    (
        "common.corrections",
        {"bug_id": "B-1", "module": "m", "description": "d", "criticality": "urgent"},
        ConstraintError,
        "criticality IN",
    ),
    ("payload.sensors", {"name": "S2", "kind": "periscope"}, ConstraintError, "kind IN"),
    # references
    (
        "systems.layouts",
        {"name": "L", "model": "Missing"},
        UnknownReferenceError,
        "systems.layouts: model 'Missing' not found in systems.models",
    ),
    (
        "systems.layouts",
        {"name": "L", "model": "M", "payload_layout": "Missing"},
        UnknownReferenceError,
        "payload_layout 'Missing' not found in payload.layouts",
    ),
    (
        "systems.layouts",
        {"name": "L", "model": "M", "computer": "Missing"},
        UnknownReferenceError,
        "computer 'Missing' not found in common.computers",
    ),
    (
        "systems.models",
        {"name": "N", "subtype": "Missing"},
        UnknownReferenceError,
        "subtype 'Missing' not found in systems.subtypes",
    ),
    (
        "systems.model-params",
        {"model": "Missing", **SPEEDS},
        UnknownReferenceError,
        "model 'Missing' not found in systems.models",
    ),
    (
        "systems.systems",
        {"user_id": "X", "layout": "Missing"},
        UnknownReferenceError,
        "layout 'Missing' not found in systems.layouts",
    ),
    (
        "systems.systems",
        {"user_id": "X", "layout": ALB_LAYOUT, "payload": 999},
        UnknownReferenceError,
        "payload 999 not found in payload.payloads",
    ),
    (
        "systems.params",
        {"system": 999, "name": "n", "value": "v"},
        UnknownReferenceError,
        "system 999 not found in systems.systems",
    ),
    (
        "payload.layouts",
        {"name": "L", "model": "Missing"},
        UnknownReferenceError,
        "model 'Missing' not found in payload.models",
    ),
    (
        "payload.gimbals",
        {"name": "g", "baud_rate": 9600, "period_ms": 20.0, "tilt_axis": "Missing"},
        UnknownReferenceError,
        "tilt_axis 'Missing' not found in payload.gimbal-axes",
    ),
    (
        "swarm.module-params",
        {"module": "Missing", "name": "x", "value": 1.0},
        UnknownReferenceError,
        "module 'Missing' not found in swarm.modules",
    ),
    (
        "common.comms",
        {"name": "r", "kind": "wifi", "system": 999},
        UnknownReferenceError,
        "system 999 not found in systems.systems",
    ),
    # rules across records
    (
        "systems.systems",
        {"user_id": "ALB-01", "layout": ALB_LAYOUT},
        DuplicateError,
        "same user_id + layout exists",
    ),
    (
        "payload.payloads",
        {"user_id": "CAM-01", "layout": "EO 1.5 Mpx 2-axis"},
        DuplicateError,
        "same user_id + layout exists",
    ),
    (
        "systems.models",
        {"name": "Albatross 250 VTOL", "subtype": "boat"},
        DuplicateError,
        "same name exists",
    ),
    (
        "systems.systems",
        {"user_id": "X", "layout": ALB_LAYOUT, "payload": 10},
        ConstraintError,
        "system payload: the payload is not of the payload layout",
    ),
    (
        "systems.systems",
        {"user_id": "X", "layout": ALB_LAYOUT, "payload": 2},
        DuplicateError,
        "same payload exists",
    ),  # CAM-02 is on ALB-02
    (
        "payload.gimbals",
        {"name": "g", "baud_rate": 9600, "period_ms": 20.0, "pan_axis": "roll +-45"},
        ConstraintError,
        "gimbal axis kind",
    ),
]


def _id(case: Any) -> str:
    table, record, error, _ = case
    return f"{table}-{error.__name__}-{'-'.join(map(str, record))[:40]}"


@pytest.fixture(scope="module")
def shared(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[SwarmDatabase, Path]]:
    """One seeded file for every case (nothing is ever written to it), with a model "M"
    without parameters and a sensor "S" without specifications to point at."""
    path = tmp_path_factory.mktemp("bad") / "swarm.db"
    with SwarmDatabase.open(path) as db:
        db.add("systems.models", {"name": "M", "subtype": "multirotor"})
        db.add("payload.sensors", {"name": "S", "kind": "camera"})
        yield db, path


@pytest.mark.parametrize(("table", "record", "error", "match"), BAD, ids=map(_id, BAD))
def test_add_refuses_and_writes_nothing(
    shared: tuple[SwarmDatabase, Path],
    table: str,
    record: dict[str, Any],
    error: type[RecordError],
    match: str,
) -> None:
    db, path = shared
    before = path.read_bytes(), db.export()
    with pytest.raises(error, match=_literal(match)) as info:
        db.add(table, record)
    assert str(info.value).startswith(BY_NAME[table].qualname)
    assert (path.read_bytes(), db.export()) == before


@pytest.mark.parametrize(("table", "record", "error", "match"), BAD, ids=map(_id, BAD))
def test_import_refuses_and_writes_nothing(
    shared: tuple[SwarmDatabase, Path],
    table: str,
    record: dict[str, Any],
    error: type[RecordError],
    match: str,
) -> None:
    """The bad record comes last, after valid records of tables written before it."""
    if error is DuplicateError and all(k in record for k in BY_NAME[table].key):
        pytest.skip("an import replaces the record with the same key (a merge, by design)")
    db, path = shared
    before = path.read_bytes(), db.export()
    group, name = table.split(".")
    doc = {
        "format": FORMAT,
        "schema_version": 2,
        "groups": {
            "common": {"computers": [{"name": "new computer", "board": "b"}]},
            "payload": {"types": [{"name": "new payload type"}]},
        },
    }
    doc["groups"].setdefault(group, {})[name] = [record]
    with pytest.raises(error, match=_literal(f"in.json: {table}[0]: ") + ".*" + _literal(match)):
        db.import_document(doc, source="in.json")
    assert (path.read_bytes(), db.export()) == before


def _literal(text: str) -> str:
    return re.escape(text)


@pytest.mark.parametrize(
    ("table", "key", "change", "error", "match"),
    [
        (
            "systems.model-params",
            "Albatross 250 VTOL",
            {"cruise_speed_m_s": math.nan},
            InvalidValueError,
            "expected a finite number",
        ),
        (
            "systems.model-params",
            "Albatross 250 VTOL",
            {"cruise_speed_m_s": -26.0},
            ConstraintError,
            "cruise_speed_m_s",
        ),
        (
            "systems.model-params",
            "Albatross 250 VTOL",
            {"min_speed_m_s": 30.0},
            ConstraintError,
            "speeds_ordered",
        ),
        (
            "systems.layouts",
            ALB_LAYOUT,
            {"model": "Missing"},
            UnknownReferenceError,
            "model 'Missing' not found",
        ),
        (
            "systems.layouts",
            ALB_LAYOUT,
            {"payload_layout": None},
            ConstraintError,
            "system payload",
        ),  # its systems carry cameras
        (
            "payload.gimbal-axes",
            "roll +-45",
            {"axis": "pan"},
            ConstraintError,
            "gimbal axis kind",
        ),  # used as a roll axis
    ],
)
def test_import_over_existing_records_refuses_and_writes_nothing(
    shared: tuple[SwarmDatabase, Path],
    table: str,
    key: str,
    change: dict[str, Any],
    error: type[RecordError],
    match: str,
) -> None:
    """Replacing a record by its key (an import's update path) checks the same rules."""
    db, path = shared
    before = path.read_bytes(), db.export()
    group, name = table.split(".")
    record = {**db.get(table, key), **change}
    doc = {"format": FORMAT, "schema_version": 2, "groups": {group: {name: [record]}}}
    with pytest.raises(error, match=_literal(match)):
        db.import_document(doc)
    assert (path.read_bytes(), db.export()) == before


@pytest.mark.parametrize(
    ("data", "match"),
    [
        (b"[" * 2000 + b"]" * 2000, "nested too deeply"),
        (b'{"format": ' + b"[" * 900 + b"]" * 900 + b"}", "format [[[[...]]]]"),
        (
            b'{"format": "bandada-swarm-db", "schema_version": 2, "groups": {"'
            + b"g" * 10**5
            + b'": {}}}',
            "unknown group 'gggggggggg",
        ),
        (b"\xff\xfe not utf-8", "not valid JSON"),
        (b"", "not valid JSON"),
    ],
    ids=["nested", "nested-value", "huge-name", "binary", "empty"],
)
def test_documents_that_would_break_a_parser_are_document_errors(data: bytes, match: str) -> None:
    with pytest.raises(DocumentError, match=_literal(match)) as info:
        decode_json(data, source="in.json")
    assert len(str(info.value)) < 300  # shown shortened, one line


def test_a_lock_held_too_long_is_a_storage_error_and_nothing_is_written(
    db_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(repository, "LOCK_TIMEOUT_S", 0.05)
    other = sqlite3.connect(db_path, isolation_level=None)
    with SwarmDatabase.open(db_path) as db:
        before = db.export()
        other.execute("BEGIN EXCLUSIVE")  # another writer, e.g. a stuck sqlite3 session
        try:
            with pytest.raises(StorageError, match=r"cannot lock it for writing .*locked"):
                db.add("systems.types", {"name": "UUV"})
            with pytest.raises(StorageError, match=r"cannot read it .*locked"):
                db.records("systems.types")
            with pytest.raises(StorageError):
                db.import_document(_doc_with_type("UUV"))
        finally:
            other.execute("ROLLBACK")
            other.close()
        assert db.export() == before
        db.add("systems.types", {"name": "UUV"})  # and it works again once released


def _doc_with_type(name: str) -> dict[str, Any]:
    return {
        "format": FORMAT,
        "schema_version": 2,
        "groups": {"systems": {"types": [{"name": name}]}},
    }
