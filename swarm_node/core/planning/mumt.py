"""Manned-unmanned teaming (MUM-T): unmanned vehicles hold formation slots relative to a
manned lead (aircraft or ground vehicle) whose position comes from its telemetry
(`LeadState.from_status`) or from ADS-B (`LeadState.from_adsb`, the decoded fields of a
MAVLink ADSB_VEHICLE message). The planner is called again whenever a new lead position
arrives: it
predicts where the lead will be `lookahead_s` later, puts the slots there, and gives
each follower a waypoint and a speed that closes its along-track error.

Slots are offsets in the lead's frame (ahead, right, up): by default a vee behind the
lead, `spacing_m` apart (at least twice the widest follower turn radius), each follower
one altitude step above the previous. Followers keep the slot they had (no reshuffle
while moving); new followers take the free slot nearest to them.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from shapely.geometry import Point
from shapely.ops import nearest_points

from swarm_node.core.autopilot.items import ItemKind, Waypoint
from swarm_proto import MissionParams, NoFlyZone, VehicleStatus

from .errors import InvalidParameterError, NoSafeRouteError
from .formation import assign_min_cost
from .geo import LocalFrame, heading_to_yaw
from .vehicles import DEFAULT_PARAMS, PlanVehicle, VehiclePlan, require_vehicles
from .zones import Obstacles, Track, ZoneSet

MIN_COURSE_SPEED_M_S = 1.0  # below this a lead's course comes from its heading

# MAVLink ADSB_FLAGS bits (common.xml) that a lead's ADS-B report must carry
ADSB_FLAGS_VALID_COORDS = 1
ADSB_FLAGS_VALID_ALTITUDE = 2
ADSB_FLAGS_VALID_HEADING = 4
ADSB_FLAGS_VALID_VELOCITY = 8
ADSB_FLAGS_SIMULATED = 64
_ADSB_NEEDED = (
    (ADSB_FLAGS_VALID_COORDS, "position"),
    (ADSB_FLAGS_VALID_ALTITUDE, "altitude"),
    (ADSB_FLAGS_VALID_HEADING, "heading"),
    (ADSB_FLAGS_VALID_VELOCITY, "velocity"),
)

DEFAULT_SPACING_M = 60.0
DEFAULT_STEP_M = 10.0
CATCH_UP_S = 20.0  # close an along-track error over about this long


@dataclass(frozen=True, slots=True)
class LeadState:
    """The lead's last known state (from its VehicleStatus or an ADS-B report)."""

    lat_deg: float
    lon_deg: float
    alt_rel_m: float
    course_deg: float
    speed_m_s: float
    time_s: float = 0.0

    def __post_init__(self) -> None:
        vals = (self.lat_deg, self.lon_deg, self.alt_rel_m, self.course_deg, self.speed_m_s)
        if not all(math.isfinite(v) for v in vals) or self.speed_m_s < 0:
            raise InvalidParameterError(f"bad lead state {vals}")

    @classmethod
    def from_status(cls, s: VehicleStatus) -> LeadState:
        """From the lead's own telemetry (it is a swarm node): course over ground from
        its velocity, or its heading when it moves slower than `MIN_COURSE_SPEED_M_S`
        (a stopped ground vehicle's velocity has no direction)."""
        speed = s.groundspeed_m_s
        course = s.course_deg if speed >= MIN_COURSE_SPEED_M_S else s.heading_deg
        return cls(s.lat_deg, s.lon_deg, s.alt_rel_m, course, speed, s.time_unix_s)

    @classmethod
    def from_adsb(
        cls,
        report: Mapping[str, Any],
        *,
        received_s: float,
        home_alt_msl_m: float,
        icao_address: int | None = None,
        allow_simulated: bool = False,
    ) -> LeadState:
        """From a decoded MAVLink ADSB_VEHICLE message, given as a mapping of its field
        names to values (what pymavlink's `to_dict()` gives; no MAVLink import here):
        `lat`/`lon` degE7, `altitude` mm above mean sea level (`altitude_type` 0: QNH
        pressure altitude, 1: geometric (GNSS); both are used as MSL), `heading`
        centidegrees (course over ground), `hor_velocity` cm/s, `flags` (the ADSB_FLAGS
        validity bits), `ICAO_address`, `tslc` (s since the transponder was last
        heard). The report describes the lead `tslc` s before `received_s`;
        `home_alt_msl_m` turns the altitude into one above home. `icao_address`: the
        lead's, to reject another aircraft's report. Simulated reports (flag
        SIMULATED) are rejected unless `allow_simulated`. Raises
        `InvalidParameterError` naming what is missing, invalid or out of range."""

        def num(name: str, lo: float, hi: float) -> float:
            if name not in report:
                raise InvalidParameterError(f"ADS-B report has no {name!r} field")
            v = report[name]
            if isinstance(v, bool) or not isinstance(v, int | float):
                raise InvalidParameterError(f"ADS-B {name} must be a number, got {v!r}")
            if not (math.isfinite(v) and lo <= v <= hi):
                raise InvalidParameterError(f"ADS-B {name} = {v!r} is not in [{lo}, {hi}]")
            return float(v)

        flags = int(num("flags", 0, 0xFFFF))
        missing = [name for bit, name in _ADSB_NEEDED if not flags & bit]
        if missing:
            raise InvalidParameterError(
                f"ADS-B report without a valid {', '.join(missing)} (flags 0x{flags:04x})"
            )
        if flags & ADSB_FLAGS_SIMULATED and not allow_simulated:
            raise InvalidParameterError("ADS-B report is flagged SIMULATED")
        icao = int(num("ICAO_address", 0, 0xFFFFFF))
        if icao_address is not None and icao != icao_address:
            raise InvalidParameterError(
                f"ADS-B report is from ICAO {icao:06X}, the lead is {icao_address:06X}"
            )
        if num("altitude_type", 0, 1) not in (0.0, 1.0):
            raise InvalidParameterError("ADS-B altitude_type must be 0 (QNH) or 1 (geometric)")
        for name, v in (("received_s", received_s), ("home_alt_msl_m", home_alt_msl_m)):
            if not math.isfinite(v):
                raise InvalidParameterError(f"{name} must be finite, got {v}")
        lat = num("lat", -90e7, 90e7) / 1e7
        lon = num("lon", -180e7, 180e7) / 1e7
        alt_msl = num("altitude", -1_000_000, 50_000_000) / 1000.0
        course = num("heading", 0, 35_999) / 100.0
        speed = num("hor_velocity", 0, 65_534) / 100.0  # 65535: unknown
        age = num("tslc", 0, 255)
        return cls(lat, lon, alt_msl - home_alt_msl_m, course, speed, received_s - age)


