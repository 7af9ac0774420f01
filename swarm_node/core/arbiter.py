"""AutopilotArbiter: the one place that decides who commands the autopilot.

Every module asks as its own owner (`Submit(request, owner)`). The arbiter gives each
request an id of its own (one counter), remembers whose it is and the owner's id, and
routes the result back to that owner with the owner's id (`on_result`). A result
nobody asked for is counted and dropped (`stray`).

Precedence, highest first (`PRECEDENCE`, the one table; docs/node.md):

    owner      module                          asks for                       under a higher holder
    EMERGENCY  emergency.py                    the emergency procedure        -
    AVOIDANCE  safety/module.py                manoeuvres                     refused
    OPERATOR   operator.py                     the operator's commands        refused
    MISSION    mission_manager.py              launch, share, way home, the   held while AVOIDANCE
                                               landing on its pad             suspends it, else refused
    FENCE      fences.py                       the fence                      does not fly: never refused
    BACKSTOP   backstop.py                     fence and rally checks         does not fly: never refused
    REATTACH   reattach.py                     the mission read back          does not fly: never refused

A request that flies the vehicle (everything but fence, rally, parameter and calibration
work, and downloads) takes control for its owner; while a higher owner holds control, a
lower owner's flight request is refused at once with a failed result marked as the
arbiter's own (`ApError.PREEMPTED`, "preempted by ..."), routed back to it like any
other. The holder keeps control until it releases it
(`release`); a higher owner may always take it (`take`: an emergency begins).

Suspension (`suspend`, `release`): AVOIDANCE takes control for a manoeuvre and suspends
the mission. The mission manager is told (`Suspended(MISSION, True)`); its flight
requests are held, not refused (a newer ChangeSpeed replaces a held one), or, while the
manoeuvre is flown on the mission's own path (`passing`: a fixed-wing's altitude
change), go on at once under it. When avoidance releases control, the holder before it
has control again, the mission manager is told (`Suspended(MISSION, False)`) and its
held requests are ruled on again, in order. A higher owner taking control ends the
suspension and drops what was held.

Delegation (`delegate`): the mission manager watching the landing of a vehicle the
operator recalled asks with the operator's rank, until the operator releases control.

Its inputs are the modules' outputs `Submit`, `Claim`, `Release`, `Suspend` and
`Delegate` (`rule`); its outcomes (`Send`, `Routed`, `Suspended`) NodeCore sends on.

Pure: no I/O, no clock.
"""

from __future__ import annotations

import itertools
from collections import Counter
from dataclasses import dataclass, field
from enum import IntEnum
from typing import assert_never

import msgspec

from .autopilot.requests import (
    ApError,
    ApRequest,
    ApResult,
    Calibrate,
    ChangeSpeed,
    DownloadMission,
    RelaySetting,
    SetParam,
    UploadFence,
    UploadRally,
)


class Owner(IntEnum):
    """Who asks the autopilot; the value is the precedence (higher wins control)."""

    REATTACH = 1
    BACKSTOP = 2
    FENCE = 3
    MISSION = 4
    OPERATOR = 5
    AVOIDANCE = 6
    EMERGENCY = 7


@dataclass(frozen=True)
class Seat:
    """One row of the precedence table."""

    owner: Owner
    module: str
    asks: str
    outranked: str  # what happens to its flight requests while a higher owner holds control


#: The precedence table, highest first (the order of `Owner`'s values; checked by tests).
PRECEDENCE: tuple[Seat, ...] = (
    Seat(Owner.EMERGENCY, "emergency.py", "the emergency procedure", "-"),
    Seat(Owner.AVOIDANCE, "safety/module.py", "collision avoidance manoeuvres", "refused"),
    Seat(Owner.OPERATOR, "operator.py", "the operator's commands", "refused"),
    Seat(
        Owner.MISSION,
        "mission_manager.py",
        "launch, share, way home, landing on its pad",
        "held while AVOIDANCE suspends it, else refused",
    ),
    Seat(Owner.FENCE, "fences.py", "the fence", "does not fly: never refused"),
    Seat(Owner.BACKSTOP, "backstop.py", "fence and rally point checks", "does not fly"),
    Seat(Owner.REATTACH, "reattach.py", "the mission read back", "does not fly"),
)

