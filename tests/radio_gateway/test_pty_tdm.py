"""The issue's checks through the emulator on real pseudo-terminals with pyserial:
real RadioLink threads (serial reads, timed writes) and the channel emulator's thread.

Timing on a shared 2-core machine is noisy, so the simulated clock runs slower than the
wall clock here (every millisecond of slot margin is two of wall time); what is asserted
is what the protocol guarantees: no collisions, 5 Hz, convergence within 3 cycles.

The default run keeps the hardest steady state (14 nodes, 1 ms of spare per slot); 4 and
8 nodes, the leave/join convergence and the 30 % loss run (10 s of wall time) are `soak`
here: the same properties are checked in simulated time by test_tdm_fleet.py, which runs
the same node cores on the same channel model."""

from __future__ import annotations

import itertools

import pytest

from radio_gateway.core.membership import Phase
from swarm_sim.radio_channel.model import ChannelParams

from .helpers import status_arrivals
from .ptyfleet import PtyFleet

# real-time TDM over pseudo-terminals: run alone, after the parallel part of `make test`
pytestmark = pytest.mark.timing


def _rates(deliveries: list, start: float, end: float) -> dict[tuple[int, int], float]:
    arrivals = status_arrivals(deliveries)
    return {
        k: sum(1 for t, _ in v if start < t <= end) / (end - start) for k, v in arrivals.items()
    }


@pytest.mark.parametrize(
    "n", [pytest.param(4, marks=pytest.mark.soak), pytest.param(8, marks=pytest.mark.soak), 14]
)
def test_nodes_keep_5_hz_status_with_no_collisions(n: int) -> None:
    # a quarter speed gives a shared, busy machine four times the slot margins (14 nodes
    # leave 1 ms of spare per slot)
    with PtyFleet(n, speed=0.25) as fleet:
        members = tuple(range(1, n + 1))
        for v in members:
            fleet.start(v, members)
        fleet.sleep(1.0)  # listen, bootstrap
        fleet.channel.reset_stats()
        t0 = fleet.clock.now()
        late0 = fleet.late_writes()
        fleet.sleep(2.2)
        t1 = fleet.clock.now()
        late1 = fleet.late_writes()
        stats = fleet.channel.stats()["channel"]
        # exactly 10 cycles: every slot of the cycle falls in the window equally often
        start, end = t0 + 0.2, t0 + 0.2 + 10 * fleet.tdm.cycle_s
        assert t1 >= end
        rates = _rates(fleet.snapshot(), start, end)
        phases = {fleet.node(v).membership.phase for v in members}
    assert stats.get("collisions", 0) == 0
    assert phases == {Phase.MEMBER}
    assert len(rates) == n * (n - 1)
    # 5 Hz from every node at every other. A write the host woke too late for is skipped
    # (never sent into the next slot) and counted: that is the machine, not the protocol,
    # so each one excuses the n - 1 arrivals it cost.
    late = sum(late1[v] - late0[v] for v in members)
    window = end - start
    excused = late * (n - 1) / (len(rates) * window)
    assert min(rates.values()) >= 0.75 * 5.0, (late, sorted(rates.values())[:5])
    assert sum(rates.values()) / len(rates) >= 0.95 * 5.0 - excused, (late, window)
    assert late <= n, "the host was too busy to keep the slots: see late_writes"


@pytest.mark.soak  # the same in simulated time: test_tdm_fleet.py
def test_a_node_leaving_and_one_joining_converge_within_3_cycles() -> None:
    with PtyFleet(7, speed=0.5) as fleet:
        members = (1, 2, 3, 4, 5, 6)
        for v in members:
            fleet.start(v, members)
        fleet.sleep(1.5)
        fleet.stop(4)
        fleet.sleep(2.5)
        fleet.start(7)
        fleet.sleep(3.0)
        collisions = fleet.channel.stats()["channel"].get("collisions", 0)
        nodes = {v: fleet.node(v) for v in (1, 2, 3, 5, 6, 7)}
        final = {v: n.membership.members for v, n in nodes.items()}
        learned = {v: list(n.membership.learned) for v, n in nodes.items()}
        tables = {v: list(n.membership.tables) for v, n in nodes.items()}
    want = (1, 2, 3, 5, 6, 7)
    assert set(final.values()) == {want}
    assert collisions == 0
    for join, node, table in ((False, 4, (1, 2, 3, 5, 6)), (True, 7, want)):
        first = min(
            c for v in (1, 2, 3, 5, 6) for c, j, nd, _ in learned[v] if (j, nd) == (join, node)
        )
        adopted = [next(c for c, ms in tables[v] if ms == table) for v in (1, 2, 3, 5, 6)]
        assert max(adopted) - first <= 3, (join, node, first, adopted)
        assert len(set(adopted)) == 1  # everyone switched on the same cycle
    assert tables[7][-1][1] == want


@pytest.mark.soak
def test_30_percent_loss_keeps_telemetry_age_under_a_second() -> None:
    # the node's own 5 Hz status, as a vehicle publishes it
    with PtyFleet(
        4, speed=1.0, params=ChannelParams(loss=0.3, seed=7), producer_period_s=0.2
    ) as fleet:
        members = (1, 2, 3, 4)
        for v in members:
            fleet.start(v, members)
        fleet.sleep(1.0)
        t0 = fleet.clock.now()
        fleet.sleep(10.0)
        deliveries = fleet.snapshot()
        lost = fleet.channel.stats()["channel"].get("lost", 0)
        flapping = sum(fleet.node(v).membership.changes_applied for v in members)
    assert lost > 0
    arrivals = status_arrivals(deliveries)
    ages = []
    over = total = 0.0
    for series in arrivals.values():
        for (_, t_prev), (t_new, _) in itertools.pairwise(series):
            if t_new > t0:
                ages.append(t_new - t_prev)
                total += t_new - max(t_prev, t0)
                over += max(0.0, t_new - (t_prev + 1.0))
    ages.sort()
    assert len(ages) > 0.8 * 10 * 5 * 12
    assert ages[int(0.99 * len(ages))] < 1.0  # 99 % of updates find telemetry < 1 s old
    assert over / total < 0.002  # older than a second less than 0.2 % of the time
    assert flapping == 0
