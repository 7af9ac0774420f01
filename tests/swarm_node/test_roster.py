"""The fleet roster (core/swarm/roster.py): the members of a mission agreed by every node
from the answers they hear, whatever their order; the members hash; MemberLost."""

from __future__ import annotations

from hypothesis import given
from hypothesis import strategies as st

from swarm_node.core.membership import Peer
from swarm_node.core.swarm.roster import MemberLost, Roster, RosterMismatch, members_hash
from swarm_proto import (
    Ack,
    AckReason,
    AckRef,
    FsmState,
    Selector,
    VehicleInfo,
    VehicleType,
)
from swarm_proto import VehicleInfo as Info

MID = 77


def info(
    vid: int,
    *,
    mid: int = MID,
    state: FsmState = FsmState.PLAN,
    fleet: int = 0,
    members_hash: int = 0,
) -> VehicleInfo:
    return Info(
        vid,
        VehicleType.COPTER,
        "q",
        f"U{vid}",
        fleet_id=fleet,
        mission_id=mid,
        fsm_state=state,
        members_hash=members_hash,
    )


def peers_of(ids: list[int], infos: dict[int, VehicleInfo] | None = None) -> dict[int, Peer]:
    infos = infos or {}
    return {i: Peer(i, present=True, info=infos.get(i)) for i in ids}


def ack(vid: int, ok: bool, mid: int = MID) -> Ack:
    return Ack(vid, 900, AckRef.MISSION, mid, ok, AckReason.OK if ok else AckReason.NOT_READY)


def test_the_roster_is_who_accepted_and_waits_for_every_answer() -> None:
    r = Roster(1)
    r.open(MID, Selector())
    peers = peers_of([2, 3, 4], {i: info(i) for i in (2, 3)})
    r.on_ack(ack(2, True))
    assert r.pending(peers) == (3, 4) and not r.ready(peers)
    r.on_ack(ack(4, False))
    r.on_info(info(3))  # 3's ack was lost; its VehicleInfo shows it in PLAN for the mission
    assert r.pending(peers) == () and r.ready(peers)
    assert r.freeze(peers) == (1, 2, 3)
    assert r.members_hash == members_hash(MID, (3, 2, 1)) != 0
    assert r.members_hash != members_hash(MID + 1, (1, 2, 3))


def test_an_ids_mission_waits_only_for_the_named_vehicles() -> None:
    r = Roster(1)
    r.open(MID, Selector.ids(1, 2))
    peers = peers_of([2, 3], {2: info(2)})
    assert r.pending(peers) == (2,)
    r.on_ack(ack(2, True))
    assert r.ready(peers) and r.freeze(peers) == (1, 2)


def test_answers_heard_before_the_mission_count() -> None:
    r = Roster(1)
    r.on_ack(ack(2, True))  # a fast peer answered before our own copy arrived
    r.open(MID, Selector())
    peers = peers_of([2], {2: info(2)})
    assert r.ready(peers) and r.freeze(peers) == (1, 2)


def frozen_with_2_and_3() -> Roster:
    """Vehicle 1's roster for MID, frozen with peers 2 and 3 (both accepted)."""
    r = Roster(1)
    r.open(MID, Selector())
    r.on_ack(ack(2, True))
    r.on_ack(ack(3, True))
    r.freeze(peers_of([2, 3], {2: info(2), 3: info(3)}))
    return r


def test_a_member_lost_is_an_event_once() -> None:
    r = frozen_with_2_and_3()
    assert r.on_peer_left(2, "stale") == [MemberLost(MID, 2, "stale")]
    assert r.on_peer_left(2, "liveliness") == []
    assert r.on_info(info(3, state=FsmState.EMERGENCY)) == [MemberLost(MID, 3, "emergency")]
    assert r.flying == (1,)
    assert r.on_peer_left(9, "stale") == []  # not a member


