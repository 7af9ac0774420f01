"""The schema's rules are enforced by SQLite itself: rows written behind bandada's back
(a plain sqlite3 connection) that break them are refused with IntegrityError. And the
record-level table metadata (tables.py) agrees with the schema."""

from __future__ import annotations

import sqlite3

import pytest

from swarm_node.database.schema import (
    LATEST_VERSION,
    MIGRATIONS,
    NODE_STATE_TABLES,
    statements,
)
from swarm_node.database.tables import BY_NAME, TABLES, WRITE_ORDER

# (what the paper or our contract says, SQL that breaks it)
VIOLATIONS = [
    (
        "model names are unique",
        "INSERT INTO system_models (subtype_id, name) VALUES (1, 'Albatross 250 VTOL')",
    ),
    (
        "the same user id + layout twice is refused",
        "INSERT INTO systems (id, user_id, layout_id) "
        "SELECT 50, user_id, layout_id FROM systems WHERE id = 1",
    ),
    (
        "the same payload user id + layout twice is refused",
        "INSERT INTO payloads (id, user_id, layout_id) "
        "SELECT 50, user_id, layout_id FROM payloads WHERE id = 1",
    ),
    (
        "a system's layout exists",
        "INSERT INTO systems (id, user_id, layout_id) VALUES (50, 'X', 999)",
    ),
    ("a model's subtype exists", "INSERT INTO system_models (subtype_id, name) VALUES (999, 'M')"),
    (
        "a subtype's type exists",
        "INSERT INTO system_subtypes (type_id, name, vehicle_type) VALUES (999, 'S', 1)",
    ),
    (
        "a payload model's subtype exists",
        "INSERT INTO payload_models (subtype_id, name) VALUES (999, 'P')",
    ),
    (
        "a layout's payload layout exists",
        "UPDATE system_layouts SET payload_layout_id = 999 WHERE id = 1",
    ),
    ("node ids are >= 1", "INSERT INTO systems (id, user_id, layout_id) VALUES (0, 'X', 1)"),
    (
        "node ids fit uint16 below broadcast",
        "INSERT INTO systems (id, user_id, layout_id) VALUES (65535, 'X', 1)",
    ),
    ("stall <= cruise", "UPDATE system_model_params SET min_speed_m_s = 30 WHERE model_id = 1"),
    ("cruise <= max", "UPDATE system_model_params SET max_speed_m_s = 20 WHERE model_id = 1"),
    (
        "bank below 90 degrees",
        "UPDATE system_model_params SET max_bank_deg = 90 WHERE model_id = 1",
    ),
    (
        "speeds are not negative",
        "UPDATE system_model_params SET min_speed_m_s = -1 WHERE model_id = 1",
    ),
    (
        "battery critical below low",
        "UPDATE system_model_params SET battery_critical_pct = 30 WHERE model_id = 1",
    ),
    (
        "battery low at most 100",
        "UPDATE system_model_params SET battery_low_pct = 101 WHERE model_id = 1",
    ),
    ("booleans are 0 or 1", "UPDATE system_model_params SET has_parachute = 2 WHERE model_id = 1"),
    (
        "STRICT: no text in a REAL column",
        "UPDATE system_model_params SET cruise_speed_m_s = 'fast' WHERE model_id = 1",
    ),
    (
        "a value is required",
        "UPDATE system_model_params SET cruise_speed_m_s = NULL WHERE model_id = 1",
    ),
    ("names are not empty", "INSERT INTO system_types (name) VALUES ('')"),
    ("names have no outer spaces", "INSERT INTO system_types (name) VALUES (' UAV2')"),
    ("names fit a message (48 chars)", f"INSERT INTO system_types (name) VALUES ('{'x' * 49}')"),
    ("user ids are not empty", "INSERT INTO systems (id, user_id, layout_id) VALUES (50, '', 1)"),
    (
        "a gimbal's pan axis is a pan axis",
        "UPDATE gimbal_configs SET pan_axis_id = (SELECT id FROM gimbal_axis_params WHERE axis = 'tilt')",
    ),
    (
        "an axis used by a gimbal keeps its kind",
        "UPDATE gimbal_axis_params SET axis = 'pan' WHERE axis = 'tilt'",
    ),
    ("axis range ordered", "UPDATE gimbal_axis_params SET min_angle_deg = 100 WHERE axis = 'roll'"),
    ("camera FOV below 180", "UPDATE sensor_params SET hfov_deg = 180 WHERE hfov_deg IS NOT NULL"),
    ("sensor kinds are known", "INSERT INTO sensors (name, kind) VALUES ('S', 'periscope')"),
    ("a payload is carried by one system", "UPDATE systems SET payload_id = 1 WHERE id = 2"),
    (
        "a system carries a payload of its layout's payload layout",
        "UPDATE systems SET payload_id = (SELECT id FROM payloads WHERE user_id = 'SDR-01') WHERE id = 1",
    ),
    (
        "a payload's layout stays the one its system's layout names",
        "UPDATE payloads SET layout_id = (SELECT id FROM payload_layouts WHERE name = 'SDR receiver') WHERE id = 1",
    ),
    (
        "a layout's payload layout stays the one its systems' payloads have",
        "UPDATE system_layouts SET payload_layout_id = NULL WHERE id = 1",
    ),
    (
        "criticality is one of four",
        "INSERT INTO corrections (bug_id, module, description, criticality) VALUES ('B1', 'm', 'd', 'urgent')",
    ),
    ("a PID's max integral is not negative", "UPDATE pid_controllers SET max_integral = -1"),
    ("mission types are unique", "INSERT INTO missions (name, mission_type) VALUES ('area 2', 1)"),
    (
        "a mission parameter is set once",
        "INSERT INTO mission_params (mission_id, name, value) SELECT mission_id, name, 1 FROM mission_params LIMIT 1",
    ),
    (
        "a system parameter is set once",
        "INSERT INTO system_params (system_id, name, value) VALUES (1, 'mav_sysid', '7')",
    ),
    ("a model in use cannot be deleted", "DELETE FROM system_models WHERE name = 'Generic Rover'"),
    ("a layout in use cannot be deleted", "DELETE FROM system_layouts WHERE id = 1"),
    ("a payload type in use cannot be deleted", "DELETE FROM payload_types WHERE name = 'optical'"),
    ("a mounted payload cannot be deleted", "DELETE FROM payloads WHERE id = 1"),
]


