"""The emergency procedure as a node module, owner EMERGENCY of the autopilot: when the
state machine enters (or escalates) STATE_EMERGENCY it takes control (`Claim`: every
lower owner's flight requests are refused from then on, avoidance's suspension ends)
and flies the procedure for the alert (commands.emergency_requests), a return kept
clear of the no-fly zones (emergency_route.py). A refusal of its requests is alerted
CRITICAL. Control is released when the state machine leaves STATE_EMERGENCY.

Pure: no I/O; `now` is passed in.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass

from swarm_proto import Alert, AlertCode, GeoPoint, NoFlyZone, Severity
from swarm_proto.text import short_text

from .arbiter import Owner
from .autopilot.requests import ApResult
from .autopilot.state import AutopilotState
from .commands import emergency_requests
from .emergency_route import zone_safe_emergency
from .outputs import Claim, ModuleOutput, Note, Publish, Submit
from .profile import VehicleProfile


@dataclass
class EmergencyProcedure:
    profile: VehicleProfile

    def start(
        self,
        code: AlertCode,
        severity: Severity,
        ap: AutopilotState,
        base: GeoPoint | None,
        zones: Sequence[NoFlyZone],
        now: float,
    ) -> list[ModuleOutput]:
        vid = self.profile.vehicle_id
        alert = Alert(vid, max(0.0, now), severity, code, f"emergency: {code.name}")
        out: list[ModuleOutput] = [Publish(alert), Claim(Owner.EMERGENCY)]
        requests, why = zone_safe_emergency(
            emergency_requests(code, self.profile), ap, base, zones, self.profile, now
        )
        if why:
            out.append(Note(logging.WARNING, f"emergency: {why}"))
        return out + [Submit(r, Owner.EMERGENCY) for r in requests]

    def on_result(self, result: ApResult, now: float) -> list[ModuleOutput]:
        if result.ok:
            return []
        text = f"emergency procedure refused: {result.reason}"
        vid = self.profile.vehicle_id
        alert = Alert(vid, max(0.0, now), Severity.CRITICAL, AlertCode.GENERIC, short_text(text))
        return [Note(logging.ERROR, text), Publish(alert)]
