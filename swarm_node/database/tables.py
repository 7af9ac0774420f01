"""The tables of the swarm database as data: groups, fields, keys and references.

This is the record-level view the CLI, the JSON export and the Zenoh queryable use:
a record is a dict of field values where a reference is the referenced record's key
(a model's name, a system's id), never an internal row id. The schema itself lives in
`schema.py`; `tests/swarm_node/database/test_schema.py` checks that the two agree
(columns, defaults, nullability, foreign keys, cascades).

Pure: no I/O. `convert()` turns operator input (JSON values or command-line text) into
checked Python values, with a clear error naming the field.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from enum import IntEnum
from typing import Any

from swarm_proto import MissionType, VehicleType

from .errors import InvalidValueError, UnknownTableError, shown

GROUPS = ("systems", "swarm", "payload", "common")  # paper section 2.3.1, in its order

KINDS = ("int", "float", "bool", "text")


class _Required:
    def __repr__(self) -> str:
        return "REQUIRED"


REQUIRED: Any = _Required()
INT64 = (-(2**63), 2**63 - 1)


@dataclass(frozen=True)
class Column:
    """One field of a record.

    `kind` is the stored type; `ref` names the table ("group.table") whose key this
    field holds; `enum` stores an IntEnum's value and shows its name."""

    name: str
    kind: str
    sql: str = ""
    ref: str | None = None
    default: Any = REQUIRED
    nullable: bool = False
    enum: type[IntEnum] | None = None
    cascade: bool = False  # ON DELETE CASCADE: the record belongs to the referenced one
    doc: str = ""

    def __post_init__(self) -> None:
        assert self.kind in KINDS, self.kind
        if not self.sql:
            object.__setattr__(self, "sql", f"{self.name}_id" if self.ref else self.name)

    @property
    def required(self) -> bool:
        return self.default is REQUIRED


@dataclass(frozen=True)
class Table:
    group: str
    name: str  # short name within its group, as the CLI spells it
    sql: str
    columns: tuple[Column, ...]
    key: tuple[str, ...]  # the fields that identify a record
    doc: str
    auto_id: bool = False  # `id` is a field (systems, payloads): the node / payload id
    since: int = 1  # schema version that created the table
    by_column: dict[str, Column] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "by_column", {c.name: c for c in self.columns})
        assert all(k in self.by_column for k in self.key), self.key

    @property
    def qualname(self) -> str:
        return f"{self.group}.{self.name}"

    @property
    def field_names(self) -> tuple[str, ...]:
        return tuple(c.name for c in self.columns)

    def column(self, name: str) -> Column:
        try:
            return self.by_column[name]
        except KeyError:
            raise InvalidValueError(
                f"{self.qualname}: unknown field {shown(name)}; fields: {', '.join(self.field_names)}"
            ) from None


def _name(doc: str = "unique name, 1..48 characters") -> Column:
    return Column("name", "text", doc=doc)


def _desc() -> Column:
    return Column("description", "text", default="")


def _param_name() -> Column:
    return Column("name", "text", doc="parameter name, 1..64 characters")


