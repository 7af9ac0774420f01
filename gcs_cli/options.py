"""Options every `gcs` command shares, and the checks that keep bad input from ever
reaching a vehicle: every number finite and in range, every position on the Earth,
every message validated against the wire contract before a session is opened. A bad
value is a `typer.BadParameter`, which `gcs` prints as one line and exits 2
(app.run)."""

from __future__ import annotations

import math
import sys
from typing import Annotated, TypeVar

import msgspec
import typer

from swarm_proto import Geometry, GeometryKind, LatLon, Selector, SelectorKind, lan, validate
from swarm_proto.errors import EncodeError
from swarm_proto.intake import too_large
from swarm_proto.topics import TOPIC_OF_TYPE

M = TypeVar("M", bound=msgspec.Struct)

# --------------------------------------------------------------------------- selection

IdsOption = Annotated[
    list[int],
    typer.Option("--id", min=1, max=65534, help="a vehicle id; repeat for more: --id 1 --id 7"),
]
FleetOption = Annotated[
    int | None, typer.Option("--fleet", min=1, max=255, help="every vehicle of this fleet")
]
AllOption = Annotated[bool, typer.Option("--all", help="every vehicle alive")]
YesOption = Annotated[
    bool, typer.Option("--yes", "-y", help="do not ask for confirmation (scripts)")
]
JsonOption = Annotated[bool, typer.Option("--json", help="print JSON instead of a table")]


def selection(ids: list[int], fleet: int | None, all_: bool, *, required: bool) -> Selector:
    """The vehicles a command addresses. `--id`, `--fleet` and `--all` exclude each
    other; with none, commands that move or arm vehicles refuse (`required`), the
    others address every vehicle."""
    given = [
        name
        for name, on in (("--id", bool(ids)), ("--fleet", fleet is not None), ("--all", all_))
        if on
    ]
    if len(given) > 1:
        raise typer.BadParameter(f"{' and '.join(given)} exclude each other: give one")
    if not given and required:
        raise typer.BadParameter(
            "say which vehicles: --id N (repeat for more), --fleet F or --all", param_hint="--id"
        )
    if ids:
        return Selector.ids(*sorted(set(ids)))
    if fleet is not None:
        return Selector.fleet(fleet)
    return Selector()


def describe(sel: Selector, alive: list[int] | None = None) -> str:
    """For people: "vehicles 1, 7", "fleet 2 (3, 4 alive)", "all 5 vehicles alive"."""
    who = ", ".join(map(str, alive)) if alive else "none known alive"
    match sel.kind:
        case SelectorKind.IDS:
            return f"vehicle{'s' if len(sel.vehicle_ids) > 1 else ''} " + ", ".join(
                map(str, sel.vehicle_ids)
            )
        case SelectorKind.FLEET:
            return f"fleet {sel.fleet_id} ({who})"
        case SelectorKind.QUANTITY:
            return f"{sel.quantity} vehicles chosen by voting"
        case _:
            return f"every vehicle alive ({who})"


def confirm(question: str, yes: bool) -> None:
    """Ask before moving or arming vehicles, unless --yes. With no terminal to ask on,
    refuse (exit 2) rather than guess."""
    if yes:
        return
    if not sys.stdin.isatty():
        raise typer.BadParameter(
            f"{question}: add --yes to confirm (no terminal to ask)", param_hint="--yes"
        )
    if not typer.confirm(question, default=False):
        typer.echo("gcs: not sent")
        raise typer.Exit(1)


# --------------------------------------------------------------------------- numbers


def finite(value: float | None, name: str, lo: float = -math.inf, hi: float = math.inf) -> None:
    """Refuse NaN, infinities and values out of [lo, hi] (typer takes "nan" as a float)."""
    if value is None:
        return
    if not math.isfinite(value):
        raise typer.BadParameter(f"{value} is not a number", param_hint=name)
    if not lo <= value <= hi:
        raise typer.BadParameter(f"{value:g} is out of range {lo:g}..{hi:g}", param_hint=name)


