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


def test_a_steady_clock_does_not_follow_a_step_of_the_system_clock() -> None:
    """A node runs on a SteadyClock; the system clock stepping an hour (NTP, a
    GPS time set) neither fires its timers early nor hangs them, and is measured."""
    import time as _time

    from swarm_proto.clock import SteadyClock, SteppingClock, steady

    stepping = clock_from_spec(f"stepping:{_time.time() + 0.05!r}:3600.0")
    assert isinstance(stepping, SteppingClock)
    node = steady(stepping)
    assert isinstance(node, SteadyClock) and node.spec() == stepping.spec()
    before = node.now()
    _time.sleep(0.1)
    after = node.now()
    assert 0.05 <= after - before < 1.0  # no step
    assert 3599.0 < node.step_s() < 3601.0  # the system clock's step, measured
    back = steady(SteppingClock(_time.time() + 0.05, -3600.0))
    _time.sleep(0.1)
    assert -3601.0 < back.step_s() < -3599.0  # type: ignore[attr-defined]
    scaled = ScaledClock(5.0)
    assert steady(scaled) is scaled  # a simulation's clock never steps


def test_a_bad_stepping_spec_is_a_clear_error() -> None:
    with pytest.raises(ValueError, match="bad clock spec 'stepping:now'"):
        clock_from_spec("stepping:now")
