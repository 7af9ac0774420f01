"""The swarm database schema (paper section 2.3.1) as an ordered list of migrations.

A database file records the last migration applied in `PRAGMA user_version` and marks
itself as ours with `PRAGMA application_id` (`APPLICATION_ID`, "BAND"). Migrations are
append-only: never edit one that has shipped; add the next one. Each is plain SQL run
inside the single transaction that brings a file up to date (all or nothing).

Every rule the paper states is a constraint SQLite enforces itself, so no writer (the
CLI, an import, a hand-written `sqlite3` session) can break it:
- foreign keys (the connection turns `PRAGMA foreign_keys` on) link type -> subtype ->
  model in both hierarchies, layouts to models, systems to layouts;
- names of types, subtypes and models are unique (across the hierarchy, so a name alone
  says which level it is; the voting compares names);
- a system or a payload is (user id, layout), unique; its internal id is the swarm
  node id, 1..65534 (uint16 on the radio);
- CHECKs bound every number (speeds ordered stall <= cruise <= max, bank below 90
  degrees, battery critical below low, names of 1..48 characters without outer spaces,
  as `swarm_proto` messages carry them);
- tables are STRICT: a value of the wrong type is refused, never coerced;
- triggers check what a CHECK cannot (a gimbal's pan axis is a pan axis; a system's
  payload is of the payload layout its system layout names).
"""

from __future__ import annotations

import sqlite3
from collections.abc import Iterator
from dataclasses import dataclass

APPLICATION_ID = 0x42414E44  # "BAND"
MIN_SQLITE = (3, 37, 0)  # STRICT tables


@dataclass(frozen=True)
class Migration:
    version: int
    description: str
    sql: str


# A name as messages carry it (swarm_proto.units.Name: at most 48 characters).
# Written out in full in each migration below: shipped SQL never changes.

