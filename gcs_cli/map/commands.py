"""What the page asks for, checked as `gcs` checks it and sent through the same
request/answer core.

A request from the page is JSON (`prepare`): a command (`gcs cmd`), a zone (`gcs zone
add`), a zone withdrawn (`gcs zone remove`) or a mission (`gcs mission`, its geometry
drawn or from a file in the formats `gcs` reads). It is turned into the message the
command line would send with the command line's own validators (options.py, cli.py,
geofiles.py): a bad value is the same one-line error (`PageError`), and nothing is
sent. `question` is the confirmation `gcs` asks, naming the vehicles; `send` goes
through `GroundStation.send_command / send_mission / send_zone` (the exchange core),
as the command line does.
"""

from __future__ import annotations

import base64
import binascii
import tempfile
import time
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import msgspec
import typer

from swarm_proto import (
    Command,
    CommandArgs,
    CommandKind,
    Geometry,
    GeoPoint,
    Mission,
    MissionParams,
    MissionType,
    NoFlyZone,
    Selector,
    SelectorKind,
)

from .. import _clickx
from ..cli import MOVING, check_payload_model, mission_defaults
from ..common import selector_from
from ..core.exchange import Exchange, Outcome
from ..ground import MISSION_TIMEOUT_S, GroundStation, new_seq
from ..options import checked, describe, finite, geometry_from, parse_geopoint

MAX_FILE_BYTES = 2_000_000  # a mission file sent from the page
TIMEOUTS_S = {"command": 5.0, "mission": MISSION_TIMEOUT_S, "zone": 10.0}  # as `gcs`


class PageError(ValueError):
    """A request the page sent that `gcs` would refuse: one line, nothing sent."""


@dataclass(frozen=True)
class Prepared:
    """A checked request, ready to send."""

    kind: str  # "command", "mission", "zone"
    what: str  # for people: "rtl", "mission 12 (area)", "zone 3"
    selector: Selector
    moving: bool  # moves or arms vehicles (the CLI's MOVING; every mission)
    command: Command | None = None
    mission: Mission | None = None
    zone: NoFlyZone | None = None
    timeout_s: float = 5.0
    geometry: Geometry | None = None  # what the page may draw before it is confirmed
    fixed: dict[str, Any] = field(default_factory=dict)  # ids chosen here: sent as confirmed


def _one_line(exc: BaseException) -> str:
    fmt = getattr(exc, "format_message", None)
    text = fmt() if callable(fmt) else str(exc)
    return " ".join(str(text).split())


def _text(value: Any) -> str:
    """A value from the page as the command line would get it typed."""
    if value is None:
        return ""
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, float):
        return repr(value)
    return str(value).strip()


def _number(value: Any, name: str, lo: float, hi: float) -> float | None:
    """An optional number: empty is not given; otherwise `finite` as the CLI checks."""
    text = _text(value)
    if text == "":
        return None
    try:
        x = float(text)
    except ValueError:
        raise typer.BadParameter(f"{text!r} is not a number", param_hint=name) from None
    finite(x, name, lo, hi)
    return x


def _int(value: Any, name: str, lo: int, hi: int) -> int:
    text = _text(value) or "0"
    try:
        x = int(text)
    except ValueError:
        raise typer.BadParameter(f"{text!r} is not an integer", param_hint=name) from None
    if not lo <= x <= hi:
        raise typer.BadParameter(f"{x} is not in the range {lo}<=x<={hi}", param_hint=name)
    return x


def _point_text(p: Any, name: str) -> str:
    """[lat, lon] or [lat, lon, alt] (numbers from a click) or "LAT,LON[,ALT]" typed."""
    if isinstance(p, list | tuple):
        return ",".join(_text(x) for x in p)
    if isinstance(p, str):
        return p
    raise typer.BadParameter(f"expected LAT,LON, got {p!r}", param_hint=name)


def _points_text(pts: Any, name: str) -> str:
    if not isinstance(pts, list | tuple):
        raise typer.BadParameter(f"expected a list of points, got {pts!r}", param_hint=name)
    return " ".join(_point_text(p, name) for p in pts)


