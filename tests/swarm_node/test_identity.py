"""Who speaks in a vehicle's name (core/identity.py), with injected time: this vehicle's
conflict and its end, untrusted peers and the source kept for them, holder tokens."""

from __future__ import annotations

from swarm_node.core.identity import (
    CLEAR_AFTER_S,
    MAX_SOURCES,
    HolderAlive,
    IdentityBook,
    IdentityNews,
)
from swarm_proto.intake import FOREIGN, Source

OWN = "aa" * 8
A = Source("a1" * 8, 7)  # vehicle 7's node, its autopilot MAVLink 7
B = Source("b2" * 8, 10)  # another node speaking as 7, on an airframe of MAVLink 10
RADIO = Source(relay=3)


def news(out: list) -> list[IdentityNews]:
    return [o for o in out if isinstance(o, IdentityNews)]


def tick(book: IdentityBook, until: float) -> list:
    """Serve the book's timer up to `until` (as the shell does)."""
    out: list = []
    while (due := book.next_deadline()) is not None and due <= until:
        out += book.on_timer(due)
    return out


# ---------------------------------------------------------------- this vehicle


def test_our_name_from_another_session_is_a_conflict_until_it_is_silent() -> None:
    book = IdentityBook(7, OWN)
    out = book.heard_own(FOREIGN, 1.0)
    assert news(out) == [IdentityNews("id 7 also used by a foreign publisher", frozenset())]
    assert book.heard_own(FOREIGN, 2.0) == []  # said once
    assert tick(book, 2.0 + CLEAR_AFTER_S - 0.1) == []
    assert news(tick(book, 2.0 + CLEAR_AFTER_S + 1.1)) == [IdentityNews("", frozenset())]
    assert book.next_deadline() is None


def test_another_node_with_our_id_is_named_by_its_session_and_airframe() -> None:
    book = IdentityBook(7, OWN, own_sysid=7)
    out = book.heard_own(B, 1.0)
    assert news(out)[0].conflict == f"id 7 also used by session {B.zid[:8]} sysid 10"


def test_our_telemetry_relayed_by_a_radio_gateway_is_no_conflict_unless_another_airframe() -> None:
    book = IdentityBook(7, OWN, own_sysid=7)
    assert book.heard_own(RADIO, 1.0) == []
    assert book.heard_own(RADIO, 1.1, sysid=7) == []
    assert news(book.heard_own(RADIO, 1.2, sysid=10))[0].conflict == (
        "id 7 also used by radio gateway 3, MAVLink 10"
    )


def test_a_holder_token_of_our_id_from_another_session_is_a_conflict_while_it_lasts() -> None:
    book = IdentityBook(7, OWN)
    assert book.holder(7, OWN, True, 0.0) == []  # our own token
    out = book.holder(7, "cc" * 8, True, 1.0)
    assert news(out)[0].conflict == "id 7 also held by session cccccccc"
    assert tick(book, 30.0) == []  # a token lasts as long as its session
    assert news(book.holder(7, "cc" * 8, False, 31.0)) == [IdentityNews("", frozenset())]


# ---------------------------------------------------------------- other vehicles


def test_a_vehicle_heard_from_two_sessions_is_untrusted_and_only_the_first_is_kept() -> None:
    book = IdentityBook(8, OWN)
    assert book.heard(7, A, 0.0) == (True, [])
    keep, out = book.heard(7, B, 0.5)
    assert not keep  # the impostor's status never reaches the node's logic
    assert news(out) == [IdentityNews("", frozenset({7}))]
    assert book.why(7).startswith("heard from session")
    assert book.heard(7, A, 0.7) == (True, [])  # the first source goes on being heard
    assert book.heard(7, B, 0.9)[0] is False
    # B stops: 7 is trusted again once B has been silent CLEAR_AFTER_S
    t = 1.0
    while t < 0.9 + CLEAR_AFTER_S + 2.0:
        book.heard(7, A, t)
        t += 0.2
    assert book.untrusted == frozenset()
    assert book.heard(7, A, t) == (True, [])