_V1 = """
PRAGMA application_id = 1111576132;

-- ---------------------------------------------------------------- Common (part 1)
CREATE TABLE computer_layouts (
    id INTEGER PRIMARY KEY,
    name TEXT NOT NULL UNIQUE CHECK (length(name) BETWEEN 1 AND 48 AND name = trim(name)),
    board TEXT NOT NULL CHECK (length(board) >= 1),
    cpu TEXT NOT NULL DEFAULT '',
    ram_mb INTEGER NOT NULL DEFAULT 0 CHECK (ram_mb BETWEEN 0 AND 16777216),
    os TEXT NOT NULL DEFAULT '',
    description TEXT NOT NULL DEFAULT ''
) STRICT;

CREATE TABLE pid_controllers (
    id INTEGER PRIMARY KEY,
    name TEXT NOT NULL UNIQUE CHECK (length(name) BETWEEN 1 AND 48 AND name = trim(name)),
    p REAL NOT NULL CHECK (p BETWEEN -1e9 AND 1e9),
    i REAL NOT NULL CHECK (i BETWEEN -1e9 AND 1e9),
    d REAL NOT NULL CHECK (d BETWEEN -1e9 AND 1e9),
    max_integral REAL NOT NULL CHECK (max_integral BETWEEN 0 AND 1e9),
    anti_windup INTEGER NOT NULL DEFAULT 1 CHECK (anti_windup IN (0, 1))
) STRICT;

-- ---------------------------------------------------------------- Payload
CREATE TABLE payload_types (
    id INTEGER PRIMARY KEY,
    name TEXT NOT NULL UNIQUE CHECK (length(name) BETWEEN 1 AND 48 AND name = trim(name)),
    description TEXT NOT NULL DEFAULT ''
) STRICT;

CREATE TABLE payload_subtypes (
    id INTEGER PRIMARY KEY,
    type_id INTEGER NOT NULL REFERENCES payload_types(id),
    name TEXT NOT NULL UNIQUE CHECK (length(name) BETWEEN 1 AND 48 AND name = trim(name)),
    description TEXT NOT NULL DEFAULT ''
) STRICT;

CREATE TABLE payload_models (
    id INTEGER PRIMARY KEY,
    subtype_id INTEGER NOT NULL REFERENCES payload_subtypes(id),
    name TEXT NOT NULL UNIQUE CHECK (length(name) BETWEEN 1 AND 48 AND name = trim(name)),
    description TEXT NOT NULL DEFAULT ''
) STRICT;

CREATE TABLE motors (
    id INTEGER PRIMARY KEY,
    name TEXT NOT NULL UNIQUE CHECK (length(name) BETWEEN 1 AND 48 AND name = trim(name)),
    kind TEXT NOT NULL CHECK (kind IN ('servo', 'brushless', 'stepper', 'dc')),
    description TEXT NOT NULL DEFAULT ''
) STRICT;

CREATE TABLE gimbal_axis_params (
    id INTEGER PRIMARY KEY,
    name TEXT NOT NULL UNIQUE CHECK (length(name) BETWEEN 1 AND 48 AND name = trim(name)),
    axis TEXT NOT NULL CHECK (axis IN ('roll', 'tilt', 'pan')),
    motor_id INTEGER REFERENCES motors(id),
    pid_id INTEGER REFERENCES pid_controllers(id),
    min_angle_deg REAL NOT NULL CHECK (min_angle_deg BETWEEN -360 AND 360),
    max_angle_deg REAL NOT NULL CHECK (max_angle_deg BETWEEN -360 AND 360),
    max_rate_deg_s REAL NOT NULL DEFAULT 0 CHECK (max_rate_deg_s BETWEEN 0 AND 10000),
    CONSTRAINT axis_range_ordered CHECK (min_angle_deg < max_angle_deg)
) STRICT;

CREATE TABLE gimbal_configs (
    id INTEGER PRIMARY KEY,
    name TEXT NOT NULL UNIQUE CHECK (length(name) BETWEEN 1 AND 48 AND name = trim(name)),
    baud_rate INTEGER NOT NULL CHECK (baud_rate BETWEEN 1 AND 100000000),
    period_ms REAL NOT NULL CHECK (period_ms > 0 AND period_ms <= 1e6),
    pan_axis_id INTEGER REFERENCES gimbal_axis_params(id),
    tilt_axis_id INTEGER REFERENCES gimbal_axis_params(id),
    roll_axis_id INTEGER REFERENCES gimbal_axis_params(id)
) STRICT;

CREATE TRIGGER gimbal_configs_axis_kind_insert BEFORE INSERT ON gimbal_configs
WHEN EXISTS (SELECT 1 FROM gimbal_axis_params WHERE id = NEW.pan_axis_id AND axis <> 'pan')
  OR EXISTS (SELECT 1 FROM gimbal_axis_params WHERE id = NEW.tilt_axis_id AND axis <> 'tilt')
  OR EXISTS (SELECT 1 FROM gimbal_axis_params WHERE id = NEW.roll_axis_id AND axis <> 'roll')
BEGIN
    SELECT RAISE(ABORT, 'gimbal axis kind: pan_axis, tilt_axis and roll_axis must name a pan, tilt and roll axis');
END;

CREATE TRIGGER gimbal_configs_axis_kind_update
BEFORE UPDATE OF pan_axis_id, tilt_axis_id, roll_axis_id ON gimbal_configs
WHEN EXISTS (SELECT 1 FROM gimbal_axis_params WHERE id = NEW.pan_axis_id AND axis <> 'pan')
  OR EXISTS (SELECT 1 FROM gimbal_axis_params WHERE id = NEW.tilt_axis_id AND axis <> 'tilt')
  OR EXISTS (SELECT 1 FROM gimbal_axis_params WHERE id = NEW.roll_axis_id AND axis <> 'roll')
BEGIN
    SELECT RAISE(ABORT, 'gimbal axis kind: pan_axis, tilt_axis and roll_axis must name a pan, tilt and roll axis');
END;

CREATE TRIGGER gimbal_axis_kind_in_use BEFORE UPDATE OF axis ON gimbal_axis_params
WHEN NEW.axis <> OLD.axis AND EXISTS (
    SELECT 1 FROM gimbal_configs
    WHERE pan_axis_id = OLD.id OR tilt_axis_id = OLD.id OR roll_axis_id = OLD.id)
BEGIN
    SELECT RAISE(ABORT, 'gimbal axis kind: the axis is used by a gimbal configuration');
END;

CREATE TABLE sensors (
    id INTEGER PRIMARY KEY,
    name TEXT NOT NULL UNIQUE CHECK (length(name) BETWEEN 1 AND 48 AND name = trim(name)),
    kind TEXT NOT NULL CHECK (kind IN ('camera', 'thermal', 'lidar', 'radar', 'sdr', 'microphone', 'other')),
    description TEXT NOT NULL DEFAULT ''
) STRICT;

CREATE TABLE sensor_params (
    sensor_id INTEGER PRIMARY KEY REFERENCES sensors(id) ON DELETE CASCADE,
    hfov_deg REAL CHECK (hfov_deg > 0 AND hfov_deg < 180),
    vfov_deg REAL CHECK (vfov_deg > 0 AND vfov_deg < 180),
    width_px INTEGER CHECK (width_px BETWEEN 1 AND 100000),
    height_px INTEGER CHECK (height_px BETWEEN 1 AND 100000),
    frame_rate_hz REAL CHECK (frame_rate_hz > 0 AND frame_rate_hz <= 100000),
    range_m REAL CHECK (range_m > 0 AND range_m <= 1e7)
) STRICT;

CREATE TABLE payload_layouts (
    id INTEGER PRIMARY KEY,
    name TEXT NOT NULL UNIQUE CHECK (length(name) BETWEEN 1 AND 48 AND name = trim(name)),
    model_id INTEGER NOT NULL REFERENCES payload_models(id),
    gimbal_id INTEGER REFERENCES gimbal_configs(id),
    sensor_id INTEGER REFERENCES sensors(id),
    description TEXT NOT NULL DEFAULT ''
) STRICT;

CREATE TABLE payloads (
    id INTEGER PRIMARY KEY CHECK (id >= 1),
    user_id TEXT NOT NULL CHECK (length(user_id) BETWEEN 1 AND 48 AND user_id = trim(user_id)),
    layout_id INTEGER NOT NULL REFERENCES payload_layouts(id),
    CONSTRAINT payload_user_id_layout_unique UNIQUE (user_id, layout_id)
) STRICT;

CREATE TABLE payload_params (
    payload_id INTEGER NOT NULL REFERENCES payloads(id) ON DELETE CASCADE,
    name TEXT NOT NULL CHECK (length(name) BETWEEN 1 AND 64 AND name = trim(name)),
    value TEXT NOT NULL,
    PRIMARY KEY (payload_id, name)
) STRICT;

-- ---------------------------------------------------------------- Systems
CREATE TABLE system_types (
    id INTEGER PRIMARY KEY,
    name TEXT NOT NULL UNIQUE CHECK (length(name) BETWEEN 1 AND 48 AND name = trim(name)),
    description TEXT NOT NULL DEFAULT ''
) STRICT;

CREATE TABLE system_subtypes (
    id INTEGER PRIMARY KEY,
    type_id INTEGER NOT NULL REFERENCES system_types(id),
    name TEXT NOT NULL UNIQUE CHECK (length(name) BETWEEN 1 AND 48 AND name = trim(name)),
    vehicle_type INTEGER NOT NULL CHECK (vehicle_type BETWEEN 0 AND 255),
    description TEXT NOT NULL DEFAULT ''
) STRICT;

CREATE TABLE system_models (
    id INTEGER PRIMARY KEY,
    subtype_id INTEGER NOT NULL REFERENCES system_subtypes(id),
    name TEXT NOT NULL UNIQUE CHECK (length(name) BETWEEN 1 AND 48 AND name = trim(name)),
    description TEXT NOT NULL DEFAULT ''
) STRICT;

CREATE TABLE system_model_params (
    model_id INTEGER PRIMARY KEY REFERENCES system_models(id) ON DELETE CASCADE,
    cruise_speed_m_s REAL NOT NULL CHECK (cruise_speed_m_s BETWEEN 0 AND 300),
    min_speed_m_s REAL NOT NULL DEFAULT 0 CHECK (min_speed_m_s BETWEEN 0 AND 300),
    max_speed_m_s REAL NOT NULL CHECK (max_speed_m_s BETWEEN 0 AND 300),
    max_bank_deg REAL NOT NULL DEFAULT 45 CHECK (max_bank_deg >= 0 AND max_bank_deg < 90),
    climb_rate_m_s REAL NOT NULL DEFAULT 0 CHECK (climb_rate_m_s BETWEEN 0 AND 100),
    sink_rate_m_s REAL NOT NULL DEFAULT 0 CHECK (sink_rate_m_s BETWEEN 0 AND 100),
    loiter_radius_m REAL NOT NULL DEFAULT 0 CHECK (loiter_radius_m BETWEEN 0 AND 10000),
    has_parachute INTEGER NOT NULL DEFAULT 0 CHECK (has_parachute IN (0, 1)),
    max_altitude_m REAL NOT NULL DEFAULT 0 CHECK (max_altitude_m BETWEEN 0 AND 8000),
    wingspan_m REAL NOT NULL DEFAULT 0 CHECK (wingspan_m BETWEEN 0 AND 100),
    mass_kg REAL NOT NULL DEFAULT 0 CHECK (mass_kg BETWEEN 0 AND 100000),
    CONSTRAINT speeds_ordered CHECK (
        min_speed_m_s <= cruise_speed_m_s AND cruise_speed_m_s <= max_speed_m_s)
) STRICT;

CREATE TABLE system_layouts (
    id INTEGER PRIMARY KEY,
    name TEXT NOT NULL UNIQUE CHECK (length(name) BETWEEN 1 AND 48 AND name = trim(name)),
    model_id INTEGER NOT NULL REFERENCES system_models(id),
    payload_layout_id INTEGER REFERENCES payload_layouts(id),
    computer_id INTEGER REFERENCES computer_layouts(id),
    description TEXT NOT NULL DEFAULT ''
) STRICT;

CREATE TABLE systems (
    id INTEGER PRIMARY KEY CHECK (id BETWEEN 1 AND 65534),
    user_id TEXT NOT NULL CHECK (length(user_id) BETWEEN 1 AND 48 AND user_id = trim(user_id)),
    layout_id INTEGER NOT NULL REFERENCES system_layouts(id),
    CONSTRAINT system_user_id_layout_unique UNIQUE (user_id, layout_id)
) STRICT;

CREATE TABLE system_params (
    system_id INTEGER NOT NULL REFERENCES systems(id) ON DELETE CASCADE,
    name TEXT NOT NULL CHECK (length(name) BETWEEN 1 AND 64 AND name = trim(name)),
    value TEXT NOT NULL,
    PRIMARY KEY (system_id, name)
) STRICT;

-- ---------------------------------------------------------------- Swarm
CREATE TABLE missions (
    id INTEGER PRIMARY KEY,
    name TEXT NOT NULL UNIQUE CHECK (length(name) BETWEEN 1 AND 48 AND name = trim(name)),
    mission_type INTEGER NOT NULL UNIQUE CHECK (mission_type BETWEEN 1 AND 255),
    description TEXT NOT NULL DEFAULT ''
) STRICT;

CREATE TABLE mission_params (
    mission_id INTEGER NOT NULL REFERENCES missions(id) ON DELETE CASCADE,
    name TEXT NOT NULL CHECK (length(name) BETWEEN 1 AND 64 AND name = trim(name)),
    value REAL NOT NULL CHECK (value BETWEEN -1e12 AND 1e12),
    unit TEXT NOT NULL DEFAULT '',
    description TEXT NOT NULL DEFAULT '',
    PRIMARY KEY (mission_id, name)
) STRICT;

CREATE TABLE modules (
    id INTEGER PRIMARY KEY,
    name TEXT NOT NULL UNIQUE CHECK (length(name) BETWEEN 1 AND 48 AND name = trim(name)),
    subtype_id INTEGER REFERENCES system_subtypes(id),
    description TEXT NOT NULL DEFAULT ''
) STRICT;

CREATE TABLE module_params (
    module_id INTEGER NOT NULL REFERENCES modules(id) ON DELETE CASCADE,
    name TEXT NOT NULL CHECK (length(name) BETWEEN 1 AND 64 AND name = trim(name)),
    value REAL NOT NULL CHECK (value BETWEEN -1e12 AND 1e12),
    unit TEXT NOT NULL DEFAULT '',
    description TEXT NOT NULL DEFAULT '',
    PRIMARY KEY (module_id, name)
) STRICT;

-- ---------------------------------------------------------------- Common (part 2)
CREATE TABLE comms_systems (
    id INTEGER PRIMARY KEY,
    name TEXT NOT NULL UNIQUE CHECK (length(name) BETWEEN 1 AND 48 AND name = trim(name)),
    kind TEXT NOT NULL CHECK (kind IN ('xtend900', 'microhard', 'wifi', 'ethernet', 'lte', 'other')),
    address TEXT NOT NULL DEFAULT '',
    system_id INTEGER REFERENCES systems(id) ON DELETE CASCADE,
    description TEXT NOT NULL DEFAULT ''
) STRICT;

CREATE TABLE corrections (
    id INTEGER PRIMARY KEY,
    bug_id TEXT NOT NULL UNIQUE CHECK (length(bug_id) BETWEEN 1 AND 48 AND bug_id = trim(bug_id)),
    module TEXT NOT NULL CHECK (length(module) >= 1),
    description TEXT NOT NULL CHECK (length(description) >= 1),
    criticality TEXT NOT NULL CHECK (criticality IN ('low', 'medium', 'high', 'critical'))
) STRICT;

-- Indexes for the foreign keys that deletes look up.
CREATE INDEX payload_subtypes_type ON payload_subtypes(type_id);
CREATE INDEX payload_models_subtype ON payload_models(subtype_id);
CREATE INDEX payloads_layout ON payloads(layout_id);
CREATE INDEX system_subtypes_type ON system_subtypes(type_id);
CREATE INDEX system_models_subtype ON system_models(subtype_id);
CREATE INDEX system_layouts_model ON system_layouts(model_id);
CREATE INDEX systems_layout ON systems(layout_id);
CREATE INDEX comms_systems_system ON comms_systems(system_id);
"""

