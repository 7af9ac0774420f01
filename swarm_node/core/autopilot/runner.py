"""Executes `ApRequest`s as plans (plans.py): COMMAND_ACK matching, timeouts, retries,
PARAM_VALUE confirmation and mission transfers, as a pure state machine.

Three lanes run side by side, each one job at a time in FIFO order: commands (and
parameter writes), mission transfers (so a long upload over a slow radio never delays an
RTL), and parameter reads. Urgent requests (Parachute, ReturnToLaunch, Land) go to the front of the command
lane and supersede a running non-urgent command, which then ends CANCELLED.

COMMAND_ACK handling of a step (table below): ACCEPTED ends the step; IN_PROGRESS
extends its deadline; TEMPORARILY_REJECTED is retried after `retry_delay_s` while
attempts remain; DENIED, UNSUPPORTED, FAILED, CANCELLED end the request. No answer
within `timeout_s` resends (COMMAND_LONG with confirmation + 1) until `attempts` are
spent. A FAILED mode change while the EKF has no position reports NO_POSITION.
A STATUSTEXT of severity WARNING or worse seen during the step is quoted in the reason
(ArduPilot explains refusals that way: "PreArm: ...", "Mode change to GUIDED failed").
ArduPilot sends that text after its COMMAND_ACK (the ACK goes out at once, texts from a
queue on the next telemetry pass), so a refusal without one waits `explain_wait_s` for
it before it is reported.

A mode change (a step with `confirm_mode`) accepted by COMMAND_ACK is done only when a
HEARTBEAT shows the mode, or shows that the autopilot left the mode it was in (asked
for at once with REQUEST_MESSAGE); `mode_confirm_s` without that fails the request
(ApError.MODE_NOT_CONFIRMED) and the steps after it are not sent.

Real ArduPilot SITL: a command may wait for a SYS_STATUS sensor bit before it
is sent (DO_FENCE_ENABLE waits for the fence to be loaded) and retry FAILED answers; a
`VerifySpec` step waits for MISSION_CURRENT to report an item (StartMission); a transfer
waits (at most `ready_wait_s`) until the autopilot has booted ("ArduPilot Ready"), since
ArduPilot answers a MISSION_COUNT before that with MISSION_ACK NO_SPACE ("Only 0 items
are supported").
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from .framing import MAVLinkMessage
from .mission_protocol import MissionDownload, MissionUpload
from .plans import (
    QUERIES,
    TRANSFERS,
    URGENT,
    CommandSpec,
    ParamSpec,
    Plan,
    PlanContext,
    Step,
    TransferSpec,
    VerifySpec,
    plan_request,
)
from .requests import ApError, ApRequest, ApResult, MissionKind
from .state import AutopilotState

MAV_RESULT_ACCEPTED = 0
MAV_RESULT_TEMPORARILY_REJECTED = 1
MAV_RESULT_DENIED = 2
MAV_RESULT_UNSUPPORTED = 3
MAV_RESULT_FAILED = 4
MAV_RESULT_IN_PROGRESS = 5
MAV_RESULT_CANCELLED = 6
MAV_PARAM_TYPE_REAL32 = 9
MAV_SEVERITY_WARNING = 4
MAV_CMD_REQUEST_MESSAGE = 512
MSG_ID_HEARTBEAT = 0
#: refusals that ArduPilot explains with a STATUSTEXT (waited for, `explain_wait_s`)
EXPLAINED = frozenset(
    {ApError.FAILED, ApError.DENIED, ApError.TEMPORARILY_REJECTED, ApError.NO_POSITION}
)

#: MAV_RESULT -> (ApError when it ends the request, whether it is retried)
ACK_TABLE: dict[int, tuple[ApError, bool]] = {
    MAV_RESULT_ACCEPTED: (ApError.NONE, False),
    MAV_RESULT_TEMPORARILY_REJECTED: (ApError.TEMPORARILY_REJECTED, True),
    MAV_RESULT_DENIED: (ApError.DENIED, False),
    MAV_RESULT_UNSUPPORTED: (ApError.UNSUPPORTED, False),
    MAV_RESULT_FAILED: (ApError.FAILED, False),
    MAV_RESULT_IN_PROGRESS: (ApError.IN_PROGRESS, False),
    MAV_RESULT_CANCELLED: (ApError.CANCELLED, False),
}

COMMAND_LANE = "command"
TRANSFER_LANE = "transfer"
QUERY_LANE = "query"


def mav_result_name(code: int) -> str:
    entry = mavlink.enums["MAV_RESULT"].get(code)
    return entry.name.removeprefix("MAV_RESULT_") if entry else f"RESULT({code})"


def command_name(code: int) -> str:
    entry = mavlink.enums["MAV_CMD"].get(code)
    return entry.name.removeprefix("MAV_CMD_") if entry else f"CMD({code})"


@dataclass(frozen=True, slots=True)
class RunnerSettings:
    command_timeout_s: float = 1.5
    command_attempts: int = 3
    retry_delay_s: float = 0.5  # after TEMPORARILY_REJECTED
    param_timeout_s: float = 1.5
    param_attempts: int = 3
    mission_timeout_s: float = 1.5
    mission_retries: int = 5
    ready_wait_s: float = 10.0  # longest wait for "ArduPilot Ready" before a transfer
    ready_poll_s: float = 0.2
    explain_wait_s: float = 0.5  # after a refusal, the wait for ArduPilot's STATUSTEXT
    mode_confirm_s: float = 3.0  # after an accepted mode change, the wait for a HEARTBEAT


@dataclass(slots=True)
class StepOutcome:
    ok: bool
    reason: str = ""
    error: ApError = ApError.NONE
    mav_result: int | None = None
    items: tuple = ()
    attempts: int = 0
    value: float | None = None


@dataclass(frozen=True, slots=True)
class Finished:
    token: int
    request: ApRequest
    result: ApResult


class _StepExec:
    outcome: StepOutcome | None = None

    def start(self, now: float, state: AutopilotState) -> list[MAVLinkMessage]:
        raise NotImplementedError

    def handle(
        self, msg: MAVLinkMessage, now: float, state: AutopilotState
    ) -> list[MAVLinkMessage]:
        raise NotImplementedError

    def on_timer(self, now: float, state: AutopilotState) -> list[MAVLinkMessage]:
        raise NotImplementedError

    def next_deadline(self) -> float | None:
        raise NotImplementedError


class _CommandExec(_StepExec):
    def __init__(
        self, spec: CommandSpec, target: tuple[int, int], settings: RunnerSettings
    ) -> None:
        self.spec = spec
        self.target = target
        self.timeout_s = spec.timeout_s or settings.command_timeout_s
        self.attempts_max = spec.attempts or settings.command_attempts
        self.retry_delay_s = settings.retry_delay_s
        self.attempts = 0
        self.deadline: float | None = None
        self.resend_at: float | None = None
        self.warning = ""
        self.outcome = None
        self.last_result: int | None = None
        self.failed_left = spec.failed_retries
        self.wait_until: float | None = None  # waiting for spec.wait_sensor
        self.explain_s = settings.explain_wait_s
        self.confirm_s = settings.mode_confirm_s
        self.refused: tuple[str, ApError, int | None] | None = None  # waiting for its text
        self.confirming = False  # accepted: waiting for a HEARTBEAT with the mode
        self.mode_before: int | None = None

    def _message(self) -> MAVLinkMessage:
        s, (ts, tc) = self.spec, self.target
        p = s.params
        if s.frame is None:
            return mavlink.MAVLink_command_long_message(
                ts, tc, s.command, min(self.attempts - 1, 255), *p
            )
        x = 0 if not math.isfinite(p[4]) else round(p[4] * 1e7)
        y = 0 if not math.isfinite(p[5]) else round(p[5] * 1e7)
        return mavlink.MAVLink_command_int_message(
            ts, tc, s.frame, s.command, 0, 0, p[0], p[1], p[2], p[3], x, y, p[6]
        )

    def _send(self, now: float) -> list[MAVLinkMessage]:
        self.attempts += 1
        self.deadline = now + self.timeout_s
        self.resend_at = None
        return [self._message()]

    def start(self, now: float, state: AutopilotState) -> list[MAVLinkMessage]:
        if self.spec.skip_if_mode is not None and state.mode_number == self.spec.skip_if_mode:
            self.outcome = StepOutcome(True, f"already in {self.spec.mode_name}")
            return []
        self.mode_before = state.mode_number
        if self.spec.wait_sensor and self.spec.wait_s > 0:
            self.wait_until = now + self.spec.wait_s  # until a fresh SYS_STATUS shows it
            return []
        return self._send(now)

    def _fail(self, reason: str, error: ApError, mav_result: int | None = None) -> None:
        if self.warning:
            reason = f"{reason} ({self.warning})"
        if self.spec.optional:
            self.outcome = StepOutcome(
                True, f"{self.spec.label}: {reason}; carried on", attempts=self.attempts
            )
            self.deadline = self.resend_at = None
            self.refused = None
            return
        self.outcome = StepOutcome(
            False, f"{self.spec.label}: {reason}", error, mav_result, attempts=self.attempts
        )
        self.deadline = self.resend_at = None
        self.refused = None

    def _refuse(
        self, reason: str, error: ApError, mav_result: int | None, now: float
    ) -> list[MAVLinkMessage]:
        """A refusal: reported with ArduPilot's explanation, waited for if not seen yet."""
        if self.warning or error not in EXPLAINED or self.explain_s <= 0 or self.spec.optional:
            self._fail(reason, error, mav_result)
        else:
            self.refused = (reason, error, mav_result)
            self.deadline, self.resend_at = now + self.explain_s, None
        return []

    def _mode_shown(self, state: AutopilotState) -> bool:
        """The HEARTBEAT shows the mode asked for, or that the autopilot left the mode
        it was in (it took the mode and moved on: RTL -> QRTL)."""
        mode = state.mode_number
        return mode == self.spec.confirm_mode or (
            self.mode_before is not None
            and mode != self.mode_before
            and self.spec.confirm_mode != self.mode_before
        )

    def _accepted(self, now: float, state: AutopilotState, result: int) -> list[MAVLinkMessage]:
        self.last_result = result
        if self.spec.confirm_mode is None or self._mode_shown(state):
            self.outcome = StepOutcome(True, mav_result=result, attempts=self.attempts)
            self.deadline = None
            return []
        self.confirming = True
        self.deadline = now + self.confirm_s
        ts, tc = self.target
        return [
            mavlink.MAVLink_command_long_message(
                ts, tc, MAV_CMD_REQUEST_MESSAGE, 0, MSG_ID_HEARTBEAT, 0, 0, 0, 0, 0, 0
            )
        ]

    def handle(
        self, msg: MAVLinkMessage, now: float, state: AutopilotState
    ) -> list[MAVLinkMessage]:
        if self.outcome is not None:
            return []
        mtype = msg.get_type()
        if self.wait_until is not None:
            if mtype == "SYS_STATUS" and (
                int(msg.onboard_control_sensors_present) & self.spec.wait_sensor
            ):
                self.wait_until = None
                return self._send(now)
            return []
        if mtype == "STATUSTEXT":
            if int(msg.severity) <= MAV_SEVERITY_WARNING:
                self.warning = str(msg.text).rstrip("\x00")[:80]
                if self.refused is not None:
                    self._fail(*self.refused)
            return []
        if self.confirming:
            if mtype == "HEARTBEAT" and self._mode_shown(state):
                self.confirming = False
                self.outcome = StepOutcome(True, mav_result=0, attempts=self.attempts)
                self.deadline = None
            return []
        if mtype != "COMMAND_ACK" or int(msg.command) != self.spec.command:
            return []
        if self.attempts == 0 or self.resend_at is not None or self.refused is not None:
            return []  # not sent yet, waiting to resend, or refused (waiting for its text)
        result = int(msg.result)
        self.last_result = result
        error, retried = ACK_TABLE.get(result, (ApError.FAILED, False))
        if result == MAV_RESULT_ACCEPTED:
            return self._accepted(now, state, result)
        if result == MAV_RESULT_IN_PROGRESS:
            self.deadline = now + self.spec.in_progress_timeout_s
            return []
        name = f"COMMAND_ACK {mav_result_name(result)}"
        if result == MAV_RESULT_FAILED and self.failed_left > 0:
            self.failed_left -= 1
            retried, self.attempts = True, min(self.attempts, self.attempts_max - 1)
        if retried and self.attempts < self.attempts_max:
            self.deadline = None
            self.resend_at = now + self.retry_delay_s
            return []
        if (
            result == MAV_RESULT_FAILED
            and self.spec.mode_name
            and not (state.ekf_has_position or state.ekf_ok)
        ):
            return self._refuse(
                f"{name}: EKF has no position yet", ApError.NO_POSITION, result, now
            )
        if result == MAV_RESULT_FAILED and self.spec.needs_armed and not state.armed:
            return self._refuse(f"{name}: not armed (send Arm first)", error, result, now)
        return self._refuse(name, error, result, now)

    def on_timer(self, now: float, state: AutopilotState) -> list[MAVLinkMessage]:
        if self.outcome is not None:
            return []
        if self.wait_until is not None:
            if now < self.wait_until:
                return []
            self.wait_until = None  # not seen: send anyway (FAILED answers are retried)
            return self._send(now)
        if self.refused is not None:
            if self.deadline is not None and now >= self.deadline:
                self._fail(*self.refused)  # no explanation came
            return []
        if self.confirming:
            if self.deadline is not None and now >= self.deadline:
                self.confirming = False
                shown = state.mode_name or str(state.mode_number)
                self._fail(
                    f"accepted, but the HEARTBEAT still shows {shown} after "
                    f"{self.confirm_s:g} s (not {self.spec.mode_name})",
                    ApError.MODE_NOT_CONFIRMED if state.link_ok else ApError.LINK_DOWN,
                    MAV_RESULT_ACCEPTED,
                )
            return []
        if self.resend_at is not None and now >= self.resend_at:
            return self._send(now)
        if self.deadline is None or now < self.deadline:
            return []
        if self.last_result == MAV_RESULT_IN_PROGRESS:
            self._fail("still IN_PROGRESS when the time ran out", ApError.IN_PROGRESS, 5)
            return []
        if self.attempts < self.attempts_max:
            return self._send(now)
        what = f"no COMMAND_ACK for {command_name(self.spec.command)} after {self.attempts} tries"
        self._fail(what, ApError.TIMEOUT if state.link_ok else ApError.LINK_DOWN)
        return []

    def next_deadline(self) -> float | None:
        if self.outcome is not None:
            return None
        if self.wait_until is not None:
            return self.wait_until
        if self.resend_at is not None:
            return self.resend_at
        return self.deadline


