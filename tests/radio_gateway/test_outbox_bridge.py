"""What goes into a slot (priorities, latest value, fragments, acknowledgements) and what
crosses between the LAN and the air (no loops, no duplicates)."""

from __future__ import annotations

import msgspec
import pytest
from hypothesis import given
from hypothesis import strategies as st

from radio_gateway.core import frame as fr
from radio_gateway.core.bridge import Bridge, OwnStatus
from radio_gateway.core.outbox import Outbox, OutMessage, ack_mask
from radio_gateway.core.reassembly import Reassembly
from radio_gateway.core.telemetry import PeerPredictor, encode_turn
from swarm_proto import (
    Ack,
    AckRef,
    Alert,
    AlertCode,
    Command,
    CommandKind,
    Geometry,
    NoFlyZone,
    Severity,
    VehicleInfo,
    VehicleType,
    lan,
    radio,
)
from swarm_proto.messages import RadioStats
from swarm_proto.topics import RadioClass, key_of

from .helpers import status

T = 1.75e9


def _out(key: str, klass: RadioClass, n: int = 10, **kw: object) -> OutMessage:
    return OutMessage(key, bytes([1, int(klass) + 1]) + bytes(n), int(klass), **kw)  # type: ignore[arg-type]


def test_classes_go_in_order_commands_first_info_last() -> None:
    ob = Outbox()
    ob.submit(_out("info", RadioClass.INFO, latest_only=True), T)
    ob.submit(_out("status", RadioClass.STATUS, latest_only=True), T)
    ob.submit(_out("alert", RadioClass.ALERT), T)
    ob.submit(_out("cmd", RadioClass.CONTROL, acked=True), T)
    recs = ob.fill(1000, T, frozenset({2}))
    kinds = [(type(r).__name__, r.data[1] if not isinstance(r, fr.Ack) else None) for r in recs]  # type: ignore[union-attr]
    assert kinds == [("Frag", 1), ("Msg", 2), ("Msg", 3), ("Msg", 4)]
    # a slot with room for one small record carries the most urgent
    ob2 = Outbox()
    ob2.submit(_out("status", RadioClass.STATUS, latest_only=True), T)
    ob2.submit(_out("alert", RadioClass.ALERT), T)
    assert [r.data[1] for r in ob2.fill(14, T, frozenset())] == [2]  # type: ignore[union-attr]


def test_latest_value_only_and_rate_limit() -> None:
    ob = Outbox()
    for i in range(5):
        ob.submit(OutMessage("s", bytes([1, 1, i]), 2, latest_only=True, max_rate_hz=5.0), T)
    recs = ob.fill(1000, T, frozenset())
    assert recs == [fr.Msg(bytes([1, 1, 4]))]
    assert ob.counts["replaced"] == 4
    ob.submit(OutMessage("s", bytes([1, 1, 9]), 2, latest_only=True, max_rate_hz=5.0), T + 0.05)
    assert ob.fill(1000, T + 0.05, frozenset()) == []  # too soon for 5 Hz
    assert ob.fill(1000, T + 0.2, frozenset()) == [fr.Msg(bytes([1, 1, 9]))]


def test_a_starved_class_moves_up() -> None:
    ob = Outbox(starve_s=1.0)
    ob.submit(_out("info", RadioClass.INFO, n=30, latest_only=True), T)
    for k in range(4):
        t = T + 0.7 * k
        ob.submit(_out("status", RadioClass.STATUS, n=30, latest_only=True), t)
        got = [r.data[1] for r in ob.fill(40, t, frozenset())]  # type: ignore[union-attr]
        if 4 in got:
            assert k >= 2  # info waited > 1 s: now level with status and older
            return
    raise AssertionError("info was starved")


def _deliver(
    ob: Outbox, budget: int, now: float, rx: dict[int, Reassembly], lost: set[int]
) -> list[bytes]:
    recs = ob.fill(budget, now, frozenset(rx))
    out = []
    for node, ra in rx.items():
        if node in lost:
            continue
        for r in recs:
            if isinstance(r, fr.Frag):
                whole = ra.on_frag(1, r, now)
                if whole is not None:
                    out.append(whole)
        for a in ra.take_acks():
            ob.on_ack(node, a)
    return out


