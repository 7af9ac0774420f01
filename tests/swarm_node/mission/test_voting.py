"""The leaderless ballot: every vehicle ends with the same winners, under
loss, a voter dying mid-vote, late joiners, radio quantization; the 200 lossy trials."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from radio_gateway.core.frame import MAX_MESSAGE_BYTES, MAX_RECORD_VALUE
from swarm_node.ballot_fleet import BallotFleet, lossy_trial
from swarm_node.core.mission.voting import (
    Ballot,
    BallotConfig,
    Decided,
    SendVote,
    VoterLost,
    members_hash,
    rank,
    score_key,
)
from swarm_proto import Vote, VoteScore, radio
from tests.conftest import examples

MID = 7


def expected_winners(scores: dict[int, float], quantity: int) -> tuple[int, ...]:
    """The paper's rule, computed here: the `quantity` best, ties by vehicle id."""
    return tuple(sorted(scores, key=lambda v: (-round(scores[v] * 10_000), v))[:quantity])


# ---------------------------------------------------------------------- pure pieces
def test_rank_best_first_ties_by_vehicle_id() -> None:
    assert rank({5: 9000, 3: 9000, 8: 9500, 1: 100}, 2) == (8, 3)
    assert rank({5: 9000, 3: 9000}, 5) == (3, 5)  # more asked than voters: all go


def test_score_key_is_the_radio_resolution() -> None:
    v = Vote(MID, 1, (VoteScore(1, 0.123456),))
    on_air = radio.decode(radio.encode(v), now_unix_s=0.0)
    assert isinstance(on_air, Vote)
    assert score_key(on_air.scores[0].score) == score_key(0.123456) == 1235
    assert score_key(1.5) == 10_000 and score_key(-1.0) == 0


def test_an_electorate_of_one_decides_alone() -> None:
    b = Ballot(MID, 4, frozenset({4}), 1, 0.5, 0.0)
    outs = b.on_timer(0.0)
    assert isinstance(outs[0], SendVote) and isinstance(outs[1], Decided)
    assert outs[1].outcome.winners == (4,)


def test_misuse_raises() -> None:
    with pytest.raises(ValueError, match="not in the electorate"):
        Ballot(MID, 9, frozenset({1, 2}), 1, 0.5, 0.0)
    with pytest.raises(ValueError, match="quantity"):
        Ballot(MID, 1, frozenset({1, 2}), 0, 0.5, 0.0)
    with pytest.raises(ValueError, match="timing"):
        BallotConfig(retry_s=0.0)


def test_foreign_votes_are_counted_and_ignored() -> None:
    b = Ballot(MID, 1, frozenset({1, 2}), 1, 0.5, 0.0)
    h = b.roster_hash
    assert h == members_hash(MID, [2, 1])
    b.on_timer(0.0)
    assert b.handle(Vote(MID + 1, 2, (VoteScore(2, 0.9),), members_hash=h), 0.1) == []
    assert b.handle(Vote(MID, 2, (VoteScore(2, 0.9),), members_hash=h ^ 1), 0.1) == []
    assert b.handle(Vote(MID, 3, (VoteScore(3, 0.9),), members_hash=h), 0.1) == []
    assert b.handle(Vote(MID, 1, (VoteScore(1, 0.9),), members_hash=h), 0.1) == []
    assert b.table == {1: 5000}  # nothing merged
    # a member's vote naming a vehicle outside the electorate: that entry only is dropped
    b.handle(Vote(MID, 2, (VoteScore(2, 0.9), VoteScore(77, 1.0)), members_hash=h), 0.2)
    assert b.table == {1: 5000, 2: 9000}
    assert b.counts == {
        "other_mission": 1,
        "wrong_roster": 1,
        "not_member": 1,
        "own_echo": 1,
        "foreign_score": 1,
    }


def test_commit_needs_every_live_member_to_hold_our_table() -> None:
    b = Ballot(MID, 1, frozenset({1, 2, 3}), 1, 0.5, 0.0)
    h = b.roster_hash
    b.on_timer(0.0)
    # 2 knows only itself: merged, not a confirmation
    assert b.handle(Vote(MID, 2, (VoteScore(2, 0.9),), members_hash=h), 0.1) == []
    full = (VoteScore(1, 0.5), VoteScore(2, 0.9), VoteScore(3, 0.2))
    assert b.handle(Vote(MID, 3, full, members_hash=h), 0.2) == []  # table grew: 3 -> confirmed
    assert b.confirmed == {3}
    outs = b.handle(Vote(MID, 2, full, members_hash=h), 0.3)
    assert outs and isinstance(outs[0], Decided)
    o = outs[0].outcome
    assert o.winners == (2,) and o.stayers == (1, 3) and o.absent == ()
    assert b.vote().committed


