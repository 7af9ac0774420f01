from __future__ import annotations

import time

import pytest

from swarm_proto import ManualClock, ScaledClock, SystemClock, clock_from_spec
from swarm_proto.clock import clock_from_env


def test_manual_clock_jumps_and_never_goes_back() -> None:
    c = ManualClock(100.0)
    c.sleep(5.0)
    c.advance(1.5)
    assert c.now() == 106.5
    with pytest.raises(ValueError):
        c.set(50.0)


def test_scaled_clock_is_shared_through_its_spec() -> None:
    a = ScaledClock(50.0, start_unix_s=1.7e9)
    b = clock_from_spec(a.spec())
    # two processes with the same spec read the same simulated time
    assert abs(a.now() - b.now()) < 50.0 * 0.05
    t0 = a.now()
    a.sleep(5.0)  # 0.1 s of wall time
    assert a.now() - t0 >= 5.0
    assert a.to_wall(10.0) == pytest.approx(0.2)


def test_specs() -> None:
    assert isinstance(clock_from_spec("system"), SystemClock)
    assert isinstance(clock_from_spec("scaled:4"), ScaledClock)
    assert clock_from_spec("manual:12").now() == 12.0
    for bad in ("", "warp:9", "scaled:x", "scaled:0"):
        with pytest.raises(ValueError):
            clock_from_spec(bad)


def test_clock_from_env(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("BANDADA_CLOCK", "manual:3")
    assert clock_from_env().now() == 3.0
    monkeypatch.delenv("BANDADA_CLOCK")
    assert abs(clock_from_env().now() - time.time()) < 1.0