def _selection(
    sel: Any, known: Iterable[int], *, required: bool, count: int = 0, payload: str = ""
) -> Selector:
    """{"ids": [...]} | {"fleet": F} | {"all": true} | {} as --id/--fleet/--all."""
    if sel is None:
        sel = {}
    if not isinstance(sel, dict):
        raise typer.BadParameter(
            f"a selection is ids, fleet or all, got {sel!r}", param_hint="--id"
        )
    ids = [_int(i, "--id", 1, 65534) for i in sel.get("ids") or []]
    unknown = sorted(set(ids) - set(known))
    if unknown:
        raise typer.BadParameter(
            f"no vehicle {', '.join(map(str, unknown))} (neither heard nor in the swarm database)",
            param_hint="--id",
        )
    fleet = _int(sel["fleet"], "--fleet", 1, 255) if sel.get("fleet") is not None else None
    return selector_from(ids, fleet, count, payload, bool(sel.get("all")), required=required)


def dismissal(req: Any) -> int:
    """The page's {"id": N}: a LOST vehicle to take off the list (as `gcs dismiss
    N`; nothing is sent). PageError (one line) for anything but a vehicle id."""
    from ..core.lost import NotLostError, finite_id

    if not isinstance(req, dict) or "id" not in req:
        raise PageError('a dismissal is {"id": VEHICLE}')
    try:
        return finite_id(req["id"])
    except NotLostError as exc:
        raise PageError(str(exc)) from None


def prepare(
    req: Any,
    *,
    gcs_id: int,
    known: Iterable[int],
    zone_ids: Iterable[int] = (),
    db_path: Path | None = None,
) -> Prepared:
    """The page's request checked as `gcs` checks it; PageError (one line) otherwise.
    `known`: the vehicle ids the ground station heard or its database lists (an id the
    page names must be one)."""
    if not isinstance(req, dict):
        raise PageError("a request is a JSON object")
    try:
        match req.get("type"):
            case "command":
                return _command(req, gcs_id, known)
            case "zone":
                return _zone(req, gcs_id, known, zone_ids)
            case "zone-remove":
                return _zone_remove(req, gcs_id, known)
            case "mission":
                return _mission(req, gcs_id, known, db_path)
            case other:
                raise PageError(f"unknown request {other!r}: command, zone, zone-remove, mission")
    except _clickx.UsageError as exc:  # typer.BadParameter: the command line's words
        raise PageError(_one_line(exc)) from None


def _command(req: dict[str, Any], gcs_id: int, known: Iterable[int]) -> Prepared:
    from ..cli import COMMAND_NAMES

    name = _text(req.get("kind")).lower()
    try:
        k = CommandKind[name.upper().replace("-", "_")]
    except KeyError:
        raise typer.BadParameter(
            f"unknown command {name!r}; one of {', '.join(COMMAND_NAMES)}", param_hint="KIND"
        ) from None
    value = _number(req.get("value"), "--value", -1.0e6, 1.0e6)
    point = req.get("point")
    geo = GeoPoint(*parse_geopoint(_point_text(point, "--point"))) if point else None
    if k == CommandKind.EMERGENCY_LAND and geo is None:
        raise typer.BadParameter(
            "emergency-land needs --point LAT,LON: where the landing route ends",
            param_hint="--point",
        )
    sel = _selection(req.get("select"), known, required=k in MOVING)
    args = CommandArgs(
        point=geo,
        value=value,
        text=_text(req.get("text")),
        fleet_id=_int(req.get("fleet_id"), "--fleet-id", 0, 255),
        mission_id=_int(req.get("mission_id"), "--mission-id", 0, 2**32 - 1),
        other_mission_id=_int(req.get("other_mission_id"), "--other-mission-id", 0, 2**32 - 1),
    )
    cmd = checked(Command(gcs_id, 1, k, sel, args))
    what = k.name.lower().replace("_", "-")
    return Prepared("command", what, sel, k in MOVING, command=cmd, timeout_s=TIMEOUTS_S["command"])


def _zone_geometry(req: dict[str, Any]) -> Geometry:
    polygon = req.get("polygon")
    circle = req.get("circle")
    return geometry_from(
        _points_text(polygon, "--polygon") if polygon is not None else None,
        None,
        _point_text(circle, "--circle") if circle is not None else None,
        None,
        None,
    )


