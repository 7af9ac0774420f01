"""The own vehicle's take-off and landing at close pads, as the mission manager flies
them (safety/pads.py decides who goes; this is the sequence on this vehicle):

- the launch: the mission's Arm waits until no neighbour with priority is on or low
  over its pad (`may_move(taking_off=True)`); while it waits the state machine's plan
  timeout does not count (`launch_queued`);
- the return of a multirotor or VTOL: the way home (zone-safe legs, then RTL; or a
  plain RTL) is flown as a mission to a hold over the own pad at its holding layer
  (`hold_layer`) and the landing there; at the hold the descent starts once the pad is
  clear (a fixed-wing circles down to the lowest layer first), not while avoidance holds
  the autopilot, and again after a manoeuvre took it off its way down; a failed step
  falls back to RTL; a new mission ends the landing.

The mission manager asks (`upload`, `hold_launch`, `home`, `answers_land`), ticks it at
the avoidance's 5 Hz (`tick`) and sends what it returns as its own requests. Peers and
pads are asked for only when a take-off or landing needs them (a swarm's size is not
walked at 5 Hz).

Pure: no I/O; `now` is passed in.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field

import msgspec

from swarm_proto import Alert, AlertCode, GeoPoint, Severity, VehicleStatus, VehicleType
from swarm_proto.text import short_text

from ..autopilot.items import ItemKind, Waypoint
from ..autopilot.requests import (
    ApRequest,
    Arm,
    ChangeAltitude,
    StartMission,
    UploadMission,
)
from ..autopilot.state import AutopilotState
from ..outputs import ModuleOutput, Note, Publish
from ..profile import VehicleProfile
from .pads import PadConfig, hold_layer, hovering, may_move

LOWERED_M = 5.0  # a fixed-wing circling down to its lowest layer is there within this
GROUND = (VehicleType.ROVER, VehicleType.BOAT)

Peers = Callable[[], Iterable[tuple[VehicleStatus, GeoPoint | None]]]


@dataclass(slots=True)
class PadLanding:
    """Landing on the own pad: the return flown to above it at the holding layer, a hold
    there (`hold_seq`) until the pad is clear, then the landing item (`land_seq`)."""

    pad: GeoPoint
    hold_seq: int
    land_seq: int
    hold_alt_rel_m: float
    descending: bool = False
    lowering: bool = False  # a fixed-wing circles down to the lowest layer first
    waited_since: float | None = None


@dataclass
class PadSequence:
    profile: VehicleProfile
    enabled: bool = True  # off with collision avoidance (NodeSettings.avoidance)
    config: PadConfig = field(default_factory=PadConfig)
    # the peers' latest statuses with their homes; every known vehicle's home (the pads);
    # the peers' vehicle types: asked for only when a take-off or landing needs them
    peers: Peers = list
    pads: Callable[[], Mapping[int, GeoPoint]] = dict
    types: Callable[[], Mapping[int, VehicleType]] = dict
    launch: ApRequest | None = None  # the mission's Arm, held until the pad is clear
    landing: PadLanding | None = None
    suspended: bool = False  # avoidance holds the autopilot: no descent meanwhile
    counters: dict[str, int] = field(default_factory=dict)
    _launch_waited: float | None = None
    _launch_why: str = ""

    # ------------------------------------------------------------------ views
    @property
    def lands_on_pad(self) -> bool:
        return self.enabled and self.profile.vehicle_type in (VehicleType.COPTER, VehicleType.VTOL)

    @property
    def answers_land(self) -> bool:
        """The landing on the pad flies: the mission manager's Land is answered at once,
        nothing sent to the autopilot."""
        return self.landing is not None

    # ------------------------------------------------------------------ asks
    def hold_launch(self, req: ApRequest, ap: AutopilotState, now: float) -> Note | None:
        """The mission's Arm held until the pad is clear (a note why; `tick` lets it go),
        or None: send it."""
        if not self.enabled or not isinstance(req, Arm) or ap.armed:
            return None
        if self.profile.vehicle_type in GROUND or not self._launch_blockers(ap):
            return None
        self.launch, self._launch_waited = req, now
        self._count("launch_held")
        return Note(logging.INFO, f"take-off: waiting ({self._launch_why})")

    def upload(self, req: UploadMission, ap: AutopilotState) -> UploadMission:
        """The mission manager's upload as flown: its zone-safe way home (legs, then RTL)
        becomes the legs, a hold over the own pad at the holding layer and the landing
        there; any other upload (a new mission: a vehicle sent on again on its way home)
        ends the landing. Kept, its gate fired in the new mission at the old hold's item
        number (measured in the demo: the route's leg was sent down towards 30 m)."""
        if not (self.lands_on_pad and req.items and req.items[-1].kind == ItemKind.RTL):
            self.landing = None
            return req
        pad = ap.home
        if pad is None:
            return req
        hold = self._hold_alt(pad)
        legs = req.items[:-1]
        self.landing = PadLanding(pad, len(legs) + 1, len(legs) + 2, hold)
        self._count("pad_returns")
        return msgspec.structs.replace(req, items=(*legs, *self._pad_items(pad, hold)))

    def home(self, ap: AutopilotState) -> tuple[Note, tuple[ApRequest, ...]] | None:
        """The mission manager's plain RTL (nothing in the way home), flown as a mission
        to above the own pad at the holding layer, a hold there and the landing (None:
        a plain RTL as asked)."""
        pad = ap.home
        if not self.lands_on_pad or not ap.armed or pad is None:
            return None
        if ap.lat_deg is None or ap.lon_deg is None:
            return None
        hold = self._hold_alt(pad)
        there = Waypoint(ItemKind.WAYPOINT, pad.lat_deg, pad.lon_deg, hold)
        items = (there, *self._pad_items(pad, hold))
        self.landing = PadLanding(pad, 2, 3, hold)
        self._count("pad_returns")
        note = Note(logging.INFO, f"return: to its pad, holding at {hold:.0f} m")
        return note, (UploadMission(items=items), StartMission(first_item=1))

    # ------------------------------------------------------------------ results
    def failed(self, req: ApRequest, reason: str, now: float) -> tuple[list[ModuleOutput], bool]:
        """A request of the landing on the pad failed: the landing is given up; whether
        one was on (the mission manager falls back to RTL)."""
        self._count("failed")
        ld, self.landing = self.landing, None
        text = f"landing on pad: {type(req).__name__} failed, RTL ({reason})"
        return [self._alert(now, text)], ld is not None

    def resumed(self) -> None:
        """Avoidance gave the autopilot back: a manoeuvre during the landing took it off
        its way down, the gate starts the descent again (a fixed-wing would circle its
        hold layer for good)."""
        self.suspended = False
        ld = self.landing
        if ld is not None:
            ld.descending = ld.lowering = False
            ld.waited_since = None

    def stop(self) -> None:
        """The mission manager stopped: nothing of its launch or landing goes on."""
        self.launch, self.landing = None, None

    # ------------------------------------------------------------------ tick
    def tick(
        self, ap: AutopilotState, now: float
    ) -> tuple[ApRequest | None, list[ModuleOutput], tuple[ApRequest, ...]]:
        """At the avoidance's 5 Hz: the launch let go (the held Arm), notes, and the
        landing's next requests."""
        if not self.enabled:
            return None, [], ()
        out: list[ModuleOutput] = []
        launched = None
        if self.launch is not None and not self._launch_blockers(ap):
            waited = now - (self._launch_waited or now)
            out.append(Note(logging.INFO, f"take-off: pad clear after {waited:.1f} s"))
            launched, self.launch = self.launch, None
        ld = self.landing
        if ld is None:
            return launched, out, ()
        if not ap.armed and (ap.alt_rel_m or 0.0) < self.config.airborne_m:
            self.landing = None  # down
            return launched, out, ()
        low = self.config.hold_alt_rel_m + LOWERED_M
        circles = not hovering(self.profile.vehicle_type, ap.mode_name, ap.groundspeed_m_s)
        if ld.lowering and not self.suspended and (ap.alt_rel_m or 0.0) <= low:
            ld.lowering = False
            out.append(Note(logging.INFO, "landing: down to the lowest layer, on to the pad"))
            return launched, out, (StartMission(first_item=ld.land_seq),)
        if (
            ld.descending
            or self.suspended
            or ap.mode_name != "AUTO"
            or ap.mission_current != ld.hold_seq
            or ap.lat_deg is None
            or ap.lon_deg is None
        ):
            return launched, out, ()
        blockers = may_move(
            self.profile.vehicle_id,
            ld.pad,
            self.peers(),
            taking_off=False,
            config=self.config,
            own_alt_msl_m=ap.alt_msl_m,
            own_circles=circles,
        )
        if blockers:
            if ld.waited_since is None:
                ld.waited_since = now
                why = ", ".join(b.why for b in blockers)
                out.append(
                    Note(logging.INFO, f"landing: holding at {ld.hold_alt_rel_m:.0f} m ({why})")
                )
            return launched, out, ()
        ld.descending = True
        waited = now - ld.waited_since if ld.waited_since is not None else 0.0
        out.append(Note(logging.INFO, f"landing: on its pad (waited {waited:.1f} s)"))
        if circles and (ap.alt_rel_m or 0.0) > low:
            # a fixed-wing circles down in its hold first (a landing leg started high
            # would dive at it)
            ld.lowering = True
            return launched, out, (ChangeAltitude(alt_rel_m=self.config.hold_alt_rel_m),)
        return launched, out, (StartMission(first_item=ld.land_seq),)

    # ------------------------------------------------------------------ internals
    def _launch_blockers(self, ap: AutopilotState) -> bool:
        pad = ap.home
        if pad is None:
            return False
        blockers = may_move(
            self.profile.vehicle_id, pad, self.peers(), taking_off=True, config=self.config
        )
        self._launch_why = ", ".join(b.why for b in blockers)
        return bool(blockers)

    def _hold_alt(self, pad: GeoPoint) -> float:
        pads = dict(self.pads())
        pads[self.profile.vehicle_id] = pad
        types = {**self.types(), self.profile.vehicle_id: self.profile.vehicle_type}
        wings = {v for v, t in types.items() if t in (VehicleType.PLANE, VehicleType.VTOL)}
        hover = {v for v, t in types.items() if t == VehicleType.COPTER}
        return hold_layer(self.profile.vehicle_id, pad, pads, self.config, wings, hover)

    def _pad_items(self, pad: GeoPoint, hold: float) -> tuple[Waypoint, Waypoint]:
        return (
            Waypoint(ItemKind.LOITER_UNLIMITED, pad.lat_deg, pad.lon_deg, hold),
            Waypoint(ItemKind.LAND, pad.lat_deg, pad.lon_deg, 0.0),
        )

    def _alert(self, now: float, text: str) -> Publish:
        vid = self.profile.vehicle_id
        return Publish(
            Alert(vid, max(0.0, now), Severity.WARNING, AlertCode.COLLISION_RISK, short_text(text))
        )

    def _count(self, what: str) -> None:
        self.counters[what] = self.counters.get(what, 0) + 1
