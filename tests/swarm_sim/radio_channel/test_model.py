"""The channel model: broadcast, airtime, collisions, deferral while receiving, loss, bit
errors, address filtering and the XTend's AT command mode."""

from __future__ import annotations

import pytest

from radio_gateway.core.xtend import RadioSettings
from swarm_sim.radio_channel.model import ChannelParams, Mode, RadioChannelModel

T = 1000.0
BANDADA = RadioSettings().registers()


def _model(n: int = 3, **params: object) -> RadioChannelModel:
    m = RadioChannelModel(n, ChannelParams(**params))  # type: ignore[arg-type]
    for i in range(n):
        m.preset(i, **BANDADA)
    return m


def _run(m: RadioChannelModel, until: float) -> list[tuple[int, bytes]]:
    out = []
    t = T
    while True:
        d = m.next_deadline()
        if d is None or d > until:
            out += m.on_timer(until)
            return out
        t = max(t, d)
        out += m.on_timer(t)


def test_a_packet_reaches_every_other_module_after_its_airtime() -> None:
    m = _model()
    m.from_host(0, b"hello", T)
    char = 10 / 230_400
    start = T + 5 * char + 3 * char  # serial bytes in, then the RO idle time
    end = start + 0.006 + 5 * 8 / 115_200
    assert m.on_timer(end + 0.0004) == []  # not before the end + latency
    got = _run(m, end + 0.01)
    assert sorted(got) == [(1, b"hello"), (2, b"hello")]
    assert m.counts["packets"] == 1 and m.counts["collisions"] == 0
    tx = m.air[0]
    assert tx.start == pytest.approx(start) and tx.end == pytest.approx(end)


def test_overlapping_packets_collide() -> None:
    m = _model()
    m.from_host(0, b"a" * 30, T)
    m.from_host(1, b"b" * 30, T + 0.001)  # within the preamble: nobody knew
    assert _run(m, T + 0.1) == []
    assert m.counts["collisions"] == 1 and m.counts["collided_packets"] == 2


def test_a_module_that_is_receiving_defers_its_packet() -> None:
    m = _model()
    m.from_host(0, b"a" * 30, T)
    m.from_host(1, b"b" * 30, T + 0.0075)  # after the preamble: it hears the channel busy
    got = _run(m, T + 0.1)
    assert sorted(got) == [(0, b"b" * 30), (1, b"a" * 30), (2, b"a" * 30), (2, b"b" * 30)]
    assert m.counts["deferred"] == 1 and m.counts["collisions"] == 0
    a, b = m.air
    assert b.start == pytest.approx(a.end)


def test_loss_and_bit_errors() -> None:
    m = _model(3, loss=0.5, seed=4)
    for k in range(200):
        m.from_host(0, bytes(20), T + 0.05 * k)
        _run(m, T + 0.05 * k + 0.04)
    lost = m.counts["lost"]
    assert 150 < lost < 250  # of 400 receptions
    m2 = _model(2, ber=0.01, seed=1)
    m2.from_host(0, bytes(100), T)
    ((_, data),) = _run(m2, T + 0.1)
    flipped = sum(bin(b).count("1") for b in data)
    assert 1 <= flipped <= 30 and m2.counts["corrupted"] == 1


def test_channel_id_and_rate_filter_and_separate_channels_do_not_interfere() -> None:
    m = _model(4)
    m.preset(1, HP=3)  # another hopping channel
    m.preset(2, ID=0x1234)  # another network id
    m.preset(3, BR=0)  # another RF rate
    m.from_host(0, b"x", T)
    m.from_host(1, b"y", T)  # simultaneous, but on channel 3: no collision
    assert _run(m, T + 0.1) == []
    assert m.counts["collisions"] == 0
    assert m.per_module[1]["filtered"] == 1 and m.per_module[2]["filtered"] == 2