_V2 = """
-- Vehicle-monitoring thresholds and the wind limit move into the model parameters.
ALTER TABLE system_model_params ADD COLUMN battery_low_pct INTEGER NOT NULL DEFAULT 30
    CHECK (battery_low_pct BETWEEN 1 AND 100);
ALTER TABLE system_model_params ADD COLUMN battery_critical_pct INTEGER NOT NULL DEFAULT 15
    CHECK (battery_critical_pct >= 0 AND battery_critical_pct < battery_low_pct);
ALTER TABLE system_model_params ADD COLUMN max_tilt_deg REAL NOT NULL DEFAULT 60
    CHECK (max_tilt_deg > 0 AND max_tilt_deg <= 180);
ALTER TABLE system_model_params ADD COLUMN max_wind_m_s REAL NOT NULL DEFAULT 0
    CHECK (max_wind_m_s BETWEEN 0 AND 100);

-- A system names the payload it carries (a physical payload, one system at a time).
ALTER TABLE systems ADD COLUMN payload_id INTEGER REFERENCES payloads(id) DEFAULT NULL;
CREATE UNIQUE INDEX systems_payload_unique ON systems(payload_id);

CREATE TRIGGER systems_payload_layout_insert BEFORE INSERT ON systems
WHEN NEW.payload_id IS NOT NULL
 AND EXISTS (SELECT 1 FROM payloads WHERE id = NEW.payload_id)
 AND (SELECT layout_id FROM payloads WHERE id = NEW.payload_id)
     IS NOT (SELECT payload_layout_id FROM system_layouts WHERE id = NEW.layout_id)
BEGIN
    SELECT RAISE(ABORT, 'system payload: the payload is not of the payload layout its system layout names');
END;

CREATE TRIGGER systems_payload_layout_update BEFORE UPDATE OF payload_id, layout_id ON systems
WHEN NEW.payload_id IS NOT NULL
 AND EXISTS (SELECT 1 FROM payloads WHERE id = NEW.payload_id)
 AND (SELECT layout_id FROM payloads WHERE id = NEW.payload_id)
     IS NOT (SELECT payload_layout_id FROM system_layouts WHERE id = NEW.layout_id)
BEGIN
    SELECT RAISE(ABORT, 'system payload: the payload is not of the payload layout its system layout names');
END;

CREATE TRIGGER payloads_layout_in_use BEFORE UPDATE OF layout_id ON payloads
WHEN NEW.layout_id IS NOT OLD.layout_id AND EXISTS (
    SELECT 1 FROM systems s JOIN system_layouts l ON l.id = s.layout_id
    WHERE s.payload_id = OLD.id AND l.payload_layout_id IS NOT NEW.layout_id)
BEGIN
    SELECT RAISE(ABORT, 'system payload: the payload is not of the payload layout its system layout names');
END;

CREATE TRIGGER system_layouts_payload_in_use BEFORE UPDATE OF payload_layout_id ON system_layouts
WHEN NEW.payload_layout_id IS NOT OLD.payload_layout_id AND EXISTS (
    SELECT 1 FROM systems s JOIN payloads p ON p.id = s.payload_id
    WHERE s.layout_id = OLD.id AND p.layout_id IS NOT NEW.payload_layout_id)
BEGIN
    SELECT RAISE(ABORT, 'system payload: the payload is not of the payload layout its system layout names');
END;

-- Classes the payload autodetection can report (person, vehicle, ...).
CREATE TABLE autodetection_classes (
    id INTEGER PRIMARY KEY,
    name TEXT NOT NULL UNIQUE CHECK (length(name) BETWEEN 1 AND 48 AND name = trim(name)),
    description TEXT NOT NULL DEFAULT ''
) STRICT;
"""

