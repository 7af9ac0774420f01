"""Mission and zone geometry in the files operators already have, and out again.

| format | extension | read | written |
|---|---|---|---|
| GeoJSON (RFC 7946, the `geojson` library checks it) | .geojson, .json | Polygon (holes), MultiPolygon, LineString, Point, MultiPoint; a Point with a `radius_m` property is a circle; properties: name, role, zone and mission ids, heights, every mission parameter | missions, zones |
| KML (`fastkml`) | .kml | Placemarks (in Folders too): Polygon (holes), LineString, Point, MultiPoint; altitudeMode relativeToGround is the mission's height above home; ExtendedData as GeoJSON's properties | missions, zones |
| QGroundControl plan | .plan | survey polygons (altitude, side overlap), corridor polylines, waypoints (altitude), geofence polygons and circles (inclusion or exclusion), rally points, planned home | missions (a survey, or waypoints), zones (the geofence) |
| MAVLink waypoints (`pymavlink.mavwp`) | .waypoints, .txt, .mission | QGC WPL 110: waypoints (relative altitude), a loiter's radius, fence vertices and circles (MAV_CMD 5001-5004), rally points (5100), item 0 as home | missions (waypoints), zones (fence items) |
| bandada | .json | a Mission, or a list of NoFlyZone, as msgspec JSON | missions, zones |

Round trips are exact where a format carries a thing: GeoJSON, KML and bandada JSON
carry everything (ids, names, heights, holes, every parameter); a .plan carries what
QGroundControl has (a survey's polygon, altitude and side overlap, waypoints and their
altitude, 2-D fences) and the rest in a `bandada` key QGroundControl ignores; a waypoint
file carries positions, the altitude and a loiter's radius only. A writer returns what
the format loses (`save_mission`, `save_zones`), for a one-line warning. Where a file
and the command line both give a value, the command line wins (cli.py).

Every geometry read is checked as the wire contract checks it (finite, on the Earth, a
simple polygon); a file that cannot be used is a `GeoFileError` with one line naming
the file and what is wrong. GeoJSON and KML give longitude first; .plan and waypoint
files latitude first: each reader knows its own.
"""

from __future__ import annotations

import json
import math
import re
import typing
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import msgspec

from swarm_proto import (
    Geometry,
    GeometryKind,
    LatLon,
    Mission,
    MissionParams,
    MissionType,
    NoFlyZone,
)

MISSION_SUFFIXES = (".geojson", ".json", ".kml", ".plan", ".waypoints", ".txt", ".mission")
WAYPOINT_SUFFIXES = (".waypoints", ".txt", ".mission")

# MAV_CMD numbers (common.xml)
NAV_WAYPOINT, NAV_LOITER_UNLIM, NAV_LOITER_TURNS, NAV_LOITER_TIME = 16, 17, 18, 19
NAV_LAND, NAV_TAKEOFF, NAV_SPLINE_WAYPOINT, NAV_LOITER_TO_ALT = 21, 22, 82, 31
FENCE_POLY_IN, FENCE_POLY_OUT, FENCE_CIRCLE_IN, FENCE_CIRCLE_OUT = 5001, 5002, 5003, 5004
RALLY_POINT = 5100
POSITION_CMDS = {
    NAV_WAYPOINT,
    NAV_LOITER_UNLIM,
    NAV_LOITER_TURNS,
    NAV_LOITER_TIME,
    NAV_LAND,
    NAV_TAKEOFF,
    NAV_SPLINE_WAYPOINT,
    NAV_LOITER_TO_ALT,
}
FRAME_GLOBAL, FRAME_GLOBAL_RELATIVE_ALT = 0, 3
FRAME_GLOBAL_INT, FRAME_GLOBAL_RELATIVE_ALT_INT = 5, 6
RELATIVE_FRAMES = (FRAME_GLOBAL_RELATIVE_ALT, FRAME_GLOBAL_RELATIVE_ALT_INT)
ABSOLUTE_FRAMES = (FRAME_GLOBAL, FRAME_GLOBAL_INT)
#: QGroundControl's CameraCalc DistanceMode (its AltMode): 1 above home, 2 above sea level
QGC_RELATIVE, QGC_ABSOLUTE = 1, 2
QGC_MANUAL_CAMERA = "Manual (no camera specs)"
#: the key of our own values in a .plan (QGroundControl ignores keys it does not know)
EXT = "bandada"

#: the mission parameters a file may give, with their types
PARAM_TYPES: dict[str, type] = {
    name: (int if typing.get_type_hints(MissionParams)[name] is int else float)
    for name in MissionParams.__struct_fields__
}
#: every property a reader understands, with its type (files give strings too: KML)
PROP_TYPES: dict[str, type] = {
    **PARAM_TYPES,
    "zone_id": int,
    "mission_id": int,
    "floor_alt_msl_m": float,
    "ceiling_alt_msl_m": float,
    "name": str,
    "role": str,
    "mission_type": str,
    "operating_area": bool,
    "unnamed": bool,
}


class GeoFileError(ValueError):
    """A file that cannot be used; the message is one line, for people."""


@dataclass(frozen=True)
class Feature:
    """One thing a file holds. `role`: area (a polygon to survey), exclusion or
    inclusion (fence: a no-fly zone or an operating area), route, waypoints, point,
    rally, home. `props`: what the file says of it, by the names of PROP_TYPES (a zone
    or mission id, its exact name, heights, mission parameters); `notes`: what the
    reader saw and did not use."""

    name: str
    geometry: Geometry
    role: str
    alt_m: float | None = None
    props: dict[str, Any] = field(default_factory=dict)
    notes: tuple[str, ...] = ()

    def describe(self) -> str:
        return f"{self.role} {self.name!r} ({self.geometry.kind.name.lower()})"

    @property
    def ours(self) -> bool:
        """Written by bandada (it names its zone or mission): its name is exact."""
        return "zone_id" in self.props or "mission_id" in self.props

    @property
    def exact_name(self) -> str:
        """The name the file gives (a bandada file's exactly, "" included), else the
        name shown for the feature."""
        if "name" in self.props:
            return str(self.props["name"])
        return "" if self.ours else self.name


def _fail(path: Path | str, why: str) -> GeoFileError:
    return GeoFileError(f"{path}: {' '.join(str(why).split())}")


def _num(v: Any, what: str) -> float:
    if isinstance(v, bool):
        raise ValueError(f"{what} {v!r} is not a number")
    try:
        x = float(v)
    except (TypeError, ValueError):
        raise ValueError(f"{what} {v!r} is not a number") from None
    if not math.isfinite(x):
        raise ValueError(f"{what} is {v}")
    return x


def _int(v: Any, what: str) -> int:
    x = _num(v, what)
    if x != int(x):
        raise ValueError(f"{what} {v!r} is not a whole number")
    return int(x)


def _ll(lat: Any, lon: Any) -> LatLon:
    la, lo = _num(lat, "latitude"), _num(lon, "longitude")
    if not (-90.0 <= la <= 90.0 and -180.0 <= lo <= 180.0):
        raise ValueError(f"position {la:g}, {lo:g} is not on the Earth")
    return LatLon(la, lo)


def _dict(v: Any, where: str) -> dict[str, Any]:
    if v is None:
        return {}
    if not isinstance(v, dict):
        raise ValueError(f"{where} is a {type(v).__name__}, not an object")
    return v


def _list(v: Any, where: str) -> list[Any]:
    if v is None:
        return []
    if not isinstance(v, list):
        raise ValueError(f"{where} is a {type(v).__name__}, not a list")
    return v


def _pairs(v: Any, where: str) -> list[LatLon]:
    """[[lat, lon], ...] as a .plan writes them."""
    out = []
    for i, p in enumerate(_list(v, where)):
        if not isinstance(p, list) or len(p) < 2:
            raise ValueError(f"{where} vertex {i + 1} is not [latitude, longitude]")
        out.append(_ll(p[0], p[1]))
    return out


