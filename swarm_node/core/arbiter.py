"""AutopilotArbiter: one owner per autopilot request, one holder of the autopilot's
control at a time.

Every module submits its requests with its own ids (`Submit(owner, request)`); the
arbiter gives each a fresh id of its own (one counter, no id ranges), remembers whose
it is and the owner's id, and routes the result back to that owner with the owner's id
(`on_result`). A result nobody asked for is counted and dropped (`stray`).

Precedence EMERGENCY > AVOIDANCE > OPERATOR > MISSION > FENCE: a request that flies the
vehicle (everything but fence, rally, parameter and calibration work, and downloads)
takes control for its owner; while a higher owner holds control, a lower owner's
flight request is refused at once with a failed result ("preempted by ..."), routed
back to it like any other. The holder keeps control until it releases it (`release`:
the node releases EMERGENCY when the state machine leaves STATE_EMERGENCY, OPERATOR
when a new mission begins or the vehicle lands); a higher owner may always take it.
Emergency results go back to the EMERGENCY owner (the node alerts on a refusal): none
is dropped.

Pure: no I/O, no clock.
"""

from __future__ import annotations

import itertools
from collections import Counter
from dataclasses import dataclass, field

import msgspec

from .autopilot.requests import (
    ApRequest,
    ApResult,
    Calibrate,
    DownloadMission,
    SetParam,
    UploadFence,
    UploadRally,
)
from .outputs import Owner

#: requests that do not fly the vehicle: never refused for precedence
NOT_FLIGHT = (UploadFence, UploadRally, SetParam, Calibrate, DownloadMission)


def flies(request: ApRequest) -> bool:
    return not isinstance(request, NOT_FLIGHT)


@dataclass(frozen=True)
class Routed:
    """A result for the module `owner` (the request's route), with the id that module
    gave its request."""

    owner: Owner
    result: ApResult


@dataclass
class AutopilotArbiter:
    holder: Owner | None = None  # who controls the autopilot's flight now
    refused: Counter[Owner] = field(default_factory=Counter)
    stray: int = 0  # results nobody asked for
    _ids: itertools.count[int] = field(default_factory=lambda: itertools.count(1))
    _owners: dict[int, tuple[Owner, int]] = field(default_factory=dict)

    def submit(
        self, owner: Owner, request: ApRequest, route: Owner | None = None
    ) -> ApRequest | Routed:
        """The request to send (with the arbiter's id), or the refusal to route back
        at once (to `route`, default the owner)."""
        to = owner if route is None else route
        if flies(request):
            if self.holder is not None and self.holder > owner:
                self.refused[owner] += 1
                return Routed(
                    to, ApResult(request.request_id, False, f"preempted by {self.holder.name}")
                )
            self.holder = owner
        rid = next(self._ids)
        self._owners[rid] = (to, request.request_id)
        return msgspec.structs.replace(request, request_id=rid)

    def on_result(self, result: ApResult) -> Routed | None:
        entry = self._owners.pop(result.request_id, None)
        if entry is None:
            self.stray += 1
            return None
        owner, own_id = entry
        return Routed(owner, msgspec.structs.replace(result, request_id=own_id))

    def take(self, owner: Owner) -> None:
        """`owner` takes control (an emergency begins) if it outranks the holder."""
        if self.holder is None or owner >= self.holder:
            self.holder = owner

    def release(self, owner: Owner) -> None:
        if self.holder == owner:
            self.holder = None

    def pending(self, owner: Owner) -> int:
        return sum(1 for o, _ in self._owners.values() if o == owner)
