"""Command handling (COMMAND_LONG / COMMAND_INT) for `SimAutopilot`, as ArduPilot's
GCS_MAVLINK and its vehicle subclasses do it: one handler per MAV_CMD in `COMMANDS`,
each returning the MAV_RESULT for the COMMAND_ACK. A handler that succeeds has its ACK
sent before what the command caused; a refused command's reason (STATUSTEXT) goes
before its NAK, which is the order ArduPilot's messages arrive in."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from . import mission_runner, telemetry
from . import streams as S
from .airframes import VehicleModel
from .firmware import SEV_INFO, SEV_NOTICE, Behaviour, Firmware, mode_number
from .mission import GLOBAL_FRAMES, Peer
from .navigation import Hold, Idle, Purpose, Sequence, Takeoff

if TYPE_CHECKING:
    from .autopilot import SimAutopilot

# MAV_RESULT
ACCEPTED, TEMPORARILY_REJECTED, DENIED, UNSUPPORTED, FAILED = 0, 1, 2, 3, 4

ARM_FORCE_MAGIC = 2989.0
DISARM_FORCE_MAGIC = 21196.0
MAV_MODE_FLAG_CUSTOM_MODE_ENABLED = 1
MAV_MODE_FLAG_DECODE_POSITION_SAFETY = 128
MAV_DO_REPOSITION_FLAGS_CHANGE_MODE = 1
MAX_ALT_M = 50_000.0  # altitudes beyond this in a command are refused as bad input

# commands and messages ArduPilot handles without doing anything the simulator models
ACCEPTED_NOOP_COMMANDS = {115, 183, 184, 181, 182, 201, 195, 197, 203, 206, 2000, 2001, 2500, 2501}


@dataclass(frozen=True, slots=True)
class Cmd:
    """COMMAND_LONG and COMMAND_INT, normalised (x/y in degrees for global frames)."""

    command: int
    p1: float
    p2: float
    p3: float
    p4: float
    x: float
    y: float
    z: float
    frame: int
    is_int: bool
    src: Peer

    @property
    def p6(self) -> float:
        return self.y


# COMMAND_LONG has no frame: ArduPilot converts it with these (GCS_MAVLINK and the
# vehicle's mav_frame_for_command_long): take-offs relative to home on a copter, local
# offset (z = height) on a plane, DO_SET_HOME absolute.
COMMAND_LONG_FRAME = {22: 3, 84: 3, 179: 0}


def on_command_long(ap: SimAutopilot, msg: Any, src: Peer, now: float) -> None:
    cmd = Cmd(
        command=int(msg.command),
        p1=msg.param1,
        p2=msg.param2,
        p3=msg.param3,
        p4=msg.param4,
        x=msg.param5,
        y=msg.param6,
        z=msg.param7,
        frame=COMMAND_LONG_FRAME.get(int(msg.command), 3),
        is_int=False,
        src=src,
    )
    run_command(ap, cmd)


def on_command_int(ap: SimAutopilot, msg: Any, src: Peer, now: float) -> None:
    cmd = Cmd(
        command=int(msg.command),
        p1=msg.param1,
        p2=msg.param2,
        p3=msg.param3,
        p4=msg.param4,
        x=msg.x * 1e-7 if msg.frame in GLOBAL_FRAMES else float(msg.x),
        y=msg.y * 1e-7 if msg.frame in GLOBAL_FRAMES else float(msg.y),
        z=msg.z,
        frame=int(msg.frame),
        is_int=True,
        src=src,
    )
    run_command(ap, cmd)


def run_command(ap: SimAutopilot, cmd: Cmd) -> None:
    mark = len(ap._out)
    handler = COMMANDS.get(cmd.command)
    if handler is None:
        result = ACCEPTED if cmd.command in ACCEPTED_NOOP_COMMANDS else UNSUPPORTED
    else:
        result = handler(ap, cmd)
    ack = mavlink.MAVLink_command_ack_message(
        cmd.command, result, 0, 0, cmd.src.sysid, cmd.src.compid
    )
    if result == ACCEPTED:
        ap._out.insert(mark, ack)  # ACK first, then what the command caused
    else:
        ap._out.append(ack)  # the reason (STATUSTEXT) first, then the NAK
    ap.counters[f"cmd:{cmd.command}:{result}"] += 1


def cmd_set_mode(ap: SimAutopilot, cmd: Cmd) -> int:
    return set_mode_common(ap, int(cmd.p1), int(cmd.p2))


def set_mode_common(ap: SimAutopilot, base: int, custom: int) -> int:
    if base & MAV_MODE_FLAG_CUSTOM_MODE_ENABLED:
        return ACCEPTED if ap._set_mode(custom) else FAILED
    if base == MAV_MODE_FLAG_DECODE_POSITION_SAFETY:
        return ACCEPTED if custom in (0, 1) else DENIED
    return DENIED


def cmd_arm_disarm(ap: SimAutopilot, cmd: Cmd) -> int:
    if cmd.p1 == 1.0:
        return ACCEPTED if ap._arm(force=cmd.p2 == ARM_FORCE_MAGIC) else FAILED
    if cmd.p1 == 0.0:
        if not ap.armed:
            return ACCEPTED
        if ap._flying() and cmd.p2 != DISARM_FORCE_MAGIC:
            return FAILED
        ap._disarm()
        if ap._flying():
            ap._set_nav(Idle())
        return ACCEPTED
    return DENIED


def cmd_takeoff(ap: SimAutopilot, cmd: Cmd) -> int:
    fw = ap.firmware
    if fw == Firmware.ROVER or (cmd.command == 84 and fw == Firmware.PLANE):
        return UNSUPPORTED
    if not math.isfinite(cmd.z) or abs(cmd.z) > MAX_ALT_M:
        return DENIED
    if fw == Firmware.COPTER:
        if cmd.frame not in (3, 6):
            return DENIED
        alt = ap.home_alt + cmd.z
        spec = ap.mode_spec
        supports = spec.name in (
            "GUIDED",
            "LOITER",
            "ALT_HOLD",
            "POSHOLD",
            "SPORT",
            "FLOWHOLD",
            "ZIGZAG",
            "GUIDED_NOGPS",
        )
        if not ap.armed or not ap.body.on_ground or not supports or alt <= ap.body.alt:
            return FAILED
        if spec.behaviour == Behaviour.GUIDED:
            ap._set_nav(Takeoff(alt, vtol=True), Purpose.GUIDED_TAKEOFF)
        else:
            ap._set_nav(Sequence([Takeoff(alt, vtol=True), Hold(ap.body.n, ap.body.e, alt)]))
        return ACCEPTED
    # ArduPlane: QuadPlane only, COMMAND_INT in MAV_FRAME_LOCAL_OFFSET_NED (z down)
    if cmd.is_int:
        if cmd.frame != 7:
            return DENIED
        height = -cmd.z
    else:
        height = cmd.z
    if ap.model != VehicleModel.VTOL:
        return FAILED
    if ap.mode_spec.behaviour != Behaviour.GUIDED:
        ap._text(SEV_INFO, "User Takeoff only in GUIDED mode")
        return FAILED
    if not ap.armed:
        ap._text(SEV_INFO, "Must be armed for takeoff")
        return FAILED
    if ap._flying():
        ap._text(SEV_INFO, "Already flying - no takeoff")
        return FAILED
    ap._set_nav(Takeoff(ap.home_alt + height, vtol=True), Purpose.GUIDED_TAKEOFF)
    return ACCEPTED


def cmd_reposition(ap: SimAutopilot, cmd: Cmd) -> int:
    if not cmd.is_int:
        return UNSUPPORTED  # ArduPilot takes DO_REPOSITION as COMMAND_INT only
    if not (-90 <= cmd.x <= 90 and -180 <= cmd.y <= 180) or (cmd.x == 0 and cmd.y == 0):
        return DENIED
    alt = ap._alt_from_frame(cmd.frame, cmd.z)
    if alt is None:
        return DENIED
    change_mode = int(cmd.p2) & MAV_DO_REPOSITION_FLAGS_CHANGE_MODE if math.isfinite(cmd.p2) else 0
    in_guided = ap.mode_spec.behaviour == Behaviour.GUIDED
    if ap.firmware == Firmware.PLANE:
        if not (change_mode or in_guided):
            return FAILED
        if not in_guided and not ap._set_mode(mode_number(ap.firmware, "GUIDED")):
            return FAILED
        radius = cmd.p3 if math.isfinite(cmd.p3) and cmd.p3 > 0 else 0.0
        ap._guided_radius = radius
        ap._guided_goto(cmd.x, cmd.y, alt, ccw=math.isfinite(cmd.p4) and cmd.p4 != 0)
        return ACCEPTED
    if not in_guided and not change_mode:
        return DENIED
    if not in_guided and not ap._set_mode(mode_number(ap.firmware, "GUIDED")):
        return FAILED
    ap._guided_goto(cmd.x, cmd.y, alt)
    return ACCEPTED


def cmd_change_speed(ap: SimAutopilot, cmd: Cmd) -> int:
    if ap.firmware == Firmware.COPTER:
        if not (math.isfinite(cmd.p2) and cmd.p2 > 0):
            return DENIED
        if int(cmd.p1) not in (0, 1, 2, 3):
            return DENIED
        return ACCEPTED if ap._change_speed(int(cmd.p1), cmd.p2) else FAILED
    if ap.firmware == Firmware.PLANE:
        beh = ap.mode_spec.behaviour
        if beh not in (Behaviour.GUIDED, Behaviour.AUTO):
            return FAILED
    return ACCEPTED if ap._change_speed(int(cmd.p1), cmd.p2) else FAILED


def cmd_change_altitude(ap: SimAutopilot, cmd: Cmd) -> int:
    if ap.firmware != Firmware.PLANE:
        return UNSUPPORTED
    alt = ap._alt_from_frame(int(cmd.p2), cmd.p1)
    if alt is None:
        return DENIED
    ap._change_alt(alt)
    return ACCEPTED


def cmd_rtl(ap: SimAutopilot, cmd: Cmd) -> int:
    ok = ap._set_mode(mode_number(ap.firmware, "RTL"))
    if ap.firmware == Firmware.PLANE:
        return ACCEPTED
    return ACCEPTED if ok else FAILED


def cmd_land(ap: SimAutopilot, cmd: Cmd) -> int:
    if ap.firmware != Firmware.COPTER:
        return UNSUPPORTED
    return ACCEPTED if ap._set_mode(mode_number(ap.firmware, "LAND")) else FAILED


def cmd_loiter_unlim(ap: SimAutopilot, cmd: Cmd) -> int:
    ok = ap._set_mode(mode_number(ap.firmware, "LOITER"))
    if ap.firmware == Firmware.PLANE:
        return ACCEPTED
    return ACCEPTED if ok else FAILED


def cmd_mission_start(ap: SimAutopilot, cmd: Cmd) -> int:
    if (math.isfinite(cmd.p1) and cmd.p1 != 0) or (math.isfinite(cmd.p2) and cmd.p2 != 0):
        return DENIED
    auto = mode_number(ap.firmware, "AUTO")
    if ap.firmware == Firmware.PLANE:
        ap._set_mode(auto)
        return ACCEPTED
    if ap.mode == auto:
        if not ap.mission_running:
            mission_runner.start_or_resume(ap)
        return ACCEPTED
    return ACCEPTED if ap._set_mode(auto) else FAILED


def cmd_parachute(ap: SimAutopilot, cmd: Cmd) -> int:
    if ap.firmware == Firmware.ROVER:
        return UNSUPPORTED
    action = int(cmd.p1) if math.isfinite(cmd.p1) else -1
    if action == 0:
        ap.params["CHUTE_ENABLED"] = (0.0, 2)
        return ACCEPTED
    if action == 1:
        ap.params["CHUTE_ENABLED"] = (1.0, 2)
        return ACCEPTED
    if action != 2:
        return FAILED
    if ap.firmware == Firmware.PLANE:
        if ap.parachute_released:
            ap._text(SEV_NOTICE, "Parachute already released")
            return FAILED
        if ap._param("CHUTE_ENABLED") == 0:
            ap._text(SEV_NOTICE, "Parachute not enabled")
            return FAILED
        return ACCEPTED if ap._parachute_release() else FAILED
    ap._parachute_release()  # ArduCopter accepts and checks inside
    return ACCEPTED


def cmd_set_home(ap: SimAutopilot, cmd: Cmd) -> int:
    if cmd.p1 == 1:
        if not ap.ekf_position:
            return FAILED
        ap._set_home(ap.body.n, ap.body.e, ap.body.alt)
        return ACCEPTED
    if not (-90 <= cmd.x <= 90 and -180 <= cmd.y <= 180) or (cmd.x == 0 and cmd.y == 0):
        return FAILED
    frame = cmd.frame if cmd.is_int else 0
    alt = ap._alt_from_frame(frame, cmd.z)
    if alt is None:
        return FAILED
    n, e = ap.frame.to_ne(cmd.x, cmd.y)
    ap._set_home(n, e, alt)
    return ACCEPTED


def cmd_set_mission_current(ap: SimAutopilot, cmd: Cmd) -> int:
    seq = int(cmd.p1) if math.isfinite(cmd.p1) else -1
    if not ap._set_mission_current(seq):
        return FAILED
    return ACCEPTED


def cmd_fence_enable(ap: SimAutopilot, cmd: Cmd) -> int:
    action = int(cmd.p1) if math.isfinite(cmd.p1) else -1
    if action not in (0, 1, 2):
        return FAILED
    if action == 1 and not ap.fence_present():
        # GCS_MAVLINK::handle_command_do_fence_enable: FAILED unless AC_Fence::present()
        # (FENCE_TYPE polygon-only and the uploaded fence not loaded yet, as real SITL does)
        return FAILED
    ap.params["FENCE_ENABLE"] = (1.0 if action == 1 else 0.0, 2)
    return ACCEPTED


def cmd_vtol_transition(ap: SimAutopilot, cmd: Cmd) -> int:
    if ap.model != VehicleModel.VTOL:
        ap._text(SEV_NOTICE, "VTOL not available")
        return FAILED
    if ap.mode_spec.behaviour != Behaviour.AUTO:
        ap._text(SEV_NOTICE, "VTOL Transition only in AUTO")
        return FAILED
    return ACCEPTED


def cmd_set_message_interval(ap: SimAutopilot, cmd: Cmd) -> int:
    if not (math.isfinite(cmd.p1) and math.isfinite(cmd.p2)):
        return DENIED
    msg_id, interval_us = int(cmd.p1), cmd.p2
    if interval_us == 0:
        interval: float | None = None
    elif interval_us < 0:
        interval = 0.0
    else:
        interval = interval_us / 1e6
    return ACCEPTED if ap.streams.set_interval(msg_id, interval, ap._t) else FAILED


def cmd_get_message_interval(ap: SimAutopilot, cmd: Cmd) -> int:
    msg_id = int(cmd.p1) if math.isfinite(cmd.p1) else -1
    if msg_id not in S.STREAMABLE:
        ap._out.append(mavlink.MAVLink_message_interval_message(max(0, min(65535, msg_id)), 0))
        return ACCEPTED
    iv = ap.streams.interval(msg_id)
    ap._out.append(
        mavlink.MAVLink_message_interval_message(msg_id, int(iv * 1e6) if iv > 0 else -1)
    )
    return ACCEPTED


def cmd_request_message(ap: SimAutopilot, cmd: Cmd) -> int:
    msg_id = int(cmd.p1) if math.isfinite(cmd.p1) else -1
    if msg_id not in telemetry.ONE_SHOT:
        return UNSUPPORTED
    msg = telemetry.build(ap, msg_id, ap._t)
    if msg is None:
        return FAILED
    ap._out.append(msg)
    return ACCEPTED


def cmd_autopilot_capabilities(ap: SimAutopilot, cmd: Cmd) -> int:
    ap._out.append(telemetry.autopilot_version(ap))
    return ACCEPTED


def cmd_get_home(ap: SimAutopilot, cmd: Cmd) -> int:
    if not ap.home_set:
        return FAILED
    ap._out.append(telemetry.home_position(ap, ap._t))
    return ACCEPTED


def cmd_mount(ap: SimAutopilot, cmd: Cmd) -> int:
    if ap.airframe.camera is None:
        return UNSUPPORTED
    cam = ap.airframe.camera
    pitch = cmd.p1
    yaw = cmd.p3 if cmd.command == 205 else cmd.p2
    if math.isfinite(pitch):
        ap.mount_pitch_deg = max(cam.pitch_min_deg, min(cam.pitch_max_deg, pitch))
    if math.isfinite(yaw):
        ap.mount_yaw_deg = yaw
    return ACCEPTED


def cmd_calibration(ap: SimAutopilot, cmd: Cmd) -> int:
    if ap.armed:
        return DENIED
    if cmd.p3 == 1:
        ap._text(SEV_INFO, "Updating barometer calibration")
        ap._text(SEV_INFO, "Barometer calibration complete")
    if cmd.p6 == 2 and ap.airframe.is_fixed_wing:
        ap._text(SEV_INFO, "Airspeed 1 calibration started")
    return ACCEPTED


# other messages ---------------------------------------------------------------


def cmd_land_start(ap: SimAutopilot, cmd: Cmd) -> int:
    """MAV_CMD_DO_LAND_START: continue the mission at its landing sequence."""
    if ap.firmware == Firmware.ROVER:
        return UNSUPPORTED
    return ACCEPTED if mission_runner.jump_to_landing_sequence(ap) else FAILED


COMMANDS: dict[int, Callable[[SimAutopilot, Cmd], int]] = {
    176: cmd_set_mode,
    400: cmd_arm_disarm,
    22: cmd_takeoff,
    84: cmd_takeoff,
    192: cmd_reposition,
    178: cmd_change_speed,
    186: cmd_change_altitude,
    20: cmd_rtl,
    21: cmd_land,
    85: cmd_land,
    17: cmd_loiter_unlim,
    300: cmd_mission_start,
    208: cmd_parachute,
    179: cmd_set_home,
    224: cmd_set_mission_current,
    207: cmd_fence_enable,
    3000: cmd_vtol_transition,
    511: cmd_set_message_interval,
    510: cmd_get_message_interval,
    512: cmd_request_message,
    520: cmd_autopilot_capabilities,
    410: cmd_get_home,
    205: cmd_mount,
    1000: cmd_mount,
    241: cmd_calibration,
    189: cmd_land_start,
}
