"""Geodetic <-> local ENU metres, and mission geometry as shapely shapes in that frame.

Every planner works in one local East-North-Up frame tangent at an origin near the
mission (pymap3d, WGS84); outputs go back to latitude/longitude. Local x is east, y is
north; a yaw is counter-clockwise from east, a heading clockwise from north.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
import pymap3d
import shapely
from shapely.geometry import LineString, Point, Polygon
from shapely.validation import explain_validity

from swarm_proto import Geometry, GeometryKind, LatLon, VehicleStatus, geodesy

from .errors import EmptyAreaError, InvalidGeometryError

CIRCLE_SEGMENTS = 64  # polygon approximation of circles (circumscribed for zones)


def heading_to_yaw(heading_deg: float) -> float:
    """Compass heading (deg, clockwise from north) -> local yaw (rad, CCW from east)."""
    return math.remainder(math.pi / 2.0 - math.radians(heading_deg), 2.0 * math.pi)


def yaw_to_heading(yaw_rad: float) -> float:
    return (90.0 - math.degrees(yaw_rad)) % 360.0


@dataclass(frozen=True, slots=True)
class VehiclePose:
    """Where a vehicle is now (geodetic), as planners need it."""

    lat_deg: float
    lon_deg: float
    alt_rel_m: float = 0.0
    heading_deg: float = 0.0
    groundspeed_m_s: float = 0.0

    @classmethod
    def from_status(cls, status: VehicleStatus) -> VehiclePose:
        return cls(
            status.lat_deg,
            status.lon_deg,
            status.alt_rel_m,
            status.heading_deg,
            status.groundspeed_m_s,
        )


def _finite(*values: float) -> bool:
    return all(math.isfinite(v) for v in values)


@dataclass(frozen=True, slots=True)
class LocalFrame:
    """A local tangent plane (ENU) at `origin` (altitude 0 = the home/origin level)."""

    lat0_deg: float
    lon0_deg: float

    def __post_init__(self) -> None:
        if not (_finite(self.lat0_deg, self.lon0_deg) and abs(self.lat0_deg) < 89.0):
            raise InvalidGeometryError(
                f"frame origin must be finite and away from the poles, got "
                f"({self.lat0_deg}, {self.lon0_deg})"
            )

    @classmethod
    def at(cls, points: Iterable[LatLon | VehiclePose]) -> LocalFrame:
        """A frame at the mean of the given points."""
        pts = list(points)
        if not pts:
            raise InvalidGeometryError("a frame needs at least one point")
        lats = [p.lat_deg for p in pts]
        lons = [p.lon_deg for p in pts]
        if not _finite(*lats, *lons):
            raise InvalidGeometryError("coordinates must be finite (got NaN or infinity)")
        return cls(float(np.mean(lats)), float(np.mean(lons)))

    @classmethod
    def for_geometry(cls, geometry: Geometry) -> LocalFrame:
        return cls.at(geometry.points)

    def to_local(self, lat_deg: float, lon_deg: float) -> tuple[float, float]:
        if not _finite(lat_deg, lon_deg):
            raise InvalidGeometryError("coordinates must be finite (got NaN or infinity)")
        e, n, _u = geodesy.enu_of(lat_deg, lon_deg, 0.0, self.lat0_deg, self.lon0_deg, 0.0)
        return e, n

    def to_local_many(self, lat_lon: Sequence[tuple[float, float]]) -> np.ndarray:
        arr = np.asarray(lat_lon, dtype=np.float64).reshape(-1, 2)
        if not np.isfinite(arr).all():
            raise InvalidGeometryError("coordinates must be finite (got NaN or infinity)")
        e, n, _u = pymap3d.geodetic2enu(
            arr[:, 0], arr[:, 1], np.zeros(len(arr)), self.lat0_deg, self.lon0_deg, 0.0
        )
        return np.column_stack([np.asarray(e, dtype=np.float64), np.asarray(n, dtype=np.float64)])

    def to_geodetic(self, x_m: float, y_m: float) -> tuple[float, float]:
        lat, lon, _h = pymap3d.enu2geodetic(x_m, y_m, 0.0, self.lat0_deg, self.lon0_deg, 0.0)
        return float(lat), float(lon)

    def to_geodetic_many(self, xy: npt.ArrayLike) -> np.ndarray:
        arr = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
        lat, lon, _h = pymap3d.enu2geodetic(
            arr[:, 0], arr[:, 1], np.zeros(len(arr)), self.lat0_deg, self.lon0_deg, 0.0
        )
        return np.column_stack([np.asarray(lat), np.asarray(lon)])

    def pose(self, pose: VehiclePose) -> tuple[float, float, float]:
        """(x, y, yaw) of a vehicle pose."""
        x, y = self.to_local(pose.lat_deg, pose.lon_deg)
        return x, y, heading_to_yaw(pose.heading_deg)

    def ring(self, ring: Sequence[LatLon]) -> list[tuple[float, float]]:
        xy = self.to_local_many([(p.lat_deg, p.lon_deg) for p in ring])
        return [(float(a), float(b)) for a, b in xy]

    def shape(self, geometry: Geometry, *, circumscribe: bool = False) -> shapely.Geometry:
        """The geometry as a local shapely shape: POLYGON -> Polygon (with holes), CIRCLE ->
        a polygon (inscribed, or circumscribed with `circumscribe` so that the polygon
        contains the true circle), POINT -> Point, POINTS -> MultiPoint, POLYLINE ->
        LineString."""
        k = geometry.kind
        if k == GeometryKind.POLYGON:
            poly = Polygon(self.ring(geometry.points), [self.ring(h) for h in geometry.holes])
            return validated_polygon(poly)
        if k == GeometryKind.CIRCLE:
            assert geometry.radius_m is not None
            x, y = self.to_local(geometry.points[0].lat_deg, geometry.points[0].lon_deg)
            return circle_polygon(x, y, geometry.radius_m, circumscribe=circumscribe)
        pts = self.ring(geometry.points)
        if k == GeometryKind.POINT:
            return Point(pts[0])
        if k == GeometryKind.POINTS:
            return shapely.MultiPoint(pts)
        return LineString(pts)


def circle_polygon(x: float, y: float, radius_m: float, *, circumscribe: bool = False) -> Polygon:
    if not (_finite(x, y, radius_m) and radius_m > 0.0):
        raise InvalidGeometryError(f"circle needs a finite positive radius, got {radius_m}")
    r = radius_m / math.cos(math.pi / CIRCLE_SEGMENTS) if circumscribe else radius_m
    return Point(x, y).buffer(r, quad_segs=CIRCLE_SEGMENTS // 4)


def validated_polygon(poly: shapely.Geometry) -> Polygon | shapely.MultiPolygon:
    """`poly` if it is a valid, finite, non-empty (Multi)Polygon, else a clear error."""
    if not isinstance(poly, Polygon | shapely.MultiPolygon):
        raise InvalidGeometryError(f"expected a polygon, got {poly.geom_type}")
    coords = shapely.get_coordinates(poly)
    if len(coords) and not np.isfinite(coords).all():
        raise InvalidGeometryError("polygon coordinates must be finite (got NaN or infinity)")
    if poly.is_empty:
        raise EmptyAreaError("polygon is empty")
    if not poly.is_valid:
        if shapely.make_valid(poly).area <= 0.0:
            raise EmptyAreaError("polygon has zero area")
        raise InvalidGeometryError(f"polygon is not simple: {explain_validity(poly)}")
    if poly.area <= 0.0:
        raise EmptyAreaError("polygon has zero area")
    return poly