TABLES: tuple[Table, ...] = (
    # ------------------------------------------------------------------ Systems
    Table(
        "systems",
        "types",
        "system_types",
        (_name("e.g. UAV, UGV, USV, GCS"), _desc()),
        ("name",),
        "Top of the system hierarchy: type -> subtype -> model.",
    ),
    Table(
        "systems",
        "subtypes",
        "system_subtypes",
        (
            _name("e.g. fixed-wing, VTOL, multirotor, rover, boat"),
            Column("type", "text", ref="systems.types"),
            Column(
                "vehicle_type",
                "int",
                enum=VehicleType,
                doc="swarm_proto VehicleType: drives autopilot modes, planners, avoidance",
            ),
            _desc(),
        ),
        ("name",),
        "System subtypes, each of one type.",
    ),
    Table(
        "systems",
        "models",
        "system_models",
        (_name("model name, unique"), Column("subtype", "text", ref="systems.subtypes"), _desc()),
        ("name",),
        "System models, each of one subtype. Model names are unique.",
    ),
    Table(
        "systems",
        "model-params",
        "system_model_params",
        (
            Column("model", "text", ref="systems.models", cascade=True),
            Column("cruise_speed_m_s", "float"),
            Column("min_speed_m_s", "float", default=0.0, doc="stall speed; 0 if it hovers"),
            Column("max_speed_m_s", "float"),
            Column("max_bank_deg", "float", default=45.0),
            Column("climb_rate_m_s", "float", default=0.0),
            Column("sink_rate_m_s", "float", default=0.0),
            Column("loiter_radius_m", "float", default=0.0),
            Column("has_parachute", "bool", default=False),
            Column("max_altitude_m", "float", default=0.0, doc="0 = unknown"),
            Column("wingspan_m", "float", default=0.0, doc="span, or frame diagonal, or width"),
            Column("mass_kg", "float", default=0.0, doc="take-off mass the speeds refer to"),
            Column("battery_low_pct", "int", default=30),
            Column("battery_critical_pct", "int", default=15),
            Column("max_tilt_deg", "float", default=60.0, doc="abnormal attitude beyond this"),
            Column("max_wind_m_s", "float", default=0.0, doc="0 = unknown"),
            Column("battery_capacity_mah", "float", default=0.0, doc="0 = unknown"),
            Column("cruise_current_a", "float", default=0.0, doc="at cruise speed; 0 = unknown"),
            Column("hover_current_a", "float", default=0.0, doc="lift motors at hover; 0 = none"),
            Column("accel_m_s2", "float", default=0.0, doc="horizontal; 0 = unknown"),
        ),
        ("model",),
        "Planning and monitoring parameters of a model (one record per model).",
    ),
    Table(
        "systems",
        "layouts",
        "system_layouts",
        (
            _name(),
            Column("model", "text", ref="systems.models"),
            Column("payload_layout", "text", ref="payload.layouts", default=None, nullable=True),
            Column("computer", "text", ref="common.computers", default=None, nullable=True),
            _desc(),
        ),
        ("name",),
        "Templates of systems: a model plus the payload layout fitted.",
    ),
    Table(
        "systems",
        "systems",
        "systems",
        (
            Column("id", "int", default=None, doc="internal id = swarm node id, 1..65534"),
            Column("user_id", "text", doc="the operator's id of the airframe"),
            Column("layout", "text", ref="systems.layouts"),
            Column("payload", "int", ref="payload.payloads", default=None, nullable=True),
        ),
        ("id",),
        "Physical systems: a user id and a layout (unique together); the id is the node id.",
        auto_id=True,
    ),
    Table(
        "systems",
        "params",
        "system_params",
        (
            Column("system", "int", ref="systems.systems", cascade=True),
            _param_name(),
            Column("value", "text"),
        ),
        ("system", "name"),
        "Parameters of one system (MAVLink system id, MAC address, udev rule, ...).",
    ),
    # ------------------------------------------------------------------ Swarm
    Table(
        "swarm",
        "missions",
        "missions",
        (_name(), Column("mission_type", "int", enum=MissionType), _desc()),
        ("name",),
        "Kinds of swarm mission (area, target, perimeter, ...).",
    ),
    Table(
        "swarm",
        "mission-params",
        "mission_params",
        (
            Column("mission", "text", ref="swarm.missions", cascade=True),
            _param_name(),
            Column("value", "float"),
            Column("unit", "text", default=""),
            _desc(),
        ),
        ("mission", "name"),
        "Default parameters of a kind of mission (names of swarm_proto MissionParams).",
    ),
    Table(
        "swarm",
        "modules",
        "modules",
        (
            _name(),
            Column("subtype", "text", ref="systems.subtypes", default=None, nullable=True),
            _desc(),
        ),
        ("name",),
        "Swarm modules (collision avoidance for fixed-wing, for multirotors, voting, ...).",
    ),
    Table(
        "swarm",
        "module-params",
        "module_params",
        (
            Column("module", "text", ref="swarm.modules", cascade=True),
            _param_name(),
            Column("value", "float"),
            Column("unit", "text", default=""),
            _desc(),
        ),
        ("module", "name"),
        "Parameters of the swarm modules.",
    ),
    # ------------------------------------------------------------------ Payload
    Table(
        "payload",
        "types",
        "payload_types",
        (_name("e.g. optical, radio frequency, sound"), _desc()),
        ("name",),
        "Top of the payload hierarchy: type -> subtype -> model (voting compares them).",
    ),
    Table(
        "payload",
        "subtypes",
        "payload_subtypes",
        (_name(), Column("type", "text", ref="payload.types"), _desc()),
        ("name",),
        "Payload subtypes, each of one type.",
    ),
    Table(
        "payload",
        "models",
        "payload_models",
        (_name(), Column("subtype", "text", ref="payload.subtypes"), _desc()),
        ("name",),
        "Payload models, each of one subtype.",
    ),
    Table(
        "payload",
        "gimbal-axes",
        "gimbal_axis_params",
        (
            _name(),
            Column("axis", "text", doc="roll, tilt or pan"),
            Column("motor", "text", ref="payload.motors", default=None, nullable=True),
            Column("pid", "text", ref="common.pids", default=None, nullable=True),
            Column("min_angle_deg", "float"),
            Column("max_angle_deg", "float"),
            Column("max_rate_deg_s", "float", default=0.0),
        ),
        ("name",),
        "Parameters of one gimbal axis (roll, tilt or pan).",
    ),
    Table(
        "payload",
        "gimbals",
        "gimbal_configs",
        (
            _name(),
            Column("baud_rate", "int"),
            Column("period_ms", "float"),
            Column("pan_axis", "text", ref="payload.gimbal-axes", default=None, nullable=True),
            Column("tilt_axis", "text", ref="payload.gimbal-axes", default=None, nullable=True),
            Column("roll_axis", "text", ref="payload.gimbal-axes", default=None, nullable=True),
        ),
        ("name",),
        "Gimbal configurations: baud rate, period, and a pan, tilt and roll axis.",
    ),
    Table(
        "payload",
        "sensors",
        "sensors",
        (
            _name(),
            Column("kind", "text", doc="camera, thermal, lidar, radar, sdr, microphone or other"),
            _desc(),
        ),
        ("name",),
        "Sensors (camera, thermal, lidar, ...).",
    ),
    Table(
        "payload",
        "sensor-params",
        "sensor_params",
        (
            Column("sensor", "text", ref="payload.sensors", cascade=True),
            Column("hfov_deg", "float", default=None, nullable=True),
            Column("vfov_deg", "float", default=None, nullable=True),
            Column("width_px", "int", default=None, nullable=True),
            Column("height_px", "int", default=None, nullable=True),
            Column("frame_rate_hz", "float", default=None, nullable=True),
            Column("range_m", "float", default=None, nullable=True),
        ),
        ("sensor",),
        "Sensor specifications: HFOV, VFOV, resolution (camera lane spacing uses them).",
    ),
    Table(
        "payload",
        "layouts",
        "payload_layouts",
        (
            _name(),
            Column("model", "text", ref="payload.models"),
            Column("gimbal", "text", ref="payload.gimbals", default=None, nullable=True),
            Column("sensor", "text", ref="payload.sensors", default=None, nullable=True),
            _desc(),
        ),
        ("name",),
        "Templates of payloads: a payload model with its gimbal configuration and sensor.",
    ),
    Table(
        "payload",
        "payloads",
        "payloads",
        (
            Column("id", "int", default=None, doc="internal payload id"),
            Column("user_id", "text"),
            Column("layout", "text", ref="payload.layouts"),
        ),
        ("id",),
        "Physical payloads: a user id and a layout (unique together).",
        auto_id=True,
    ),
    Table(
        "payload",
        "params",
        "payload_params",
        (
            Column("payload", "int", ref="payload.payloads", cascade=True),
            _param_name(),
            Column("value", "text"),
        ),
        ("payload", "name"),
        "Parameters of one payload (interfaces, protocols, ...).",
    ),
    Table(
        "payload",
        "detection-classes",
        "autodetection_classes",
        (_name(), _desc()),
        ("name",),
        "Classes the payload autodetection reports (person, vehicle, ...).",
        since=2,
    ),
    Table(
        "payload",
        "motors",
        "motors",
        (_name(), Column("kind", "text", doc="servo, brushless, stepper or dc"), _desc()),
        ("name",),
        "Gimbal motorisation.",
    ),
    # ------------------------------------------------------------------ Common
    Table(
        "common",
        "computers",
        "computer_layouts",
        (
            _name(),
            Column("board", "text"),
            Column("cpu", "text", default=""),
            Column("ram_mb", "int", default=0),
            Column("os", "text", default=""),
            _desc(),
        ),
        ("name",),
        "Onboard (companion) computer layouts: Raspberry Pi, NVIDIA Jetson, ...",
    ),
    Table(
        "common",
        "comms",
        "comms_systems",
        (
            _name(),
            Column("kind", "text", doc="xtend900, microhard, wifi, ethernet, lte or other"),
            Column("address", "text", default="", doc="IP address or serial device"),
            Column(
                "system", "int", ref="systems.systems", default=None, nullable=True, cascade=True
            ),
            _desc(),
        ),
        ("name",),
        "Communication systems and their addresses.",
    ),
    Table(
        "common",
        "corrections",
        "corrections",
        (
            Column("bug_id", "text"),
            Column("module", "text"),
            Column("description", "text"),
            Column("criticality", "text", doc="low, medium, high or critical"),
        ),
        ("bug_id",),
        "Known bugs: id, module, description, criticality (the GCS colours by it).",
    ),
    Table(
        "common",
        "pids",
        "pid_controllers",
        (
            _name(),
            Column("p", "float"),
            Column("i", "float"),
            Column("d", "float"),
            Column("max_integral", "float"),
            Column("anti_windup", "bool", default=True),
        ),
        ("name",),
        "PID controllers of the gimbals.",
    ),
)

