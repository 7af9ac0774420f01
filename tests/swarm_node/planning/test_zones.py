"""No-fly zone manager: conflicts with floor/ceiling, vertical and lateral avoidance."""

from __future__ import annotations

import itertools
import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from shapely.geometry import Point, Polygon

from swarm_node.core.planning import (
    LocalFrame,
    NoSafeRouteError,
    Obstacles,
    Zone,
    ZoneSet,
    visibility_path,
)
from swarm_proto import Geometry, NoFlyZone
from tests.conftest import examples

BOX = Polygon([(400, -100), (600, -100), (600, 100), (400, 100)])


def test_conflicts_respect_floor_and_ceiling() -> None:
    zs = ZoneSet((Zone(7, BOX, floor_rel_m=50.0, ceiling_rel_m=150.0),))
    assert zs.conflicts([(0, 0, 100), (1000, 0, 100)])[0].zone_id == 7
    assert zs.conflicts([(0, 0, 200), (1000, 0, 200)]) == []  # above the ceiling
    assert zs.conflicts([(0, 0, 30), (1000, 0, 30)]) == []  # below the floor
    assert zs.conflicts([(500, 0, 100)])[0].leg_end is None  # a waypoint inside


def test_vertical_avoidance_when_the_ceiling_can_be_cleared() -> None:
    zs = ZoneSet((Zone(1, BOX, ceiling_rel_m=80.0),), margin_m=20.0, vertical_margin_m=20.0)
    out = zs.avoid([(0, 0, 60), (1000, 0, 60)], max_alt_rel_m=120.0)
    assert zs.conflicts(out) == []
    assert max(p[2] for p in out) == pytest.approx(100.0)
    assert all(abs(p[1]) < 1e-9 for p in out)  # no lateral detour
    assert out[0] == (0, 0, 60) and out[-1] == (1000, 0, 60)


def test_lateral_reroute_when_the_ceiling_is_too_high() -> None:
    zs = ZoneSet((Zone(1, BOX, ceiling_rel_m=500.0),), margin_m=20.0)
    out = zs.avoid([(0, 0, 60), (1000, 0, 60)], max_alt_rel_m=120.0)
    assert zs.conflicts(out) == []
    assert all(p[2] == 60 for p in out)
    assert max(abs(p[1]) for p in out) >= 120.0 - 1e-6  # around the inflated box
    length = sum(math.dist(a[:2], b[:2]) for a, b in itertools.pairwise(out))
    assert length < 1000 + 2 * 130  # the shortest way round, not a wide detour


def test_enclosed_end_point_signals_replan() -> None:
    ring = Polygon(
        [(-500, -500), (500, -500), (500, 500), (-500, 500)],
        [[(-400, -400), (400, -400), (400, 400), (-400, 400)]],
    )
    zs = ZoneSet((Zone(1, ring),))
    with pytest.raises(NoSafeRouteError):
        zs.avoid([(0, 0, 50), (1000, 1000, 50)], max_alt_rel_m=100.0)
    with pytest.raises(NoSafeRouteError):
        ZoneSet((Zone(1, BOX),)).avoid([(500, 0, 50), (1000, 0, 50)], max_alt_rel_m=100.0)


def test_zones_from_messages_use_validity_and_msl() -> None:
    frame = LocalFrame(40.0, -3.0)
    z = NoFlyZone(
        3,
        Geometry.circle(40.0, -3.0, 100.0),
        floor_alt_msl_m=600.0,
        ceiling_alt_msl_m=700.0,
        valid_from_unix_s=100.0,
        valid_until_unix_s=200.0,
    )
    assert ZoneSet.from_messages([z], frame, now_unix_s=50.0).zones == ()
    assert ZoneSet.from_messages([z], frame, now_unix_s=250.0).zones == ()
    zs = ZoneSet.from_messages([z], frame, now_unix_s=150.0, home_alt_msl_m=550.0)
    (zone,) = zs.zones
    assert (zone.floor_rel_m, zone.ceiling_rel_m) == (50.0, 150.0)
    # circles become polygons that contain the true circle
    assert zone.polygon.contains(Point(0, 0).buffer(99.9, quad_segs=64))


@settings(max_examples=examples(40))
@given(
    st.lists(
        st.tuples(st.floats(-800, 800), st.floats(-800, 800), st.floats(20, 150)),
        min_size=1,
        max_size=4,
    ),
    st.tuples(st.floats(-1000, 1000), st.floats(-1000, 1000)),
    st.tuples(st.floats(-1000, 1000), st.floats(-1000, 1000)),
)
def test_reroutes_never_enter_a_zone(
    circles: list[tuple[float, float, float]], a: tuple[float, float], b: tuple[float, float]
) -> None:
    zs = ZoneSet(
        tuple(Zone(i, Point(x, y).buffer(r)) for i, (x, y, r) in enumerate(circles)), margin_m=10.0
    )
    try:
        out = zs.avoid([(*a, 50.0), (*b, 50.0)], max_alt_rel_m=100.0)
    except NoSafeRouteError:
        # only when an end point is in (or touching) the inflated zones, or walled in
        near = zs.keep_out(None).buffer(1.0)
        walled = any(len(p.interiors) for p in getattr(near, "geoms", [near]))
        assert near.contains(Point(a)) or near.contains(Point(b)) or walled
        return
    assert zs.conflicts(out) == []
    assert out[0][:2] == a and out[-1][:2] == b


def test_visibility_path_is_shortest_around_a_square() -> None:
    sq = Polygon([(-1, -1), (1, -1), (1, 1), (-1, 1)])
    path = visibility_path((-3, 0), (3, 0), sq)
    length = sum(math.dist(p, q) for p, q in itertools.pairwise(path))
    # around the square grown by the 0.5 m node clearance: (-3,0) (-1.5,1.5) (1.5,1.5) (3,0)
    assert length == pytest.approx(2 * math.hypot(1.5, 1.5) + 3, abs=1e-6)
    obs = Obstacles(sq)
    assert obs.path((-3, 5), (3, 5)) == [(-3, 5), (3, 5)]


def test_obstacles_are_equal_by_value_so_memoized_transitions_are_found_again() -> None:
    """The area planner builds its obstacles again in each of its rounds (and a worker in
    each job): equal by value, the transitions memoized for one are found for the next
    (by identity, a 11-member survey planned 4,000 transitions, most two or three
    times; now 1,800)."""
    from swarm_node.core.planning.coverage import Pose, _cached_transition, _transition
    from swarm_node.core.planning.turns import DubinsTurns

    zone = Point(0.0, 0.0).buffer(40.0)
    a, b = Obstacles(zone, zone), Obstacles(Point(0.0, 0.0).buffer(40.0), zone)
    assert a == b and hash(a) == hash(b) and a is not b
    assert a != Obstacles(Point(0.0, 1.0).buffer(40.0), zone) and a != Obstacles(zone)
    turns = DubinsTurns(30.0)
    start, end = Pose(-100.0, -60.0, 0.0), Pose(-100.0, 60.0, math.pi)
    _cached_transition.cache_clear()
    first = _transition(start, end, turns, a)
    again = _transition(start, end, turns, b)
    info = _cached_transition.cache_info()
    assert again == first and info.hits == 1 and info.misses == 1
