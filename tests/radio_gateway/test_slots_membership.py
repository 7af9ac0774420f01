"""The slot table (a pure function of membership) and the membership state machine: every
transition of `TRANSITIONS` is driven here from frames and cycles."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from radio_gateway.core.frame import Change, Frame, frame_overhead, heard_bytes
from radio_gateway.core.membership import TRANSITIONS, Membership, Phase, Trigger
from radio_gateway.core.slots import SlotLayout, TdmConfig, physical_limit, table_hash

from .helpers import TDM, TIMING, fleet

C0 = 8_750_000_000  # a cycle number near 2025


@given(st.sets(st.integers(1, 65534), min_size=1, max_size=30), st.randoms())
def test_every_node_computes_the_same_table_from_the_same_members(
    members: set[int], rnd: object
) -> None:
    order = list(members)
    rnd.shuffle(order)  # type: ignore[attr-defined]
    a = SlotLayout.build(tuple(members), TIMING, TDM)
    b = SlotLayout.build(tuple(order), TIMING, TDM)
    assert a == b and a.table_hash == table_hash(tuple(order))


@given(st.integers(1, 40), st.sampled_from([0.002, 0.005, 0.010]), st.integers(20, 140))
def test_slots_tile_the_period_and_fit_their_packets(n: int, guard: float, payload: int) -> None:
    tdm = TdmConfig(guard_s=guard, min_payload=payload)
    lay = SlotLayout.build(tuple(range(1, n + 1)), TIMING, tdm)
    assert lay.slots * lay.slot_s == pytest.approx(lay.k * tdm.cycle_s)
    assert lay.slot_s + 1e-9 >= lay.min_slot_s
    assert lay.budget >= payload
    wire = frame_overhead(n, lay.budget)
    assert TIMING.airtime_s(wire) + guard <= lay.slot_s + 1e-9  # the packet and guard fit
    for p in (0, 1, 7):  # small periods: exact in floating point
        starts = [lay.slot_start(p, i) for i in range(lay.slots)]
        assert starts == sorted(starts)
        assert all(
            lay.slot_cycle(p, i) == int(starts[i] / tdm.cycle_s + 1e-6) for i in range(lay.slots)
        )
    assert lay.over_limit == (n > physical_limit(TIMING, tdm))


def test_a_full_cycle_lends_one_member_slot_in_rotation_to_joiners() -> None:
    n = physical_limit(TIMING, TDM)
    lay = SlotLayout.build(tuple(range(1, n + 1)), TIMING, TDM)
    assert not lay.join_slot and lay.k == 1
    lent = [lay.join_index(p) for p in range(0, 3 * n * lay.join_every, lay.join_every)]
    assert sorted(set(lent)) == list(range(n))  # everyone lends its slot in turn
    assert all(lay.join_index(p) is None for p in range(1, lay.join_every))
    assert lay.member_slot(1, 0) is None and lay.member_slot(2, 0) == 1


# --------------------------------------------------------------------------- transitions


def _m(me: int = 9, **kw: object) -> Membership:
    m = Membership(me, TIMING, TDM, **kw)  # type: ignore[arg-type]
    return m


def _frame(src: int, cycle: int, members: tuple[int, ...], **kw: object) -> Frame:
    n = len(members)
    return Frame(
        src=src,
        cycle=cycle,
        table_hash=table_hash(members),
        n_members=n,
        heard=kw.pop("heard", b"\xff" * heard_bytes(n)),  # type: ignore[arg-type]
        **kw,  # type: ignore[arg-type]
    )


def _advance(m: Membership, start: int, cycles: int) -> int:
    for c in range(start, start + cycles):
        m.advance(c)
    return start + cycles


def _triggers(*ms: Membership) -> set[tuple[Phase, Trigger]]:
    return {(t.old, t.trigger) for m in ms for t in m.transitions}


def test_listening_alone_bootstraps() -> None:
    m = _m(initial_members=(3, 9))
    _advance(m, C0, TDM.listen_cycles + 1)
    assert m.phase is Phase.MEMBER and m.members == (3, 9)
    lone = _m(initial_members=(1, 2))  # not in the configured table: alone
    _advance(lone, C0, TDM.listen_cycles + 1)
    assert lone.members == (9,)


def test_learning_a_table_then_joining_it() -> None:
    m = _m()
    m.advance(C0)
    for c in range(C0 + 1, C0 + 4):
        for src in (1, 2):
            m.on_frame(_frame(src, c, (1, 2)))
        m.advance(c)
    assert m.phase is Phase.JOINING and m.members == (1, 2)
    slot = next(s for s in [m.next_tx(C0 * 0.2, 0)] if s is not None)
    assert slot.join
    m.sent(slot)
    m.on_frame(_frame(1, slot.cycle + 1, (1, 2), records=(Change(True, 9, slot.cycle + 3),)))
    _advance(m, slot.cycle + 1, 3)
    assert m.phase is Phase.MEMBER and m.members == (1, 2, 9)
    assert _triggers(m) == {
        (Phase.LISTENING, Trigger.LEARNED_OTHER),
        (Phase.JOINING, Trigger.ADMITTED),
    }


def test_a_quick_restart_finds_itself_still_in_the_table() -> None:
    m = _m()
    m.advance(C0)
    for c in range(C0 + 1, C0 + 4):
        for src in (1, 2):
            m.on_frame(_frame(src, c, (1, 2, 9)))
        m.advance(c)
    assert m.phase is Phase.MEMBER and m.members == (1, 2, 9)
    assert _triggers(m) == {(Phase.LISTENING, Trigger.LEARNED_MEMBER)}


def _member(members: tuple[int, ...] = (1, 2, 9)) -> tuple[Membership, int]:
    m = _m(initial_members=members)
    c = _advance(m, C0, TDM.listen_cycles + 1)
    assert m.phase is Phase.MEMBER
    return m, c


def test_a_member_told_it_left_rejoins() -> None:
    """A LEAVE of us is contested (a JOIN of us at its cycle, in our next frame); when
    most members carried the LEAVE and none repeated the contest before its cycle, we
    keep quiet until their frames show which table holds: theirs without us, so we
    apply the LEAVE and rejoin."""
    m, c = _member()
    for src in (1, 2):
        m.on_frame(_frame(src, c, (1, 2, 9), records=(Change(False, 9, c + 2),)))
    assert Change(True, 9, c + 2) in m.change_records()  # our contest
    assert Change(False, 9, c + 2) not in m.change_records()  # not ours to spread
    c = _advance(m, c, 3)
    assert m.phase is Phase.MEMBER and m.members == (1, 2, 9)
    assert m.next_tx(c * TDM.cycle_s, 0) is None  # quiet: our slot may be someone's now
    for src in (1, 2):
        m.on_frame(_frame(src, c, (1, 2)))
    c = _advance(m, c, 1)
    assert m.phase is Phase.JOINING and m.members == (1, 2)
    assert (Phase.MEMBER, Trigger.REMOVED) in _triggers(m)
    # doubting with nobody heard is no deadlock: the outage rule ends in a new table
    m, c = _member()
    for src in (1, 2):
        m.on_frame(_frame(src, c, (1, 2, 9), records=(Change(False, 9, c + 2),)))
    c = _advance(m, c, TDM.outage_periods + TDM.activation_periods + 4)
    assert m.members == (9,) and m.next_tx(c * TDM.cycle_s, 0) is not None


def test_a_contested_leave_that_was_heard_keeps_the_member() -> None:
    """The same LEAVE, but a member repeats our contest (it held the LEAVE and heard
    us): a JOIN beats a LEAVE, every node that holds both keeps us, no table changes."""
    m, c = _member()
    for src in (1, 2):
        m.on_frame(_frame(src, c, (1, 2, 9), records=(Change(False, 9, c + 2),)))
    echo = (Change(False, 9, c + 2), Change(True, 9, c + 2))
    m.on_frame(_frame(1, c + 1, (1, 2, 9), records=echo))
    c = _advance(m, c, 3)
    assert m.phase is Phase.MEMBER and m.members == (1, 2, 9)
    assert not m.pending and m.changes_applied == 0
    assert m.next_tx(c * TDM.cycle_s, 0) is not None
    # and a peer that held the LEAVE and hears the contest keeps us too
    p = _m(1, initial_members=(1, 2, 9))
    c = _advance(p, C0, TDM.listen_cycles + 1)
    p.on_frame(_frame(2, c, (1, 2, 9), heard=b"\x00", records=(Change(False, 9, c + 2),)))
    assert (False, 9) in p.pending
    p.on_frame(_frame(9, c + 1, (1, 2, 9), records=(Change(True, 9, c + 2),)))
    assert p.projected_members() == (1, 2, 9)
    c = _advance(p, c, 3)
    assert p.members == (1, 2, 9) and not p.pending and p.changes_applied == 0


def test_a_leave_of_us_carried_by_one_member_of_many_is_not_applied() -> None:
    """`swarm-sim demo --radio` r15: vehicle 2 went stale at every node while every
    table but its own kept it. One member's LEAVE of us, which the others rejected
    (they heard us), is contested; with no repeat of it by most members, we stay."""
    fleet7 = (1, 2, 3, 4, 5, 6, 9)
    m = _m(9, initial_members=fleet7)
    c = _advance(m, C0, TDM.listen_cycles + 1)
    m.on_frame(_frame(1, c, fleet7, records=(Change(False, 9, c + 2),)))
    for _ in range(3):
        for src in (1, 2, 3, 4, 5, 6):
            m.on_frame(_frame(src, c, fleet7))
        c = _advance(m, c, 1)
    assert m.phase is Phase.MEMBER and m.members == fleet7 and m.changes_applied == 0
    assert m.next_tx(c * TDM.cycle_s, 0) is not None


def test_a_stale_members_leaves_of_peers_we_hear_are_not_adopted() -> None:
    """`swarm-sim demo --radio` run 5 (docs/radio.md, "A LEAVE is checked"): gateway 2's
    loop stalled over a second (load 4.6 on 2 cores); catching up cycle by cycle before
    reading what the radio had heard, it found every peer silent for `silent_periods`
    and scheduled LEAVE(1, 3, 4, 5, 6, 900). Every gateway adopted those LEAVEs from its
    frame, itself included, and the fleet's table became [2] and then []. A LEAVE of a
    member the receiver hears (or of itself, reported heard) is a stale view: not adopted.
    """
    fleet7 = (1, 2, 3, 4, 5, 6, 900)
    m = _m(1, initial_members=fleet7)
    c = _advance(m, C0, TDM.listen_cycles + 1)
    for _ in range(3):  # the fleet is on the air, every peer heard, reporting us
        for src in (2, 3, 4, 5, 6, 900):
            m.on_frame(_frame(src, c, fleet7))
        c = _advance(m, c, 1)
    stale = tuple(Change(False, n, c + 2) for n in (1, 3, 4, 5, 6, 900))
    for src in (3, 4, 5, 6, 900):
        m.on_frame(_frame(src, c, fleet7))
    m.on_frame(_frame(2, c, fleet7, heard=b"\x00", records=stale))  # 2 heard nobody
    for _ in range(4):
        for src in (2, 3, 4, 5, 6, 900):
            m.on_frame(_frame(src, c, fleet7))
        c = _advance(m, c, 1)
    assert m.phase is Phase.MEMBER and m.members == fleet7
    assert not m.pending and m.changes_applied == 0
    # a member that really went quiet still leaves, on another member's word
    for _ in range(2):
        for src in (2, 3, 4, 5, 6):
            m.on_frame(_frame(src, c, fleet7, heard=b"\x3f"))  # nobody hears 900
        c = _advance(m, c, 1)
    m.on_frame(_frame(2, c, fleet7, heard=b"\x3f", records=(Change(False, 900, c + 2),)))
    c = _advance(m, c, 3)
    assert m.members == (1, 2, 3, 4, 5, 6) and m.phase is Phase.MEMBER


def test_a_stall_of_our_own_is_no_evidence_against_the_peers() -> None:
    """RadioNode.on_timer tells the membership when its timer came cycles late (our
    process was descheduled): the peers' silence over the stall does not remove them,
    however long (past `outage_periods`, the silence of everyone counts otherwise)."""
    gap = TDM.outage_periods + 3
    for stall in (False, True):
        m, c = _member()
        for src in (1, 2):
            m.on_frame(_frame(src, c, (1, 2, 9)))
        if stall:
            m.stalled(gap)
        c = _advance(m, c, gap + 1)  # the catch-up, nothing heard
        leaves = {node for _, join, node, _ in m.learned if not join}
        assert leaves == (set() if stall else {1, 2})
        if stall:  # a peer that stays silent afterwards, while another is heard, leaves
            for _ in range(TDM.silent_periods + 2):
                m.on_frame(_frame(1, c, (1, 2, 9), heard=b"\x04"))  # 1 hears us, not 2
                c = _advance(m, c, 1)
            assert set(m.pending) == {(False, 2)}


def test_every_member_silent_at_once_is_an_outage_not_evidence() -> None:
    """The channel, or our receiver, went quiet (the channel emulator descheduled in the
    --radio demo at load 17): no LEAVE for `outage_periods`, and the first member heard
    again gives every member a fresh grace period (the others may be heard a slot
    later). Past `outage_periods` the silence counts: members that all left at once leave."""
    for quiet in (TDM.silent_periods + 1, TDM.outage_periods):
        m, c = _member((1, 2, 3, 9))
        for src in (1, 2, 3):
            m.on_frame(_frame(src, c, (1, 2, 3, 9)))
        c = _advance(m, c, quiet + 1)
        assert not m.pending, quiet
        for _ in range(TDM.silent_periods):  # 1 is back, alone so far (hearing only us)
            m.on_frame(_frame(1, c, (1, 2, 3, 9), heard=b"\x08"))
            c = _advance(m, c, 1)
        assert not m.pending, quiet  # 2 and 3 have their grace period
        for _ in range(2):  # 2 is back too; 3 never comes back: it leaves
            for src in (1, 2):
                m.on_frame(_frame(src, c, (1, 2, 3, 9), heard=b"\x0b"))
            c = _advance(m, c, 1)
        assert set(m.pending) == {(False, 3)}, quiet
    m, c = _member((1, 2, 3, 9))
    for src in (1, 2, 3):
        m.on_frame(_frame(src, c, (1, 2, 3, 9)))
    c = _advance(m, c, TDM.outage_periods + 2)  # the last cycle: outage_periods + 1 quiet
    assert set(m.pending) == {(False, 1), (False, 2), (False, 3)}
    _advance(m, c, TDM.activation_periods + 1)
    assert m.members == (9,) and m.phase is Phase.MEMBER


def test_an_outvoted_member_relearns() -> None:
    m, c = _member()
    for _ in range(TDM.mismatch_periods + 1):
        for src in (1, 2):
            m.on_frame(_frame(src, c, (1, 2, 9, 10)))  # they admitted 10; we missed it
        c = _advance(m, c, 1)
    assert m.phase is Phase.LISTENING
    assert (Phase.MEMBER, Trigger.OUTVOTED) in _triggers(m)


def test_a_member_meeting_a_bigger_group_relearns() -> None:
    m, c = _member((9,))
    for _ in range(TDM.mismatch_periods + 1):
        for src in (20, 21, 22):
            m.on_frame(_frame(src, c, (20, 21, 22)))
        c = _advance(m, c, 1)
    assert m.phase is Phase.LISTENING
    assert (Phase.MEMBER, Trigger.FOREIGN) in _triggers(m)


def test_a_joiner_outvoted_or_ignored_starts_over() -> None:
    a = _m()
    a.advance(C0)
    c = C0 + 1
    for c in range(C0 + 1, C0 + 4):
        for src in (1, 2):
            a.on_frame(_frame(src, c, (1, 2)))
        a.advance(c)
    assert a.phase is Phase.JOINING
    for c2 in range(c + 1, c + 1 + TDM.mismatch_periods + 1):
        for src in (1, 2):
            a.on_frame(_frame(src, c2, (1, 2, 5)))
        a.advance(c2)
    assert (Phase.JOINING, Trigger.OUTVOTED) in _triggers(a)

    b = _m()
    b.advance(C0)
    c = C0 + 1
    for c in range(C0 + 1, C0 + 4):
        for src in (1, 2):
            b.on_frame(_frame(src, c, (1, 2)))
        b.advance(c)
    sends = 0
    while b.phase is Phase.JOINING and c < C0 + 5000:
        c += 1
        for src in (1, 2):
            b.on_frame(_frame(src, c, (1, 2)))  # they keep ignoring our JOIN
        slot = b.next_tx(c * TDM.cycle_s, 0)
        if slot is not None and slot.cycle <= c:
            b.sent(slot)
            sends += 1
        b.advance(c)
    assert b.phase is Phase.LISTENING and sends == 16
    assert (Phase.JOINING, Trigger.LOST) in _triggers(b)


def test_every_transition_in_the_table_is_exercised() -> None:
    """The tests above drive each entry; this keeps the table and the tests in step."""
    assert {(k[0], k[1]) for k in TRANSITIONS} == {
        (Phase.LISTENING, Trigger.LEARNED_MEMBER),
        (Phase.LISTENING, Trigger.LEARNED_OTHER),
        (Phase.LISTENING, Trigger.SILENCE),
        (Phase.JOINING, Trigger.ADMITTED),
        (Phase.JOINING, Trigger.OUTVOTED),
        (Phase.JOINING, Trigger.LOST),
        (Phase.MEMBER, Trigger.REMOVED),
        (Phase.MEMBER, Trigger.OUTVOTED),
        (Phase.MEMBER, Trigger.FOREIGN),
    }


def test_two_groups_that_formed_apart_merge_when_they_meet() -> None:
    """Groups on different hopping channels form their own tables; put them on one
    channel and the smaller group relearns and joins the larger one."""
    f = fleet(6, initial=False, max_nodes=6)
    for v in (4, 5, 6):
        f.model.preset(f.members[v].module, HP=1)
    f.run(f.t + 20.0)
    assert f.node(1).membership.members == (1, 2, 3)
    assert f.node(4).membership.members == (4, 5, 6)
    for v in (4, 5, 6):
        f.model.modules[f.members[v].module].registers["HP"] = 0
    f.run(f.t + 40.0)
    want = tuple(range(1, 7))
    assert all(f.node(v).membership.members == want for v in want)
    collisions = f.model.counts["collisions"]
    f.run(f.t + 5.0)
    assert f.model.counts["collisions"] == collisions