def test_command_mode_needs_guard_times_and_answers_like_an_xtend() -> None:
    m = RadioChannelModel(2)  # factory settings: 9600 baud, 1 s guard times
    m.from_host(0, b"+++", T + 2.0)
    assert _run(m, T + 2.5) == []  # the guard time after has not passed
    assert _run(m, T + 3.2) == [(0, b"OK\r")]
    assert m.modules[0].mode is Mode.COMMAND
    m.from_host(0, b"ATBD\r", T + 3.3)
    m.from_host(0, b"ATBD 8,BR,PL 5,ZZ\r", T + 3.4)
    m.from_host(0, b"ATWR,CN\r", T + 3.5)
    got = b"".join(d for _, d in _run(m, T + 3.6))
    assert got == b"3\rOK\r1\rERROR\rERROR\rOK\rOK\r"
    assert m.modules[0].mode is Mode.DATA and m.modules[0].baud == 230_400
    m.power_cycle(0)
    assert m.modules[0].registers["BD"] == 8  # written to flash
    # without silence before, "+++" is just data
    m.from_host(1, b"xyz", T + 5.0)
    m.from_host(1, b"+++", T + 5.1)
    out = _run(m, T + 7.0)
    assert (0, b"xyz+++") in out or ((0, b"xyz") in out and (0, b"+++") in out)
    assert m.modules[1].mode is Mode.DATA


def test_unsaved_settings_are_lost_on_power_cycle_and_wrong_baud_garbles() -> None:
    m = RadioChannelModel(2)
    m.from_host(0, b"+++", T + 2.0)
    _run(m, T + 3.2)
    m.from_host(0, b"ATHP 5,CN\r", T + 3.3)
    _run(m, T + 3.4)
    assert m.modules[0].registers["HP"] == 5
    m.power_cycle(0)
    assert m.modules[0].registers["HP"] == 0
    m.from_host(0, b"+++", T + 6.0, host_baud=230_400)  # module still at 9600
    out = _run(m, T + 8.0)
    assert (0, b"OK\r") not in out and m.modules[0].mode is Mode.DATA
    assert out and out[0][1] != b"+++"  # what went out is garbage
    assert m.per_module[0]["baud_mismatch"] == 1


def test_datasheet_timing_adds_setup_and_the_longer_preamble() -> None:
    from swarm_sim.radio_channel.model import XTEND_DATASHEET

    m = RadioChannelModel(2, XTEND_DATASHEET)
    for i in range(2):
        m.preset(i, **BANDADA)
    m.from_host(0, b"x" * 40, T)
    _run(m, T + 0.1)
    tx = m.air[0]
    char = 10 / 230_400
    ready = T + 43 * char
    assert ready + 0.0008 <= tx.start <= ready + 0.001 + 1e-9
    assert tx.end - tx.start == pytest.approx(0.0065 + 40 * 8 / 115_200)


def test_a_module_setting_up_to_transmit_misses_a_packet_half_duplex() -> None:
    m = _model(3, tx_setup_s=0.002)
    m.from_host(0, b"a" * 30, T)
    # module 1's setup starts during module 0's preamble tail: it cannot hear 0 any more
    m.from_host(1, b"b" * 10, T + 0.0095)
    _run(m, T + 0.1)
    assert m.per_module[1]["missed_half_duplex"] >= 1


@pytest.mark.parametrize("capture", [0.0, 1.0])
def test_capture_keeps_the_earlier_of_two_overlapping_packets(capture: float) -> None:
    m = _model(3, capture=capture)
    m.from_host(0, b"a" * 30, T)
    m.from_host(1, b"b" * 30, T + 0.001)
    got = _run(m, T + 0.1)
    assert m.counts["collisions"] == 1 and m.counts["collisions_tdm"] == 1
    assert got == ([(2, b"a" * 30)] if capture else [])


def test_collisions_with_a_late_write_are_counted_apart() -> None:
    m = _model()
    m.from_host(0, b"a" * 30, T)
    m.from_host(1, b"b" * 30, T + 0.001, late=True)
    _run(m, T + 0.1)
    assert m.counts["collisions_late"] == 1 and m.counts["collisions_tdm"] == 0
    assert m.counts["late_writes"] == 1