def test_a_member_that_accepted_and_is_lost_in_plan_is_an_event() -> None:
    r = Roster(1)
    r.open(MID, Selector())
    r.on_ack(ack(2, True))
    assert r.on_peer_left(2, "liveliness") == [MemberLost(MID, 2, "liveliness")]


def test_a_different_members_hash_is_reported() -> None:
    r = Roster(1)
    r.open(MID, Selector())
    peers = peers_of([2], {2: info(2)})
    r.on_ack(ack(2, True))
    r.freeze(peers)
    assert r.on_info(info(2, state=FsmState.GO_MISSION, members_hash=r.members_hash)) == []
    ev = r.on_info(info(2, state=FsmState.GO_MISSION, members_hash=r.members_hash ^ 1))
    assert ev == [RosterMismatch(MID, 2, r.members_hash ^ 1, r.members_hash)]


def test_a_member_lost_by_silence_back_with_another_roster_is_reported_once() -> None:
    """The two sides of a partition replanned apart: heard again, a mismatch (the same
    roster back: `back`, a member again)."""
    r = frozen_with_2_and_3()
    r.on_peer_left(2, "stale")
    theirs = members_hash(MID, [2], 1)
    ev = r.on_info(info(2, state=FsmState.GO_MISSION, members_hash=theirs))
    assert ev == [RosterMismatch(MID, 2, theirs, r.members_hash)]
    assert r.on_info(info(2, state=FsmState.GO_MISSION, members_hash=theirs)) == []
    assert r.on_info(info(2, state=FsmState.GO_MISSION, members_hash=r.members_hash)) == []
    r.back(2)
    assert 2 in r.flying and not r.lost


@st.composite
def fleets(draw: st.DrawFn) -> tuple[list[int], dict[int, bool], list[list[int]]]:
    ids = draw(st.lists(st.integers(1, 40), min_size=2, max_size=8, unique=True))
    accepts = {i: draw(st.booleans()) for i in ids}
    accepts[ids[0]] = True
    # each node hears the others' answers in its own order (ack or, for acceptances,
    # VehicleInfo: both say the same)
    orders = [draw(st.permutations([j for j in ids if j != i])) for i in ids]
    return ids, accepts, orders


@given(fleets(), st.randoms(use_true_random=False))
def test_every_node_computes_the_same_roster_whatever_the_order(data, rnd) -> None:  # type: ignore[no-untyped-def]
    ids, accepts, orders = data
    hashes = set()
    rosters = []
    for i, order in zip(ids, orders, strict=True):
        if not accepts[i]:
            continue  # a vehicle that refused has no roster
        r = Roster(i)
        if rnd.random() < 0.5:
            r.open(MID, Selector())
        for j in order:
            if accepts[j] and rnd.random() < 0.5:
                r.on_info(info(j))
            r.on_ack(ack(j, accepts[j]))
        if r.mission_id is None:
            r.open(MID, Selector())
        peers = peers_of([j for j in ids if j != i], {j: info(j) for j in ids if accepts[j]})
        assert r.ready(peers)
        rosters.append(r.freeze(peers))
        hashes.add(r.members_hash)
    assert len(set(rosters)) == 1 and len(hashes) == 1
    assert rosters[0] == tuple(sorted(j for j in ids if accepts[j]))


def test_a_fleet_agrees_on_its_roster_and_reports_a_lost_member() -> None:
    """Three nodes in the fleet harness: the mission to ALL is frozen with the same
    members and hash on every node, published in VehicleInfo; a member that dies in
    flight is a MemberLost on each survivor."""
    from tests.swarm_node.test_mission_defects import area, keep_polling
    from tests.swarm_node.test_node_core import activate, fleet, send

    f = fleet(3)
    activate(f)
    send(f, area(31))
    keep_polling(f, 5.0)
    hashes = {n.roster.members_hash for n in f.nodes.values()}
    assert len(hashes) == 1 and 0 not in hashes
    published = {i.members_hash for i in f.messages(VehicleInfo) if i.mission_id == 31}
    assert hashes <= published
    assert not any(n.roster.mismatches for n in f.nodes.values())
    f.nodes.pop(3)
    keep_polling(f, 4.0)
    for i in (1, 2):
        assert f.nodes[i].lost_members == [MemberLost(31, 3, "stale")]
        assert f.nodes[i].roster.flying == (1, 2)


