"""The swarm database over Zenoh: a queryable that serves a node's database to peers,
and the client functions that query it.

Keys (under `bandada/<swarm>/`, `swarm_proto.topics.DATABASE`):

    db/<node_id>                          DbInfo: schema version, record count per table
    db/<node_id>/profile                  VehicleProfile of the node itself
    db/<node_id>/profiles                 list of VehicleProfile: every system it knows
    db/<node_id>/table/<group>/<table>    list of records; `?field=value;...` filters
    db/<node_id>/export                   the export document (every group)

Replies are MessagePack (msgspec), encoding `application/msgpack`, with the same field
names as the JSON export; an error is a `reply_err` carrying `{"error": "<message>"}`.
Wildcards work as in any Zenoh query: `db/*/profile` asks every node for its own
profile, `db/*` lists the nodes serving a database. Plain zenoh-python + msgspec can
read every reply (docs/database.md has an example).

Peers' garbage is the peer's fault: the client raises `DbQueryError` (one node) or
skips and logs the bad reply (wildcards); the queryable answers malformed queries with
an error reply and counts them, never raising into Zenoh's thread.
"""

from __future__ import annotations

import logging
import threading
import time
from collections import Counter
from typing import Any

import msgspec
import zenoh

from swarm_node.core.profile import VehicleProfile
from swarm_proto.topics import DATABASE, prefix

from .errors import SwarmDbError, shown
from .repository import SwarmDatabase
from .tables import TABLES, table

log = logging.getLogger(__name__)

ENCODING = "application/msgpack"
DEFAULT_TIMEOUT_S = 5.0

_encoder = msgspec.msgpack.Encoder()


class DbInfo(msgspec.Struct, frozen=True):
    """What `db/<node_id>` answers."""

    node_id: int
    schema_version: int
    tables: dict[str, int]  # "group/table" -> number of records


class DbQueryError(SwarmDbError):
    """A database query got no answer, an error answer, or a malformed answer."""


def _error(message: str) -> bytes:
    return _encoder.encode({"error": message})


def table_resources() -> list[str]:
    return [f"table/{t.group}/{t.name}" for t in TABLES]


RESOURCES: tuple[str, ...] = ("", "profile", "profiles", "export", *table_resources())


class DatabaseQueryable:
    """Serves `db` to peers under `bandada/<swarm>/db/<node_id>/**` until `close()`."""

    def __init__(
        self, session: zenoh.Session, db: SwarmDatabase, node_id: int, swarm: str = "default"
    ) -> None:
        self.db = db
        self.node_id = node_id
        self.base = DATABASE.key(swarm, node_id=node_id)
        self.served: Counter[str] = Counter()  # resource -> replies sent
        self.errors: Counter[str] = Counter()  # reason -> error replies
        self._keys = [(r, zenoh.KeyExpr(self._key(r))) for r in RESOURCES]
        self._lock = threading.Lock()
        self._queryable: zenoh.Queryable[Any] | None = session.declare_queryable(
            f"{self.base}/**", self._on_query
        )

    def _key(self, resource: str) -> str:
        return f"{self.base}/{resource}" if resource else self.base

    def close(self) -> None:
        with self._lock:
            q, self._queryable = self._queryable, None
        if q is not None:
            try:
                q.undeclare()
            except Exception:  # the session is already closed
                log.debug("undeclare failed", exc_info=True)

    def __enter__(self) -> DatabaseQueryable:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # ------------------------------------------------------------------ serving
    def _on_query(self, query: zenoh.Query) -> None:
        try:
            self._serve(query)
        except Exception:  # never raise into Zenoh's thread
            log.exception("database query %s failed", query.selector)
            self.errors["internal"] += 1
            try:
                query.reply_err(_error("internal error serving the query"))
            except Exception:
                log.debug("reply_err failed", exc_info=True)

    def _serve(self, query: zenoh.Query) -> None:
        qke = query.key_expr
        matched = [r for r, k in self._keys if qke.intersects(k)]
        if not matched:
            self.errors["unknown"] += 1
            known = ", ".join(r or "(info)" for r in RESOURCES[:4]) + ", table/<group>/<table>"
            query.reply_err(_error(f"{qke}: no such resource; known: {known}"))
            return
        params = dict(query.parameters.__iter__())  # the stub types __iter__ as a list
        for resource in matched:
            try:
                payload = self.answer(resource, params)
            except SwarmDbError as exc:
                self.errors["refused"] += 1
                query.reply_err(_error(f"{self._key(resource)}: {exc}"))
                continue
            query.reply(self._key(resource), payload, encoding=zenoh.Encoding(ENCODING))
            self.served[resource or "info"] += 1

    def answer(self, resource: str, params: dict[str, str] | None = None) -> bytes:
        """The encoded reply for one resource (raises SwarmDbError)."""
        params = params or {}
        if resource == "":
            counts = {k.replace(".", "/", 1): n for k, n in self.db.counts().items()}
            return _encoder.encode(DbInfo(self.node_id, self.db.schema_version, counts))
        if resource == "profile":
            return _encoder.encode(self.db.vehicle_profile(vehicle_id=self.node_id))
        if resource == "profiles":
            return _encoder.encode(self.db.profiles())
        if resource == "export":
            return _encoder.encode(self.db.export())
        _, group, name = resource.split("/")
        t = table(group, name)
        for field in params:  # checked even when the table is empty
            if field not in t.by_column:
                raise SwarmDbError(f"unknown field {shown(field)} in filter")
        records = self.db.records(t)
        records = [r for r in records if all(str(r[k]) == v for k, v in params.items())]
        return _encoder.encode(records)