@given(st.binary(min_size=1, max_size=2000), st.integers(30, 400))
def test_fragments_reassemble_whatever_the_slot_size(data: bytes, budget: int) -> None:
    ob = Outbox()
    ob.submit(OutMessage("m", data, 0, acked=True), T)
    rx = {2: Reassembly(), 3: Reassembly()}
    got: list[bytes] = []
    for i in range(200):
        got += _deliver(ob, budget, T + 0.2 * i, rx, set())
        if not ob.chunked:
            break
    assert got == [data, data]
    assert ob.counts["retransmitted"] == 0


def test_missing_chunks_are_resent_until_everyone_has_them_then_given_up() -> None:
    ob = Outbox(ack_timeout_s=0.3, max_rounds=3)
    data = bytes(range(200))
    ob.submit(OutMessage("m", data, 0, acked=True), T)
    rx = {2: Reassembly(), 3: Reassembly()}
    got = _deliver(ob, 100, T, rx, lost={3})  # node 3 misses the first slot
    for i in range(1, 20):
        got += _deliver(ob, 100, T + 0.2 * i, rx, set())
    assert sorted(got) == [data, data]
    assert ob.counts["retransmitted"] >= 1 and not ob.chunked
    # a receiver that never answers: give up after max_rounds, counted
    ob2 = Outbox(ack_timeout_s=0.3, max_rounds=3)
    ob2.submit(OutMessage("m", data, 0, acked=True), T)
    for i in range(40):
        ob2.fill(100, T + 0.2 * i, frozenset({9}))
    assert ob2.counts["failed"] == 1 and not ob2.chunked
    # ...or when that member leaves
    ob3 = Outbox()
    ob3.submit(OutMessage("m", data, 0, acked=True), T)
    ob3.fill(1000, T, frozenset({9}))
    ob3.forget(9)
    ob3.fill(1000, T + 1, frozenset())
    assert not ob3.chunked and ob3.counts["failed"] == 0


def test_reassembly_is_robust() -> None:
    ra = Reassembly(max_partials=2)
    f0 = fr.Frag(1, 3, 0, bytes(16), True)
    assert ra.on_frag(5, f0, T) is None
    assert ra.take_acks() == [fr.Ack(5, 1, ack_mask({0}, 3))]
    assert ra.on_frag(5, fr.Frag(1, 4, 1, bytes(16), True), T) is None  # inconsistent total
    assert ra.counts["inconsistent"] == 1
    for seq in (2, 3, 4):
        ra.on_frag(5, fr.Frag(seq, 2, 0, bytes(16), False), T + seq)
    assert ra.counts["evicted"] >= 1 and len([k for k in ra.partials if k[0] == 5]) <= 2
    whole = ra.on_frag(6, fr.Frag(7, 1, 0, b"abc", True), T)
    assert whole == b"abc"
    assert ra.on_frag(6, fr.Frag(7, 1, 0, b"abc", True), T + 1) is None  # never twice
    assert fr.Ack(6, 7) in ra.take_acks()
    ra.expire(T + 100)
    assert not ra.partials and not ra.done


# --------------------------------------------------------------------------- bridge


def _bridge(node_id: int = 1) -> Bridge:
    return Bridge("default", node_id, frozenset({node_id}))


def _lan(msg: object) -> tuple[str, bytes]:
    return key_of("default", msg), lan.encode(msg)  # type: ignore[arg-type]


