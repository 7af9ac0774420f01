"""What each `ApRequest` becomes in MAVLink, per vehicle type: a plan of steps (data),
built by pure functions and executed by `runner.RequestRunner`.

| request        | COPTER                         | VTOL (QuadPlane)          | PLANE                          | ROVER / BOAT   |
|----------------|--------------------------------|---------------------------|--------------------------------|----------------|
| SetMode        | DO_SET_MODE (custom mode), confirmed by HEARTBEAT | same   | same                           | same           |
| Arm / Disarm   | COMPONENT_ARM_DISARM (force: 21196); PLANE, VTOL: DO_SET_MISSION_CURRENT 1 first (leaves "In landing sequence") ||||
| Takeoff        | [GUIDED] + NAV_TAKEOFF (alt)   | [GUIDED] + NAV_TAKEOFF    | [PARAM TKOFF_ALT] + TAKEOFF mode | ok, nothing  |
| Goto           | DO_REPOSITION (COMMAND_INT, change-mode flag: GUIDED)                                        ||||
| ChangeSpeed    | DO_CHANGE_SPEED ground         | airspeed (or ground)      | airspeed (or ground)           | ground         |
| ChangeAltitude | DO_REPOSITION to the last Goto target (GUIDED only) | DO_CHANGE_ALTITUDE (COMMAND_INT) | same       | ok, nothing    |
| ReturnToLaunch | RTL mode                       | RTL mode (Q_RTL_MODE)     | RTL mode                       | RTL mode       |
| Land           | LAND mode                      | QLAND mode                | DO_LAND_START (mission landing)| HOLD mode      |
| Parachute      | DO_PARACHUTE release           | same                      | same                           | not applicable |
| StartMission   | DO_SET_MISSION_CURRENT (first, at least 1) + [AUTO] + MISSION_START, then MISSION_CURRENT checked ||||
| Upload*/Download | mission protocol (mission_protocol.py); UploadFence(enable=...) + DO_FENCE_ENABLE          ||||
| SetParam       | PARAM_SET, confirmed by the PARAM_VALUE echo                                                 ||||
| ReadParam      | PARAM_REQUEST_READ, answered by PARAM_VALUE (its own lane: never behind a command)           ||||
| Calibrate      | PREFLIGHT_CALIBRATION (gyro p1, baro p3, accel level p5=2, airspeed p6=2); compass: DO_START_MAG_CAL ||||

StartMission: ArduPilot accepts MISSION_START in AUTO while a mission runs and ignores
it, and a mission uploaded in AUTO keeps the old current item ("Auto mission changed but
failed to restart command"), so DO_SET_MISSION_CURRENT always comes first (recorded:
`mission-start-in-auto`), and the request succeeds only once MISSION_CURRENT has reported
that item (else `ApError.NOT_STARTED`). UploadFence's DO_FENCE_ENABLE(1) waits until
SYS_STATUS reports the geofence present: ArduPilot refuses the enable (FAILED) until it
has loaded the uploaded fence (AC_Fence::present(); with FENCE_TYPE polygon-only, loading
happens in the fence task after the upload and only once the EKF has an origin).

A mode change (SetMode, and the mode steps of Takeoff, StartMission, ReturnToLaunch,
Land) succeeds only once a HEARTBEAT after the COMMAND_ACK shows the mode taken (or the
autopilot moved on from the mode it was in: a QuadPlane's RTL becomes QRTL at once), so
the next step that depends on it (an Arm after SetMode) never runs in the old mode;
the HEARTBEAT is asked for at once (REQUEST_MESSAGE), not waited for at 1 Hz.

Take-off needs the vehicle armed (Arm first): the plan fails early with a clear reason
rather than letting ArduPilot answer FAILED. [x] = a step skipped when already true.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from swarm_proto import VehicleType
from swarm_proto.ardupilot import mode_number

from . import requests as rq
from .conversion import ConversionError, fence_items, mission_items, rally_items
from .mission_item import MavCmd, MavFrame, MissionItem
from .requests import ApError, ApRequest, ApResult, MissionKind
from .state import SENSOR_GEOFENCE, AutopilotState

FORCE_MAGIC = 21196  # COMPONENT_ARM_DISARM param2: skip checks
MAV_MODE_FLAG_CUSTOM_MODE_ENABLED = 1
MAV_DO_REPOSITION_FLAGS_CHANGE_MODE = 1
PARACHUTE_RELEASE = 2
SPEED_AIRSPEED = 0
SPEED_GROUNDSPEED = 1

_FIXED_WING = (VehicleType.PLANE, VehicleType.VTOL)
_GROUND = (VehicleType.ROVER, VehicleType.BOAT)
_AUTOPILOT_TYPES = (VehicleType.PLANE, VehicleType.VTOL, VehicleType.COPTER, *_GROUND)

#: Requests that jump the command queue and supersede a running non-urgent command.
URGENT = (rq.Parachute, rq.ReturnToLaunch, rq.Land)
#: Requests that run in the mission-transfer lane (beside commands, not behind them).
TRANSFERS = (
    rq.UploadMission,
    rq.UploadMissionItems,
    rq.UploadFence,
    rq.UploadRally,
    rq.DownloadMission,
)
#: Requests that run in a lane of their own (reads: they neither wait behind a command
#: nor hold one up, and a name the autopilot does not have costs only their own time).
QUERIES = (rq.ReadParam,)
#: Requests that do not depend on the vehicle type.
TYPE_FREE = (
    rq.UploadMissionItems,
    rq.UploadFence,
    rq.UploadRally,
    rq.DownloadMission,
    rq.SetParam,
    rq.ReadParam,
)
CALIBRATIONS = ("gyro", "baro", "airspeed", "accel", "compass")
FENCE_LOAD_WAIT_S = 5.0  # longest wait for SYS_STATUS to show the uploaded fence loaded
FENCE_ENABLE_RETRIES = 3  # a FAILED enable (fence still not loaded) tried again


class InvalidRequest(ValueError):
    """Our own misuse: a request no autopilot could carry out (NaN, unknown mode...)."""


@dataclass(frozen=True, slots=True)
class CommandSpec:
    """A COMMAND_LONG (or COMMAND_INT when `frame` is set), answered by COMMAND_ACK."""

    command: int
    label: str
    params: tuple[float, ...] = (0.0,) * 7  # p1..p7 (COMMAND_INT: p1..p4, x, y, z)
    frame: int | None = None  # COMMAND_INT frame; None = COMMAND_LONG
    skip_if_mode: int | None = None  # skip when the autopilot is already in this mode
    mode_name: str = ""  # for DO_SET_MODE: the mode, to explain a refusal
    timeout_s: float | None = None  # None: the runner's default
    attempts: int | None = None
    in_progress_timeout_s: float = 10.0
    needs_armed: bool = False  # a FAILED answer while disarmed says "not armed"
    wait_sensor: int = 0  # SYS_STATUS present bit to wait for (in a SYS_STATUS received
    #                       after the step began) before sending; sent anyway after wait_s
    wait_s: float = 0.0
    failed_retries: int = 0  # FAILED answers retried (after retry_delay_s) this many times
    confirm_mode: int | None = None  # DO_SET_MODE: wait for a HEARTBEAT showing it
    optional: bool = False  # a refusal does not fail the plan (noted in the reason)


@dataclass(frozen=True, slots=True)
class VerifySpec:
    """No message: wait until the autopilot has reported MISSION_CURRENT == `seq` since
    the request began; `timeout_s` without it fails the request (ApError.NOT_STARTED)."""

    seq: int
    label: str
    timeout_s: float = 5.0


@dataclass(frozen=True, slots=True)
class ParamSpec:
    name: str
    value: float
    label: str
    optional: bool = False  # failure does not fail the plan (noted in the reason)
    read: bool = False  # PARAM_REQUEST_READ (value unused) instead of PARAM_SET


@dataclass(frozen=True, slots=True)
class TransferSpec:
    kind: MissionKind
    label: str
    items: tuple[MissionItem, ...] | None = None  # None: download


Step = CommandSpec | ParamSpec | TransferSpec | VerifySpec


@dataclass(frozen=True, slots=True)
class Plan:
    steps: tuple[Step, ...]
    goto_target: tuple[float, float, float] | None = None  # remembered on success
    notes: tuple[str, ...] = field(default=())


@dataclass(frozen=True, slots=True)
class PlanContext:
    state: AutopilotState
    vehicle_type: VehicleType
    last_goto: tuple[float, float, float] | None = None


def _finite(*values: float) -> bool:
    return all(isinstance(v, int | float) and math.isfinite(v) for v in values)


def _latlon_ok(lat: float, lon: float) -> bool:
    return _finite(lat, lon) and -90.0 <= lat <= 90.0 and -180.0 <= lon <= 180.0


def check_request(request: ApRequest, vehicle_type: VehicleType | None) -> None:
    """Raise InvalidRequest if `request` is malformed (whatever the autopilot's state).
    `vehicle_type` None = not known yet: type-specific checks wait for the plan."""
    r = request
    if isinstance(r, rq.SetMode):
        if vehicle_type in _AUTOPILOT_TYPES:
            try:
                mode_number(vehicle_type, r.mode)
            except ValueError as exc:
                raise InvalidRequest(str(exc)) from exc
    elif isinstance(r, rq.Takeoff | rq.ChangeAltitude):
        if not (_finite(r.alt_rel_m) and -1000.0 <= r.alt_rel_m <= 10000.0):
            raise InvalidRequest(f"{type(r).__name__}: altitude {r.alt_rel_m} m")
        if isinstance(r, rq.Takeoff) and r.alt_rel_m <= 0:
            raise InvalidRequest("Takeoff: altitude must be above home")
    elif isinstance(r, rq.Goto):
        if not (_latlon_ok(r.lat_deg, r.lon_deg) and _finite(r.alt_rel_m)):
            raise InvalidRequest(f"Goto: bad target ({r.lat_deg}, {r.lon_deg}, {r.alt_rel_m})")
    elif isinstance(r, rq.ChangeSpeed):
        if not (_finite(r.speed_m_s) and 0 < r.speed_m_s <= 300):
            raise InvalidRequest(f"ChangeSpeed: speed {r.speed_m_s} m/s")
    elif isinstance(r, rq.StartMission):
        if not 0 <= r.first_item <= 65535:
            raise InvalidRequest(f"StartMission: first_item {r.first_item}")
    elif isinstance(r, rq.SetParam | rq.ReadParam):
        if not (0 < len(r.name) <= 16 and r.name.isascii() and r.name.isprintable()):
            raise InvalidRequest(f"{type(r).__name__}: bad name {r.name!r}")
        if isinstance(r, rq.SetParam) and not _finite(r.value):
            raise InvalidRequest(f"SetParam {r.name}: value {r.value}")
    elif isinstance(r, rq.Calibrate):
        if r.what not in CALIBRATIONS:
            raise InvalidRequest(f"Calibrate: {r.what!r} is not one of {', '.join(CALIBRATIONS)}")
    elif isinstance(r, rq.UploadMission):
        if vehicle_type in _AUTOPILOT_TYPES:
            try:
                mission_items(r.items, vehicle_type)
            except ConversionError as exc:
                raise InvalidRequest(str(exc)) from exc
    elif isinstance(r, rq.UploadFence):
        try:
            fence_items(r)
        except ConversionError as exc:
            raise InvalidRequest(str(exc)) from exc
    elif isinstance(r, rq.UploadRally):
        try:
            rally_items(r)
        except ConversionError as exc:
            raise InvalidRequest(str(exc)) from exc
    elif isinstance(r, rq.UploadMissionItems):
        for it in r.items:
            problem = it.problem()
            if problem:
                raise InvalidRequest(f"UploadMissionItems item {it.seq}: {problem}")
    elif not isinstance(r, ApRequest):
        raise InvalidRequest(f"not an ApRequest: {r!r}")


def _done(request: ApRequest, ok: bool, reason: str, error: ApError = ApError.NONE) -> ApResult:
    return ApResult(request.request_id, ok, reason, error=error)


def _mode(vt: VehicleType, name: str, label: str, skip_if_current: bool = False) -> CommandSpec:
    number = mode_number(vt, name)
    return CommandSpec(
        MavCmd.DO_SET_MODE,
        label,
        (MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, float(number), 0, 0, 0, 0, 0),
        skip_if_mode=number if skip_if_current else None,
        mode_name=name,
        confirm_mode=number,
    )


def _long(command: int, label: str, *params: float, **kw: object) -> CommandSpec:
    p = tuple(float(x) for x in params) + (0.0,) * (7 - len(params))
    return CommandSpec(command, label, p, **kw)  # type: ignore[arg-type]


def _reposition(label: str, lat: float, lon: float, alt: float, change_mode: bool) -> CommandSpec:
    flags = MAV_DO_REPOSITION_FLAGS_CHANGE_MODE if change_mode else 0
    return CommandSpec(
        MavCmd.DO_REPOSITION,
        label,
        (-1.0, float(flags), 0.0, math.nan, lat, lon, alt),
        frame=MavFrame.GLOBAL_RELATIVE_ALT,
    )


def plan_request(request: ApRequest, ctx: PlanContext) -> Plan | ApResult:
    """The steps for `request` now, or its result when nothing needs sending."""
    r, vt, st = request, ctx.vehicle_type, ctx.state
    name = type(r).__name__
    if vt not in _AUTOPILOT_TYPES and not isinstance(r, TYPE_FREE):
        return _done(
            r,
            False,
            f"{name}: vehicle type unknown (configure it or wait for a HEARTBEAT)",
            ApError.UNKNOWN_VEHICLE,
        )
    fixed_wing, ground = vt in _FIXED_WING, vt in _GROUND
    if isinstance(r, rq.SetMode):
        try:
            return Plan((_mode(vt, r.mode, f"SetMode {r.mode.upper()}"),))
        except ValueError as exc:
            return _done(r, False, str(exc), ApError.DENIED)
    if isinstance(r, rq.Arm | rq.Disarm):
        arm = isinstance(r, rq.Arm)
        arming = _long(
            MavCmd.COMPONENT_ARM_DISARM, name, 1.0 if arm else 0.0, FORCE_MAGIC if r.force else 0.0
        )
        if arm and fixed_wing and not st.armed and not r.force:
            # ArduPlane refuses to arm "In landing sequence" after a landing its mission
            # flew (AP_Mission keeps the flag until its current item is set again, which
            # clears it even when answered FAILED for want of a mission)
            leave = _long(
                MavCmd.DO_SET_MISSION_CURRENT, "Arm: out of the landing sequence", 1, optional=True
            )
            return Plan((leave, arming))
        return Plan((arming,))
    if isinstance(r, rq.Takeoff):
        if ground:
            return _done(r, True, f"{vt.name} does not take off: nothing to do")
        # ArduPilot refuses take-off while disarmed (FAILED, explained as "not armed");
        # the state's armed flag may lag a just-accepted Arm by one HEARTBEAT, so the
        # autopilot decides rather than this plan.
        if vt == VehicleType.PLANE:
            return Plan(
                (
                    ParamSpec("TKOFF_ALT", r.alt_rel_m, "Takeoff TKOFF_ALT", optional=True),
                    _mode(vt, "TAKEOFF", "Takeoff TAKEOFF mode"),
                )
            )
        return Plan(
            (
                _mode(vt, "GUIDED", "Takeoff GUIDED", skip_if_current=True),
                _long(
                    MavCmd.NAV_TAKEOFF,
                    "Takeoff NAV_TAKEOFF",
                    0,
                    0,
                    0,
                    math.nan,
                    0,
                    0,
                    r.alt_rel_m,
                    needs_armed=True,
                ),
            )
        )
    if isinstance(r, rq.Goto):
        return Plan(
            (_reposition("Goto", r.lat_deg, r.lon_deg, r.alt_rel_m, change_mode=True),),
            goto_target=(r.lat_deg, r.lon_deg, r.alt_rel_m),
        )
    if isinstance(r, rq.ChangeSpeed):
        kind = SPEED_AIRSPEED if (r.airspeed and fixed_wing) else SPEED_GROUNDSPEED
        return Plan((_long(MavCmd.DO_CHANGE_SPEED, name, kind, r.speed_m_s, -1.0),))
    if isinstance(r, rq.ChangeAltitude):
        if ground:
            return _done(r, True, f"{vt.name} has no altitude to change: nothing to do")
        if fixed_wing:
            return Plan(
                (
                    CommandSpec(
                        MavCmd.DO_CHANGE_ALTITUDE,
                        name,
                        (r.alt_rel_m, float(MavFrame.GLOBAL_RELATIVE_ALT), 0, 0, 0, 0, 0),
                        frame=MavFrame.GLOBAL_RELATIVE_ALT,
                    ),
                )
            )
        if st.mode_name != "GUIDED":
            return _done(
                r,
                False,
                f"ChangeAltitude: COPTER changes altitude in GUIDED only "
                f"(now {st.mode_name or 'unknown'})",
                ApError.FAILED,
            )
        if ctx.last_goto is not None:
            lat, lon = ctx.last_goto[0], ctx.last_goto[1]
        elif st.lat_deg is not None and st.lon_deg is not None:
            lat, lon = st.lat_deg, st.lon_deg
        else:
            return _done(r, False, "ChangeAltitude: no position yet", ApError.NO_POSITION)
        return Plan(
            (_reposition(name, lat, lon, r.alt_rel_m, change_mode=False),),
            goto_target=(lat, lon, r.alt_rel_m),
        )
    if isinstance(r, rq.ReturnToLaunch):
        return Plan((_mode(vt, "RTL", "ReturnToLaunch RTL"),))
    if isinstance(r, rq.Land):
        if vt == VehicleType.PLANE:
            return Plan((_long(MavCmd.DO_LAND_START, "Land DO_LAND_START"),))
        mode = {VehicleType.COPTER: "LAND", VehicleType.VTOL: "QLAND"}.get(vt, "HOLD")
        return Plan((_mode(vt, mode, f"Land {mode}"),))
    if isinstance(r, rq.Parachute):
        if ground:
            return _done(r, False, f"{vt.name} has no parachute", ApError.NOT_APPLICABLE)
        return Plan((_long(MavCmd.DO_PARACHUTE, name, PARACHUTE_RELEASE),))
    if isinstance(r, rq.StartMission):
        # MISSION_START alone does nothing in AUTO while a mission runs
        first = max(1, r.first_item)
        return Plan(
            (
                _long(MavCmd.DO_SET_MISSION_CURRENT, "StartMission set current", first),
                _mode(vt, "AUTO", "StartMission AUTO", skip_if_current=True),
                _long(MavCmd.MISSION_START, "StartMission MISSION_START"),
                VerifySpec(first, "StartMission"),
            )
        )
    if isinstance(r, rq.UploadMission):
        try:
            items = mission_items(r.items, vt, st.home)
        except ConversionError as exc:
            return _done(r, False, str(exc), ApError.DENIED)
        return Plan((TransferSpec(MissionKind.MISSION, "UploadMission", tuple(items)),))
    if isinstance(r, rq.UploadMissionItems):
        return Plan((TransferSpec(r.kind, f"Upload {r.kind.name.lower()}", r.items),))
    if isinstance(r, rq.UploadFence):
        fence: list[Step] = [TransferSpec(MissionKind.FENCE, "UploadFence", tuple(fence_items(r)))]
        if r.enable is not None:
            # enabling waits until ArduPilot has loaded the fence (SYS_STATUS present)
            fence.append(
                _long(
                    MavCmd.DO_FENCE_ENABLE,
                    "UploadFence enable",
                    float(r.enable),
                    failed_retries=FENCE_ENABLE_RETRIES if r.enable else 0,
                    wait_sensor=SENSOR_GEOFENCE if r.enable else 0,
                    wait_s=FENCE_LOAD_WAIT_S if r.enable else 0.0,
                )
            )
        return Plan(tuple(fence))
    if isinstance(r, rq.UploadRally):
        return Plan((TransferSpec(MissionKind.RALLY, "UploadRally", tuple(rally_items(r))),))
    if isinstance(r, rq.DownloadMission):
        return Plan((TransferSpec(r.kind, f"Download {r.kind.name.lower()}"),))
    if isinstance(r, rq.SetParam):
        return Plan((ParamSpec(r.name, r.value, f"SetParam {r.name}"),))
    if isinstance(r, rq.ReadParam):
        return Plan((ParamSpec(r.name, 0.0, f"ReadParam {r.name}", read=True),))
    if isinstance(r, rq.Calibrate):
        label = f"Calibrate {r.what}"
        slow = {"timeout_s": 15.0, "attempts": 1, "in_progress_timeout_s": 120.0}
        if r.what == "compass":
            return Plan((_long(MavCmd.DO_START_MAG_CAL, label, 0, 0, 1, 0, 0, **slow),))
        p = {
            "gyro": (1,),
            "baro": (0, 0, 1),
            "accel": (0, 0, 0, 0, 2),
            "airspeed": (0, 0, 0, 0, 0, 2),
        }
        return Plan((_long(MavCmd.PREFLIGHT_CALIBRATION, label, *p[r.what], **slow),))
    return _done(r, False, f"{name} is not supported", ApError.UNSUPPORTED)