# ---------------------------------------------------------------------------- client


class DbReply(msgspec.Struct, frozen=True):
    """One reply to a database query: `value` decoded from MessagePack, or `error`."""

    key: str
    value: Any = None
    error: str | None = None


def selector(swarm: str, node_id: int | str = "*", resource: str = "", **filters: Any) -> str:
    """The selector of a resource of one node (or of every node: node_id="*")."""
    key = f"{prefix(swarm)}/db/{node_id}" + (f"/{resource}" if resource else "")
    if filters:
        key += "?" + ";".join(f"{k}={v}" for k, v in filters.items())
    return key


def query(
    session: zenoh.Session, sel: str, *, timeout_s: float = DEFAULT_TIMEOUT_S
) -> list[DbReply]:
    """Every reply to a database selector, decoded (never raises on a peer's bytes)."""
    out: list[DbReply] = []
    replies = session.get(sel, timeout=timeout_s, consolidation=zenoh.ConsolidationMode.NONE)
    for reply in replies:
        if reply.ok is not None:
            sample = reply.ok
            key = str(sample.key_expr)
            try:
                out.append(DbReply(key, msgspec.msgpack.decode(sample.payload.to_bytes())))
            except msgspec.DecodeError as exc:
                out.append(DbReply(key, error=f"malformed reply: {exc}"))
        else:
            err = reply.err
            text = "error reply"
            try:
                body = msgspec.msgpack.decode(err.payload.to_bytes()) if err is not None else None
                if isinstance(body, dict) and isinstance(body.get("error"), str):
                    text = body["error"]
            except msgspec.DecodeError:
                text = "malformed error reply"
            out.append(DbReply(sel, error=text))
    return out


def fetch(
    session: zenoh.Session,
    swarm: str,
    node_id: int,
    resource: str = "",
    *,
    timeout_s: float = DEFAULT_TIMEOUT_S,
    **filters: Any,
) -> Any:
    """The decoded value of one node's resource; DbQueryError if none or an error.
    Asks again until `timeout_s` while nobody answers (a new session or a node that
    just started has not yet learnt the other's queryable)."""
    sel = selector(swarm, node_id, resource, **filters)
    deadline = time.monotonic() + timeout_s
    while True:
        replies = query(session, sel, timeout_s=max(0.1, deadline - time.monotonic()))
        if replies or time.monotonic() >= deadline:
            break
        time.sleep(0.1)
    for r in replies:
        if r.error is None:
            return r.value
    if replies:
        raise DbQueryError(f"{sel}: {replies[0].error}")
    raise DbQueryError(f"{sel}: no reply within {timeout_s:g} s (is node {node_id} up?)")


def _convert(value: Any, typ: Any, what: str) -> Any:
    try:
        return msgspec.convert(value, typ)
    except msgspec.ValidationError as exc:
        raise DbQueryError(f"{what}: malformed reply ({exc})") from None


def fetch_info(
    session: zenoh.Session, swarm: str, node_id: int, *, timeout_s: float = DEFAULT_TIMEOUT_S
) -> DbInfo:
    value = fetch(session, swarm, node_id, timeout_s=timeout_s)
    info: DbInfo = _convert(value, DbInfo, f"node {node_id} info")
    return info


def fetch_profile(
    session: zenoh.Session, swarm: str, node_id: int, *, timeout_s: float = DEFAULT_TIMEOUT_S
) -> VehicleProfile:
    """A peer's own VehicleProfile, from its database."""
    value = fetch(session, swarm, node_id, "profile", timeout_s=timeout_s)
    profile: VehicleProfile = _convert(value, VehicleProfile, f"node {node_id} profile")
    return profile


def fetch_profiles(
    session: zenoh.Session, swarm: str, *, timeout_s: float = DEFAULT_TIMEOUT_S
) -> dict[int, VehicleProfile]:
    """Every reachable node's own profile (`db/*/profile`), by node id. Nodes without
    a profile and malformed replies are skipped (and logged)."""
    out: dict[int, VehicleProfile] = {}
    for r in query(session, selector(swarm, "*", "profile"), timeout_s=timeout_s):
        if r.error is not None:
            log.info("database query: %s", r.error)
            continue
        try:
            p = msgspec.convert(r.value, VehicleProfile)
        except msgspec.ValidationError as exc:
            log.warning("malformed profile from %s: %s", r.key, exc)
            continue
        out[p.vehicle_id] = p
    return out


def fetch_table(
    session: zenoh.Session,
    swarm: str,
    node_id: int,
    group: str,
    table: str,
    *,
    timeout_s: float = DEFAULT_TIMEOUT_S,
    **filters: Any,
) -> list[dict[str, Any]]:
    value = fetch(session, swarm, node_id, f"table/{group}/{table}", timeout_s=timeout_s, **filters)
    records: list[dict[str, Any]] = _convert(
        value, list[dict[str, Any]], f"node {node_id} {group}.{table}"
    )
    return records


def fetch_export(
    session: zenoh.Session, swarm: str, node_id: int, *, timeout_s: float = DEFAULT_TIMEOUT_S
) -> dict[str, Any]:
    value = fetch(session, swarm, node_id, "export", timeout_s=timeout_s)
    doc: dict[str, Any] = _convert(value, dict[str, Any], f"node {node_id} export")
    return doc
