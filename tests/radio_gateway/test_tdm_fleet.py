"""Fleets of radio node cores on the emulated channel, in simulated time (pure, seeded):
the TDM schedule, membership changes, loss, time sync and rate reduction."""

from __future__ import annotations

import dataclasses
import itertools
import os
from collections import Counter

import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from radio_gateway.core.membership import Phase, Trigger
from radio_gateway.core.outbox import OutMessage
from radio_gateway.core.slots import SlotLayout, TdmConfig, physical_limit
from radio_gateway.core.timesync import FREE
from swarm_proto import Geometry, Mission, MissionType, radio
from swarm_proto.topics import MISSION, key_of
from swarm_sim.radio_channel.harness import Fleet
from tests.conftest import examples

from .helpers import TDM, TIMING, fleet, status_arrivals, status_producer, worst_ages


def _rates(f: Fleet, start: float, end: float) -> dict[tuple[int, int], float]:
    arrivals = status_arrivals(f.deliveries)
    return {
        k: sum(1 for t, _ in v if start < t <= end) / (end - start) for k, v in arrivals.items()
    }


@pytest.mark.parametrize("n", [4, 8, 14])
def test_steady_state_keeps_5_hz_without_collisions(n: int) -> None:
    assert physical_limit(TIMING, TDM) >= 14
    f = fleet(n)
    t0 = f.t
    f.run(t0 + 10.0)
    assert f.model.counts["collisions"] == 0
    assert f.model.counts["deferred"] == 0
    rates = _rates(f, t0 + 1.0, t0 + 10.0)
    assert len(rates) == n * (n - 1)
    assert min(rates.values()) >= 0.98 * 5.0
    hashes = {f.node(v).membership.table_hash for v in range(1, n + 1)}
    assert len(hashes) == 1
    assert all(f.node(v).membership.phase is Phase.MEMBER for v in range(1, n + 1))


def _step(f: Fleet, cycles: int) -> list[dict[int, tuple[tuple[int, ...], set[tuple[bool, int]]]]]:
    """Run cycle by cycle; per cycle, each active node's members and pending changes."""
    out = []
    for _ in range(cycles):
        f.run(f.t + TDM.cycle_s)
        out.append(
            {
                nid: (m.node.membership.members, set(m.node.membership.pending))
                for nid, m in f.members.items()
                if m.active
            }
        )
    return out


def test_a_node_leaving_and_one_joining_converge_within_3_cycles() -> None:
    f = fleet(8)
    f.run(f.t + 2.0)
    collisions = f.model.counts["collisions"]
    f.stop(5)
    history = _step(f, 15)
    detected = next(
        i for i, snap in enumerate(history) if any((False, 5) in p for _, p in snap.values())
    )
    want = (1, 2, 3, 4, 6, 7, 8)
    agreed = next(i for i, snap in enumerate(history) if all(ms == want for ms, _ in snap.values()))
    assert detected <= TDM.silent_periods + 1
    assert agreed - detected <= 3
    assert all(all(ms == want for ms, _ in s.values()) for s in history[agreed:])

    f.add(9, producer=status_producer(9))
    history = _step(f, 20)
    asked = next(
        i for i, snap in enumerate(history) if any((True, 9) in p for _, p in snap.values())
    )
    want = (1, 2, 3, 4, 6, 7, 8, 9)
    agreed = next(i for i, snap in enumerate(history) if all(ms == want for ms, _ in snap.values()))
    assert agreed - asked <= 3
    assert f.node(9).membership.phase is Phase.MEMBER
    f.run(f.t + 2.0)
    assert f.model.counts["collisions"] == collisions  # never a collision on the way
    rates = _rates(f, f.t - 1.6, f.t)
    assert all(rates[(r, 9)] >= 4.0 for r in (1, 2, 3, 4, 6, 7, 8))


@pytest.mark.parametrize("n", [4, pytest.param(8, marks=pytest.mark.soak)])  # 14: below
def test_30_percent_loss_keeps_telemetry_age_under_a_second(n: int) -> None:
    f = fleet(n, loss=0.3, seed=3)
    t0 = f.t
    f.run(t0 + 60.0)
    ages = worst_ages(status_arrivals(f.deliveries), t0 + 2.0)
    assert len(ages) > 0.6 * 60 * 5 * n * (n - 1)
    assert ages[-1] < 1.0  # the oldest telemetry any node ever held
    assert all(f.node(v).membership.changes_applied == 0 for v in range(1, n + 1))  # no flapping
    assert sum(f.node(v).counts["tx_relayed"] for v in range(1, n + 1)) > 0


