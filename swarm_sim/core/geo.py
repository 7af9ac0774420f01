"""Flat-earth geometry around a fixed origin (the vehicle's boot position).

Positions inside the simulator are metres north/east of the origin; latitude/longitude
are computed on the way out. The equirectangular projection is accurate to well under a
metre over the tens of kilometres a simulated sortie covers.
"""

from __future__ import annotations

import math

EARTH_RADIUS_M = 6_378_137.0  # WGS84 equatorial radius, as ArduPilot's Location uses


def wrap_180(deg: float) -> float:
    """Angle in [-180, 180)."""
    return (deg + 180.0) % 360.0 - 180.0


def wrap_360(deg: float) -> float:
    """Angle in [0, 360)."""
    return deg % 360.0


class LocalFrame:
    """North/east metres <-> latitude/longitude around `origin`."""

    __slots__ = ("_m_per_deg_lat", "_m_per_deg_lon", "lat0", "lon0")

    def __init__(self, lat0_deg: float, lon0_deg: float) -> None:
        if not (math.isfinite(lat0_deg) and math.isfinite(lon0_deg)) or abs(lat0_deg) > 89.0:
            raise ValueError(f"bad origin {lat0_deg}, {lon0_deg}")
        self.lat0 = lat0_deg
        self.lon0 = lon0_deg
        self._m_per_deg_lat = math.radians(1.0) * EARTH_RADIUS_M
        self._m_per_deg_lon = self._m_per_deg_lat * math.cos(math.radians(lat0_deg))

    def to_ne(self, lat_deg: float, lon_deg: float) -> tuple[float, float]:
        return (
            (lat_deg - self.lat0) * self._m_per_deg_lat,
            wrap_180(lon_deg - self.lon0) * self._m_per_deg_lon,
        )

    def to_latlon(self, north_m: float, east_m: float) -> tuple[float, float]:
        lat = self.lat0 + north_m / self._m_per_deg_lat
        lon = wrap_180(self.lon0 + east_m / self._m_per_deg_lon)
        return lat, lon


def distance_m(n1: float, e1: float, n2: float, e2: float) -> float:
    return math.hypot(n2 - n1, e2 - e1)


def bearing_deg(n1: float, e1: float, n2: float, e2: float) -> float:
    """Bearing from point 1 to point 2, degrees clockwise from north in [0, 360)."""
    return wrap_360(math.degrees(math.atan2(e2 - e1, n2 - n1)))


def point_in_polygon(n: float, e: float, polygon: list[tuple[float, float]]) -> bool:
    """Ray casting; `polygon` is a list of (north, east) vertices, open or closed."""
    inside = False
    count = len(polygon)
    if count < 3:
        return False
    j = count - 1
    for i in range(count):
        ni, ei = polygon[i]
        nj, ej = polygon[j]
        if (ei > e) != (ej > e):
            cross = ni + (e - ei) * (nj - ni) / (ej - ei)
            if n < cross:
                inside = not inside
        j = i
    return inside
