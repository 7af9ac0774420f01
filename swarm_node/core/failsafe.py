"""The autopilot's own failsafe for a lost companion, set and verified like the fence.

A node that dies (its process killed, its computer off) leaves its autopilot flying
what it was last told: ArduPilot flies its mission on. What it does next is the
autopilot's GCS failsafe: the node sends HEARTBEATs from MAVLink system
`source_sysid` (255), which ArduPilot takes as its ground station's when SYSID_MYGCS
names it; once those stop for the timeout, the failsafe's action flies the vehicle.
`FailsafeKeeper` makes that action known to every peer (docs/reliability.md): it sets
each parameter below and reads it back (`SetParam`: PARAM_SET confirmed by the
PARAM_VALUE echo) whenever the node (re)attaches to its autopilot (the node starts,
the autopilot reboots, the link comes back), retrying every `retry_s` and alerting
once (CRITICAL) while one is refused.

    ArduCopter  SYSID_MYGCS = node, FS_GCS_ENABLE = 1 (RTL), FS_GCS_TIMEOUT = T,
                FS_OPTIONS = 0 (no "continue in AUTO / pilot control on GCS failsafe")
    ArduPlane   SYSID_MYGCS = node, FS_GCS_ENABL = 1 (heartbeat), FS_SHORT_ACTN = 0
    (and VTOL)  (no change in AUTO), FS_LONG_ACTN = 1 (RTL), FS_LONG_TIMEOUT = T
    QuadPlane   also Q_RTL_MODE = 1: at its RTL point (its own pad's rally point) it
                switches to QRTL and lands there, instead of circling it for good

Other vehicle types are left alone. `T` is `COMPANION_TIMEOUT_S`: longer than a stall
or a node restart the fleet rides out (a 3 s SIGSTOP, a restart that reattaches), so
the failsafe takes home only an aircraft whose node is gone.

Pure: `on_autopilot`, `on_result`, `on_timer` take `now`; requests are `Submit`s of
owner BACKSTOP (they do not fly the vehicle).
"""

from __future__ import annotations

import itertools
import logging
from dataclasses import dataclass, field

from swarm_proto import Alert, AlertCode, Severity, VehicleType
from swarm_proto.text import short_text

from .autopilot.requests import ApResult, SetParam
from .autopilot.state import AutopilotState
from .outputs import ModuleOutput, Note, Owner, Publish, Submit

COMPANION_TIMEOUT_S = 10.0
RETRY_S = 5.0
NODE_SYSID = 255  # the node link's MAVLink system id (autopilot/link.py)
# ArduPilot renamed its MAVLink ids after 4.6 (SYSID_MYGCS is MAV_GCS_SYSID on master,
# SYSID_THISMAV MAV_SYSID); an autopilot ignores a PARAM_SET of a name it does not have,
# so a name that is not confirmed is tried under its other name before it is refused
RENAMED = {"SYSID_MYGCS": "MAV_GCS_SYSID", "MAV_GCS_SYSID": "SYSID_MYGCS"}


def failsafe_params(
    vehicle_type: VehicleType,
    timeout_s: float = COMPANION_TIMEOUT_S,
    node_sysid: int = NODE_SYSID,
) -> tuple[tuple[str, float], ...]:
    """The parameters that make the autopilot go home `timeout_s` after the node's
    last HEARTBEAT, per vehicle type (none: left alone)."""
    if vehicle_type == VehicleType.COPTER:
        return (
            ("SYSID_MYGCS", float(node_sysid)),
            ("FS_OPTIONS", 0.0),
            ("FS_GCS_TIMEOUT", timeout_s),
            ("FS_GCS_ENABLE", 1.0),
        )
    if vehicle_type in (VehicleType.PLANE, VehicleType.VTOL):
        plane = (
            ("SYSID_MYGCS", float(node_sysid)),
            ("FS_SHORT_ACTN", 0.0),
            ("FS_LONG_ACTN", 1.0),
            ("FS_LONG_TIMEOUT", timeout_s),
            ("FS_GCS_ENABL", 1.0),
        )
        return plane + ((("Q_RTL_MODE", 1.0),) if vehicle_type == VehicleType.VTOL else ())
    return ()