@pytest.mark.parametrize(("rule", "sql"), VIOLATIONS, ids=[v[0] for v in VIOLATIONS])
def test_sqlite_refuses_rows_that_break_a_rule(
    raw: sqlite3.Connection, rule: str, sql: str
) -> None:
    with pytest.raises(sqlite3.IntegrityError):
        raw.execute(sql)
    assert raw.execute("PRAGMA foreign_key_check").fetchall() == []


def test_a_systems_own_records_go_with_it(raw: sqlite3.Connection) -> None:
    raw.execute("DELETE FROM systems WHERE id = 7")  # QUAD-01: params and radios are its own
    assert raw.execute("SELECT COUNT(*) FROM system_params WHERE system_id = 7").fetchone() == (0,)
    assert raw.execute("SELECT COUNT(*) FROM comms_systems WHERE system_id = 7").fetchone() == (0,)


def test_rules_hold_within_a_fresh_schema_too() -> None:
    conn = sqlite3.connect(":memory:", isolation_level=None)
    conn.execute("PRAGMA foreign_keys = ON")
    for m in MIGRATIONS:
        for stmt in statements(m.sql):
            conn.execute(stmt)
    with pytest.raises(sqlite3.IntegrityError):
        conn.execute("INSERT INTO system_models (subtype_id, name) VALUES (1, 'M')")  # no subtype 1


_SQL_TYPE = {"int": "INTEGER", "float": "REAL", "bool": "INTEGER", "text": "TEXT"}


def _sql_default(text: str | None) -> object:
    if text is None or text == "NULL":
        return None
    if text.startswith("'"):
        return text.strip("'")
    return float(text)


@pytest.mark.parametrize("t", TABLES, ids=lambda t: t.qualname)
def test_table_metadata_matches_the_schema(raw: sqlite3.Connection, t: object) -> None:
    from swarm_node.database.tables import Table

    assert isinstance(t, Table)
    info = {r[1]: r for r in raw.execute(f"PRAGMA table_info({t.sql})")}
    expected = {c.sql for c in t.columns}
    assert set(info) - {"id"} == expected - {"id"}, "metadata and schema list other columns"
    for c in t.columns:
        _, _, sql_type, notnull, default, pk = info[c.sql]
        assert sql_type == _SQL_TYPE[c.kind if not c.ref else "int"], c.name
        if c.name == "id":
            assert pk == 1
            continue
        assert bool(notnull or pk) == (not c.nullable), c.name  # a PRIMARY KEY is NOT NULL
        if c.required:
            assert default is None, f"{c.name} has an SQL default but is required"
        else:
            want = c.default
            want = (
                float(want) if isinstance(want, (bool, int, float)) and want is not None else want
            )
            assert _sql_default(default) == want, c.name
    fks = {r[3]: r for r in raw.execute(f"PRAGMA foreign_key_list({t.sql})")}
    refs = {c.sql: c for c in t.columns if c.ref}
    assert set(fks) == set(refs)
    for col_sql, c in refs.items():
        _, _, parent, _, to, _, on_delete, _ = fks[col_sql]
        assert c.ref is not None
        assert parent == BY_NAME[c.ref].sql and to == "id"
        assert (on_delete == "CASCADE") == c.cascade, c.name


def test_every_table_is_in_the_schema_and_in_write_order(raw: sqlite3.Connection) -> None:
    names = {
        r[0]
        for r in raw.execute(
            "SELECT name FROM sqlite_schema WHERE type = 'table' AND name NOT LIKE 'sqlite_%'"
        )
    }
    # and the node's own state, not one of the paper's records
    assert names == {t.sql for t in TABLES} | set(NODE_STATE_TABLES)
    assert sorted(t.qualname for t in WRITE_ORDER) == sorted(t.qualname for t in TABLES)
    seen: set[str] = set()
    for t in WRITE_ORDER:  # every table after what it references
        for c in t.columns:
            if c.ref and c.ref != t.qualname:
                assert c.ref in seen, f"{t.qualname} written before {c.ref}"
        seen.add(t.qualname)


def test_schema_version_and_application_id(raw: sqlite3.Connection) -> None:
    assert raw.execute("PRAGMA user_version").fetchone() == (LATEST_VERSION,)
    assert raw.execute("PRAGMA application_id").fetchone() == (0x42414E44,)
    assert [m.version for m in MIGRATIONS] == list(range(1, LATEST_VERSION + 1))
