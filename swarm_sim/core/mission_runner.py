"""AUTO mission execution (AP_Mission and the vehicles' mode_auto): NAV items become
navigation tasks, DO items run alongside the NAV item before them, DO_JUMP loops, and
MISSION_ITEM_REACHED / `Mission: N Type` / `Reached ...` texts are sent as ArduPilot
sends them."""

from __future__ import annotations

import math
from typing import Any, Protocol

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from .airframes import AirframeParams, VehicleModel
from .arming import Arming
from .firmware import (
    MISSION_CMD_NAMES,
    SEV_CRITICAL,
    SEV_INFO,
    SEV_NOTICE,
    Behaviour,
    Firmware,
    ModeSpec,
    mode_number,
)
from .geo import LocalFrame
from .home import HomeState
from .kinematics import Body
from .mission import FRAME_ABSOLUTE, GLOBAL_FRAMES, MissionItem
from .navigation import FlyTo, Hold, Idle, Loiter, NavTask, Purpose, Sequence, Takeoff
from .navigator import Navigator
from .outbox import Outbox
from .params import Parameters
from .sensors import Sensors
from .stores import ItemStores, is_nav
from .timeline import Timeline


class ModeControl(Protocol):
    """What the mission needs of the flight modes: it ends in RTL (a plane), a landing
    sequence switches to AUTO."""

    @property
    def mode(self) -> int: ...
    @property
    def spec(self) -> ModeSpec: ...
    def set_mode(self, number: int) -> bool: ...


