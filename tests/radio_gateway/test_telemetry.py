"""Send on error in the gateway (radio_gateway/core/telemetry.py): the sender's decisions,
the receivers' predictions and their error bound, on VehicleStatus as the node publishes
it."""

from __future__ import annotations

import math

import msgspec
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from radio_gateway.core.telemetry import (
    OwnTelemetry,
    PeerPredictor,
    PredictConfig,
    SendOnErrorConfig,
    carried,
    decode_turn,
    encode_turn,
    error_bound,
)
from swarm_proto import AlertFlag, FsmState, VehicleStatus, radio
from tests.conftest import examples

LAT0, LON0 = 37.4112, -5.9889
MLAT = 111_132.0
MLON = 111_320.0 * math.cos(math.radians(LAT0))
T0 = 1.75e9


def _at(x: float, y: float, vx: float, vy: float, t: float, **kw: object) -> VehicleStatus:
    return VehicleStatus(
        vehicle_id=kw.pop("vid", 3),  # type: ignore[arg-type]
        time_unix_s=t,
        lat_deg=LAT0 + y / MLAT,
        lon_deg=LON0 + x / MLON,
        alt_msl_m=110.0,
        alt_rel_m=100.0,
        vel_north_m_s=vy,
        vel_east_m_s=vx,
        armed=True,
        **kw,  # type: ignore[arg-type]
    )


def _orbit(t: float, r: float = 90.0, v: float = 18.0) -> VehicleStatus:
    """Counter-clockwise orbit of radius r centred on the origin, at t s after T0."""
    a = v / r * t
    return _at(r * math.cos(a), r * math.sin(a), -v * math.sin(a), v * math.cos(a), T0 + t)


def _dist(a: VehicleStatus, b: VehicleStatus) -> float:
    return math.hypot((a.lat_deg - b.lat_deg) * MLAT, (a.lon_deg - b.lon_deg) * MLON)


def test_the_turn_rate_is_estimated_and_an_orbit_is_predicted_exactly() -> None:
    own = OwnTelemetry()
    for i in range(10):
        own.update(_orbit(0.2 * i), T0 + 0.2 * i)
    assert own.turn_rate == pytest.approx(18.0 / 90.0, rel=0.01)  # CCW positive
    s = own.latest
    assert s is not None
    later, moved = carried(s, own.turn_rate, s.time_unix_s + 5.0)
    assert _dist(later, _orbit(1.8 + 5.0)) < 0.5  # a straight line would be 20+ m off
    assert moved == pytest.approx(2 * 90.0 * math.sin(18.0 / 90.0 * 5.0 / 2), rel=0.01)
    turn = math.degrees(18.0 / 90.0 * 5.0)
    assert later.heading_deg == pytest.approx((s.heading_deg - turn) % 360.0, abs=0.5)
    assert later.vel_north_m_s == pytest.approx(_orbit(6.8).vel_north_m_s, abs=0.2)


def test_the_turn_rate_travels_after_the_40_bytes_and_old_decoders_ignore_it() -> None:
    s = _orbit(0.0)
    data = radio.encode(s) + encode_turn(0.2)
    assert decode_turn(data) == pytest.approx(0.2, abs=1e-4)
    assert decode_turn(radio.encode(s)) == 0.0  # a sender that appends nothing
    assert encode_turn(99.0) == encode_turn(3.2767)  # saturates
    back = radio.decode(data, now_unix_s=T0)
    assert isinstance(back, VehicleStatus) and back.vehicle_id == 3


