"""`gcs db`: the swarm database from the command line.

    gcs db list [GROUP [TABLE]] [--json]      groups, tables and counts; or records
    gcs db show GROUP TABLE KEY... [--json]   one record
    gcs db add GROUP TABLE FIELD=VALUE... [--record JSON]
    gcs db remove GROUP TABLE KEY...
    gcs db export FILE [--group GROUP]...     JSON ("-" = stdout)
    gcs db import FILE [--replace]            JSON ("-" = stdin), all or nothing
    gcs db profile VEHICLE [--json]           what a node resolves: VehicleProfile
    gcs db query NODE [RESOURCE] --connect ENDPOINT   a peer's database over Zenoh
    gcs db path                               which file is used

Groups: systems, swarm, payload, common (paper section 2.3.1). The file is `--db PATH`,
else `$BANDADA_DB`, else `~/.local/share/bandada/swarm.db` (XDG); a missing file is
created with the seed data; a corrupt or foreign file is refused and left untouched.
Exit status: 0 ok, 1 the database refused (message on stderr), 2 usage.
"""

from __future__ import annotations

import json
import math
import os
import sqlite3
import sys
import tempfile
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Annotated, Any

import msgspec
import typer
from rich.console import Console
from rich.table import Table as RichTable

from swarm_node.database import SwarmDatabase, SwarmDbError, resolve_db_path
from swarm_node.database.document import decode_json, encode_json
from swarm_node.database.tables import GROUPS, TABLES, Table, convert, table, tables_of
from swarm_proto.session import zenoh_reason as _zenoh_reason

_TABLES_HELP = "\n\n".join(
    f"{g}: {', '.join(t.name for t in TABLES if t.group == g)}" for g in GROUPS
)
app = typer.Typer(
    help="The swarm database: systems, swarm, payload and common tables (docs/database.md).",
    epilog=f"Tables by group:\n\n{_TABLES_HELP}",
    no_args_is_help=True,
)

DbOption = Annotated[
    Path | None,
    typer.Option(
        "--db",
        envvar="BANDADA_DB",
        help="database file (default: $BANDADA_DB, else ~/.local/share/bandada/swarm.db)",
        show_default=False,
        readable=False,  # checked by the database, with its own message
    ),
]
JsonOption = Annotated[bool, typer.Option("--json", help="print JSON")]


def _fail(message: str, code: int = 1) -> typer.Exit:
    typer.echo(f"error: {message}", err=True)
    return typer.Exit(code)


@contextmanager
def _open(db_path: Path | None) -> Iterator[SwarmDatabase]:
    """The database, or exit 1 with a one-line message: the database's own errors, and
    as a last resort any OSError or SQLite error (never a traceback)."""
    path = resolve_db_path(db_path)
    try:
        db = SwarmDatabase.open(path)
    except SwarmDbError as exc:
        raise _fail(str(exc)) from None
    except (OSError, sqlite3.Error) as exc:
        raise _fail(f"{path}: {_why(exc)}") from None
    if db.created:
        typer.echo(f"created {path} with the seed data", err=True)
    try:
        yield db
    except SwarmDbError as exc:
        raise _fail(str(exc)) from None
    except (OSError, sqlite3.Error) as exc:
        raise _fail(f"{path}: {_why(exc)}") from None
    finally:
        db.close()


def _why(exc: BaseException) -> str:
    if isinstance(exc, OSError) and exc.strerror:
        return f"{exc.strerror} ({exc.filename})" if exc.filename else exc.strerror
    return str(exc)


def _table(group: str, name: str) -> Table:
    try:
        return table(group, name)
    except SwarmDbError as exc:
        raise _fail(str(exc), 2) from None


def _console() -> Console:
    return Console(soft_wrap=False, width=max(100, Console().width))


def _json_out(value: Any) -> None:
    typer.echo(encode_json(value).decode().rstrip("\n"))


def _cell(value: Any) -> str:
    return "" if value is None else str(value)


