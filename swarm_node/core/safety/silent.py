"""Where a silent member's aircraft is now: a pure prediction from its last report.

A member whose node fell silent (its liveliness token gone, its telemetry stale) is
still an aircraft: its autopilot flies on what it was last told, then its GCS failsafe
takes it home (failsafe.py, docs/reliability.md). The ground station and the map show
a LOST vehicle at the position predicted here, which nobody reports any more (avoidance
does not use it yet: docs/reliability.md, known limits):

    from its last report, for the failsafe's timeout (from that report: its node's
    last HEARTBEAT went with it)
        along its share's remaining route (`route`: the mission coordinator's, from the
        member's published progress), at the share's speed; no route known: straight
        on with its last velocity
    then its RTL
        straight to its rally point (its base, else its home) at its speed, at its
        altitude or the rally point's if higher; there a multirotor or a QuadPlane
        lands (descends at `land_speed_m_s` to its home's height: Q_RTL_MODE 1), a
        plane circles it
    no failsafe (rovers, boats: left alone): the route, then held at its end

The prediction is only as good as the model: the error bound (`error_m`) starts at
`base_error_m` and grows with the time since the report (`growth_m_s` plus
`growth_fraction` of its speed: timing along the route, wind, the turns), up to
`max_error_m`; a fixed-wing circling its rally point adds its loiter radius. The
caller keeps it until the member is heard again, seen landed or dismissed.

Pure: no I/O, no clock; `now` is passed in, on the clock of the last report's time.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from swarm_proto import VehicleInfo, VehicleType, geodesy

from ..failsafe import COMPANION_TIMEOUT_S, failsafe_params
from ..landing_point import landing_point
from .ttc import Track

MULTIROTOR_TYPES = frozenset({VehicleType.COPTER})
# what lands at its rally point when its RTL gets there: a multirotor, and a QuadPlane
# (the node sets Q_RTL_MODE 1: RTL switches to QRTL there; failsafe.py); a plane circles
LANDS_AT_RALLY = frozenset({VehicleType.COPTER, VehicleType.VTOL})
LOITER_RADIUS_M = 60.0  # ArduPlane's WP_LOITER_RAD default: how wide it circles its rally point


def rally_point(info: VehicleInfo | None) -> tuple[float, float, float] | None:
    """Where a member's RTL goes (lat, lon, alt MSL): its autopilot's rally point, which
    its node set at its own landing point (its pad, or its slot at the base:
    landing_point.py, the same on every node and the ground station), at the base's
    height; None without a base (its RTL goes home)."""
    if info is None or info.base is None:
        return None
    b = info.base
    at = landing_point(info.vehicle_id, info.home, b) if info.home is not None else None
    return (*(at or (b.lat_deg, b.lon_deg)), b.alt_msl_m)


def failsafe_after_s(vehicle_type: VehicleType | None) -> float | None:
    """How long after its node's last HEARTBEAT the autopilot goes home by itself (the
    failsafe the node sets and verifies; None: the type is left alone)."""
    if vehicle_type is None:
        return COMPANION_TIMEOUT_S  # an aircraft until its VehicleInfo says otherwise
    return COMPANION_TIMEOUT_S if failsafe_params(vehicle_type) else None


@dataclass(frozen=True, slots=True)
class SilentModel:
    base_error_m: float = 5.0
    growth_m_s: float = 1.0
    growth_fraction: float = 0.1
    max_error_m: float = 50.0
    land_speed_m_s: float = 1.0  # ArduCopter LAND_SPEED (50 cm/s) and its RTL descent
    min_speed_m_s: float = 3.0  # an RTL is never slower than this


@dataclass(frozen=True, slots=True)
class Prediction:
    track: Track  # at `now`, `error_m` its bound
    phase: str  # "route" | "straight" | "rtl" | "landing" | "landed" | "circling" | "held"


@dataclass(frozen=True, slots=True)
class SilentAircraft:
    """A silent member as last reported, and what it will do without its node.

    `last`: its last report (position, NED velocity, `time_s` when sent); `home_msl_m`
    its home's height; `route`: (lat, lon, height above home) of its share's remaining
    points in order (None: not known); `speed_m_s` along it; `rally`: (lat, lon,
    height above mean sea level) it returns to (None: its home, if known, else it is
    predicted on its route)."""

    last: Track
    vehicle_type: VehicleType | None
    home_msl_m: float
    route: tuple[tuple[float, float, float], ...] | None = None
    speed_m_s: float = 0.0
    rally: tuple[float, float, float] | None = None
    home: tuple[float, float] | None = None
    failsafe_s: float | None = COMPANION_TIMEOUT_S
    model: SilentModel = SilentModel()

    @classmethod
    def of(
        cls,
        last: Track,
        vehicle_type: VehicleType | None,
        info: VehicleInfo | None,
        home_msl_m: float,
    ) -> SilentAircraft:
        """From its last report and what its VehicleInfo says: its home (and its
        height, else `home_msl_m` from the report), its cruise speed, its rally point
        (`rally_point`) and its type's failsafe. The avoider and the ground station
        predict alike."""
        home = None
        if info is not None and info.home is not None:
            home, home_msl_m = (info.home.lat_deg, info.home.lon_deg), info.home.alt_msl_m
        return cls(
            last,
            vehicle_type,
            home_msl_m,
            None,
            info.cruise_speed_m_s if info is not None else 0.0,
            rally_point(info),
            home,
            failsafe_after_s(vehicle_type),
        )

    def with_route(
        self, route: Sequence[tuple[float, float, float]], speed_m_s: float
    ) -> SilentAircraft:
        return SilentAircraft(
            self.last,
            self.vehicle_type,
            self.home_msl_m,
            tuple(route) or None,
            speed_m_s,
            self.rally,
            self.home,
            self.failsafe_s,
            self.model,
        )

    @property
    def _last_speed(self) -> float:
        t = self.last
        return math.hypot(t.vel_north_m_s, t.vel_east_m_s)

    def _speed(self) -> float:
        return max(self.speed_m_s, self._last_speed, self.model.min_speed_m_s)

    def predict(self, now: float) -> Prediction:
        """Where it is at `now`, how it moves, and how far the truth may be from it."""
        m, t = self.model, self.last
        age = max(0.0, now - t.time_s)
        fs = self.failsafe_s
        d1 = age if fs is None else min(age, fs)
        pos, vel, phase = self._flown(d1)
        if fs is not None and age > fs:
            pos, vel, phase = self._rtl(pos, age - fs)
        speed = self._speed()
        error = min(
            m.max_error_m, m.base_error_m + (m.growth_m_s + m.growth_fraction * speed) * age
        )
        if phase == "circling":
            error += LOITER_RADIUS_M
        lat, lon, h = geodesy.geodetic(pos[0], pos[1], pos[2], t.lat_deg, t.lon_deg, t.alt_msl_m)
        track = Track(
            t.vehicle_id,
            float(lat),
            float(lon),
            float(h),
            float(vel[1]),
            float(vel[0]),
            float(-vel[2]),
            now,
            t.max_speed_m_s,
            error,
            t.max_accel_m_s2,
        )
        return Prediction(track, phase)

    # ------------------------------------------------------------------ the phases
    def _enu(self, lat: float, lon: float, h_msl: float) -> np.ndarray:
        t = self.last
        return np.asarray(geodesy.enu(lat, lon, h_msl, t.lat_deg, t.lon_deg, t.alt_msl_m), float)

    def _flown(self, d: float) -> tuple[np.ndarray, np.ndarray, str]:
        """`d` seconds on from the last report, as its node left it."""
        t = self.last
        if self.route:
            pts = [np.zeros(3)] + [
                self._enu(la, lo, self.home_msl_m + a) for la, lo, a in self.route
            ]
            pos, vel, done = _walk(pts, self._speed(), d)
            return pos, vel, "held" if done else "route"
        vel = np.array([t.vel_east_m_s, t.vel_north_m_s, -t.vel_down_m_s])
        if self.failsafe_s is None and self.vehicle_type not in (None, VehicleType.PLANE):
            return np.zeros(3), np.zeros(3), "held"  # a rover or a boat: where it was
        return vel * d, vel, "straight"

    def _rtl(self, start: np.ndarray, d: float) -> tuple[np.ndarray, np.ndarray, str]:
        """`d` seconds into its RTL from `start`."""
        target = self.rally
        if target is None and self.home is not None:
            target = (self.home[0], self.home[1], self.home_msl_m)
        if target is None:
            return start, np.zeros(3), "rtl"
        r = self._enu(*target)
        top = max(float(start[2]), float(r[2]))
        over = np.array([r[0], r[1], top])
        pos, vel, done = _walk([start, np.array([start[0], start[1], top]), over], self._speed(), d)
        if not done:
            return pos, vel, "rtl"
        if self.vehicle_type not in LANDS_AT_RALLY:
            return over, np.zeros(3), "circling"
        # how long the way there took: the time spent on it, then the landing
        legs = float(np.linalg.norm(over[:2] - start[:2])) + (top - float(start[2]))
        left = d - legs / self._speed()
        ground = float(self._enu(target[0], target[1], self.home_msl_m)[2])
        z = max(ground, top - self.model.land_speed_m_s * max(left, 0.0))
        if z <= ground:
            return np.array([over[0], over[1], ground]), np.zeros(3), "landed"
        return (
            np.array([over[0], over[1], z]),
            np.array([0.0, 0.0, -self.model.land_speed_m_s]),
            "landing",
        )


def _walk(
    points: Sequence[np.ndarray], speed: float, d: float
) -> tuple[np.ndarray, np.ndarray, bool]:
    """Where `d` seconds at `speed` along the polyline `points` puts it: (position,
    velocity, at its end)."""
    left = speed * d
    for a, b in itertools.pairwise(points):
        seg = b - a
        n = float(np.linalg.norm(seg))
        if n <= 1e-9:
            continue
        if left <= n:
            u = seg / n
            return a + u * left, u * speed, False
        left -= n
    return np.asarray(points[-1], float), np.zeros(3), True