BY_NAME: dict[str, Table] = {t.qualname: t for t in TABLES}
BY_SQL: dict[str, Table] = {t.sql: t for t in TABLES}

# Write order: every table after the tables it references (deletes go in reverse).
WRITE_ORDER: tuple[Table, ...] = tuple(
    BY_NAME[n]
    for n in (
        "common.computers",
        "common.pids",
        "payload.types",
        "payload.subtypes",
        "payload.models",
        "payload.motors",
        "payload.gimbal-axes",
        "payload.gimbals",
        "payload.sensors",
        "payload.sensor-params",
        "payload.layouts",
        "payload.payloads",
        "payload.params",
        "payload.detection-classes",
        "systems.types",
        "systems.subtypes",
        "systems.models",
        "systems.model-params",
        "systems.layouts",
        "systems.systems",
        "systems.params",
        "swarm.missions",
        "swarm.mission-params",
        "swarm.modules",
        "swarm.module-params",
        "common.comms",
        "common.corrections",
    )
)


def tables_of(group: str) -> tuple[Table, ...]:
    check_group(group)
    return tuple(t for t in TABLES if t.group == group)


def check_group(group: str) -> str:
    if group not in GROUPS:
        raise UnknownTableError(f"unknown group {shown(group)}; groups: {', '.join(GROUPS)}")
    return group


