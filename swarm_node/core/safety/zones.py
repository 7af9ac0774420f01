"""The zone book: every no-fly zone and operating area a node holds, and the one
geometry monitoring, the fence keeper, the planners and collision avoidance ask it.

    book[zone.zone_id] = zone                 (a dict of NoFlyZone by id; `version` counts changes)
    book.in_force(now) / no_fly(now) / operating_areas(now)
    book.breach(lat, lon, alt_msl, now)       what is breached (monitoring), or None
    breach(zones, ...), ceiling_msl(zones, ...) the same for any collection of zones
    book.ceiling_msl(lat, lon, alt_msl, now)  the lowest floor of a no-fly zone above
                                              (avoidance never climbs into it)
    inside(geometry, lat, lon)                point in a POLYGON or CIRCLE
    distance_outside_m(geometry, lat, lon)    horizontal metres to it (0 inside)

Every shape is measured in metres on the WGS84 ellipsoid: a circle by the ground
distance to its centre (`swarm_proto.geodesy.distance_m`), a polygon in the East-North-Up
frame tangent at its centroid (`planning.geo.LocalFrame`, pymap3d), the frame the
planners plan in. Pure: no I/O, `now` passed in.
"""

from __future__ import annotations

import functools
from collections.abc import Iterable, Iterator, MutableMapping

import shapely
from shapely.geometry import Point

from swarm_proto import Geometry, GeometryKind, NoFlyZone
from swarm_proto.geodesy import distance_m

from ..planning.geo import LocalFrame


@functools.lru_cache(maxsize=256)
def _polygon(geometry: Geometry) -> tuple[LocalFrame, shapely.Geometry]:
    frame = LocalFrame.for_geometry(geometry)
    shape = frame.shape(geometry)
    shapely.prepare(shape)
    return frame, shape


def inside(geometry: Geometry, lat_deg: float, lon_deg: float) -> bool:
    """Whether a point is inside (or on the edge of) a POLYGON (holes excluded) or a
    CIRCLE; any other kind contains nothing."""
    return distance_outside_m(geometry, lat_deg, lon_deg) == 0.0


def distance_outside_m(geometry: Geometry, lat_deg: float, lon_deg: float) -> float:
    """Horizontal metres from a point to a POLYGON or CIRCLE (0 inside; inf for kinds
    that enclose nothing)."""
    if geometry.kind == GeometryKind.CIRCLE:
        c = geometry.points[0]
        d = distance_m(c.lat_deg, c.lon_deg, lat_deg, lon_deg) - (geometry.radius_m or 0.0)
        return max(0.0, d)
    if geometry.kind == GeometryKind.POLYGON:
        frame, shape = _polygon(geometry)
        return float(shape.distance(Point(frame.to_local(lat_deg, lon_deg))))
    return float("inf")


def breach(
    zones: Iterable[NoFlyZone], lat_deg: float, lon_deg: float, alt_msl_m: float, now: float
) -> str | None:
    """What a vehicle there breaches ("left operating area 2", "in no-fly zone 3"), or
    None. Operating areas are 2-D (as ArduPilot's inclusion fences); with several, the
    vehicle must be inside all of them. A no-fly zone counts between its floor and
    ceiling."""
    in_force = sorted(
        (z for z in zones if z.in_force(now)), key=lambda z: (not z.operating_area, z.zone_id)
    )
    for z in in_force:
        if z.operating_area:
            if not inside(z.geometry, lat_deg, lon_deg):
                return f"left operating area {z.zone_id}"
        elif z.floor_alt_msl_m <= alt_msl_m <= z.ceiling_alt_msl_m and inside(
            z.geometry, lat_deg, lon_deg
        ):
            return f"in no-fly zone {z.zone_id}"
    return None


def ceiling_msl(
    zones: Iterable[NoFlyZone],
    lat_deg: float,
    lon_deg: float,
    alt_msl_m: float,
    now: float,
    radius_m: float = 0.0,
) -> float | None:
    """The lowest floor (MSL) of the no-fly zones in force whose floor is above
    `alt_msl_m` and that lie within `radius_m` horizontally: how high a vehicle there
    may climb. None: nothing above."""
    best: float | None = None
    for z in zones:
        if z.operating_area or not z.in_force(now) or z.floor_alt_msl_m <= alt_msl_m:
            continue
        if distance_outside_m(z.geometry, lat_deg, lon_deg) > radius_m:
            continue
        if best is None or z.floor_alt_msl_m < best:
            best = z.floor_alt_msl_m
    return best


class ZoneBook(MutableMapping[int, NoFlyZone]):
    """The zones a node holds, by id (operating areas too). A dict to its callers, so
    `book[zone_id] = zone` replaces a zone; `version` grows with every change."""

    def __init__(self) -> None:
        self._zones: dict[int, NoFlyZone] = {}
        self.version = 0

    # ------------------------------------------------------------------ mapping
    def __getitem__(self, zone_id: int) -> NoFlyZone:
        return self._zones[zone_id]

    def __setitem__(self, zone_id: int, zone: NoFlyZone) -> None:
        self._zones[zone_id] = zone
        self.version += 1

    def __delitem__(self, zone_id: int) -> None:
        del self._zones[zone_id]
        self.version += 1

    def __iter__(self) -> Iterator[int]:
        return iter(self._zones)

    def __len__(self) -> int:
        return len(self._zones)

    def __repr__(self) -> str:
        return f"ZoneBook({sorted(self._zones)}, version={self.version})"

    # ------------------------------------------------------------------ views
    def in_force(self, now: float) -> list[NoFlyZone]:
        return [z for z in self._zones.values() if z.in_force(now)]

    def no_fly(self, now: float) -> list[NoFlyZone]:
        """The no-fly zones in force: what the planners route around."""
        return [z for z in self.in_force(now) if not z.operating_area]

    def operating_areas(self, now: float) -> list[NoFlyZone]:
        return [z for z in self.in_force(now) if z.operating_area]

    # ------------------------------------------------------------------ questions
    def breach(self, lat_deg: float, lon_deg: float, alt_msl_m: float, now: float) -> str | None:
        """What a vehicle there breaches, or None (`breach`)."""
        return breach(self._zones.values(), lat_deg, lon_deg, alt_msl_m, now)

    def ceiling_msl(
        self, lat_deg: float, lon_deg: float, alt_msl_m: float, now: float, radius_m: float = 0.0
    ) -> float | None:
        """How high a vehicle there may climb (`ceiling_msl`)."""
        return ceiling_msl(self._zones.values(), lat_deg, lon_deg, alt_msl_m, now, radius_m)