def test_30_percent_loss_at_14_nodes_stays_fresh_and_stable() -> None:
    """At 14 nodes a slot holds only its own status (no room to relay others'), so an
    unlucky run of losses can exceed a second; it stays rare and the table stable."""
    f = fleet(14, loss=0.3, seed=3)
    t0 = f.t
    f.run(t0 + 30.0)
    arrivals = status_arrivals(f.deliveries)
    over = total = 0.0
    for series in arrivals.values():
        for (_, t_prev), (t_new, _) in itertools.pairwise(series):
            if t_new > t0 + 2.0:
                total += t_new - max(t_prev, t0 + 2.0)
                over += max(0.0, t_new - (t_prev + 1.0))
    assert over / total < 0.005  # telemetry older than 1 s less than 0.5 % of the time
    assert all(f.node(v).membership.changes_applied == 0 for v in range(1, 15))
    assert f.model.counts["collisions"] == 0


def test_nodes_without_configuration_find_each_other() -> None:
    f = fleet(6, initial=False, seed=2)
    t0 = f.t
    f.run(t0 + 30.0)
    want = tuple(range(1, 7))
    assert all(f.node(v).membership.members == want for v in want)
    assert all(f.node(v).membership.phase is Phase.MEMBER for v in want)
    collisions = f.model.counts["collisions"]
    f.run(f.t + 10.0)
    assert f.model.counts["collisions"] == collisions  # settled: none after convergence
    assert min(_rates(f, f.t - 9.0, f.t).values()) >= 0.98 * 5.0


def test_two_nodes_joining_at_once_both_get_in() -> None:
    f = fleet(4)
    f.run(f.t + 2.0)
    for v in (5, 6):
        f.add(v, producer=status_producer(v))
    f.run(f.t + 15.0)
    want = tuple(range(1, 7))
    assert all(f.node(v).membership.members == want for v in want)
    collisions = f.model.counts["collisions"]
    f.run(f.t + 5.0)
    assert f.model.counts["collisions"] == collisions


def test_time_sync_puts_a_free_running_clock_on_the_slots() -> None:
    f = fleet(4)
    f.run(f.t + 2.0)
    late = f.add(5, producer=status_producer(5), offset_s=0.025, source_stratum=FREE)
    f.run(f.t + 6.0)
    assert late.membership.phase is Phase.MEMBER
    assert late.timesync.correction_s == pytest.approx(-0.025, abs=0.001)
    assert late.timesync.stratum(0) in (1, 2) or late.timesync.reference(10**12) is None
    for v in (1, 2, 3, 4):
        off = f.node(v).timesync.offset_s(5)
        assert off is not None and abs(off) < 0.001
    assert f.model.counts["collisions"] == 0
    assert f.model.counts["deferred"] == 0


def test_a_gps_node_never_moves_its_clock() -> None:
    f = fleet(3)
    f.add(4, producer=status_producer(4), offset_s=0.003)  # GPS-stratum, slightly off
    f.run(f.t + 5.0)
    assert f.node(4).timesync.correction_s == 0.0
    off = f.node(1).timesync.offset_s(4)
    # its clock runs 3 ms ahead, so its frames arrive 3 ms early: measured and reported
    assert off is not None and off == pytest.approx(-0.003, abs=1e-4)


def test_past_the_physical_limit_every_node_sends_less_often_instead_of_colliding() -> None:
    n = 20
    f = fleet(n, max_nodes=n)
    t0 = f.t
    f.run(t0 + 10.0)
    lay = f.node(1).membership.layout
    assert lay.over_limit and lay.k == 2
    assert f.model.counts["collisions"] == 0
    rates = _rates(f, t0 + 1.0, t0 + 10.0)
    assert min(rates.values()) >= 0.95 * 2.5
    warnings = [no.text for _, _, no in f.notices if no.level == "warning"]
    assert any("every 2 cycles (2.50 Hz)" in w for w in warnings)


def test_missions_are_fragmented_acknowledged_and_retransmitted_through_loss() -> None:
    f = fleet(5, loss=0.3, seed=5)
    f.run(f.t + 2.0)
    mission = Mission(
        mission_id=77,
        issuer_id=1,
        mission_type=MissionType.AREA,
        geometry=Geometry.polygon(
            [(37.41, -5.98), (37.411, -5.9787), (37.412, -5.9774), (37.42, -5.96), (37.425, -5.99)]
        ),
        name="fields north of the base",
    )
    data = radio.encode(mission)
    p = MISSION.radio
    f.node(1).submit(
        OutMessage(key_of("default", mission), data, int(p.klass), p.latest_only, p.acked),
        f.t,
    )
    f.run(f.t + 10.0)
    got = Counter(dst for _, dst, _, d in f.deliveries if d == data)
    assert got == {2: 1, 3: 1, 4: 1, 5: 1}  # everyone, exactly once
    assert f.node(1).outbox.counts["retransmitted"] >= 1
    assert not f.node(1).outbox.chunked  # every member acknowledged it


