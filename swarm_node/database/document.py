"""The export document: the whole database (or some groups of it) as plain data, written
as JSON by `gcs db export` and served as MessagePack by the Zenoh queryable.

    {"format": "bandada-swarm-db", "schema_version": 2,
     "groups": {"systems": {"models": [{"name": ..., "subtype": ...}, ...], ...},
                "swarm": {...}, "payload": {...}, "common": {...}}}

Records use field names and reference other records by their key (a model by its name,
a system by its id), never by internal row ids, so a document can be merged into
another database. Pure: bytes in, checked data out; errors are DocumentError.
"""

from __future__ import annotations

from typing import Any

import msgspec

from .errors import DocumentError, UnknownTableError, shown
from .schema import LATEST_VERSION
from .tables import GROUPS, Table, table

FORMAT = "bandada-swarm-db"

Record = dict[str, Any]


def empty_document(version: int = LATEST_VERSION) -> dict[str, Any]:
    return {"format": FORMAT, "schema_version": version, "groups": {}}


def encode_json(doc: dict[str, Any]) -> bytes:
    return msgspec.json.format(msgspec.json.encode(doc), indent=2) + b"\n"


def decode_json(data: bytes | str, source: str = "document") -> dict[str, Any]:
    try:
        doc = msgspec.json.decode(data)
    except msgspec.DecodeError as exc:
        raise DocumentError(f"{source}: not valid JSON ({exc})") from None
    except RecursionError:
        raise DocumentError(
            f"{source}: not usable JSON (arrays or objects nested too deeply)"
        ) from None
    check_document(doc, source)
    return doc


def check_document(doc: Any, source: str = "document") -> list[tuple[Table, list[Record]]]:
    """The tables and records of a document, after checking its shape; records are
    checked field by field when written."""
    if not isinstance(doc, dict):
        raise DocumentError(f"{source}: expected a JSON object, got {type(doc).__name__}")
    if doc.get("format") != FORMAT:
        raise DocumentError(
            f"{source}: not a bandada swarm database export "
            f"(format {shown(doc.get('format'))}, expected {FORMAT!r})"
        )
    version = doc.get("schema_version")
    if isinstance(version, bool) or not isinstance(version, int) or version < 1:
        raise DocumentError(f"{source}: schema_version must be a positive integer")
    if version > LATEST_VERSION:
        raise DocumentError(
            f"{source}: written by a newer bandada (schema version {version}; "
            f"this one knows up to {LATEST_VERSION}): upgrade bandada to import it"
        )
    groups = doc.get("groups")
    if not isinstance(groups, dict):
        raise DocumentError(f"{source}: 'groups' must be an object of groups")
    out: list[tuple[Table, list[Record]]] = []
    for group, tables in groups.items():
        if group not in GROUPS:
            raise DocumentError(
                f"{source}: unknown group {shown(group)}; groups: {', '.join(GROUPS)}"
            )
        if not isinstance(tables, dict):
            raise DocumentError(f"{source}: group {shown(group)} must be an object of tables")
        for name, records in tables.items():
            try:
                t = table(group, name)
            except UnknownTableError as exc:
                raise DocumentError(f"{source}: {exc}") from None
            if not isinstance(records, list) or not all(isinstance(r, dict) for r in records):
                raise DocumentError(f"{source}: {t.qualname} must be a list of objects")
            out.append((t, records))
    return out
