"""Simulated time as one autopilot has run it, and the actions due at given times (the
boot sequence, the fence loader). Time comes in with each input; nothing here reads a
clock."""

from __future__ import annotations

import bisect
import math
from collections.abc import Callable


class Timeline:
    def __init__(self, now: float) -> None:
        self.boot_time = now
        self.t = now  # the time physics and events have been run to
        self.event_t = now  # the time of the event being run
        self.now = now  # the time of the message or timer being handled
        self._events: list[tuple[float, Callable[[], None]]] = []
        self.next_at = math.inf  # when the earliest action is due (read on every deadline)

    def boot_ms(self, now: float) -> int:
        """Milliseconds since boot, as MAVLink's time_boot_ms (wraps at 2**32)."""
        return max(0, int((now - self.boot_time) * 1000)) & 0xFFFFFFFF

    def schedule(self, at: float, action: Callable[[], None]) -> None:
        """Run `action` at `at` (after the actions already due then)."""
        bisect.insort(self._events, (at, action), key=lambda ev: ev[0])
        self.next_at = self._events[0][0]

    def run_next(self) -> None:
        """Run the earliest action; `event_t` is its time while it runs (an action that
        reschedules itself counts from there)."""
        at, action = self._events.pop(0)
        self.next_at = self._events[0][0] if self._events else math.inf
        self.event_t = at
        action()
