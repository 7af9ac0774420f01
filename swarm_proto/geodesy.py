"""One geodesy for every distance and offset the swarm computes (WGS84, pymap3d).

Monitoring, fences, the planners' zone geometry, the mission manager, collision
avoidance, the separation analysis and the simulator's scenario set-up all use these
functions, so a vehicle that one module says is 30 m from a zone is 30 m from it for
every other module. Before there were three formulas (a spherical haversine,
a flat-earth 111,320 m per degree, and pymap3d); the flat-earth one is off by 0.3 %
north-south at 37 degrees of latitude (0.9 m in 300 m).

    distance_m(lat1, lon1, lat2, lon2)           ground distance on the ellipsoid
    distance_3d_m(lat1, lon1, h1, lat2, lon2, h2) straight line between two points (ECEF)
    offset(lat, lon, north_m, east_m)            the point so many metres north and east
    enu(lat, lon, h, lat0, lon0, h0)             East-North-Up metres in a tangent frame
    geodetic(e, n, u, lat0, lon0, h0)            and back
    ecef(lat, lon, h)                            Earth-centred, Earth-fixed metres

Ground distance: the ECEF chord between the two points at the ellipsoid's surface,
turned into the arc on a sphere of the ellipsoid's Gaussian mean radius at their mid
latitude. It agrees with the WGS84 geodesic (pyproj's `Geod.inv`, Karney's algorithm)
to 1 micrometre up to 10 km and to 1 mm up to 50 km (tests/swarm_proto/test_geodesy.py);
the swarm never looks further. Heights are metres above the ellipsoid; callers pass
altitudes above mean sea level, whose geoid separation is the same to centimetres
over the few kilometres a swarm spans, so relative geometry is exact to that.

The simulator's vehicles (`swarm_sim/core/geo.py`) keep ArduPilot's own flat-earth
scaling on purpose: they emulate the autopilot, which uses it.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt
import pymap3d

WGS84_A_M = 6_378_137.0
WGS84_F = 1.0 / 298.257223563
WGS84_E2 = WGS84_F * (2.0 - WGS84_F)

FloatArray = npt.NDArray[np.float64]


def mean_radius_m(lat_deg: float) -> float:
    """The ellipsoid's Gaussian mean radius of curvature at `lat_deg`: sqrt(M N)."""
    w = 1.0 - WGS84_E2 * math.sin(math.radians(lat_deg)) ** 2
    return WGS84_A_M * math.sqrt(1.0 - WGS84_E2) / w


def ecef(lat_deg: float, lon_deg: float, h_m: float = 0.0) -> tuple[float, float, float]:
    """One point's ECEF metres: pymap3d's `geodetic2ecef` formula on Python floats (the
    avoidance and the planners call it hundreds of thousands of times a flight, where
    numpy's per-call cost was most of its time); tests/swarm_proto/test_geodesy.py holds
    it to pymap3d's answer."""
    lat, lon = math.radians(lat_deg), math.radians(lon_deg)
    sin_lat, cos_lat = math.sin(lat), math.cos(lat)
    n = WGS84_A_M / math.sqrt(1.0 - WGS84_E2 * sin_lat * sin_lat)
    return (
        (n + h_m) * cos_lat * math.cos(lon),
        (n + h_m) * cos_lat * math.sin(lon),
        (n * (1.0 - WGS84_E2) + h_m) * sin_lat,
    )


def enu_of(
    lat_deg: float, lon_deg: float, h_m: float, lat0_deg: float, lon0_deg: float, h0_m: float
) -> tuple[float, float, float]:
    """One point's East, North, Up metres in the frame tangent at (lat0, lon0, h0): `enu`
    for one point, on Python floats (pymap3d's `geodetic2enu`: the ECEF difference turned
    into the tangent frame)."""
    x, y, z = ecef(lat_deg, lon_deg, h_m)
    x0, y0, z0 = ecef(lat0_deg, lon0_deg, h0_m)
    dx, dy, dz = x - x0, y - y0, z - z0
    lat0, lon0 = math.radians(lat0_deg), math.radians(lon0_deg)
    sin_lat, cos_lat = math.sin(lat0), math.cos(lat0)
    sin_lon, cos_lon = math.sin(lon0), math.cos(lon0)
    t = cos_lon * dx + sin_lon * dy
    east = -sin_lon * dx + cos_lon * dy
    up = cos_lat * t + sin_lat * dz
    north = -sin_lat * t + cos_lat * dz
    return east, north, up


