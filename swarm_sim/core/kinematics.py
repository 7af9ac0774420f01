"""Kinematic vehicle models: point masses with speed, acceleration, turn and climb
limits, stepped with a fixed `dt` towards a `Target` chosen by the autopilot emulation.

- `MultirotorModel`: hovers; accelerates towards the target and brakes to stop on it.
- `FixedWingModel`: never slower than its minimum airspeed in flight, turns at most at
  the bank-limited rate g*tan(bank)/V, climbs and sinks at limited rates, drifts with
  the wind (it holds its ground track by crabbing).
- `VtolModel`: a multirotor in VTOL flight and a fixed-wing in cruise, with forward
  transitions (accelerate to the minimum airspeed, then `transition_time_s`) and back
  transitions (brake on the lift motors).
- `GroundModel`: rover and boat, 2-D, yaw-rate limited.

Pure: no clock, no I/O. Positions are metres north/east of an origin, altitude is metres
above mean sea level.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from enum import IntEnum
from typing import Protocol

from .airframes import AirframeParams, VehicleModel
from .geo import wrap_180, wrap_360

G_M_S2 = 9.80665
HOVER_THROTTLE_PCT = 38.0  # the recorded SITL quad hovered at 36-40 %


class Guide(IntEnum):
    """What the autopilot asks the airframe to do."""

    IDLE = 0  # motors off or at idle: stays on the ground; in the air it falls or glides
    HOLD = 1  # hover here, loiter around here (fixed-wing), or stop (ground vehicles)
    GOTO = 2  # go to (n, e, alt)
    LOITER = 3  # circle (n, e) at `radius` (hover-capable: fly the circle too)
    TAKEOFF = 4  # climb to `alt`: vertically if hover-capable, climb-out if fixed-wing
    LAND = 5  # descend onto (n, e) and touch down
    PARACHUTE = 6  # under a parachute canopy: sink and drift with the wind


class VtolState(IntEnum):
    """MAVLink MAV_VTOL_STATE values."""

    UNDEFINED = 0
    TRANSITION_TO_FW = 1
    TRANSITION_TO_MC = 2
    MC = 3
    FW = 4


@dataclass(frozen=True, slots=True)
class Target:
    kind: Guide
    n: float = 0.0
    e: float = 0.0
    alt: float = 0.0  # metres above mean sea level
    speed: float = 0.0  # 0: the airframe's cruise speed (VTOL flight: its VTOL speed)
    radius: float = 0.0  # LOITER/HOLD circle radius; 0: the airframe's loiter radius
    ccw: bool = False
    fixed_wing: bool = True  # VTOL only: fly this target as an aeroplane
    stop: bool = True  # GOTO: brake to stop on the point (hover-capable and ground)
    climb_rate: float = 0.0  # 0: airframe default
    sink_rate: float = 0.0  # 0: airframe default
    track_from: tuple[float, float] | None = None  # GOTO: fly the line from here


#: Multirotor line following: cross-track speed per metre off the line (1/s).
TRACK_GAIN_1_S = 1.0


class EventKind(IntEnum):
    TOUCHDOWN = 1  # value: vertical speed at contact, m/s
    TRANSITION_STARTED = 2  # value: airspeed
    TRANSITION_AIRSPEED = 3  # value: airspeed
    TRANSITION_DONE = 4
    BACK_TRANSITION_DONE = 5


@dataclass(frozen=True, slots=True)
class ModelEvent:
    kind: EventKind
    value: float = 0.0


@dataclass(slots=True)
class Body:
    """Kinematic state. Velocities are over the ground, north/east/down, m/s."""

    n: float = 0.0
    e: float = 0.0
    alt: float = 0.0
    ground_alt: float = 0.0  # flat terrain at the home altitude
    vn: float = 0.0
    ve: float = 0.0
    vd: float = 0.0
    airspeed: float = 0.0
    heading_deg: float = 0.0
    roll_rad: float = 0.0
    pitch_rad: float = 0.0
    yaw_rate_rad_s: float = 0.0
    on_ground: bool = True
    throttle_pct: float = 0.0
    vtol_state: VtolState = VtolState.UNDEFINED
    transition_s: float = -1.0  # time since the transition airspeed was reached
    wind_n: float = 0.0
    wind_e: float = 0.0
    _prev_vn: float = field(default=0.0, repr=False)
    _prev_ve: float = field(default=0.0, repr=False)

    @property
    def groundspeed(self) -> float:
        return math.hypot(self.vn, self.ve)

    @property
    def height(self) -> float:
        """Metres above the ground."""
        return self.alt - self.ground_alt

    @property
    def climb_rate(self) -> float:
        return -self.vd

    @property
    def course_deg(self) -> float:
        if self.groundspeed < 0.2:
            return self.heading_deg
        return wrap_360(math.degrees(math.atan2(self.ve, self.vn)))


class KinematicModel(Protocol):
    params: AirframeParams

    def step(self, body: Body, target: Target, dt: float) -> list[ModelEvent]: ...


def _clamp(x: float, lo: float, hi: float) -> float:
    return lo if x < lo else hi if x > hi else x


def _limit_vec(dx: float, dy: float, limit: float) -> tuple[float, float]:
    mag = math.hypot(dx, dy)
    if mag <= limit or mag == 0.0:
        return dx, dy
    s = limit / mag
    return dx * s, dy * s


def _touchdown(body: Body, events: list[ModelEvent], keep_horizontal: bool = False) -> None:
    impact = max(0.0, body.vd)
    body.alt = body.ground_alt
    body.vd = 0.0
    body.on_ground = True
    if not keep_horizontal:
        body.vn = body.ve = 0.0
    body.roll_rad = body.pitch_rad = 0.0
    events.append(ModelEvent(EventKind.TOUCHDOWN, impact))


def _fall(body: Body, dt: float, events: list[ModelEvent]) -> None:
    """Unpowered in the air: ballistic with drag, until the ground."""
    body.vd = min(body.vd + G_M_S2 * dt, 40.0)
    decay = math.exp(-0.3 * dt)
    body.vn = body.wind_n + (body.vn - body.wind_n) * decay
    body.ve = body.wind_e + (body.ve - body.wind_e) * decay
    _integrate(body, dt)
    body.throttle_pct = 0.0
    if body.alt <= body.ground_alt:
        _touchdown(body, events)


def _parachute(body: Body, sink: float, dt: float, events: list[ModelEvent]) -> None:
    body.vd += _clamp(sink - body.vd, -G_M_S2 * dt, G_M_S2 * dt)
    decay = math.exp(-1.0 * dt)
    body.vn = body.wind_n + (body.vn - body.wind_n) * decay
    body.ve = body.wind_e + (body.ve - body.wind_e) * decay
    body.throttle_pct = 0.0
    _integrate(body, dt)
    if body.alt <= body.ground_alt:
        _touchdown(body, events)


def _integrate(body: Body, dt: float) -> None:
    body.n += body.vn * dt
    body.e += body.ve * dt
    body.alt -= body.vd * dt


def _vertical(body: Body, alt_target: float, climb: float, sink: float, dt: float) -> None:
    """Track `alt_target` with a 1/s altitude loop, rate- and acceleration-limited."""
    vz_want = _clamp((alt_target - body.alt) * 1.0, -sink, climb)
    vz = -body.vd
    vz += _clamp(vz_want - vz, -2.5 * dt, 2.5 * dt)
    body.vd = -vz


LEAN_MAX_DEG = 30.0  # hover-capable vehicles' lean limit (ANGLE_MAX, Q_ANGLE_MAX defaults)


def _hover_attitude(body: Body, dt: float) -> None:
    """Tilt from the horizontal acceleration and the air drag (cosmetic, for ATTITUDE)."""
    if dt <= 0:
        return
    an = (body.vn - body._prev_vn) / dt
    ae = (body.ve - body._prev_ve) / dt
    body._prev_vn, body._prev_ve = body.vn, body.ve
    van, vae = body.vn - body.wind_n, body.ve - body.wind_e
    body.airspeed = math.hypot(van, vae)
    an += 0.03 * van * abs(van)
    ae += 0.03 * vae * abs(vae)
    h = math.radians(body.heading_deg)
    fwd = an * math.cos(h) + ae * math.sin(h)
    right = -an * math.sin(h) + ae * math.cos(h)
    # ArduCopter's ANGLE_MAX and a QuadPlane's Q_ANGLE_MAX (30 degrees by default): a
    # VTOL slowing on its lift motors from wing speed leans no further (its wing still
    # carries it), and the first step after the wing model (an old previous speed)
    # does not read as a dive
    lim = math.radians(LEAN_MAX_DEG)
    body.pitch_rad = _clamp(-math.atan2(fwd, G_M_S2), -lim, lim)
    body.roll_rad = _clamp(math.atan2(right, G_M_S2), -lim, lim)


def _yaw_towards(body: Body, heading_want: float, rate_deg_s: float, dt: float) -> None:
    err = wrap_180(heading_want - body.heading_deg)
    step = _clamp(err, -rate_deg_s * dt, rate_deg_s * dt)
    body.yaw_rate_rad_s = math.radians(step / dt) if dt > 0 else 0.0
    body.heading_deg = wrap_360(body.heading_deg + step)


class MultirotorModel:
    """Hover-capable flight (a copter, or a QuadPlane on its lift motors)."""

    def __init__(
        self,
        params: AirframeParams,
        *,
        speed: float | None = None,
        climb: float | None = None,
        sink: float | None = None,
    ) -> None:
        self.params = params
        self.speed = speed if speed is not None else params.cruise_speed_m_s
        self.climb = climb if climb is not None else params.climb_rate_m_s
        self.sink = sink if sink is not None else params.sink_rate_m_s

    def step(self, body: Body, target: Target, dt: float) -> list[ModelEvent]:
        events: list[ModelEvent] = []
        p = self.params
        kind = target.kind
        if kind == Guide.PARACHUTE:
            _parachute(body, p.parachute_sink_m_s, dt, events)
            return events
        if kind == Guide.IDLE:
            if body.on_ground:
                body.vn = body.ve = body.vd = 0.0
                body.throttle_pct = 0.0
                body.airspeed = math.hypot(body.wind_n, body.wind_e)
            else:
                _fall(body, dt, events)
            return events
        if body.on_ground and kind != Guide.TAKEOFF and target.alt <= body.ground_alt + 0.5:
            body.vn = body.ve = body.vd = 0.0
            body.throttle_pct = 15.0
            return events
        speed = target.speed if target.speed > 0 else self.speed
        climb = target.climb_rate if target.climb_rate > 0 else self.climb
        sink = target.sink_rate if target.sink_rate > 0 else self.sink
        tn, te, talt = target.n, target.e, target.alt
        stop = target.stop
        if kind == Guide.LOITER and target.radius > 0.5:
            tn, te = self._circle_point(body, target, speed)
            stop = False
        elif kind == Guide.TAKEOFF:
            tn, te = body.n, body.e
            speed = 0.0
        elif kind == Guide.LAND:
            talt = body.ground_alt - 1.0
            sink = p.land_speed_m_s if body.height <= p.land_final_alt_m else sink
            if math.hypot(tn - body.n, te - body.e) > 2.0:
                talt = body.alt  # reposition over the landing point first
        # horizontal
        dn, de = tn - body.n, te - body.e
        dist = math.hypot(dn, de)
        vmax = min(speed, math.sqrt(2.0 * p.accel_m_s2 * dist), 1.0 * dist) if stop else speed
        tracked = (
            self._track_velocity(body, target, vmax) if kind == Guide.GOTO and dist > 0.5 else None
        )
        if tracked is not None:
            # back to the line first: the correction across it takes the acceleration
            # it needs, the speed along it what is left
            (vn_want, ve_want), (un, ue) = tracked
            dv_n, dv_e = vn_want - body.vn, ve_want - body.ve
            d_along = dv_n * un + dv_e * ue
            d_cross = -dv_n * ue + dv_e * un
            budget = p.accel_m_s2 * dt
            d_cross = _clamp(d_cross, -budget, budget)
            rest = math.sqrt(max(budget * budget - d_cross * d_cross, 0.0))
            d_along = _clamp(d_along, -rest, rest)
            dvn, dve = un * d_along - ue * d_cross, ue * d_along + un * d_cross
        else:
            if dist > 1e-6:
                vn_want, ve_want = dn / dist * vmax, de / dist * vmax
            else:
                vn_want = ve_want = 0.0
            dvn, dve = _limit_vec(vn_want - body.vn, ve_want - body.ve, p.accel_m_s2 * dt)
        body.vn += dvn
        body.ve += dve
        # vertical
        if kind == Guide.LAND and talt < body.alt - 1e-3 and talt < body.ground_alt:
            vz = -body.vd
            vz += _clamp(-sink - vz, -2.5 * dt, 2.5 * dt)
            body.vd = -vz
        else:
            _vertical(body, talt, climb, sink, dt)
        if body.on_ground and body.vd < 0:
            body.on_ground = False
        _integrate(body, dt)
        if body.groundspeed > 1.0:
            _yaw_towards(body, body.course_deg, p.turn_rate_deg_s, dt)
        else:
            body.yaw_rate_rad_s = 0.0
        _hover_attitude(body, dt)
        body.throttle_pct = _clamp(HOVER_THROTTLE_PCT * (1.0 - 0.04 * body.vd), 10.0, 100.0)
        if not body.on_ground and body.alt <= body.ground_alt:
            _touchdown(body, events)
        return events

    def _track_velocity(
        self, body: Body, target: Target, vmax: float
    ) -> tuple[tuple[float, float], tuple[float, float]] | None:
        """ArduCopter's position controller flies the line from `track_from` to the
        target (AC_WPNav), not straight at the target from wherever it is: the velocity
        along the line (`vmax`, braking as it nears the point) plus a correction back to
        the line that brakes to zero on it (no overshoot). The leg after a corner thus
        starts about WPNAV_RADIUS off its line (the previous point was reached that far
        before the corner) and the copter rejoins it on the inside of the corner: the
        recorded `copter-corner-cutting` flights pass 1.1-1.2 m from each 90-degree
        corner, 0.8-0.9 m off the planned lines, with up to 1.4-1.6 m of cross-track
        just after a corner. Returns (velocity wanted, unit vector of the line); None: no
        line to follow (or past its end)."""
        if target.track_from is None:
            return None
        fn, fe = target.track_from
        ln, le = target.n - fn, target.e - fe
        length = math.hypot(ln, le)
        if length < 1.0:
            return None
        un, ue = ln / length, le / length
        to_n, to_e = target.n - body.n, target.e - body.e
        along_left = to_n * un + to_e * ue  # along the line, to the end
        if along_left <= 0.0:
            return None
        cross = -(body.n - fn) * ue + (body.e - fe) * un  # right of the line: positive
        a = self.params.accel_m_s2
        v_cross = min(TRACK_GAIN_1_S * abs(cross), math.sqrt(2.0 * a * abs(cross)), vmax)
        v_cross = -math.copysign(v_cross, cross)
        v_along = math.sqrt(max(vmax * vmax - v_cross * v_cross, 0.0))
        return (un * v_along - ue * v_cross, ue * v_along + un * v_cross), (un, ue)

    @staticmethod
    def _circle_point(body: Body, target: Target, speed: float) -> tuple[float, float]:
        """A point ahead on the circle, so the controller flies around it."""
        ang = math.atan2(body.e - target.e, body.n - target.n)
        lead = min(1.0, speed * 1.0 / max(target.radius, 1.0))
        ang += -lead if target.ccw else lead
        return target.n + target.radius * math.cos(ang), target.e + target.radius * math.sin(ang)


class FixedWingModel:
    """Fixed-wing flight: bank-limited turns, airspeed never below the minimum in flight."""

    def __init__(self, params: AirframeParams) -> None:
        self.params = params

    def turn_rate_max_rad_s(self, airspeed: float) -> float:
        return G_M_S2 * math.tan(math.radians(self.params.max_bank_deg)) / max(airspeed, 1.0)

    def step(self, body: Body, target: Target, dt: float) -> list[ModelEvent]:
        events: list[ModelEvent] = []
        p = self.params
        kind = target.kind
        if kind == Guide.PARACHUTE:
            body.airspeed = 0.0
            _parachute(body, p.parachute_sink_m_s, dt, events)
            return events
        if body.on_ground:
            return self._ground_step(body, target, dt, events)
        if kind == Guide.IDLE:
            return self._glide(body, dt, events)
        # desired course, airspeed and altitude
        speed_want = _clamp(
            target.speed if target.speed > 0 else p.cruise_speed_m_s,
            p.min_airspeed_m_s,
            p.max_speed_m_s,
        )
        alt_want = target.alt
        sink = target.sink_rate if target.sink_rate > 0 else p.sink_rate_m_s
        climb = target.climb_rate if target.climb_rate > 0 else p.climb_rate_m_s
        dn, de = target.n - body.n, target.e - body.e
        dist = math.hypot(dn, de)
        if kind in (Guide.LOITER, Guide.HOLD):
            radius = target.radius if target.radius > 0 else max(p.loiter_radius_m, 10.0)
            course_want = self._loiter_course(body, target, radius)
        elif kind == Guide.TAKEOFF:
            course_want = body.heading_deg
        elif kind == Guide.LAND:
            course_want = math.degrees(math.atan2(de, dn)) if dist > 60.0 else body.course_deg
            speed_want = p.min_airspeed_m_s
            alt_want = body.ground_alt + max(0.0, dist - 20.0) * 0.08
            alt_want = min(alt_want, body.alt)
        else:
            course_want = self._track_course(body, target, dist)
        # airspeed
        body.airspeed += _clamp(speed_want - body.airspeed, -2.0 * dt, 2.0 * dt)
        body.airspeed = max(body.airspeed, p.min_airspeed_m_s)
        # heading: hold the ground course by crabbing into the wind
        heading_want = self._heading_for_course(body, course_want)
        err = math.radians(wrap_180(heading_want - body.heading_deg))
        wmax = self.turn_rate_max_rad_s(body.airspeed)
        rate = _clamp(1.0 * err, -wmax, wmax)
        body.yaw_rate_rad_s += _clamp(rate - body.yaw_rate_rad_s, -1.0 * dt, 1.0 * dt)
        body.heading_deg = wrap_360(body.heading_deg + math.degrees(body.yaw_rate_rad_s * dt))
        body.roll_rad = math.atan(body.airspeed * body.yaw_rate_rad_s / G_M_S2)
        # vertical
        if kind == Guide.LAND and body.height < 0.5:
            body.vd = 0.5
        else:
            _vertical(body, alt_want, climb, sink, dt)
        h = math.radians(body.heading_deg)
        body.vn = body.airspeed * math.cos(h) + body.wind_n
        body.ve = body.airspeed * math.sin(h) + body.wind_e
        body.pitch_rad = math.asin(_clamp(-body.vd / max(body.airspeed, 1.0), -0.5, 0.5)) + 0.03
        _integrate(body, dt)
        body.throttle_pct = _clamp(
            65.0 * (body.airspeed / p.cruise_speed_m_s) ** 2 + 8.0 * -body.vd, 0.0, 100.0
        )
        if body.alt <= body.ground_alt:
            _touchdown(body, events, keep_horizontal=True)
            body.airspeed = math.hypot(body.vn - body.wind_n, body.ve - body.wind_e)
        return events

    def _ground_step(
        self, body: Body, target: Target, dt: float, events: list[ModelEvent]
    ) -> list[ModelEvent]:
        p = self.params
        rolling = target.kind in (Guide.TAKEOFF, Guide.GOTO, Guide.LOITER, Guide.HOLD)
        rolling = rolling and target.alt > body.ground_alt + 1.0
        h = math.radians(body.heading_deg)
        gs = body.vn * math.cos(h) + body.ve * math.sin(h)
        if rolling:
            gs += 3.0 * dt  # take-off run or catapult
            body.throttle_pct = 100.0
        else:
            gs = max(0.0, gs - 3.0 * dt)  # roll-out
            body.throttle_pct = 0.0
        body.vn, body.ve = gs * math.cos(h), gs * math.sin(h)
        body.airspeed = max(0.0, gs)
        body.vd = 0.0
        _integrate(body, dt)
        body.alt = body.ground_alt
        if rolling and body.airspeed >= p.min_airspeed_m_s:
            body.on_ground = False
            body.vd = -min(p.climb_rate_m_s, 1.0)
        return events

    def _glide(self, body: Body, dt: float, events: list[ModelEvent]) -> list[ModelEvent]:
        p = self.params
        body.airspeed = max(p.stall_speed_m_s, body.airspeed - 1.0 * dt)
        body.yaw_rate_rad_s = 0.0
        body.roll_rad = 0.0
        body.vd += _clamp(p.sink_rate_m_s * 0.5 - body.vd, -1.0 * dt, 1.0 * dt)
        h = math.radians(body.heading_deg)
        body.vn = body.airspeed * math.cos(h) + body.wind_n
        body.ve = body.airspeed * math.sin(h) + body.wind_e
        body.throttle_pct = 0.0
        _integrate(body, dt)
        if body.alt <= body.ground_alt:
            _touchdown(body, events, keep_horizontal=True)
        return events

    @staticmethod
    def _track_course(body: Body, target: Target, dist: float) -> float:
        """Course to the target along the line from `track_from` (L1-style: aim at the
        point of the line one L1 distance ahead), or straight at it."""
        if dist <= 1.0:
            return body.course_deg
        l1 = max(60.0, 3.0 * body.airspeed)
        if target.track_from is not None and dist > l1:
            fn, fe = target.track_from
            tn, te = target.n - fn, target.e - fe
            length = math.hypot(tn, te)
            if length > 1.0:
                un, ue = tn / length, te / length
                along = (body.n - fn) * un + (body.e - fe) * ue
                cross = -(body.n - fn) * ue + (body.e - fe) * un
                if abs(cross) < l1:
                    ahead = along + math.sqrt(l1 * l1 - cross * cross)
                    if ahead < length:
                        an, ae = fn + un * ahead, fe + ue * ahead
                        return math.degrees(math.atan2(ae - body.e, an - body.n))
        return math.degrees(math.atan2(target.e - body.e, target.n - body.n))

    @staticmethod
    def _loiter_course(body: Body, target: Target, radius: float) -> float:
        """Tangent to the circle, bent towards it in proportion to the radial error."""
        dn, de = body.n - target.n, body.e - target.e
        d = math.hypot(dn, de)
        outward = math.degrees(math.atan2(de, dn))
        if d > 3.0 * radius:
            return wrap_360(outward + 180.0)
        correction = math.degrees(math.atan((d - radius) / (0.5 * radius)))
        if target.ccw:
            return wrap_360(outward - 90.0 - correction)
        return wrap_360(outward + 90.0 + correction)

    @staticmethod
    def _heading_for_course(body: Body, course_deg: float) -> float:
        wind = math.hypot(body.wind_n, body.wind_e)
        if wind < 0.1 or body.airspeed < 1.0:
            return course_deg
        c = math.radians(course_deg)
        cross = -body.wind_n * math.sin(c) + body.wind_e * math.cos(c)
        return wrap_360(course_deg - math.degrees(math.asin(_clamp(cross / body.airspeed, -1, 1))))


class VtolModel:
    """A QuadPlane: lift motors for VTOL flight, wings for cruise, and the transitions."""

    def __init__(self, params: AirframeParams) -> None:
        self.params = params
        self.hover = MultirotorModel(
            params,
            speed=params.vtol_speed_m_s,
            climb=params.vtol_climb_rate_m_s,
            sink=params.vtol_sink_rate_m_s,
        )
        self.wing = FixedWingModel(params)

    def step(self, body: Body, target: Target, dt: float) -> list[ModelEvent]:
        p = self.params
        if body.vtol_state == VtolState.UNDEFINED:
            body.vtol_state = VtolState.MC
        want_fw = (
            target.fixed_wing
            and target.kind in (Guide.GOTO, Guide.LOITER, Guide.HOLD)
            and not body.on_ground
        )
        state = body.vtol_state
        if target.kind in (Guide.IDLE, Guide.PARACHUTE):
            if state == VtolState.FW and target.kind == Guide.IDLE:
                return self.wing.step(body, target, dt)
            return self.hover.step(body, target, dt)
        if state == VtolState.FW:
            if want_fw:
                return self.wing.step(body, target, dt)
            body.vtol_state = VtolState.TRANSITION_TO_MC
            state = body.vtol_state
        if state == VtolState.TRANSITION_TO_MC:
            events = self.hover.step(body, target, dt)
            body.airspeed = math.hypot(body.vn - body.wind_n, body.ve - body.wind_e)
            if body.groundspeed <= p.vtol_speed_m_s + 0.5:
                body.vtol_state = VtolState.MC
                events.append(ModelEvent(EventKind.BACK_TRANSITION_DONE))
            if want_fw:
                body.vtol_state = VtolState.FW
            return events
        if state == VtolState.MC:
            if want_fw and body.height >= 5.0:
                body.vtol_state = VtolState.TRANSITION_TO_FW
                body.transition_s = -1.0
                air = math.hypot(body.vn - body.wind_n, body.ve - body.wind_e)
                body.airspeed = air
                return [
                    ModelEvent(EventKind.TRANSITION_STARTED, air),
                    *self._forward(body, target, dt),
                ]
            return self.hover.step(body, target, dt)
        # TRANSITION_TO_FW
        if not want_fw:
            body.vtol_state = VtolState.TRANSITION_TO_MC
            return self.hover.step(body, target, dt)
        return self._forward(body, target, dt)

    def _forward(self, body: Body, target: Target, dt: float) -> list[ModelEvent]:
        """Forward transition: accelerate on the wing while the lift motors hold height."""
        p = self.params
        events: list[ModelEvent] = []
        course_want = math.degrees(math.atan2(target.e - body.e, target.n - body.n))
        _yaw_towards(body, course_want, 15.0, dt)
        body.airspeed = min(body.airspeed + p.transition_accel_m_s2 * dt, p.cruise_speed_m_s)
        h = math.radians(body.heading_deg)
        body.vn = body.airspeed * math.cos(h) + body.wind_n
        body.ve = body.airspeed * math.sin(h) + body.wind_e
        _vertical(body, body.alt, p.vtol_climb_rate_m_s, p.vtol_sink_rate_m_s, dt)
        _integrate(body, dt)
        body.roll_rad = 0.0
        body.pitch_rad = -0.05
        body.throttle_pct = 90.0
        if body.transition_s < 0.0:
            if body.airspeed >= p.min_airspeed_m_s:
                body.transition_s = 0.0
                events.append(ModelEvent(EventKind.TRANSITION_AIRSPEED, body.airspeed))
        else:
            body.transition_s += dt
            if body.transition_s >= p.transition_time_s:
                body.vtol_state = VtolState.FW
                body.transition_s = -1.0
                events.append(ModelEvent(EventKind.TRANSITION_DONE))
        return events


class GroundModel:
    """Rover or boat: 2-D, yaw-rate limited, slows down for turns and to stop on a point."""

    def __init__(self, params: AirframeParams) -> None:
        self.params = params

    def step(self, body: Body, target: Target, dt: float) -> list[ModelEvent]:
        p = self.params
        h = math.radians(body.heading_deg)
        speed = body.vn * math.cos(h) + body.ve * math.sin(h)
        speed_want = 0.0
        if target.kind in (Guide.GOTO, Guide.LOITER):
            dn, de = target.n - body.n, target.e - body.e
            dist = math.hypot(dn, de)
            radius = target.radius if target.kind == Guide.LOITER else 0.0
            if dist > max(radius, 0.3):
                bearing = math.degrees(math.atan2(de, dn))
                err = wrap_180(bearing - body.heading_deg)
                _yaw_towards(body, bearing, p.turn_rate_deg_s, dt)
                cruise = target.speed if target.speed > 0 else p.cruise_speed_m_s
                speed_want = cruise * max(0.0, math.cos(math.radians(min(abs(err), 90.0))))
                if abs(err) > 60.0 and p.model == VehicleModel.BOAT:
                    # boats cannot pivot: turn on a circle small enough to reach the point
                    omega = math.radians(p.turn_rate_deg_s)
                    speed_want = min(0.3 * cruise, 0.5 * dist * omega)
                if target.stop or radius > 0:
                    speed_want = min(speed_want, math.sqrt(2.0 * p.accel_m_s2 * dist), dist)
        if speed_want == 0.0:
            body.yaw_rate_rad_s = 0.0
        speed += _clamp(speed_want - speed, -p.accel_m_s2 * dt, p.accel_m_s2 * dt)
        h = math.radians(body.heading_deg)
        body.vn, body.ve, body.vd = speed * math.cos(h), speed * math.sin(h), 0.0
        _integrate(body, dt)
        body.alt = body.ground_alt
        body.on_ground = True
        body.airspeed = speed
        body.roll_rad = body.pitch_rad = 0.0
        body.throttle_pct = _clamp(100.0 * abs(speed) / max(p.max_speed_m_s, 0.1), 0.0, 100.0)
        return []


def make_model(params: AirframeParams) -> KinematicModel:
    """The kinematic model of an airframe."""
    if params.model == VehicleModel.COPTER:
        return MultirotorModel(params)
    if params.model == VehicleModel.VTOL:
        return VtolModel(params)
    if params.model == VehicleModel.PLANE:
        return FixedWingModel(params)
    return GroundModel(params)
