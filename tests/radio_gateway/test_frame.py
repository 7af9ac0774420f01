"""Framing (COBS + CRC-16) and authentication: round trips, every corruption caught,
forged, replayed and bit-flipped frames rejected, and a fuzzed decoder that never does
anything but count drops."""

from __future__ import annotations

import binascii
import contextlib

import pytest
from hypothesis import given
from hypothesis import strategies as st

from radio_gateway.core import auth, cobs
from radio_gateway.core import frame as fr
from radio_gateway.core.node import Deliver, NodeConfig, RadioNode, Transmit
from radio_gateway.core.outbox import OutMessage

from .helpers import KEY, TDM, TIMING, status_out

T0 = 1.75e9
CYCLE = int(T0 / 0.2)


# --------------------------------------------------------------------------- COBS


@given(st.binary(max_size=1200))
def test_cobs_round_trip_has_no_zeros_and_bounded_overhead(data: bytes) -> None:
    enc = cobs.encode(data)
    assert 0 not in enc
    assert len(enc) + 1 <= cobs.max_encoded_len(len(data))
    assert cobs.decode(enc) == data


@given(st.binary(max_size=300))
def test_cobs_decoder_raises_only_cobs_error(data: bytes) -> None:
    with contextlib.suppress(cobs.CobsError):
        cobs.decode(data)


def test_deframer_splits_resyncs_and_drops_stale_partials() -> None:
    d = cobs.Deframer(max_frame=10, gap_s=0.02)
    assert d.feed(b"ab\x00cd", 0.0) == [b"ab"]
    assert d.feed(b"e\x00\x00", 0.001) == [b"cde"]  # empty frames between delimiters ignored
    assert d.feed(b"xy", 0.002) == []
    assert d.feed(b"z\x00", 0.5) == [b"z"]  # "xy" was cut off by a long gap
    assert d.truncated == 1
    assert d.feed(b"0123456789ABC\x00ok\x00", 0.6) == [b"ok"]
    assert d.oversized == 1


# --------------------------------------------------------------------------- frames

records = st.one_of(
    st.builds(fr.Msg, st.binary(min_size=1, max_size=60)),
    st.builds(fr.Relay, st.binary(min_size=1, max_size=60)),
    st.builds(
        lambda seq, total, first, n, acked, by: fr.Frag(
            seq, total, min(first, total - 1), bytes(16 * n), acked, by if acked else 0
        ),
        st.integers(0, 0xFFFF),
        st.integers(20, 255),
        st.integers(0, 200),
        st.integers(1, 3),
        st.booleans(),
        st.sampled_from([0, 1, 900, 65534]),  # acknowledged by one node only (an Ack)
    ).filter(lambda f: f.chunks.stop <= f.total),
    st.builds(fr.Ack, st.integers(1, 65534), st.integers(0, 0xFFFF), st.binary(max_size=8)),
    st.builds(
        fr.Change, st.booleans(), st.integers(1, 65534), st.integers(CYCLE - 100, CYCLE + 100)
    ),
    st.builds(
        fr.LevelChange,
        st.integers(1, 65534),
        st.integers(0, 3),
        st.integers(CYCLE - 100, CYCLE + 100),
    ),
)


@st.composite
def frames(draw: st.DrawFn) -> fr.Frame:
    n = draw(st.integers(0, 20))
    return fr.Frame(
        src=draw(st.integers(1, 65534)),
        cycle=draw(st.integers(CYCLE - 5, CYCLE + 5)),
        table_hash=draw(st.integers(0, 0xFFFF)),
        n_members=n,
        heard=draw(st.binary(min_size=fr.heard_bytes(n), max_size=fr.heard_bytes(n))),
        join=draw(st.booleans()),
        stratum=draw(st.integers(0, 3)),
        records=tuple(draw(st.lists(records, max_size=6))),
        level=draw(st.integers(0, 3)),
    )


