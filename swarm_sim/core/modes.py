"""Flight modes (Plane/Copter/Rover::set_mode and the modes' behaviours): the current mode,
the checks a mode change must pass (worded as ArduPilot's texts), what entering a mode
makes the vehicle fly, and what the vehicle does when a mode's or a guided command's
task is complete."""

from __future__ import annotations

import math
from typing import Any

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from .airframes import AirframeParams, VehicleModel
from .arming import Arming
from .firmware import (
    BOOT_MODE,
    INITIAL_MODE,
    MODES,
    SEV_CRITICAL,
    SEV_INFO,
    SEV_WARNING,
    Behaviour,
    Firmware,
    ModeSpec,
    base_mode,
    mode_number,
)
from .kinematics import Body
from .mission_runner import MissionRunner
from .navigation import FlyTo, Hold, Idle, Land, Loiter, Parachute, Purpose, Sequence, Takeoff
from .navigator import Navigator
from .outbox import Outbox
from .params import Parameters
from .sensors import Sensors
from .stores import ItemStores
from .timeline import Timeline


class Modes:
    def __init__(
        self,
        airframe: AirframeParams,
        firmware: Firmware,
        mav_type: int,
        *,
        body: Body,
        sensors: Sensors,
        params: Parameters,
        stores: ItemStores,
        navigator: Navigator,
        arming: Arming,
        mission: MissionRunner,
        timeline: Timeline,
        out: Outbox,
    ) -> None:
        self.airframe = airframe
        self.firmware = firmware
        self.model = airframe.model
        self.mav_type = mav_type
        self.body = body
        self.sensors = sensors
        self.params = params
        self.stores = stores
        self.nav = navigator
        self.arming = arming
        self.mission = mission
        self.timeline = timeline
        self.out = out
        self.mode = BOOT_MODE[firmware]

    @property
    def spec(self) -> ModeSpec:
        return MODES[self.firmware][self.mode]

    @property
    def behaviour(self) -> Behaviour:
        return self.spec.behaviour

    def base_mode(self) -> int:
        return base_mode(self.firmware, self.spec, self.arming.armed)

    def heartbeat(self) -> Any:
        """HEARTBEAT (ArduPilot sends one on every mode change too)."""
        return mavlink.MAVLink_heartbeat_message(
            self.mav_type, 3, self.base_mode(), self.mode, self.arming.system_status(), 3
        )

    # ------------------------------------------------------------------ boot

    def boot_ready(self, boot_time: float) -> None:
        """ArduPilot Ready: the boot mode gives way to the initial mode."""
        if self.mode != BOOT_MODE[self.firmware]:
            return
        if self.firmware == Firmware.PLANE:
            # recorded: INITIALISING -> MANUAL -> the RC mode switch's mode (FBWA)
            self.mode = 0
            self.out.send(self.heartbeat())
            self.timeline.schedule(boot_time + 1.4, self._initial_mode)
        else:
            self._initial_mode()

    def _initial_mode(self) -> None:
        if self.mode in (0, BOOT_MODE[self.firmware]) and not self.arming.armed:
            changed = self.mode != INITIAL_MODE[self.firmware]
            self.mode = INITIAL_MODE[self.firmware]
            self.nav.task = Idle()
            if changed:
                self.out.send(self.heartbeat())

    # ------------------------------------------------------------------ mode changes

    def set_mode(self, number: int) -> bool:
        """Plane/Copter/Rover::set_mode. On failure the reason is sent as STATUSTEXT."""
        spec = MODES[self.firmware].get(number)
        if spec is None or not spec.selectable:
            self.out.text(SEV_WARNING, f"No such mode {number}")
            return False
        if spec.vtol and self.model != VehicleModel.VTOL:
            self.out.text(SEV_INFO, "Q_ENABLE 0")
            return False
        if number == self.mode:
            return True
        if spec.requires_position and not self.sensors.ekf_position:
            self.out.text(SEV_WARNING, f"Mode change to {spec.name} failed: requires position")
            return False
        if (
            self.firmware == Firmware.COPTER
            and spec.behaviour == Behaviour.AUTO
            and self.arming.armed
            and self.body.on_ground
            and not self.stores.starts_with_takeoff()
        ):
            self.out.text(SEV_CRITICAL, "Auto: Missing Takeoff Cmd")
            return False
        self.mode = number
        self.nav.speed = None
        self.out.send(self.heartbeat())
        self._enter(spec)
        return True

    def _enter(self, spec: ModeSpec) -> None:
        beh = spec.behaviour
        b, nav = self.body, self.nav
        n, e, alt = nav.here()
        if beh == Behaviour.AUTO:
            self.mission.start_or_resume()
            return
        self.stores.progress.running = False
        if beh in (Behaviour.MANUAL, Behaviour.INITIALISING):
            if self.firmware == Firmware.PLANE and not b.on_ground and not nav.vtol_hovering():
                h = math.radians(b.heading_deg)
                nav.set(
                    FlyTo(
                        n + 1e5 * math.cos(h), e + 1e5 * math.sin(h), alt, accept_m=0.0, stop=False
                    )
                )
            else:
                nav.set(Hold(n, e, alt, vtol=nav.vtol_hovering()))
        elif beh == Behaviour.HOLD:
            sn, se = nav.stopping_point()
            nav.set(Hold(sn, se, alt, vtol=spec.vtol or not nav.fixed_wing))
        elif beh == Behaviour.GUIDED:
            nav.set(nav.hold_here())
        elif beh == Behaviour.RTL:
            if (
                self.firmware == Firmware.PLANE
                and self.params.value("RTL_AUTOLAND") == 2
                and self.mission.jump_to_landing_sequence()
            ):
                return
            nav.set(nav.rtl_task())
        elif beh == Behaviour.QRTL:
            nav.set(nav.qrtl_task())
        elif beh == Behaviour.LAND:
            ln, le = nav.stopping_point()
            nav.set(nav.land_task(ln, le, vtol=True))
        elif beh == Behaviour.CIRCLE:
            if self.firmware == Firmware.COPTER:
                h = math.radians(b.heading_deg)
                nav.set(Loiter(n + 10 * math.cos(h), e + 10 * math.sin(h), alt, radius=10.0))
            else:
                nav.set(Loiter(n, e, alt, radius=nav.loiter_radius or 20.0))
        elif beh == Behaviour.LOITER:
            nav.set(Loiter(n, e, alt))
        elif beh == Behaviour.TAKEOFF:
            if b.on_ground:
                climb = nav.home.alt + self.params.value("TKOFF_ALT")
                nav.set(Sequence([Takeoff(climb, vtol=False), Loiter(n, e, climb)]))
            else:
                nav.set(Loiter(n, e, alt))

    # ------------------------------------------------------------------ task complete

    def task_done(self) -> None:
        """The navigation task is complete: the mission goes on, a guided target or
        take-off holds there, a landing disarms, a mode's task ends as the mode does."""
        nav = self.nav
        task, leaf = nav.task, nav.leaf()
        if nav.purpose == Purpose.MISSION:
            self.mission.item_done()
            return
        if nav.purpose == Purpose.GUIDED_GOTO:
            dest = task.destination or nav.here()
            if self.firmware == Firmware.PLANE:
                self.out.send(mavlink.MAVLink_mission_item_reached_message(0))
                if nav.vtol_hovering() and isinstance(task, FlyTo) and task.vtol:
                    nav.set(Hold(*dest, vtol=True))
                else:
                    nav.set(Loiter(*dest, radius=nav.guided_radius))
            else:
                nav.set(Hold(*dest))
            return
        if nav.purpose in (Purpose.GUIDED_TAKEOFF, Purpose.GUIDED_VELOCITY):
            n, e, alt = nav.here()
            if nav.purpose == Purpose.GUIDED_TAKEOFF and isinstance(task, Takeoff):
                alt = task.alt
            nav.set(Hold(n, e, alt, vtol=self.model == VehicleModel.VTOL))
            return
        # mode tasks
        if isinstance(leaf, Land) or (
            isinstance(task, Sequence) and isinstance(task.tasks[-1], Land)
        ):
            self.arming.land_complete()
            nav.set(Idle())
            return
        beh = self.spec.behaviour
        if beh == Behaviour.RTL and self.firmware == Firmware.ROVER:
            self.out.text(SEV_INFO, "Reached destination")
            nav.set(Hold(*nav.here()))
        elif beh == Behaviour.RTL and self.firmware == Firmware.PLANE and isinstance(task, FlyTo):
            # RTL_AUTOLAND=1: home reached, land via the mission's DO_LAND_START
            if self.params.value("RTL_AUTOLAND") == 1 and self.mission.jump_to_landing_sequence():
                return
            # Q_RTL_MODE=1: a QuadPlane at its RTL point switches to QRTL and lands
            # there vertically (ModeRTL::update, RTL_COMPLETE_SWITCHING_TO_VTOL_LAND_RTL);
            # 0 (the default) circles it for good
            if self.model == VehicleModel.VTOL and self.params.value("Q_RTL_MODE") == 1:
                self.set_mode(mode_number(self.firmware, "QRTL"))
                return
            nav.set(Loiter(task.n, task.e, task.alt))
        elif beh == Behaviour.TAKEOFF:
            nav.set(Loiter(*nav.here()))
        elif isinstance(task, Parachute):
            nav.set(Idle())
        else:
            nav.set(nav.hold_here())