def test_a_straight_leg_sends_only_heartbeats_a_new_manoeuvre_sends_at_once_twice() -> None:
    """(A 3 s heartbeat here, so that the turn, not the heartbeat, triggers the send.)"""
    own = OwnTelemetry(SendOnErrorConfig(threshold_m=5.0, heartbeat_s=3.0), encode=radio.encode)
    reasons: list[tuple[float, str]] = []
    t = 0.0
    while t < 20.0:
        if t < 10.0:  # straight east at 18 m/s
            s = _at(18.0 * t, 0.0, 18.0, 0.0, T0 + t)
        else:  # then a 60 m radius turn to the left
            a = 18.0 / 60.0 * (t - 10.0)
            s = _at(
                180.0 + 60.0 * math.sin(a),
                60.0 - 60.0 * math.cos(a),
                18.0 * math.cos(a),
                18.0 * math.sin(a),
                T0 + t,
            )
        own.update(s, T0 + t)
        if abs(t / 0.4 - round(t / 0.4)) < 1e-6:  # a transmit opportunity every 400 ms
            c = own.candidate(T0 + t, horizon_s=0.45)
            if c is not None:
                own.sent(c, T0 + t)
                reasons.append((round(t, 1), c.reason))
        t = round(t + 0.1, 1)
    first_leg = [r for x, r in reasons if x < 10.0]
    assert first_leg[0] == "first" and set(first_leg[1:]) == {"heartbeat"}
    assert 3 <= len(first_leg) <= 5  # about one every 3 s
    turn = [(x, r) for x, r in reasons if x >= 10.0]
    i = next(i for i, (_, r) in enumerate(turn) if r == "error")
    assert turn[i][0] <= 11.2  # before the peers are 5 m off (the estimate lags 0.4 s)
    assert turn[i + 1][1] == "repeat"  # a lost frame does not leave a peer on the old leg
    assert own.need_level(T0 + 20.0) == 1  # flying: the default share
    own.update(msgspec.structs.replace(own.latest, armed=False), T0 + 20.0)  # type: ignore[arg-type]
    assert own.need_level(T0 + 20.0) == 0  # parked: the least


def test_with_manoeuvre_share_a_manoeuvre_that_outran_the_slots_asks_for_more() -> None:
    own = OwnTelemetry(SendOnErrorConfig(manoeuvre_share=True, calm_s=10.0), encode=radio.encode)
    own.update(_at(0, 0, 18, 0, T0), T0)
    c = own.candidate(T0, 0.5)
    assert c is not None
    own.sent(c, T0)
    own.update(_at(18, 0, 0, 18, T0 + 1.0), T0 + 1.0)  # it turned; we could not send
    own.update(_at(18, 18, 0, 18, T0 + 2.0), T0 + 2.0)
    c = own.candidate(T0 + 2.0, 0.5)
    assert c is not None and c.reason == "error"
    assert own.need_level(T0 + 2.0) == 2 and own.need_level(T0 + 12.5) == 1


def test_a_discrete_change_goes_out_at_the_next_opportunity_and_avoiding_needs_most() -> None:
    own = OwnTelemetry(encode=radio.encode)
    own.update(_at(0, 0, 0, 0, T0), T0)
    c = own.candidate(T0, 0.5)
    assert c is not None and c.reason == "first"
    own.sent(c, T0)
    assert own.candidate(T0 + 0.2, 0.5) is None  # nothing changed, no heartbeat yet
    own.update(_at(0, 0, 0, 0, T0 + 0.3, fsm_state=FsmState.GO_MISSION), T0 + 0.3)
    c = own.candidate(T0 + 0.4, 0.5)
    assert c is not None and c.reason == "changed"
    own.sent(c, T0 + 0.4)
    own.update(_at(0, 0, 0, 0, T0 + 0.5, alerts=AlertFlag.COLLISION_RISK), T0 + 0.5)
    assert own.need_level(T0 + 0.5) == 2


def test_a_node_that_stops_publishing_still_sends_its_heartbeat() -> None:
    """An autopilot link loss freezes the node's status: the gateway repeats it each
    heartbeat (the peers see the vehicle, its data growing old), never more often."""
    own = OwnTelemetry(encode=radio.encode)
    own.update(_at(0, 0, 10, 0, T0), T0)
    sent = []
    for i in range(50):
        t = T0 + 0.2 * i
        c = own.candidate(t, 0.5)
        if c is not None:
            own.sent(c, t)
            sent.append(c.reason)
    assert sent[0] == "first" and set(sent[1:]) == {"heartbeat"} and len(sent) == 10


vel = st.floats(-25.0, 25.0)