def _zone(
    req: dict[str, Any], gcs_id: int, known: Iterable[int], zone_ids: Iterable[int]
) -> Prepared:
    given = _text(req.get("zone_id"))
    zone_id = (
        _int(given, "ZONE_ID", 1, 2**32 - 1) if given else max([0, *zone_ids]) + 1
    )  # the next free id, as the page offers it
    geometry = _zone_geometry(req)
    floor = _number(req.get("floor"), "--floor", -1000.0, 8000.0)
    ceiling = _number(req.get("ceiling"), "--ceiling", -1000.0, 8000.0)
    minutes = _number(req.get("minutes"), "--minutes", 0.0, 1.0e6)
    area = bool(req.get("operating_area"))
    now = time.time()
    try:
        zone = NoFlyZone(
            zone_id,
            geometry,
            -1000.0 if floor is None else floor,
            8000.0 if ceiling is None else ceiling,
            now,
            now + minutes * 60 if minutes else None,
            True,
            _text(req.get("name"))[:48],
            area,
            gcs_id,
        )
    except ValueError as exc:
        raise typer.BadParameter(str(exc)) from exc
    sel = _selection(req.get("select"), known, required=False)
    what = f"{'operating area' if area else 'zone'} {zone_id}"
    return Prepared(
        "zone",
        what,
        sel,
        False,
        zone=checked(zone),
        timeout_s=TIMEOUTS_S["zone"],
        geometry=geometry,
        fixed={"zone_id": zone_id},
    )


def _zone_remove(req: dict[str, Any], gcs_id: int, known: Iterable[int]) -> Prepared:
    zone_id = _int(req.get("zone_id"), "ZONE_ID", 1, 2**32 - 1)
    placeholder = Geometry.circle(0.0, 0.0, 1.0)  # as `gcs zone remove`: dropped by id
    zone = NoFlyZone(zone_id, placeholder, active=False, issuer_id=gcs_id)
    sel = _selection(req.get("select"), known, required=False)
    return Prepared("zone", f"withdraw zone {zone_id}", sel, False, zone=zone, timeout_s=10.0)


MISSION_PARAMS = (  # page field, CLI option, MissionParams field, range
    ("alt", "--alt", "altitude_rel_m", 0.0, 8000.0),
    ("speed", "--speed", "speed_m_s", 0.0, 300.0),
    ("overlap", "--overlap", "side_overlap", 0.0, 0.95),
    ("radius", "--radius", "radius_m", 0.0, 1.0e6),
    ("alt_step", "--alt-step", "altitude_step_m", 0.0, 8000.0),
    ("duration", "--duration", "duration_s", 0.0, 1.0e7),
)


def _mission_geometry(req: dict[str, Any], mtype: MissionType) -> Geometry:
    drawn = {k: req.get(k) for k in ("polygon", "point", "circle", "line", "points")}
    file = req.get("file")
    if file is not None:
        if any(v is not None for v in drawn.values()):
            raise typer.BadParameter("--file and --polygon/--point/... exclude each other")
        return _file_geometry(file, mtype, _text(req.get("feature")) or None)
    return geometry_from(
        _points_text(drawn["polygon"], "--polygon") if drawn["polygon"] is not None else None,
        _point_text(drawn["point"], "--point") if drawn["point"] is not None else None,
        _point_text(drawn["circle"], "--circle") if drawn["circle"] is not None else None,
        _points_text(drawn["line"], "--line") if drawn["line"] is not None else None,
        _points_text(drawn["points"], "--points") if drawn["points"] is not None else None,
    )


