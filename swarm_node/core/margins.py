"""How far from its planned path ArduPilot really flies, per vehicle type: the margin
plans keep from no-fly zones, and the zone-safe way home in an emergency.


- **ArduCopter** (and multirotor-like ground vehicles) accepts a waypoint within
  WPNAV_RADIUS (default 200 cm) and rounds each corner on its inside: the recorded
  `copter-corner-cutting` flights (WPNAV_SPEED 10 m/s, WPNAV_ACCEL 2.5 m/s^2,
  WPNAV_JERK 1 m/s^3) passed 1.1-1.2 m from every 90-degree corner and up to 1.65 m off
  a leg's own line just after a corner. Waypoints planned 0.1-0.6 m outside a 35 m zone
  took it into the zone in 3 of 3 runs. Margin: WPNAV_RADIUS + that cross-track.
- **ArduPlane** (and QuadPlane in forward flight) turns at its turn radius and passes
  waypoints that it cannot make within its acceptance radius (`Passed waypoint ... dist
  32m` against 15 m): its plans keep `TURN_RADIUS_MARGIN` times its turn radius from
  zones and every corner is made flyable and checked with the flight predictor
  (`planning/flight.py`); that margin is the mission manager's (`flyable`), not this
  module's. ArduPlane flies a planned turn's waypoints up to `FIXED_WING_CUT_M` on
  their inside (a SITL QuadPlane, NAVL1_PERIOD 14: 24-37 m), so every turn a plan adds
  keeps `FIXED_WING_KEEP_M` from a zone: what ArduPlane cuts, plus the clearance it
  must keep as flown. A turn planned 26.7 m from the zone took the QuadPlane 0.2 m
  into it ("Polygon fence breached").

What each vehicle type must keep from every zone as ArduPilot flies it, measured from
ArduPilot's own positions in `make sitl-check` and `make sitl-fleet`:
`FLOWN_CLEARANCE_M`.
"""

from __future__ import annotations

from swarm_proto import VehicleType

from .profile import VehicleProfile

#: ArduCopter WPNAV_RADIUS default (200 cm): a waypoint counts as reached this far away.
COPTER_WP_RADIUS_M = 2.0
#: The largest cross-track recorded from ArduCopter on its legs (1.39-1.65 m, just after
#: a corner; `copter-corner-cutting`).
COPTER_CROSS_TRACK_M = 1.65
#: ArduRover WP_RADIUS default (2 m); rovers and boats pivot or turn near the point.
GROUND_WP_RADIUS_M = 2.0
#: The clearance from every zone each kind of vehicle keeps as ArduPilot flies it.
FIXED_WING_FLOWN_CLEARANCE_M = 10.0
MULTIROTOR_FLOWN_CLEARANCE_M = 2.0
#: How far inside a planned turn's waypoints ArduPlane flies (SITL QuadPlane: 24-37 m).
FIXED_WING_CUT_M = 37.0
#: The least clearance from a zone of a fixed-wing's planned turns (lanes keep more:
#: their turn radius): less only where a point it must pass is nearer the zone.
FIXED_WING_KEEP_M = FIXED_WING_CUT_M + FIXED_WING_FLOWN_CLEARANCE_M
#: A fixed-wing's lanes end this much further from a zone than its turn radius, so that
#: the turn at a lane's end keeps FIXED_WING_KEEP_M (planning/fleet_plan.py).
FIXED_WING_LANE_EXTRA_M = 20.0


def track_margin_m(profile: VehicleProfile) -> float:
    """The clearance a hover-capable or ground vehicle's plan keeps from zones so that
    what ArduPilot flies around its corners stays out: 3.65 m for a copter. 0 for a
    fixed-wing (its turn margin is planned apart, see `mission_manager.flyable`)."""
    if profile.is_fixed_wing:
        return 0.0
    if profile.vehicle_type == VehicleType.COPTER:
        return COPTER_WP_RADIUS_M + COPTER_CROSS_TRACK_M
    return GROUND_WP_RADIUS_M + COPTER_CROSS_TRACK_M  # not measured: as a copter's