@dataclass
class FailsafeKeeper:
    vehicle_id: int
    vehicle_type: VehicleType
    # request ids apart from the backstop's (both are owner BACKSTOP)
    ids: itertools.count[int] = field(default_factory=lambda: itertools.count(1 << 24))
    timeout_s: float = COMPANION_TIMEOUT_S
    retry_s: float = RETRY_S
    verified: int = 0  # parameters set and read back
    failures: int = 0  # refusals in a row (alerted at the first)
    _todo: list[tuple[str, float]] = field(default_factory=list)
    _due: float = 0.0
    _epoch: tuple[int, int] | None = None  # (reboots, link losses) last attached at
    _in_flight: int | None = None  # the request id
    _why: str = "node start"
    _renamed: set[str] = field(default_factory=set)  # names tried under their other name
    _known_as: dict[str, str] = field(default_factory=dict)  # a renamed name: the one it has

    @property
    def params(self) -> tuple[tuple[str, float], ...]:
        return failsafe_params(self.vehicle_type, self.timeout_s)

    @property
    def done(self) -> bool:
        """Every parameter set and verified since the last attachment."""
        return self._epoch is not None and not self._todo and self._in_flight is None

    def expects(self, request_id: int) -> bool:
        return self._in_flight is not None and request_id == self._in_flight

    def on_autopilot(self, ap: AutopilotState, now: float) -> list[ModuleOutput]:
        epoch = (ap.reboots, ap.link_losses)
        if ap.link_ok and ap.autopilot_ready and epoch != self._epoch and self.params:
            before, self._epoch = self._epoch, epoch
            self._why = (
                "node start"
                if before is None
                else "autopilot rebooted"
                if epoch[0] != before[0]
                else "link back"
            )
            self._todo = [(self._known_as.get(n, n), v) for n, v in self.params]
            self._due = now
        return self._next(ap, now)

    def on_result(self, result: ApResult, ap: AutopilotState, now: float) -> list[ModuleOutput]:
        if not self.expects(result.request_id):
            return []
        self._in_flight = None
        name, value = self._todo[0]
        if result.ok:
            self._todo.pop(0)
            if name in RENAMED:  # the name this autopilot knows, asked first next time
                self._known_as[name] = self._known_as[RENAMED[name]] = name
            self.verified += 1
            out: list[ModuleOutput] = []
            if self.failures:
                self.failures = 0
                out.append(self._alert(now, Severity.INFO, f"autopilot failsafe {name} set"))
            if not self._todo:
                text = f"autopilot failsafe set and verified ({self._why})"
                out.append(Note(logging.INFO, text))
            return out + self._next(ap, now)
        other = RENAMED.get(name)
        if other is not None and other not in self._renamed:
            self._renamed.add(name)  # this autopilot may know it by its other name
            self._todo[0] = (other, value)
            return self._next(ap, now)
        self._renamed.discard(other or "")
        self.failures += 1
        self._due = now + self.retry_s
        text = f"autopilot failsafe {name}={value:g} not set: {result.reason}"
        out = [Note(logging.WARNING, f"{text}; again in {self.retry_s:g} s")]
        if self.failures == 1:
            out.append(self._alert(now, Severity.CRITICAL, text))
        return out

    def on_timer(self, ap: AutopilotState, now: float) -> list[ModuleOutput]:
        return self._next(ap, now)

    def next_deadline(self) -> float | None:
        if self._in_flight is not None or not self._todo:
            return None
        return self._due

    def _next(self, ap: AutopilotState, now: float) -> list[ModuleOutput]:
        if self._in_flight is not None or not self._todo or now < self._due:
            return []
        if not ap.link_ok or not ap.autopilot_ready:
            return []
        name, value = self._todo[0]
        rid = self._in_flight = next(self.ids)
        return [Submit(SetParam(name=name, value=value, request_id=rid), Owner.BACKSTOP)]

    def _alert(self, now: float, severity: Severity, text: str) -> Publish:
        alert = Alert(self.vehicle_id, max(0.0, now), severity, AlertCode.GENERIC, short_text(text))
        return Publish(alert)