def test_only_locally_originated_on_air_topics_go_on_air() -> None:
    b = _bridge(1)
    own, other = status(1, T), status(2, T)
    out = b.from_lan(*_lan(own), T)
    assert out is not None and out.data == radio.encode(own) and out.latest_only and out.klass == 2
    assert b.from_lan(*_lan(other), T) is None  # vehicle 2's status is not ours to send
    stats = RadioStats(node_id=1, time_unix_s=T)
    assert b.from_lan(*_lan(stats), T) is None  # LAN-only topic
    zone = NoFlyZone(zone_id=4, geometry=Geometry.circle(37.4, -5.9, 100.0))
    assert b.from_lan(*_lan(zone), T) is not None  # no originator (issuer 0): forwarded
    gcs_zone = NoFlyZone(zone_id=5, geometry=Geometry.circle(37.4, -5.9, 100.0), issuer_id=900)
    assert b.from_lan(*_lan(gcs_zone), T) is None  # a ground station's: its own gateway sends it
    assert Bridge("default", 900, frozenset({900})).from_lan(*_lan(gcs_zone), T) is not None
    assert (
        Bridge("default", 1, frozenset({1}), forward_unattributed=False).from_lan(*_lan(zone), T)
        is None
    )
    assert b.from_lan(*_lan(own), T + 0.1) is None  # unchanged: not sent twice
    key, payload = _lan(own)
    assert b.from_lan(key.replace("/1/", "/3/"), payload, T) is None  # key and content disagree
    assert b.from_lan(key, b"\xc1garbage", T) is None
    assert b.counts["lan_wrong_key"] == 1 and b.counts["lan_undecodable"] == 1


def test_what_the_lan_already_has_is_not_republished_from_the_air() -> None:
    b = _bridge(2)
    s = status(1, T)
    b.from_lan(*_lan(s), T)  # heard over the LAN first
    assert b.from_air(radio.encode(s), T + 0.1) is None
    assert b.counts["air_duplicate"] == 1
    new = status(1, T + 0.2)
    pub = b.from_air(radio.encode(new), T + 0.3)
    assert pub is not None and pub.key == key_of("default", new)
    assert lan.decode(pub.payload, type(new)) == radio.quantized(new)
    assert b.from_air(radio.encode(new), T + 0.35) is None  # relayed copy: once only


def test_nothing_heard_on_air_goes_back_on_air() -> None:
    b = _bridge(1)
    cmd = Command(issuer_id=900, seq=3, kind=CommandKind.RTL)
    pub = b.from_air(radio.encode(cmd), T)
    assert pub is not None
    # a local node republishes it (or another gateway's copy comes back): not forwarded
    assert b.from_lan(pub.key, pub.payload, T + 0.01) is None
    b1 = Bridge("default", 1, frozenset({900}))
    b1.from_lan(*_lan(cmd), T, from_gateway=True)
    assert b1.from_lan(*_lan(cmd), T + 0.1) is None
    assert b1.counts["lan_echo_of_air"] == 1


def test_gateways_on_one_lan_publish_once() -> None:
    low, high = _bridge(1), _bridge(2)
    for b, other in ((low, 2), (high, 1)):
        b.from_lan(*_lan(RadioStats(node_id=other, time_unix_s=T)), T)
    assert low.designated(T) and not high.designated(T)
    alert = Alert(vehicle_id=7, time_unix_s=T, severity=Severity.WARNING, code=AlertCode.GPS_LOSS)
    data = radio.encode(alert)
    assert low.from_air(data, T) is not None
    assert high.from_air(data, T) is None  # held
    high.from_lan(*_lan(radio.quantized(alert)), T + 0.05, from_gateway=True)  # low's copy
    assert high.due(T + 1.0) == []
    assert high.counts["air_published_elsewhere"] == 1
    # the low gateway missed one: the other publishes it after the hold-off
    info = VehicleInfo(vehicle_id=7, vehicle_type=VehicleType.PLANE, model="x", user_id="y")
    assert high.from_air(radio.encode(info), T + 2) is None
    assert [p.key for p in high.due(T + 2.5)] == [key_of("default", info)]
    # a gateway not heard for a while is no longer relied on
    assert high.designated(T + 10.0)


def test_air_garbage_is_counted() -> None:
    b = _bridge()
    assert b.from_air(b"\x01\xee\x00", T) is None
    assert b.from_air(radio.encode(RadioStats(node_id=3, time_unix_s=T)), T) is None
    assert b.counts["air_undecodable"] == 1 and b.counts["air_not_on_air_topic"] == 1


def test_latest_keep_sends_the_newest_values_together_oldest_first() -> None:
    """latest_keep=2: one frame every other cycle carries both statuses of the period."""
    ob = Outbox(latest_keep=2)
    for i in range(3):
        ob.submit(OutMessage("s", bytes([1, 0x64, i]) + bytes(37), 2, True, False, 5.0), 0.1 * i)
    assert ob.pending() == 2 and ob.counts["replaced"] == 1
    recs = ob.fill(200, 0.3, frozenset())
    assert [r.data[2] for r in recs if isinstance(r, fr.Msg)] == [1, 2]
    assert ob.pending() == 0
    ob.submit(OutMessage("s", bytes([1, 0x64, 9]) + bytes(37), 2, True, False, 5.0), 0.31)
    recs = ob.fill(200, 0.35, frozenset())  # under the rate limit since the last send
    assert recs == [] and ob.pending() == 1