def test_a_lost_voter_is_not_waited_for_and_confirmations_restart() -> None:
    b = Ballot(MID, 1, frozenset({1, 2, 3}), 2, 0.5, 0.0)
    h = b.roster_hash
    b.on_timer(0.0)
    mine_and_2 = (VoteScore(1, 0.5), VoteScore(2, 0.9))
    b.handle(Vote(MID, 2, mine_and_2, members_hash=h), 0.1)
    b.handle(Vote(MID, 2, mine_and_2, members_hash=h), 0.2)
    assert b.confirmed == {2}
    assert b.handle(VoterLost(3), 2.0) == []  # a vote of 2 sent after the loss is needed
    assert b.confirmed == set()
    outs = b.handle(Vote(MID, 2, mine_and_2, members_hash=h), 2.1)
    assert isinstance(outs[0], Decided)
    assert outs[0].outcome.winners == (2, 1) and outs[0].outcome.absent == (3,)


def test_no_agreement_by_the_deadline_fails_once() -> None:
    b = Ballot(MID, 1, frozenset({1, 2}), 1, 0.5, 0.0, BallotConfig(deadline_s=5.0))
    t = 0.0
    failed = []
    while (d := b.next_deadline()) is not None:
        t = d
        failed += [o for o in b.on_timer(t) if not isinstance(o, SendVote)]
    assert t == 5.0 and len(failed) == 1
    assert b.failed is not None and b.failed.waiting_for == (2,)
    assert "no score from [2]" in b.failed.reason


def test_re_sending_is_bounded() -> None:
    """A voter whose peers never answer sends deadline/retry votes, then stops."""
    b = Ballot(MID, 1, frozenset({1, 2}), 1, 0.5, 0.0)
    sent = 0
    while (d := b.next_deadline()) is not None:
        sent += sum(isinstance(o, SendVote) for o in b.on_timer(d))
    assert sent == 40  # 20 s / 0.5 s


# ---------------------------------------------------------------------- fleets
@given(
    scores=st.dictionaries(st.integers(1, 65534), st.floats(0.0, 1.0), min_size=2, max_size=12),
    quantity=st.integers(1, 12),
    seed=st.integers(0, 2**16),
    encoding=st.sampled_from(["lan", "radio"]),
)
@settings(max_examples=examples(60))
def test_same_inputs_same_winners_on_every_vehicle(
    scores: dict[int, float], quantity: int, seed: int, encoding: str
) -> None:
    f = BallotFleet(scores, quantity, seed=seed, encoding=encoding)
    res = f.run()
    assert res.problems(f.electorate) == []
    want = expected_winners(scores, quantity)
    assert {o.winners for o in res.outcomes.values()} == {want}


@given(
    scores=st.dictionaries(
        st.integers(1, 200), st.sampled_from([0.1, 0.5, 0.9]), min_size=3, max_size=10
    ),
    quantity=st.integers(1, 4),
    seed=st.integers(0, 2**16),
)
@settings(max_examples=examples(40))
def test_under_loss_the_winners_are_still_the_papers(
    scores: dict[int, float], quantity: int, seed: int
) -> None:
    """20 % loss, no death: everyone decides, on the full table."""
    f = BallotFleet(scores, quantity, seed=seed, loss=0.2)
    res = f.run()
    assert res.problems(f.electorate) == []
    assert {o.winners for o in res.outcomes.values()} == {expected_winners(scores, quantity)}


def test_200_lossy_trials_never_assign_twice_nor_leave_out() -> None:
    """The issue's check: 20 % loss, random voter death, random join order."""
    deaths = lates = 0
    for seed in range(200):
        f, res = lossy_trial(seed, "radio" if seed % 4 == 0 else "lan")
        assert res.problems(f.electorate) == [], f"seed {seed}"
        deaths += bool(f.death_s)
        lates += any(f.start_s.values())
        # the winners are the paper's rule over the agreed table
        o = next(iter(res.outcomes.values()))
        table = {s.vehicle_id: s.score for s in o.scores}
        assert o.winners == expected_winners(table, f.quantity)
        # the table holds every live voter; the dead one only if its vote got out
        assert set(table) >= f.electorate - res.dead
    assert deaths > 120 and lates > 100  # the trials exercise both


def test_a_voter_dying_before_its_vote_got_out_is_absent_everywhere() -> None:
    f = BallotFleet({1: 0.9, 2: 0.5, 3: 0.4, 4: 0.3}, 2, death_s={1: 0.0})
    res = f.run()
    assert res.problems(f.electorate) == []
    assert {(o.winners, o.absent) for o in res.outcomes.values()} == {((2, 3), (1,))}


def test_a_voter_dying_after_its_vote_is_still_counted_everywhere() -> None:
    """Its score reached the others: the same winners everywhere, it among them (the
    new fleet's roster then loses it, as any member lost in flight)."""
    f = BallotFleet({1: 0.9, 2: 0.5, 3: 0.4, 4: 0.3}, 2, death_s={1: 0.03})
    res = f.run()
    assert res.problems(f.electorate) == []
    assert {o.winners for o in res.outcomes.values()} == {(1, 2)}


def test_a_late_joiner_is_waited_for() -> None:
    f = BallotFleet({1: 0.2, 2: 0.5, 3: 0.4, 4: 0.9}, 1, start_s={4: 3.0}, loss=0.2, seed=5)
    res = f.run()
    assert res.problems(f.electorate) == []
    assert min(res.decided_s.values()) >= 3.0  # nobody decides without 4's score
    assert {o.winners for o in res.outcomes.values()} == {(4,)}