@given(frames())
def test_frames_round_trip(f: fr.Frame) -> None:
    wire = fr.encode(f, KEY)
    assert wire.endswith(b"\x00") and wire.count(0) == 1
    # the bound slots are budgeted with; exact when COBS has no zero to spare a byte on
    assert len(wire) <= fr.max_wire_size(f)
    assert len(wire) >= fr.max_wire_size(f) - (len(wire) // 254)
    assert fr.decode(wire[:-1], KEY, CYCLE) == f


def test_a_long_frame_full_of_zeros_fits_its_budget() -> None:
    """Found by hypothesis: past 254 bytes COBS spares a byte when there are zeros, so
    the budget is a bound, not the size."""
    frag = fr.Frag(0, 20, 0, bytes(48), False)
    f = fr.Frame(
        src=1,
        cycle=CYCLE,
        table_hash=0,
        n_members=0,
        heard=b"",
        stratum=0,
        records=(fr.Msg(bytes(20)), frag, frag, frag, frag),
    )
    wire = fr.encode(f, KEY)
    assert len(wire) == fr.max_wire_size(f) - 1
    assert fr.decode(wire[:-1], KEY, CYCLE) == f


@given(frames(), st.data())
def test_every_single_bit_flip_is_caught(f: fr.Frame, data: st.DataObject) -> None:
    raw = bytearray(fr.encode(f, KEY)[:-1])
    i = data.draw(st.integers(0, len(raw) * 8 - 1))
    raw[i // 8] ^= 1 << (i % 8)
    with pytest.raises(fr.FrameError) as e:
        fr.decode(bytes(raw), KEY, CYCLE)
    assert e.value.reason in ("cobs", "crc", "short")


def _with_crc(body: bytes) -> bytes:
    """A frame whose CRC is right for `body` (what a forger or a lucky error produces)."""
    return cobs.encode(body + binascii.crc_hqx(body, 0xFFFF).to_bytes(2, "little"))


def test_a_tampered_frame_with_a_valid_crc_fails_the_tag() -> None:
    """Would pass if the MAC were skipped: the CRC is correct, only the tag catches it."""
    f = fr.Frame(src=7, cycle=CYCLE, table_hash=1, n_members=0, records=(fr.Msg(b"\x01\x05go"),))
    data = cobs.decode(fr.encode(f, KEY)[:-1])
    body, tag = bytearray(data[: -fr.TRAILER_BYTES]), data[-fr.TRAILER_BYTES : -fr.CRC_BYTES]
    body[-1] ^= 0x01  # change the message
    with pytest.raises(fr.FrameError) as e:
        fr.decode(_with_crc(bytes(body) + tag), KEY, CYCLE)
    assert e.value.reason == "mac"
    with pytest.raises(fr.FrameError) as e:
        fr.decode(fr.encode(f, bytes(32))[:-1], KEY, CYCLE)  # another swarm's key
    assert e.value.reason == "mac"


def test_the_tag_binds_the_whole_cycle_counter() -> None:
    f = fr.Frame(src=7, cycle=CYCLE, table_hash=1, n_members=0)
    wire = fr.encode(f, KEY)[:-1]
    assert fr.decode(wire, KEY, CYCLE + 30_000).cycle == CYCLE  # nearest match: fine
    with pytest.raises(fr.FrameError, match="mac"):
        fr.decode(wire, KEY, CYCLE + 65_536)  # the same 16 bits, 3.6 hours later


def test_auth_overhead_is_at_most_8_bytes() -> None:
    assert auth.AUTH_OVERHEAD_BYTES == auth.TAG_BYTES + auth.COUNTER_BYTES <= 8


def test_replay_guard() -> None:
    g = auth.ReplayGuard(window_cycles=2)
    assert g.check(5, 100, 100) is None
    assert g.check(5, 100, 100) == "replay"
    assert g.check(5, 99, 100) == "replay"
    assert g.check(5, 101, 100) is None
    assert g.check(6, 90, 100) == "stale"
    assert g.check(6, 103, 100) == "stale"


def test_key_files() -> None:
    k = bytes(range(32))
    assert auth.parse_key(k.hex().encode() + b"\n") == k
    assert auth.parse_key(k) == k
    with pytest.raises(auth.SwarmKeyError):
        auth.parse_key(b"too short")


# --------------------------------------------------------------------------- through a node


def _pair() -> tuple[RadioNode, RadioNode]:
    a = RadioNode(NodeConfig(1, timing=TIMING, tdm=TDM, initial_members=(1, 2)), KEY, T0)
    b = RadioNode(NodeConfig(2, timing=TIMING, tdm=TDM, initial_members=(1, 2)), KEY, T0)
    return a, b


def _first_frame(a: RadioNode, t: float = T0) -> tuple[bytes, float]:
    a.submit(status_out(1, t), t)
    while True:
        for act in a.on_timer(t):
            if isinstance(act, Transmit) and not act.join:
                return act.data, act.at
        t = max(t, a.next_deadline())


def test_a_node_rejects_forged_replayed_and_bit_flipped_frames() -> None:
    a, b = _pair()
    wire, at = _first_frame(a)
    t = at + 0.02
    b.on_timer(t)
    good = b.handle_bytes(wire, t)
    assert [type(x) for x in good] == [Deliver]
    # replayed: the same frame again, now and a cycle later
    assert b.handle_bytes(wire, t + 0.001) == []
    assert b.handle_bytes(wire, t + 0.2) == []
    assert b.counts["drop_replay"] == 2
    # forged: right format, wrong key
    evil = RadioNode(NodeConfig(1, timing=TIMING, tdm=TDM, initial_members=(1, 2)), bytes(32), T0)
    forged, at2 = _first_frame(evil, T0 + 0.4)
    assert b.handle_bytes(forged, at2 + 0.02) == []
    assert b.counts["drop_mac"] == 1
    # bit-flipped: the next genuine frame with one bit changed
    a.submit(status_out(1, T0 + 0.8), T0 + 0.8)
    nxt, at3 = _first_frame(a, T0 + 0.8)
    flipped = bytearray(nxt)
    flipped[10] ^= 0x10
    assert b.handle_bytes(bytes(flipped), at3 + 0.02) == []
    assert b.counts["drop_crc"] + b.counts["drop_cobs"] == 1
    assert [type(x) for x in b.handle_bytes(nxt, at3 + 0.02)] == [Deliver]  # genuine still fine
    # our own frames coming back are not news
    assert a.handle_bytes(nxt, at3 + 0.02) == []
    assert a.counts["drop_own"] == 1


def test_a_stale_frame_is_rejected_even_with_a_valid_tag() -> None:
    a, b = _pair()
    wire, at = _first_frame(a)
    later = at + 10.0  # recorded, played back 10 s later
    b.on_timer(later)
    assert b.handle_bytes(wire, later) == []
    assert b.counts["drop_stale"] == 1


@given(st.lists(st.binary(max_size=120), max_size=8))
def test_fuzzed_bytes_are_only_ever_counted_drops(chunks: list[bytes]) -> None:
    _, b = _pair()
    out = []
    for i, c in enumerate(chunks):
        out += b.handle_bytes(c + b"\x00", T0 + 0.001 * i)
    assert out == []
    assert b.counts["rx_frames"] == 0
    assert b.membership.members == (1, 2) or b.membership.members == ()


@given(st.data())
def test_fuzzed_authentic_frames_never_crash_a_node(data: st.DataObject) -> None:
    """Garbage a peer with the key could send (a bug, not an attacker): counted, no crash."""
    _, b = _pair()
    b.on_timer(T0)
    body = bytearray(data.draw(st.binary(min_size=fr.HEADER_BYTES, max_size=80)))
    body[0] = (fr.PROTOCOL_VERSION << 5) | (body[0] & 0x1F)
    body[1:3] = (3).to_bytes(2, "little")
    body[3:5] = (CYCLE & 0xFFFF).to_bytes(2, "little")
    body += auth.tag(KEY, CYCLE, bytes(body))
    acts = b.handle_bytes(_with_crc(bytes(body)) + b"\x00", T0 + 0.01)  # must not raise
    assert all(isinstance(x, Deliver) for x in acts)
    dropped = sum(v for k, v in b.counts.items() if k.startswith("drop_"))
    assert dropped + b.counts["rx_frames"] == 1


def test_refused_messages_are_counted() -> None:
    a, _ = _pair()
    a.submit(OutMessage("x", b""), T0)
    a.submit(OutMessage("y", bytes(5000)), T0)
    assert a.counts["tx_refused"] == 2


def test_a_level_above_3_or_a_frag_acked_by_node_0_is_malformed() -> None:
    body = fr.encode_body(fr.Frame(src=5, cycle=CYCLE, table_hash=1, n_members=0))
    bad_level = body + bytes((fr.RecordType.LEVEL, 5)) + bytes((1, 0, 0, 0, 4))
    with pytest.raises(fr.FrameError, match="level"):
        fr.parse_body(bad_level, CYCLE)
    frag = bytes((0, 0, 1, 0, 0, 0)) + bytes(16)  # seq 0, 1 chunk, first 0, node 0
    bad_by = body + bytes((fr.RecordType.FRAG_ACKED_BY, len(frag))) + frag
    with pytest.raises(fr.FrameError, match="node 0"):
        fr.parse_body(bad_by, CYCLE)
    with pytest.raises(ValueError, match="level"):
        fr.encode_body(fr.Frame(src=5, cycle=CYCLE, table_hash=1, n_members=0, level=4))