@settings(max_examples=examples(60), deadline=None)
@given(
    vx=vel,
    vy=vel,
    w=st.floats(-0.3, 0.3),
    pieces=st.lists(
        st.tuples(st.floats(0.2, 2.0), st.floats(-1.0, 1.0), st.floats(-1.0, 1.0)),
        min_size=1,
        max_size=6,
    ),
)
def test_the_error_bound_holds_for_any_manoeuvre_within_the_acceleration(
    vx: float, vy: float, w: float, pieces: list[tuple[float, float, float]]
) -> None:
    """The truth leaves the predicted state with any acceleration within 6 m/s^2 (pieces
    of constant acceleration, any direction): it stays within the published bound."""
    cfg = PredictConfig(max_accel_mps2=6.0)
    p = PeerPredictor(cfg)
    s0 = _at(0.0, 0.0, vx, vy, T0)
    ok = p.on_status(s0, w, T0)
    assert ok
    # the prediction itself turns at w: its acceleration is |v| w, within the bound too
    if math.hypot(vx, vy) * abs(w) > 6.0:
        return
    x = y = 0.0
    ux, uy = vx, vy
    t = 0.0
    for dur, ax_u, ay_u in pieces:
        norm = max(1.0, math.hypot(ax_u, ay_u))
        ax, ay = 6.0 * ax_u / norm, 6.0 * ay_u / norm
        steps = max(1, int(dur / 0.05))
        for _ in range(steps):
            dt = dur / steps
            x += ux * dt + 0.5 * ax * dt * dt
            y += uy * dt + 0.5 * ay * dt * dt
            ux += ax * dt
            uy += ay * dt
            t += dt
            pos = p.position(3, T0 + t)
            assert pos is not None
            err = math.hypot(
                (pos[0] - (LAT0 + y / MLAT)) * MLAT, (pos[1] - (LON0 + x / MLON)) * MLON
            )
            assert err <= pos[3] + 0.01, (t, err, pos[3])


def test_predictions_come_at_5_hz_and_stop_when_the_peer_falls_silent() -> None:
    p = PeerPredictor(PredictConfig(republish_hz=5.0, predict_max_s=5.0))
    assert p.on_status(_orbit(0.0), 0.2, T0)
    out: list[VehicleStatus] = []
    t = T0
    while t < T0 + 3.0:
        t += 0.05
        out += p.due(t)
    assert 14 <= len(out) <= 15
    assert all(s.predicted_s > 0 and s.position_error_m > 0 for s in out)
    assert all(_dist(s, _orbit(s.time_unix_s - T0)) <= s.position_error_m + 0.05 for s in out)
    assert out[-1].predicted_s == pytest.approx(3.0, abs=0.2)
    # the radio says it is gone: no more predictions, the node sees it go stale
    assert p.due(t + 0.2, alive=lambda vid: False) == [] and 3 not in p.peers
    # heard again, then nothing for predict_max_s: dropped
    assert p.on_status(_orbit(3.5), 0.2, T0 + 3.5)
    assert p.due(T0 + 3.5 + 5.1) == [] and 3 not in p.peers
    # each drop says why (the gateway logs it: its node sees the peer go stale after)
    assert p.dropped == [(3, "the radio no longer hears it"), (3, "no status heard for 5.1 s")]


def test_an_older_or_repeated_status_keeps_the_newer_and_the_peer_alive() -> None:
    p = PeerPredictor()
    assert p.on_status(_orbit(2.0), 0.0, T0 + 2.0)
    assert not p.on_status(_orbit(1.0), 0.0, T0 + 2.1)
    assert not p.on_status(_orbit(2.0), 0.0, T0 + 6.0)  # repeated (a frozen autopilot link)
    assert p.due(T0 + 8.0)  # still predicted: heard 2 s ago
    s = p.predicted(3, T0 + 8.0)
    assert s is not None and s.predicted_s == pytest.approx(6.0)
    assert not p.on_status(msgspec.structs.replace(_orbit(1.5)), math.nan, T0 + 8.0)


def test_the_bound_is_the_smaller_of_acceleration_and_speed_limits() -> None:
    cfg = PredictConfig(max_accel_mps2=6.0, max_speed_m_s=35.0)
    assert error_bound(1.0, 18.0, cfg) == pytest.approx(6.0)
    assert error_bound(20.0, 18.0, cfg) == pytest.approx(53.0 * 20.0)
    assert error_bound(-1.0, 18.0, cfg) == 0.0


def test_bad_settings_are_refused() -> None:
    with pytest.raises(ValueError):
        SendOnErrorConfig(threshold_m=0.0)
    with pytest.raises(ValueError):
        SendOnErrorConfig(heartbeat_s=-1.0)
    with pytest.raises(ValueError):
        PredictConfig(republish_hz=0.0)