def table(group: str, name: str | None = None) -> Table:
    """A table by group and short name, or by "group.name"."""
    if name is None:
        group, _, name = group.partition(".")
    check_group(group)
    found = BY_NAME.get(f"{group}.{name}")
    if found is None:
        names = ", ".join(t.name for t in tables_of(group))
        raise UnknownTableError(f"unknown table {shown(name)} in group {group}; tables: {names}")
    return found


def referrers(target: Table) -> list[tuple[Table, Column]]:
    """Every (table, field) that references `target`."""
    return [(t, c) for t in TABLES for c in t.columns if c.ref == target.qualname]


def ref_kind(col: Column) -> str:
    """The kind of value a reference field holds: the referenced table's key kind."""
    assert col.ref is not None
    target = BY_NAME[col.ref]
    return target.by_column[target.key[0]].kind


# ---------------------------------------------------------------------------- values

_TRUE = {"true", "yes", "on", "1"}
_FALSE = {"false", "no", "off", "0"}


def convert(table: Table, col: Column, value: Any, *, text: bool = False) -> Any:
    """A checked value for `col` from JSON-like input (`text=False`) or from
    command-line text (`text=True`: "26.5", "true", "VTOL", an empty string for null).
    Raises InvalidValueError naming the field."""
    where = f"{table.qualname}.{col.name}"
    if text and isinstance(value, str) and value == "" and col.nullable:
        return None
    if value is None:
        if col.nullable or (col.name == "id" and table.auto_id):
            return None
        raise InvalidValueError(f"{where}: a value is required")
    kind = ref_kind(col) if col.ref else col.kind
    try:
        if col.enum is not None:
            return _enum(col.enum, value, text)
        if kind == "int":
            return _int(value, text)
        if kind == "float":
            return _float(value, text)
        if kind == "bool":
            return _bool(value, text)
        return _text(value)
    except (TypeError, ValueError, OverflowError) as exc:
        raise InvalidValueError(f"{where}: {exc}") from None