#: who suspends whom: their flight requests are held, not refused, while it holds control
SUSPENDS: dict[Owner, tuple[Owner, ...]] = {Owner.AVOIDANCE: (Owner.MISSION,)}

#: requests that do not fly the vehicle: never refused for precedence
NOT_FLIGHT = (UploadFence, UploadRally, SetParam, Calibrate, DownloadMission, RelaySetting)


def flies(request: ApRequest) -> bool:
    return not isinstance(request, NOT_FLIGHT)


# ----------------------------------------------------------------------- inputs
@dataclass(frozen=True)
class Submit:
    """An autopilot request of `owner`: the arbiter ranks it by its owner (or the rank
    delegated to it) and routes its result back to it."""

    request: ApRequest
    owner: Owner


@dataclass(frozen=True)
class Claim:
    """`owner` takes control of the autopilot (an emergency begins)."""

    owner: Owner


@dataclass(frozen=True)
class Release:
    """`owner` gives control back (to whoever held it before a suspension it began)."""

    owner: Owner


@dataclass(frozen=True)
class Suspend:
    """Avoidance takes control and suspends the mission; `passing`: the mission's
    requests go on under the manoeuvre (flown on its path) instead of being held."""

    passing: bool


@dataclass(frozen=True)
class Delegate:
    """`to` asks with `rank`'s precedence until `rank` releases control."""

    to: Owner
    rank: Owner


ToArbiter = Submit | Claim | Release | Suspend | Delegate


# ----------------------------------------------------------------------- outcomes
@dataclass(frozen=True)
class Send:
    """A request to send to the autopilot (with the arbiter's id), on `owner`'s behalf."""

    request: ApRequest
    owner: Owner


@dataclass(frozen=True)
class Routed:
    """A result for the module `owner`, with the id that module gave its request."""

    owner: Owner
    result: ApResult


@dataclass(frozen=True)
class Suspended:
    """Told to a suspended owner: its flight requests are held (`on`), or no longer."""

    owner: Owner
    on: bool


Outcome = Send | Routed | Suspended


@dataclass
class _Suspension:
    by: Owner
    before: Owner | None  # the holder control goes back to
    passing: bool  # the suspended owners' requests go on under the manoeuvre
    held: list[tuple[Owner, Owner, ApRequest]] = field(default_factory=list)  # owner, rank


