"""GPS time sources: NMEA parsing, the least-delay estimator, and MAVLink SYSTEM_TIME
from real pymavlink bytes over UDP on 127.0.0.1."""

from __future__ import annotations

import socket
import time
from collections.abc import Callable

import pytest
from hypothesis import given
from hypothesis import strategies as st
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from radio_gateway.core.gpstime import GpsTimeEstimator, parse_nmea_time
from radio_gateway.core.timesync import FREE, GPS
from radio_gateway.runtime.timesource import MavlinkTimeSource, time_source_from_spec


def _nmea(body: str) -> str:
    cs = 0
    for ch in body:
        cs ^= ord(ch)
    return f"${body}*{cs:02X}"


def test_nmea_rmc_and_zda() -> None:
    rmc = _nmea("GPRMC,123519.50,A,4807.038,N,01131.000,E,022.4,084.4,230394,003.1,W")
    assert parse_nmea_time(rmc) == pytest.approx(764426119.5)  # 1994-03-23 12:35:19.5 UTC
    zda = _nmea("GNZDA,201530.00,04,07,2025,00,00")
    assert parse_nmea_time(zda) == pytest.approx(1751660130.0)
    void = _nmea("GPRMC,123519,V,,,,,,,230394,,")
    assert parse_nmea_time(void) is None  # no fix
    assert parse_nmea_time(rmc[:-2] + "00") is None  # bad checksum
    assert parse_nmea_time("$GPGGA,123519,4807.038,N*47") is None


@given(st.text(max_size=120))
def test_nmea_parser_never_raises(line: str) -> None:
    parse_nmea_time(line)


def test_estimator_keeps_the_least_delayed_sample() -> None:
    e = GpsTimeEstimator(window=8, max_age_s=5.0)
    assert e.now(0.0) is None
    offset = 1.75e9
    for i, delay in enumerate([0.040, 0.012, 0.030, 0.025]):
        e.add(offset + i, i + delay)  # each message reaches us `delay` late
    assert e.now(10.0) is None  # stale: last sample at ~3 s, now 10 s
    assert e.now(4.0) == pytest.approx(offset + 4.0 - 0.012)


def _assert_gps_time(now: Callable[[], float], gps: float, start: float) -> None:
    """The source's time is the GPS time sent (`gps` at monotonic `start`), not this
    machine's clock: never ahead of it (each sample is stamped before it is received),
    behind by no more than its least-delayed sample's delay. That delay is a few ms;
    0.5 s is what a loaded 2-core host may add by holding the reader thread (and this
    one) through a scheduler slice or more."""
    before = gps + (time.monotonic() - start)
    got = now()
    after = gps + (time.monotonic() - start)
    assert before - 0.5 <= got <= after + 1e-3, (before, got, after)


def test_mavlink_system_time_is_a_gps_time_source() -> None:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    src = MavlinkTimeSource(f"udpin:127.0.0.1:{port}")
    try:
        assert src.stratum == FREE  # no SYSTEM_TIME yet: the system clock, stratum 3
        mav = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
        gps = 2.0e9  # a GPS time far from this machine's clock
        start = time.monotonic()
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as out:
            for _ in range(40):
                now = gps + (time.monotonic() - start)
                msg = mavlink.MAVLink_system_time_message(int(now * 1e6), 1000)
                out.sendto(msg.pack(mav), ("127.0.0.1", port))
                time.sleep(0.02)
        time.sleep(0.1)
        assert src.stratum == GPS
        _assert_gps_time(src.now, gps, start)
    finally:
        src.close()


def test_time_source_specs() -> None:
    assert time_source_from_spec("clock").stratum == GPS
    assert time_source_from_spec("clock-free").stratum == FREE
    with pytest.raises(ValueError, match="bad time source"):
        time_source_from_spec("sundial")


def test_nmea_time_source_reads_a_serial_port() -> None:
    """NmeaTimeSource on a real pseudo-terminal through pyserial: RMC and ZDA sentences of
    a GPS time far from this machine's clock, with noise and corrupt sentences between."""
    import os
    from datetime import UTC, datetime

    from radio_gateway.runtime.timesource import NmeaTimeSource

    master, slave = os.openpty()
    src = NmeaTimeSource(os.ttyname(slave), 9600)
    try:
        assert src.stratum == FREE
        gps = 2.0e9
        start = time.monotonic()
        for i in range(30):
            t = datetime.fromtimestamp(gps + (time.monotonic() - start), UTC)
            hms = t.strftime("%H%M%S.") + f"{t.microsecond // 10_000:02d}"
            if i % 2:
                line = _nmea(f"GNZDA,{hms},{t:%d},{t:%m},{t:%Y},00,00")
            else:
                line = _nmea(f"GPRMC,{hms},A,3724.672,N,00559.335,W,0.1,0.0,{t:%d%m%y},,")
            noise = b"$GPGSV,garbage*00\r\n\xff\xfe\r\n" if i % 5 == 0 else b""
            os.write(master, noise + line.encode() + b"\r\n")
            time.sleep(0.02)
        time.sleep(0.1)
        assert src.stratum == GPS
        _assert_gps_time(src.now, gps, start)  # sentences carry centiseconds: behind, never ahead
    finally:
        src.close()
        os.close(master)
        os.close(slave)