class MissionRunner:
    #: the flight modes, attached once they exist (they run the mission in AUTO)
    modes: ModeControl

    def __init__(
        self,
        airframe: AirframeParams,
        firmware: Firmware,
        *,
        body: Body,
        frame: LocalFrame,
        stores: ItemStores,
        params: Parameters,
        sensors: Sensors,
        home: HomeState,
        navigator: Navigator,
        arming: Arming,
        timeline: Timeline,
        out: Outbox,
    ) -> None:
        self.airframe = airframe
        self.firmware = firmware
        self.model = airframe.model
        self.body = body
        self.frame = frame
        self.stores = stores
        self.progress = stores.progress
        self.params = params
        self.sensors = sensors
        self.home = home
        self.nav = navigator
        self.arming = arming
        self.timeline = timeline
        self.out = out

    @property
    def items(self) -> list[MissionItem]:
        return self.stores.mission

    @property
    def in_auto(self) -> bool:
        return self.modes.spec.behaviour == Behaviour.AUTO

    def items_changed(self) -> list[Any]:
        """The mission store changed (an upload or a clear completed): MIS_TOTAL's new
        value (sent after the MISSION_ACK), and in AUTO the mission restarted."""
        p = self.progress
        self.params.set_value("MIS_TOTAL", float(self.stores.mission_total))
        out: list[Any] = [self.params.value_message("MIS_TOTAL")]
        if self.in_auto and p.running:
            # AP_Mission in AUTO: the current item's index is kept and restarted in the
            # new mission; when the new mission has no such item it carries on with the
            # old one (recorded: mission-start-in-auto; MISSION_START does not help,
            # DO_SET_MISSION_CURRENT or leaving AUTO and coming back does)
            if 0 < p.seq < len(self.items):
                p.complete = False
                self.run_from(p.seq)
            else:
                self.out.text(SEV_CRITICAL, "Auto mission changed but failed to restart command")
            return out
        p.rewind()
        if self.in_auto:
            self.start_or_resume()
        return out

    def start_or_resume(self) -> None:
        p = self.progress
        if len(self.items) <= 1:
            p.running = False
            self.nav.set(self.nav.hold_here() if not self.body.on_ground else Idle())
            return
        if p.complete or not 0 < p.seq < len(self.items):
            p.complete = False
            p.jumps.clear()
            start = 1
        else:
            start = p.seq
        p.running = True
        self.run_from(start)

    def set_current(self, seq: int) -> bool:
        """DO_SET_MISSION_CURRENT / MISSION_SET_CURRENT; False for no such item."""
        if not 0 < seq < len(self.items):
            return False
        self.progress.seq = seq
        self.progress.complete = False
        self.progress.in_landing_sequence = False
        if self.in_auto:
            self.progress.running = True
            self.run_from(seq)
        return True

    def run_from(self, seq: int) -> None:
        items = self.items
        guard = 0
        while seq < len(items) and guard < 4 * len(items) + 10:
            guard += 1
            item = items[seq]
            if item.command == 177:  # DO_JUMP
                seq = self._jump(seq, item)
                continue
            self.out.text(SEV_INFO, f"Mission: {seq} {MISSION_CMD_NAMES.get(item.command, '?')}")
            if not is_nav(item.command):
                self.do_command(item)
                seq += 1
                continue
            self.progress.seq = seq
            started = self._start_nav_item(item)
            k = seq + 1
            while k < len(items) and not is_nav(items[k].command) and items[k].command != 177:
                self.out.text(
                    SEV_INFO, f"Mission: {k} {MISSION_CMD_NAMES.get(items[k].command, '?')}"
                )
                self.do_command(items[k])
                k += 1
            if started == "done":
                self.item_done()
            return
        self._finished()

    def _jump(self, seq: int, item: MissionItem) -> int:
        target, repeat = int(item.param1), int(item.param2)
        taken = self.progress.jumps.get(seq, 0)
        if 0 < target < len(self.items) and (repeat < 0 or taken < repeat):
            self.progress.jumps[seq] = taken + 1
            return target
        return seq + 1

    def _next_waypoint(self) -> tuple[float, float] | None:
        """(n, e) of the next NAV item if it is a plain waypoint (ArduCopter rounds the
        corner towards it instead of stopping), else None."""
        items = self.items
        k = self.progress.seq + 1
        while k < len(items) and not is_nav(items[k].command) and items[k].command != 177:
            k += 1
        if k >= len(items) or items[k].command != 16 or items[k].param1 > 0:
            return None
        n, e, _alt = self.item_location(items[k])
        return n, e

    def _start_nav_item(self, item: MissionItem) -> str:
        """Start the task for a NAV item: "started", "done" (complete at once) or "mode"
        (the item switched modes)."""
        fw, b, nav = self.firmware, self.body, self.nav
        cmd = item.command
        n, e, alt = self.item_location(item)
        vtol_model = self.model == VehicleModel.VTOL
        if cmd in (16, 82):  # WAYPOINT, SPLINE_WAYPOINT
            accept = item.param2 if item.param2 > 0 else nav.wp_radius()
            hold = 0.0 if fw == Firmware.PLANE else max(0.0, item.param1)
            prev = nav.task.destination if isinstance(nav.leaf(), FlyTo) else None
            origin = (prev[0], prev[1]) if prev is not None else None  # the leg is flown as a line
            task = FlyTo(
                n,
                e,
                alt,
                accept_m=accept,
                hold_s=hold,
                stop=not nav.fixed_wing,
                origin=origin,
                next_ne=self._next_waypoint() if fw == Firmware.COPTER else None,
            )
            nav.set(task, Purpose.MISSION)
        elif cmd in (17, 18, 19, 31):  # LOITER_UNLIM, _TURNS, _TIME, _TO_ALT
            radius = abs(item.param3) if cmd != 31 else abs(item.param2)
            turns = item.param1 if cmd == 18 else None
            time_s = item.param1 if cmd == 19 else (0.0 if cmd == 31 else None)
            nav.set(
                Loiter(n, e, alt, radius=radius, ccw=item.param3 < 0, turns=turns, time_s=time_s),
                Purpose.MISSION,
            )
        elif cmd == 20:  # RETURN_TO_LAUNCH
            if fw == Firmware.PLANE:
                self.modes.set_mode(mode_number(fw, "RTL"))
                return "mode"
            if fw == Firmware.ROVER:  # done on arrival; the mission then completes
                hn, he = nav.rtl_point()
                nav.set(FlyTo(hn, he, b.alt, accept_m=nav.wp_radius()), Purpose.MISSION)
            else:
                nav.set(nav.rtl_task(), Purpose.MISSION)
        elif cmd == 22 or (cmd == 84 and not vtol_model):  # TAKEOFF (VTOL_TAKEOFF on a copter)
            if fw == Firmware.ROVER or (cmd == 84 and fw == Firmware.PLANE):
                return "done"
            target_alt = self.home.item_alt(item)
            if not b.on_ground and b.alt >= target_alt - 0.5:
                return "done"
            nav.set(Takeoff(target_alt, vtol=fw == Firmware.COPTER), Purpose.MISSION)
        elif cmd == 84:  # VTOL_TAKEOFF on a QuadPlane
            target_alt = self.home.item_alt(item)
            if not b.on_ground and b.alt >= target_alt - 0.5:
                return "done"
            nav.set(Takeoff(target_alt, vtol=True), Purpose.MISSION)
        elif cmd in (21, 85):  # LAND, VTOL_LAND
            if fw == Firmware.ROVER or (cmd == 85 and not nav.hover_capable):
                return "done"
            if fw == Firmware.PLANE:
                self.progress.in_landing_sequence = True
            vertical = fw == Firmware.COPTER or cmd == 85
            tasks: list[NavTask] = []
            if item.has_location:
                if vertical and vtol_model:
                    if math.hypot(n - b.n, e - b.e) > 2.0 * nav.loiter_radius:
                        tasks.append(FlyTo(n, e, b.alt, accept_m=nav.loiter_radius, stop=False))
                    tasks.append(FlyTo(n, e, b.alt, accept_m=3.0, vtol=True))
                elif vertical:
                    tasks.append(FlyTo(n, e, b.alt, accept_m=2.0))
            else:
                n, e = b.n, b.e
            tasks.append(nav.land_task(n, e, vtol=vertical))
            nav.set(Sequence(tasks), Purpose.MISSION)
        elif cmd == 93:  # NAV_DELAY
            nav.set(Hold(*nav.here(), time_s=max(0.0, item.param1)), Purpose.MISSION)
        else:
            return "done"
        return "started"

    def item_location(self, item: MissionItem) -> tuple[float, float, float]:
        b = self.body
        if item.frame in GLOBAL_FRAMES and not (item.x == 0 and item.y == 0):
            n, e = self.frame.to_ne(item.lat_deg, item.lon_deg)
        else:
            n, e = b.n, b.e
        if self.airframe.is_ground:
            return n, e, b.ground_alt
        if item.frame in GLOBAL_FRAMES and not (
            item.z == 0 and item.frame not in FRAME_ABSOLUTE and item.command != 16
        ):
            alt = self.home.item_alt(item)
        else:
            alt = b.alt
        return n, e, alt

    def do_command(self, item: MissionItem) -> None:
        cmd = item.command
        if cmd == 178:  # DO_CHANGE_SPEED
            self.nav.change_speed(int(item.param1), item.param2)
        elif cmd == 179:  # DO_SET_HOME
            if item.param1 == 1 or not item.has_location:
                self.home.set(self.body.n, self.body.e, self.body.alt)
            else:
                n, e = self.frame.to_ne(item.lat_deg, item.lon_deg)
                self.home.set(n, e, self.home.item_alt(item))
            self.out.send(self.home.position_message(self.timeline.t))
        elif cmd == 208:  # DO_PARACHUTE
            if int(item.param1) == 2:
                self.arming.parachute_release()
        elif cmd == 207:  # DO_FENCE_ENABLE
            enable = int(item.param1) == 1
            self.params.set_value("FENCE_ENABLE", 1.0 if enable else 0.0)
            self.out.text(SEV_INFO, "Fence Enabled" if enable else "Fence Disabled")

    def item_done(self) -> None:
        """The current NAV item's task is complete: report it, go on with the next."""
        items = self.items
        seq = self.progress.seq
        item = items[seq] if 0 < seq < len(items) else None
        self.out.send(mavlink.MAVLink_mission_item_reached_message(seq))
        if item is not None and item.command in (16, 82):
            task = self.nav.task
            leaf = task if isinstance(task, FlyTo) else None
            if self.firmware == Firmware.COPTER:
                self.out.text(SEV_INFO, f"Reached command #{seq}")
            else:
                dist = int(leaf.reached_dist_m) if leaf is not None else 0
                self.out.text(SEV_INFO, f"Reached waypoint #{seq} dist {dist}m")
        landed_item = item is not None and (
            item.command in (21, 85) or (item.command == 20 and self.firmware == Firmware.COPTER)
        )
        if landed_item and self.body.on_ground:
            self.arming.land_complete()
        k = seq + 1
        while k < len(items) and not is_nav(items[k].command) and items[k].command != 177:
            k += 1  # DO commands after the item already ran with it
        if k >= len(items):
            self._finished()
        else:
            self.run_from(k)

    def _finished(self) -> None:
        self.progress.running = False
        self.progress.complete = True
        fw, nav = self.firmware, self.nav
        if fw == Firmware.PLANE:
            if self.arming.armed and not self.body.on_ground:
                self.modes.set_mode(mode_number(fw, "RTL"))
                self.out.text(SEV_INFO, "Mission complete, changing mode to RTL")
            else:
                nav.set(Idle())
        elif fw == Firmware.ROVER:
            # ModeAuto::exit_mission with MIS_DONE_BEHAVE=0: stop, staying in AUTO
            self.out.text(SEV_NOTICE, "Mission Complete")
            nav.set(Hold(*nav.here()))
        elif self.body.on_ground:
            self.arming.disarm()  # Copter ModeAuto::exit_mission: landed, safe to disarm
            nav.set(Idle())
        else:
            nav.set(nav.hold_here())

    def landing_sequence_start(self) -> int | None:
        """Index of the DO_LAND_START closest to the vehicle (AP_Mission::
        get_landing_sequence_start), or None."""
        best, best_d = None, math.inf
        b = self.body
        for idx, item in enumerate(self.items):
            if idx == 0 or item.command != 189:
                continue
            if item.has_location:
                n, e = self.frame.to_ne(item.lat_deg, item.lon_deg)
                d = math.hypot(n - b.n, e - b.e)
            else:
                d = math.inf if best is not None else 1e12
            if d < best_d:
                best, best_d = idx, d
        return best

    def jump_to_landing_sequence(self) -> bool:
        """Switch to AUTO at the landing sequence (RTL_AUTOLAND, MAV_CMD_DO_LAND_START)."""
        idx = self.landing_sequence_start()
        if idx is None or not self.sensors.ekf_position:
            return False
        self.out.text(SEV_INFO, "Landing sequence start")
        self.progress.seq = idx
        self.progress.in_landing_sequence = True
        self.progress.complete = False
        auto = mode_number(self.firmware, "AUTO")
        if self.modes.mode == auto:
            self.progress.running = True
            self.run_from(idx)
            return True
        return self.modes.set_mode(auto)
