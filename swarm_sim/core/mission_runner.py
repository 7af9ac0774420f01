"""AUTO mission execution for `SimAutopilot` (AP_Mission and the vehicles' mode_auto):
NAV items become navigation tasks, DO items run alongside the NAV item before them,
DO_JUMP loops, and MISSION_ITEM_REACHED / `Mission: N Type` / `Reached ...` texts are
sent as ArduPilot sends them."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from .airframes import VehicleModel
from .firmware import (
    MISSION_CMD_NAMES,
    SEV_CRITICAL,
    SEV_INFO,
    SEV_NOTICE,
    Behaviour,
    Firmware,
    mode_number,
)
from .mission import FRAME_ABSOLUTE, GLOBAL_FRAMES, MISSION, MissionItem
from .navigation import FlyTo, Hold, Idle, Loiter, NavTask, Purpose, Sequence, Takeoff

if TYPE_CHECKING:
    from .autopilot import SimAutopilot


def items_changed(ap: SimAutopilot, mission_type: int) -> list[Any]:
    out: list[Any] = []
    if mission_type == MISSION:
        ap.params["MIS_TOTAL"] = (float(max(0, len(ap.mission_items) - 1)), 4)
        names = sorted(ap.params)
        out.append(ap._param_value("MIS_TOTAL", names.index("MIS_TOTAL"), len(names)))
        if ap.mode_spec.behaviour == Behaviour.AUTO and ap.mission_running:
            # AP_Mission in AUTO: the current item's index is kept and restarted in the
            # new mission; when the new mission has no such item it carries on with the
            # old one (recorded: mission-start-in-auto; MISSION_START does not help,
            # DO_SET_MISSION_CURRENT or leaving AUTO and coming back does)
            if 0 < ap.mission_seq < len(ap.mission_items):
                ap.mission_complete = False
                run_from(ap, ap.mission_seq)
            else:
                ap._text(SEV_CRITICAL, "Auto mission changed but failed to restart command")
            return out
        ap.mission_seq = 0
        ap.mission_complete = False
        ap._jumps.clear()
        if ap.mode_spec.behaviour == Behaviour.AUTO:
            start_or_resume(ap)
    return out


def is_nav(command: int) -> bool:
    return command <= 95 or command in (213, 42702, 42703)


def start_or_resume(ap: SimAutopilot) -> None:
    if len(ap.mission_items) <= 1:
        ap.mission_running = False
        ap._set_nav(ap._hold_here() if not ap.body.on_ground else Idle())
        return
    if ap.mission_complete or not 0 < ap.mission_seq < len(ap.mission_items):
        ap.mission_complete = False
        ap._jumps.clear()
        start = 1
    else:
        start = ap.mission_seq
    ap.mission_running = True
    run_from(ap, start)


def run_from(ap: SimAutopilot, seq: int) -> None:
    items = ap.mission_items
    guard = 0
    while seq < len(items) and guard < 4 * len(items) + 10:
        guard += 1
        item = items[seq]
        if item.command == 177:  # DO_JUMP
            seq = jump(ap, seq, item)
            continue
        ap._text(SEV_INFO, f"Mission: {seq} {MISSION_CMD_NAMES.get(item.command, '?')}")
        if not is_nav(item.command):
            do_command(ap, item)
            seq += 1
            continue
        ap.mission_seq = seq
        started = start_nav_item(ap, item)
        k = seq + 1
        while k < len(items) and not is_nav(items[k].command) and items[k].command != 177:
            ap._text(SEV_INFO, f"Mission: {k} {MISSION_CMD_NAMES.get(items[k].command, '?')}")
            do_command(ap, items[k])
            k += 1
        if started == "done":
            item_done(ap)
        return
    finished(ap)


def jump(ap: SimAutopilot, seq: int, item: MissionItem) -> int:
    target, repeat = int(item.param1), int(item.param2)
    taken = ap._jumps.get(seq, 0)
    if 0 < target < len(ap.mission_items) and (repeat < 0 or taken < repeat):
        ap._jumps[seq] = taken + 1
        return target
    return seq + 1


def _next_waypoint(ap: SimAutopilot) -> tuple[float, float] | None:
    """(n, e) of the next NAV item if it is a plain waypoint (ArduCopter rounds the
    corner towards it instead of stopping), else None."""
    items = ap.mission_items
    k = ap.mission_seq + 1
    while k < len(items) and not is_nav(items[k].command) and items[k].command != 177:
        k += 1
    if k >= len(items) or items[k].command != 16 or items[k].param1 > 0:
        return None
    n, e, _alt = item_location(ap, items[k])
    return n, e


def start_nav_item(ap: SimAutopilot, item: MissionItem) -> str:
    """Start the task for a NAV item: "started", "done" (complete at once) or "mode"
    (the item switched modes)."""
    fw, b = ap.firmware, ap.body
    cmd = item.command
    n, e, alt = item_location(ap, item)
    vtol_model = ap.model == VehicleModel.VTOL
    if cmd in (16, 82):  # WAYPOINT, SPLINE_WAYPOINT
        accept = item.param2 if item.param2 > 0 else ap._wp_radius()
        hold = 0.0 if fw == Firmware.PLANE else max(0.0, item.param1)
        prev = ap.nav.destination if isinstance(ap._leaf_task(), FlyTo) else None
        origin = (prev[0], prev[1]) if prev is not None else None  # the leg is flown as a line
        task = FlyTo(
            n,
            e,
            alt,
            accept_m=accept,
            hold_s=hold,
            stop=not ap.fixed_wing,
            origin=origin,
            next_ne=_next_waypoint(ap) if fw == Firmware.COPTER else None,
        )
        ap._set_nav(task, Purpose.MISSION)
    elif cmd in (17, 18, 19, 31):  # LOITER_UNLIM, _TURNS, _TIME, _TO_ALT
        radius = abs(item.param3) if cmd != 31 else abs(item.param2)
        turns = item.param1 if cmd == 18 else None
        time_s = item.param1 if cmd == 19 else (0.0 if cmd == 31 else None)
        ap._set_nav(
            Loiter(n, e, alt, radius=radius, ccw=item.param3 < 0, turns=turns, time_s=time_s),
            Purpose.MISSION,
        )
    elif cmd == 20:  # RETURN_TO_LAUNCH
        if fw == Firmware.PLANE:
            ap._set_mode(mode_number(fw, "RTL"))
            return "mode"
        if fw == Firmware.ROVER:  # done on arrival; the mission then completes
            hn, he = ap._rtl_point()
            ap._set_nav(FlyTo(hn, he, b.alt, accept_m=ap._wp_radius()), Purpose.MISSION)
        else:
            ap._set_nav(ap._rtl_task(), Purpose.MISSION)
    elif cmd == 22 or (cmd == 84 and not vtol_model):  # TAKEOFF (VTOL_TAKEOFF on a copter)
        if fw == Firmware.ROVER or (cmd == 84 and fw == Firmware.PLANE):
            return "done"
        target_alt = item_alt(ap, item)
        if not b.on_ground and b.alt >= target_alt - 0.5:
            return "done"
        ap._set_nav(Takeoff(target_alt, vtol=fw == Firmware.COPTER), Purpose.MISSION)
    elif cmd == 84:  # VTOL_TAKEOFF on a QuadPlane
        target_alt = item_alt(ap, item)
        if not b.on_ground and b.alt >= target_alt - 0.5:
            return "done"
        ap._set_nav(Takeoff(target_alt, vtol=True), Purpose.MISSION)
    elif cmd in (21, 85):  # LAND, VTOL_LAND
        if fw == Firmware.ROVER or (cmd == 85 and not ap.hover_capable):
            return "done"
        vertical = fw == Firmware.COPTER or cmd == 85
        tasks: list[NavTask] = []
        if item.has_location:
            if vertical and vtol_model:
                if math.hypot(n - b.n, e - b.e) > 2.0 * ap.loiter_radius:
                    tasks.append(FlyTo(n, e, b.alt, accept_m=ap.loiter_radius, stop=False))
                tasks.append(FlyTo(n, e, b.alt, accept_m=3.0, vtol=True))
            elif vertical:
                tasks.append(FlyTo(n, e, b.alt, accept_m=2.0))
        else:
            n, e = b.n, b.e
        tasks.append(ap._land_task(n, e, vtol=vertical))
        ap._set_nav(Sequence(tasks), Purpose.MISSION)
    elif cmd == 93:  # NAV_DELAY
        ap._set_nav(Hold(*ap._here(), time_s=max(0.0, item.param1)), Purpose.MISSION)
    else:
        return "done"
    return "started"


def item_alt(ap: SimAutopilot, item: MissionItem) -> float:
    if item.frame in FRAME_ABSOLUTE:
        return item.z
    return ap.home_alt + item.z


def item_location(ap: SimAutopilot, item: MissionItem) -> tuple[float, float, float]:
    b = ap.body
    if item.frame in GLOBAL_FRAMES and not (item.x == 0 and item.y == 0):
        n, e = ap.frame.to_ne(item.lat_deg, item.lon_deg)
    else:
        n, e = b.n, b.e
    if ap.airframe.is_ground:
        return n, e, b.ground_alt
    if item.frame in GLOBAL_FRAMES and not (
        item.z == 0 and item.frame not in FRAME_ABSOLUTE and item.command != 16
    ):
        alt = item_alt(ap, item)
    else:
        alt = b.alt
    return n, e, alt


def do_command(ap: SimAutopilot, item: MissionItem) -> None:
    cmd = item.command
    if cmd == 178:  # DO_CHANGE_SPEED
        ap._change_speed(int(item.param1), item.param2)
    elif cmd == 179:  # DO_SET_HOME
        if item.param1 == 1 or not item.has_location:
            ap._set_home(ap.body.n, ap.body.e, ap.body.alt)
        else:
            n, e = ap.frame.to_ne(item.lat_deg, item.lon_deg)
            ap._set_home(n, e, item_alt(ap, item))
    elif cmd == 208:  # DO_PARACHUTE
        if int(item.param1) == 2:
            ap._parachute_release()
    elif cmd == 207:  # DO_FENCE_ENABLE
        enable = int(item.param1) == 1
        ap.params["FENCE_ENABLE"] = (1.0 if enable else 0.0, 2)
        ap._text(SEV_INFO, "Fence Enabled" if enable else "Fence Disabled")


def item_done(ap: SimAutopilot) -> None:
    seq = ap.mission_seq
    item = ap.mission_items[seq] if 0 < seq < len(ap.mission_items) else None
    ap._out.append(mavlink.MAVLink_mission_item_reached_message(seq))
    if item is not None and item.command in (16, 82):
        leaf = ap.nav if isinstance(ap.nav, FlyTo) else None
        if ap.firmware == Firmware.COPTER:
            ap._text(SEV_INFO, f"Reached command #{seq}")
        else:
            dist = int(leaf.reached_dist_m) if leaf is not None else 0
            ap._text(SEV_INFO, f"Reached waypoint #{seq} dist {dist}m")
    landed_item = item is not None and (
        item.command in (21, 85) or (item.command == 20 and ap.firmware == Firmware.COPTER)
    )
    if landed_item and ap.body.on_ground:
        ap._land_complete()
    k = seq + 1
    while (
        k < len(ap.mission_items)
        and not is_nav(ap.mission_items[k].command)
        and ap.mission_items[k].command != 177
    ):
        k += 1  # DO commands after the item already ran with it
    if k >= len(ap.mission_items):
        finished(ap)
    else:
        run_from(ap, k)


def finished(ap: SimAutopilot) -> None:
    ap.mission_running = False
    ap.mission_complete = True
    if ap.firmware == Firmware.PLANE:
        if ap.armed and not ap.body.on_ground:
            ap._set_mode(mode_number(ap.firmware, "RTL"))
            ap._text(SEV_INFO, "Mission complete, changing mode to RTL")
        else:
            ap._set_nav(Idle())
    elif ap.firmware == Firmware.ROVER:
        # ModeAuto::exit_mission with MIS_DONE_BEHAVE=0: stop, staying in AUTO
        ap._text(SEV_NOTICE, "Mission Complete")
        ap._set_nav(Hold(*ap._here()))
    elif ap.body.on_ground:
        ap._disarm()  # Copter ModeAuto::exit_mission: landed, safe to disarm
        ap._set_nav(Idle())
    else:
        ap._set_nav(ap._hold_here())


def starts_with_takeoff(ap: SimAutopilot) -> bool:
    for item in ap.mission_items[1:]:
        if is_nav(item.command):
            return item.command in (22, 84)
    return False


def landing_sequence_start(ap: SimAutopilot) -> int | None:
    """Index of the DO_LAND_START closest to the vehicle (AP_Mission::
    get_landing_sequence_start), or None."""
    best, best_d = None, math.inf
    b = ap.body
    for idx, item in enumerate(ap.mission_items):
        if idx == 0 or item.command != 189:
            continue
        if item.has_location:
            n, e = ap.frame.to_ne(item.lat_deg, item.lon_deg)
            d = math.hypot(n - b.n, e - b.e)
        else:
            d = math.inf if best is not None else 1e12
        if d < best_d:
            best, best_d = idx, d
    return best


def jump_to_landing_sequence(ap: SimAutopilot) -> bool:
    """Switch to AUTO at the landing sequence (RTL_AUTOLAND, MAV_CMD_DO_LAND_START)."""
    idx = landing_sequence_start(ap)
    if idx is None or not ap.ekf_position:
        return False
    ap._text(SEV_INFO, "Landing sequence start")
    ap.mission_seq = idx
    ap.mission_complete = False
    auto = mode_number(ap.firmware, "AUTO")
    if ap.mode == auto:
        ap.mission_running = True
        run_from(ap, idx)
        return True
    return ap._set_mode(auto)