class _VerifyExec(_StepExec):
    """Waits for MISSION_CURRENT reported since the request began to show the mission
    started at spec.seq: that item, or a later one other than the item current before
    the request (MISSION_CURRENT is the current NAV item: ArduPilot runs DO items such
    as DO_CHANGE_SPEED at once and reports the first NAV item after them; the item
    current before is what a mission that did not restart keeps reporting). When the
    mission last uploaded is known, its first NAV item from spec.seq on counts too, even
    if it is the item current before: a new mission whose first waypoint has the index
    the old one was at (a vehicle on its way home, two items into the return, sent its
    next mission) is started, and staying there flies it."""

    def __init__(
        self, spec: VerifySpec, seen: set[int], before: int | None = None, nav: int | None = None
    ) -> None:
        self.spec = spec
        self.seen = seen
        self.before = before
        self.nav = nav
        self.deadline: float | None = None
        self.outcome = None

    def _check(self) -> None:
        seq = self.spec.seq
        if (
            seq in self.seen
            or (self.nav is not None and self.nav in self.seen)
            or any(v > seq and v != self.before for v in self.seen)
        ):
            self.outcome = StepOutcome(True)
            self.deadline = None

    def start(self, now: float, state: AutopilotState) -> list[MAVLinkMessage]:
        self.deadline = now + self.spec.timeout_s
        self._check()
        return []

    def handle(
        self, msg: MAVLinkMessage, now: float, state: AutopilotState
    ) -> list[MAVLinkMessage]:
        if self.outcome is None:
            self._check()
        return []

    def on_timer(self, now: float, state: AutopilotState) -> list[MAVLinkMessage]:
        if self.outcome is not None or self.deadline is None or now < self.deadline:
            return []
        reason = (
            f"{self.spec.label}: accepted, but MISSION_CURRENT stayed {state.mission_current} "
            f"(not {self.spec.seq}) for {self.spec.timeout_s:g} s: the mission did not start"
        )
        error = ApError.NOT_STARTED if state.link_ok else ApError.LINK_DOWN
        self.outcome = StepOutcome(False, reason, error)
        self.deadline = None
        return []

    def next_deadline(self) -> float | None:
        return None if self.outcome is not None else self.deadline


