"""Navigation tasks: what a mode or a mission item asks of the airframe, step by step.

A task turns the vehicle state into a kinematic `Target` every physics step and says
when it is done. Modes and mission items are mapped to tasks by the autopilot emulation
(`autopilot.py`); composite behaviours (copter RTL: climb, return, loiter, land) are
`Sequence`s of simple tasks.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from enum import IntEnum
from typing import Protocol

from .kinematics import Body, Guide, Target

#: The radius of the turn ArduCopter flies at a corner between two AUTO waypoints, fitted
#: to the recorded `copter-corner-cutting` flights (WPNAV_SPEED 10 m/s, WPNAV_ACCEL
#: 2.5 m/s^2, WPNAV_JERK 1 m/s^3, WPNAV_RADIUS 2 m): 90-degree corners passed 1.1-1.2 m
#: away on their inside, 0.8-0.9 m off the planned lines (a 2.9 m arc passes 1.2 m from
#: the corner and 0.85 m from the lines).
COPTER_CORNER_RADIUS_M = 3.4
#: Sharper turns than this are flown by braking to the point (no rounding).
COPTER_ROUNDED_TURN_MAX_RAD = math.radians(100.0)


class Purpose(IntEnum):
    """Why the current navigation task runs (decides what happens when it completes)."""

    MODE = 0
    MISSION = 1
    GUIDED_GOTO = 2
    GUIDED_TAKEOFF = 3
    GUIDED_VELOCITY = 4


class NavContext(Protocol):
    """What tasks read from the autopilot."""

    @property
    def body(self) -> Body: ...
    @property
    def hover_capable(self) -> bool: ...
    @property
    def fixed_wing(self) -> bool: ...
    @property
    def wp_speed(self) -> float: ...
    @property
    def wp_accel(self) -> float: ...
    @property
    def loiter_radius(self) -> float: ...


class NavTask:
    """Base class: holds the vehicle where it is."""

    name = "task"

    def target(self, ctx: NavContext) -> Target:
        b = ctx.body
        return Target(Guide.HOLD, b.n, b.e, b.alt)

    def update(self, ctx: NavContext, dt: float) -> bool:
        """Advance by `dt`; True once the task is complete."""
        return False

    @property
    def destination(self) -> tuple[float, float, float] | None:
        """(n, e, alt) the task is heading for, if any (for NAV_CONTROLLER_OUTPUT)."""
        return None


@dataclass
class Idle(NavTask):
    """Motors off (or at ground idle)."""

    name = "idle"

    def target(self, ctx: NavContext) -> Target:
        return Target(Guide.IDLE)


@dataclass
class Hold(NavTask):
    """Hover, stop, or (fixed-wing) loiter around a point."""

    n: float
    e: float
    alt: float
    vtol: bool = False  # QuadPlane: hold on the lift motors
    radius: float = 0.0
    ccw: bool = False
    time_s: float | None = None  # done after this long (None: never)
    elapsed_s: float = 0.0
    name = "hold"

    def target(self, ctx: NavContext) -> Target:
        return Target(
            Guide.HOLD,
            self.n,
            self.e,
            self.alt,
            radius=self.radius,
            ccw=self.ccw,
            fixed_wing=not self.vtol,
        )

    def update(self, ctx: NavContext, dt: float) -> bool:
        self.elapsed_s += dt
        return self.time_s is not None and self.elapsed_s >= self.time_s

    @property
    def destination(self) -> tuple[float, float, float] | None:
        return self.n, self.e, self.alt


@dataclass
class FlyTo(NavTask):
    """Go to a point; done within `accept_m` (hover-capable: also within 2 m of height)
    or, for fixed-wing, once past the line through the point square to the track.

    A fixed-wing's track starts at `origin` (the previous waypoint) unless that gives no
    track: ArduPlane's `set_next_WP` flies from where the aircraft is when the previous
    waypoint is the point itself (`Location::line_path_proportion` reads two coincident
    points as passed). That happens when the same item is started again: a mission
    uploaded in AUTO restarts its current index, then DO_SET_MISSION_CURRENT starts it
    once more. Without a track the point could only be reached within `accept_m`, and an
    aircraft that had flown past it, its turn circle wider than that, circled it for
    ever (a demo VTOL until BATTERY_LOW)."""

    n: float
    e: float
    alt: float
    accept_m: float
    speed: float = 0.0
    stop: bool = True
    vtol: bool = False
    hold_s: float = 0.0  # wait at the point (copter/rover NAV_WAYPOINT param1)
    origin: tuple[float, float] | None = None
    next_ne: tuple[float, float] | None = None  # copter: the next waypoint, to round the corner
    reached: bool = False
    reached_dist_m: float = 0.0
    held_s: float = 0.0
    name = "flyto"

    def _no_track(self, ctx: NavContext) -> None:
        """ArduPlane's set_next_WP: no track from a previous waypoint on the point itself;
        the aircraft flies from where it is."""
        if (
            ctx.fixed_wing
            and not self.vtol
            and self.origin is not None
            and math.hypot(self.n - self.origin[0], self.e - self.origin[1]) < 1.0
        ):
            self.origin = (ctx.body.n, ctx.body.e)

    def target(self, ctx: NavContext) -> Target:
        self._no_track(ctx)
        speed = self.speed if self.speed > 0 else ctx.wp_speed
        if self.vtol:
            speed = 0.0  # the VTOL speed
        corner = self._corner(ctx, speed)
        if corner is not None:
            return corner
        return Target(
            Guide.GOTO,
            self.n,
            self.e,
            self.alt,
            speed=speed,
            stop=self.stop,
            fixed_wing=not self.vtol,
            track_from=self.origin,
        )

    def _corner(self, ctx: NavContext, speed: float) -> Target | None:
        """A multirotor in AUTO with another waypoint after this one does not stop at
        the corner (ArduCopter's S-curves): it slows to the speed of a turn of
        COPTER_CORNER_RADIUS_M and rounds the corner on its inside, following the next
        leg from where the turn begins."""
        if self.next_ne is None or self.origin is None or ctx.fixed_wing or self.hold_s > 0:
            return None
        b = ctx.body
        in_n, in_e = self.n - self.origin[0], self.e - self.origin[1]
        out_n, out_e = self.next_ne[0] - self.n, self.next_ne[1] - self.e
        len_in, len_out = math.hypot(in_n, in_e), math.hypot(out_n, out_e)
        if len_in < 1.0 or len_out < 1.0:
            return None
        cos_t = (in_n * out_n + in_e * out_e) / (len_in * len_out)
        turn = math.acos(max(-1.0, min(1.0, cos_t)))
        if not math.radians(5.0) <= turn <= COPTER_ROUNDED_TURN_MAX_RAD:
            return None  # nearly straight on, or a sharp turn: it brakes to the point
        accel = max(ctx.wp_accel, 0.5)
        tangent = min(COPTER_CORNER_RADIUS_M * math.tan(turn / 2.0), 0.5 * len_in, 0.5 * len_out)
        left = ((self.n - b.n) * in_n + (self.e - b.e) * in_e) / len_in  # along, to the corner
        if left <= tangent:  # in the turn: follow the next leg
            return Target(
                Guide.GOTO,
                self.next_ne[0],
                self.next_ne[1],
                self.alt,
                speed=speed,
                stop=False,
                fixed_wing=False,
                track_from=(self.n, self.e),
            )
        # brake to the turn's speed at the start of the turn
        v_turn = math.sqrt(accel * COPTER_CORNER_RADIUS_M)
        v = min(speed, math.sqrt(v_turn * v_turn + 2.0 * accel * (left - tangent)))
        return Target(
            Guide.GOTO,
            self.n,
            self.e,
            self.alt,
            speed=v,
            stop=False,
            fixed_wing=False,
            track_from=self.origin,
        )

    def update(self, ctx: NavContext, dt: float) -> bool:
        b = ctx.body
        self._no_track(ctx)
        if self.origin is None:
            self.origin = (b.n, b.e)
        if not self.reached:
            dist = math.hypot(self.n - b.n, self.e - b.e)
            if ctx.fixed_wing and not self.vtol:
                on_point = dist <= self.accept_m or self._passed(b)
            else:
                on_point = dist <= self.accept_m and abs(self.alt - b.alt) <= 2.0
                if self.next_ne is not None and self.hold_s <= 0 and abs(self.alt - b.alt) <= 2.0:
                    on_point = on_point or self._passed(b)  # a rounded corner, passed
            if on_point:
                self.reached = True
                self.reached_dist_m = dist
        if self.reached:
            self.held_s += dt
            return self.held_s >= self.hold_s
        return False

    def _passed(self, b: Body) -> bool:
        assert self.origin is not None
        tn, te = self.n - self.origin[0], self.e - self.origin[1]
        if math.hypot(tn, te) < 1.0:
            return False
        return (b.n - self.n) * tn + (b.e - self.e) * te > 0.0

    @property
    def destination(self) -> tuple[float, float, float] | None:
        return self.n, self.e, self.alt


@dataclass
class Loiter(NavTask):
    """Fly to a point and circle it (hover-capable vehicles with radius 0 hover on it);
    done after `turns` circles or `time_s` seconds there, or never."""

    n: float
    e: float
    alt: float
    radius: float = 0.0
    ccw: bool = False
    turns: float | None = None
    time_s: float | None = None
    vtol: bool = False
    arrived: bool = False
    elapsed_s: float = 0.0
    angle_rad: float = 0.0
    _last_bearing: float | None = None
    name = "loiter"

    def target(self, ctx: NavContext) -> Target:
        if not self.arrived and not ctx.fixed_wing and self.radius <= 0.5:
            return Target(Guide.GOTO, self.n, self.e, self.alt, speed=ctx.wp_speed, stop=True)
        if ctx.fixed_wing and not self.vtol:
            radius = self.radius if self.radius > 0 else ctx.loiter_radius
            # ArduPlane loiters at the target airspeed DO_CHANGE_SPEED set, as it flies legs
            return Target(
                Guide.LOITER,
                self.n,
                self.e,
                self.alt,
                speed=ctx.wp_speed,
                radius=radius,
                ccw=self.ccw,
            )
        kind = Guide.LOITER if self.radius > 0.5 else Guide.HOLD
        return Target(
            kind,
            self.n,
            self.e,
            self.alt,
            speed=min(ctx.wp_speed, 5.0),
            radius=self.radius,
            ccw=self.ccw,
            fixed_wing=not self.vtol,
        )

    def update(self, ctx: NavContext, dt: float) -> bool:
        b = ctx.body
        radius = self.radius if self.radius > 0 else (ctx.loiter_radius if ctx.fixed_wing else 0.0)
        dist = math.hypot(self.n - b.n, self.e - b.e)
        if not self.arrived:
            near = dist <= max(radius * 1.2, radius + 10.0, 2.0)
            if near and abs(self.alt - b.alt) <= 5.0:
                self.arrived = True
                self._last_bearing = math.atan2(b.e - self.e, b.n - self.n)
            return False
        self.elapsed_s += dt
        bearing = math.atan2(b.e - self.e, b.n - self.n)
        if self._last_bearing is not None and dist > 0.5:
            step = (bearing - self._last_bearing + math.pi) % (2 * math.pi) - math.pi
            self.angle_rad += abs(step)
        self._last_bearing = bearing
        if self.turns is not None:
            if radius > 0.5:
                return self.angle_rad >= self.turns * 2 * math.pi
            # hovering on the spot: ArduCopter spins once per turn; take 1 turn = 10 s
            return self.elapsed_s >= self.turns * 10.0
        if self.time_s is not None:
            return self.elapsed_s >= self.time_s
        return False

    @property
    def destination(self) -> tuple[float, float, float] | None:
        return self.n, self.e, self.alt


@dataclass
class Takeoff(NavTask):
    """Climb to `alt`: vertically for hover-capable vehicles, straight ahead for planes."""

    alt: float
    vtol: bool = True
    n: float | None = None
    e: float | None = None
    name = "takeoff"

    def target(self, ctx: NavContext) -> Target:
        b = ctx.body
        if self.n is None or self.e is None:
            self.n, self.e = b.n, b.e
        return Target(Guide.TAKEOFF, self.n, self.e, self.alt, fixed_wing=not self.vtol)

    def update(self, ctx: NavContext, dt: float) -> bool:
        b = ctx.body
        return not b.on_ground and b.alt >= self.alt - (0.5 if self.vtol else 2.0)

    @property
    def destination(self) -> tuple[float, float, float] | None:
        b_n = self.n if self.n is not None else 0.0
        b_e = self.e if self.e is not None else 0.0
        return b_n, b_e, self.alt


@dataclass
class Land(NavTask):
    """Land on (n, e): vertically (hover-capable, VTOL) or on a glide slope (fixed-wing)."""

    n: float
    e: float
    vtol: bool = True
    settle_s: float = 1.0  # on the ground and stopped this long: land complete
    touched_down: bool = False
    settled_s: float = 0.0
    name = "land"

    def target(self, ctx: NavContext) -> Target:
        return Target(Guide.LAND, self.n, self.e, ctx.body.ground_alt, fixed_wing=not self.vtol)

    def update(self, ctx: NavContext, dt: float) -> bool:
        b = ctx.body
        if b.on_ground:
            self.touched_down = True
        if self.touched_down and b.on_ground and b.groundspeed < 0.5:
            self.settled_s += dt
        return self.settled_s >= self.settle_s

    @property
    def destination(self) -> tuple[float, float, float] | None:
        return self.n, self.e, 0.0


@dataclass
class Sequence(NavTask):
    """Sub-tasks one after the other; done when the last one is."""

    tasks: list[NavTask] = field(default_factory=list)
    index: int = 0
    name = "sequence"

    @property
    def current(self) -> NavTask | None:
        return self.tasks[self.index] if self.index < len(self.tasks) else None

    def target(self, ctx: NavContext) -> Target:
        task = self.current
        if task is None:
            task = self.tasks[-1] if self.tasks else NavTask()
        return task.target(ctx)

    def update(self, ctx: NavContext, dt: float) -> bool:
        while self.index < len(self.tasks):
            if not self.tasks[self.index].update(ctx, dt):
                return False
            self.index += 1
            dt = 0.0
        return True

    @property
    def destination(self) -> tuple[float, float, float] | None:
        task = self.current
        return task.destination if task is not None else None


@dataclass
class Parachute(NavTask):
    """Under canopy until on the ground."""

    name = "parachute"

    def target(self, ctx: NavContext) -> Target:
        return Target(Guide.PARACHUTE)

    def update(self, ctx: NavContext, dt: float) -> bool:
        return ctx.body.on_ground
