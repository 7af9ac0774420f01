"""An emergency return that does not cross a no-fly zone.

ArduPilot's RTL flies a straight line to the rally point (or home). Against SITL a
copter that breached a zone was sent to RTL and flew straight through it (13.8 m from
its centre). When that straight line would cross a zone in force, the node flies the
zone-safe way home instead, as the mission manager does after a mission: the legs
around the zones, uploaded as a mission ending in RTL (so ArduPilot's own RTL only
flies the last, clear, stretch and lands). When the line is clear, or no zone-safe leg
can be planned (e.g. the vehicle is inside the zone), plain RTL.
"""

from __future__ import annotations

from collections.abc import Sequence

import msgspec

from swarm_proto import GeoPoint, NoFlyZone

from .autopilot.items import ItemKind, Waypoint
from .autopilot.requests import ApRequest, ReturnToLaunch, StartMission, UploadMission
from .autopilot.state import AutopilotState
from .planning import PlanningError
from .planning.flight import FIXED_WING_ACCEPT_M
from .planning.transit import (
    TRANSIT_MARGIN_M,
    fixed_wing_transit,
    flown_turn_radius_m,
    safe_transit,
)
from .profile import VehicleProfile

MIN_RETURN_ALT_M = 30.0  # as the mission manager's way home


def zone_safe_emergency(
    requests: tuple[ApRequest, ...],
    ap: AutopilotState,
    base: GeoPoint | None,
    zones: Sequence[NoFlyZone],
    profile: VehicleProfile,
    now: float,
) -> tuple[tuple[ApRequest, ...], str]:
    """`requests` with an RTL replaced by the zone-safe way to the base (the rally point;
    home without one) when RTL's straight line would cross a zone; and why, for the log
    ("" when unchanged)."""
    if not any(isinstance(r, ReturnToLaunch) for r in requests):
        return requests, ""
    home = ap.home
    if not zones or home is None or ap.lat_deg is None or ap.lon_deg is None or not ap.armed:
        return requests, ""
    if ap.landed:
        return requests, ""
    there = (base.lat_deg, base.lon_deg) if base is not None else (home.lat_deg, home.lon_deg)
    start = (ap.lat_deg, ap.lon_deg)
    alt = max(ap.alt_rel_m or 0.0, MIN_RETURN_ALT_M)
    # the planners' margin at the speed it flies now (faster than cruise: a wider turn)
    radius = flown_turn_radius_m(profile, max(ap.airspeed_m_s, ap.groundspeed_m_s))
    margin = max(TRANSIT_MARGIN_M, 2.0 * radius)
    try:
        if profile.is_fixed_wing:
            legs = fixed_wing_transit(
                start,
                ap.heading_deg,
                there,
                alt,
                zones,
                radius_m=radius,
                now=now,
                home_alt_msl_m=home.alt_msl_m,
            )
        else:
            legs = safe_transit(
                start, there, alt, zones, now=now, home_alt_msl_m=home.alt_msl_m, margin_m=margin
            )
    except (PlanningError, ValueError) as exc:
        return requests, f"no zone-safe way home ({exc}): plain RTL"
    if len(legs) <= 1:
        return requests, ""  # the straight line is clear
    if profile.is_fixed_wing:
        legs = [
            msgspec.structs.replace(w, acceptance_radius_m=FIXED_WING_ACCEPT_M)
            if w.kind == ItemKind.WAYPOINT and w.acceptance_radius_m == 0.0
            else w
            for w in legs
        ]
    route = (UploadMission(items=(*legs, Waypoint(ItemKind.RTL))), StartMission())
    out: list[ApRequest] = []
    for r in requests:
        out += list(route) if isinstance(r, ReturnToLaunch) else [r]
    return tuple(out), f"RTL would cross a no-fly zone: {len(legs)} zone-safe legs home, then RTL"
