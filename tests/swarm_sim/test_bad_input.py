"""Bad input on the MAVLink link: garbage bytes, truncated and corrupted frames, messages
for another system, malformed field values. Counted and dropped, never a crash, never a
changed state; the vehicle keeps answering good messages."""

from __future__ import annotations

import math
import random
import socket
import time

from hypothesis import given, settings
from hypothesis import strategies as st
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from swarm_proto.clock import ScaledClock
from swarm_sim.core import SITL_HOME, VehicleEndpoint
from swarm_sim.runtime import VehicleServer, VehicleSpec
from tests.conftest import examples, free_tcp_port
from tests.swarm_sim.conftest import make_pilot

T0 = 1_700_000_000.0


class _Sink:
    def write(self, data: bytes) -> None:
        pass


ENC = mavlink.MAVLink(_Sink(), srcSystem=255, srcComponent=190)
ENC1 = mavlink.MAVLink(_Sink(), srcSystem=255, srcComponent=190)
ENC1.WIRE_PROTOCOL_VERSION = "1.0"


def frame(msg: object, v1: bool = False) -> bytes:
    return msg.pack(ENC1 if v1 else ENC, force_mavlink1=v1)  # type: ignore[attr-defined]


def set_mode(custom: int, target: int = 1) -> bytes:
    return frame(mavlink.MAVLink_command_long_message(target, 1, 176, 0, 1, custom, 0, 0, 0, 0, 0))


def ready_endpoint() -> tuple[VehicleEndpoint, float]:
    ep = VehicleEndpoint.create("copter", home=SITL_HOME, now=T0)
    now = T0
    while not ep.autopilot.ekf_position:
        now = ep.next_deadline() or now + 0.1
        ep.on_timer(now)
    return ep, now


def acks_in(ep: VehicleEndpoint, data: bytes) -> list[tuple[int, int]]:
    parser = mavlink.MAVLink(_Sink(), srcSystem=0, srcComponent=0)
    return [
        (m.command, m.result)
        for m in parser.parse_buffer(data) or []
        if m.get_type() == "COMMAND_ACK"
    ]


def test_garbage_truncated_and_corrupted_frames_are_counted() -> None:
    ep, now = ready_endpoint()
    rng = random.Random(3)
    garbage = bytes(rng.randrange(256) for _ in range(5000))
    ep.receive(garbage, now)
    good = set_mode(4)
    corrupted = bytearray(good)
    corrupted[12] ^= 0x55
    ep.receive(bytes(corrupted), now)
    ep.receive(good[:15], now)  # truncated: the rest never comes
    ep.receive(b"\x00" * 300, now)  # ... instead, zeros that complete and fail the frame
    out = ep.receive(good, now)
    assert acks_in(ep, out) == [(176, 0)]  # the good frame still gets through
    assert ep.autopilot.mode_name == "GUIDED"
    c = ep.counters
    assert c["bad_crc"] + c["bad_data"] + c["unknown_message"] >= 2
    assert c["rx_messages"] >= 1


def test_corrupted_frame_changes_nothing() -> None:
    ep, now = ready_endpoint()
    good = bytearray(set_mode(4))
    good[-1] ^= 0xFF  # CRC
    out = ep.receive(bytes(good), now)
    assert acks_in(ep, out) == [] and ep.autopilot.mode_name == "STABILIZE"
    assert ep.counters["bad_crc"] + ep.counters["bad_data"] == 1


def test_split_frames_and_mavlink1() -> None:
    ep, now = ready_endpoint()
    data = set_mode(5)
    out = b"".join(ep.receive(bytes([b]), now) for b in data)  # a byte at a time
    assert acks_in(ep, out) == [(176, 0)]
    v1 = frame(mavlink.MAVLink_command_long_message(1, 1, 176, 0, 1, 4, 0, 0, 0, 0, 0), v1=True)
    assert v1[0] == 0xFE
    assert acks_in(ep, ep.receive(v1, now)) == [(176, 0)]
    assert ep.autopilot.mode_name == "GUIDED"


def test_messages_for_another_system_or_component_are_ignored() -> None:
    ep, now = ready_endpoint()
    out = ep.receive(set_mode(4, target=7), now)
    assert acks_in(ep, out) == [] and ep.autopilot.counters["foreign_target"] == 1
    other_comp = frame(mavlink.MAVLink_command_long_message(1, 154, 176, 0, 1, 4, 0, 0, 0, 0, 0))
    assert acks_in(ep, ep.receive(other_comp, now)) == []
    assert ep.autopilot.counters["foreign_component"] == 1
    assert acks_in(ep, ep.receive(set_mode(4, target=0), now)) == [(176, 0)]  # broadcast


def test_own_echo_is_ignored() -> None:
    ep, now = ready_endpoint()
    echo_enc = mavlink.MAVLink(_Sink(), srcSystem=1, srcComponent=1)
    msg = mavlink.MAVLink_command_long_message(1, 1, 176, 0, 1, 4, 0, 0, 0, 0, 0)
    assert acks_in(ep, ep.receive(msg.pack(echo_enc), now)) == []
    assert ep.autopilot.counters["own_echo"] == 1