def _print_records(t: Table, records: list[dict[str, Any]]) -> None:
    console = _console()
    title = f"{t.qualname} ({len(records)}): {t.doc}"
    if len(t.columns) > 7 and 0 < len(records) <= 8:  # wide and short: one column a record
        key = t.key[0]
        rt = RichTable(title=title, title_justify="left")
        rt.add_column("field")
        for r in records:
            rt.add_column(_cell(r[key]))
        for c in t.columns:
            if c.name != key:
                rt.add_row(c.name, *(_cell(r[c.name]) for r in records))
    else:
        rt = RichTable(title=title, title_justify="left")
        for c in t.columns:
            rt.add_column(c.name)
        for r in records:
            rt.add_row(*(_cell(r[c.name]) for c in t.columns))
    console.print(rt)


def _print_record(t: Table, record: dict[str, Any]) -> None:
    rt = RichTable(title=t.qualname, title_justify="left", show_header=False)
    rt.add_column("field", style="bold")
    rt.add_column("value")
    for c in t.columns:
        rt.add_row(c.name, _cell(record[c.name]))
    _console().print(rt)


# ---------------------------------------------------------------------------- commands


@app.command("list")
def list_(
    group: Annotated[
        str | None, typer.Argument(metavar="GROUP", help=f"one of {', '.join(GROUPS)}")
    ] = None,
    table_name: Annotated[
        str | None, typer.Argument(metavar="TABLE", help="a table of GROUP")
    ] = None,
    as_json: JsonOption = False,
    db_path: DbOption = None,
) -> None:
    """Groups and tables with their record counts; a group's records; a table's records.

    Example: gcs db list systems systems --json
    """
    with _open(db_path) as db:
        if group is None:
            counts = db.counts()
            if as_json:
                _json_out({g: {t.name: counts[t.qualname] for t in tables_of(g)} for g in GROUPS})
                return
            rt = RichTable(title=f"swarm database {db.path} (schema v{db.schema_version})")
            for col in ("group", "table", "records", "what"):
                rt.add_column(col)
            for t in TABLES:
                rt.add_row(t.group, t.name, str(counts[t.qualname]), t.doc)
            _console().print(rt)
            return
        if table_name is None:
            try:
                tables = tables_of(group)
            except SwarmDbError as exc:
                raise _fail(str(exc), 2) from None
            if as_json:
                _json_out(db.group(group))
                return
            for t in tables:
                _print_records(t, db.records(t))
            return
        t = _table(group, table_name)
        records = db.records(t)
        if as_json:
            _json_out(records)
        else:
            _print_records(t, records)


@app.command()
def show(
    group: Annotated[str, typer.Argument(metavar="GROUP", help=f"one of {', '.join(GROUPS)}")],
    table_name: Annotated[str, typer.Argument(metavar="TABLE")],
    key: Annotated[
        list[str],
        typer.Argument(
            metavar="KEY...", help="the record's key: a name; for systems/payloads an id or user id"
        ),
    ],
    as_json: JsonOption = False,
    db_path: DbOption = None,
) -> None:
    """One record.

    Example: gcs db show systems models "Generic Quadcopter"
    """
    t = _table(group, table_name)
    with _open(db_path) as db:
        record = db.get(t, *key, text=True)
        if as_json:
            _json_out(record)
        else:
            _print_record(t, record)


def _parse_fields(t: Table, pairs: list[str], record_json: str | None) -> dict[str, Any]:
    record: dict[str, Any] = {}
    if record_json:
        try:
            loaded = json.loads(record_json)
        except json.JSONDecodeError as exc:
            raise _fail(f"--record: not valid JSON ({exc})", 2) from None
        except RecursionError:
            raise _fail("--record: not usable JSON (nested too deeply)", 2) from None
        if not isinstance(loaded, dict):
            raise _fail("--record: expected a JSON object of fields", 2)
        record.update(loaded)
    for pair in pairs:
        name, sep, value = pair.partition("=")
        if not sep or not name:
            raise _fail(f"expected FIELD=VALUE, got {pair!r}", 2)
        record[name] = convert(t, t.column(name), value, text=True)
    return record