_V3 = """
-- Endurance for the planners: battery capacity, the current drawn at cruise (level
-- flight or driving at cruise speed) and at hover (lift motors), and the horizontal
-- acceleration a vehicle that stops on its waypoints brakes and accelerates with.
-- 0 = unknown (the planners then assume no endurance limit / ArduPilot defaults).
ALTER TABLE system_model_params ADD COLUMN battery_capacity_mah REAL NOT NULL DEFAULT 0
    CHECK (battery_capacity_mah BETWEEN 0 AND 1000000);
ALTER TABLE system_model_params ADD COLUMN cruise_current_a REAL NOT NULL DEFAULT 0
    CHECK (cruise_current_a BETWEEN 0 AND 1000);
ALTER TABLE system_model_params ADD COLUMN hover_current_a REAL NOT NULL DEFAULT 0
    CHECK (hover_current_a BETWEEN 0 AND 1000);
ALTER TABLE system_model_params ADD COLUMN accel_m_s2 REAL NOT NULL DEFAULT 0
    CHECK (accel_m_s2 BETWEEN 0 AND 100);
"""

_V4 = """
-- What the operator declared, as this node holds it, and the share it flies:
-- restored at start, so a restarted node forgets nothing (swarm_node/database/state.py).
-- One row per declaration and node (a simulation's nodes may share one file);
-- payload is the message in swarm_proto's LAN encoding (MessagePack); stamp_unix_s is
-- the declaration's stamp (the newest wins). Not one of the paper's records: never
-- exported, imported or served as a table.
CREATE TABLE node_declared (
    node_id INTEGER NOT NULL CHECK (node_id BETWEEN 1 AND 65534),
    kind TEXT NOT NULL CHECK (kind IN ('zone', 'command', 'assignment', 'mission', 'sortie')),
    key TEXT NOT NULL CHECK (length(key) BETWEEN 1 AND 200),
    stamp_unix_s REAL NOT NULL CHECK (stamp_unix_s >= 0),
    payload BLOB NOT NULL,
    PRIMARY KEY (node_id, kind, key)
) STRICT;
"""