def _props(raw: dict[str, Any], where: str) -> dict[str, Any]:
    """Known properties converted to their types (KML gives strings); others kept."""
    out: dict[str, Any] = {}
    for k, v in raw.items():
        t = PROP_TYPES.get(k)
        if t is None or v is None:
            out[k] = v
        elif t is str:
            out[k] = str(v)
        elif t is bool:
            out[k] = v if isinstance(v, bool) else str(v).strip().lower() in ("1", "true", "yes")
        elif t is int:
            out[k] = _int(v, f"{where}: {k}")
        else:
            out[k] = _num(v, f"{where}: {k}")
    return out


def _open_ring(ring: Sequence[LatLon]) -> tuple[LatLon, ...]:
    pts = list(ring)
    if len(pts) > 1 and pts[0] == pts[-1]:
        pts.pop()
    return tuple(pts)


def polygon(shell: Sequence[LatLon], holes: Sequence[Sequence[LatLon]] = ()) -> Geometry:
    return Geometry(GeometryKind.POLYGON, _open_ring(shell), tuple(_open_ring(h) for h in holes))


def _one_altitude(alts: Sequence[float], what: str) -> tuple[float | None, tuple[str, ...]]:
    """The mission altitude of a set of waypoint altitudes: their common value, or the
    highest (noted) when they differ."""
    if not alts:
        return None, ()
    hi, lo = max(alts), min(alts)
    if hi - lo > 0.01:
        return hi, (f"{what} altitudes differ ({lo:g}-{hi:g} m): the highest, {hi:g} m, is used",)
    return hi, ()


# --------------------------------------------------------------------------- reading


def read_features(path: Path | str) -> list[Feature]:
    p = Path(path)
    try:
        raw = p.read_bytes()
    except OSError as exc:
        raise _fail(p, f"cannot read: {exc.strerror or exc}") from None
    suffix = p.suffix.lower()
    try:
        if suffix in (".geojson", ".json"):
            data = _json(raw)
            if isinstance(data, dict) and "mission_type" in data:
                m = msgspec.convert(data, Mission)
                return [_mission_feature(m)]
            if (
                isinstance(data, list)
                and data
                and isinstance(data[0], dict)
                and "zone_id" in data[0]
            ):
                zones = msgspec.convert(data, list[NoFlyZone])
                return [_zone_feature(z) for z in zones]
            found = _geojson(data)
        elif suffix == ".kml":
            found = _kml(raw)
        elif suffix == ".plan":
            found = _plan(_json(raw))
        elif suffix in WAYPOINT_SUFFIXES:
            found = _wpl(p)
        else:
            raise ValueError(
                f"unknown format {suffix or '(no extension)'}; use one of "
                + ", ".join(MISSION_SUFFIXES)
            )
    except GeoFileError:
        raise
    except (
        ValueError,
        KeyError,
        TypeError,
        IndexError,
        AttributeError,
        msgspec.ValidationError,
    ) as exc:
        raise _fail(p, str(exc)) from None
    except Exception as exc:  # a parser's own error type (lxml, geojson ...)
        raise _fail(p, f"cannot parse: {exc}") from None
    if not found:
        raise _fail(p, "no geometry in it")
    return found