def _number(text: str, what: str, name: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise typer.BadParameter(
            f"{what} {text.strip()!r} is not a number", param_hint=name
        ) from None
    if not math.isfinite(v):
        raise typer.BadParameter(f"{what} is {text.strip()}", param_hint=name)
    return v


def parse_latlon(text: str, name: str = "--point") -> tuple[float, float]:
    parts = text.split(",")
    if len(parts) != 2:
        raise typer.BadParameter(f"expected LAT,LON, got {text!r}", param_hint=name)
    lat, lon = (_number(p, w, name) for p, w in zip(parts, ("latitude", "longitude"), strict=True))
    _on_earth(lat, lon, name)
    return lat, lon


def _on_earth(lat: float, lon: float, name: str) -> None:
    if not -90.0 <= lat <= 90.0:
        raise typer.BadParameter(f"latitude {lat:g} is out of range -90..90", param_hint=name)
    if not -180.0 <= lon <= 180.0:
        raise typer.BadParameter(f"longitude {lon:g} is out of range -180..180", param_hint=name)


def parse_geopoint(text: str, name: str = "--point") -> tuple[float, float, float]:
    """LAT,LON[,ALT_MSL]."""
    parts = text.split(",")
    if len(parts) not in (2, 3):
        raise typer.BadParameter(f"expected LAT,LON[,ALT_MSL], got {text!r}", param_hint=name)
    lat, lon = parse_latlon(",".join(parts[:2]), name)
    alt = _number(parts[2], "altitude", name) if len(parts) == 3 else 0.0
    finite(alt, name, -1000.0, 8000.0)
    return lat, lon, alt


def parse_points(text: str, name: str) -> list[tuple[float, float]]:
    pts = [parse_latlon(p, name) for p in text.replace(";", " ").split()]
    if not pts:
        raise typer.BadParameter("no points given", param_hint=name)
    return pts


def parse_circle(text: str, name: str = "--circle") -> tuple[float, float, float]:
    parts = text.split(",")
    if len(parts) != 3:
        raise typer.BadParameter(f"expected LAT,LON,RADIUS_M, got {text!r}", param_hint=name)
    lat, lon = parse_latlon(",".join(parts[:2]), name)
    r = _number(parts[2], "radius", name)
    if not 0.0 < r <= 1.0e6:
        raise typer.BadParameter(f"radius {r:g} m must be > 0 and <= 1000 km", param_hint=name)
    return lat, lon, r


def geometry_from(
    polygon: str | None, point: str | None, circle: str | None, line: str | None, points: str | None
) -> Geometry:
    given = [x for x in (polygon, point, circle, line, points) if x]
    if len(given) != 1:
        raise typer.BadParameter(
            "give exactly one of --polygon, --point, --circle, --line, --points (or --file)"
        )
    try:
        if polygon:
            return Geometry.polygon(parse_points(polygon, "--polygon"))
        if point:
            return Geometry.point(*parse_latlon(point))
        if circle:
            return Geometry.circle(*parse_circle(circle))
        if line:
            pts = parse_points(line, "--line")
            return Geometry(GeometryKind.POLYLINE, tuple(LatLon(a, b) for a, b in pts))
        pts = parse_points(points or "", "--points")
        return Geometry(GeometryKind.POINTS, tuple(LatLon(a, b) for a, b in pts))
    except ValueError as exc:  # invalid polygon (self-intersecting, too few vertices ...)
        raise typer.BadParameter(str(exc)) from exc


def checked(msg: M) -> M:
    """A message the vehicles will accept, or exit 2 naming the field or the size cap
    (nothing sent)."""
    try:
        validate(msg)
    except EncodeError as exc:
        raise typer.BadParameter(str(exc)) from exc
    topic = TOPIC_OF_TYPE.get(type(msg))
    problem = too_large(topic, len(lan.encode(msg))) if topic is not None else None
    if problem:
        raise typer.BadParameter(f"{type(msg).__name__} is {problem} (docs/security.md)")
    return msg