@app.command()
def add(
    group: Annotated[str, typer.Argument(metavar="GROUP", help=f"one of {', '.join(GROUPS)}")],
    table_name: Annotated[str, typer.Argument(metavar="TABLE")],
    fields: Annotated[
        list[str] | None,
        typer.Argument(metavar="FIELD=VALUE...", help="an empty VALUE means null"),
    ] = None,
    record_json: Annotated[
        str | None, typer.Option("--record", help="fields as a JSON object")
    ] = None,
    as_json: JsonOption = False,
    db_path: DbOption = None,
) -> None:
    """Add one record; references are by name (or id for systems and payloads).

    Example: gcs db add payload payload-types name=Lidar
    """
    t = _table(group, table_name)
    with _open(db_path) as db:
        record = db.add(t, _parse_fields(t, fields or [], record_json))
        if as_json:
            _json_out(record)
        else:
            typer.echo(f"added to {t.qualname}: {_summary(t, record)}")


def _summary(t: Table, record: dict[str, Any]) -> str:
    return ", ".join(f"{k}={record[k]!r}" for k in t.field_names if record[k] not in (None, ""))


@app.command()
def remove(
    group: Annotated[str, typer.Argument(metavar="GROUP", help=f"one of {', '.join(GROUPS)}")],
    table_name: Annotated[str, typer.Argument(metavar="TABLE")],
    key: Annotated[list[str], typer.Argument(metavar="KEY...", help="the record's key")],
    as_json: JsonOption = False,
    db_path: DbOption = None,
) -> None:
    """Remove one record (and its own parameters); refused while others use it.

    Example: gcs db remove systems systems 13
    """
    t = _table(group, table_name)
    with _open(db_path) as db:
        record = db.remove(t, *key, text=True)
        if as_json:
            _json_out(record)
        else:
            typer.echo(f"removed from {t.qualname}: {_summary(t, record)}")


@app.command()
def export(
    file: Annotated[str, typer.Argument(help="JSON file to write, '-' for stdout")],
    group: Annotated[
        list[str] | None, typer.Option("--group", "-g", help="only this group (repeatable)")
    ] = None,
    db_path: DbOption = None,
) -> None:
    """Write the database (or some groups) as JSON.

    Example: gcs db export swarm.json --group systems
    """
    for g in group or ():
        if g not in GROUPS:
            raise _fail(f"unknown group {g!r}; groups: {', '.join(GROUPS)}", 2)
    with _open(db_path) as db:
        data = encode_json(db.export(group))
    if file == "-":
        sys.stdout.write(data.decode())
        return
    target = Path(file)
    tmp: str | None = None
    try:
        fd, tmp = tempfile.mkstemp(dir=target.parent, prefix=f".{target.name}.")
        with os.fdopen(fd, "wb") as f:
            f.write(data)
        os.replace(tmp, target)
    except OSError as exc:
        if tmp is not None:
            Path(tmp).unlink(missing_ok=True)
        raise _fail(f"cannot write {file}: {exc.strerror or exc}") from None
    typer.echo(f"exported to {file}", err=True)


@app.command("import")
def import_(
    file: Annotated[str, typer.Argument(help="JSON file to read, '-' for stdin")],
    replace: Annotated[
        bool,
        typer.Option("--replace", help="empty the tables the file holds before writing"),
    ] = False,
    db_path: DbOption = None,
) -> None:
    """Import a JSON export: every record is checked; on any error nothing is written.

    Example: gcs db import swarm.json
    """
    try:
        data = sys.stdin.buffer.read() if file == "-" else Path(file).read_bytes()
    except OSError as exc:
        raise _fail(f"cannot read {file}: {exc.strerror or exc}") from None
    try:  # the document is checked before the database is opened (or created)
        doc = decode_json(data, source=file)
    except SwarmDbError as exc:
        raise _fail(str(exc)) from None
    with _open(db_path) as db:
        written = db.import_document(doc, replace=replace, source=file)
    total = sum(written.values())
    typer.echo(f"imported {total} records into {len(written)} tables from {file}")


