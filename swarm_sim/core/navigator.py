"""What the vehicle is flying now: the navigation task a mode, a guided command or a
mission item set (`navigation.py`), why it runs (`Purpose`), the speed override
(DO_CHANGE_SPEED), and the tasks ArduPilot's modes fly (hold here, RTL, QRTL, land),
built from the vehicle's state and parameters. The `NavContext` of its tasks."""

from __future__ import annotations

import math

from .airframes import AirframeParams, VehicleModel
from .firmware import SEV_INFO, Firmware
from .geo import LocalFrame
from .home import HomeState
from .kinematics import Body, Guide, Target, VtolState
from .navigation import (
    FlyTo,
    Hold,
    Idle,
    Land,
    Loiter,
    NavTask,
    Parachute,
    Purpose,
    Sequence,
    Takeoff,
)
from .outbox import Outbox
from .params import Parameters
from .stores import ItemStores

COPTER_LAND_SETTLE_S = 1.0  # touchdown -> land complete (copter land detector)
PLANE_LAND_SETTLE_S = 5.0  # touchdown -> "Land complete" (recorded QuadPlane ~6 s)
RTL_LOITER_TIME_S = 5.0  # RTL_LOIT_TIME


class Navigator:
    def __init__(
        self,
        airframe: AirframeParams,
        firmware: Firmware,
        body: Body,
        params: Parameters,
        frame: LocalFrame,
        home: HomeState,
        stores: ItemStores,
        out: Outbox,
    ) -> None:
        self.airframe = airframe
        self.firmware = firmware
        self.model = airframe.model
        self.body = body
        self.params = params
        self.frame = frame
        self.home = home
        self.stores = stores
        self.out = out
        self.task: NavTask = Idle()
        self.purpose = Purpose.MODE
        self.speed: float | None = None  # DO_CHANGE_SPEED override
        self.guided_radius = 0.0  # a plane's loiter radius at a guided target

    def set(self, task: NavTask, purpose: Purpose = Purpose.MODE) -> None:
        self.task = task
        self.purpose = purpose

    def target(self, armed: bool) -> Target:
        """What the airframe is asked to do this physics step: the task's target, motors
        idle while disarmed or on the ground before a take-off (a ground vehicle holds)."""
        task = self.task
        if isinstance(task, Parachute):
            return task.target(self)
        if not armed:
            return Target(Guide.IDLE)
        target = task.target(self)
        b = self.body
        if self.airframe.is_ground:
            if target.kind in (Guide.TAKEOFF, Guide.LAND, Guide.IDLE):
                return Target(Guide.HOLD, b.n, b.e, b.alt)
            return target
        if b.on_ground and target.kind != Guide.TAKEOFF:
            return Target(Guide.IDLE)
        return target

    # ------------------------------------------------------------------ state views

    def leaf(self) -> NavTask:
        """The task flown now (inside a Sequence: its current step)."""
        task = self.task
        while isinstance(task, Sequence):
            current = task.current
            if current is None:
                break
            task = current
        return task

    @property
    def taking_off(self) -> bool:
        return isinstance(self.leaf(), Takeoff)

    @property
    def landing(self) -> bool:
        return isinstance(self.leaf(), (Land, Parachute))

    def landing_context(self) -> bool:
        return isinstance(self.leaf(), (Land, Parachute, Idle))

    def here(self) -> tuple[float, float, float]:
        return self.body.n, self.body.e, self.body.alt

    def flying(self) -> bool:
        return not self.body.on_ground and not self.airframe.is_ground

    def vtol_hovering(self) -> bool:
        return self.model == VehicleModel.VTOL and self.body.vtol_state in (
            VtolState.MC,
            VtolState.TRANSITION_TO_MC,
        )

    # NavContext --------------------------------------------------------------------

    @property
    def hover_capable(self) -> bool:
        return self.airframe.can_hover

    @property
    def fixed_wing(self) -> bool:
        return self.airframe.is_fixed_wing

    @property
    def wp_speed(self) -> float:
        if self.speed is not None:
            return self.speed
        if self.firmware == Firmware.COPTER:
            return self.params.value("WPNAV_SPEED") / 100.0
        if self.firmware == Firmware.PLANE:
            return self.params.value("AIRSPEED_CRUISE")
        return self.params.value("WP_SPEED")

    @property
    def wp_accel(self) -> float:
        """Horizontal acceleration in AUTO (copter: WPNAV_ACCEL)."""
        if self.firmware == Firmware.COPTER:
            return self.params.value("WPNAV_ACCEL") / 100.0
        return self.airframe.accel_m_s2

    @property
    def loiter_radius(self) -> float:
        if self.firmware == Firmware.PLANE:
            return max(10.0, self.params.value("WP_LOITER_RAD"))
        return 0.0

    def wp_radius(self) -> float:
        if self.firmware == Firmware.COPTER:
            return self.params.value("WPNAV_RADIUS") / 100.0
        return self.params.value("WP_RADIUS")

    # ------------------------------------------------------------------ tasks

    def stopping_point(self) -> tuple[float, float]:
        """Where the vehicle comes to a stop if it brakes now (QLAND/LAND land there)."""
        b = self.body
        v = b.groundspeed
        if v < 1.0:
            return b.n, b.e
        d = v * v / (2.0 * max(self.airframe.accel_m_s2, 0.5))
        return b.n + b.vn / v * d, b.e + b.ve / v * d

    def hold_here(self) -> NavTask:
        n, e, alt = self.here()
        if self.firmware == Firmware.PLANE and not self.vtol_hovering():
            return Loiter(n, e, alt)
        n, e = self.stopping_point()  # brake, then hold where it stops
        return Hold(n, e, alt, vtol=self.vtol_hovering())

    def land_task(self, n: float, e: float, vtol: bool) -> Land:
        settle = PLANE_LAND_SETTLE_S if self.firmware == Firmware.PLANE else COPTER_LAND_SETTLE_S
        return Land(n, e, vtol=vtol, settle_s=settle)

    def rtl_point(self) -> tuple[float, float]:
        n, e, _ = self.rtl_target()
        return n, e

    def rtl_target(self) -> tuple[float, float, float | None]:
        """The nearest rally point, or home if it is nearer and RALLY_INCL_HOME is 1 (as
        ArduPilot's AP_Rally, RALLY_LIMIT_KM not modelled), with the rally point's altitude
        (MSL; None for home)."""
        best: tuple[float, float, float | None] = (*self.home.ne, None)
        b = self.body
        rally = self.stores.rally
        best_d = math.hypot(best[0] - b.n, best[1] - b.e)
        if self.params.value("RALLY_INCL_HOME") == 0 and rally:
            best_d = math.inf
        for item in rally:
            n, e = self.frame.to_ne(item.lat_deg, item.lon_deg)
            d = math.hypot(n - b.n, e - b.e)
            if d < best_d:
                alt = self.home.alt_from_frame(item.frame, item.z)
                best, best_d = (n, e, alt), d
        return best

    def rtl_task(self) -> NavTask:
        b = self.body
        hn, he, rally_alt = self.rtl_target()
        if self.firmware == Firmware.COPTER:
            # ArduCopter climbs to max(rally altitude, RTL_ALT) (and keeps a higher one)
            rtl_alt = max(b.alt, self.home.alt + self.params.value("RTL_ALT") / 100.0)
            if rally_alt is not None:
                rtl_alt = max(rtl_alt, rally_alt)
            tasks: list[NavTask] = []
            if b.alt < rtl_alt - 0.5:
                tasks.append(FlyTo(b.n, b.e, rtl_alt, accept_m=2.0, stop=True))
            tasks += [
                FlyTo(hn, he, rtl_alt, accept_m=2.0, stop=True),
                Hold(hn, he, rtl_alt, time_s=RTL_LOITER_TIME_S),
                self.land_task(hn, he, vtol=True),
            ]
            return Sequence(tasks)
        if self.firmware == Firmware.PLANE:
            # fly home, then (when done) loiter there or land via DO_LAND_START
            rtl = self.params.value("RTL_ALTITUDE")
            alt = b.alt if rtl < 0 else self.home.alt + rtl
            if rally_alt is not None:
                # ArduPlane flies to a rally point at the rally point's own altitude
                # (recorded: plane-rtl-rally-alt-zero descends into the ground; RTL_ALTITUDE
                # is no floor)
                alt = rally_alt
            return FlyTo(hn, he, alt, accept_m=self.loiter_radius, stop=False)
        return FlyTo(hn, he, b.alt, accept_m=self.params.value("WP_RADIUS"), stop=True)

    def qrtl_task(self) -> NavTask:
        b = self.body
        hn, he = self.rtl_point()
        tasks: list[NavTask] = []
        far = math.hypot(hn - b.n, he - b.e) > 2.0 * self.loiter_radius
        if far:
            alt = max(b.alt, self.home.alt + 15.0)
            tasks.append(FlyTo(hn, he, alt, accept_m=self.loiter_radius, stop=False))
        tasks.append(FlyTo(hn, he, max(b.alt, self.home.alt + 5.0), accept_m=3.0, vtol=True))
        tasks.append(self.land_task(hn, he, vtol=True))
        return Sequence(tasks)

    # ------------------------------------------------------------------ guided

    def goto(self, lat: float, lon: float, alt: float) -> None:
        """A guided target: fly there (a plane loiters on arrival, a QuadPlane hovering
        near it moves on its lift motors)."""
        n, e = self.frame.to_ne(lat, lon)
        if self.airframe.is_ground:
            alt = self.body.ground_alt
        if self.firmware == Firmware.PLANE:
            if (
                self.vtol_hovering()
                and math.hypot(n - self.body.n, e - self.body.e) < 2.0 * self.loiter_radius
                and self.flying()
            ):
                self.set(FlyTo(n, e, alt, accept_m=2.0, vtol=True), Purpose.GUIDED_GOTO)
            else:
                self.set(
                    FlyTo(n, e, alt, accept_m=self.loiter_radius + 10.0, stop=False),
                    Purpose.GUIDED_GOTO,
                )
            return
        accept = self.wp_radius()
        self.set(FlyTo(n, e, alt, accept_m=accept, stop=True), Purpose.GUIDED_GOTO)

    def change_alt(self, alt: float, *, guided: bool) -> None:
        """A new altitude for the task flown (in GUIDED without one: hold here at it)."""
        task = self.leaf()
        if isinstance(task, (FlyTo, Hold, Loiter)):
            task.alt = alt
        elif guided:
            hold = self.hold_here()
            if isinstance(hold, (Hold, Loiter)):
                hold.alt = alt
            self.set(hold)

    def change_speed(self, speed_type: int, speed: float) -> bool:
        """DO_CHANGE_SPEED; False when refused."""
        if not math.isfinite(speed) or speed <= 0:
            return False
        if self.firmware == Firmware.PLANE:
            if speed_type == 0:
                if (
                    not self.params.value("AIRSPEED_MIN")
                    <= speed
                    <= self.params.value("AIRSPEED_MAX")
                ):
                    return False
                self.speed = speed
                self.out.text(SEV_INFO, f"Set airspeed {int(speed)} m/s")
                return True
            if speed_type == 1:
                self.out.text(SEV_INFO, f"Set groundspeed {int(speed)}")
                return True
            return False
        if speed_type in (0, 1):
            self.speed = min(speed, self.airframe.max_speed_m_s)
            return True
        return speed_type in (2, 3)
