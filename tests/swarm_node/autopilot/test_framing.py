"""MavFramer: real ArduPilot bytes in any chunking decode exactly as pymavlink reads
them; garbage, corruption and truncation cost only the damaged packets, never raise."""

from __future__ import annotations

import random
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st
from pymavlink import mavutil
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from swarm_node.core.autopilot.framing import BadFrame, MavEncoder, MavFramer


def sitl_packets(shared_dir: Path, name: str, limit: int = 3000) -> list[bytes]:
    conn = mavutil.mavlink_connection(str(shared_dir / "data" / "ardupilot-sitl" / name))
    out: list[bytes] = []
    try:
        while len(out) < limit:
            msg = conn.recv_match()
            if msg is None:
                break
            out.append(bytes(msg.get_msgbuf()))
    finally:
        conn.close()
    return out


def decoded(items: list) -> list[bytes]:
    return [bytes(m.get_msgbuf()) for m in items if not isinstance(m, BadFrame)]


def test_real_sitl_bytes_in_random_chunks(shared_dir: Path) -> None:
    packets = sitl_packets(shared_dir, "arduplane-quadplane-sortie.tlog")
    stream = b"".join(packets)
    rng = random.Random(3)
    framer = MavFramer()
    out: list = []
    i = 0
    while i < len(stream):
        n = rng.randint(1, 300)
        out += framer.feed(stream[i : i + n])
        i += n
    assert decoded(out) == packets
    assert framer.garbage_bytes == 0


def _packets(n: int) -> list[bytes]:
    enc = MavEncoder(1, 1)
    msgs = [
        mavlink.MAVLink_heartbeat_message(2, 3, 81, 4, 3, 3),
        mavlink.MAVLink_global_position_int_message(
            1000, 374112000, -59889000, 40000, 30000, 1, 2, 3, 9000
        ),
        mavlink.MAVLink_statustext_message(6, b"Mission: 3 WP"),
        mavlink.MAVLink_system_time_message(1_795_315_038_996_864, 252_159),
    ]
    return [enc.encode(msgs[i % len(msgs)]) for i in range(n)]


@given(
    garbage=st.lists(st.binary(min_size=1, max_size=40), min_size=1, max_size=8),
    positions=st.lists(st.integers(0, 11), min_size=1, max_size=8),
    chunk=st.integers(1, 64),
)
def test_garbage_between_packets_costs_nothing_else(
    garbage: list[bytes], positions: list[int], chunk: int
) -> None:
    packets = _packets(12)
    stream = bytearray()
    inserted = dict(zip(positions, garbage, strict=False))
    for i, p in enumerate(packets):
        if i in inserted:
            stream += inserted[i]
        stream += p
    stream += bytes(300)  # later traffic: lets a false start in the garbage run out
    framer = MavFramer()
    out: list = []
    for i in range(0, len(stream), chunk):
        out += framer.feed(bytes(stream[i : i + chunk]))
    assert decoded(out) == packets
    assert all(b.n_bytes > 0 for b in out if isinstance(b, BadFrame))


@given(
    which=st.integers(0, 11),
    offset=st.integers(0, 200),
    flip=st.integers(1, 255),
    truncate=st.booleans(),
)
def test_a_corrupted_or_truncated_packet_loses_only_itself(
    which: int, offset: int, flip: int, truncate: bool
) -> None:
    packets = _packets(12)
    bad = bytearray(packets[which])
    if truncate:
        bad = bad[: max(1, offset % len(bad))]
    else:
        bad[offset % len(bad)] ^= flip
    stream = b"".join(packets[:which]) + bytes(bad) + b"".join(packets[which + 1 :]) + bytes(300)
    out = MavFramer().feed(stream)
    good = decoded(out)
    others = packets[:which] + packets[which + 1 :]
    assert [p for p in good if p != packets[which]] == others
    assert any(isinstance(b, BadFrame) for b in out)


def test_pymavlink_parser_loses_more_than_ours_after_a_bad_length() -> None:
    """Why MavFramer exists: a corrupted length byte makes pymavlink's own parser
    swallow the next packets."""
    packets = _packets(12)
    bad = bytearray(packets[0])
    bad[1] = 250  # length byte
    stream = bytes(bad) + b"".join(packets[1:]) + bytes(300)
    ours = decoded(MavFramer().feed(stream))
    parser = mavlink.MAVLink(None)
    parser.robust_parsing = True
    theirs = [m for m in (parser.parse_buffer(stream) or []) if m.get_type() != "BAD_DATA"]
    assert ours == packets[1:]
    assert len(theirs) < len(ours)


@pytest.mark.parametrize("data", [b"", b"\xfd", b"\xfe\x00", b"\x00" * 1000, bytes(range(256)) * 4])
def test_odd_inputs_never_raise(data: bytes) -> None:
    MavFramer().feed(data)


@given(st.binary(max_size=2000))
def test_random_bytes_never_raise(data: bytes) -> None:
    framer = MavFramer()
    out = framer.feed(data) + framer.feed(bytes(300))
    assert sum(b.n_bytes for b in out if isinstance(b, BadFrame)) <= len(data) + 300


def test_encoder_numbers_packets_and_checks_its_ids() -> None:
    enc = MavEncoder(255, 191)
    a = enc.encode(mavlink.MAVLink_heartbeat_message(18, 8, 0, 0, 4, 3))
    b = enc.encode(mavlink.MAVLink_heartbeat_message(18, 8, 0, 0, 4, 3))
    assert a[4] + 1 == b[4]  # seq
    assert (a[5], a[6]) == (255, 191)
    with pytest.raises(ValueError):
        MavEncoder(0, 1)
