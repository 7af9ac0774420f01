"""Export -> import is lossless (the seed data, and random records added on top); an
import is all or nothing, and a malformed document is a clear DocumentError."""

from __future__ import annotations

import copy
from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from swarm_node.database import (
    DocumentError,
    DuplicateError,
    InUseError,
    InvalidValueError,
    SwarmDatabase,
    UnknownReferenceError,
)
from swarm_node.database.document import decode_json, encode_json
from tests.conftest import examples

from .conftest import snapshot


def _roundtrip(db: SwarmDatabase) -> dict[str, Any]:
    """export -> JSON bytes -> a fresh empty database -> export."""
    data = encode_json(db.export())
    with SwarmDatabase.memory(seed=False) as fresh:
        fresh.import_document(decode_json(data))
        return fresh.export()


def test_seed_export_import_is_lossless(seeded: SwarmDatabase) -> None:
    exported = seeded.export()
    assert _roundtrip(seeded) == exported
    with SwarmDatabase.memory(seed=False) as fresh:
        fresh.import_document(exported)
        assert fresh.profiles() == seeded.profiles()
        assert fresh.payload_classes() == seeded.payload_classes()


def test_export_to_a_file_and_back(tmp_path: Path, seeded: SwarmDatabase) -> None:
    out = tmp_path / "fleet.json"
    out.write_bytes(encode_json(seeded.export()))
    with SwarmDatabase.open(tmp_path / "other.db", seed=False) as other:
        written = other.import_document(decode_json(out.read_bytes()), source=str(out))
        assert sum(written.values()) == sum(seeded.counts().values())
        assert other.export() == seeded.export()


_names = st.text(
    alphabet=st.characters(codec="utf-8", exclude_categories=("Cs", "Cc", "Zs", "Zl", "Zp")),
    min_size=1,
    max_size=48,
)
_text = st.text(alphabet=st.characters(codec="utf-8", exclude_characters="\x00"), max_size=200)


@st.composite
def _additions(draw: st.DrawFn) -> list[tuple[str, dict[str, Any]]]:
    """Random valid records to add on top of the seed data (fresh names each time)."""
    out: list[tuple[str, dict[str, Any]]] = []
    used: set[str] = set()

    def fresh(prefix: str) -> str:
        name = draw(_names.filter(lambda s: (prefix + s)[:48] not in used))
        name = (prefix + name)[:48]
        used.add(name)
        return name

    for _ in range(draw(st.integers(0, 3))):
        model = fresh("m:")
        stall = draw(st.floats(0, 100, allow_nan=False))
        cruise = draw(st.floats(stall, 200))
        out.append(
            (
                "systems.models",
                {
                    "name": model,
                    "subtype": draw(st.sampled_from(["VTOL", "multirotor", "boat"])),
                    "description": draw(_text),
                },
            )
        )
        out.append(
            (
                "systems.model-params",
                {
                    "model": model,
                    "cruise_speed_m_s": cruise,
                    "min_speed_m_s": stall,
                    "max_speed_m_s": draw(st.floats(cruise, 300)),
                    "max_bank_deg": draw(st.floats(0, 89.999)),
                    "loiter_radius_m": draw(st.floats(0, 10000)),
                    "has_parachute": draw(st.booleans()),
                    "battery_low_pct": 50,
                    "battery_critical_pct": draw(st.integers(0, 49)),
                },
            )
        )
        layout = fresh("l:")
        out.append(("systems.layouts", {"name": layout, "model": model, "payload_layout": None}))
        for _ in range(draw(st.integers(0, 3))):
            uid = fresh("u:")
            node = draw(st.integers(14, 899).filter(lambda i: str(i) not in used))
            used.add(str(node))
            out.append(("systems.systems", {"id": node, "user_id": uid, "layout": layout}))
            out.append(("systems.params", {"system": node, "name": "note", "value": draw(_text)}))
    for _ in range(draw(st.integers(0, 2))):
        out.append(
            (
                "common.corrections",
                {
                    "bug_id": fresh("b:"),
                    "module": draw(_names),
                    "description": draw(_names),
                    "criticality": draw(st.sampled_from(["low", "medium", "high", "critical"])),
                },
            )
        )
    for _ in range(draw(st.integers(0, 2))):
        sensor = fresh("s:")
        out.append(("payload.sensors", {"name": sensor, "kind": "camera"}))
        out.append(
            (
                "payload.sensor-params",
                {
                    "sensor": sensor,
                    "hfov_deg": draw(st.one_of(st.none(), st.floats(1e-9, 179.9))),
                    "vfov_deg": draw(st.floats(0.001, 179.9)),
                    "width_px": draw(st.one_of(st.none(), st.integers(1, 100000))),
                },
            )
        )
    return out


@settings(max_examples=examples(20), suppress_health_check=[HealthCheck.too_slow])
@given(additions=_additions())
def test_export_import_round_trip_is_lossless_for_any_records(
    additions: list[tuple[str, dict[str, Any]]],
) -> None:
    with SwarmDatabase.memory() as db:
        for table, record in additions:
            stored = db.add(table, record)
            for k, v in record.items():  # what goes in comes out
                assert stored[k] == v, (table, k)
        exported = db.export()
        assert _roundtrip(db) == exported
        with SwarmDatabase.memory(seed=False) as fresh:
            fresh.import_document(exported)
            assert fresh.profiles() == db.profiles()