def test_nan_and_out_of_range_fields() -> None:
    p = make_pilot("copter")
    p.wait_ready()
    nan, inf = math.nan, math.inf
    p.c.mav.command_long_send(1, 1, 176, 0, nan, nan, 0, 0, 0, 0, 0)
    p.c.mav.command_long_send(1, 1, 400, 0, inf, 0, 0, 0, 0, 0, 0)
    p.c.mav.command_long_send(1, 1, 511, 0, 33, nan, 0, 0, 0, 0, 0)
    p.c.mav.command_int_send(1, 1, 6, 192, 0, 0, nan, 1, nan, nan, 2**31 - 1, -(2**31), nan)
    p.c.mav.set_position_target_global_int_send(0, 1, 1, 6, 0, 0, 0, nan, inf, 0, 0, 0, 0, 0, 0, 0)
    p.c.mav.mission_count_send(1, 1, 2, 0)
    p.c.mav.mission_item_int_send(1, 1, 0, 6, 16, 0, 1, nan, 0, 0, 0, 0, 0, nan, 0)
    p.c.mav.param_set_send(1, 1, b"SIM_WIND_SPD", nan, 9)
    p.c.mav.mission_count_send(1, 1, 1, 7)  # unknown mission type
    p.h.run_for(2)
    ap = p.ap
    assert not ap.armed and ap.mode_name == "STABILIZE"
    assert ap.params["SIM_WIND_SPD"][0] == 0.0
    assert ap.streams.interval(33) == 0.25
    assert all(math.isfinite(v) for v in (ap.body.n, ap.body.e, ap.body.alt))
    assert ap.counters["bad_field"] >= 1 and ap.counters["bad_mission_type"] == 1
    assert p.set_mode("GUIDED") == 0  # still answering


@settings(max_examples=examples(60), deadline=None)
@given(st.binary(min_size=0, max_size=600), st.integers(0, 2**32 - 1))
def test_random_bytes_never_raise(data: bytes, seed: int) -> None:
    ep = VehicleEndpoint.create("vtol", home=SITL_HOME, now=T0)
    rng = random.Random(seed)
    # random bytes around real frames
    pieces = [data, set_mode(15), bytes(rng.randrange(256) for _ in range(rng.randrange(64)))]
    for i, piece in enumerate(pieces):
        ep.receive(piece, T0 + i)
    ep.on_timer(T0 + 10)


FLOATS = st.floats(allow_nan=True, allow_infinity=True, width=32)


@settings(max_examples=examples(150), deadline=None)
@given(
    st.sampled_from(
        [
            176,
            400,
            22,
            84,
            192,
            178,
            186,
            20,
            21,
            17,
            300,
            208,
            179,
            224,
            207,
            3000,
            511,
            510,
            512,
            520,
            410,
            205,
            1000,
            241,
            99,
            0,
            65535,
        ]
    ),
    st.lists(FLOATS, min_size=7, max_size=7),
    st.integers(0, 40),
    st.booleans(),
)
def test_random_commands_never_raise(
    command: int, params: list[float], frame_id: int, as_int: bool
) -> None:
    p = make_pilot("plane" if command % 2 else "copter")
    p.wait_ready()
    if as_int:
        x = int(params[4]) if math.isfinite(params[4]) and abs(params[4]) < 2**31 else 0
        y = int(params[5]) if math.isfinite(params[5]) and abs(params[5]) < 2**31 else 0
        p.c.mav.command_int_send(1, 1, frame_id, command, 0, 0, *params[:4], x, y, params[6])
    else:
        p.c.mav.command_long_send(1, 1, command, 0, *params)
    p.h.run_for(3)
    b = p.ap.body
    assert all(math.isfinite(v) for v in (b.n, b.e, b.alt, b.vn, b.ve, b.vd))
    assert p.ap.home_set and math.isfinite(p.ap.home_alt)


def test_garbage_over_tcp_does_not_stop_the_server() -> None:
    port = free_tcp_port()
    server = VehicleServer([VehicleSpec("rover", port=port)], ScaledClock(20.0))
    server.start_thread()
    try:
        with socket.create_connection(("127.0.0.1", port), timeout=5) as s:
            s.sendall(bytes(random.Random(1).randrange(256) for _ in range(20000)))
            s.sendall(set_mode(15)[:9])
            counters = server.endpoints[0].counters
            deadline = time.monotonic() + 10  # read before closing: unread data makes an RST
            while counters["rx_bytes"] < 20009 and time.monotonic() < deadline:
                time.sleep(0.05)
        with socket.create_connection(("127.0.0.1", port), timeout=5) as s:
            s.sendall(set_mode(4))  # HOLD
            deadline = time.monotonic() + 10
            got = b""
            while time.monotonic() < deadline and b"\xfd" not in got:
                got += s.recv(4096)
            assert got  # still serving
        assert server.endpoints[0].counters["rx_bytes"] >= 20009
    finally:
        server.close()
