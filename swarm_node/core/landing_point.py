"""Where each vehicle's autopilot returns on its own (ArduPilot's RTL goes to the nearest
rally point: a failsafe, an operator's RTL sent straight to it, a node that died): the
vehicle's own landing point, never another's. One rally point at the base sent every
RTL there (a copter whose node was killed landed on another copter's pad).

    landing_point(vehicle_id, home, base) -> (lat, lon)

- A vehicle based near the swarm's base (its home within `PAD_AREA_M` of it) returns
  to its own pad: its home, where it took off.
- One from elsewhere gets a landing point the fleet assigns near the base: slot
  `vehicle_id` of a sunflower (Vogel) spiral around the base, `SLOT_M` apart, the same
  on every node without a message (ids are unique, so are the slots).

Pure: no I/O, no clock.
"""

from __future__ import annotations

import math

from swarm_proto import GeoPoint
from swarm_proto.geodesy import distance_m, offset

PAD_AREA_M = 1000.0  # a home this close to the base is the vehicle's pad at the base
SLOT_M = 25.0  # neighbouring assigned landing points are about this far apart
_GOLDEN_ANGLE = math.pi * (3.0 - math.sqrt(5.0))


def assigned_slot(vehicle_id: int, base: GeoPoint) -> tuple[float, float]:
    """Landing point `vehicle_id` of the spiral around the base (lat, lon)."""
    k = max(1, vehicle_id)
    r = SLOT_M * math.sqrt(k)
    a = k * _GOLDEN_ANGLE
    return offset(base.lat_deg, base.lon_deg, r * math.cos(a), r * math.sin(a))


def landing_point(vehicle_id: int, home: GeoPoint, base: GeoPoint) -> tuple[float, float]:
    """Where this vehicle lands on its own: its pad, or its slot at the base."""
    if distance_m(home.lat_deg, home.lon_deg, base.lat_deg, base.lon_deg) <= PAD_AREA_M:
        return home.lat_deg, home.lon_deg
    return assigned_slot(vehicle_id, base)
