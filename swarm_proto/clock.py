"""Injected time. Cores never read a clock: they are handed `now`. Shells hold a Clock.

- `SystemClock`: real time (an aircraft, a lab).
- `ScaledClock`: simulated time running `speedup` times faster than the wall clock.
  Every process of one simulation builds the same ScaledClock from the same spec
  string (passed in the BANDADA_CLOCK environment variable), so they all share one
  simulated time without talking to each other.
- `ManualClock`: tests and single-process fast-time harnesses; time moves only when
  told (`advance`, `set`, or `sleep`, which jumps instead of waiting).
- `SteadyClock`: what a node runs on: UNIX time read once at start, then
  advanced by the monotonic clock only, so a step of the system clock (NTP, a GPS time
  set, an operator's `date`) never makes a node's timers fire early or hang; the step
  is measured (`step_s`) and reported. `steady(clock)` wraps the system clock.
- `SteppingClock`: the system clock that steps by `offset_s` at `at_unix_s` (the fault
  campaign's clock jump, `stepping:AT:OFFSET`).
"""

from __future__ import annotations

import os
import threading
import time
from typing import Protocol, runtime_checkable

ENV_VAR = "BANDADA_CLOCK"


@runtime_checkable
class Clock(Protocol):
    def now(self) -> float:
        """Current time on this clock, UNIX seconds (simulated in a simulation)."""
        ...

    def sleep(self, seconds: float) -> None:
        """Block for `seconds` of this clock's time."""
        ...

    def to_wall(self, seconds: float) -> float:
        """How many wall-clock seconds `seconds` of this clock's time take (for timeouts
        of blocking calls such as queue.get)."""
        ...

    def spec(self) -> str:
        """A string from which `clock_from_spec` builds the same clock in another process."""
        ...


class SystemClock:
    def now(self) -> float:
        return time.time()

    def sleep(self, seconds: float) -> None:
        if seconds > 0:
            time.sleep(seconds)

    def to_wall(self, seconds: float) -> float:
        return seconds

    def spec(self) -> str:
        return "system"


class ScaledClock:
    """now = start_unix_s + speedup * (monotonic() - wall_anchor_s)."""

    def __init__(
        self, speedup: float, start_unix_s: float | None = None, wall_anchor_s: float | None = None
    ) -> None:
        if not speedup > 0:
            raise ValueError("speedup must be positive")
        self.speedup = float(speedup)
        self.start_unix_s = time.time() if start_unix_s is None else float(start_unix_s)
        self.wall_anchor_s = time.monotonic() if wall_anchor_s is None else float(wall_anchor_s)

    def now(self) -> float:
        return self.start_unix_s + self.speedup * (time.monotonic() - self.wall_anchor_s)

    def sleep(self, seconds: float) -> None:
        if seconds > 0:
            time.sleep(seconds / self.speedup)

    def to_wall(self, seconds: float) -> float:
        return max(0.0, seconds / self.speedup)

    def spec(self) -> str:
        return f"scaled:{self.speedup!r}:{self.start_unix_s!r}:{self.wall_anchor_s!r}"


class ManualClock:
    def __init__(self, start_unix_s: float = 1.7e9) -> None:
        self._t = float(start_unix_s)
        self._lock = threading.Lock()

    def now(self) -> float:
        return self._t

    def set(self, t: float) -> None:
        with self._lock:
            if t < self._t:
                raise ValueError("a ManualClock never goes back")
            self._t = float(t)

    def advance(self, dt: float) -> None:
        self.set(self._t + dt)

    def sleep(self, seconds: float) -> None:
        if seconds > 0:
            self.advance(seconds)

    def to_wall(self, seconds: float) -> float:
        return 0.0

    def spec(self) -> str:
        return f"manual:{self._t!r}"


class SteppingClock(SystemClock):
    """The system clock, stepped by `offset_s` from wall time `at_unix_s` on."""

    def __init__(self, at_unix_s: float, offset_s: float) -> None:
        self.at_unix_s, self.offset_s = float(at_unix_s), float(offset_s)

    def now(self) -> float:
        t = time.time()
        return t + self.offset_s if t >= self.at_unix_s else t

    def spec(self) -> str:
        return f"stepping:{self.at_unix_s!r}:{self.offset_s!r}"


class SteadyClock:
    """UNIX time at start, then the monotonic clock: never steps (see the module doc).
    `step_s()` is how far the wrapped clock now is from it (a step of the system clock)."""

    def __init__(self, inner: Clock) -> None:
        self.inner = inner
        self._anchor = inner.now()
        self._mono = time.monotonic()

    def now(self) -> float:
        return self._anchor + (time.monotonic() - self._mono)

    def step_s(self) -> float:
        return self.inner.now() - self.now()

    def sleep(self, seconds: float) -> None:
        if seconds > 0:
            time.sleep(seconds)

    def to_wall(self, seconds: float) -> float:
        return seconds

    def spec(self) -> str:
        return self.inner.spec()


def steady(clock: Clock) -> Clock:
    """The clock a node runs on: the system clock (stepped or not) made steady; a
    simulation's scaled or manual clock as it is (they never step)."""
    if isinstance(clock, SystemClock):
        return SteadyClock(clock)
    return clock


def clock_from_spec(spec: str) -> Clock:
    """Build a clock from `Clock.spec()` output ("system", "scaled:K:START:ANCHOR",
    "scaled:K" for a fresh scaled clock starting now, "manual:START")."""
    kind, _, rest = spec.strip().partition(":")
    try:
        if kind == "system":
            return SystemClock()
        if kind == "scaled":
            parts = [float(p) for p in rest.split(":")] if rest else []
            if len(parts) == 1:
                return ScaledClock(parts[0])
            if len(parts) == 3:
                return ScaledClock(parts[0], parts[1], parts[2])
        if kind == "manual":
            return ManualClock(float(rest)) if rest else ManualClock()
        if kind == "stepping":
            at, offset = (float(p) for p in rest.split(":"))
            return SteppingClock(at, offset)
    except ValueError as exc:
        raise ValueError(f"bad clock spec {spec!r}: {exc}") from exc
    raise ValueError(
        f"bad clock spec {spec!r}: expected system, scaled:K[:START:ANCHOR], manual or "
        "stepping:AT:OFFSET"
    )


def clock_from_env(default: Clock | None = None) -> Clock:
    """The clock named by BANDADA_CLOCK, else `default`, else the system clock."""
    spec = os.environ.get(ENV_VAR)
    if spec:
        return clock_from_spec(spec)
    return default if default is not None else SystemClock()
