"""MAVLink integer fields from floats, clamped so that packing a message never fails."""

from __future__ import annotations

import math


def i32(value: float) -> int:
    if not math.isfinite(value):
        return 0
    return max(-(2**31), min(2**31 - 1, round(value)))


def i16(value: float) -> int:
    return max(-32768, min(32767, round(value)))


def deg_e7(value: float) -> int:
    """Degrees as MAVLink's degE7."""
    return i32(value * 1e7)