class _ParamExec(_StepExec):
    def __init__(self, spec: ParamSpec, target: tuple[int, int], settings: RunnerSettings) -> None:
        self.spec = spec
        self.target = target
        self.timeout_s = settings.param_timeout_s
        self.attempts_max = settings.param_attempts
        self.attempts = 0
        self.deadline: float | None = None
        self.outcome = None

    def _send(self, now: float) -> list[MAVLinkMessage]:
        self.attempts += 1
        self.deadline = now + self.timeout_s
        if self.spec.read:
            return [
                mavlink.MAVLink_param_request_read_message(
                    self.target[0], self.target[1], self.spec.name.encode("ascii"), -1
                )
            ]
        return [
            mavlink.MAVLink_param_set_message(
                self.target[0],
                self.target[1],
                self.spec.name.encode("ascii"),
                float(self.spec.value),
                MAV_PARAM_TYPE_REAL32,
            )
        ]

    def start(self, now: float, state: AutopilotState) -> list[MAVLinkMessage]:
        return self._send(now)

    def _end(self, ok: bool, reason: str, error: ApError, value: float | None = None) -> None:
        if not ok and self.spec.optional:
            ok, error = True, ApError.NONE
            reason = f"{reason}; carried on with the autopilot's own value"
        self.outcome = StepOutcome(
            ok,
            f"{self.spec.label}: {reason}" if reason else "",
            error,
            attempts=self.attempts,
            value=value,
        )
        self.deadline = None

    def handle(
        self, msg: MAVLinkMessage, now: float, state: AutopilotState
    ) -> list[MAVLinkMessage]:
        if self.outcome is not None or msg.get_type() != "PARAM_VALUE":
            return []
        name = msg.param_id
        if isinstance(name, bytes | bytearray):
            name = name.decode("ascii", "replace")
        if str(name).rstrip("\x00") != self.spec.name:
            return []
        value = float(msg.param_value)
        if self.spec.read:
            if math.isfinite(value):
                self._end(True, "", ApError.NONE, value)
            else:
                self._end(False, f"{self.spec.name} = {value:g}", ApError.FAILED)
            return []
        want = float(self.spec.value)
        if math.isfinite(value) and abs(value - want) <= 1e-6 * max(1.0, abs(want)):
            self._end(True, "", ApError.NONE)
        else:
            self._end(False, f"the autopilot kept {self.spec.name} = {value:g}", ApError.FAILED)
        return []

    def on_timer(self, now: float, state: AutopilotState) -> list[MAVLinkMessage]:
        if self.outcome is not None or self.deadline is None or now < self.deadline:
            return []
        if self.attempts < self.attempts_max:
            return self._send(now)
        self._end(
            False,
            f"no PARAM_VALUE after {self.attempts} tries",
            ApError.TIMEOUT if state.link_ok else ApError.LINK_DOWN,
        )
        return []

    def next_deadline(self) -> float | None:
        return None if self.outcome is not None else self.deadline