def test_a_failed_import_writes_nothing(tmp_path: Path) -> None:
    path = tmp_path / "swarm.db"
    with SwarmDatabase.open(path) as db:
        before = db.export()
        doc = db.export(["systems"])
        doc["groups"]["systems"]["systems"].append({"id": 77, "user_id": "NEW", "layout": "nope"})
        doc["groups"]["systems"]["types"].append({"name": "UUV"})  # valid, earlier in order
        with pytest.raises(
            UnknownReferenceError, match=r"systems.systems\[14\]: .*layout 'nope' not found"
        ):
            db.import_document(doc, source="fleet.json")
        assert db.export() == before
    bytes_before = snapshot(path)[0]
    dup = copy.deepcopy(before)
    dup["groups"]["systems"]["systems"].append(
        {"id": 60, "user_id": "ALB-01", "layout": "Albatross 250 VTOL + EO 1.5 Mpx"}
    )
    with SwarmDatabase.open(path) as db, pytest.raises(DuplicateError, match=r"user_id \+ layout"):
        db.import_document(dup)
    assert path.read_bytes() == bytes_before


def test_import_merges_by_key(seeded: SwarmDatabase) -> None:
    doc = seeded.export(["systems"])
    params = doc["groups"]["systems"]["model-params"]
    params[0]["loiter_radius_m"] = 120.0
    only = {
        "format": doc["format"],
        "schema_version": 2,
        "groups": {"systems": {"model-params": params}},
    }
    written = seeded.import_document(only)
    assert written == {"systems.model-params": 5}
    assert seeded.vehicle_profile(1).loiter_radius_m == 120.0
    assert seeded.counts()["systems.model-params"] == 5


def test_replace_empties_the_documents_tables(seeded: SwarmDatabase) -> None:
    doc = seeded.export(["common"])
    doc["groups"]["common"]["corrections"] = [
        {"bug_id": "BND-1", "module": "voting", "description": "ties", "criticality": "low"}
    ]
    doc["groups"]["common"]["comms"] = doc["groups"]["common"]["comms"][:2]
    seeded.import_document(doc, replace=True)
    assert seeded.counts()["common.comms"] == 2
    assert seeded.counts()["common.corrections"] == 1
    # replacing a table that other (absent) tables use is refused, nothing changes
    before = seeded.export()
    models = {"format": doc["format"], "schema_version": 2, "groups": {"systems": {"models": []}}}
    with pytest.raises(InUseError, match=r"cannot replace systems\.models"):
        seeded.import_document(models, replace=True)
    assert seeded.export() == before


def test_a_previous_version_document_imports_with_defaults() -> None:
    with SwarmDatabase.memory() as db:
        doc = db.export()
    doc["schema_version"] = 1
    for rec in doc["groups"]["systems"]["model-params"]:
        for k in ("battery_low_pct", "battery_critical_pct", "max_tilt_deg", "max_wind_m_s"):
            del rec[k]
    for rec in doc["groups"]["systems"]["systems"]:
        del rec["payload"]
    del doc["groups"]["payload"]["detection-classes"]
    with SwarmDatabase.memory(seed=False) as fresh:
        fresh.import_document(doc)
        assert fresh.vehicle_profile(1).battery_low_pct == 30
        assert fresh.counts()["payload.detection-classes"] == 0


@pytest.mark.parametrize(
    ("data", "match"),
    [
        (b"{not json", "not valid JSON"),
        (b"[]", "expected a JSON object"),
        (b'{"format": "other"}', "not a bandada swarm database export"),
        (b'{"format": "bandada-swarm-db", "schema_version": 99, "groups": {}}', "newer bandada"),
        (
            b'{"format": "bandada-swarm-db", "schema_version": "2", "groups": {}}',
            "positive integer",
        ),
        (b'{"format": "bandada-swarm-db", "schema_version": 2, "groups": []}', "'groups' must be"),
        (
            b'{"format": "bandada-swarm-db", "schema_version": 2, "groups": {"fleet": {}}}',
            "unknown group 'fleet'",
        ),
        (
            b'{"format": "bandada-swarm-db", "schema_version": 2, "groups": {"systems": {"cars": []}}}',
            "unknown table 'cars'",
        ),
        (
            b'{"format": "bandada-swarm-db", "schema_version": 2, "groups": {"systems": {"types": {}}}}',
            "must be a list of objects",
        ),
        (
            b'{"format": "bandada-swarm-db", "schema_version": 2, "groups": {"systems": {"types": [1]}}}',
            "must be a list of objects",
        ),
    ],
)
def test_malformed_documents_are_refused(data: bytes, match: str) -> None:
    with pytest.raises(DocumentError, match=match):
        decode_json(data, source="in.json")


def test_bad_fields_in_a_document_name_the_record(seeded: SwarmDatabase) -> None:
    doc = {
        "format": "bandada-swarm-db",
        "schema_version": 2,
        "groups": {"systems": {"types": [{"name": "OK"}, {"name": "X", "wheels": 4}]}},
    }
    with pytest.raises(
        InvalidValueError, match=r"in.json: systems.types\[1\]: .*unknown field 'wheels'"
    ):
        seeded.import_document(doc, source="in.json")
    assert "OK" not in [r["name"] for r in seeded.records("systems.types")]
