"""mavcodec packs and unpacks the plain MAVLink 2 frames exactly as pymavlink does (the
same bytes, the same message objects), and leaves everything else to pymavlink."""

from __future__ import annotations

import random
import struct
from typing import Any

import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from swarm_node.core.autopilot import mavcodec
from swarm_node.core.autopilot.framing import MavEncoder, MavFramer
from swarm_sim.core import SITL_HOME, VehicleEndpoint

_RANGES = {
    "B": (0, 255),
    "b": (-128, 127),
    "H": (0, 65535),
    "h": (-32768, 32767),
    "I": (0, 2**32 - 1),
    "i": (-(2**31), 2**31 - 1),
    "Q": (0, 2**64 - 1),
    "q": (-(2**63), 2**63 - 1),
}


def _random_message(cls: Any, rng: random.Random) -> Any:
    codes = [c for c in cls.unpacker.format.lstrip("<") if not c.isdigit()]
    values = {}
    for name, code in zip(cls.ordered_fieldnames, codes, strict=True):
        if code in "fd":
            # a float32 that survives the round trip; zeros too (MAVLink 2 trims them)
            values[name] = rng.choice(
                [0.0, struct.unpack("<f", struct.pack("<f", rng.uniform(-1e4, 1e4)))[0]]
            )
        else:
            lo, hi = _RANGES[code]
            values[name] = rng.choice([0, lo, hi, rng.randint(lo, hi)])
    return cls(**values)


def _same(a: Any, b: Any) -> None:
    assert type(a) is type(b)
    da, db = dict(vars(a)), dict(vars(b))
    assert vars(da.pop("_header")) == vars(db.pop("_header"))
    assert repr(sorted(da.items())) == repr(sorted(db.items()))  # NaN fields compare by repr


def test_every_plain_message_packs_and_unpacks_as_pymavlink_does() -> None:
    rng = random.Random(20)
    enc = mavlink.MAVLink(None, srcSystem=7, srcComponent=1)
    parser = mavlink.MAVLink(None)
    layouts = mavcodec._LAYOUTS
    assert len(layouts) > 100 and mavlink.MAVLINK_MSG_ID_GLOBAL_POSITION_INT in layouts
    for msg_id in sorted(layouts):
        cls = mavlink.mavlink_map[msg_id]
        for _ in range(5):
            msg = _random_message(cls, rng)
            enc.seq = rng.randrange(256)
            ours = mavcodec.pack(msg, enc.seq, 7, 1)
            theirs = bytes(msg.pack(enc))
            assert ours == theirs, cls.msgname
            buf = bytearray(b"\x00junk" + theirs)
            _same(mavcodec.unpack(buf, 5, len(theirs)), parser.decode(bytearray(theirs)))


def test_a_simulated_vehicles_stream_decodes_to_the_same_messages() -> None:
    ep = VehicleEndpoint.create("copter", home=SITL_HOME, now=1.8e9, sysid=3)
    data = b"".join(ep.on_timer(1.8e9 + 0.05 * k) for k in range(400))
    reference = mavlink.MAVLink(None)
    reference.robust_parsing = True
    expected = reference.parse_buffer(data) or []
    got = MavFramer().feed(data)
    assert len(got) == len(expected) > 300
    for a, b in zip(got, expected, strict=True):
        _same(a, b)


def test_what_is_not_a_plain_frame_is_left_to_pymavlink() -> None:
    enc = mavlink.MAVLink(None, srcSystem=7, srcComponent=1)
    text = mavlink.MAVLink_statustext_message(6, b"hello")  # a string
    assert mavcodec.pack(text, 0, 7, 1) is None
    frame = bytearray(text.pack(enc))
    assert mavcodec.unpack(frame, 0, len(frame)) is None
    hb = mavlink.MAVLink_heartbeat_message(2, 3, 0, 0, 4, 3)
    frame = bytearray(hb.pack(enc))
    bad_crc = frame[:-1] + bytes([frame[-1] ^ 0xFF])
    assert mavcodec.unpack(bad_crc, 0, len(bad_crc)) is None
    signed = bytearray(frame)
    signed[2] = 0x01
    assert mavcodec.unpack(signed, 0, len(signed)) is None
    v1 = bytearray(hb.pack(enc, force_mavlink1=True))
    assert mavcodec.unpack(v1, 0, len(v1)) is None
    # the framer still reports a corrupted frame, as before
    out = MavFramer().feed(bytes(bad_crc) + bytes(frame))
    assert [type(x).__name__ for x in out] == ["BadFrame", "MAVLink_heartbeat_message"]


def test_a_field_out_of_range_raises_as_pymavlink_does() -> None:
    hb = mavlink.MAVLink_heartbeat_message(2, 3, 0, 0, 999, 3)  # system_status: uint8
    with pytest.raises(struct.error):
        mavcodec.pack(hb, 0, 7, 1)
    with pytest.raises(struct.error):
        hb.pack(mavlink.MAVLink(None, srcSystem=7, srcComponent=1))


def test_the_encoder_numbers_its_frames() -> None:
    encoder = MavEncoder(250, 190)
    hb = mavlink.MAVLink_heartbeat_message(6, 8, 0, 0, 4, 3)
    frames = [encoder.encode(hb) for _ in range(300)]
    assert [f[4] for f in frames[:3]] == [0, 1, 2] and frames[256][4] == 0
    msgs = MavFramer().feed(b"".join(frames))
    assert len(msgs) == 300 and msgs[0].get_srcSystem() == 250
