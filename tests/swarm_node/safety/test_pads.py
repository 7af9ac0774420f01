"""Take-off and landing deconfliction at neighbouring pads (safety/pads.py)."""

from __future__ import annotations

import itertools

from hypothesis import given
from hypothesis import strategies as st

from swarm_node.core.safety.pads import PadConfig, hold_layer, holds_apart_m, may_move
from swarm_proto import GeoPoint, MissionState, VehicleStatus, geodesy

LAT, LON = 37.41, -5.99
T = 1.8e9


def pad(east_m: float, north_m: float = 0.0) -> GeoPoint:
    lat, lon = geodesy.offset(LAT, LON, north_m, east_m)
    return GeoPoint(lat, lon, 10.0)


def status(
    vid: int,
    east_m: float,
    alt_rel_m: float = 0.0,
    armed: bool = False,
    state: MissionState = MissionState.IDLE,
) -> VehicleStatus:
    p = pad(east_m)
    return VehicleStatus(
        vehicle_id=vid,
        time_unix_s=T,
        lat_deg=p.lat_deg,
        lon_deg=p.lon_deg,
        alt_msl_m=10.0 + alt_rel_m,
        alt_rel_m=alt_rel_m,
        armed=armed,
        mission_state=state,
    )


def ids(blockers: list) -> list[int]:
    return [b.vehicle_id for b in blockers]


def test_a_simultaneous_take_off_goes_in_id_order() -> None:
    """Three vehicles 8 m apart, all about to take off: only the lowest id goes."""
    peers = {v: status(v, 8.0 * (v - 1), state=MissionState.PREMISSION) for v in (1, 2, 3)}
    pads = {v: pad(8.0 * (v - 1)) for v in peers}

    def blockers(v: int) -> list[int]:
        return ids(may_move(v, pads[v], [(s, pads[u]) for u, s in peers.items()], taking_off=True))

    assert blockers(1) == []
    assert blockers(2) == [1]
    assert sorted(blockers(3)) == [1, 2]


def test_the_next_goes_once_the_one_before_is_high_or_gone() -> None:
    mine = pad(8.0)
    climbing = status(1, 0.0, alt_rel_m=12.0, armed=True, state=MissionState.PREMISSION)
    assert ids(may_move(2, mine, [(climbing, pad(0.0))], taking_off=True)) == [1]
    high = status(1, 0.0, alt_rel_m=31.0, armed=True, state=MissionState.PREMISSION)
    assert may_move(2, mine, [(high, pad(0.0))], taking_off=True) == []
    gone = status(1, 60.0, alt_rel_m=12.0, armed=True, state=MissionState.MISSION)
    assert may_move(2, mine, [(gone, pad(0.0))], taking_off=True) == []


def test_who_does_not_block_a_take_off() -> None:
    mine = pad(8.0)
    # a higher id about to take off waits for us; a lower id that is not going (IDLE)
    # or stands on a pad far away does not hold us; a silent peer is not in the list
    higher = status(3, 16.0, state=MissionState.PREMISSION)
    idle = status(1, 0.0, state=MissionState.IDLE)
    far = status(1, 60.0, state=MissionState.PREMISSION)
    for peer, p in ((higher, pad(16.0)), (idle, pad(0.0)), (far, pad(60.0))):
        assert may_move(2, mine, [(peer, p)], taking_off=True) == [], peer


def test_landing_waits_for_a_low_neighbour_and_for_the_layers_below() -> None:
    mine = pad(8.0)

    def blockers(peer: VehicleStatus, at: GeoPoint, own_rel: float) -> list[int]:
        return ids(may_move(2, mine, [(peer, at)], taking_off=False, own_alt_msl_m=10.0 + own_rel))

    taking_off = status(3, 16.0, alt_rel_m=5.0, armed=True)  # higher id, but low
    assert blockers(taking_off, pad(16.0), 60.0) == [3]
    holding = status(1, 0.0, alt_rel_m=60.0, armed=True)  # a neighbour holding at 60 m
    assert blockers(holding, pad(0.0), 90.0) == [1]  # we would descend through it
    assert blockers(holding, pad(0.0), 30.0) == []  # it is above us
    level_lower = status(1, 0.0, alt_rel_m=62.0, armed=True)
    level_higher = status(3, 16.0, alt_rel_m=62.0, armed=True)
    assert blockers(level_lower, pad(0.0), 60.0) == [1]  # level: the lower id first
    assert blockers(level_higher, pad(16.0), 60.0) == []
    # a take-off is not held by a neighbour 60 m up
    assert may_move(2, mine, [(holding, pad(0.0))], taking_off=True) == []
    landed = status(1, 0.0, alt_rel_m=0.2, armed=False)
    assert blockers(landed, pad(0.0), 60.0) == []