# --------------------------------------------------------------------------- send on error


def _soe_bridge(node: int) -> Bridge:
    return Bridge("default", node, frozenset({node}), predictor=PeerPredictor())


def test_send_on_error_hands_the_own_status_to_the_node_and_predicts_peers() -> None:
    b = _soe_bridge(1)
    own = status(1, T)
    out = b.from_lan(*_lan(own), T)
    assert isinstance(out, OwnStatus) and out.status == own  # the node decides when
    moving = msgspec.structs.replace(status(2, T), vel_north_m_s=10.0)
    heard = radio.encode(moving) + encode_turn(0.0)
    pub = b.from_air(heard, T + 0.1)
    assert pub is not None and pub.message.predicted_s == 0.0  # as heard, at once
    assert b.predictions(T + 0.2) == []  # every 200 ms after that
    (pred,) = b.predictions(T + 0.31)
    s = pred.message
    assert s.vehicle_id == 2 and s.time_unix_s == T + 0.31
    assert s.predicted_s == pytest.approx(0.31) and s.position_error_m > 0
    assert (s.lat_deg - moving.lat_deg) * 111_132 == pytest.approx(3.1, abs=0.05)
    assert pred.key == key_of("default", s)
    # our own status relayed back to us by a peer is not republished
    assert b.from_air(radio.encode(status(1, T + 1)), T + 1.1) is None
    assert b.counts["air_own_status"] == 1


def test_a_prediction_never_goes_on_air_and_a_lan_peer_is_not_predicted() -> None:
    b = _soe_bridge(1)
    pred = msgspec.structs.replace(status(1, T), predicted_s=0.4, position_error_m=1.0)
    assert b.from_lan(*_lan(pred), T) is None
    assert b.counts["lan_predicted"] == 1
    b.from_air(radio.encode(status(3, T)), T)
    assert 3 in (b.predictor.peers if b.predictor else {})
    b.from_lan(*_lan(status(3, T + 0.1)), T + 0.1)  # vehicle 3 is on our LAN as well
    assert b.predictions(T + 1.0) == []
    b.from_air(radio.encode(status(3, T + 0.5)), T + 0.5)
    assert b.predictions(T + 1.5) == []  # still on the LAN: its own statuses suffice


def test_only_the_designated_gateway_publishes_predictions() -> None:
    low, high = _soe_bridge(1), _soe_bridge(2)
    for b, other in ((low, 2), (high, 1)):
        b.from_lan(*_lan(RadioStats(node_id=other, time_unix_s=T)), T)
    for b in (low, high):
        b.from_air(radio.encode(status(7, T)), T)
    assert len(low.predictions(T + 0.3)) == 1
    assert high.predictions(T + 0.3) == []  # it still predicts, to take over
    assert len(high.predictions(T + 10.0 + 0.3)) == 0  # (silent for 10 s: dropped)


def test_an_ack_is_acknowledged_on_air_by_its_issuer_only() -> None:
    b = _bridge(5)
    out = b.from_lan(*_lan(Ack(5, 900, AckRef.COMMAND, 3, True)), T)
    assert isinstance(out, OutMessage) and out.acked and out.ack_by == 900
    ob = Outbox()
    ob.submit(out, T)
    (frag,) = ob.fill(200, T, frozenset({1, 2, 900}))
    assert isinstance(frag, fr.Frag) and frag.ack_by == 900
    mine, other = Reassembly(node_id=900), Reassembly(node_id=1)
    assert mine.on_frag(5, frag, T) == out.data and other.on_frag(5, frag, T) == out.data
    assert mine.take_acks() and not other.take_acks()  # everyone delivers, one acks
    ob.on_ack(900, fr.Ack(5, frag.seq))
    assert ob.fill(200, T + 5, frozenset({1, 2, 900})) == [] and ob.pending() == 0
