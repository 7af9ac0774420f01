"""The autopilot's backstop kept true: the fence (no-fly zones and operating
areas, fences.py) and the rally point (the base) the node loads into ArduPilot must be
there if the companion computer fails; an autopilot that reboots or reconnects may come
back with an empty or different store.

Whenever the node (re)attaches to its autopilot (the node starts, the autopilot reboots
(its time since boot went back), the link comes back after a loss), whenever a ground
station changed the fence, the rally points or their parameters through MAVLink
passthrough (`recheck`: as after a reboot) and whenever the base it wants as rally
point changes, `BackstopKeeper` checks each store by downloading it and comparing it
with what it should hold:

    VERIFY    download, compare     -> same: done
                                    -> different: WARNING, RESTORE
    RESTORE   the fence: the FenceKeeper uploads it again (FENCE_TYPE, items, enable);
              the rally point: UploadRally
    REVERIFY  download, compare     -> same: WARNING "restored and verified"
                                    -> different: CRITICAL, RESTORE again in `retry_s`

A failed request (link down, timeout) is retried after `retry_s`. The fence is checked
only once the FenceKeeper has nothing to upload (its own upload first); the rally point
`settle_s` after it changed (a SET_BASE command uploads it itself).

Comparison is as ArduPilot stores items: command, latitude and longitude to 2e-7
degrees, a circle's radius (or a polygon's vertex count) to 0.5 m, a rally point's
altitude to 1 m (ArduPilot keeps it in whole metres).

Pure: `on_autopilot`, `on_result`, `on_timer` take `now`; requests are `Submit`s of
owner BACKSTOP (never refused for precedence: they do not fly the vehicle).
"""

from __future__ import annotations

import itertools
import logging
from dataclasses import dataclass, field
from enum import Enum
from typing import TYPE_CHECKING

import msgspec

from swarm_proto import Alert, AlertCode, GeoPoint, Severity, VehicleType
from swarm_proto.text import short_text

from .autopilot.conversion import ConversionError, fence_items, rally_items
from .autopilot.mission_item import MissionItem
from .autopilot.requests import ApResult, DownloadMission, MissionKind, UploadFence, UploadRally
from .autopilot.state import AutopilotState
from .commands import rally_alt_rel_m
from .landing_point import landing_point
from .outputs import ModuleOutput, Note, Owner, Publish, Submit

if TYPE_CHECKING:
    from .fences import FenceKeeper  # (fences.Fences composes the two)

RETRY_S = 5.0
SETTLE_S = 2.0
_LATLON_TOL_DEG = 2e-7
_PARAM_TOL = 0.5
_RALLY_ALT_TOL_M = 1.0


#: Why a check runs when the autopilot may have lost its stores (alerted when it had).
ATTACHED = frozenset({"node start", "autopilot rebooted", "link back"})
#: ... or when a ground station changed them through MAVLink passthrough (`recheck`)
FROM_OUTSIDE = "set by "


class Stage(Enum):
    VERIFY = "verify"
    RESTORE = "restore"
    REVERIFY = "reverify"


_NAME = {MissionKind.FENCE: "fence", MissionKind.RALLY: "rally point"}
_CODE = {MissionKind.FENCE: AlertCode.NO_FLY_ZONE, MissionKind.RALLY: AlertCode.GENERIC}


def rally_point(
    vehicle_id: int, vehicle_type: VehicleType, base: GeoPoint | None, home: GeoPoint | None
) -> UploadRally | None:
    """The rally point the autopilot should hold: this vehicle's own landing point at
    the base (landing_point.py; commands.rally_alt_rel_m)."""
    if base is None or home is None:
        return None
    alt = rally_alt_rel_m(vehicle_type, base.alt_msl_m - home.alt_msl_m)
    lat, lon = landing_point(vehicle_id, home, base)
    return UploadRally(points=((lat, lon, alt),))


def same_items(kind: MissionKind, held: tuple[MissionItem, ...], want: list[MissionItem]) -> bool:
    """Whether the autopilot's store holds what was uploaded, as ArduPilot stores it."""
    if len(held) != len(want):
        return False
    for h, w in zip(held, want, strict=True):
        if h.command != w.command:
            return False
        if (
            abs(h.lat_deg - w.lat_deg) > _LATLON_TOL_DEG
            or abs(h.lon_deg - w.lon_deg) > _LATLON_TOL_DEG
        ):
            return False
        if kind == MissionKind.FENCE and abs(h.param1 - w.param1) > _PARAM_TOL:
            return False
        if kind == MissionKind.RALLY and abs(h.alt_m - w.alt_m) > _RALLY_ALT_TOL_M:
            return False
    return True


