"""How long a vehicle can fly, and what its waypoints cost in time beyond their length.

The planners split work so that the fleet finishes together; two things make a share
take longer, or cost more battery, than its length over the speed says:

- a vehicle that stops on each waypoint (multirotors, rovers, boats: ArduCopter brakes
  towards a stop on a waypoint, counts it reached within its acceptance radius, and
  accelerates away) flies each leg with a trapezoidal speed profile from and to the
  speed v0 = sqrt(2 a r) it still has at the acceptance radius r (`STOP_ACCEPT_M`):
  d / v + (v - v0)^2 / (a v), or 2 (vp - v0) / a with vp = sqrt(a d + v0^2) for a leg
  too short to reach v (`leg_s`), and at a corner of angle t cancels the part of v0
  no longer pointing the new way, v0 (1 - cos t) / a (`stop_and_go_s`);
- the battery: a sortie is a climb (lift motors), the share and the way home (cruise
  current), and a landing (lift motors). `Endurance.cruise_budget_s` is the time at
  cruise the battery allows once the climb and landing are paid for, keeping
  `battery_critical_pct` plus `RESERVE_FRACTION` of the capacity unused, so a vehicle
  flying its share and the way home never reaches BATTERY_CRITICAL.

The figures come from the vehicle profile (the swarm database's model parameters:
`battery_capacity_mah`, `cruise_current_a`, `hover_current_a`, `accel_m_s2`); a
profile without a capacity or a cruise current has no endurance limit.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass

from swarm_node.core.profile import VehicleProfile
from swarm_proto import VehicleType

#: battery kept unused beyond the critical level (model error, wind, a go-around)
RESERVE_FRACTION = 0.10
#: a vehicle that stops on its waypoints counts one reached this close (WPNAV_RADIUS 2 m)
STOP_ACCEPT_M = 2.0
#: horizontal acceleration when the profile has none (ArduCopter WPNAV_ACCEL 250 cm/s/s)
DEFAULT_ACCEL_M_S2 = {VehicleType.COPTER: 2.5, VehicleType.ROVER: 1.0, VehicleType.BOAT: 0.5}
#: QuadPlane lift-system defaults (Q_WP_SPEED_UP, Q_WP_SPEED_DN), for VTOL climbs and landings
VTOL_CLIMB_M_S = 2.5
VTOL_SINK_M_S = 1.5
#: QuadPlane forward transition: accelerate on the lift motors to the minimum airspeed,
#: then Q_TRANSITION_MS (5 s) to complete it (assumption: 3 m/s/s)
VTOL_TRANSITION_ACCEL_M_S2 = 3.0
VTOL_TRANSITION_S = 5.0
#: the last metres of a landing at ArduPilot's LAND_SPEED (0.5 m/s)
LAND_FINAL_M = 10.0
LAND_FINAL_M_S = 0.5


#: the mission manager starts a share once this much of the take-off altitude is reached
CLIMB_FRACTION = 0.8
#: a plane's climb-out in TAKEOFF mode when its profile has no climb rate (TECS_CLMB_MAX)
PLANE_CLIMB_M_S = 5.0
#: arming, the take-off command and the start of the mission, each a MAVLink round trip
#: with its ack (measured in fast time: 0.3 s from release to the climb)
LAUNCH_COMMANDS_S = 0.5


def launch_s(profile: VehicleProfile, altitude_m: float) -> float:
    """Seconds from the plan to the start of a share for a vehicle on the ground at its
    home: arm, take off and climb to CLIMB_FRACTION of `altitude_m` (a VTOL on its lift
    motors at VTOL_CLIMB_M_S, a multirotor at its climb rate, a plane in TAKEOFF mode
    at its climb rate), then start; a ground vehicle only arms and starts."""
    vt = profile.vehicle_type
    if vt in (VehicleType.ROVER, VehicleType.BOAT) or not math.isfinite(altitude_m):
        return LAUNCH_COMMANDS_S
    if vt == VehicleType.VTOL:
        up = VTOL_CLIMB_M_S
    elif vt == VehicleType.PLANE:
        up = profile.climb_rate_m_s or PLANE_CLIMB_M_S
    else:
        up = profile.climb_rate_m_s or VTOL_CLIMB_M_S
    return LAUNCH_COMMANDS_S + CLIMB_FRACTION * max(altitude_m, 0.0) / up


def stops_on_waypoints(profile: VehicleProfile) -> bool:
    """Whether the vehicle brakes to a stop on every waypoint (not fixed-wing)."""
    return not profile.is_fixed_wing


def accel_m_s2(profile: VehicleProfile) -> float:
    """The acceleration a vehicle that stops on its waypoints brakes and accelerates
    with (the profile's, else ArduPilot's default for its type); 0 for a fixed-wing."""
    if not stops_on_waypoints(profile):
        return 0.0
    return profile.accel_m_s2 or DEFAULT_ACCEL_M_S2.get(profile.vehicle_type, 2.5)


def leg_s(length_m: float, speed_m_s: float, accel: float) -> float:
    """Time of a straight leg between two waypoints the vehicle brakes for (from and to
    the speed it has at their acceptance radius); at constant speed when `accel` is 0."""
    v, d = speed_m_s, max(length_m, 0.0)
    if accel <= 0.0:
        return d / v
    v0 = min(math.sqrt(2.0 * accel * STOP_ACCEPT_M), v)
    if d >= (v * v - v0 * v0) / accel:
        return d / v + (v - v0) ** 2 / (accel * v)
    vp = math.sqrt(accel * d + v0 * v0)
    return 2.0 * (vp - v0) / accel


def stop_and_go_s(points: Sequence[tuple[float, float]], speed_m_s: float, accel: float) -> float:
    """Time along a polyline braking for each of its points after the first (constant
    speed when `accel` is 0); at a corner of angle t the vehicle also has to cancel
    the part of its speed v0 that no longer points the new way, v0 (1 - cos t) / a."""
    pts = [p for i, p in enumerate(points) if i == 0 or math.dist(p, points[i - 1]) > 1e-9]
    total = sum(leg_s(math.dist(a, b), speed_m_s, accel) for a, b in itertools.pairwise(pts))
    if accel <= 0.0:
        return total
    v0 = min(math.sqrt(2.0 * accel * STOP_ACCEPT_M), speed_m_s)
    for a, b, c in zip(pts, pts[1:], pts[2:], strict=False):
        h1 = math.atan2(b[1] - a[1], b[0] - a[0])
        h2 = math.atan2(c[1] - b[1], c[0] - b[0])
        total += v0 * (1.0 - math.cos(h2 - h1)) / accel
    return total


def transition_s(profile: VehicleProfile, speed_m_s: float) -> float:
    """Seconds a VTOL starting its share in hover loses to the forward transition,
    against flying the same distance at `speed_m_s`: it accelerates to its minimum
    airspeed (1.1 x stall) at VTOL_TRANSITION_ACCEL_M_S2, then takes VTOL_TRANSITION_S
    to reach `speed_m_s`. 0 for other vehicles."""
    if profile.vehicle_type != VehicleType.VTOL or speed_m_s <= 0.0:
        return 0.0
    v_min = min(1.1 * profile.min_speed_m_s, speed_m_s)
    t1 = v_min / VTOL_TRANSITION_ACCEL_M_S2
    d = v_min * t1 / 2.0 + VTOL_TRANSITION_S * (v_min + speed_m_s) / 2.0
    return max(t1 + VTOL_TRANSITION_S - d / speed_m_s, 0.0)


@dataclass(frozen=True, slots=True)
class Endurance:
    """A vehicle's battery budget for one sortie to `altitude_m` above home."""

    usable_mah: float  # capacity above the critical level and the reserve (inf: unknown)
    cruise_a: float
    climb_s: float  # on the lift motors (0 for vehicles without)
    land_s: float
    hover_a: float

    @classmethod
    def of(cls, profile: VehicleProfile, altitude_m: float) -> Endurance:
        cap, cruise = profile.battery_capacity_mah, profile.cruise_current_a
        if not (cap > 0.0 and cruise > 0.0 and math.isfinite(cap) and math.isfinite(cruise)):
            return cls(math.inf, 1.0, 0.0, 0.0, 0.0)
        usable = cap * max(1.0 - profile.battery_critical_pct / 100.0 - RESERVE_FRACTION, 0.0)
        alt = max(altitude_m, 0.0)
        climb = land = 0.0
        hover = profile.hover_current_a
        if hover > 0.0 and profile.vehicle_type in (VehicleType.COPTER, VehicleType.VTOL):
            vtol = profile.vehicle_type == VehicleType.VTOL
            up = VTOL_CLIMB_M_S if vtol else (profile.climb_rate_m_s or VTOL_CLIMB_M_S)
            down = VTOL_SINK_M_S if vtol else (profile.sink_rate_m_s or VTOL_SINK_M_S)
            final = min(alt, LAND_FINAL_M)
            climb = alt / up
            land = (alt - final) / down + final / LAND_FINAL_M_S
        return cls(usable, cruise, climb, land, hover)

    @property
    def cruise_budget_s(self) -> float:
        """Seconds at cruise current (share and way home) the battery allows after the
        climb and the landing: inf when the profile has no battery figures."""
        if math.isinf(self.usable_mah):
            return math.inf
        left = self.usable_mah - self.hover_a * (self.climb_s + self.land_s) / 3.6
        return max(left, 0.0) * 3.6 / self.cruise_a

    def ground_budget_s(self, battery_pct: float, profile: VehicleProfile) -> float:
        """`cruise_budget_s` for a sortie from the ground with `battery_pct` (a vehicle
        that flew before and was not given a fresh battery): inf without battery figures."""
        if math.isinf(self.usable_mah):
            return math.inf
        frac = min(max(battery_pct, 0.0), 100.0) / 100.0
        usable = profile.battery_capacity_mah * max(
            frac - profile.battery_critical_pct / 100.0 - RESERVE_FRACTION, 0.0
        )
        left = usable - self.hover_a * (self.climb_s + self.land_s) / 3.6
        return max(left, 0.0) * 3.6 / self.cruise_a

    def airborne_budget_s(self, battery_pct: float, profile: VehicleProfile) -> float:
        """Seconds at cruise left to a vehicle in the air with `battery_pct`, keeping
        its critical level, the reserve and its landing: inf without battery figures."""
        if math.isinf(self.usable_mah):
            return math.inf
        cap = profile.battery_capacity_mah
        frac = min(max(battery_pct, 0.0), 100.0) / 100.0
        left = cap * max(frac - profile.battery_critical_pct / 100.0 - RESERVE_FRACTION, 0.0)
        left -= self.hover_a * self.land_s / 3.6
        return max(left, 0.0) * 3.6 / self.cruise_a

    def left_pct(self, flown_s: float, capacity_mah: float, start_pct: float = 100.0) -> float:
        """Battery left (% of capacity) after the climb and `flown_s` at cruise from
        `start_pct`, by the model: what every node can compute alike for a member (its
        published progress says how long it has flown), where the members' measured
        batteries differ by when each node last heard them. `start_pct` without battery
        figures."""
        if math.isinf(self.usable_mah) or capacity_mah <= 0.0 or not math.isfinite(flown_s):
            return start_pct
        mah = (self.cruise_a * max(flown_s, 0.0) + self.hover_a * self.climb_s) / 3.6
        return min(max(start_pct - 100.0 * mah / capacity_mah, 0.0), 100.0)

    def used_pct(self, cruise_s: float, capacity_mah: float) -> float:
        """Battery used (% of capacity) by a sortie with `cruise_s` at cruise."""
        if math.isinf(self.usable_mah) or capacity_mah <= 0.0:
            return 0.0
        mah = (self.cruise_a * cruise_s + self.hover_a * (self.climb_s + self.land_s)) / 3.6
        return 100.0 * mah / capacity_mah
