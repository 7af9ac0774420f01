"""Send on error: the dead-reckoning model a vehicle runs of itself and its peers run of it."""

from __future__ import annotations

import contextlib
import itertools
import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from radio_gateway.core.deadreckon import (
    KINEMATICS_BYTES,
    Kinematics,
    PeerView,
    SendOnError,
    decode_kinematics,
    distance,
    encode_kinematics,
    predict,
)
from tests.conftest import examples

finite = st.floats(-1e3, 1e3, allow_nan=False)
speed = st.floats(-25, 25, allow_nan=False)
rate = st.floats(-0.4, 0.4, allow_nan=False)


@st.composite
def states(draw: st.DrawFn) -> Kinematics:
    return Kinematics(
        draw(st.floats(0, 1e4)),
        draw(finite),
        draw(finite),
        draw(finite),
        draw(speed),
        draw(speed),
        draw(st.floats(-5, 5)),
        draw(rate),
    )


def test_a_straight_leg_is_predicted_exactly() -> None:
    k = Kinematics(10.0, 0, 0, 100, 18, 0, 1, 0.0)
    p = predict(k, 12.0)
    assert (p.x, p.y, p.z) == pytest.approx((36, 0, 102))


def test_an_orbit_closes_after_one_turn() -> None:
    w = 18 / 80  # an 80 m orbit at 18 m/s
    k = Kinematics(0.0, 0, 0, 50, 18, 0, 0, w)
    quarter = predict(k, math.pi / 2 / w)
    assert (quarter.x, quarter.y) == pytest.approx((80, 80), abs=1e-6)
    full = predict(k, 2 * math.pi / w)
    assert distance(full, k) == pytest.approx(0, abs=1e-6)


@given(states(), st.floats(0, 30), st.floats(0, 30))
def test_prediction_composes(k: Kinematics, a: float, b: float) -> None:
    """Predicting in two steps lands where one step does: every node that starts from the
    same state predicts the same position, whenever it updates."""
    one = predict(k, k.t + a + b)
    two = predict(predict(k, k.t + a), k.t + a + b)
    assert distance(one, two) < 1e-6 * (1 + abs(one.x) + abs(one.y) + abs(one.z))


@given(states())
def test_the_wire_form_round_trips(k: Kinematics) -> None:
    data = encode_kinematics(k)
    assert len(data) == KINEMATICS_BYTES
    back = decode_kinematics(data)
    assert back.t == k.t
    assert distance(back, k) < 1e-3 * (1 + abs(k.x) + abs(k.y) + abs(k.z))


@given(st.binary(max_size=64))
def test_bad_bytes_raise_value_error_only(data: bytes) -> None:
    with contextlib.suppress(ValueError):
        decode_kinematics(data)


def _track(t: float) -> Kinematics:
    """A leg east for 10 s, then an 80 m orbit (accelerations within 6 m/s^2)."""
    leg = Kinematics(0.0, 0, 0, 100, 18, 0, 0, 0.0)
    if t <= 10:
        return predict(leg, t)
    return predict(Kinematics(10.0, 180, 0, 100, 18, 0, 0, 18 / 80 * 1.0), t)


@settings(max_examples=examples(30), deadline=None)
@given(st.floats(1.0, 10.0), st.floats(0.3, 2.0))
def test_the_peers_error_stays_within_the_threshold(threshold: float, heartbeat: float) -> None:
    """Checked every 100 ms against a horizon of one step, the sender keeps the peers'
    prediction (from what it sent) within the threshold, and speaks at least every
    heartbeat."""
    s = SendOnError(threshold_m=threshold, heartbeat_s=heartbeat)
    view = PeerView()
    sent_at: list[float] = []
    for i in range(300):
        now = i * 0.1
        truth = _track(now)
        if s.due(truth, now, horizon_s=0.1):
            s.sent(truth, now)
            view.on_state(truth)
            sent_at.append(now)
        p = view.predicted(now)
        assert p is not None
        assert math.dist((p.x, p.y, p.z), (truth.x, truth.y, truth.z)) <= threshold + 1e-6
    assert max(b - a for a, b in itertools.pairwise(sent_at)) <= heartbeat + 0.1
    # a leg and an orbit cost few messages: far fewer than one per step
    assert len(sent_at) < 300 / 2


@settings(max_examples=examples(50), deadline=None)
@given(st.lists(st.booleans(), min_size=5, max_size=40), st.floats(0.05, 1.0))
def test_the_bound_holds_whatever_is_lost(delivered: list[bool], step: float) -> None:
    """The peer's error bound holds with any pattern of lost messages."""
    view = PeerView(max_accel_mps2=6.0)
    for i, ok in enumerate(delivered):
        now = 8.0 + i * step  # across the leg-to-orbit change at 10 s
        truth = _track(now)
        if ok:
            view.on_state(truth)
        p = view.predicted(now)
        if p is not None:
            err = math.dist((p.x, p.y, p.z), (truth.x, truth.y, truth.z))
            assert err <= p.bound_m + 1e-6


def test_an_older_state_is_ignored() -> None:
    view = PeerView()
    assert view.on_state(Kinematics(2.0, 0, 0, 0, 1, 0, 0))
    assert not view.on_state(Kinematics(1.0, 5, 5, 0, 1, 0, 0))
    assert view.stale == 1 and view.last is not None and view.last.t == 2.0


def test_invalid_settings_and_states_are_refused() -> None:
    with pytest.raises(ValueError):
        SendOnError(threshold_m=0)
    with pytest.raises(ValueError):
        Kinematics(math.nan, 0, 0, 0, 0, 0, 0)
