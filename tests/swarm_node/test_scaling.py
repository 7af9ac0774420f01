"""A node's and the fast-time harness's cost per event does not grow with the
swarm. Counted, never timed: peers a node core looks at per input (its staleness
deadlines, its timer, and any module walking the peer table), and vehicle deadlines the
fast-time harness evaluates per event."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import pytest

from swarm_node.core.node import AutopilotUpdate, NodeCore, NodeSettings, PeerAlive, Received
from swarm_proto import FsmState, VehicleInfo, VehicleStatus, VehicleType

STATUS_S, INFO_S = 0.2, 1.0


class CountingPeers(dict):  # type: ignore[type-arg]
    """A peer table that counts every peer handed out by a walk over it (a module that
    looks at all the peers for one input shows up here)."""

    walked = 0

    def __iter__(self) -> Iterator[Any]:
        for k in super().__iter__():
            self.walked += 1
            yield k

    def values(self) -> Any:
        return [self._count(v) for v in super().values()]

    def items(self) -> Any:
        return [(k, self._count(v)) for k, v in super().items()]

    def keys(self) -> Any:
        return [self._count(k) for k in super().__iter__()]

    def _count(self, x: Any) -> Any:
        self.walked += 1
        return x


def _node(
    fleet_profiles: dict, peers: int, *, liveliness: bool, avoidance: bool = False
) -> tuple[NodeCore, int]:
    """Node 7 on the ground (no base: it never plans), hearing `peers` synthetic peers
    (status at 5 Hz, info at 1 Hz, with or without liveliness tokens) for 4 simulated
    seconds, timers served as the runtime serves them. Returns the node and the number
    of inputs and timer calls it handled."""
    settings = NodeSettings(avoidance=avoidance)
    core = NodeCore(fleet_profiles[7], settings, now=0.0, fleet_profiles=fleet_profiles)
    table = CountingPeers(core.members.peers)
    core.members.peers = table
    ids = range(1000, 1000 + peers)
    events: list[tuple[float, int, object]] = []
    for k in range(int(4.0 / STATUS_S)):
        t = k * STATUS_S
        for i, vid in enumerate(ids):
            at = t + STATUS_S * i / peers  # spread over the period, as real peers are
            events.append(
                (
                    at,
                    vid,
                    VehicleStatus(vid, at, 37.41, -5.99, 60.0, 50.0, fsm_state=FsmState.GO_MISSION),
                )
            )
            if k % int(INFO_S / STATUS_S) == 0:
                events.append((at, vid, VehicleInfo(vid, VehicleType.VTOL, "Albatross", "A")))
    events.sort(key=lambda e: (e[0], e[1]))
    handled = 0
    if liveliness:
        for vid in ids:
            core.handle(PeerAlive(vid, True), 0.0)
    next_ap = 0.0
    for at, _vid, msg in events:
        while min(core.next_deadline(), next_ap) <= at:  # the runtime's loop
            now = min(core.next_deadline(), next_ap)
            if now >= next_ap:
                next_ap += 0.2
                core.handle(AutopilotUpdate(core.autopilot), now)
            if now >= core.next_deadline():
                core.on_timer(now)
            handled += 1
        core.handle(Received(msg), at)
        core.next_deadline()  # the runtime asks after every input
        handled += 1
    assert len(core.members.live()) == peers
    return core, handled


@pytest.mark.parametrize("liveliness", [False, True])
def test_peers_looked_at_per_event_do_not_grow_with_the_swarm(
    fleet_profiles: dict, liveliness: bool
) -> None:
    per_event = {}
    for peers in (10, 100, 1000):
        core, handled = _node(fleet_profiles, peers, liveliness=liveliness)
        table = core.members.peers
        assert isinstance(table, CountingPeers)
        visits = getattr(core.members, "visits", 0) + table.walked
        per_event[peers] = visits / handled
    # before the staleness deadline alone walked every peer at every call:
    # about `peers` visits per event; now a couple, whatever the swarm's size
    assert max(per_event.values()) <= 3.0, per_event
    assert per_event[1000] <= 1.2 * per_event[10] + 0.1, per_event


def test_avoidance_on_a_grounded_node_walks_no_peer_at_its_ticks(fleet_profiles: dict) -> None:
    """Collision avoidance's 5 Hz tick on a vehicle on the ground: the peers' statuses
    wait (the latest per peer) and the pad rules' peer table is asked only for a take-off
    or a landing, so the visits per event stay as flat as without avoidance."""
    per_event = {}
    for peers in (10, 100, 1000):
        core, handled = _node(fleet_profiles, peers, liveliness=True, avoidance=True)
        assert core.avoid.enabled and core.avoid.counters.get("ticks", 0) >= 15
        table = core.members.peers
        assert isinstance(table, CountingPeers)
        per_event[peers] = (getattr(core.members, "visits", 0) + table.walked) / handled
    assert max(per_event.values()) <= 3.0, per_event
    assert per_event[1000] <= 1.2 * per_event[10] + 0.1, per_event


def test_staleness_by_deadline_still_drops_a_silent_peer_on_time(fleet_profiles: dict) -> None:
    """The deadline lists keep the rule: a peer heard only by telemetry leaves
    `stale_after_s` after it was last heard, among a thousand that keep talking."""
    core, _ = _node(fleet_profiles, 1000, liveliness=False)
    m = core.members
    last = max(p.last_heard_s for p in m.peers.values())
    silent = 5000  # a new peer, heard once
    m.on_status(VehicleStatus(silent, last, 37.41, -5.99, 60.0, 50.0), last)
    # everyone else keeps talking (each silence of all of them over `feed_quiet_s` would
    # be our feed's, no evidence against anyone)
    for t in (last + 0.9, last + 1.8):
        for vid in range(1000, 2000):
            m.on_status(VehicleStatus(vid, t, 37.41, -5.99, 60.0, 50.0), t)
    assert m.next_deadline() == pytest.approx(last + m.stale_after_s)
    assert [e.node_id for e in m.on_timer(last + m.stale_after_s - 1e-6)] == []
    left = m.on_timer(last + m.stale_after_s)
    assert [e.node_id for e in left] == [silent]
    # the next: were all of them to fall silent now, that would be our feed's silence,
    # held until `feed_outage_s`
    assert m.next_deadline() == pytest.approx(last + 1.8 + m.feed_outage_s)


def test_the_fast_time_harness_evaluates_deadlines_per_event_not_per_vehicle(
    fleet_profiles: dict,
) -> None:
    """FastFleet keeps one heap of the vehicles' deadlines: a vehicle's deadline is
    evaluated when something happened to it, so evaluations per event stay flat as the
    fleet grows (before, every step asked every vehicle, twice)."""
    from swarm_sim.fast_fleet import FastFleet

    ratio = {}
    for n in (3, 24):
        ids = [(1, 7, 8, 10, 12)[i % 5] for i in range(n)]
        profiles = {i + 1: _renumbered(fleet_profiles[vid], i + 1) for i, vid in enumerate(ids)}
        fleet = FastFleet.build(list(profiles), profiles)
        fleet.run_for(2.0)  # up and talking
        calls = 0
        inner = fleet._vehicle_deadline

        def counted(v: Any, inner: Any = inner) -> float:
            nonlocal calls
            calls += 1
            return float(inner(v))

        events = 0
        fleet._vehicle_deadline = counted  # type: ignore[method-assign]
        handle = {vid: v.node.handle for vid, v in fleet.vehicles.items()}
        for vid, v in fleet.vehicles.items():

            def h(event: Any, now: float, f: Any = handle[vid]) -> Any:
                nonlocal events
                events += 1
                return f(event, now)

            v.node.handle = h  # type: ignore[method-assign]
        fleet.run_for(3.0)
        ratio[n] = calls / events
    assert ratio[24] <= 1.5 * ratio[3], ratio


def _renumbered(profile: Any, vid: int) -> Any:
    import msgspec

    return msgspec.structs.replace(profile, vehicle_id=vid)


def test_a_fleet_split_over_two_processes_is_one_swarm(fleet_profiles: dict) -> None:
    """ParallelFleet (the sim benchmark's 100 vehicles on 2 cores): six vehicles in two
    processes, every node hears all five others, across the split, and the parts
    exchange what they publish, once per window of the swarm's network latency."""
    from swarm_sim.parallel_fleet import ParallelFleet

    ids = (1, 7, 8, 10, 12, 2)
    with ParallelFleet(ids, fleet_profiles, parts=2) as fleet:
        assert len(fleet.workers) == 1  # the first part runs here
        fleet.run_for(3.0)
        peers = fleet.live_peers()
    assert peers == {v: sorted(set(ids) - {v}) for v in ids}
    assert fleet.exchanged > 0
    # at most one exchange per window of the network latency, not one per deadline
    assert 0 < fleet.steps <= 3.0 / fleet.latency_s + 1
    assert len(fleet.cpu_s) == 2


def test_a_split_fleet_skips_idle_windows_and_runs_the_same(fleet_profiles: dict) -> None:
    """A window starts when something is first due in either part (the sim
    bench's wall time is mostly the exchanges): fewer exchanges than back-to-back
    windows, and the same swarm, message for message, as with them."""
    from swarm_sim.parallel_fleet import ParallelFleet

    ids = (1, 7, 8, 10, 12, 2)
    runs = {}
    for skip in (False, True):
        with ParallelFleet(ids, fleet_profiles, parts=2, liveliness=True, skip_idle=skip) as f:
            f.run_for(4.0)
            runs[skip] = (f.steps, f.published(), f.heard_messages(), f.live_peers())
    (dense, *reference), (sparse, *skipping) = runs[False], runs[True]
    assert abs(dense - 4.0 / 0.010) <= 1
    assert sparse < dense / 2
    assert reference[0] and repr(skipping) == repr(reference)