def ecef_many(lat_deg: npt.ArrayLike, lon_deg: npt.ArrayLike, h_m: npt.ArrayLike) -> FloatArray:
    """(N, 3) ECEF metres."""
    x, y, z = pymap3d.geodetic2ecef(
        np.asarray(lat_deg, float), np.asarray(lon_deg, float), np.asarray(h_m, float)
    )
    return np.stack([np.asarray(x, float), np.asarray(y, float), np.asarray(z, float)], -1)


def distance_3d_m(
    lat1: float, lon1: float, h1_m: float, lat2: float, lon2: float, h2_m: float
) -> float:
    """The straight-line distance between two points (ECEF chord), metres."""
    a = ecef(lat1, lon1, h1_m)
    b = ecef(lat2, lon2, h2_m)
    return math.dist(a, b)


def distance_m(lat1: float, lon1: float, lat2: float, lon2: float) -> float:
    """Ground distance between two points on the WGS84 ellipsoid, metres (see above)."""
    chord = distance_3d_m(lat1, lon1, 0.0, lat2, lon2, 0.0)
    r = mean_radius_m(0.5 * (lat1 + lat2))
    return 2.0 * r * math.asin(min(1.0, chord / (2.0 * r)))


def enu(
    lat_deg: npt.ArrayLike,
    lon_deg: npt.ArrayLike,
    h_m: npt.ArrayLike,
    lat0_deg: float,
    lon0_deg: float,
    h0_m: float = 0.0,
) -> FloatArray:
    """East, North, Up metres in the frame tangent at (lat0, lon0, h0): shape (..., 3)."""
    e, n, u = pymap3d.geodetic2enu(lat_deg, lon_deg, h_m, lat0_deg, lon0_deg, h0_m)
    return np.stack([np.asarray(e, float), np.asarray(n, float), np.asarray(u, float)], -1)


def geodetic(
    e_m: npt.ArrayLike,
    n_m: npt.ArrayLike,
    u_m: npt.ArrayLike,
    lat0_deg: float,
    lon0_deg: float,
    h0_m: float = 0.0,
) -> FloatArray:
    """Latitude, longitude (degrees) and height of ENU points: shape (..., 3)."""
    lat, lon, h = pymap3d.enu2geodetic(e_m, n_m, u_m, lat0_deg, lon0_deg, h0_m)
    return np.stack([np.asarray(lat, float), np.asarray(lon, float), np.asarray(h, float)], -1)


def ned_to_enu_velocity(
    lat_deg: npt.ArrayLike,
    lon_deg: npt.ArrayLike,
    vn: npt.ArrayLike,
    ve: npt.ArrayLike,
    vd: npt.ArrayLike,
    lat0_deg: float,
    lon0_deg: float,
) -> FloatArray:
    """NED velocities measured at (lat, lon), rotated into the frame tangent at
    (lat0, lon0) (it matters at tens of kilometres, where meridians converge): (..., 3)."""
    x, y, z = pymap3d.enu2uvw(ve, vn, -np.asarray(vd, float), lat_deg, lon_deg)
    e, n, u = pymap3d.uvw2enu(x, y, z, lat0_deg, lon0_deg)
    return np.stack([np.asarray(e, float), np.asarray(n, float), np.asarray(u, float)], -1)


def offset(lat_deg: float, lon_deg: float, north_m: float, east_m: float) -> tuple[float, float]:
    """The point `north_m` north and `east_m` east of (lat, lon), laid out on the
    ellipsoid's tangent plane there (how scenarios and formations are laid out): its
    ground distance is hypot(north, east) to 3e-6 relative up to 10 km (2 cm at 14 km)."""
    lat, lon, _h = pymap3d.enu2geodetic(east_m, north_m, 0.0, lat_deg, lon_deg, 0.0)
    return float(lat), float(lon)


def bearing_deg(lat1: float, lon1: float, lat2: float, lon2: float) -> float:
    """Initial compass bearing from the first point to the second (degrees, 0 = north)."""
    e, n, _u = pymap3d.geodetic2enu(lat2, lon2, 0.0, lat1, lon1, 0.0)
    return math.degrees(math.atan2(float(e), float(n))) % 360.0
