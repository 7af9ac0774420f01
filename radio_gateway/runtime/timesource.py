"""Time sources for the TDM: GPS time from MAVLink SYSTEM_TIME or NMEA, or a clock.

Each gives `now()` (UNIX seconds) and its current `stratum` (0: GPS-derived, 3: a
free-running clock). A GPS source that loses its fix falls back to the system clock at
stratum 3, so the node keeps time from its peers' frames instead.
"""

from __future__ import annotations

import contextlib
import logging
import threading
import time
from typing import Protocol

from swarm_proto.clock import Clock, SystemClock

from ..core.gpstime import GpsTimeEstimator, parse_nmea_time
from ..core.timesync import FREE, GPS

log = logging.getLogger(__name__)


class TimeSource(Protocol):
    def now(self) -> float: ...

    @property
    def stratum(self) -> int: ...

    def close(self) -> None: ...


class ClockTimeSource:
    """A Clock as the time source: the simulation's shared clock (GPS time in a
    simulation), or a system clock disciplined by chrony with GPS + PPS (stratum 0)."""

    def __init__(self, clock: Clock | None = None, stratum: int = GPS) -> None:
        self.clock = clock or SystemClock()
        self._stratum = stratum

    def now(self) -> float:
        return self.clock.now()

    @property
    def stratum(self) -> int:
        return self._stratum

    def close(self) -> None:
        pass


class _EstimatedSource:
    def __init__(self) -> None:
        self.estimator = GpsTimeEstimator()
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def _add(self, gps_unix_s: float) -> None:
        with self._lock:
            self.estimator.add(gps_unix_s, time.monotonic())

    def now(self) -> float:
        with self._lock:
            t = self.estimator.now(time.monotonic())
        return time.time() if t is None else t

    @property
    def stratum(self) -> int:
        with self._lock:
            return GPS if self.estimator.valid(time.monotonic()) else FREE

    def _start(self, target: object, name: str) -> None:
        self._thread = threading.Thread(target=target, name=name, daemon=True)  # type: ignore[arg-type]
        self._thread.start()

    def close(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=2)


class MavlinkTimeSource(_EstimatedSource):
    """GPS time from the autopilot's SYSTEM_TIME (time_unix_usec, 0 without GPS time)."""

    def __init__(self, url: str) -> None:
        super().__init__()
        from pymavlink import mavutil

        self.conn = mavutil.mavlink_connection(url, source_system=255, source_component=191)
        self._start(self._run, "mavlink-time")

    def _run(self) -> None:
        while not self._stop.is_set():
            try:
                msg = self.conn.recv_match(type="SYSTEM_TIME", blocking=True, timeout=0.5)
            except (OSError, ValueError):
                log.warning("MAVLink time source read failed", exc_info=True)
                self._stop.wait(0.5)
                continue
            if msg is not None and msg.time_unix_usec > 0:
                self._add(msg.time_unix_usec / 1e6)

    def close(self) -> None:
        super().close()
        with contextlib.suppress(Exception):
            self.conn.close()


class NmeaTimeSource(_EstimatedSource):
    """GPS time from NMEA RMC/ZDA sentences on a serial port."""

    def __init__(self, port: str, baud: int = 9600) -> None:
        super().__init__()
        import serial

        self.ser = serial.Serial(port, baud, timeout=0.5)
        self._start(self._run, "nmea-time")

    def _run(self) -> None:
        while not self._stop.is_set():
            try:
                line = self.ser.readline()
            except (OSError, ValueError):
                if self._stop.is_set():
                    return
                log.warning("NMEA time source read failed", exc_info=True)
                self._stop.wait(0.5)
                continue
            t = parse_nmea_time(line.decode("ascii", "replace"))
            if t is not None:
                self._add(t)

    def close(self) -> None:
        super().close()
        with contextlib.suppress(Exception):
            self.ser.close()


def time_source_from_spec(spec: str, clock: Clock | None = None) -> TimeSource:
    """ "clock" (BANDADA_CLOCK or the system clock, stratum 0: a simulation, or a system
    clock disciplined by GPS+PPS), "clock-free" (same clock, stratum 3: follow peers),
    "mavlink:<pymavlink url>", "nmea:<port>[:<baud>]"."""
    kind, _, rest = spec.partition(":")
    if kind == "clock":
        return ClockTimeSource(clock, GPS)
    if kind == "clock-free":
        return ClockTimeSource(clock, FREE)
    if kind == "mavlink" and rest:
        return MavlinkTimeSource(rest)
    if kind == "nmea" and rest:
        port, _, baud = rest.partition(":")
        return NmeaTimeSource(port, int(baud) if baud else 9600)
    raise ValueError(
        f"bad time source {spec!r}: clock, clock-free, mavlink:URL or nmea:PORT[:BAUD]"
    )