@dataclass(frozen=True, slots=True)
class Offset:
    ahead_m: float
    right_m: float
    up_m: float


@dataclass(frozen=True, slots=True)
class FormationSlot:
    vehicle_id: int
    index: int
    x: float
    y: float
    alt_rel_m: float
    speed_m_s: float


@dataclass(frozen=True, slots=True)
class MumtPlan:
    frame: LocalFrame
    lead_xy: tuple[float, float]  # predicted
    slots: tuple[FormationSlot, ...]
    vehicles: tuple[VehiclePlan, ...]
    tracks: tuple[Track, ...] = ()  # each positioned follower's way to its slot

    def slot_of(self, vehicle_id: int) -> FormationSlot:
        return next(s for s in self.slots if s.vehicle_id == vehicle_id)


def vee_offsets(n: int, spacing_m: float, step_m: float) -> list[Offset]:
    """Slot k: (k // 2 + 1) spacings behind, alternately right and left, k+1 steps up."""
    out = []
    for k in range(n):
        rank = k // 2 + 1
        side = 1.0 if k % 2 == 0 else -1.0
        out.append(Offset(-rank * spacing_m, side * rank * spacing_m, (k + 1) * step_m))
    return out


def plan_mumt(
    lead: LeadState,
    vehicles: Sequence[PlanVehicle],
    params: MissionParams = DEFAULT_PARAMS,
    *,
    now_s: float | None = None,
    lookahead_s: float = 5.0,
    previous: Mapping[int, int] | None = None,
    offsets: Sequence[Offset] | None = None,
    zones: Sequence[NoFlyZone] = (),
    home_alt_msl_m: float = 0.0,
    zone_margin_m: float = 0.0,
    frame: LocalFrame | None = None,
) -> MumtPlan:
    """Slots for `vehicles` around the lead predicted `lookahead_s` after `now_s` (the
    lead's report is `now_s - lead.time_s` old). `previous` maps vehicle id -> slot index
    from the last plan, kept when still valid."""
    require_vehicles(vehicles)
    frame = frame or LocalFrame(lead.lat_deg, lead.lon_deg)
    age = max((now_s - lead.time_s) if now_s is not None else 0.0, 0.0)
    yaw = heading_to_yaw(lead.course_deg)
    lx, ly = frame.to_local(lead.lat_deg, lead.lon_deg)
    travel = lead.speed_m_s * (age + lookahead_s)
    px, py = lx + travel * math.cos(yaw), ly + travel * math.sin(yaw)
    r_max = max((v.profile.turn_radius_m() for v in vehicles), default=0.0)
    spacing = max(params.radius_m or DEFAULT_SPACING_M, 2.0 * r_max)
    step = params.altitude_step_m or DEFAULT_STEP_M
    offs = list(offsets) if offsets is not None else vee_offsets(len(vehicles), spacing, step)
    if len(offs) < len(vehicles):
        raise InvalidParameterError(f"{len(vehicles)} followers but only {len(offs)} slots")
    c, s = math.cos(yaw), math.sin(yaw)
    slot_xy = [
        (px + o.ahead_m * c + o.right_m * s, py + o.ahead_m * s - o.right_m * c) for o in offs
    ]
    zs = ZoneSet.from_messages(
        zones, frame, now_unix_s=lead.time_s, home_alt_msl_m=home_alt_msl_m, margin_m=zone_margin_m
    )
    # keep previous slots; the others by least total distance
    prev = dict(previous or {})
    taken = {
        i for vid, i in prev.items() if i < len(offs) and any(v.vehicle_id == vid for v in vehicles)
    }
    index: dict[int, int] = {
        v.vehicle_id: prev[v.vehicle_id]
        for v in vehicles
        if v.vehicle_id in prev and prev[v.vehicle_id] < len(offs)
    }
    new = [v for v in vehicles if v.vehicle_id not in index]
    free = [i for i in range(len(offs)) if i not in taken]
    if new:
        xy = [frame.to_local(v.pose.lat_deg, v.pose.lon_deg) if v.pose else (px, py) for v in new]
        cost = np.array([[math.dist(p, slot_xy[i]) for i in free] for p in xy])
        for v, col in zip(new, assign_min_cost(cost), strict=True):
            index[v.vehicle_id] = free[col]
    slots, plans = [], []
    tracks: list[Track] = []
    for v in vehicles:
        k = index[v.vehicle_id]
        x, y = slot_xy[k]
        alt = lead.alt_rel_m + offs[k].up_m
        z = zs.zone_containing(x, y, alt)
        if z is not None:  # hold the nearest point outside the zone instead
            keep = zs.keep_out(alt, 1.0)
            q = nearest_points(
                keep.exterior if hasattr(keep, "exterior") else keep.boundary, Point(x, y)
            )[0]
            x, y = float(q.x), float(q.y)
        lo, hi = v.speed_range()
        along = 0.0
        if v.pose is not None:
            vx, vy = frame.to_local(v.pose.lat_deg, v.pose.lon_deg)
            along = (x - vx) * c + (y - vy) * s  # slot ahead of the follower: speed up
        speed = min(max(lead.speed_m_s + along / CATCH_UP_S, lo), hi)
        slots.append(FormationSlot(v.vehicle_id, k, x, y, alt, speed))
        way = [(x, y)]
        if v.pose is not None:  # around the zones on the way to the slot
            here = frame.to_local(v.pose.lat_deg, v.pose.lon_deg)
            way = [here, (x, y)]
            if zs.entered(way, alt) is not None:
                if zs.zone_containing(*here, alt) is not None:
                    raise NoSafeRouteError(
                        f"vehicle {v.vehicle_id} is inside a no-fly zone: replan the mission"
                    )
                try:
                    way = Obstacles(zs.keep_out(alt)).path(here, (x, y))
                except NoSafeRouteError:  # it is within the margin: around the zones alone
                    way = Obstacles(zs.raw(alt)).path(here, (x, y))
            tracks.append(Track(v.vehicle_id, "transit", tuple(way), alt))
            way = way[1:]
        ll = frame.to_geodetic_many(way).tolist()
        wps = (
            Waypoint(ItemKind.CHANGE_SPEED, speed_m_s=speed),
            *(Waypoint(ItemKind.WAYPOINT, la, lo, alt) for la, lo in ll),
        )
        plans.append(VehiclePlan(v.vehicle_id, wps, 0.0, 0.0))
    return MumtPlan(frame, (px, py), tuple(slots), tuple(plans), tuple(tracks))
