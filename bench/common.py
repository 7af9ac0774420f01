"""Helpers shared by benchmarks."""

from __future__ import annotations

import statistics
import time
from collections.abc import Callable


def time_us(fn: Callable[[], object], *, repeat: int = 7, number: int = 2000) -> float:
    """Median microseconds per call over `repeat` batches of `number` calls."""
    samples = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        for _ in range(number):
            fn()
        samples.append((time.perf_counter() - t0) / number * 1e6)
    return round(statistics.median(samples), 3)
