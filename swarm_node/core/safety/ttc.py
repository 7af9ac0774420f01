"""Closest point of approach (CPA) between vehicles that keep their velocity: pure numpy.

Every position is put in one local East-North-Up frame tangent at an origin
(`swarm_proto.geodesy`: pymap3d, WGS84, geodetic -> ECEF -> ENU, exact on the
ellipsoid, no flat-earth scale), and every NED velocity is rotated from its own vehicle's tangent plane into that frame (ENU ->
ECEF -> ENU), so the geometry stays exact for vehicles kilometres apart.

Altitudes are above mean sea level (`VehicleStatus.alt_msl_m`, ADS-B altitude): the one
datum every vehicle shares (altitude above home is not, homes differ). They are used as
heights over the ellipsoid; the geoid separation is the same to a few centimetres across
the few kilometres avoidance looks at, so the relative geometry is exact to that.

Stale telemetry is never trusted as fresh: a report `age` seconds old is first
extrapolated to `now` with its velocity, and the vehicle may have manoeuvred since, so
its protection volume widens by how far it could be from the extrapolation: at most
`0.5 * max_accel * age^2` (it changes velocity no faster than that) and never more than
`age * (max_speed + speed)` (the distance it could have moved, plus where the
extrapolation put it). A report that is itself a prediction (a radio peer's status
republished by its gateway: `VehicleStatus.position_error_m`) widens it by
that error bound as well. Callers compare `miss_m - margin_m` with their thresholds.

    rel_p = p_other - p_own, rel_v = v_other - v_own
    t_cpa = clip(-(rel_p . rel_v) / |rel_v|^2, 0, horizon)     (0 when diverging)
    d_cpa = |rel_p + rel_v * t_cpa|
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from swarm_proto import VehicleStatus, geodesy

FloatArray = npt.NDArray[np.float64]

EPS_SPEED2 = 1e-9  # |relative velocity|^2 below this: no relative motion, CPA is now
DEFAULT_MAX_ACCEL_M_S2 = 10.0  # a fixed-wing at 45 degrees of bank (g tan 45)


class BadTrackError(ValueError):
    """A track with a non-finite or impossible value (never fed to the geometry)."""


@dataclass(frozen=True, slots=True)
class Track:
    """Where a vehicle was at `time_s` and how it moved (NED velocity, m/s).

    `time_s` is on the caller's clock (the one `now` is on); `max_speed_m_s` is how fast
    it could go, used to widen its protection volume by what it could have moved since;
    `error_m` is how far the reported position may be from the truth at `time_s` (a
    radio gateway's prediction: `VehicleStatus.position_error_m`; 0 when measured)."""

    vehicle_id: int
    lat_deg: float
    lon_deg: float
    alt_msl_m: float
    vel_north_m_s: float = 0.0
    vel_east_m_s: float = 0.0
    vel_down_m_s: float = 0.0
    time_s: float = 0.0
    max_speed_m_s: float = 0.0
    error_m: float = 0.0
    max_accel_m_s2: float = DEFAULT_MAX_ACCEL_M_S2

    def __post_init__(self) -> None:
        values = (
            self.lat_deg,
            self.lon_deg,
            self.alt_msl_m,
            self.vel_north_m_s,
            self.vel_east_m_s,
            self.vel_down_m_s,
            self.time_s,
            self.max_speed_m_s,
            self.error_m,
        )
        # one sum: any NaN or infinity (or values so large they overflow) is not finite
        if not math.isfinite(sum(values)):
            raise BadTrackError(f"vehicle {self.vehicle_id}: non-finite track value {values}")
        if not (-90.0 <= self.lat_deg <= 90.0 and -180.0 <= self.lon_deg <= 180.0):
            raise BadTrackError(
                f"vehicle {self.vehicle_id}: position ({self.lat_deg}, {self.lon_deg}) out of range"
            )
        if self.max_speed_m_s < 0.0 or self.error_m < 0.0 or not self.max_accel_m_s2 >= 0.0:
            raise BadTrackError(
                f"vehicle {self.vehicle_id}: negative max speed, acceleration or error"
            )

    @classmethod
    def from_status(
        cls, s: VehicleStatus, *, time_s: float | None = None, max_speed_m_s: float = 0.0
    ) -> Track:
        """From a VehicleStatus; `time_s` defaults to the sample's own time; a predicted
        status's error bound (`position_error_m`) becomes the track's `error_m`."""
        return cls(
            s.vehicle_id,
            s.lat_deg,
            s.lon_deg,
            s.alt_msl_m,
            s.vel_north_m_s,
            s.vel_east_m_s,
            s.vel_down_m_s,
            s.time_unix_s if time_s is None else time_s,
            max_speed_m_s,
            s.position_error_m,
        )

    @property
    def vertical_speed_m_s(self) -> float:
        """Upwards positive."""
        return -self.vel_down_m_s


@dataclass(frozen=True, slots=True)
class Frame:
    """A local ENU frame tangent at (lat0, lon0, h0)."""

    lat0_deg: float
    lon0_deg: float
    h0_m: float = 0.0

    def positions(self, lat: FloatArray, lon: FloatArray, h: FloatArray) -> FloatArray:
        """(N, 3) east, north, up metres."""
        return geodesy.enu(lat, lon, h, self.lat0_deg, self.lon0_deg, self.h0_m)

    def velocities(
        self, lat: FloatArray, lon: FloatArray, vn: FloatArray, ve: FloatArray, vd: FloatArray
    ) -> FloatArray:
        """(N, 3) ENU velocities in this frame, from NED velocities at (lat, lon)."""
        return geodesy.ned_to_enu_velocity(lat, lon, vn, ve, vd, self.lat0_deg, self.lon0_deg)


@dataclass(frozen=True, slots=True)
class Kinematic:
    """Tracks put in one frame at one instant: extrapolated positions, velocities, and
    the widening of each protection volume for staleness."""

    ids: tuple[int, ...]
    pos: FloatArray  # (N, 3) ENU m at `now`
    vel: FloatArray  # (N, 3) ENU m/s
    age_s: FloatArray  # (N,) how old each report is at `now` (>= 0)
    margin_m: FloatArray  # (N,) how far from its extrapolation it could be, + error bound


def kinematic(tracks: Sequence[Track], now: float, frame: Frame | None = None) -> Kinematic:
    """Every track extrapolated to `now` in one frame (default: at the first track)."""
    if not tracks:
        empty = np.zeros((0, 3))
        return Kinematic((), empty, empty, np.zeros(0), np.zeros(0))
    lat = np.array([t.lat_deg for t in tracks])
    lon = np.array([t.lon_deg for t in tracks])
    h = np.array([t.alt_msl_m for t in tracks])
    if frame is None:
        frame = Frame(float(lat[0]), float(lon[0]), float(h[0]))
    vn = np.array([t.vel_north_m_s for t in tracks])
    ve = np.array([t.vel_east_m_s for t in tracks])
    vd = np.array([t.vel_down_m_s for t in tracks])
    age = np.maximum(0.0, now - np.array([t.time_s for t in tracks]))
    vel = frame.velocities(lat, lon, vn, ve, vd)
    pos = frame.positions(lat, lon, h) + vel * age[:, None]
    speed = np.hypot(vn, ve)
    by_speed = age * (np.array([t.max_speed_m_s for t in tracks]) + speed)
    by_accel = 0.5 * np.array([t.max_accel_m_s2 for t in tracks]) * age * age
    margin = np.minimum(by_speed, by_accel)
    margin += np.array([t.error_m for t in tracks])
    return Kinematic(tuple(t.vehicle_id for t in tracks), pos, vel, age, margin)


@dataclass(frozen=True, slots=True)
class Approach:
    """Closest approach of pairs over [now, now + horizon] (arrays broadcast alike)."""

    t_cpa_s: FloatArray  # seconds from now to the closest point (0: now, or diverging)
    miss_m: FloatArray  # 3-D distance at the closest point
    horizontal_m: FloatArray  # its horizontal part
    vertical_m: FloatArray  # its vertical part (other above own: positive)
    range_m: FloatArray  # 3-D distance now
    margin_m: FloatArray  # the pair's staleness widening (add to thresholds)


def closest_approach(rel_pos: FloatArray, rel_vel: FloatArray, horizon_s: float) -> Approach:
    """CPA of relative motions `rel_pos + rel_vel * t`, t in [0, horizon] ((..., 3))."""
    v2 = np.einsum("...i,...i->...", rel_vel, rel_vel)
    pv = np.einsum("...i,...i->...", rel_pos, rel_vel)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(v2 > EPS_SPEED2, -pv / np.where(v2 > EPS_SPEED2, v2, 1.0), 0.0)
    t = np.clip(t, 0.0, max(0.0, horizon_s))
    at = rel_pos + rel_vel * t[..., None]
    return Approach(
        t_cpa_s=t,
        miss_m=np.linalg.norm(at, axis=-1),
        horizontal_m=np.linalg.norm(at[..., :2], axis=-1),
        vertical_m=at[..., 2],
        range_m=np.linalg.norm(rel_pos, axis=-1),
        margin_m=np.zeros_like(t),
    )


def entry_time(
    rel_pos: FloatArray, rel_vel: FloatArray, radius_m: FloatArray | float, horizon_s: float
) -> FloatArray:
    """When each relative motion `rel_pos + rel_vel * t` first comes within `radius_m`
    (the loss of separation), t in [0, horizon]; 0 if it is within it now, infinity if
    it does not come that close by the horizon ((..., 3) in, (...) out).

        |p + v t| = R  ->  t = (-(p.v) - sqrt((p.v)^2 - |v|^2 (|p|^2 - R^2))) / |v|^2
    """
    r = np.broadcast_to(np.asarray(radius_m, dtype=float), rel_pos.shape[:-1])
    p2 = np.einsum("...i,...i->...", rel_pos, rel_pos)
    v2 = np.einsum("...i,...i->...", rel_vel, rel_vel)
    pv = np.einsum("...i,...i->...", rel_pos, rel_vel)
    disc = pv * pv - v2 * (p2 - r * r)
    moving = v2 > EPS_SPEED2
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(
            moving & (disc >= 0.0),
            (-pv - np.sqrt(np.maximum(disc, 0.0))) / np.where(moving, v2, 1.0),
            np.inf,
        )
    t = np.where(t < 0.0, np.inf, t)  # outside and moving apart: both roots behind
    t = np.where(p2 <= r * r, 0.0, t)  # within it now
    return np.where(t <= max(0.0, horizon_s), t, np.inf)


def along_route(
    start: FloatArray, points: FloatArray, speed_m_s: float, horizon_s: float
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """The legs of a vehicle flying from `start` through `points` ((M, 3), one frame) at
    `speed_m_s`, then holding at the last point, over [0, horizon]: each leg's start time,
    start position and velocity ((L,), (L, 3), (L, 3))."""
    times, starts, vels = [], [], []
    t, at = 0.0, np.asarray(start, dtype=float)
    for p in np.asarray(points, dtype=float):
        if t >= horizon_s:
            break
        d = p - at
        length = float(np.linalg.norm(d))
        if length < 1e-6:
            continue
        if speed_m_s <= 0.0:
            break
        times.append(t)
        starts.append(at)
        vels.append(d * (speed_m_s / length))
        t += length / speed_m_s
        at = p
    times.append(t)  # holding at the last point
    starts.append(at)
    vels.append(np.zeros(3))
    return np.array(times), np.array(starts), np.array(vels)


def route_approach(
    legs: tuple[FloatArray, FloatArray, FloatArray],
    pos: FloatArray,
    vel: FloatArray,
    radius_m: FloatArray,
    horizon_s: float,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Closest approach and loss of separation between a vehicle flying `legs`
    (`along_route`) and others keeping their velocity (`pos`, `vel`: (N, 3) at t = 0):
    exact, leg by leg. Returns (t_cpa, miss, entry) ((N,) each; entry: infinity if never
    within `radius_m` by the horizon)."""
    times, starts, vels = legs
    n = pos.shape[0]
    best_t, best_miss, entry = np.zeros(n), np.full(n, np.inf), np.full(n, np.inf)
    for i, t0 in enumerate(times):
        if t0 > horizon_s:
            break
        t1 = times[i + 1] if i + 1 < len(times) else horizon_s
        span = max(0.0, min(t1, horizon_s) - t0)
        rel_p = pos + vel * t0 - starts[i]
        rel_v = vel - vels[i]
        a = closest_approach(rel_p, rel_v, span)
        better = a.miss_m < best_miss
        best_t = np.where(better, t0 + a.t_cpa_s, best_t)
        best_miss = np.where(better, a.miss_m, best_miss)
        e = entry_time(rel_p, rel_v, radius_m, span)
        entry = np.where(np.isinf(entry) & np.isfinite(e), t0 + e, entry)
    return best_t, best_miss, entry


def approaches(own: Track, others: Sequence[Track], now: float, horizon_s: float) -> Approach:
    """CPA of `own` against each of `others` (arrays of len(others)), in own's frame."""
    k = kinematic([own, *others], now)
    a = closest_approach(k.pos[1:] - k.pos[0], k.vel[1:] - k.vel[0], horizon_s)
    return Approach(
        a.t_cpa_s, a.miss_m, a.horizontal_m, a.vertical_m, a.range_m, k.margin_m[1:] + k.margin_m[0]
    )


def pairwise(k: Kinematic, horizon_s: float) -> Approach:
    """CPA of every pair (N, N matrices; the diagonal is each vehicle with itself)."""
    a = closest_approach(
        k.pos[None, :, :] - k.pos[:, None, :], k.vel[None, :, :] - k.vel[:, None, :], horizon_s
    )
    margin = k.margin_m[:, None] + k.margin_m[None, :]
    return Approach(a.t_cpa_s, a.miss_m, a.horizontal_m, a.vertical_m, a.range_m, margin)


Legs = tuple[FloatArray, FloatArray, FloatArray]  # each leg's start time, position, velocity


def straight(pos: FloatArray, vel: FloatArray) -> Legs:
    """One vehicle keeping its velocity, as legs."""
    return np.zeros(1), np.asarray(pos, dtype=float)[None, :], np.asarray(vel, dtype=float)[None, :]


def along_intent(
    start: FloatArray,
    vel: FloatArray,
    points: FloatArray,
    speed_m_s: float,
    turn_radius_m: float,
    horizon_s: float,
    *,
    hold_at_end: bool,
    step_s: float = 0.5,
) -> Legs:
    """The legs of a contact flying its published path: from `start` (moving with `vel`)
    through `points` ((M, 3), one frame) at `speed_m_s`. A leading point already behind
    it (its newer intent not heard yet) is skipped. Turning on the spot
    (`turn_radius_m` 0, a multirotor) this is `along_route`; otherwise it turns no
    tighter than `turn_radius_m` (a fixed-wing): it steers towards each point and takes
    the next once abeam of it (ArduPlane's waypoint passing), so a lane's end closer
    than its turning circle is flown as the loop it is. After the last point it holds
    there (`hold_at_end`) or goes on straight."""
    pts = np.asarray(points, dtype=float)
    p0 = np.asarray(start, dtype=float)
    v0 = np.asarray(vel, dtype=float)
    if len(pts) > 1 and float(np.dot(pts[0, :2] - p0[:2], v0[:2])) < 0.0:
        pts = pts[1:]  # passed: the contact flies to the next one
    speed = max(speed_m_s, float(np.hypot(v0[0], v0[1])))
    if turn_radius_m <= 0.0 or speed <= 0.0:
        times, starts, vels = along_route(p0, pts, speed, horizon_s)
        if not hold_at_end and len(times) > 1:
            vels[-1] = vels[-2]  # goes on as it flew the last leg
        return times, starts, vels
    omega = speed / turn_radius_m  # its fastest turn, rad/s
    x, y, z = float(p0[0]), float(p0[1]), float(p0[2])
    if math.hypot(v0[0], v0[1]) > 0.5:
        heading = math.atan2(v0[1], v0[0])
    else:
        heading = math.atan2(pts[0, 1] - y, pts[0, 0] - x)
    prev = (x, y)
    i, n = 0, len(pts)
    ts: list[float] = []
    ss: list[tuple[float, float, float]] = []
    vs: list[tuple[float, float, float]] = []
    t = 0.0
    while t < horizon_s:
        vz = 0.0
        if i < n:
            tx, ty, tz = pts[i]
            want = math.atan2(ty - y, tx - x)
            turn = (want - heading + math.pi) % (2.0 * math.pi) - math.pi
            heading += max(-omega * step_s, min(omega * step_s, turn))
            vz = max(-5.0, min(5.0, (tz - z) / max(step_s, math.hypot(tx - x, ty - y) / speed)))
        elif hold_at_end:
            break
        vx, vy = speed * math.cos(heading), speed * math.sin(heading)
        ts.append(t)
        ss.append((x, y, z))
        vs.append((vx, vy, vz))
        x, y, z, t = x + vx * step_s, y + vy * step_s, z + vz * step_s, t + step_s
        if i < n:
            tx, ty = pts[i, 0], pts[i, 1]
            lx, ly = tx - prev[0], ty - prev[1]
            if math.hypot(tx - x, ty - y) < speed * step_s or (lx * (tx - x) + ly * (ty - y)) < 0:
                prev, i = (tx, ty), i + 1  # reached or abeam: on to the next
    ts.append(t)  # from here: still (held) or on, straight (the horizon is reached)
    ss.append((x, y, z))
    vs.append((0.0, 0.0, 0.0) if hold_at_end else vs[-1] if vs else (0.0, 0.0, 0.0))
    return np.array(ts), np.array(ss), np.array(vs)


def legs_approach(
    a: Legs, b: Legs, radius_m: float, horizon_s: float
) -> tuple[float, float, float]:
    """Closest approach and loss of separation (within `radius_m`) of two vehicles each
    flying its legs, over [0, horizon]: exact, interval by interval. (t_cpa, miss,
    entry; entry infinity if never within `radius_m` by the horizon)."""
    cuts = np.unique(np.concatenate([a[0], b[0], [0.0]]))
    cuts = cuts[(cuts >= 0.0) & (cuts < horizon_s)]
    ends = np.append(cuts[1:], horizon_s)
    spans = ends - cuts

    def at(legs: Legs) -> tuple[FloatArray, FloatArray]:
        times, starts, vels = legs
        idx = np.clip(np.searchsorted(times, cuts, side="right") - 1, 0, len(times) - 1)
        pos = starts[idx] + vels[idx] * (cuts - times[idx])[:, None]
        return pos, vels[idx]

    pa, va = at(a)
    pb, vb = at(b)
    rel_p, rel_v = pb - pa, vb - va
    # each interval's closest approach and entry, clipped to its own span (vectorised)
    v2 = np.einsum("ij,ij->i", rel_v, rel_v)
    pv = np.einsum("ij,ij->i", rel_p, rel_v)
    p2 = np.einsum("ij,ij->i", rel_p, rel_p)
    moving = v2 > EPS_SPEED2
    safe_v2 = np.where(moving, v2, 1.0)
    t = np.clip(np.where(moving, -pv / safe_v2, 0.0), 0.0, spans)
    miss = np.linalg.norm(rel_p + rel_v * t[:, None], axis=1)
    k = int(np.argmin(miss))
    r2 = radius_m * radius_m
    disc = pv * pv - v2 * (p2 - r2)
    te = np.where(moving & (disc >= 0.0), (-pv - np.sqrt(np.maximum(disc, 0.0))) / safe_v2, np.inf)
    te = np.where(te < 0.0, np.inf, te)
    te = np.where(p2 <= r2, 0.0, te)
    te = np.where(te <= spans, te, np.inf)
    hit = np.flatnonzero(np.isfinite(te))
    entry = float(cuts[hit[0]] + te[hit[0]]) if hit.size else math.inf
    return float(cuts[k] + t[k]), float(miss[k]), entry
