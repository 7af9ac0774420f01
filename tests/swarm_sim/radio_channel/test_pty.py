"""The emulated channel on pseudo-terminals, driven with pyserial like real XTends."""

from __future__ import annotations

import time
from pathlib import Path

import pytest
import serial

from radio_gateway.core.xtend import RadioSettings
from swarm_sim.radio_channel.model import ChannelParams
from swarm_sim.radio_channel.pty import PtyRadioChannel


def _read(ser: serial.Serial, n: int, timeout: float = 3.0) -> bytes:
    buf = b""
    deadline = time.monotonic() + timeout
    while len(buf) < n and time.monotonic() < deadline:
        buf += ser.read(n - len(buf))
    return buf


def test_one_write_is_broadcast_to_every_other_port(tmp_path: Path) -> None:
    regs = RadioSettings().registers()
    with PtyRadioChannel(3, ChannelParams(), registers=regs, link_dir=tmp_path) as ch:
        assert [p.name for p in ch.links] == ["radio0", "radio1", "radio2"]
        ports = [serial.Serial(str(p), 230_400, timeout=0.1) for p in ch.links]
        try:
            ports[0].write(b"broadcast\x00")
            assert _read(ports[1], 10) == b"broadcast\x00"
            assert _read(ports[2], 10) == b"broadcast\x00"
            assert ports[0].read(10) == b""  # no echo to the sender
            stats = ch.stats()
            assert stats["channel"]["packets"] == 1 and stats["modules"][1]["rx"] == 1
        finally:
            for p in ports:
                p.close()
    assert not any(p.exists() for p in ch.links)


def test_a_host_at_the_wrong_serial_rate_gets_garbage() -> None:
    regs = RadioSettings().registers()  # modules at 230,400 baud
    with PtyRadioChannel(2, ChannelParams(), registers=regs) as ch:
        good = serial.Serial(ch.ports[0], 230_400, timeout=0.1)
        slow = serial.Serial(ch.ports[1], 9_600, timeout=0.1)
        try:
            good.write(b"hello\x00")
            got = _read(slow, 6)
            assert got and got != b"hello\x00"
            slow.write(b"hi\x00")
            got = _read(good, 3)
            assert got and got != b"hi\x00"
            assert ch.stats()["modules"][1]["baud_mismatch"] == 1
        finally:
            good.close()
            slow.close()


@pytest.mark.timing  # real time on pseudo-terminals: run alone (make test's second part)
def test_what_a_descheduled_emulator_reads_late_is_counted_apart() -> None:
    """Two hosts write 30 ms apart (no overlap on air) while the emulator's process is
    stopped (a loaded machine): it reads both at once, their packets overlap, and the
    collision is counted as late (`collisions_late`), not as a TDM fault."""
    import os
    import signal

    from swarm_sim.radio_channel.pty import ChannelProcess

    regs = RadioSettings().registers()
    with ChannelProcess(3, ChannelParams(), registers=regs) as ch:
        ports = [serial.Serial(p, 230_400, timeout=0.1) for p in ch.ports]
        try:
            ports[0].write(b"settle\x00")
            assert _read(ports[1], 7) == b"settle\x00"
            ch.reset_stats()
            os.kill(ch._proc.pid, signal.SIGSTOP)
            try:
                ports[0].write(b"a" * 40 + b"\x00")
                time.sleep(0.03)
                ports[1].write(b"b" * 40 + b"\x00")
                time.sleep(0.05)
            finally:
                os.kill(ch._proc.pid, signal.SIGCONT)
            time.sleep(0.3)
            stats = ch.stats()
        finally:
            for p in ports:
                p.close()
    c = stats["channel"]
    assert c.get("collisions", 0) == 1 and c.get("collisions_late", 0) == 1
    assert c.get("collisions_tdm", 0) == 0 and stats["late_reads"] >= 1