class _TransferExec(_StepExec):
    def __init__(
        self, spec: TransferSpec, target: tuple[int, int], settings: RunnerSettings
    ) -> None:
        self.spec = spec
        if spec.items is None:
            self.transfer: MissionUpload | MissionDownload = MissionDownload(
                spec.kind,
                target,
                timeout_s=settings.mission_timeout_s,
                retries=settings.mission_retries,
            )
        else:
            self.transfer = MissionUpload(
                spec.kind,
                spec.items,
                target,
                timeout_s=settings.mission_timeout_s,
                retries=settings.mission_retries,
            )
        self.outcome = None
        self.ready_wait_s = settings.ready_wait_s
        self.ready_poll_s = settings.ready_poll_s
        self.waiting_since: float | None = None  # waiting for "ArduPilot Ready"
        self.poll_at: float | None = None

    def _check(self, state: AutopilotState) -> None:
        res = self.transfer.result
        if res is None or self.outcome is not None:
            return
        error = res.error
        if not res.ok and error == ApError.TIMEOUT and not state.link_ok:
            error = ApError.LINK_DOWN
        self.outcome = StepOutcome(
            res.ok,
            f"{self.spec.label}: {res.reason}" if res.reason else "",
            error,
            items=res.items,
            attempts=res.attempts,
        )

    def start(self, now: float, state: AutopilotState) -> list[MAVLinkMessage]:
        if not state.autopilot_ready:  # ArduPilot refuses transfers while booting
            self.waiting_since, self.poll_at = now, now + self.ready_poll_s
            return []
        out = self.transfer.start(now)
        self._check(state)
        return out

    def handle(
        self, msg: MAVLinkMessage, now: float, state: AutopilotState
    ) -> list[MAVLinkMessage]:
        if self.waiting_since is not None:
            return []
        out = self.transfer.handle(msg, now)
        self._check(state)
        return out

    def on_timer(self, now: float, state: AutopilotState) -> list[MAVLinkMessage]:
        if self.waiting_since is not None:
            if not state.autopilot_ready and now - self.waiting_since < self.ready_wait_s:
                self.poll_at = now + self.ready_poll_s
                return []
            self.waiting_since = self.poll_at = None  # ready (or waited long enough)
            out = self.transfer.start(now)
            self._check(state)
            return out
        out = self.transfer.on_timer(now)
        self._check(state)
        return out

    def next_deadline(self) -> float | None:
        if self.waiting_since is not None:
            return self.poll_at
        return self.transfer.next_deadline()


