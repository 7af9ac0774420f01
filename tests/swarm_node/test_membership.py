from __future__ import annotations

import msgspec
from hypothesis import given
from hypothesis import strategies as st

from swarm_node.core.membership import PeerJoined, PeerLeft, SwarmMembership
from swarm_proto import FsmState, VehicleInfo, VehicleStatus, VehicleType


def status(
    vid: int, t: float, fleet: int = 0, fsm: FsmState = FsmState.GO_MISSION
) -> VehicleStatus:
    return VehicleStatus(vid, t, 37.0, -6.0, 100.0, 90.0, fleet_id=fleet, fsm_state=fsm)


def test_join_by_liveliness_and_leave_at_once() -> None:
    m = SwarmMembership(1)
    assert m.on_alive(2, True, 0.0) == [PeerJoined(2, "liveliness")]
    assert m.on_alive(2, True, 0.1) == []
    assert m.on_status(status(2, 0.2), 0.2) == []
    assert m.on_timer(100.0) == []  # a live token keeps it, telemetry or not
    assert m.on_alive(2, False, 100.0) == [PeerLeft(2, "liveliness")]
    assert m.live_ids() == []
    assert m.on_alive(2, True, 101.0) == [PeerJoined(2, "liveliness")]  # restarted: rejoins


def test_radio_peers_join_by_telemetry_and_go_stale() -> None:
    m = SwarmMembership(1, stale_after_s=2.0)
    assert m.on_status(status(5, 0.0), 0.0) == [PeerJoined(5, "telemetry")]
    assert m.next_deadline() == 2.0
    assert m.on_timer(1.9) == []
    m.on_status(status(5, 1.9), 1.9)
    assert m.on_timer(3.5) == []
    assert m.on_timer(4.0) == [PeerLeft(5, "stale")]
    assert m.next_deadline() is None


def test_a_peer_heard_only_by_its_info_gets_longer_to_go_stale() -> None:
    """A ground station behind the radio sends only its 1 Hz VehicleInfo, the lowest
    radio class: a second or two between updates must not make it leave and rejoin."""
    m = SwarmMembership(1, stale_after_s=2.0, info_stale_after_s=5.0)
    gcs = VehicleInfo(900, VehicleType.GCS, "GCS", "ground")
    assert m.on_info(gcs, 0.0) == [PeerJoined(900, "telemetry")]
    assert m.on_timer(3.0) == []
    m.on_info(gcs, 3.0)
    assert m.next_deadline() == 8.0
    assert m.on_timer(7.9) == []
    assert m.on_timer(8.0) == [PeerLeft(900, "stale")]
    # a vehicle: its status counts, and the short rule applies even when info also came
    m.on_info(VehicleInfo(5, VehicleType.COPTER, "quad", "Q1"), 10.0)
    m.on_status(status(5, 10.0), 10.0)
    assert m.on_timer(12.0) == [PeerLeft(5, "stale")]


def test_self_is_never_a_peer() -> None:
    m = SwarmMembership(1)
    assert m.on_alive(1, True, 0.0) == [] and m.on_status(status(1, 0.0), 0.0) == []
    assert m.live_ids() == []


def test_fleets_and_ground_stations() -> None:
    m = SwarmMembership(1)
    m.on_status(status(2, 0.0, fleet=3, fsm=FsmState.PLAN), 0.0)
    m.on_status(status(4, 0.0, fleet=3), 0.0)
    m.on_status(status(6, 0.0, fleet=1), 0.0)
    m.on_info(VehicleInfo(900, VehicleType.GCS, "GCS", "ground"), 0.0)
    assert [p.node_id for p in m.fleet(3)] == [2, 4]
    assert [p.node_id for p in m.vehicles()] == [2, 4, 6]
    assert m.peers[900].is_ground_station
    assert m.peers[2].fsm_state == FsmState.PLAN


def _talking(m: SwarmMembership, peers: tuple[int, ...], start: float, end: float) -> None:
    t = start
    while t <= end + 1e-9:
        for vid in peers:
            m.on_status(status(vid, t), t)
        t = round(t + 0.2, 6)