def test_a_large_message_spans_several_slots_at_14_nodes() -> None:
    f = fleet(14)
    f.run(f.t + 1.0)
    big = bytes([1, 6]) + bytes(range(256)) * 2  # opaque 514-byte payload
    f.node(3).submit(OutMessage("big", big, klass=0, acked=True), f.t)
    f.run(f.t + 6.0)
    got = Counter(dst for _, dst, _, d in f.deliveries if d == big)
    assert set(got) == set(range(1, 15)) - {3} and set(got.values()) == {1}
    assert f.model.counts["collisions"] == 0


def test_layout_matches_the_issue_and_the_paper() -> None:
    """XTend at 115.2 kbps carries 2,880 bytes per 200 ms; at 9.6 kbps a slot of 50 ms
    holds one small packet: the paper's four nodes with 50 ms each (Figure 21)."""
    from radio_gateway.core.airtime import LinkTiming

    assert TIMING.rf_bps / 8 * 0.2 == 2880
    slow = LinkTiming(rf_bps=9600, max_packet=256)
    lay = SlotLayout.build((1, 2, 3, 4), slow, TdmConfig(guard_s=0.005, min_payload=20))
    assert lay.k == 1 and lay.slots == 4 and lay.slot_s == pytest.approx(0.05)
    assert 20 <= lay.budget < 40
    # a 40-byte status frame does not fit 50 ms at 9.6 kbps: three nodes per cycle
    assert physical_limit(slow, TdmConfig(guard_s=0.005)) == 3


@pytest.mark.scale
def test_thirty_unconfigured_nodes_find_each_other_and_share_the_air() -> None:
    """30 nodes, no initial table, 10 % loss: they converge on one table past the limit
    (every node every 2nd or 3rd cycle) and then never collide."""
    f = fleet(30, initial=False, loss=0.1, seed=11, max_nodes=30)
    f.run(f.t + 150.0)
    want = tuple(range(1, 31))
    assert all(f.node(v).membership.members == want for v in want)
    lay = f.node(1).membership.layout
    assert lay.k >= 2
    collisions = f.model.counts["collisions"]
    f.run(f.t + 30.0)
    assert f.model.counts["collisions"] == collisions
    rates = _rates(f, f.t - 28.0, f.t)
    assert min(rates.values()) >= 0.7 * lay.rate_hz  # 10 % loss


def test_a_table_change_in_a_full_cycle_never_collides() -> None:
    """13 nodes at 5 ms guards: slots of 15 ms, shorter than the 20 ms a frame is built
    before its slot. When the lowest id leaves, every slot moves: a frame built before
    the change for a slot after it, under the old table, collided with the new table's
    owner of that time (the table-change collision; also what a gateway
    stalled on a loaded machine, declared gone and back, runs into). Now no frame is
    built under a table for a slot the next table governs."""
    tdm = TdmConfig(guard_s=0.005)
    n = physical_limit(TIMING, tdm)
    f = fleet(n, tdm=tdm, seed=4)
    f.run(f.t + 2.0)
    lay = f.node(2).membership.layout
    assert lay.slot_s < f.node(2).config.prep_s and f.model.counts["collisions"] == 0
    f.stop(1)  # the first slot's owner: every slot moves when it is declared gone
    f.run(f.t + 4.0)
    assert all(f.node(v).membership.members == tuple(range(2, n + 1)) for v in range(2, n + 1))
    f.add(1, producer=status_producer(1), initial_members=tuple(range(1, n + 1)))
    f.run(f.t + 12.0)
    assert f.node(2).membership.members == tuple(range(1, n + 1))
    assert f.model.counts["collisions"] == 0


@pytest.mark.parametrize(("phase_s", "stall_s"), [(0.0, 1.1), (0.05, 1.0), (0.1, 0.9), (0.0, 2.0)])
def test_a_gateway_stalled_past_the_leave_timeout_does_not_dissolve_the_table(
    phase_s: float, stall_s: float
) -> None:
    """`swarm-sim demo --radio` run 5: gateway 2's process stalled for about a second
    (load 4.6 on 2 cores). It heard nothing (what its port held came too late for the
    replay window) and, catching up cycle by cycle, found every peer silent for
    `silent_periods`: it scheduled LEAVE(everyone else), every gateway adopted those
    from its frames (themselves included), and the table became [2], then [] (the
    stalls here did that before the fix). Now the stalled gateway takes its stall as no
    evidence, and nobody adopts a LEAVE of a member it hears: only the silent one is
    removed, and it rejoins."""
    f = fleet(7)
    f.run(f.t + 3.0 + phase_s)
    assert all(f.node(i).membership.members == tuple(range(1, 8)) for i in range(1, 8))
    f.stop(2)  # the process is descheduled: no timer, no reads, no writes
    f.run(f.t + stall_s)
    f.resume(2)
    f.run(f.t + 6.0)
    for i in range(1, 8):
        m = f.node(i).membership
        assert m.phase is Phase.MEMBER and m.members == tuple(range(1, 8)), i
        assert all(len(members) >= 6 for _, members in m.tables), (i, m.tables)
        if i != 2:
            assert not any(t.trigger is Trigger.REMOVED for t in m.transitions), i


