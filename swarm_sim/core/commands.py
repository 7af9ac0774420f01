"""Command handling (COMMAND_LONG / COMMAND_INT) for `SimAutopilot`, as ArduPilot's
GCS_MAVLINK and its vehicle subclasses do it: one handler per MAV_CMD in `COMMANDS`,
each returning the MAV_RESULT for the COMMAND_ACK. A handler that succeeds has its ACK
sent before what the command caused; a refused command's reason (STATUSTEXT) goes
before its NAK, which is the order ArduPilot's messages arrive in."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from . import streams as S
from . import telemetry
from .airframes import VehicleModel
from .firmware import SEV_INFO, SEV_NOTICE, Behaviour, Firmware, mode_number
from .mission import GLOBAL_FRAMES, MAX_ALT_M, Peer
from .navigation import Hold, Idle, Purpose, Sequence, Takeoff
from .vehicle import Vehicle

# MAV_RESULT
ACCEPTED, TEMPORARILY_REJECTED, DENIED, UNSUPPORTED, FAILED = 0, 1, 2, 3, 4

ARM_FORCE_MAGIC = 2989.0
DISARM_FORCE_MAGIC = 21196.0
MAV_MODE_FLAG_CUSTOM_MODE_ENABLED = 1
MAV_MODE_FLAG_DECODE_POSITION_SAFETY = 128
MAV_DO_REPOSITION_FLAGS_CHANGE_MODE = 1

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


def on_command_long(v: Vehicle, msg: Any, src: Peer, now: float) -> None:
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
    run_command(v, cmd)


def on_command_int(v: Vehicle, msg: Any, src: Peer, now: float) -> None:
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
    run_command(v, cmd)


def run_command(v: Vehicle, cmd: Cmd) -> None:
    mark = v.out.mark()
    handler = COMMANDS.get(cmd.command)
    if handler is None:
        result = ACCEPTED if cmd.command in ACCEPTED_NOOP_COMMANDS else UNSUPPORTED
    else:
        result = handler(v, cmd)
    ack = mavlink.MAVLink_command_ack_message(
        cmd.command, result, 0, 0, cmd.src.sysid, cmd.src.compid
    )
    # the ACK first, then what the command caused; a refusal's reason (STATUSTEXT) too:
    # ArduPilot answers at once and sends the text from its queue after (seen against
    # SITL: "Arm: In landing sequence", "PreArm: QLAND mode not armable")
    v.out.insert_at(mark, ack)
    v.counters[f"cmd:{cmd.command}:{result}"] += 1


def cmd_set_mode(v: Vehicle, cmd: Cmd) -> int:
    return set_mode_common(v, int(cmd.p1), int(cmd.p2))


def set_mode_common(v: Vehicle, base: int, custom: int) -> int:
    if base & MAV_MODE_FLAG_CUSTOM_MODE_ENABLED:
        return ACCEPTED if v.modes.set_mode(custom) else FAILED
    if base == MAV_MODE_FLAG_DECODE_POSITION_SAFETY:
        return ACCEPTED if custom in (0, 1) else DENIED
    return DENIED


def cmd_arm_disarm(v: Vehicle, cmd: Cmd) -> int:
    if cmd.p1 == 1.0:
        return ACCEPTED if v.arming.arm(v.modes.spec, force=cmd.p2 == ARM_FORCE_MAGIC) else FAILED
    if cmd.p1 == 0.0:
        if not v.arming.armed:
            return ACCEPTED
        if v.navigator.flying() and cmd.p2 != DISARM_FORCE_MAGIC:
            return FAILED
        v.arming.disarm()
        if v.navigator.flying():
            v.navigator.set(Idle())
        return ACCEPTED
    return DENIED


def cmd_takeoff(v: Vehicle, cmd: Cmd) -> int:
    fw, nav, b = v.firmware, v.navigator, v.body
    if fw == Firmware.ROVER or (cmd.command == 84 and fw == Firmware.PLANE):
        return UNSUPPORTED
    if not math.isfinite(cmd.z) or abs(cmd.z) > MAX_ALT_M:
        return DENIED
    if fw == Firmware.COPTER:
        if cmd.frame not in (3, 6):
            return DENIED
        alt = v.home.alt + cmd.z
        spec = v.modes.spec
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
        if not v.arming.armed or not b.on_ground or not supports or alt <= b.alt:
            return FAILED
        if spec.behaviour == Behaviour.GUIDED:
            nav.set(Takeoff(alt, vtol=True), Purpose.GUIDED_TAKEOFF)
        else:
            nav.set(Sequence([Takeoff(alt, vtol=True), Hold(b.n, b.e, alt)]))
        return ACCEPTED
    # ArduPlane: QuadPlane only, COMMAND_INT in MAV_FRAME_LOCAL_OFFSET_NED (z down)
    if cmd.is_int:
        if cmd.frame != 7:
            return DENIED
        height = -cmd.z
    else:
        height = cmd.z
    if v.airframe.model != VehicleModel.VTOL:
        return FAILED
    if v.modes.behaviour != Behaviour.GUIDED:
        v.out.text(SEV_INFO, "User Takeoff only in GUIDED mode")
        return FAILED
    if not v.arming.armed:
        v.out.text(SEV_INFO, "Must be armed for takeoff")
        return FAILED
    if nav.flying():
        v.out.text(SEV_INFO, "Already flying - no takeoff")
        return FAILED
    nav.set(Takeoff(v.home.alt + height, vtol=True), Purpose.GUIDED_TAKEOFF)
    return ACCEPTED


def cmd_reposition(v: Vehicle, cmd: Cmd) -> int:
    if not cmd.is_int:
        return UNSUPPORTED  # ArduPilot takes DO_REPOSITION as COMMAND_INT only
    if not (-90 <= cmd.x <= 90 and -180 <= cmd.y <= 180) or (cmd.x == 0 and cmd.y == 0):
        return DENIED
    alt = v.home.alt_from_frame(cmd.frame, cmd.z)
    if alt is None:
        return DENIED
    change_mode = int(cmd.p2) & MAV_DO_REPOSITION_FLAGS_CHANGE_MODE if math.isfinite(cmd.p2) else 0
    in_guided = v.modes.behaviour == Behaviour.GUIDED
    guided = mode_number(v.firmware, "GUIDED")
    if v.firmware == Firmware.PLANE:
        if not (change_mode or in_guided):
            return FAILED
        if not in_guided and not v.modes.set_mode(guided):
            return FAILED
        v.navigator.guided_radius = cmd.p3 if math.isfinite(cmd.p3) and cmd.p3 > 0 else 0.0
        v.navigator.goto(cmd.x, cmd.y, alt)
        return ACCEPTED
    if not in_guided and not change_mode:
        return DENIED
    if not in_guided and not v.modes.set_mode(guided):
        return FAILED
    v.navigator.goto(cmd.x, cmd.y, alt)
    return ACCEPTED


def cmd_change_speed(v: Vehicle, cmd: Cmd) -> int:
    if v.firmware == Firmware.COPTER:
        if not (math.isfinite(cmd.p2) and cmd.p2 > 0):
            return DENIED
        if int(cmd.p1) not in (0, 1, 2, 3):
            return DENIED
        return ACCEPTED if v.navigator.change_speed(int(cmd.p1), cmd.p2) else FAILED
    if v.firmware == Firmware.PLANE and v.modes.behaviour not in (
        Behaviour.GUIDED,
        Behaviour.AUTO,
    ):
        return FAILED
    return ACCEPTED if v.navigator.change_speed(int(cmd.p1), cmd.p2) else FAILED


def cmd_change_altitude(v: Vehicle, cmd: Cmd) -> int:
    if v.firmware != Firmware.PLANE:
        return UNSUPPORTED
    alt = v.home.alt_from_frame(int(cmd.p2), cmd.p1)
    if alt is None:
        return DENIED
    v.navigator.change_alt(alt, guided=v.modes.behaviour == Behaviour.GUIDED)
    return ACCEPTED


def cmd_rtl(v: Vehicle, cmd: Cmd) -> int:
    ok = v.modes.set_mode(mode_number(v.firmware, "RTL"))
    if v.firmware == Firmware.PLANE:
        return ACCEPTED
    return ACCEPTED if ok else FAILED


def cmd_land(v: Vehicle, cmd: Cmd) -> int:
    if v.firmware != Firmware.COPTER:
        return UNSUPPORTED
    return ACCEPTED if v.modes.set_mode(mode_number(v.firmware, "LAND")) else FAILED


def cmd_loiter_unlim(v: Vehicle, cmd: Cmd) -> int:
    ok = v.modes.set_mode(mode_number(v.firmware, "LOITER"))
    if v.firmware == Firmware.PLANE:
        return ACCEPTED
    return ACCEPTED if ok else FAILED


def cmd_mission_start(v: Vehicle, cmd: Cmd) -> int:
    if (math.isfinite(cmd.p1) and cmd.p1 != 0) or (math.isfinite(cmd.p2) and cmd.p2 != 0):
        return DENIED
    auto = mode_number(v.firmware, "AUTO")
    if v.firmware == Firmware.PLANE:
        v.modes.set_mode(auto)
        return ACCEPTED
    if v.modes.mode == auto:
        if not v.stores.progress.running:
            v.mission.start_or_resume()
        return ACCEPTED
    return ACCEPTED if v.modes.set_mode(auto) else FAILED


def cmd_parachute(v: Vehicle, cmd: Cmd) -> int:
    if v.firmware == Firmware.ROVER:
        return UNSUPPORTED
    action = int(cmd.p1) if math.isfinite(cmd.p1) else -1
    if action in (0, 1):
        v.params.set_value("CHUTE_ENABLED", float(action))
        return ACCEPTED
    if action != 2:
        return FAILED
    if v.firmware == Firmware.PLANE:
        if v.arming.parachute_released:
            v.out.text(SEV_NOTICE, "Parachute already released")
            return FAILED
        if v.params.value("CHUTE_ENABLED") == 0:
            v.out.text(SEV_NOTICE, "Parachute not enabled")
            return FAILED
        return ACCEPTED if v.arming.parachute_release() else FAILED
    v.arming.parachute_release()  # ArduCopter accepts and checks inside
    return ACCEPTED


def cmd_set_home(v: Vehicle, cmd: Cmd) -> int:
    if cmd.p1 == 1:
        if not v.sensors.ekf_position:
            return FAILED
        v.home.set(v.body.n, v.body.e, v.body.alt)
    else:
        if not (-90 <= cmd.x <= 90 and -180 <= cmd.y <= 180) or (cmd.x == 0 and cmd.y == 0):
            return FAILED
        frame = cmd.frame if cmd.is_int else 0
        alt = v.home.alt_from_frame(frame, cmd.z)
        if alt is None:
            return FAILED
        n, e = v.frame.to_ne(cmd.x, cmd.y)
        v.home.set(n, e, alt)
    v.out.send(v.home.position_message(v.timeline.t))
    return ACCEPTED


def cmd_set_mission_current(v: Vehicle, cmd: Cmd) -> int:
    seq = int(cmd.p1) if math.isfinite(cmd.p1) else -1
    if not v.mission.set_current(seq):
        return FAILED
    v.out.send(telemetry.mission_current(v))
    return ACCEPTED


def cmd_fence_enable(v: Vehicle, cmd: Cmd) -> int:
    action = int(cmd.p1) if math.isfinite(cmd.p1) else -1
    if action not in (0, 1, 2):
        return FAILED
    if action == 1 and not v.fence.present():
        # GCS_MAVLINK::handle_command_do_fence_enable: FAILED unless AC_Fence::present()
        # (FENCE_TYPE polygon-only and the uploaded fence not loaded yet, as real SITL does)
        return FAILED
    v.params.set_value("FENCE_ENABLE", 1.0 if action == 1 else 0.0)
    return ACCEPTED


def cmd_vtol_transition(v: Vehicle, cmd: Cmd) -> int:
    if v.airframe.model != VehicleModel.VTOL:
        v.out.text(SEV_NOTICE, "VTOL not available")
        return FAILED
    if v.modes.behaviour != Behaviour.AUTO:
        v.out.text(SEV_NOTICE, "VTOL Transition only in AUTO")
        return FAILED
    return ACCEPTED


def cmd_set_message_interval(v: Vehicle, cmd: Cmd) -> int:
    if not (math.isfinite(cmd.p1) and math.isfinite(cmd.p2)):
        return DENIED
    msg_id, interval_us = int(cmd.p1), cmd.p2
    if interval_us == 0:
        interval: float | None = None
    elif interval_us < 0:
        interval = 0.0
    else:
        interval = interval_us / 1e6
    return ACCEPTED if v.streams.set_interval(msg_id, interval, v.timeline.t) else FAILED


def cmd_get_message_interval(v: Vehicle, cmd: Cmd) -> int:
    msg_id = int(cmd.p1) if math.isfinite(cmd.p1) else -1
    if msg_id not in S.STREAMABLE:
        v.out.send(mavlink.MAVLink_message_interval_message(max(0, min(65535, msg_id)), 0))
        return ACCEPTED
    iv = v.streams.interval(msg_id)
    v.out.send(mavlink.MAVLink_message_interval_message(msg_id, int(iv * 1e6) if iv > 0 else -1))
    return ACCEPTED


def cmd_request_message(v: Vehicle, cmd: Cmd) -> int:
    msg_id = int(cmd.p1) if math.isfinite(cmd.p1) else -1
    if msg_id not in telemetry.ONE_SHOT:
        return UNSUPPORTED
    msg = telemetry.build(v, msg_id, v.timeline.t)
    if msg is None:
        return FAILED
    v.out.send(msg)
    return ACCEPTED


def cmd_autopilot_capabilities(v: Vehicle, cmd: Cmd) -> int:
    v.out.send(telemetry.autopilot_version(v))
    return ACCEPTED


def cmd_get_home(v: Vehicle, cmd: Cmd) -> int:
    if not v.home.is_set:
        return FAILED
    v.out.send(v.home.position_message(v.timeline.t))
    return ACCEPTED


def cmd_mount(v: Vehicle, cmd: Cmd) -> int:
    if v.mount is None:
        return UNSUPPORTED
    v.mount.point(cmd.p1, cmd.p3 if cmd.command == 205 else cmd.p2)
    return ACCEPTED


def cmd_calibration(v: Vehicle, cmd: Cmd) -> int:
    if v.arming.armed:
        return DENIED
    if cmd.p3 == 1:
        v.out.text(SEV_INFO, "Updating barometer calibration")
        v.out.text(SEV_INFO, "Barometer calibration complete")
    if cmd.p6 == 2 and v.airframe.is_fixed_wing:
        v.out.text(SEV_INFO, "Airspeed 1 calibration started")
    return ACCEPTED


def cmd_land_start(v: Vehicle, cmd: Cmd) -> int:
    """MAV_CMD_DO_LAND_START: continue the mission at its landing sequence."""
    if v.firmware == Firmware.ROVER:
        return UNSUPPORTED
    return ACCEPTED if v.mission.jump_to_landing_sequence() else FAILED


COMMANDS: dict[int, Callable[[Vehicle, Cmd], int]] = {
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
