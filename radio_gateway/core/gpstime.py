"""GPS time from messages that arrive late by a variable delay (pure).

A GPS time message (MAVLink SYSTEM_TIME, an NMEA RMC or ZDA sentence) says what time it
was when it was produced; it reaches us some milliseconds later. `GpsTimeEstimator`
keeps the largest (GPS time - local receive time) over a window: the sample that waited
least, which is the best estimate of the offset between GPS time and the local
monotonic clock. (A PPS-disciplined system clock, e.g. chrony with a PPS refclock, is
better still: use the system clock as a stratum-0 source then.)
"""

from __future__ import annotations

import calendar
from collections import deque
from dataclasses import dataclass, field


def _nmea_checksum_ok(line: str) -> bool:
    if not line.startswith("$") or "*" not in line:
        return False
    body, _, cs = line[1:].partition("*")
    x = 0
    for ch in body:
        x ^= ord(ch)
    try:
        return int(cs[:2], 16) == x
    except ValueError:
        return False


def _hms(text: str) -> tuple[int, int, float]:
    return int(text[0:2]), int(text[2:4]), float(text[4:])


def parse_nmea_time(line: str) -> float | None:
    """UNIX time of a valid RMC or ZDA sentence (any talker), else None."""
    line = line.strip()
    if not _nmea_checksum_ok(line):
        return None
    fields = line[1:].split("*")[0].split(",")
    kind = fields[0][2:]
    try:
        if kind == "RMC" and len(fields) >= 10 and fields[2] == "A":
            h, m, s = _hms(fields[1])
            d = fields[9]
            yy = int(d[4:6])
            day, month, year = int(d[0:2]), int(d[2:4]), (2000 if yy < 80 else 1900) + yy
        elif kind == "ZDA" and len(fields) >= 5 and fields[1]:
            h, m, s = _hms(fields[1])
            day, month, year = int(fields[2]), int(fields[3]), int(fields[4])
        else:
            return None
        whole = calendar.timegm((year, month, day, h, m, 0, 0, 0, 0))
    except (ValueError, IndexError, OverflowError):
        return None
    return whole + s


@dataclass
class GpsTimeEstimator:
    window: int = 16
    max_age_s: float = 5.0  # without a sample for this long, there is no estimate
    _offsets: deque[float] = field(default_factory=deque)
    _last_local: float | None = None

    def add(self, gps_unix_s: float, local_s: float) -> None:
        """A GPS time received at local (monotonic) time `local_s`."""
        self._offsets.append(gps_unix_s - local_s)
        while len(self._offsets) > self.window:
            self._offsets.popleft()
        self._last_local = local_s

    def valid(self, local_s: float) -> bool:
        return self._last_local is not None and local_s - self._last_local <= self.max_age_s

    def now(self, local_s: float) -> float | None:
        if not self.valid(local_s):
            return None
        return local_s + max(self._offsets)