def test_a_foreign_publisher_beside_a_session_makes_the_vehicle_untrusted() -> None:
    book = IdentityBook(8, OWN)
    book.heard(7, A, 0.0)
    keep, out = book.heard(7, FOREIGN, 0.1)
    assert not keep and news(out)[0].untrusted == frozenset({7})
    assert "a foreign publisher" in book.why(7)


def test_one_session_with_two_mavlink_system_ids_is_untrusted() -> None:
    book = IdentityBook(8, OWN)
    book.heard(7, A, 0.0)
    copied = Source(A.zid, 10)  # an impostor that copied 7's session id
    keep, out = book.heard(7, copied, 0.1)
    assert news(out)[0].untrusted == frozenset({7})
    assert book.why(7) == "MAVLink system ids 7 and 10"
    assert keep  # same key as the incumbent: nothing tells them apart but the sysid


def test_radio_relays_of_a_vehicle_on_the_lan_are_the_same_vehicle() -> None:
    book = IdentityBook(8, OWN)
    for t in range(20):
        assert book.heard(7, A, t * 0.2) == (True, [])
        assert book.heard(7, RADIO, t * 0.2 + 0.1, sysid=7 if t % 5 == 0 else 0) == (True, [])
    assert book.untrusted == frozenset()


def test_a_vehicle_that_reports_a_conflict_is_untrusted_until_it_stops() -> None:
    book = IdentityBook(8, OWN)
    keep, out = book.heard(7, A, 0.0, reports_conflict=True)
    assert keep and news(out)[0].untrusted == frozenset({7})
    assert book.why(7) == "it reports an identity conflict"
    for t in range(1, 70):
        book.heard(7, A, t * 0.2)
        tick(book, t * 0.2)
    assert book.untrusted == frozenset()


def test_ground_stations_share_an_id_by_design() -> None:
    book = IdentityBook(8, OWN)
    other = Source("dd" * 8)
    assert book.heard(900, Source("cc" * 8), 0.0, ground=True) == (True, [])
    assert book.heard(900, other, 0.1) == (True, [])  # a second `gcs` process
    assert book.untrusted == frozenset()


def test_two_sessions_holding_one_id_make_it_untrusted() -> None:
    book = IdentityBook(8, OWN)
    book.holder(7, A.zid, True, 0.0)
    out = book.holder(7, B.zid, True, 0.1)
    assert news(out)[0].untrusted == frozenset({7})
    out = book.holder(7, B.zid, False, 5.0)
    assert news(out) == [IdentityNews("", frozenset())]


def test_a_token_alone_makes_nobody_alive() -> None:
    book = IdentityBook(8, OWN)
    assert book.holder(55, "ee" * 8, True, 0.0) == []  # a phantom: no telemetry, ever
    assert book.holder(7, A.zid, True, 0.0) == []
    _, out = book.heard(7, A, 0.3)
    assert [o for o in out if isinstance(o, HolderAlive)] == [HolderAlive(7, True)]
    # a foreign token left behind does not keep 7 alive when its node goes
    book.holder(7, "ff" * 8, True, 1.0)
    out = book.holder(7, A.zid, False, 2.0)
    assert [o for o in out if isinstance(o, HolderAlive)] == [HolderAlive(7, False)]


def test_a_node_that_restarts_is_alive_again_once_heard() -> None:
    book = IdentityBook(8, OWN)
    book.holder(7, A.zid, True, 0.0)
    book.heard(7, A, 0.1)
    assert book.holder(7, A.zid, False, 1.0) == [HolderAlive(7, False)]
    again = Source("a3" * 8, 7)  # a new session
    assert book.holder(7, again.zid, True, 2.0) == []
    _, out = book.heard(7, again, 2.1)
    assert HolderAlive(7, True) in out
    assert book.untrusted == frozenset()  # the old session is silent: one source now
    assert tick(book, 20.0) == []


def test_what_is_remembered_per_vehicle_is_bounded() -> None:
    book = IdentityBook(8, OWN)
    book.heard(7, A, 0.0)
    for i in range(1000):
        book.heard(7, Source(f"{i:032x}"), 0.001 * i)
        book.holder(7, f"{i:032x}", True, 0.001 * i)
    track = book.tracks[7]
    assert len(track.sources) <= MAX_SOURCES and len(track.holders) <= MAX_SOURCES
    assert track.incumbent == A.key