#: Tables that hold the node's own state, not the paper's records (not in tables.TABLES).
NODE_STATE_TABLES: tuple[str, ...] = ("node_declared",)

MIGRATIONS: tuple[Migration, ...] = (
    Migration(1, "the four groups: Systems, Swarm, Payload, Common", _V1),
    Migration(
        2,
        "model battery/tilt/wind limits, a system's payload, autodetection classes",
        _V2,
    ),
    Migration(3, "model battery capacity, cruise and hover current, acceleration", _V3),
    Migration(4, "the node's declared state and sortie, restored at start", _V4),
)
LATEST_VERSION = MIGRATIONS[-1].version


def statements(script: str) -> Iterator[str]:
    """The complete SQL statements of a script, one at a time (triggers included):
    run them with `execute` so a migration never commits half-way, as `executescript`
    would."""
    buf: list[str] = []
    for line in script.splitlines(keepends=True):
        buf.append(line)
        text = "".join(buf)
        if sqlite3.complete_statement(text):
            stmt = text.strip()
            if stmt and not all(
                ln.strip().startswith("--") or not ln.strip() for ln in stmt.splitlines()
            ):
                yield stmt
            buf = []
    rest = "".join(buf).strip()
    if rest and not all(ln.strip().startswith("--") or not ln.strip() for ln in rest.splitlines()):
        raise ValueError(f"incomplete SQL statement at the end of a migration: {rest[:80]!r}")
