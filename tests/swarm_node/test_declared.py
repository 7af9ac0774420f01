"""The declared book (core/declared.py): the newest stamp wins wherever a
declaration comes from, so nodes that hear the same declarations in any order, or
learn them from each other, converge; a withdrawal stays withdrawn; a vehicle's base
and fleet follow from the commands in stamp order."""

from __future__ import annotations

import random

from hypothesis import given, settings
from hypothesis import strategies as st

from swarm_node.core.declared import DeclaredBook
from swarm_proto import (
    Command,
    CommandArgs,
    CommandKind,
    FleetAssignment,
    Geometry,
    GeoPoint,
    Mission,
    MissionType,
    NoFlyZone,
    Selector,
    SelectorKind,
)
from swarm_proto.messages import DeclaredMission
from tests.conftest import examples

GCS = 900
T = 1.8e9


def zone(zid: int, stamp: float, active: bool = True, r: float = 50.0) -> NoFlyZone:
    return NoFlyZone(zid, Geometry.circle(37.41, -5.99, r), active=active, time_unix_s=stamp)


def set_base(stamp: float, lat: float, target: Selector | None = None) -> Command:
    return Command(
        GCS,
        int(stamp) % 100000,
        CommandKind.SET_BASE,
        target or Selector(),
        CommandArgs(point=GeoPoint(lat, -5.99, 10.0)),
        stamp,
    )


def set_fleet(stamp: float, fleet: int, ids: tuple[int, ...]) -> Command:
    return Command(
        GCS,
        int(stamp) % 100000 + 1,
        CommandKind.SET_FLEET,
        Selector(SelectorKind.IDS, ids),
        CommandArgs(fleet_id=fleet),
        stamp,
    )


def test_the_newest_zone_wins_and_a_withdrawal_stays_withdrawn() -> None:
    book = DeclaredBook()
    assert book.offer_zone(zone(3, T + 10), T) is not None
    withdrawn = zone(3, T + 20, active=False)
    assert book.offer_zone(withdrawn, T) == withdrawn
    # a node that missed the withdrawal offers what it held: older, ignored
    assert book.offer_zone(zone(3, T + 10), T) is None
    assert book.zones[3] == withdrawn and book.stale == 1
    # a repeat of the same declaration changes nothing and is no stale offer
    assert book.offer_zone(withdrawn, T) is None and book.stale == 1


def test_an_unstamped_declaration_takes_the_time_it_was_first_heard() -> None:
    book = DeclaredBook()
    got = book.offer_zone(zone(4, 0.0), T + 5)
    assert got is not None and got.time_unix_s == T + 5
    assert book.offer_zone(zone(4, 0.0), T + 9) is not None  # heard again later: newer
    assert book.zones[4].time_unix_s == T + 9


def test_base_and_fleet_follow_the_commands_in_stamp_order() -> None:
    book = DeclaredBook()
    book.offer_command(set_base(T + 1, 37.1), T)  # to all
    book.offer_command(set_base(T + 2, 37.2, Selector(SelectorKind.IDS, (7,))), T)
    book.offer_command(set_fleet(T + 3, 4, (7, 8)), T)
    book.offer_command(set_base(T + 4, 37.4, Selector(SelectorKind.FLEET, fleet_id=4)), T)
    base7, at7, fleet7, _ = book.resolve(7)
    base1, _, fleet1, _ = book.resolve(1)
    assert base7 is not None and base7.lat_deg == 37.4 and at7 == T + 4 and fleet7 == 4
    assert base1 is not None and base1.lat_deg == 37.1 and fleet1 == 0
    # a newer base to ALL supersedes (and drops) every older base declaration
    book.offer_command(set_base(T + 5, 37.5), T)
    assert [c.time_unix_s for c in book.commands.values() if c.kind == CommandKind.SET_BASE] == [
        T + 5
    ]
    assert book.resolve(7)[0].lat_deg == 37.5  # type: ignore[union-attr]
    # an older one arriving late changes nothing
    assert book.offer_command(set_base(T + 2.5, 36.0, Selector(SelectorKind.IDS, (7,))), T) is None
    # a fleet assignment that leaves 7 out takes it out of fleet 4
    book.offer_assignment(FleetAssignment(4, 0, (8,), GCS, T + 6), T)
    assert book.resolve(7)[2] == 0 and book.resolve(8)[2] == 4


def test_a_mission_withdrawn_never_comes_back_in_force() -> None:
    book = DeclaredBook()
    m = Mission(5, GCS, MissionType.AREA, Geometry.circle(37.41, -5.99, 100.0))
    assert book.accept_mission(m, T) is not None
    assert book.end_mission(5, T + 60) is not None
    assert book.offer_mission(DeclaredMission(m, True, T + 120)) is None
    assert not book.missions[5].in_force


# ---------------------------------------------------------------- convergence

declaration = st.one_of(
    st.builds(
        zone,
        st.integers(1, 4),
        st.integers(1, 30).map(lambda k: T + k),
        st.booleans(),
        st.sampled_from([20.0, 50.0]),
    ),
    st.builds(
        set_base,
        st.integers(1, 30).map(lambda k: T + k),
        st.sampled_from([37.1, 37.2]),
        st.sampled_from([None, Selector(SelectorKind.IDS, (7,))]),
    ),
    st.builds(
        set_fleet,
        st.integers(1, 30).map(lambda k: T + k),
        st.integers(1, 3),
        st.sampled_from([(7,), (7, 8), (8,)]),
    ),
)


def offer(book: DeclaredBook, d: object) -> None:
    if isinstance(d, NoFlyZone):
        book.offer_zone(d, T)
    elif isinstance(d, Command):
        book.offer_command(d, T)


@settings(max_examples=examples(200), deadline=None)
@given(st.lists(declaration, min_size=1, max_size=12), st.randoms(use_true_random=False))
def test_any_order_and_any_split_converge_to_the_same_book(
    decls: list[object], rnd: random.Random
) -> None:
    """One node hears everything in one order; two others each hear a part, in another
    order, then learn from each other: all three hold the same zones and resolve the
    same base and fleet for every vehicle."""
    a = DeclaredBook()
    for d in decls:
        offer(a, d)
    shuffled = list(decls)
    rnd.shuffle(shuffled)
    cut = rnd.randrange(len(shuffled) + 1)
    b, c = DeclaredBook(), DeclaredBook()
    for d in shuffled[:cut]:
        offer(b, d)
    for d in shuffled[cut:]:
        offer(c, d)
    b.merge(c.snapshot(2, T), T)
    c.merge(b.snapshot(3, T), T)
    for book in (b, c):
        assert book.zones == a.zones
        for vid in (1, 7, 8):
            assert book.resolve(vid) == a.resolve(vid)