def flying(
    vid: int, east_m: float, north_m: float, alt_rel_m: float, speed_m_s: float
) -> VehicleStatus:
    """An airborne peer at (east, north) of the origin, flying south at `speed_m_s`."""
    p = pad(east_m, north_m)
    return VehicleStatus(
        vehicle_id=vid,
        time_unix_s=T,
        lat_deg=p.lat_deg,
        lon_deg=p.lon_deg,
        alt_msl_m=10.0 + alt_rel_m,
        alt_rel_m=alt_rel_m,
        vel_north_m_s=-speed_m_s,
        armed=True,
        mission_state=MissionState.MISSION,
    )


def test_a_circling_vtol_waits_for_a_neighbour_on_its_slow_approach_to_a_pad_60_m_away() -> None:
    """The demo's near-collision (4.78 m, vehicles 4 and 6, story time 708 s), its
    numbers from the run's flight.csv: 6 (pad at 150 m east) held at 180 m; 4 (pad at
    90 m east, 60 m from 6's) was on its landing approach, hovering down at 5 m/s from
    35 m, 130 m from 6's pad. 6 was let down (4 was slow and more than 40 m from its
    pad) and circled down its hold (out to 179 m from its pad) through 4's approach
    path: 4.78 m apart at 52 and 47.7 m. Its own circle counts, and a neighbour near its
    pad counts at its pad too (it is on its way down there): 6 waits."""
    mine, theirs = pad(150.0), pad(90.0)
    approaching = flying(4, 117.0, 126.0, alt_rel_m=35.0, speed_m_s=5.0)
    # 6 circles at 180 m: 4, below it and landing on a pad inside 6's circle, holds it
    blocked = may_move(
        6, mine, [(approaching, theirs)], taking_off=False, own_alt_msl_m=190.0, own_circles=True
    )
    assert ids(blocked) == [4] and "its own pad" in blocked[0].why
    # after a climb for 4, at 62 m, 4 74 m from the pad (at 47.7 m): still held
    closer = flying(4, 83.0, 31.0, alt_rel_m=47.7, speed_m_s=5.0)
    assert ids(
        may_move(
            6, mine, [(closer, theirs)], taking_off=False, own_alt_msl_m=72.0, own_circles=True
        )
    ) == [4]
    # 4 down on its pad: 6 goes
    down = status(4, 90.0, alt_rel_m=0.0, armed=False)
    assert (
        may_move(6, mine, [(down, theirs)], taking_off=False, own_alt_msl_m=190.0, own_circles=True)
        == []
    )
    # a multirotor hovers straight down over its pad: its 40 m band is unchanged
    assert may_move(6, mine, [(closer, theirs)], taking_off=False, own_alt_msl_m=72.0) == []


def test_a_neighbour_far_from_its_pad_does_not_hold_a_landing() -> None:
    """Below us and its pad next to ours, but out on its mission 500 m away: it is not
    landing, we go (a lander does not wait for the whole fleet to come home)."""
    mine, theirs = pad(150.0), pad(120.0)
    away = flying(5, 120.0, 500.0, alt_rel_m=90.0, speed_m_s=26.0)
    assert (
        may_move(6, mine, [(away, theirs)], taking_off=False, own_alt_msl_m=190.0, own_circles=True)
        == []
    )
    # nearer its pad than `approach_m`, it is on its way down there: it holds us
    back = flying(5, 120.0, 150.0, alt_rel_m=90.0, speed_m_s=26.0)
    assert ids(
        may_move(6, mine, [(back, theirs)], taking_off=False, own_alt_msl_m=190.0, own_circles=True)
    ) == [5]
    # a take-off is not held by it (the rule is the landing's)
    assert may_move(6, mine, [(back, theirs)], taking_off=True, own_circles=True) == []


@given(st.lists(st.tuples(st.floats(-60, 60), st.floats(0, 120)), min_size=2, max_size=7))
def test_landings_never_deadlock(spots: list[tuple[float, float]]) -> None:
    """Any number of vehicles waiting over neighbouring pads at any heights: unless one
    is low (taking off or landing: moving), one of them may land."""
    peers = {
        v + 1: status(v + 1, e, alt_rel_m=max(2.0, h), armed=True) for v, (e, h) in enumerate(spots)
    }
    pads = {v: pad(spots[v - 1][0]) for v in peers}
    free = [
        v
        for v, me in peers.items()
        if not may_move(
            v,
            pads[v],
            [(s, pads[u]) for u, s in peers.items()],
            taking_off=False,
            own_alt_msl_m=me.alt_msl_m,
        )
    ]
    if all(s.alt_rel_m >= PadConfig().stagger_m for s in peers.values()):
        assert free