def _file_geometry(file: Any, mtype: MissionType, feature: str | None) -> Geometry:
    """A file the page read (name, base64 data), read as `gcs mission --file` reads it."""
    from ..geofiles import MISSION_SUFFIXES, GeoFileError, mission_geometry

    if not isinstance(file, dict):
        raise typer.BadParameter("a file is {name, data}", param_hint="--file")
    name = Path(_text(file.get("name")) or "file").name
    suffix = Path(name).suffix.lower()
    if suffix not in MISSION_SUFFIXES:
        raise typer.BadParameter(
            f"{name}: unknown format {suffix or '(no extension)'}; use one of "
            + ", ".join(MISSION_SUFFIXES),
            param_hint="--file",
        )
    try:
        data = base64.b64decode(_text(file.get("data")), validate=True)
    except (binascii.Error, ValueError):
        raise typer.BadParameter(f"{name}: not base64 data", param_hint="--file") from None
    if len(data) > MAX_FILE_BYTES:
        raise typer.BadParameter(
            f"{name}: {len(data)} bytes, more than {MAX_FILE_BYTES}", param_hint="--file"
        )
    with tempfile.TemporaryDirectory(prefix="gcs-map-") as tmp:
        path = Path(tmp) / name
        path.write_bytes(data)
        try:
            return mission_geometry(path, mtype, feature)
        except GeoFileError as exc:
            why = str(exc).replace(str(path), name)
            raise typer.BadParameter(why, param_hint="--file") from None


def _mission(
    req: dict[str, Any], gcs_id: int, known: Iterable[int], db_path: Path | None
) -> Prepared:
    name = _text(req.get("mission_type")).lower()
    try:
        mtype = MissionType[name.upper()]
    except KeyError:
        raise typer.BadParameter(f"unknown mission type {name!r}", param_hint="TYPE") from None
    geometry = _mission_geometry(req, mtype)
    given = {
        field: _number(req.get(key), opt, lo, hi) for key, opt, field, lo, hi in MISSION_PARAMS
    }
    count = _int(req.get("count"), "--count", 0, 255)
    payload = _text(req.get("payload"))
    if payload:
        check_payload_model(payload, db_path)
    values = {**mission_defaults(mtype, db_path, circle=geometry.radius_m is not None)}
    values.update({k: v for k, v in given.items() if v is not None})
    sel = _selection(req.get("select"), known, required=True, count=count, payload=payload)
    given_id = _text(req.get("mission_id"))
    mission_id = _int(given_id, "--mission-id", 1, 2**32 - 1) if given_id else new_seq() or 1
    try:
        params = msgspec.convert(values, MissionParams, strict=False)
        m = Mission(
            mission_id,
            gcs_id,
            mtype,
            geometry,
            params,
            sel,
            _text(req.get("name"))[:48],
            time.time(),
        )
    except (ValueError, msgspec.ValidationError) as exc:
        raise typer.BadParameter(str(exc)) from exc
    what = f"mission {m.mission_id} ({mtype.name.lower()})"
    return Prepared(
        "mission",
        what,
        sel,
        True,
        mission=checked(m),
        timeout_s=TIMEOUTS_S["mission"],
        geometry=geometry,
        fixed={"mission_id": m.mission_id},
    )


def question(p: Prepared, alive: Mapping[int, int] | None) -> str:
    """The confirmation `gcs` asks, naming the vehicles: "rtl to fleet 2 (3, 4 alive)?"
    `alive`: id -> fleet of the vehicles alive now (None: not known)."""
    who = None
    if alive is not None and p.selector.kind != SelectorKind.IDS:
        who = sorted(v for v, f in alive.items() if p.selector.addresses(v, f))
    return f"{p.what} to {describe(p.selector, who)}?"


def send(
    gs: GroundStation, p: Prepared, progress: Callable[[Exchange, float], None] | None = None
) -> Outcome:
    """Send through the exchange core, as `gcs cmd / mission / zone add` do."""
    if p.command is not None:
        c = p.command
        return gs.send_command(c.kind, c.target, c.args, timeout_s=p.timeout_s, progress=progress)
    if p.mission is not None:
        return gs.send_mission(p.mission, timeout_s=p.timeout_s, progress=progress)
    assert p.zone is not None  # stamped when sent: the newest declaration of an id wins
    return gs.send_zone(p.zone, p.selector, timeout_s=p.timeout_s, progress=progress)


def geometry_preview(p: Prepared) -> dict[str, Any] | None:
    from .model import geometry_json

    return geometry_json(p.geometry) if p.geometry is not None else None
