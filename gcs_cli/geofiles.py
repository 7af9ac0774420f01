"""Mission and zone geometry in the files operators already have, and out again.

| format | extension | read | written |
|---|---|---|---|
| GeoJSON (RFC 7946, the `geojson` library) | .geojson, .json | Polygon (holes), MultiPolygon, LineString, Point, MultiPoint; a Point with a `radius_m` property is a circle | missions, zones |
| KML (`fastkml`) | .kml | Placemarks (in Folders too): Polygon, LineString, Point; ExtendedData `radius_m` makes a Point a circle | missions, zones |
| QGroundControl plan | .plan | survey polygons, corridor polylines, waypoints, geofence polygons and circles (inclusion or exclusion), rally points, planned home | missions (a survey, or waypoints), zones (the geofence) |
| MAVLink waypoints (`pymavlink.mavwp`) | .waypoints, .txt, .mission | QGC WPL 110: waypoints, fence vertices and circles (MAV_CMD 5001-5004), rally points (5100), item 0 as home | missions (waypoints), zones (fence items) |
| bandada | .json | a Mission, or a list of NoFlyZone, as msgspec JSON | missions, zones |

Every geometry read is checked as the wire contract checks it (finite, on the Earth, a
simple polygon); a file that cannot be used is a `GeoFileError` with one line naming
the file and what is wrong. GeoJSON and KML give longitude first; .plan and waypoint
files latitude first: each reader knows its own.
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import msgspec

from swarm_proto import Geometry, GeometryKind, LatLon, Mission, MissionType, NoFlyZone

MISSION_SUFFIXES = (".geojson", ".json", ".kml", ".plan", ".waypoints", ".txt", ".mission")

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
FRAME_GLOBAL_RELATIVE_ALT = 3


class GeoFileError(ValueError):
    """A file that cannot be used; the message is one line, for people."""


@dataclass(frozen=True)
class Feature:
    """One thing a file holds. `role`: area (a polygon to survey), exclusion or
    inclusion (fence: a no-fly zone or an operating area), route, waypoints, point,
    rally, home."""

    name: str
    geometry: Geometry
    role: str
    alt_m: float | None = None
    props: dict[str, Any] = field(default_factory=dict)

    def describe(self) -> str:
        return f"{self.role} {self.name!r} ({self.geometry.kind.name.lower()})"


def _fail(path: Path | str, why: str) -> GeoFileError:
    return GeoFileError(f"{path}: {' '.join(str(why).split())}")


def _num(v: Any, what: str) -> float:
    try:
        x = float(v)
    except (TypeError, ValueError):
        raise ValueError(f"{what} {v!r} is not a number") from None
    if not math.isfinite(x):
        raise ValueError(f"{what} is {v}")
    return x


def _ll(lat: Any, lon: Any) -> LatLon:
    la, lo = _num(lat, "latitude"), _num(lon, "longitude")
    if not (-90.0 <= la <= 90.0 and -180.0 <= lo <= 180.0):
        raise ValueError(f"position {la:g}, {lo:g} is not on the Earth")
    return LatLon(la, lo)


def _open_ring(ring: Sequence[LatLon]) -> tuple[LatLon, ...]:
    pts = list(ring)
    if len(pts) > 1 and pts[0] == pts[-1]:
        pts.pop()
    return tuple(pts)


def polygon(shell: Sequence[LatLon], holes: Sequence[Sequence[LatLon]] = ()) -> Geometry:
    return Geometry(GeometryKind.POLYGON, _open_ring(shell), tuple(_open_ring(h) for h in holes))


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
                return [
                    Feature(
                        m.name or f"mission {m.mission_id}",
                        m.geometry,
                        _role_of(m.geometry),
                        props={"mission": m},
                    )
                ]
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
        elif suffix in (".waypoints", ".txt", ".mission"):
            found = _wpl(p)
        else:
            raise ValueError(
                f"unknown format {suffix or '(no extension)'}; use one of "
                + ", ".join(MISSION_SUFFIXES)
            )
    except GeoFileError:
        raise
    except (ValueError, KeyError, TypeError, IndexError, msgspec.ValidationError) as exc:
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


def _zone_feature(z: NoFlyZone) -> Feature:
    return Feature(
        z.name or f"zone {z.zone_id}",
        z.geometry,
        "inclusion" if z.operating_area else "exclusion",
        props={
            "zone_id": z.zone_id,
            "floor_alt_msl_m": z.floor_alt_msl_m,
            "ceiling_alt_msl_m": z.ceiling_alt_msl_m,
        },
    )


def _geojson(data: Any) -> list[Feature]:
    import geojson

    obj = geojson.GeoJSON.to_instance(data, strict=True)
    if not getattr(obj, "is_valid", True):
        raise ValueError(
            f"invalid GeoJSON: {'; '.join(obj.errors()) if hasattr(obj, 'errors') else ''}"
        )
    feats = (
        obj["features"]
        if obj.get("type") == "FeatureCollection"
        else (
            [obj]
            if obj.get("type") == "Feature"
            else [{"type": "Feature", "geometry": obj, "properties": {}}]
        )
    )
    out: list[Feature] = []
    for i, f in enumerate(feats, 1):
        props = dict(f.get("properties") or {})
        name = str(props.get("name") or f.get("id") or f"feature {i}")
        g = f.get("geometry")
        if g is None:
            continue
        out += _from_geojson_geometry(g, name, props)
    return out


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
        if radius is not None:
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


def _from_kml_placemark(pm: Any, i: int) -> list[Feature]:
    name = str(pm.name or f"placemark {i}")
    props: dict[str, Any] = {}
    if pm.extended_data is not None:
        for d in pm.extended_data.elements or []:
            if getattr(d, "name", None):
                props[d.name] = d.value
    g = pm.geometry

    def ll(c: Sequence[Any]) -> LatLon:
        return _ll(c[1], c[0])  # KML: longitude, latitude[, altitude]

    def one(geom: Any) -> list[Feature]:
        t = geom.geom_type
        if t == "Polygon":
            shell = [ll(c) for c in geom.exterior.coords]
            holes = [[ll(c) for c in r.coords] for r in geom.interiors]
            return [Feature(name, polygon(shell, holes), _geo_role(props, "area"), props=props)]
        if t == "LineString":
            return [
                Feature(
                    name,
                    Geometry(GeometryKind.POLYLINE, tuple(ll(c) for c in geom.coords)),
                    _geo_role(props, "route"),
                    props=props,
                )
            ]
        if t == "Point":
            c = geom.coords[0]
            p = ll(c)
            altitude = _num(c[2], "altitude") if len(c) > 2 else None
            if props.get("radius_m") is not None:
                return [
                    Feature(
                        name,
                        Geometry.circle(p.lat_deg, p.lon_deg, _num(props["radius_m"], "radius_m")),
                        _geo_role(props, "exclusion"),
                        altitude,
                        props,
                    )
                ]
            return [
                Feature(
                    name,
                    Geometry(GeometryKind.POINT, (p,)),
                    _geo_role(props, "point"),
                    altitude,
                    props,
                )
            ]
        if hasattr(geom, "geoms"):
            return [f for sub in geom.geoms for f in one(sub)]
        raise ValueError(f"{name}: KML {t} is not used")

    return one(g)


def _plan(data: Any) -> list[Feature]:
    if not isinstance(data, dict) or data.get("fileType") != "Plan":
        raise ValueError("not a QGroundControl plan (fileType is not 'Plan')")
    out: list[Feature] = []
    mission = data.get("mission") or {}
    home = mission.get("plannedHomePosition")
    if home:
        out.append(
            Feature(
                "home",
                Geometry(GeometryKind.POINT, (_ll(home[0], home[1]),)),
                "home",
                _num(home[2], "altitude") if len(home) > 2 and home[2] is not None else None,
            )
        )
    waypoints: list[LatLon] = []
    for i, item in enumerate(mission.get("items") or [], 1):
        if item.get("type") == "ComplexItem":
            ctype = str(item.get("complexItemType", "")).lower()
            if ctype == "survey" or "polygon" in item:
                out.append(
                    Feature(
                        f"survey {i}",
                        polygon([_ll(a, b) for a, b in item["polygon"]]),
                        "area",
                        props=item,
                    )
                )
            elif "polyline" in item:
                out.append(
                    Feature(
                        f"corridor {i}",
                        Geometry(
                            GeometryKind.POLYLINE, tuple(_ll(a, b) for a, b in item["polyline"])
                        ),
                        "route",
                        props=item,
                    )
                )
        elif item.get("type") == "SimpleItem" and int(item.get("command", 0)) in POSITION_CMDS:
            params = item.get("params") or []
            given = len(params) >= 7 and params[4] is not None and params[5] is not None
            if given and not (params[4] == 0 and params[5] == 0):
                waypoints.append(_ll(params[4], params[5]))
    if waypoints:
        kind = GeometryKind.POLYLINE if len(waypoints) >= 2 else GeometryKind.POINT
        out.append(
            Feature(
                "waypoints",
                Geometry(kind, tuple(waypoints)),
                "route" if len(waypoints) >= 2 else "point",
            )
        )
    fence = data.get("geoFence") or {}
    for i, poly in enumerate(fence.get("polygons") or [], 1):
        role = "inclusion" if poly.get("inclusion") else "exclusion"
        out.append(
            Feature(f"fence polygon {i}", polygon([_ll(a, b) for a, b in poly["polygon"]]), role)
        )
    for i, circ in enumerate(fence.get("circles") or [], 1):
        c = circ["circle"]
        role = "inclusion" if circ.get("inclusion") else "exclusion"
        centre = _ll(*c["center"][:2])
        out.append(
            Feature(
                f"fence circle {i}",
                Geometry.circle(centre.lat_deg, centre.lon_deg, _num(c["radius"], "radius")),
                role,
            )
        )
    rally = (data.get("rallyPoints") or {}).get("points") or []
    for i, r in enumerate(rally, 1):
        out.append(
            Feature(
                f"rally {i}",
                Geometry(GeometryKind.POINT, (_ll(r[0], r[1]),)),
                "rally",
                _num(r[2], "altitude") if len(r) > 2 else None,
            )
        )
    return out


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
    fence_ring: list[LatLon] = []
    ring_cmd = 0
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
        elif cmd in (FENCE_POLY_IN, FENCE_POLY_OUT):
            if ring_cmd != cmd or not fence_ring:
                ring_cmd, fence_ring = cmd, []
            fence_ring.append(_ll(lat, lon))
            if len(fence_ring) == int(it.param1):  # param1: the ring's vertex count
                role = "inclusion" if cmd == FENCE_POLY_IN else "exclusion"
                out.append(Feature(f"fence polygon {len(out) + 1}", polygon(fence_ring), role))
                fence_ring = []
        elif cmd in (FENCE_CIRCLE_IN, FENCE_CIRCLE_OUT):
            role = "inclusion" if cmd == FENCE_CIRCLE_IN else "exclusion"
            centre = _ll(lat, lon)
            out.append(
                Feature(
                    f"fence circle {len(out) + 1}",
                    Geometry.circle(centre.lat_deg, centre.lon_deg, _num(it.param1, "radius")),
                    role,
                )
            )
        elif cmd == RALLY_POINT:
            out.append(
                Feature(
                    f"rally {len(out) + 1}",
                    Geometry(GeometryKind.POINT, (_ll(lat, lon),)),
                    "rally",
                    float(it.z),
                )
            )
    if fence_ring:
        raise ValueError(f"a fence polygon has {len(fence_ring)} vertices, fewer than it says")
    if waypoints:
        kind = GeometryKind.POLYLINE if len(waypoints) >= 2 else GeometryKind.POINT
        out.append(
            Feature(
                "waypoints",
                Geometry(kind, tuple(waypoints)),
                "route" if len(waypoints) >= 2 else "point",
            )
        )
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


def mission_geometry(path: Path | str, mtype: MissionType, feature: str | None = None) -> Geometry:
    """The geometry a mission of `mtype` flies, from a file: the feature named or
    numbered, or the first that fits (a survey polygon before a fence polygon)."""
    feats = read_features(path)
    wants = WANTS.get(mtype, ())
    if feature is not None:
        f = pick(feats, feature, path)
        return _as(f.geometry, wants, mtype, path, f.describe())
    ranked = sorted(feats, key=lambda f: (f.role in NOT_MISSION_ROLES, f.role == "inclusion"))
    for kind in wants:
        for f in ranked:
            if f.geometry.kind == kind and f.role not in ("home", "rally"):
                return f.geometry
    # waypoints can stand for what is wanted: a polygon's vertices, points
    for f in ranked:
        if f.role in ("route", "waypoints", "point") and f.geometry.kind in (
            GeometryKind.POLYLINE,
            GeometryKind.POINTS,
        ):
            try:
                return _as(f.geometry, wants, mtype, path, f.describe())
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


def zone_features(path: Path | str) -> list[Feature]:
    """The zones and operating areas in a file: every exclusion and inclusion polygon
    or circle (a GeoJSON/KML polygon with no role is a no-fly zone; a survey area is
    not a zone)."""
    feats = read_features(path)
    zones = [
        (
            f
            if f.role in ("exclusion", "inclusion")
            else Feature(f.name, f.geometry, "exclusion", f.alt_m, f.props)
        )
        for f in feats
        if f.geometry.kind in (GeometryKind.POLYGON, GeometryKind.CIRCLE)
        and (
            f.role in ("exclusion", "inclusion")
            or Path(path).suffix.lower() in (".geojson", ".json", ".kml")
        )
    ]
    if not zones:
        has = ", ".join(f.describe() for f in feats[:8])
        raise _fail(path, f"no fence polygon or circle in it (it has {has})")
    for z in zones:
        if z.geometry.holes:
            raise _fail(path, f"{z.describe()}: a zone has no holes (declare two zones)")
    return zones


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


def _geojson_geometry(g: Geometry) -> tuple[dict[str, Any], dict[str, Any]]:
    """(GeoJSON geometry, extra properties)."""
    if g.kind == GeometryKind.POLYGON:
        rings = [_ring_lonlat(g.points), *(_ring_lonlat(h) for h in g.holes)]
        return {"type": "Polygon", "coordinates": rings}, {}
    if g.kind == GeometryKind.CIRCLE:
        c = g.points[0]
        return {"type": "Point", "coordinates": [c.lon_deg, c.lat_deg]}, {"radius_m": g.radius_m}
    if g.kind == GeometryKind.POLYLINE:
        return {"type": "LineString", "coordinates": [[p.lon_deg, p.lat_deg] for p in g.points]}, {}
    if g.kind == GeometryKind.POINTS:
        return {"type": "MultiPoint", "coordinates": [[p.lon_deg, p.lat_deg] for p in g.points]}, {}
    p = g.points[0]
    return {"type": "Point", "coordinates": [p.lon_deg, p.lat_deg]}, {}


def geojson_text(items: Sequence[tuple[str, Geometry, dict[str, Any]]]) -> str:
    import geojson

    feats = []
    for name, g, props in items:
        geom, extra = _geojson_geometry(g)
        feats.append(geojson.Feature(geometry=geom, properties={"name": name, **extra, **props}))
    fc = geojson.FeatureCollection(feats)
    if not fc.is_valid:
        raise ValueError(f"GeoJSON not valid: {fc.errors()}")
    return geojson.dumps(fc, indent=2) + "\n"


def kml_text(title: str, items: Sequence[tuple[str, Geometry, dict[str, Any]]]) -> str:
    from fastkml import containers, data, features, kml
    from pygeoif import geometry as pg

    marks = []
    for name, g, props in items:
        extra: dict[str, Any] = dict(props)
        if g.kind == GeometryKind.POLYGON:
            shape: Any = pg.Polygon(
                [(p.lon_deg, p.lat_deg) for p in g.points],
                [[(p.lon_deg, p.lat_deg) for p in h] for h in g.holes],
            )
        elif g.kind == GeometryKind.POLYLINE:
            shape = pg.LineString([(p.lon_deg, p.lat_deg) for p in g.points])
        elif g.kind == GeometryKind.POINTS:
            shape = pg.MultiPoint([(p.lon_deg, p.lat_deg) for p in g.points])
        else:
            p = g.points[0]
            shape = pg.Point(p.lon_deg, p.lat_deg)
            if g.kind == GeometryKind.CIRCLE:
                extra["radius_m"] = g.radius_m
        ed = data.ExtendedData(
            elements=[data.Data(name=k, value=str(v)) for k, v in extra.items() if v is not None]
        )
        marks.append(features.Placemark(name=name, geometry=shape, extended_data=ed))
    doc = kml.KML(features=[containers.Document(name=title, features=marks)])
    return str(doc.to_string(prettyprint=True))


def plan_text(
    mission: Mission | None = None,
    zones: Sequence[NoFlyZone] = (),
    rally: Sequence[tuple[float, float, float]] = (),
    home: tuple[float, float, float] | None = None,
) -> str:
    """A QGroundControl plan (fileType Plan, mission version 2, geoFence version 2,
    rallyPoints version 2): an area mission as a survey complex item (its polygon and
    camera side overlap; QGroundControl generates the transects), other missions as
    waypoints at the mission's altitude above home."""
    items: list[dict[str, Any]] = []
    if mission is not None:
        g, prm = mission.geometry, mission.params
        alt = prm.altitude_rel_m
        if g.kind == GeometryKind.POLYGON and mission.mission_type in (MissionType.AREA,):
            items.append(
                {
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
                            "CameraName": "Manual (no camera specs)",
                            "DistanceToSurface": alt,
                            "DistanceMode": 1,
                            "SideOverlap": round(prm.side_overlap * 100, 1),
                            "FrontalOverlap": 70,
                            "ValueSetIsDistance": True,
                        },
                    },
                }
            )
        else:
            pts = list(g.points)
            if g.kind == GeometryKind.POLYGON:
                pts.append(pts[0])
            for p in pts:
                cmd = NAV_LOITER_UNLIM if g.kind == GeometryKind.CIRCLE else NAV_WAYPOINT
                r = g.radius_m or 0.0
                items.append(
                    {
                        "type": "SimpleItem",
                        "command": cmd,
                        "frame": FRAME_GLOBAL_RELATIVE_ALT,
                        "autoContinue": True,
                        "doJumpId": len(items) + 1,
                        "params": [0, 0, r, None, p.lat_deg, p.lon_deg, alt],
                    }
                )
    centre = (
        mission.geometry.points[0]
        if mission is not None
        else (zones[0].geometry.points[0] if zones else None)
    )
    planned_home = (
        list(home) if home else ([centre.lat_deg, centre.lon_deg, 0] if centre else [0, 0, 0])
    )
    fence: dict[str, Any] = {"version": 2, "polygons": [], "circles": []}
    for z in zones:
        if not z.active:
            continue
        if z.geometry.kind == GeometryKind.CIRCLE:
            c = z.geometry.points[0]
            fence["circles"].append(
                {
                    "version": 1,
                    "inclusion": z.operating_area,
                    "circle": {"center": [c.lat_deg, c.lon_deg], "radius": z.geometry.radius_m},
                }
            )
        else:
            fence["polygons"].append(
                {
                    "version": 1,
                    "inclusion": z.operating_area,
                    "polygon": [[p.lat_deg, p.lon_deg] for p in z.geometry.points],
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
    }
    return json.dumps(plan, indent=2) + "\n"


def wpl_text(
    mission: Mission | None = None,
    zones: Sequence[NoFlyZone] = (),
    home: tuple[float, float, float] | None = None,
) -> str:
    """QGC WPL 110 via pymavlink's MAVWPLoader: item 0 the home, then the mission's
    waypoints (relative altitude) and the zones as fence items (5001-5004)."""
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
    ) -> None:
        seq = loader.count()
        loader.add(
            link.MAVLink_mission_item_message(
                0, 0, seq, frame, cmd, 1 if seq == 0 else 0, 1, p1, 0, 0, 0, lat, lon, alt
            )
        )

    first = (
        mission.geometry.points[0]
        if mission is not None
        else (zones[0].geometry.points[0] if zones else LatLon(0.0, 0.0))
    )
    h = home or (first.lat_deg, first.lon_deg, 0.0)
    add(NAV_WAYPOINT, h[0], h[1], h[2], frame=0)  # MAV_FRAME_GLOBAL: home
    if mission is not None:
        g, alt = mission.geometry, mission.params.altitude_rel_m
        pts = list(g.points) + ([g.points[0]] if g.kind == GeometryKind.POLYGON else [])
        for p in pts:
            if g.kind == GeometryKind.CIRCLE:
                add(NAV_LOITER_UNLIM, p.lat_deg, p.lon_deg, alt)
            else:
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
                    w.param1,
                    w.param2,
                    w.param3,
                    w.param4,
                    f"{w.x:.8f}",
                    f"{w.y:.8f}",
                    f"{w.z:.3f}",
                    w.autocontinue,
                )
            )
        )
    return "\n".join(lines) + "\n"


