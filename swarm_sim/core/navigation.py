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
        return Target(Guide.HOLD, self.n, self.e, self.alt, radius=self.radius, ccw=self.ccw,
                      fixed_wing=not self.vtol)  # fmt: skip

    def update(self, ctx: NavContext, dt: float) -> bool:
        self.elapsed_s += dt
        return self.time_s is not None and self.elapsed_s >= self.time_s

    @property
    def destination(self) -> tuple[float, float, float] | None:
        return self.n, self.e, self.alt


@dataclass
class FlyTo(NavTask):
    """Go to a point; done within `accept_m` (hover-capable: also within 2 m of height)
    or, for fixed-wing, once past the line through the point square to the track."""

    n: float
    e: float
    alt: float
    accept_m: float
    speed: float = 0.0
    stop: bool = True
    vtol: bool = False
    hold_s: float = 0.0  # wait at the point (copter/rover NAV_WAYPOINT param1)
    origin: tuple[float, float] | None = None
    reached: bool = False
    reached_dist_m: float = 0.0
    held_s: float = 0.0
    name = "flyto"

    def target(self, ctx: NavContext) -> Target:
        speed = self.speed if self.speed > 0 else ctx.wp_speed
        if self.vtol:
            speed = 0.0  # the VTOL speed
        return Target(Guide.GOTO, self.n, self.e, self.alt, speed=speed, stop=self.stop,
                      fixed_wing=not self.vtol, track_from=self.origin)  # fmt: skip

    def update(self, ctx: NavContext, dt: float) -> bool:
        b = ctx.body
        if self.origin is None:
            self.origin = (b.n, b.e)
        if not self.reached:
            dist = math.hypot(self.n - b.n, self.e - b.e)
            if ctx.fixed_wing and not self.vtol:
                on_point = dist <= self.accept_m or self._passed(b)
            else:
                on_point = dist <= self.accept_m and abs(self.alt - b.alt) <= 2.0
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
            return Target(Guide.LOITER, self.n, self.e, self.alt, speed=ctx.wp_speed,
                          radius=radius, ccw=self.ccw)  # fmt: skip
        kind = Guide.LOITER if self.radius > 0.5 else Guide.HOLD
        return Target(kind, self.n, self.e, self.alt, speed=min(ctx.wp_speed, 5.0),
                      radius=self.radius, ccw=self.ccw, fixed_wing=not self.vtol)  # fmt: skip

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