@dataclass
class _Check:
    stage: Stage = Stage.VERIFY
    due: float = 0.0
    why: str = "node start"
    failed: bool = False  # a CRITICAL mismatch was alerted (until it matches again)


@dataclass
class BackstopKeeper:
    vehicle_id: int
    fence: FenceKeeper
    retry_s: float = RETRY_S
    settle_s: float = SETTLE_S
    checks: dict[MissionKind, _Check] = field(default_factory=dict)
    rally_want: UploadRally | None = None
    verified: int = 0  # checks that found the store right
    restored: int = 0  # stores restored and verified
    mismatches: int = 0  # stores found different after a restore (CRITICAL)
    _epoch: tuple[int, int] | None = None  # (reboots, link losses) last attached at
    _in_flight: tuple[MissionKind, int] | None = None  # (store, request id)
    _now: float = float("-inf")  # when the checks were last tried
    _ids: itertools.count[int] = field(default_factory=lambda: itertools.count(1))

    # ------------------------------------------------------------------ inputs
    def on_autopilot(
        self, ap: AutopilotState, rally_want: UploadRally | None, now: float
    ) -> list[ModuleOutput]:
        """Each autopilot state: a new attachment (start, reboot, reconnect) or a new
        rally point to check."""
        if rally_want is not None:
            rally_want = msgspec.structs.replace(rally_want, request_id=0)
        if rally_want != self.rally_want:
            self.rally_want = rally_want
            if rally_want is not None:
                self._check(MissionKind.RALLY, now + self.settle_s, "base set")
            else:
                self.checks.pop(MissionKind.RALLY, None)
        epoch = (ap.reboots, ap.link_losses)
        if ap.link_ok and ap.autopilot_ready and ap.home is not None and epoch != self._epoch:
            before, self._epoch = self._epoch, epoch
            if before is None:
                why = "node start"
            elif epoch[0] != before[0]:
                why = "autopilot rebooted"
            else:
                why = "link back"
            self._check(MissionKind.FENCE, now, why)
            if self.rally_want is not None:
                self._check(MissionKind.RALLY, now, why)
        return self._next(ap, now)

    def recheck(self, why: str, *, restore: bool, now: float) -> None:
        """A ground station changed the stores or their settings (passthrough.py): both
        checked as after a reboot; `restore`: the fence is uploaded again first (a
        setting such as FENCE_ENABLE, which a download of the items cannot see)."""
        if self.fence.want is not None:
            if restore:
                self.fence.forget()
            self._check(MissionKind.FENCE, now, why)
        if self.rally_want is not None:
            self._check(MissionKind.RALLY, now, why)

    def on_result(self, result: ApResult, ap: AutopilotState, now: float) -> list[ModuleOutput]:
        if self._in_flight is None or result.request_id != self._in_flight[1]:
            return []
        kind, _ = self._in_flight
        self._in_flight = None
        check = self.checks.get(kind)
        if check is None:
            return self._next(ap, now)
        if not result.ok:
            check.due = now + self.retry_s  # link down, timeout: again later
            return [
                Note(logging.INFO, f"{_NAME[kind]} check: {result.reason}; retrying"),
                *self._next(ap, now),
            ]
        if check.stage == Stage.RESTORE:  # our rally upload went through: read it back
            check.stage, check.due = Stage.REVERIFY, now
            return self._next(ap, now)
        return self._compare(kind, check, result.items, ap, now)

    def on_timer(self, ap: AutopilotState, now: float) -> list[ModuleOutput]:
        return self._next(ap, now)

    def next_deadline(self) -> float | None:
        """The next check due later than the last time it ran (one due but waiting for
        the link or the fence keeper is tried again at the node's 5 Hz updates)."""
        if self._in_flight is not None:
            return None
        due = [c.due for c in self.checks.values() if c.due > self._now]
        return min(due) if due else None

    # ------------------------------------------------------------------ internals
    def _check(self, kind: MissionKind, due: float, why: str) -> None:
        old = self.checks.get(kind)
        self.checks[kind] = _Check(Stage.VERIFY, due, why, failed=old.failed if old else False)

    def _wanted(self, kind: MissionKind) -> list[MissionItem] | None:
        """What the store should hold (None: nothing to check yet)."""
        try:
            if kind == MissionKind.FENCE:
                want: UploadFence | None = self.fence.want
                return None if want is None else fence_items(want)
            return None if self.rally_want is None else rally_items(self.rally_want)
        except ConversionError:
            return None

    def _next(self, ap: AutopilotState, now: float) -> list[ModuleOutput]:
        self._now = now
        if self._in_flight is not None or not ap.link_ok or not ap.autopilot_ready:
            return []
        for kind in (MissionKind.FENCE, MissionKind.RALLY):
            check = self.checks.get(kind)
            if check is None or now < check.due:
                continue
            if kind == MissionKind.FENCE:
                if self.fence.want is None:  # no zone declared: the fence is left alone
                    del self.checks[kind]
                    continue
                if self.fence.busy or self.fence.want != self.fence.held:
                    continue  # its own upload first; checked once it is done
            if check.stage == Stage.RESTORE:
                if kind == MissionKind.FENCE:
                    check.stage = Stage.REVERIFY  # the FenceKeeper has uploaded it again
                else:
                    assert self.rally_want is not None
                    return self._submit(kind, self.rally_want)
            return self._submit(kind, DownloadMission(kind=kind))
        return []

    def _submit(
        self, kind: MissionKind, request: DownloadMission | UploadRally
    ) -> list[ModuleOutput]:
        rid = next(self._ids)
        self._in_flight = (kind, rid)
        return [Submit(msgspec.structs.replace(request, request_id=rid), Owner.BACKSTOP)]

    def _compare(
        self,
        kind: MissionKind,
        check: _Check,
        held: tuple[MissionItem, ...],
        ap: AutopilotState,
        now: float,
    ) -> list[ModuleOutput]:
        want = self._wanted(kind)
        if want is None:
            del self.checks[kind]
            return self._next(ap, now)
        name = _NAME[kind]
        out: list[ModuleOutput] = []
        if same_items(kind, held, want):
            del self.checks[kind]
            self.verified += 1
            if check.stage == Stage.REVERIFY:
                self.restored += 1
                text = f"{name} restored and verified ({check.why})"
                out.append(Note(logging.WARNING, text))
                if _alerted(check.why):
                    out.append(self._alert(now, Severity.WARNING, kind, text))
            else:
                out.append(Note(logging.INFO, f"{name} verified on the autopilot ({check.why})"))
            if check.failed:
                out.append(
                    self._alert(now, Severity.INFO, kind, f"{name} on the autopilot right again")
                )
            return out + self._next(ap, now)
        detail = f"{len(held)} items, {len(want)} wanted"
        if check.stage == Stage.VERIFY:
            if _alerted(check.why):
                text = f"autopilot {name} lost or changed ({check.why}): restoring"
                out += [
                    Note(logging.WARNING, f"{text}; {detail}"),
                    self._alert(now, Severity.WARNING, kind, text),
                ]
            else:  # a new base: the rally point is uploaded for it
                out.append(Note(logging.INFO, f"{name} for the new base: uploading ({detail})"))
        else:
            self.mismatches += 1
            text = f"autopilot {name} differs after restore: {detail}"
            if not check.failed:
                out.append(self._alert(now, Severity.CRITICAL, kind, text))
            check.failed = True
            out.append(Note(logging.ERROR, f"{text}; again in {self.retry_s:g} s"))
        check.due = now if check.stage == Stage.VERIFY else now + self.retry_s
        check.stage = Stage.RESTORE
        if kind == MissionKind.FENCE:
            self.fence.forget()  # it uploads the fence again (type, items, enable)
        return out + self._next(ap, now)

    def _alert(self, now: float, severity: Severity, kind: MissionKind, text: str) -> Publish:
        return Publish(
            Alert(self.vehicle_id, max(0.0, now), severity, _CODE[kind], short_text(text))
        )


def _alerted(why: str) -> bool:
    """A store found different is alerted when the autopilot may have lost it or a
    ground station changed it (not for a new base: the rally point is uploaded for it)."""
    return why in ATTACHED or why.startswith(FROM_OUTSIDE)