def test_a_partition_after_the_votes_crossed_still_agrees() -> None:
    """The halves stop hearing each other once every table is complete: each half
    waits for the other until liveliness loses it, then decides on the same table."""
    scores = {1: 0.9, 2: 0.8, 3: 0.2, 4: 0.1}
    f = BallotFleet(scores, 2, cut_s=0.03, side=frozenset({1, 2}))
    res = f.run()
    assert res.problems(f.electorate) == []
    assert {o.winners for o in res.outcomes.values()} == {(1, 2)}


def test_a_partition_before_the_votes_crossed_decides_per_side() -> None:
    """Cut from the start: each side elects among the scores it holds, the same within
    the side; the sides differ (the documented partition behaviour: each side flies
    what it decided, the roster merges the fleets again when they meet)."""
    scores = {1: 0.9, 2: 0.8, 3: 0.2, 4: 0.1}
    f = BallotFleet(scores, 1, cut_s=0.0, side=frozenset({1, 2}))
    res = f.run()
    assert not res.failures
    assert {res.outcomes[v].winners for v in (1, 2)} == {(1,)}
    assert {res.outcomes[v].winners for v in (3, 4)} == {(3,)}
    assert res.outcomes[3].absent == (1, 2)


# ---------------------------------------------------------------------- the radio
@pytest.mark.parametrize("n", [6, 50])
def test_a_vote_fits_the_radio_encoding(n: int) -> None:
    """A full table (every score, the largest ids, round and hash) within the radio's
    limits: one unfragmented record for 6 voters, within a message for 50."""
    v = Vote(
        2**32 - 1,
        65534,
        tuple(VoteScore(65534 - i, 0.1234) for i in range(n)),
        round=255,
        members_hash=0xFFFF,
        committed=True,
    )
    data = radio.encode(v)
    assert radio.decode(data, now_unix_s=0.0) == v
    assert len(data) <= (MAX_RECORD_VALUE if n <= 6 else MAX_MESSAGE_BYTES)


def test_a_vote_round_for_six_over_the_emulated_tdm_channel() -> None:
    """Six gateways on the emulated XTend channel (statuses at 5 Hz alongside): every
    ballot decides, on the same winners, with no collision."""
    from bench.voting import agree_radio

    r = agree_radio(6, seed=3)
    assert r["collisions"] == 0 and r["votes_sent"] > 0


@given(
    votes=st.lists(
        st.tuples(
            st.integers(1, 8),  # voter (6..8 outside the electorate)
            st.lists(
                st.tuples(st.integers(1, 8), st.floats(allow_nan=True, allow_infinity=True)),
                max_size=8,
            ),
            st.booleans(),
            st.sampled_from(["ours", "other", "mission"]),
        ),
        max_size=30,
    )
)
@settings(max_examples=examples(150))
def test_bad_votes_never_crash_nor_corrupt_the_table(
    votes: list[tuple[int, list[tuple[int, float]], bool, str]],
) -> None:
    """Votes built by hand (no decoder in front: out-of-range, NaN, duplicate entries,
    strangers, other rosters and missions): the ballot never raises, its table only
    holds electorate members with scores in range, and its own entry is there."""
    electorate = frozenset({1, 2, 3, 4, 5})
    b = Ballot(MID, 1, electorate, 2, 0.7, 0.0)
    t = 0.0
    for voter, entries, committed, which in votes:
        t += 0.01
        v = Vote(
            MID + (which == "mission"),
            voter,
            tuple(VoteScore(vid, s) for vid, s in entries),
            members_hash=b.roster_hash ^ (which == "other"),
            committed=committed,
        )
        b.handle(v, t)
        b.on_timer(t)
    assert set(b.table) <= electorate and 1 in b.table
    assert all(0 <= k <= 10_000 for k in b.table.values())
    if b.outcome is not None:
        assert set(b.outcome.winners) | set(b.outcome.stayers) == set(b.table)


def test_a_restarted_voter_with_another_score_still_converges() -> None:
    """Two values for one vehicle (a voter that restarted and scored itself again): the
    lower is kept everywhere, so the tables still converge and all decide alike."""
    ballots = {
        v: Ballot(MID, v, frozenset({1, 2, 3}), 1, s, 0.0)
        for v, s in {1: 0.9, 2: 0.5, 3: 0.4}.items()
    }
    ballots[3].table[1] = 1000  # 3 heard an older, lower score of vehicle 1
    t = 0.0
    while not all(b.done for b in ballots.values()) and t < 30.0:
        t = min(d for b in ballots.values() if (d := b.next_deadline()) is not None)
        for b in ballots.values():
            if b.next_deadline() == t:
                for o in b.on_timer(t):
                    if isinstance(o, SendVote):
                        for other in ballots.values():
                            if other is not b:
                                other.handle(o.vote, t)
    outcomes = {b.outcome for b in ballots.values()}
    assert len(outcomes) == 1
    o = outcomes.pop()
    assert o is not None and o.winners == (2,)
    assert ballots[1].counts["score_conflict"] == 1