def test_the_members_hash_and_progress_travel_on_both_encodings() -> None:
    from swarm_proto import lan, radio

    msg = msgspec_replace(
        info(5, members_hash=0xBEEF), mission_progress_m=1234.56, mission_path_m=5000.0
    )
    assert lan.decode(lan.encode(msg), VehicleInfo) == msg
    back = radio.decode(radio.encode(msg), now_unix_s=1.8e9)
    assert isinstance(back, VehicleInfo)
    assert (back.members_hash, back.mission_progress_m, back.mission_path_m) == (
        0xBEEF,
        1234.56,
        5000.0,
    )


def msgspec_replace(m: VehicleInfo, **kw: float) -> VehicleInfo:
    import msgspec

    return msgspec.structs.replace(m, **kw)


def test_a_member_that_finished_its_share_is_not_lost() -> None:
    r = frozen_with_2_and_3()
    home = msgspec_replace(
        info(2, mid=0, state=FsmState.GO_MISSION), mission_progress_m=900.0, mission_path_m=900.0
    )
    assert r.on_info(home) == [] and r.finished == {2}
    recalled = msgspec_replace(
        info(3, mid=0, state=FsmState.GO_MISSION), mission_progress_m=300.0, mission_path_m=900.0
    )
    assert r.on_info(recalled) == [MemberLost(MID, 3, "left the mission")]
    assert r.flying == (1,)


def test_a_member_the_plan_gave_nothing_is_neither_lost_nor_a_joiner() -> None:
    """A member with no share (a quadcopter whose field is beyond its battery) stays on
    the ground and leaves the mission at once: not a loss to replan for, and its
    VehicleInfo still in PLAN for the mission (heard after our plan) is not a joiner.
    Before, the mixed demo's five idle members set every node replanning twice."""
    r = frozen_with_2_and_3()
    r.nothing_to_fly([3, 9])  # 9: not a member, ignored
    assert r.finished == {3} and r.flying == (1, 2)
    assert r.on_info(info(3)) == []  # still in PLAN: no MemberJoined
    down = info(3, mid=0, state=FsmState.INACTIVE)  # completed on the ground, path 0
    assert r.on_info(down) == [] and r.lost == {}
    assert r.survivors(peers_of([2, 3], {2: info(2), 3: info(3)})) == (1, 2)


def test_mission_ids_past_2_31_hash_and_earlier_hashes_are_unchanged() -> None:
    """Mission ids are uint32 (`gcs mission` picks them from the clock): one past 2^31
    crashed the node's VehicleInfo (OverflowError). The hash of every id below 2^31 (and
    of the return mission, -1) is what it was."""
    from swarm_node.core.mission.voting import members_hash as ballot_hash

    assert members_hash(3_000_000_000, (1, 2)) == ballot_hash(3_000_000_000, (1, 2)) > 0
    assert members_hash(2**32 - 1, (1,)) == members_hash(-1, (1,))  # the same 4 bytes
    assert members_hash(41, (1, 2, 3)) == 0xB823  # as before the fix


def test_an_untrusted_vehicle_is_neither_a_member_nor_waited_for_nor_joined() -> None:
    r = Roster(1)
    r.open(MID, Selector())
    peers = peers_of([2, 3], {2: info(2), 3: info(3)})
    r.distrust(frozenset({3}))
    r.on_ack(ack(2, True))
    r.on_ack(ack(3, True))  # its answer may be an impostor's
    assert r.pending(peers) == () and r.ready(peers)
    assert r.freeze(peers) == (1, 2)
    assert r.on_info(info(3)) == []  # in PLAN for our mission: not joined while untrusted
    r.distrust(frozenset())
    assert [type(e).__name__ for e in r.on_info(info(3))] == ["MemberJoined"]