@given(
    st.lists(
        st.tuples(
            st.floats(-60, 60),
            st.floats(-250, 250),
            st.floats(0, 180),
            st.floats(0, 30),
            st.booleans(),
        ),
        min_size=2,
        max_size=7,
    )
)
def test_landings_never_deadlock_with_circles_and_approaches(
    spots: list[tuple[float, float, float, float, bool]],
) -> None:
    """As above, with vehicles off their pads (on their way in), at any speed, circling
    or hovering: the own circle and a neighbour counted at its pad only widen the reach,
    the waits still follow altitude then id, so unless one is low one of them may land."""
    peers = {
        v + 1: flying(v + 1, e, n, alt_rel_m=max(2.0, h), speed_m_s=speed)
        for v, (e, n, h, speed, _c) in enumerate(spots)
    }
    pads = {v: pad(spots[v - 1][0]) for v in peers}
    circles = {v: spots[v - 1][4] for v in peers}
    free = [
        v
        for v, me in peers.items()
        if not may_move(
            v,
            pads[v],
            [(s, pads[u]) for u, s in peers.items()],
            taking_off=False,
            own_alt_msl_m=me.alt_msl_m,
            own_circles=circles[v],
        )
    ]
    if all(s.alt_rel_m >= PadConfig().stagger_m for s in peers.values()):
        assert free


@given(st.lists(st.tuples(st.floats(-400, 400), st.floats(-400, 400)), min_size=1, max_size=8))
def test_holding_layers_never_repeat_among_pads_whose_circles_may_overlap(
    spots: list[tuple[float, float]],
) -> None:
    pads = {v + 1: pad(e, n) for v, (e, n) in enumerate(spots)}
    cfg = PadConfig()
    layer = {
        v: hold_layer(v, p, {u: q for u, q in pads.items() if u != v}) for v, p in pads.items()
    }
    for a, b in itertools.combinations(pads, 2):
        pa, pb = pads[a], pads[b]
        if geodesy.distance_m(pa.lat_deg, pa.lon_deg, pb.lat_deg, pb.lon_deg) < cfg.hold_near_m:
            assert layer[a] != layer[b]
    assert min(layer.values()) == cfg.hold_alt_rel_m


def test_multirotors_hover_over_pads_40_m_apart_at_one_layer() -> None:
    """Two quadcopters on pads 40 m apart hover still over them: more than the avoider's
    30 m release distance apart, they hold (and land) at the lowest layer, 30 m, not
    30 and 60 m (the second one's climb to 60 m and its 42 s descent cost it its
    reserve in two sorties on one battery); 20 m apart they still take two layers, and
    next to a fixed-wing's circle (150 m) they do too."""
    quads = {7: pad(0), 8: pad(40)}
    hover = {7, 8}
    assert [hold_layer(v, p, quads, hovering=hover) for v, p in quads.items()] == [30.0, 30.0]
    assert hold_layer(8, pad(40), {7: pad(0)}) == 60.0  # types not known: circles
    close = {7: pad(0), 8: pad(20)}
    assert [hold_layer(v, p, close, hovering=hover) for v, p in close.items()] == [30.0, 60.0]
    mixed = {7: pad(0), 8: pad(40), 2: pad(80)}
    layers = {v: hold_layer(v, p, mixed, fixed_wing={2}, hovering=hover) for v, p in mixed.items()}
    assert layers == {7: 30.0, 8: 60.0, 2: 90.0}
    assert holds_apart_m(True, True) == 30.0 and holds_apart_m(False, False) == 150.0
    assert holds_apart_m(True, False) == holds_apart_m(False, True) == 90.0


@given(
    st.lists(
        st.tuples(st.floats(-200, 200), st.floats(-200, 200), st.booleans()), min_size=1, max_size=8
    )
)
def test_holding_layers_never_repeat_among_holds_that_could_conflict(
    spots: list[tuple[float, float, bool]],
) -> None:
    """With hoverers and circlers mixed: two vehicles whose pads are closer than their
    holds need (30 m both hovering, 150 m both circling, 90 m one of each) never share a
    layer, and every vehicle computes the same layers from the same pads and types."""
    pads = {v + 1: pad(e, n) for v, (e, n, _h) in enumerate(spots)}
    hover = {v + 1 for v, (_e, _n, h) in enumerate(spots) if h}
    wing = set(pads) - hover
    layer = {
        v: hold_layer(
            v, p, {u: q for u, q in pads.items() if u != v}, fixed_wing=wing, hovering=hover
        )
        for v, p in pads.items()
    }
    for a, b in itertools.combinations(pads, 2):
        pa, pb = pads[a], pads[b]
        d = geodesy.distance_m(pa.lat_deg, pa.lon_deg, pb.lat_deg, pb.lon_deg)
        if d < holds_apart_m(a in hover, b in hover):
            assert layer[a] != layer[b]
    assert min(layer.values()) == PadConfig().hold_alt_rel_m