def test_every_telemetry_peer_silent_at_once_is_our_feed_not_theirs() -> None:
    """Behind the radio every peer comes through our gateway (5 Hz each): when all of
    them fall silent at once, our gateway (or the channel) stopped, not all of them (the
    --radio demo at load 10-20 lost its peers at launch and replanned three times). None
    goes stale before `feed_outage_s`; heard again, each gets a fresh `stale_after_s`."""
    m = SwarmMembership(1, stale_after_s=2.0)
    _talking(m, (2, 3, 4), 0.0, 1.0)
    assert m.on_timer(3.5) == [] and m.on_timer(5.9) == []
    assert m.next_deadline() == 1.0 + m.feed_outage_s  # held until then
    assert sorted(e.node_id for e in m.on_timer(6.0)) == [2, 3, 4]  # too long: they are gone
    # a 3 s gap (a gateway descheduled): nobody lost; 2 and 3 come back, 4 never does
    m = SwarmMembership(1, stale_after_s=2.0)
    _talking(m, (2, 3, 4), 0.0, 1.0)
    assert m.on_timer(4.0) == []
    _talking(m, (2, 3), 4.0, 5.8)  # 4 had its fresh 2 s from 4.0
    assert m.on_timer(5.8) == []
    _talking(m, (2, 3), 6.0, 6.0)
    assert m.on_timer(6.0) == [PeerLeft(4, "stale")]


def test_a_single_silent_peer_among_talking_ones_leaves_on_time() -> None:
    m = SwarmMembership(1, stale_after_s=2.0)
    _talking(m, (2, 3, 4), 0.0, 1.0)
    _talking(m, (2, 3), 1.2, 3.0)
    assert m.on_timer(2.9) == []
    assert m.on_timer(3.0) == [PeerLeft(4, "stale")]
    # one peer only: its silence is taken at its word, as before
    m = SwarmMembership(1, stale_after_s=2.0)
    _talking(m, (2,), 0.0, 1.0)
    assert m.on_timer(3.0) == [PeerLeft(2, "stale")]


def test_behind_the_radio_a_peer_gets_4_s_before_it_goes_stale() -> None:
    """A radio peer comes at 5 Hz as its gateway's prediction while the radio hears it;
    a gap here is the gateway's own: 4 s, not 2 s (`radio_stale_after_s`). On a LAN
    (no predictions) the 2 s stand."""
    for radio in (False, True):
        m = SwarmMembership(1, stale_after_s=2.0)
        for t in (0.0, 0.2):
            for vid in (2, 3):
                s = status(vid, t)
                if radio:
                    s = msgspec.structs.replace(s, position_error_m=0.1, predicted_s=0.2)
                m.on_status(s, t)
        _talking(m, (2,), 0.4, 3.0)  # 3 falls silent after 0.2 s; 2 keeps talking
        left = m.on_timer(3.0)
        assert left == ([] if radio else [PeerLeft(3, "stale")]), radio
        assert m.behind_radio is radio
        if radio:
            _talking(m, (2,), 3.2, 4.2)
            assert m.on_timer(4.2) == [PeerLeft(3, "stale")]


_Heard = list[tuple[str, int, int]]  # (what: status / info / alive / dead, peer, time step)


@given(
    st.lists(
        st.tuples(
            st.sampled_from(["status", "info", "alive", "dead"]),
            st.integers(2, 6),
            st.integers(0, 3),
        ),
        max_size=40,
    ),
    st.lists(st.tuples(st.sampled_from(["status", "info"]), st.integers(1, 7)), max_size=12),
)
def test_a_run_heard_again_at_once_is_the_same_as_one_by_one(before: _Heard, run: list) -> None:
    """`heard_again` (a node hearing a batch) takes a run of statuses and infos
    from known peers heard again as `on_status` / `on_info` take each, and stops,
    untouched, at the first message that would take another path."""

    def message(what: str, vid: int, t: float) -> VehicleStatus | VehicleInfo:
        if what == "status":
            return status(vid, t)
        return VehicleInfo(vid, VehicleType.GCS if vid == 6 else VehicleType.COPTER, "m", "u")

    def state(m: SwarmMembership) -> str:
        return repr((m.peers, list(m._watch), list(m._watch_info), m._latest_s))

    one, bulk = SwarmMembership(1), SwarmMembership(1)
    now = 0.0
    for what, vid, dt in before:
        now += dt * 0.1
        for m in (one, bulk):
            if what in ("alive", "dead"):
                m.on_alive(vid, what == "alive", now)
            else:
                msg = message(what, vid, now)
                m.on_status(msg, now) if isinstance(msg, VehicleStatus) else m.on_info(msg, now)
    now += 0.1
    msgs = [message(what, vid, now) for what, vid in run]
    taken = bulk.heard_again(msgs, now)
    for msg in msgs[:taken]:
        got = one.on_status(msg, now) if isinstance(msg, VehicleStatus) else one.on_info(msg, now)
        assert got == []  # nothing but what is kept of the peer changed
    assert state(bulk) == state(one)
    if taken < len(msgs):
        nxt = msgs[taken]
        if isinstance(nxt, VehicleStatus):
            one.on_status(nxt, now)
            bulk.on_status(nxt, now)
        else:
            one.on_info(nxt, now)
            bulk.on_info(nxt, now)
        assert state(bulk) == state(one)