@app.command()
def profile(
    vehicle: Annotated[str, typer.Argument(help="node id or user id")],
    model: Annotated[
        str | None, typer.Option(help="system model, when the user id names several")
    ] = None,
    as_json: JsonOption = False,
    db_path: DbOption = None,
) -> None:
    """What a node resolves from the database: its VehicleProfile.

    Example: gcs db profile 7 --json
    """
    with _open(db_path) as db:
        if vehicle.isascii() and vehicle.isdigit():
            p = db.vehicle_profile(int(vehicle))
        else:
            p = db.vehicle_profile(user_id=vehicle, model=model)
        params = db.system_params(p.vehicle_id)
    data = msgspec.to_builtins(p)
    if as_json:
        _json_out({"profile": data, "params": params})
        return
    rt = RichTable(title=f"node {p.vehicle_id}: {p.user_id} ({p.model})", show_header=False)
    rt.add_column("field", style="bold")
    rt.add_column("value")
    for k, v in data.items():
        rt.add_row(k, f"{p.vehicle_type.name} ({v})" if k == "vehicle_type" else _cell(v))
    rt.add_row("turn radius at cruise (m)", f"{p.turn_radius_m():.1f}")
    for k, v in params.items():
        rt.add_row(f"param {k}", v)
    _console().print(rt)


@app.command()
def query(
    ctx: typer.Context,
    node: Annotated[str, typer.Argument(help="node id, or '*' for every node")],
    resource: Annotated[
        str,
        typer.Argument(help="'' (info), profile, profiles, export, table/<group>/<table>"),
    ] = "",
    connect: Annotated[
        list[str] | None, typer.Option(help="Zenoh endpoint to connect to (repeatable)")
    ] = None,
    swarm: Annotated[str | None, typer.Option(help="swarm name (default: gcs --swarm)")] = None,
    timeout: Annotated[float, typer.Option(help="seconds to wait for replies")] = 5.0,
) -> None:
    """Query a peer's swarm database over Zenoh; prints every reply as JSON. Without
    its own --connect/--swarm it uses gcs's (`gcs --connect R db query 7`).

    Example: gcs --connect tcp/10.0.0.1:7447 db query 7 profile
    """
    import zenoh

    from swarm_node.database.queryable import query as zquery
    from swarm_node.database.queryable import selector
    from swarm_proto.session import ZenohSettings, open_session

    if node != "*" and not (node.isascii() and node.isdigit() and 1 <= int(node) <= 65534):
        raise _fail(f"node must be a node id (1..65534) or '*', got {node!r}", 2)
    if not math.isfinite(timeout) or timeout <= 0:
        raise _fail(f"--timeout must be a positive number of seconds, got {timeout:g}", 2)
    link = ctx.find_root().obj  # gcs's --connect, --zenoh-config and --swarm
    settings = getattr(link, "settings", None)
    swarm = swarm or str(getattr(link, "swarm", "default"))
    if connect:
        try:
            from swarm_proto.endpoints import zenoh_endpoint

            connect = [zenoh_endpoint(c) for c in connect]
        except ValueError as exc:
            raise _fail(str(exc), 2) from None
        settings = ZenohSettings(connect=tuple(connect))
    elif settings is None:
        settings = ZenohSettings()
    try:
        sel = selector(swarm, node, resource)
    except ValueError as exc:
        raise _fail(str(exc), 2) from None
    try:
        session = open_session(settings)
    except zenoh.ZError as exc:
        raise _fail(f"cannot open a Zenoh session: {_zenoh_reason(exc)}", 2) from None
    deadline = time.monotonic() + timeout
    try:
        while True:  # a fresh session learns the peers' queryables within a moment
            replies = zquery(session, sel, timeout_s=max(0.1, deadline - time.monotonic()))
            if replies or time.monotonic() >= deadline:
                break
            time.sleep(0.1)
    except zenoh.ZError as exc:
        raise _fail(f"{sel}: {_zenoh_reason(exc)}", 2) from None
    finally:
        session.close()
    if not replies:
        raise _fail(f"{sel}: no reply within {timeout:g} s")
    _json_out([msgspec.to_builtins(r) for r in replies])
    errors = [r.error for r in replies if r.error is not None]
    if len(errors) == len(replies):
        raise _fail(str(errors[0]))


@app.command()
def path(db_path: DbOption = None) -> None:
    """Print the database file this command line uses.

    Example: gcs db path
    """
    typer.echo(str(resolve_db_path(db_path)))