@dataclass(slots=True)
class _Job:
    token: int
    request: ApRequest
    urgent: bool
    plan: Plan | None = None
    index: int = 0
    step: _StepExec | None = None
    notes: list[str] = field(default_factory=list)
    items: tuple = ()
    seen_current: set[int] = field(default_factory=set)  # MISSION_CURRENT seqs since submitted
    current_before: int | None = None  # MISSION_CURRENT when its first step started
    value: float | None = None  # a ReadParam's value


class RequestRunner:
    def __init__(self, settings: RunnerSettings | None = None) -> None:
        self.settings = settings or RunnerSettings()
        lanes = (COMMAND_LANE, TRANSFER_LANE, QUERY_LANE)
        self._queues: dict[str, deque[_Job]] = {lane: deque() for lane in lanes}
        self._active: dict[str, _Job | None] = dict.fromkeys(lanes)
        self.last_goto: tuple[float, float, float] | None = None
        # (seq, command) of the mission last uploaded (None: not uploaded by us)
        self.mission_items: tuple[tuple[int, int], ...] | None = None

    def first_nav(self, seq: int) -> int | None:
        """The first NAV item (MAV_CMD_NAV_*: commands below 100) at or after `seq` of the
        mission last uploaded; None when unknown."""
        if self.mission_items is None:
            return None
        return min((s for s, cmd in self.mission_items if s >= seq and cmd < 100), default=None)

    # ------------------------------------------------------------------ public

    def pending(self) -> int:
        return sum(len(q) for q in self._queues.values()) + sum(
            1 for j in self._active.values() if j is not None
        )

    def submit(
        self, token: int, request: ApRequest, ctx: PlanContext, now: float
    ) -> tuple[list[MAVLinkMessage], list[Finished]]:
        lane = (
            TRANSFER_LANE
            if isinstance(request, TRANSFERS)
            else QUERY_LANE
            if isinstance(request, QUERIES)
            else COMMAND_LANE
        )
        job = _Job(token, request, urgent=isinstance(request, URGENT))
        out: list[MAVLinkMessage] = []
        done: list[Finished] = []
        if job.urgent:
            self._queues[lane].appendleft(job)
            active = self._active[lane]
            if active is not None and not active.urgent:
                done.append(
                    self._finish(
                        active, False, f"superseded by {type(request).__name__}", ApError.CANCELLED
                    )
                )
                self._active[lane] = None
        else:
            self._queues[lane].append(job)
        self._pump(ctx, now, out, done)
        return out, done

    def handle(
        self, msg: MAVLinkMessage, ctx: PlanContext, now: float
    ) -> tuple[list[MAVLinkMessage], list[Finished]]:
        out: list[MAVLinkMessage] = []
        done: list[Finished] = []
        if msg.get_type() == "MISSION_CURRENT":
            for job in self._active.values():
                if job is not None:
                    job.seen_current.add(int(msg.seq))
        for job in list(self._active.values()):
            if job is not None and job.step is not None:
                out += job.step.handle(msg, now, ctx.state)
        self._pump(ctx, now, out, done)
        return out, done

    def on_timer(self, ctx: PlanContext, now: float) -> tuple[list[MAVLinkMessage], list[Finished]]:
        out: list[MAVLinkMessage] = []
        done: list[Finished] = []
        for job in list(self._active.values()):
            if job is not None and job.step is not None:
                deadline = job.step.next_deadline()
                if deadline is not None and now >= deadline:
                    out += job.step.on_timer(now, ctx.state)
        self._pump(ctx, now, out, done)
        return out, done

    def next_deadline(self) -> float | None:
        t: float | None = None
        for job in self._active.values():
            if job is not None and job.step is not None:
                d = job.step.next_deadline()
                if d is not None and (t is None or d < t):
                    t = d
        return t

    def cancel_all(self, reason: str) -> list[Finished]:
        done: list[Finished] = []
        for lane in self._queues:
            job = self._active[lane]
            if job is not None:
                done.append(self._finish(job, False, reason, ApError.CANCELLED))
                self._active[lane] = None
            while self._queues[lane]:
                done.append(
                    self._finish(self._queues[lane].popleft(), False, reason, ApError.CANCELLED)
                )
        return done

    # ------------------------------------------------------------------ machinery

    def _finish(
        self,
        job: _Job,
        ok: bool,
        reason: str,
        error: ApError = ApError.NONE,
        mav_result: int | None = None,
        attempts: int = 0,
    ) -> Finished:
        notes = [n for n in job.notes if n]
        if ok and notes and not reason:
            reason = "; ".join(notes)
        result = ApResult(
            job.request.request_id,
            ok,
            reason,
            mav_result=mav_result,
            error=error,
            items=job.items,
            attempts=attempts,
            value=job.value,
        )
        return Finished(job.token, job.request, result)

    def _pump(
        self, ctx: PlanContext, now: float, out: list[MAVLinkMessage], done: list[Finished]
    ) -> None:
        """Advance every lane until each waits for the autopilot or is idle."""
        for lane in self._queues:
            while True:
                job = self._active[lane]
                if job is None:
                    if not self._queues[lane]:
                        break
                    job = self._queues[lane].popleft()
                    self._active[lane] = job
                    if not self._plan(job, ctx, now, done):
                        self._active[lane] = None
                        continue
                    self._start_step(job, ctx, now, out)
                step = job.step
                assert step is not None
                if step.outcome is None:
                    break
                outcome = step.outcome
                if outcome.items:
                    job.items = tuple(outcome.items)
                if outcome.value is not None:
                    job.value = outcome.value
                if not outcome.ok:
                    done.append(
                        self._finish(
                            job,
                            False,
                            outcome.reason,
                            outcome.error,
                            outcome.mav_result,
                            outcome.attempts,
                        )
                    )
                    self._active[lane] = None
                    continue
                job.notes.append(outcome.reason)
                assert job.plan is not None
                job.index += 1
                if job.index >= len(job.plan.steps):
                    if job.plan.goto_target is not None:
                        self.last_goto = job.plan.goto_target
                    for sp in job.plan.steps:
                        if (
                            isinstance(sp, TransferSpec)
                            and sp.kind == MissionKind.MISSION
                            and sp.items is not None
                        ):
                            self.mission_items = tuple((i.seq, i.command) for i in sp.items)
                    done.append(
                        self._finish(
                            job, True, "", ApError.NONE, outcome.mav_result, outcome.attempts
                        )
                    )
                    self._active[lane] = None
                    continue
                self._start_step(job, ctx, now, out)

    def _plan(self, job: _Job, ctx: PlanContext, now: float, done: list[Finished]) -> bool:
        if not ctx.state.link_ok:
            done.append(
                self._finish(
                    job,
                    False,
                    f"{type(job.request).__name__}: no link to the autopilot",
                    ApError.LINK_DOWN,
                )
            )
            return False
        planned = plan_request(
            job.request, PlanContext(ctx.state, ctx.vehicle_type, self.last_goto)
        )
        if isinstance(planned, ApResult):
            done.append(Finished(job.token, job.request, planned))
            return False
        job.plan = planned
        job.index = 0
        return True

    def _start_step(
        self, job: _Job, ctx: PlanContext, now: float, out: list[MAVLinkMessage]
    ) -> None:
        assert job.plan is not None
        spec: Step = job.plan.steps[job.index]
        target = (ctx.state.sysid, ctx.state.compid)
        if job.index == 0:
            job.current_before = ctx.state.mission_current
        if isinstance(spec, CommandSpec):
            job.step = _CommandExec(spec, target, self.settings)
        elif isinstance(spec, ParamSpec):
            job.step = _ParamExec(spec, target, self.settings)
        elif isinstance(spec, VerifySpec):
            job.step = _VerifyExec(
                spec, job.seen_current, job.current_before, self.first_nav(spec.seq)
            )
        else:
            job.step = _TransferExec(spec, target, self.settings)
        out += job.step.start(now, ctx.state)

    def is_idle(self) -> bool:
        return self.pending() == 0


def mission_kind_of(request: ApRequest) -> MissionKind | None:
    """Which mission type a transfer request reads or writes."""
    from . import requests as rq

    if isinstance(request, rq.UploadMission):
        return MissionKind.MISSION
    if isinstance(request, rq.UploadMissionItems | rq.DownloadMission):
        return request.kind
    if isinstance(request, rq.UploadFence):
        return MissionKind.FENCE
    if isinstance(request, rq.UploadRally):
        return MissionKind.RALLY
    return None