@dataclass
class AutopilotArbiter:
    holder: Owner | None = None  # who controls the autopilot's flight now
    refused: Counter[Owner] = field(default_factory=Counter)
    stray: int = 0  # results nobody asked for
    _ids: itertools.count[int] = field(default_factory=lambda: itertools.count(1))
    _owners: dict[int, tuple[Owner, int]] = field(default_factory=dict)
    _suspension: _Suspension | None = None
    _acting: dict[Owner, Owner] = field(default_factory=dict)  # owner -> the rank it asks with

    # ------------------------------------------------------------------ views
    @property
    def suspended_by(self) -> Owner | None:
        return self._suspension.by if self._suspension is not None else None

    def rank(self, owner: Owner) -> Owner:
        return self._acting.get(owner, owner)

    def held(self) -> list[ApRequest]:
        """The suspended owners' requests held now, in order."""
        s = self._suspension
        return [r for _, _, r in s.held] if s is not None else []

    def will_steer(self) -> bool:
        """A held request will reach the autopilot once the suspension ends and say where
        the vehicle goes: not a speed (the speed rule's ChangeSpeed goes on after the
        resume), not one the holder given control back outranks (it will be refused)."""
        s = self._suspension
        if s is None:
            return False
        return any(
            not isinstance(r, ChangeSpeed) and not (s.before is not None and s.before > rank)
            for _, rank, r in s.held
        )

    def pending(self, owner: Owner) -> int:
        return sum(1 for o, _ in self._owners.values() if o == owner)

    def rule(self, o: ToArbiter) -> list[Outcome]:
        """A module's request or control output, ruled on."""
        match o:
            case Submit(request, owner):
                return self.submit(owner, request)
            case Claim(owner):
                return self.take(owner)
            case Release(owner):
                return self.release(owner)
            case Suspend(passing):
                return self.suspend(Owner.AVOIDANCE, passing=passing)
            case Delegate(to, rank):
                self.delegate(to, rank)
                return []
            case _:
                assert_never(o)

    # ------------------------------------------------------------------ requests
    def submit(self, owner: Owner, request: ApRequest) -> list[Outcome]:
        """The request to send (with the arbiter's id), its refusal to route back at
        once, or nothing (held while its owner is suspended)."""
        if not flies(request):
            return [self._send(owner, request)]
        return self._rule(owner, self.rank(owner), request)

    def _rule(self, owner: Owner, rank: Owner, request: ApRequest) -> list[Outcome]:
        s = self._suspension
        if s is not None and owner in SUSPENDS[s.by]:
            if s.passing:
                return [self._send(owner, request)]
            if isinstance(request, ChangeSpeed):  # only the newest speed goes on
                s.held = [h for h in s.held if not isinstance(h[2], ChangeSpeed)]
            s.held.append((owner, rank, request))
            return []
        if self.holder is not None and self.holder > rank:
            self.refused[owner] += 1
            reason = f"preempted by {self.holder.name}"
            refused = ApResult(request.request_id, False, reason, error=ApError.PREEMPTED)
            return [Routed(owner, refused)]
        out = self._preempt(rank)
        self.holder = rank
        return [*out, self._send(owner, request)]

    def on_result(self, result: ApResult) -> Routed | None:
        entry = self._owners.pop(result.request_id, None)
        if entry is None:
            self.stray += 1
            return None
        owner, own_id = entry
        return Routed(owner, msgspec.structs.replace(result, request_id=own_id))

    # ------------------------------------------------------------------ control
    def take(self, owner: Owner) -> list[Outcome]:
        """`owner` takes control (an emergency begins) if it outranks the holder."""
        out = self._preempt(owner)
        if self.holder is None or owner >= self.holder:
            self.holder = owner
        return out

    def suspend(self, by: Owner, *, passing: bool) -> list[Outcome]:
        """`by` (AVOIDANCE) takes control and suspends the owners it suspends; again
        while suspended: whether their requests go on under it (`passing`) changed."""
        s = self._suspension
        if s is not None:
            s.passing = passing
            return []
        if self.holder is not None and self.holder > by:
            return []  # a higher owner holds control: nothing to suspend
        before = self.holder if self.holder != by else None
        self._suspension = _Suspension(by, before, passing)
        self.holder = by
        return [Suspended(o, True) for o in SUSPENDS[by]]

    def release(self, owner: Owner) -> list[Outcome]:
        """`owner` gives control back: to the holder before a suspension it began (the
        held requests ruled on again), else to nobody. The operator releasing control
        ends its delegation."""
        self._acting = {k: v for k, v in self._acting.items() if v != owner}
        s = self._suspension
        if s is None or s.by != owner:
            if self.holder == owner:
                self.holder = None
            return []
        self._suspension = None
        if self.holder == owner:
            self.holder = s.before
        out: list[Outcome] = [Suspended(o, False) for o in SUSPENDS[owner]]
        for o, rank, request in s.held:
            out += self._rule(o, rank, request)
        return out

    def delegate(self, to: Owner, rank: Owner) -> None:
        """`to` asks with `rank`'s precedence until `rank` releases control."""
        self._acting[to] = rank

    # ------------------------------------------------------------------ internals
    def _send(self, owner: Owner, request: ApRequest) -> Send:
        rid = next(self._ids)
        self._owners[rid] = (owner, request.request_id)
        return Send(msgspec.structs.replace(request, request_id=rid), owner)

    def _preempt(self, owner: Owner) -> list[Outcome]:
        """A suspension ends, its held requests dropped, when a higher owner takes
        control (an emergency: it stopped the mission)."""
        s = self._suspension
        if s is None or owner <= s.by:
            return []
        self._suspension = None
        return [Suspended(o, False) for o in SUSPENDS[s.by]]