def _json(raw: bytes) -> Any:
    try:
        return json.loads(raw.decode("utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ValueError(f"not JSON ({exc})") from None


def _role_of(g: Geometry) -> str:
    return {
        GeometryKind.POLYGON: "area",
        GeometryKind.POLYLINE: "route",
        GeometryKind.POINTS: "waypoints",
    }.get(g.kind, "point")


def mission_props(m: Mission) -> dict[str, Any]:
    """A mission's id, type, name and every parameter set, as file properties."""
    return {
        "mission_id": m.mission_id,
        "mission_type": m.mission_type.name.lower(),
        "name": m.name,
        **{k: v for k, v in msgspec.to_builtins(m.params).items() if v is not None},
    }


def _mission_feature(m: Mission) -> Feature:
    return Feature(
        m.name or f"mission {m.mission_id}",
        m.geometry,
        _role_of(m.geometry),
        props=mission_props(m),
    )


def zone_props(z: NoFlyZone) -> dict[str, Any]:
    """A zone's id, name, kind and heights, as file properties."""
    return {
        "zone_id": z.zone_id,
        "name": z.name,
        "role": "inclusion" if z.operating_area else "exclusion",
        "floor_alt_msl_m": z.floor_alt_msl_m,
        "ceiling_alt_msl_m": z.ceiling_alt_msl_m,
    }


def _zone_feature(z: NoFlyZone) -> Feature:
    return Feature(
        z.name or f"zone {z.zone_id}",
        z.geometry,
        "inclusion" if z.operating_area else "exclusion",
        props=zone_props(z),
    )


def _geojson(data: Any) -> list[Feature]:
    import geojson

    # the library checks the file; the coordinates are read from it as written (the
    # library's objects round them to 6 decimals, 0.1 m)
    obj = geojson.GeoJSON.to_instance(data, strict=True)
    if not getattr(obj, "is_valid", True):
        raise ValueError(
            f"invalid GeoJSON: {'; '.join(obj.errors()) if hasattr(obj, 'errors') else ''}"
        )
    data = _dict(data, "the file")
    feats = (
        _list(data.get("features"), "features")
        if data.get("type") == "FeatureCollection"
        else (
            [data]
            if data.get("type") == "Feature"
            else [{"type": "Feature", "geometry": data, "properties": {}}]
        )
    )
    out: list[Feature] = []
    for i, f in enumerate(feats, 1):
        where = f"feature {i}"
        f = _dict(f, where)
        props = _props(_dict(f.get("properties"), f"{where}'s properties"), where)
        name = str(props.get("name") or f.get("id") or where)
        g = f.get("geometry")
        if g is None:
            continue
        out += _from_geojson_geometry(g, name, props)
    return out


def _is_mission(props: dict[str, Any]) -> bool:
    """A mission's properties (its radius_m is a parameter; its circle's radius is
    circle_radius_m); elsewhere a Point's radius_m makes it a circle."""
    return "mission_id" in props or "mission_type" in props


def _geo_role(props: dict[str, Any], default: str) -> str:
    role = str(props.get("role") or "")
    if props.get("operating_area"):
        return "inclusion"
    return role if role in ("area", "exclusion", "inclusion", "route", "rally", "home") else default


def _from_geojson_geometry(g: Any, name: str, props: dict[str, Any]) -> list[Feature]:
    kind, coords = g["type"], g.get("coordinates")

    def ll(c: Sequence[Any]) -> LatLon:
        if len(c) < 2:
            raise ValueError(f"{name}: a position needs longitude and latitude")
        return _ll(c[1], c[0])  # GeoJSON: longitude first

    def alt(c: Sequence[Any]) -> float | None:
        return _num(c[2], "altitude") if len(c) > 2 else None

    if kind == "Polygon":
        rings = [[ll(c) for c in ring] for ring in coords]
        return [Feature(name, polygon(rings[0], rings[1:]), _geo_role(props, "area"), props=props)]
    if kind == "MultiPolygon":
        return [
            Feature(
                f"{name} {j}",
                polygon([ll(c) for c in poly[0]], [[ll(c) for c in r] for r in poly[1:]]),
                _geo_role(props, "area"),
                props=props,
            )
            for j, poly in enumerate(coords, 1)
        ]
    if kind == "LineString":
        return [
            Feature(
                name,
                Geometry(GeometryKind.POLYLINE, tuple(ll(c) for c in coords)),
                _geo_role(props, "route"),
                props=props,
            )
        ]
    if kind == "Point":
        radius = props.get("radius_m")
        if radius is not None and not _is_mission(props):
            p = ll(coords)
            return [
                Feature(
                    name,
                    Geometry.circle(p.lat_deg, p.lon_deg, _num(radius, "radius_m")),
                    _geo_role(props, "exclusion"),
                    alt(coords),
                    props,
                )
            ]
        if props.get("circle_radius_m") is not None:  # a mission's circle (its own radius)
            p = ll(coords)
            r = _num(props["circle_radius_m"], "circle_radius_m")
            return [Feature(name, Geometry.circle(p.lat_deg, p.lon_deg, r), "point", props=props)]
        return [
            Feature(
                name,
                Geometry(GeometryKind.POINT, (ll(coords),)),
                _geo_role(props, "point"),
                alt(coords),
                props,
            )
        ]
    if kind == "MultiPoint":
        return [
            Feature(
                name,
                Geometry(GeometryKind.POINTS, tuple(ll(c) for c in coords)),
                _geo_role(props, "waypoints"),
                props=props,
            )
        ]
    if kind == "GeometryCollection":
        return [f for sub in g["geometries"] for f in _from_geojson_geometry(sub, name, props)]
    raise ValueError(f"{name}: GeoJSON {kind} is not used")


def _kml(raw: bytes) -> list[Feature]:
    from fastkml import kml

    text = re.sub(r"^\s*<\?xml[^>]*\?>", "", raw.decode("utf-8"))  # lxml: str without it
    doc = kml.KML.from_string(text)
    out: list[Feature] = []

    def walk(container: Any) -> None:
        for f in getattr(container, "features", None) or []:
            if getattr(f, "geometry", None) is not None:
                out.extend(_from_kml_placemark(f, len(out) + 1))
            walk(f)

    walk(doc)
    return out


def _kml_altitude(pm: Any, coords: Sequence[Sequence[float]], name: str) -> tuple[dict, tuple]:
    """What a Placemark's altitudes say: relativeToGround is a height above home (the
    mission's altitude); absolute is above sea level (noted, not used for a mission)."""
    mode = getattr(getattr(pm, "kml_geometry", None), "altitude_mode", None)
    alts = [float(c[2]) for c in coords if len(c) > 2]
    if mode is None or not alts:
        return {}, ()
    value = getattr(mode, "value", str(mode))
    if value == "relativeToGround":
        alt, notes = _one_altitude(alts, name)
        return {"altitude_rel_m": alt}, notes
    if value == "absolute" and any(alts):
        return {}, (
            f"{name}: altitudes above sea level ({max(alts):g} m, KML absolute) are not a "
            "height above home: not used",
        )
    return {}, ()


def _from_kml_placemark(pm: Any, i: int) -> list[Feature]:
    raw: dict[str, Any] = {}
    if pm.extended_data is not None:
        for d in pm.extended_data.elements or []:
            if getattr(d, "name", None):
                raw[d.name] = d.value
    name = str(pm.name or f"placemark {i}")
    props = _props(raw, name)
    if props.pop("unnamed", False):  # ours, with no name (the Placemark's is made up)
        props["name"] = ""
    elif pm.name is not None:
        props.setdefault("name", str(pm.name))
    g = pm.geometry

    def ll(c: Sequence[Any]) -> LatLon:
        return _ll(c[1], c[0])  # KML: longitude, latitude[, altitude]

    def with_alt(coords: Sequence[Sequence[float]]) -> tuple[dict[str, Any], tuple[str, ...]]:
        found, notes = _kml_altitude(pm, coords, name)
        return {**found, **props} if "altitude_rel_m" in props else {**props, **found}, notes

    def one(geom: Any) -> list[Feature]:
        t = geom.geom_type
        if t == "Polygon":
            shell = [ll(c) for c in geom.exterior.coords]
            holes = [[ll(c) for c in r.coords] for r in geom.interiors]
            p, notes = with_alt(list(geom.exterior.coords))
            return [Feature(name, polygon(shell, holes), _geo_role(p, "area"), None, p, notes)]
        if t == "LineString":
            p, notes = with_alt(list(geom.coords))
            return [
                Feature(
                    name,
                    Geometry(GeometryKind.POLYLINE, tuple(ll(c) for c in geom.coords)),
                    _geo_role(p, "route"),
                    None,
                    p,
                    notes,
                )
            ]
        if t == "MultiPoint":
            coords = [sub.coords[0] for sub in geom.geoms]
            p, notes = with_alt(coords)
            return [
                Feature(
                    name,
                    Geometry(GeometryKind.POINTS, tuple(ll(c) for c in coords)),
                    _geo_role(p, "waypoints"),
                    None,
                    p,
                    notes,
                )
            ]
        if t == "Point":
            c = geom.coords[0]
            pt = ll(c)
            p, notes = with_alt([c])
            altitude = _num(c[2], "altitude") if len(c) > 2 else None
            radius = p.get("radius_m")
            if radius is not None and not _is_mission(p):
                circle = Geometry.circle(pt.lat_deg, pt.lon_deg, _num(radius, "radius_m"))
                return [Feature(name, circle, _geo_role(p, "exclusion"), altitude, p, notes)]
            if p.get("circle_radius_m") is not None:
                r = _num(p["circle_radius_m"], "circle_radius_m")
                circle = Geometry.circle(pt.lat_deg, pt.lon_deg, r)
                return [Feature(name, circle, "point", altitude, p, notes)]
            return [
                Feature(
                    name,
                    Geometry(GeometryKind.POINT, (pt,)),
                    _geo_role(p, "point"),
                    altitude,
                    p,
                    notes,
                )
            ]
        if hasattr(geom, "geoms"):
            return [f for sub in geom.geoms for f in one(sub)]
        raise ValueError(f"{name}: KML {t} is not used")

    return one(g)


def _camera(item: dict[str, Any], where: str) -> tuple[dict[str, Any], tuple[str, ...]]:
    """A QGroundControl survey's altitude and side overlap: its CameraCalc (version 2:
    DistanceToSurface with DistanceMode 1 above home, 2 above sea level; SideOverlap in %
    unless the camera is manual), or the version 3 `grid` object."""
    out: dict[str, Any] = {}
    notes: list[str] = []
    ts = _dict(item.get("TransectStyleComplexItem"), f"{where} TransectStyleComplexItem")
    calc = _dict(ts.get("CameraCalc"), f"{where} CameraCalc")
    grid = _dict(item.get("grid"), f"{where} grid")
    if "DistanceToSurface" in calc:
        d = _num(calc["DistanceToSurface"], f"{where} DistanceToSurface")
        mode = calc.get("DistanceMode")
        relative = calc.get("DistanceToSurfaceRelative", True) if mode is None else None
        if (mode is not None and int(_num(mode, "DistanceMode")) == QGC_ABSOLUTE) or (
            relative is False
        ):
            notes.append(f"{where}: {d:g} m above sea level is not a height above home: not used")
        else:
            out["altitude_rel_m"] = d
    elif "altitude" in grid:
        d = _num(grid["altitude"], f"{where} grid altitude")
        if grid.get("relativeAltitude", True):
            out["altitude_rel_m"] = d
        else:
            notes.append(f"{where}: {d:g} m above sea level is not a height above home: not used")
    side = calc.get("SideOverlap")
    if side is not None and calc.get("CameraName") != QGC_MANUAL_CAMERA:
        out["side_overlap"] = _num(side, f"{where} SideOverlap") / 100.0
    elif "imageSideOverlap" in _dict(item.get("camera"), f"{where} camera"):
        out["side_overlap"] = _num(item["camera"]["imageSideOverlap"], "imageSideOverlap") / 100
    elif calc.get("CameraName") == QGC_MANUAL_CAMERA and "AdjustedFootprintSide" in calc:
        notes.append(
            f"{where}: a manual camera's lane spacing "
            f"({_num(calc['AdjustedFootprintSide'], 'AdjustedFootprintSide'):g} m) is not an "
            "overlap: the mission's side overlap applies"
        )
    return out, tuple(notes)


def _plan(data: Any) -> list[Feature]:
    if not isinstance(data, dict) or data.get("fileType") != "Plan":
        raise ValueError("not a QGroundControl plan (fileType is not 'Plan')")
    out: list[Feature] = []
    ext = _dict(data.get(EXT), EXT)
    ours = _dict(ext.get("mission"), f"{EXT} mission")
    mission = _dict(data.get("mission"), "mission")
    home = mission.get("plannedHomePosition")
    if home and ext.get("home", True):
        home = _list(home, "plannedHomePosition")
        if len(home) < 2:
            raise ValueError("plannedHomePosition is not [latitude, longitude, altitude]")
        out.append(
            Feature(
                "home",
                Geometry(GeometryKind.POINT, (_ll(home[0], home[1]),)),
                "home",
                _num(home[2], "altitude") if len(home) > 2 and home[2] is not None else None,
            )
        )
    waypoints: list[LatLon] = []
    alts: list[float] = []
    notes: list[str] = []
    loiter_radius: float | None = None
    for i, item in enumerate(_list(mission.get("items"), "mission items"), 1):
        item = _dict(item, f"mission item {i}")
        if item.get("type") == "ComplexItem":
            ctype = str(item.get("complexItemType", "")).lower()
            if ctype == "survey" or "polygon" in item:
                found, seen = _camera(item, f"survey {i}")
                exact = _props(_dict(ours.get("params"), f"{EXT} params"), EXT)
                # QGroundControl's overlap is a percentage, and x * 100 / 100 is not
                # always x in floating point: where the survey still has the one written
                # for bandada's own value (not edited since), that exact value
                if "side_overlap" in found and math.isclose(
                    found["side_overlap"], exact.get("side_overlap", math.nan), rel_tol=1e-12
                ):
                    found["side_overlap"] = exact["side_overlap"]
                props = {**exact, **found}
                holes = [_pairs(h, f"{EXT} hole") for h in _list(ours.get("holes"), EXT)]
                props.update(_mission_ext(ours))
                out.append(
                    Feature(
                        f"survey {i}",
                        polygon(_pairs(item["polygon"], f"survey {i} polygon"), holes),
                        "area",
                        props=props,
                        notes=seen,
                    )
                )
            elif "polyline" in item:
                out.append(
                    Feature(
                        f"corridor {i}",
                        Geometry(
                            GeometryKind.POLYLINE,
                            tuple(_pairs(item["polyline"], f"corridor {i} polyline")),
                        ),
                        "route",
                    )
                )
        elif item.get("type") == "SimpleItem" and int(_num(item.get("command", 0), "command")) in (
            POSITION_CMDS
        ):
            params = _list(item.get("params"), f"mission item {i} params")
            given = len(params) >= 7 and params[4] is not None and params[5] is not None
            if given and not (params[4] == 0 and params[5] == 0):
                waypoints.append(_ll(params[4], params[5]))
                frame = int(_num(item.get("frame", FRAME_GLOBAL_RELATIVE_ALT), "frame"))
                if params[6] is not None and frame in RELATIVE_FRAMES:
                    alts.append(_num(params[6], "altitude"))
                elif params[6] is not None and frame in ABSOLUTE_FRAMES and params[6]:
                    notes.append(f"item {i}: altitude above sea level, not used")
                if int(item["command"]) == NAV_LOITER_UNLIM and params[2]:
                    loiter_radius = abs(_num(params[2], "loiter radius"))
    if waypoints:
        out.append(_waypoints_feature(waypoints, alts, loiter_radius, ours, tuple(notes)))
    fence = _dict(data.get("geoFence"), "geoFence")
    for i, poly in enumerate(_list(fence.get("polygons"), "geoFence polygons"), 1):
        poly = _dict(poly, f"fence polygon {i}")
        role = "inclusion" if poly.get("inclusion") else "exclusion"
        props = _props(_dict(poly.get(EXT), EXT), f"fence polygon {i}")
        out.append(
            Feature(
                f"fence polygon {i}",
                polygon(_pairs(poly.get("polygon"), f"fence polygon {i}")),
                role,
                props=props,
            )
        )
    for i, circ in enumerate(_list(fence.get("circles"), "geoFence circles"), 1):
        circ = _dict(circ, f"fence circle {i}")
        c = _dict(circ.get("circle"), f"fence circle {i}")
        role = "inclusion" if circ.get("inclusion") else "exclusion"
        (centre,) = _pairs([c.get("center")], f"fence circle {i} center")
        out.append(
            Feature(
                f"fence circle {i}",
                Geometry.circle(centre.lat_deg, centre.lon_deg, _num(c.get("radius"), "radius")),
                role,
                props=_props(_dict(circ.get(EXT), EXT), f"fence circle {i}"),
            )
        )
    rally = _list(_dict(data.get("rallyPoints"), "rallyPoints").get("points"), "rally points")
    for i, r in enumerate(rally, 1):
        if not isinstance(r, list) or len(r) < 2:
            raise ValueError(f"rally point {i} is not [latitude, longitude, altitude]")
        out.append(
            Feature(
                f"rally {i}",
                Geometry(GeometryKind.POINT, (_ll(r[0], r[1]),)),
                "rally",
                _num(r[2], "altitude") if len(r) > 2 else None,
            )
        )
    return out


def _mission_ext(ours: dict[str, Any]) -> dict[str, Any]:
    """The mission's id, type and name from our key of a file."""
    out: dict[str, Any] = {}
    for k in ("mission_id", "mission_type", "name"):
        if k in ours:
            out[k] = ours[k]
    return _props(out, EXT)


def _waypoints_feature(
    pts: list[LatLon],
    alts: list[float],
    loiter_radius: float | None,
    ours: dict[str, Any],
    notes: tuple[str, ...],
) -> Feature:
    """Waypoints as one feature: a polyline (two or more), a point, or a circle (one
    loiter with a radius); our key of the file says what the mission was (a polygon's
    closed ring, points)."""
    alt, seen = _one_altitude(alts, "waypoint")
    props = {**_props(_dict(ours.get("params"), f"{EXT} params"), EXT)}
    if alt is not None:
        props["altitude_rel_m"] = alt
    props.update(_mission_ext(ours))
    kind = str(ours.get("kind", "")).upper()
    if len(pts) == 1 and loiter_radius:
        g = Geometry.circle(pts[0].lat_deg, pts[0].lon_deg, loiter_radius)
        return Feature("waypoints", g, "point", props=props, notes=notes + seen)
    if kind == "POLYGON" and len(pts) >= 4:
        return Feature("waypoints", polygon(pts), "area", props=props, notes=notes + seen)
    if kind == "POINTS":
        g = Geometry(GeometryKind.POINTS, tuple(pts))
        return Feature("waypoints", g, "waypoints", props=props, notes=notes + seen)
    g = Geometry(GeometryKind.POLYLINE if len(pts) >= 2 else GeometryKind.POINT, tuple(pts))
    role = "route" if len(pts) >= 2 else "point"
    return Feature("waypoints", g, role, props=props, notes=notes + seen)


def _wpl(path: Path) -> list[Feature]:
    from pymavlink import mavwp

    loader = mavwp.MAVWPLoader()
    try:
        n = loader.load(str(path))
    except Exception as exc:  # pymavlink raises a bare MAVWPError or ValueError
        raise ValueError(f"not a MAVLink waypoint file ({exc})") from None
    items = [loader.wp(i) for i in range(n)]
    out: list[Feature] = []
    waypoints: list[LatLon] = []
    alts: list[float] = []
    notes: list[str] = []
    loiter_radius: float | None = None
    fence_ring: list[LatLon] = []
    ring_cmd = 0
    fences = rallies = 0
    for i, it in enumerate(items):
        cmd = int(it.command)
        lat, lon = float(it.x), float(it.y)
        if i == 0 and cmd == NAV_WAYPOINT:  # item 0: the home position
            if not (lat == 0 and lon == 0):
                out.append(
                    Feature(
                        "home", Geometry(GeometryKind.POINT, (_ll(lat, lon),)), "home", float(it.z)
                    )
                )
            continue
        if cmd in POSITION_CMDS:
            if not (lat == 0 and lon == 0):
                waypoints.append(_ll(lat, lon))
                if int(it.frame) in RELATIVE_FRAMES:
                    alts.append(_num(it.z, "altitude"))
                elif int(it.frame) in ABSOLUTE_FRAMES and it.z:
                    notes.append(f"item {i}: altitude above sea level, not used")
                if cmd == NAV_LOITER_UNLIM and it.param3:
                    loiter_radius = abs(_num(it.param3, "loiter radius"))
        elif cmd in (FENCE_POLY_IN, FENCE_POLY_OUT):
            if ring_cmd != cmd or not fence_ring:
                ring_cmd, fence_ring = cmd, []
            fence_ring.append(_ll(lat, lon))
            if len(fence_ring) == int(it.param1):  # param1: the ring's vertex count
                role = "inclusion" if cmd == FENCE_POLY_IN else "exclusion"
                fences += 1
                out.append(Feature(f"fence polygon {fences}", polygon(fence_ring), role))
                fence_ring = []
        elif cmd in (FENCE_CIRCLE_IN, FENCE_CIRCLE_OUT):
            role = "inclusion" if cmd == FENCE_CIRCLE_IN else "exclusion"
            centre = _ll(lat, lon)
            fences += 1
            out.append(
                Feature(
                    f"fence circle {fences}",
                    Geometry.circle(centre.lat_deg, centre.lon_deg, _num(it.param1, "radius")),
                    role,
                )
            )
        elif cmd == RALLY_POINT:
            rallies += 1
            out.append(
                Feature(
                    f"rally {rallies}",
                    Geometry(GeometryKind.POINT, (_ll(lat, lon),)),
                    "rally",
                    float(it.z),
                )
            )
    if fence_ring:
        raise ValueError(f"a fence polygon has {len(fence_ring)} vertices, fewer than it says")
    if waypoints:
        out.append(_waypoints_feature(waypoints, alts, loiter_radius, {}, tuple(notes)))
    return out


# --------------------------------------------------------------------------- choosing

#: the geometry kinds each mission type takes, in order of preference
WANTS: dict[MissionType, tuple[GeometryKind, ...]] = {
    MissionType.AREA: (GeometryKind.POLYGON,),
    MissionType.PERIMETER: (GeometryKind.POLYGON, GeometryKind.CIRCLE),
    MissionType.TARGET: (GeometryKind.POINT, GeometryKind.CIRCLE),
    MissionType.ROUTE: (GeometryKind.POLYLINE,),
    MissionType.OBJECTIVE: (GeometryKind.POINTS, GeometryKind.POINT),
    MissionType.AUTOLAND: (GeometryKind.POINT,),
    MissionType.MUMT: (GeometryKind.POINT, GeometryKind.POLYLINE),
}
NOT_MISSION_ROLES = ("exclusion", "home", "rally")


def pick(features: list[Feature], name: str | None, path: Path | str) -> Feature:
    """--feature NAME or N (from 1)."""
    if name is None:
        raise AssertionError
    if name.isdigit():
        i = int(name)
        if not 1 <= i <= len(features):
            raise _fail(path, f"feature {i}: it has {len(features)} (1..{len(features)})")
        return features[i - 1]
    for f in features:
        if f.name == name:
            return f
    names = ", ".join(repr(f.name) for f in features[:10])
    raise _fail(path, f"no feature named {name!r}; it has {names}")


@dataclass(frozen=True)
class FileMission:
    """What a file gives for a mission: its geometry, the parameters it states (by
    MissionParams' field names), its name and id when it has them, and what was noted
    reading it."""

    geometry: Geometry
    params: dict[str, Any]
    name: str | None
    mission_id: int | None
    feature: Feature
    notes: tuple[str, ...] = ()


def mission_from_file(
    path: Path | str, mtype: MissionType, feature: str | None = None
) -> FileMission:
    """The mission of `mtype` in a file: the feature named or numbered, or the first
    that fits (a survey polygon before a fence polygon), with what the file says of its
    altitude, overlap and other parameters, name and id."""
    feats = read_features(path)
    f, g = _choose(feats, mtype, feature, path)
    params = {k: f.props[k] for k in PARAM_TYPES if f.props.get(k) is not None}
    if g.kind == GeometryKind.CIRCLE and not _is_mission(f.props):
        params.pop("radius_m", None)  # it made the circle: the circle's radius is its own
    mid = f.props.get("mission_id")
    name = f.exact_name if (f.ours or "name" in f.props) else None
    return FileMission(g, params, name, mid if isinstance(mid, int) else None, f, f.notes)


def mission_geometry(path: Path | str, mtype: MissionType, feature: str | None = None) -> Geometry:
    """The geometry a mission of `mtype` flies, from a file (`mission_from_file`)."""
    return mission_from_file(path, mtype, feature).geometry


def _choose(
    feats: list[Feature], mtype: MissionType, feature: str | None, path: Path | str
) -> tuple[Feature, Geometry]:
    wants = WANTS.get(mtype, ())
    if feature is not None:
        f = pick(feats, feature, path)
        return f, _as(f.geometry, wants, mtype, path, f.describe())
    ranked = sorted(feats, key=lambda f: (f.role in NOT_MISSION_ROLES, f.role == "inclusion"))
    for kind in wants:
        for f in ranked:
            if f.geometry.kind == kind and f.role not in ("home", "rally"):
                return f, f.geometry
    # waypoints can stand for what is wanted: a polygon's vertices, points
    for f in ranked:
        if f.role in ("route", "waypoints", "point") and f.geometry.kind in (
            GeometryKind.POLYLINE,
            GeometryKind.POINTS,
        ):
            try:
                return f, _as(f.geometry, wants, mtype, path, f.describe())
            except GeoFileError:
                continue
    has = ", ".join(f.describe() for f in feats[:8])
    raise _fail(path, f"nothing for a {mtype.name.lower()} mission (it has {has})")


def _as(
    g: Geometry, wants: tuple[GeometryKind, ...], mtype: MissionType, path: Path | str, what: str
) -> Geometry:
    if g.kind in wants:
        return g
    try:
        if GeometryKind.POLYGON in wants and g.kind in (GeometryKind.POLYLINE, GeometryKind.POINTS):
            return polygon(g.points)
        if GeometryKind.POINTS in wants and g.kind == GeometryKind.POLYLINE:
            return Geometry(GeometryKind.POINTS, g.points)
        if GeometryKind.POLYLINE in wants and g.kind == GeometryKind.POINTS and len(g.points) > 1:
            return Geometry(GeometryKind.POLYLINE, g.points)
    except ValueError as exc:
        raise _fail(path, f"{what}: {exc}") from None
    raise _fail(path, f"{what} cannot be a {mtype.name.lower()} mission's geometry")


# --------------------------------------------------------------------------- zones


@dataclass(frozen=True)
class ZoneSpec:
    """A zone a file declares: its geometry, kind, and the id, name and heights the
    file gives (None: not given)."""

    source: str  # how the file names it, for people
    geometry: Geometry
    operating_area: bool
    zone_id: int | None = None
    name: str = ""
    floor_alt_msl_m: float | None = None
    ceiling_alt_msl_m: float | None = None


@dataclass(frozen=True)
class Skipped:
    """Something in a file that is not imported as a zone, and why."""

    what: str
    why: str
    role: str = ""  # the feature's (rally, home, area ...)

    def __str__(self) -> str:
        return f"{self.what}: {self.why}"


@dataclass(frozen=True)
class ZoneFile:
    """A file's zones, what is not imported (each with why), its rally points
    ((lat, lon, altitude above home or None)) and its planned home."""

    zones: list[ZoneSpec]
    skipped: list[Skipped]
    rally: list[tuple[float, float, float | None]]
    home: tuple[float, float, float | None] | None = None


def _skip_reason(f: Feature, path: Path | str) -> str:
    cmd = f"gcs mission TYPE --file {Path(path).name}"
    if f.role == "home":
        return "the planned home: each vehicle's home is its own autopilot's"
    if f.role == "rally":
        return "a rally point: --base-from-file makes the first one the swarm's base"
    if f.role == "area":
        return f"a survey area is a mission, not a zone ({cmd})"
    if f.geometry.kind == GeometryKind.POINT:
        return "a point is not a zone (a circle needs a radius: a radius_m property)"
    if f.geometry.kind in (GeometryKind.POLYLINE, GeometryKind.POINTS):
        return f"a route or waypoints: a zone is a polygon or a circle ({cmd})"
    return "not a fence"


def zones_from_file(path: Path | str) -> ZoneFile:
    """The zones and operating areas in a file: every exclusion and inclusion polygon
    or circle (a GeoJSON or KML polygon with no role is a no-fly zone; a survey area is
    not a zone), and everything else listed with why it is not one. A zone has no holes:
    an operating area's hole becomes a no-fly zone of its own (the same airspace); a
    no-fly zone's hole is dropped (all of it is no-fly: stricter), and listed."""
    feats = read_features(path)
    loose = Path(path).suffix.lower() in (".geojson", ".json", ".kml")
    zones: list[ZoneSpec] = []
    skipped: list[Skipped] = []
    rally: list[tuple[float, float, float | None]] = []
    home = None
    for f in feats:
        g = f.geometry
        fence = g.kind in (GeometryKind.POLYGON, GeometryKind.CIRCLE) and (
            f.role in ("exclusion", "inclusion") or (loose and f.role == "area")
        )
        if f.role == "rally":
            rally.append((g.points[0].lat_deg, g.points[0].lon_deg, f.alt_m))
        if f.role == "home":
            home = (g.points[0].lat_deg, g.points[0].lon_deg, f.alt_m)
        if not fence:
            skipped.append(Skipped(f.describe(), _skip_reason(f, path), f.role))
            continue
        area = f.role == "inclusion"
        shell = Geometry(g.kind, g.points, (), g.radius_m)
        floor, ceiling = f.props.get("floor_alt_msl_m"), f.props.get("ceiling_alt_msl_m")
        zones.append(
            ZoneSpec(
                f.name,
                shell,
                area,
                f.props.get("zone_id"),
                f.exact_name[:48],
                None if floor is None else float(floor),
                None if ceiling is None else float(ceiling),
            )
        )
        for k, hole in enumerate(g.holes, 1):
            what = f"hole {k} of {'operating area' if area else 'no-fly zone'} {f.name!r}"
            if area:
                zones.append(
                    ZoneSpec(
                        f"{what} (a no-fly zone)",
                        Geometry(GeometryKind.POLYGON, hole),
                        False,
                        None,
                        f"{f.exact_name or f.name} hole {k}"[:48],
                    )
                )
            else:
                skipped.append(
                    Skipped(what, "a no-fly zone has no holes: all of it is declared no-fly")
                )
    return ZoneFile(zones, skipped, rally, home)


def zone_features(path: Path | str) -> list[Feature]:
    """The zone features of a file (see `zones_from_file`); GeoFileError if none."""
    zf = zones_from_file(path)
    if not zf.zones:
        has = "; ".join(str(s) for s in zf.skipped[:6])
        raise _fail(path, f"no fence polygon or circle in it (it has {has})")
    return [
        Feature(
            z.source,
            z.geometry,
            "inclusion" if z.operating_area else "exclusion",
            props={
                k: v
                for k, v in (
                    ("zone_id", z.zone_id),
                    ("name", z.name),
                    ("floor_alt_msl_m", z.floor_alt_msl_m),
                    ("ceiling_alt_msl_m", z.ceiling_alt_msl_m),
                )
                if v is not None
            },
        )
        for z in zf.zones
    ]


# --------------------------------------------------------------------------- writing


def _suffix(path: Path) -> str:
    s = path.suffix.lower()
    if s not in MISSION_SUFFIXES:
        raise _fail(
            path,
            f"unknown format {s or '(no extension)'}; use one of " + ", ".join(MISSION_SUFFIXES),
        )
    return s


def _write(path: Path, text: str) -> None:
    try:
        path.write_text(text, encoding="utf-8")
    except OSError as exc:
        raise _fail(path, f"cannot write: {exc.strerror or exc}") from None


def _ring_lonlat(points: Sequence[LatLon]) -> list[list[float]]:
    ring = [[p.lon_deg, p.lat_deg] for p in points]
    return [*ring, ring[0]]


def _geojson_geometry(g: Geometry, circle_key: str) -> tuple[dict[str, Any], dict[str, Any]]:
    """(GeoJSON geometry, extra properties); a circle is a Point with its radius in
    `circle_key` (zones: radius_m; a mission's circle: circle_radius_m, its radius_m
    being a parameter)."""
    if g.kind == GeometryKind.POLYGON:
        rings = [_ring_lonlat(g.points), *(_ring_lonlat(h) for h in g.holes)]
        return {"type": "Polygon", "coordinates": rings}, {}
    if g.kind == GeometryKind.CIRCLE:
        c = g.points[0]
        return {"type": "Point", "coordinates": [c.lon_deg, c.lat_deg]}, {circle_key: g.radius_m}
    if g.kind == GeometryKind.POLYLINE:
        return {"type": "LineString", "coordinates": [[p.lon_deg, p.lat_deg] for p in g.points]}, {}
    if g.kind == GeometryKind.POINTS:
        return {"type": "MultiPoint", "coordinates": [[p.lon_deg, p.lat_deg] for p in g.points]}, {}
    p = g.points[0]
    return {"type": "Point", "coordinates": [p.lon_deg, p.lat_deg]}, {}


def geojson_text(
    items: Sequence[tuple[str, Geometry, dict[str, Any]]], circle_key: str = "radius_m"
) -> str:
    """A FeatureCollection, coordinates at full precision (the geojson library would
    round them to 6 decimals, 0.1 m; the wire carries 1e-7 degrees), checked valid."""
    import geojson

    feats = []
    for name, g, props in items:
        geom, extra = _geojson_geometry(g, circle_key)
        feats.append(
            {"type": "Feature", "geometry": geom, "properties": {"name": name, **extra, **props}}
        )
    fc = {"type": "FeatureCollection", "features": feats}
    checked = geojson.GeoJSON.to_instance(fc, strict=True)
    if not checked.is_valid:
        raise ValueError(f"GeoJSON not valid: {checked.errors()}")
    return json.dumps(fc, indent=2) + "\n"


def kml_text(
    title: str,
    items: Sequence[tuple[str, Geometry, dict[str, Any]]],
    circle_key: str = "radius_m",
    altitude_rel_m: float | None = None,
) -> str:
    """A KML Document of Placemarks, ExtendedData for the properties; with
    `altitude_rel_m` the coordinates are at that height (altitudeMode relativeToGround,
    as Google Earth shows a flight)."""
    from fastkml import containers, data, features, kml
    from fastkml import geometry as kg
    from fastkml.enums import AltitudeMode
    from pygeoif import geometry as pg

    z = altitude_rel_m
    mode = AltitudeMode.relative_to_ground if z is not None else None

    def xy(p: LatLon) -> Any:  # (lon, lat) or (lon, lat, height)
        return (p.lon_deg, p.lat_deg) if z is None else (p.lon_deg, p.lat_deg, z)

    marks = []
    for name, g, props in items:
        extra: dict[str, Any] = dict(props)
        shape: Any
        if g.kind == GeometryKind.POLYGON:
            shape = kg.Polygon(
                altitude_mode=mode,
                geometry=pg.Polygon(
                    [xy(p) for p in g.points], [[xy(p) for p in h] for h in g.holes]
                ),
            )
        elif g.kind == GeometryKind.POLYLINE:
            shape = kg.LineString(
                altitude_mode=mode, geometry=pg.LineString([xy(p) for p in g.points])
            )
        elif g.kind == GeometryKind.POINTS:
            shape = kg.MultiGeometry(
                altitude_mode=mode,
                kml_geometries=[
                    kg.Point(altitude_mode=mode, geometry=pg.Point(*xy(p))) for p in g.points
                ],
            )
        else:
            p = g.points[0]
            shape = kg.Point(altitude_mode=mode, geometry=pg.Point(*xy(p)))
            if g.kind == GeometryKind.CIRCLE:
                extra[circle_key] = g.radius_m
        ed = data.ExtendedData(
            elements=[
                data.Data(name=k, value=_kml_value(v))
                for k, v in extra.items()
                if v is not None and k != "name"
            ]
        )
        marks.append(features.Placemark(name=name, kml_geometry=shape, extended_data=ed))
    doc = kml.KML(features=[containers.Document(name=title, features=marks)])
    return str(doc.to_string(prettyprint=True))


def _kml_props(props: dict[str, Any]) -> dict[str, Any]:
    """Properties for ExtendedData: the name is the Placemark's (an empty one is said
    with `unnamed`: the Placemark then shows a made-up name)."""
    out = {k: v for k, v in props.items() if k != "name"}
    if props.get("name") == "":
        out["unnamed"] = True
    return out


def _kml_value(v: Any) -> str:
    return repr(v) if isinstance(v, float) else str(v)


def _plan_item(cmd: int, p: LatLon, alt: float, jump: int, p3: float = 0.0) -> dict[str, Any]:
    return {
        "type": "SimpleItem",
        "command": cmd,
        "frame": FRAME_GLOBAL_RELATIVE_ALT,
        "autoContinue": True,
        "doJumpId": jump,
        "params": [0, 0, p3, None, p.lat_deg, p.lon_deg, alt],
    }


def plan_text(
    mission: Mission | None = None,
    zones: Sequence[NoFlyZone] = (),
    rally: Sequence[tuple[float, float, float]] = (),
    home: tuple[float, float, float] | None = None,
) -> str:
    """A QGroundControl plan (fileType Plan, mission version 2, geoFence version 2,
    rallyPoints version 2): an area mission as a survey complex item (its polygon,
    altitude above home and camera side overlap; QGroundControl generates the
    transects), other missions as waypoints at the mission's altitude above home (a
    circle as one unlimited loiter with its radius); the zones as the geofence. What
    QGroundControl has no place for (holes, ids, names, heights, other parameters) is
    in the `bandada` keys, which it ignores."""
    items: list[dict[str, Any]] = []
    ext: dict[str, Any] = {"version": 1}
    if mission is not None:
        g, prm = mission.geometry, mission.params
        alt = prm.altitude_rel_m
        ext["mission"] = {
            "mission_id": mission.mission_id,
            "mission_type": mission.mission_type.name.lower(),
            "name": mission.name,
            "kind": g.kind.name,
            "params": {k: v for k, v in msgspec.to_builtins(prm).items() if v is not None},
            "holes": [[[p.lat_deg, p.lon_deg] for p in h] for h in g.holes],
        }
        if g.kind == GeometryKind.POLYGON and mission.mission_type == MissionType.AREA:
            items.append(_survey(g, alt, prm.side_overlap))
        elif g.kind == GeometryKind.CIRCLE:
            items.append(_plan_item(NAV_LOITER_UNLIM, g.points[0], alt, 1, g.radius_m or 0.0))
        else:
            pts = list(g.points) + ([g.points[0]] if g.kind == GeometryKind.POLYGON else [])
            items += [_plan_item(NAV_WAYPOINT, p, alt, k) for k, p in enumerate(pts, 1)]
    centre = (
        mission.geometry.points[0]
        if mission is not None
        else (zones[0].geometry.points[0] if zones else None)
    )
    if not home:
        ext["home"] = False  # a placeholder: the vehicles' homes are their own
    planned_home = (
        list(home) if home else ([centre.lat_deg, centre.lon_deg, 0] if centre else [0, 0, 0])
    )
    fence: dict[str, Any] = {"version": 2, "polygons": [], "circles": []}
    for z in zones:
        if not z.active:
            continue
        ours = {k: v for k, v in zone_props(z).items() if k != "role"}
        if z.geometry.kind == GeometryKind.CIRCLE:
            c = z.geometry.points[0]
            fence["circles"].append(
                {
                    "version": 1,
                    "inclusion": z.operating_area,
                    "circle": {"center": [c.lat_deg, c.lon_deg], "radius": z.geometry.radius_m},
                    EXT: ours,
                }
            )
        else:
            fence["polygons"].append(
                {
                    "version": 1,
                    "inclusion": z.operating_area,
                    "polygon": [[p.lat_deg, p.lon_deg] for p in z.geometry.points],
                    EXT: ours,
                }
            )
    plan = {
        "fileType": "Plan",
        "version": 1,
        "groundStation": "bandada",
        "mission": {
            "version": 2,
            "firmwareType": 3,
            "vehicleType": 2,
            "cruiseSpeed": 15,
            "hoverSpeed": 5,
            "plannedHomePosition": planned_home,
            "items": items,
        },
        "geoFence": fence,
        "rallyPoints": {"version": 2, "points": [list(r) for r in rally]},
        EXT: ext,
    }
    return json.dumps(plan, indent=2) + "\n"


def _survey(g: Geometry, alt: float, side_overlap: float) -> dict[str, Any]:
    """A survey complex item as QGroundControl 4 writes one (version 5, CameraCalc
    version 2: a custom camera, its distance to the surface above home and overlaps)."""
    return {
        "type": "ComplexItem",
        "complexItemType": "survey",
        "version": 5,
        "polygon": [[p.lat_deg, p.lon_deg] for p in g.points],
        "angle": 0,
        "entryLocation": 0,
        "flyAlternateTransects": False,
        "splitConcavePolygons": False,
        "TransectStyleComplexItem": {
            "version": 2,
            "Items": [],
            "VisualTransectPoints": [],
            "CameraShots": 0,
            "CameraTriggerInTurnAround": True,
            "HoverAndCapture": False,
            "Refly90Degrees": False,
            "TurnAroundDistance": 10,
            "CameraCalc": {
                "version": 2,
                "CameraName": "Custom Camera",
                "DistanceToSurface": alt,
                "DistanceMode": QGC_RELATIVE,
                "SideOverlap": side_overlap * 100.0,
                "FrontalOverlap": 70,
                "ValueSetIsDistance": True,
            },
        },
    }


def wpl_text(
    mission: Mission | None = None,
    zones: Sequence[NoFlyZone] = (),
    home: tuple[float, float, float] | None = None,
) -> str:
    """QGC WPL 110 via pymavlink's MAVWPLoader: item 0 the home, then the mission's
    waypoints (relative altitude; a circle as one unlimited loiter with its radius) and
    the zones as fence items (5001-5004)."""
    from pymavlink import mavutil, mavwp

    link = mavutil.mavlink
    loader = mavwp.MAVWPLoader()

    def add(
        cmd: int,
        lat: float,
        lon: float,
        alt: float,
        p1: float = 0.0,
        frame: int = FRAME_GLOBAL_RELATIVE_ALT,
        p3: float = 0.0,
    ) -> None:
        seq = loader.count()
        loader.add(
            link.MAVLink_mission_item_message(
                0, 0, seq, frame, cmd, 1 if seq == 0 else 0, 1, p1, 0, p3, 0, lat, lon, alt
            )
        )

    first = (
        mission.geometry.points[0]
        if mission is not None
        else (zones[0].geometry.points[0] if zones else LatLon(0.0, 0.0))
    )
    h = home or (first.lat_deg, first.lon_deg, 0.0)
    add(NAV_WAYPOINT, h[0], h[1], h[2], frame=FRAME_GLOBAL)  # home
    if mission is not None:
        g, alt = mission.geometry, mission.params.altitude_rel_m
        if g.kind == GeometryKind.CIRCLE:
            c = g.points[0]
            add(NAV_LOITER_UNLIM, c.lat_deg, c.lon_deg, alt, p3=float(g.radius_m or 0.0))
        else:
            pts = list(g.points) + ([g.points[0]] if g.kind == GeometryKind.POLYGON else [])
            for p in pts:
                add(NAV_WAYPOINT, p.lat_deg, p.lon_deg, alt)
    for z in zones:
        if not z.active:
            continue
        g = z.geometry
        if g.kind == GeometryKind.CIRCLE:
            c = g.points[0]
            add(
                FENCE_CIRCLE_IN if z.operating_area else FENCE_CIRCLE_OUT,
                c.lat_deg,
                c.lon_deg,
                0.0,
                float(g.radius_m or 0.0),
            )
        else:
            for p in g.points:
                add(
                    FENCE_POLY_IN if z.operating_area else FENCE_POLY_OUT,
                    p.lat_deg,
                    p.lon_deg,
                    0.0,
                    float(len(g.points)),
                )
    lines = ["QGC WPL 110"]
    for i in range(loader.count()):
        w = loader.wp(i)
        lines.append(
            "\t".join(
                str(x)
                for x in (
                    w.seq,
                    w.current,
                    w.frame,
                    w.command,
                    _g(w.param1),
                    _g(w.param2),
                    _g(w.param3),
                    _g(w.param4),
                    f"{w.x:.8f}",
                    f"{w.y:.8f}",
                    _g(w.z),
                    w.autocontinue,
                )
            )
        )
    return "\n".join(lines) + "\n"


def _g(x: float) -> str:
    """A number as short as it is exact (repr of the float)."""
    return repr(float(x))


#: MissionParams' fields for people: (words, unit)
PARAM_WORDS: dict[str, tuple[str, str]] = {
    "altitude_rel_m": ("altitude", " m"),
    "speed_m_s": ("speed", " m/s"),
    "side_overlap": ("side overlap", ""),
    "radius_m": ("radius", " m"),
    "altitude_step_m": ("altitude step", " m"),
    "loops": ("loops", ""),
    "duration_s": ("duration", " s"),
    "heading_deg": ("heading", " deg"),
    "lead_vehicle_id": ("lead vehicle", ""),
    "separation_s": ("separation", " s"),
}


def param_words(name: str, value: Any) -> str:
    """ "speed 7.5 m/s" for ("speed_m_s", 7.5)."""
    words, unit = PARAM_WORDS.get(name, (name, ""))
    return f"{words} {value:g}{unit}" if isinstance(value, float | int) else f"{words} {value}"


def _lost_params(params: MissionParams, kept: Sequence[str]) -> list[str]:
    """The parameters set away from the message's defaults that a format has no place
    for."""
    default = msgspec.to_builtins(MissionParams())
    return [
        param_words(k, v)
        for k, v in msgspec.to_builtins(params).items()
        if k not in kept and v is not None and v != default.get(k)
    ]


def mission_losses(suffix: str, mission: Mission) -> list[str]:
    """What `suffix` cannot carry of `mission`, for people ([] when nothing)."""
    g = mission.geometry
    lost: list[str] = []
    if suffix in WAYPOINT_SUFFIXES:
        if g.holes:
            lost.append(f"{len(g.holes)} hole(s)")
        lost.append(f"mission id {mission.mission_id}")
        if mission.name:
            lost.append(f"the name {mission.name!r}")
        kept = ["altitude_rel_m"] + (["radius_m"] if g.kind == GeometryKind.CIRCLE else [])
        lost += _lost_params(mission.params, kept)
    elif suffix == ".plan" and g.holes:
        lost.append(f"{len(g.holes)} hole(s) for QGroundControl (kept for gcs in the file)")
    return lost


def zone_losses(suffix: str, zones: Sequence[NoFlyZone]) -> list[str]:
    """What `suffix` cannot carry of `zones`, for people ([] when nothing)."""
    active = [z for z in zones if z.active]
    lost: list[str] = []
    full = NoFlyZone(1, Geometry.circle(0.0, 0.0, 1.0))
    high = [
        z.zone_id
        for z in active
        if not z.operating_area
        and (z.floor_alt_msl_m, z.ceiling_alt_msl_m)
        != (full.floor_alt_msl_m, full.ceiling_alt_msl_m)
    ]
    if suffix in WAYPOINT_SUFFIXES:
        lost.append("zone ids " + ", ".join(str(z.zone_id) for z in active))
        names = [repr(z.name) for z in active if z.name]
        if names:
            lost.append("names " + ", ".join(names))
        if high:
            lost.append("floor and ceiling of " + ", ".join(map(str, high)))
    elif suffix == ".plan" and high:
        lost.append(
            "floor and ceiling of "
            + ", ".join(map(str, high))
            + " for QGroundControl (its fences are 2-D; kept for gcs in the file)"
        )
    return lost


def save_mission(path: Path | str, mission: Mission) -> list[str]:
    """Write the mission in the format of the file's extension; returns what that
    format cannot carry ([] when the file holds all of it)."""
    p = Path(path)
    s = _suffix(p)
    name = mission.name or f"mission {mission.mission_id}"
    props = mission_props(mission)
    g = mission.geometry
    try:
        if s == ".json":
            text = msgspec.json.format(msgspec.json.encode(mission), indent=2).decode() + "\n"
        elif s == ".geojson":
            text = geojson_text([(name, g, props)], "circle_radius_m")
        elif s == ".kml":
            text = kml_text(
                name,
                [(name, g, _kml_props(props))],
                "circle_radius_m",
                mission.params.altitude_rel_m,
            )
        elif s == ".plan":
            text = plan_text(mission)
        else:
            text = wpl_text(mission)
    except ValueError as exc:
        raise _fail(p, str(exc)) from None
    _write(p, text)
    return mission_losses(s, mission)


def save_zones(path: Path | str, zones: Sequence[NoFlyZone]) -> list[str]:
    """Write the zones in force in the format of the file's extension; returns what
    that format cannot carry."""
    p = Path(path)
    s = _suffix(p)
    active = [z for z in zones if z.active]
    items = [(z.name or f"zone {z.zone_id}", z.geometry, zone_props(z)) for z in active]
    try:
        if s == ".json":
            text = msgspec.json.format(msgspec.json.encode(list(active)), indent=2).decode() + "\n"
        elif s == ".geojson":
            text = geojson_text(items)
        elif s == ".kml":
            text = kml_text("zones", [(n, g, _kml_props(pr)) for n, g, pr in items])
        elif s == ".plan":
            text = plan_text(None, active)
        else:
            text = wpl_text(None, active)
    except ValueError as exc:
        raise _fail(p, str(exc)) from None
    _write(p, text)
    return zone_losses(s, active)