def save_mission(path: Path | str, mission: Mission) -> None:
    p = Path(path)
    s = _suffix(p)
    name = mission.name or f"mission {mission.mission_id}"
    props = {
        "mission_id": mission.mission_id,
        "mission_type": mission.mission_type.name.lower(),
        **{k: v for k, v in msgspec.to_builtins(mission.params).items() if v is not None},
    }
    try:
        if s == ".json":
            text = msgspec.json.format(msgspec.json.encode(mission), indent=2).decode() + "\n"
        elif s == ".geojson":
            text = geojson_text([(name, mission.geometry, props)])
        elif s == ".kml":
            text = kml_text(name, [(name, mission.geometry, props)])
        elif s == ".plan":
            text = plan_text(mission)
        else:
            text = wpl_text(mission)
    except ValueError as exc:
        raise _fail(p, str(exc)) from None
    _write(p, text)


def save_zones(path: Path | str, zones: Sequence[NoFlyZone]) -> None:
    p = Path(path)
    s = _suffix(p)
    active = [z for z in zones if z.active]
    items = [
        (
            z.name or f"zone {z.zone_id}",
            z.geometry,
            {
                "zone_id": z.zone_id,
                "role": "inclusion" if z.operating_area else "exclusion",
                **(
                    {}
                    if z.operating_area
                    else {
                        "floor_alt_msl_m": z.floor_alt_msl_m,
                        "ceiling_alt_msl_m": z.ceiling_alt_msl_m,
                    }
                ),
            },
        )
        for z in active
    ]
    if s == ".json":
        text = msgspec.json.format(msgspec.json.encode(list(active)), indent=2).decode() + "\n"
    elif s == ".geojson":
        text = geojson_text(items)
    elif s == ".kml":
        text = kml_text("zones", items)
    elif s == ".plan":
        text = plan_text(None, active)
    else:
        text = wpl_text(None, active)
    _write(p, text)