def _int(v: Any, text: bool) -> int:
    if text and isinstance(v, str):
        v = int(v.strip())
    if isinstance(v, bool) or not isinstance(v, int):
        raise TypeError(f"expected an integer, got {shown(v)}")
    if not INT64[0] <= v <= INT64[1]:
        raise ValueError(f"integer {v} out of range")
    return v


def _float(v: Any, text: bool) -> float:
    if text and isinstance(v, str):
        v = float(v.strip())
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise TypeError(f"expected a number, got {shown(v)}")
    f = float(v)
    if not math.isfinite(f):
        raise ValueError(f"expected a finite number, got {shown(v)}")
    return f


def _bool(v: Any, text: bool) -> bool:
    if isinstance(v, bool):
        return v
    if isinstance(v, int) and v in (0, 1):
        return bool(v)
    if text and isinstance(v, str):
        low = v.strip().lower()
        if low in _TRUE:
            return True
        if low in _FALSE:
            return False
    raise TypeError(f"expected true or false, got {shown(v)}")


def _text(v: Any) -> str:
    if not isinstance(v, str):
        raise TypeError(f"expected text, got {shown(v)}")
    if "\x00" in v:
        raise ValueError("text must not contain NUL characters")
    try:
        v.encode("utf-8")
    except UnicodeEncodeError:
        raise ValueError("text is not valid Unicode (lone surrogate)") from None
    return v


def _enum(enum: type[IntEnum], v: Any, text: bool) -> int:
    if isinstance(v, str):
        s = v.strip()
        if text and s.lstrip("-").isdigit():
            return _int(int(s), False)
        for member in enum:
            if member.name.lower() == s.lower().replace("-", "_"):
                return int(member.value)
        names = ", ".join(m.name for m in enum)
        raise ValueError(f"unknown {enum.__name__} {shown(v)}; one of {names} (or an integer)")
    return _int(v, False)


def show_enum(col: Column, value: Any) -> Any:
    """The exported form of a stored value: an enum's name where it has one."""
    if col.enum is not None and value is not None:
        try:
            return col.enum(value).name
        except ValueError:
            return value
    if col.kind == "bool" and value is not None:
        return bool(value)
    return value


def check_fields(table: Table, record: Mapping[str, Any]) -> None:
    for name in record:
        table.column(name)


# ---------------------------------------------------------------------------- docs


def render_markdown() -> str:
    """The table reference of docs/database.md (`python -m swarm_node.database`;
    tests/swarm_node/database/test_docs.py fails when the doc is stale)."""
    out = ["<!-- generated by `python -m swarm_node.database`: do not edit -->", ""]
    for group in GROUPS:
        out += [f"### {group}", ""]
        out += ["| table | key | fields | what |", "|---|---|---|---|"]
        for t in tables_of(group):
            fields = []
            for c in t.columns:
                text = f"`{c.name}`"
                if c.ref:
                    text += f" -> {c.ref}"
                elif c.enum is not None:
                    text += f" ({c.enum.__name__})"
                else:
                    text += f" ({c.kind})"
                if c.nullable:
                    text += " or null"
                if not c.required and c.default is not None and not (t.auto_id and c.name == "id"):
                    text += f" = {c.default!r}"
                fields.append(text)
            key = " + ".join(t.key)
            out.append(f"| `{t.name}` (`{t.sql}`) | {key} | {', '.join(fields)} | {t.doc} |")
        out.append("")
    return "\n".join(out)
