"""The zone book (safety/zones.py): one store and one geometry for monitoring, the
fence keeper, the planners and avoidance."""

from __future__ import annotations

import math

import msgspec
import pytest
from hypothesis import given
from hypothesis import strategies as st
from shapely.geometry import Point

from swarm_node.core.node import NodeCore, Received
from swarm_node.core.planning import LocalFrame, ZoneSet
from swarm_node.core.profile import VehicleProfile
from swarm_node.core.safety.zones import ZoneBook, distance_outside_m, inside
from swarm_proto import Geometry, NoFlyZone, VehicleType, geodesy

LAT, LON = 37.41, -5.99


def square(half_m: float, n_m: float = 0.0, e_m: float = 0.0) -> Geometry:
    corners = [(-1, -1), (-1, 1), (1, 1), (1, -1)]
    return Geometry.polygon(
        [geodesy.offset(LAT, LON, n_m + a * half_m, e_m + b * half_m) for a, b in corners]
    )


def test_breach_checks_floor_ceiling_and_operating_areas() -> None:
    book = ZoneBook()
    book[1] = NoFlyZone(1, square(100.0), floor_alt_msl_m=50.0, ceiling_alt_msl_m=150.0)
    book[2] = NoFlyZone(2, square(1000.0), operating_area=True)
    assert book.breach(LAT, LON, 100.0, 0.0) == "in no-fly zone 1"
    assert book.breach(LAT, LON, 160.0, 0.0) is None  # over it
    assert book.breach(LAT, LON, 40.0, 0.0) is None  # under it
    far = geodesy.offset(LAT, LON, 1200.0, 0.0)
    assert book.breach(*far, 100.0, 0.0) == "left operating area 2"
    assert [z.zone_id for z in book.no_fly(0.0)] == [1]
    assert [z.zone_id for z in book.operating_areas(0.0)] == [2]


def test_zones_out_of_force_are_left_out_and_changes_are_counted() -> None:
    book = ZoneBook()
    book[1] = NoFlyZone(1, square(100.0), valid_from_unix_s=100.0, valid_until_unix_s=200.0)
    assert book.version == 1
    assert book.no_fly(50.0) == [] and book.breach(LAT, LON, 0.0, 50.0) is None
    assert len(book.no_fly(150.0)) == 1
    assert book.no_fly(250.0) == []
    del book[1]
    assert book.version == 2 and len(book) == 0


def test_ceiling_is_the_lowest_floor_above_within_the_radius() -> None:
    book = ZoneBook()
    book[1] = NoFlyZone(1, square(50.0), floor_alt_msl_m=200.0)
    book[2] = NoFlyZone(2, square(50.0, n_m=300.0), floor_alt_msl_m=150.0)
    book[3] = NoFlyZone(3, square(50.0), floor_alt_msl_m=-10.0, ceiling_alt_msl_m=60.0)  # below
    assert book.ceiling_msl(LAT, LON, 100.0, 0.0) == 200.0
    # zone 2 is 250 m away from its edge: counted within a 300 m radius
    assert book.ceiling_msl(LAT, LON, 100.0, 0.0, radius_m=300.0) == 150.0
    assert book.ceiling_msl(LAT, LON, 250.0, 0.0) is None


@given(st.floats(-400, 400), st.floats(-400, 400))
def test_containment_agrees_with_the_planners_zone_polygons(n: float, e: float) -> None:
    """A point the zone book puts inside a zone is inside the planners' shape of it
    (the same ENU geometry; the planners' circle is circumscribed)."""
    zone_sq = NoFlyZone(1, square(150.0, 20.0, -30.0))
    zone_c = NoFlyZone(2, Geometry.circle(LAT, LON, 170.0))
    frame = LocalFrame(LAT, LON)
    planned = ZoneSet.from_messages([zone_sq, zone_c], frame, now_unix_s=0.0)
    la, lo = geodesy.offset(LAT, LON, n, e)
    p = Point(frame.to_local(la, lo))
    for z, pz in zip((zone_sq, zone_c), planned.zones, strict=True):
        d = pz.polygon.distance(p)
        if inside(z.geometry, la, lo):
            assert d < 1e-6
        elif z.geometry.kind.name == "POLYGON":
            # outside for the book: outside the planners' polygon, by the same distance
            assert d == pytest.approx(distance_outside_m(z.geometry, la, lo), abs=0.05)


def test_circle_distance_is_ground_distance_to_the_centre_less_the_radius() -> None:
    la, lo = geodesy.offset(LAT, LON, 300.0, 400.0)
    assert distance_outside_m(Geometry.circle(LAT, LON, 100.0), la, lo) == pytest.approx(
        400.0, abs=1e-5
    )
    assert distance_outside_m(Geometry.point(LAT, LON), la, lo) == math.inf


def test_the_node_monitoring_fences_and_planners_share_one_book(fleet_profiles: dict) -> None:
    profile: VehicleProfile = next(
        p for p in fleet_profiles.values() if p.vehicle_type == VehicleType.COPTER
    )
    node = NodeCore(profile)
    zone = NoFlyZone(4, square(80.0))
    node.handle(Received(zone), 1.0)
    assert isinstance(node.monitor.zones, ZoneBook)
    held = msgspec.structs.replace(zone, time_unix_s=1.0)  # unstamped: stamped on receipt
    assert node.zones.no_fly(1.0) == [held] == node.monitor.zones.no_fly(1.0)
    assert node.monitor.zones.breach(LAT, LON, 10.0, 1.0) == "in no-fly zone 4"