def _silence(f: Fleet, outage_s: float, stalled: int = 0, stall_s: float = 0.0) -> None:
    params = f.model.params
    start = f.t
    f.model.params = dataclasses.replace(params, loss=1.0)
    if stalled:
        f.stop(stalled)
    for t, what in sorted([(outage_s, "channel"), (stall_s, "gateway")]):
        if what == "gateway" and not stalled:
            continue
        f.run(max(f.t, start + t))
        if what == "channel":
            f.model.params = params
        else:
            f.resume(stalled)
    f.run(f.t + 6.0)


def _assert_table_kept(f: Fleet, stalled: int = 0) -> None:
    """Every table whole throughout, but for `stalled`, which may be removed (and
    rejoin): a gateway silent past `silent_periods` while the others hear each other."""
    want = tuple(range(1, 8))
    for i in want:
        m = f.node(i).membership
        assert m.phase is Phase.MEMBER and m.members == want, (i, m.members)
        for _, members in m.tables:
            assert set(want) - set(members) <= {stalled}, (i, m.tables)
        if not stalled:
            assert not m.learned, (i, m.learned)  # no LEAVE was even scheduled


@pytest.mark.parametrize(
    ("phase_s", "outage_s"), [(0.0, 0.5), (0.07, 0.9), (0.13, 1.0), (0.07, 1.6), (0.19, 2.5)]
)
def test_a_channel_outage_for_everyone_removes_nobody(phase_s: float, outage_s: float) -> None:
    """The --radio demo at load 17: the channel emulator's process was descheduled,
    every gateway heard nobody for over a second and scheduled every peer out (tables of
    4, 1 and 0 members; 1.0-1.2 s outages emptied every table here before the fix).
    Silence of every member at once is an outage, no evidence: no LEAVE, and a grace
    period for all when one is heard again."""
    f = fleet(7)
    f.run(f.t + 3.0 + phase_s)
    _silence(f, outage_s)
    _assert_table_kept(f)


@settings(max_examples=examples(int(os.environ.get("OUTAGE_EXAMPLES", "5"))), deadline=None)
@given(
    phase_s=st.floats(0.0, 0.2),
    outage_s=st.floats(0.5, 2.5),
    stalled=st.sampled_from([0, 1, 4, 7]),
    stall_s=st.floats(0.0, 2.5),
)
# Found by `make fuzz`, not yet understood: a 0.5 s outage with gateway 1 descheduled
# for 1.0 s from the same moment keeps every table whole, but gateway 1 learns a LEAVE of
# itself (and contests it), which the 0.8 s allowance says should not even be scheduled
@example(phase_s=0.03125, outage_s=0.5, stalled=1, stall_s=1.0).xfail(
    raises=AssertionError, reason="a LEAVE of a gateway stalled 1.0 s is scheduled"
)
def test_no_outage_up_to_2_5_s_shrinks_a_table(
    phase_s: float, outage_s: float, stalled: int, stall_s: float
) -> None:
    """Any outage of 0.5-2.5 s at any phase of the cycle, with or without one gateway
    descheduled too for up to 2.5 s from the same moment (on a loaded host both
    starve at once): no table loses a member but the stalled gateway, and that one
    only if it stayed silent after the channel came back for about the LEAVE timeout
    (`silent_periods`: 1 s; 0.8 s allowed for the phase)."""
    f = fleet(7)
    f.run(f.t + 3.0 + phase_s)
    _silence(f, outage_s, stalled, stall_s)
    _assert_table_kept(f, stalled if stall_s > outage_s + 0.8 else 0)


def test_a_peer_is_predicted_as_long_as_the_slot_table_keeps_it() -> None:
    """The gateway stops predicting a peer to its node after `silent_s` (3 s) unheard,
    but never before the slot table itself would remove it: past the physical limit a
    period is several cycles (36 members: every 3rd cycle, 0.6 s), and 5 + 2 periods
    of it are 4.2 s."""
    for n, k in ((7, 1), (36, 3)):
        f = fleet(n)
        f.run(f.t + 2.0)
        node = f.node(1)
        assert node.membership.layout.k == k and len(node.membership.members) == n
        want = max(3.0, (TDM.silent_periods + TDM.activation_periods) * k * TDM.cycle_s)
        assert node.silence_limit_s(3.0) == pytest.approx(want)
    assert want > 3.0
