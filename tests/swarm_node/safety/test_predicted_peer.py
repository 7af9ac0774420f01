"""A radio peer's predicted status (its gateway's dead reckoning to `now`, with
`position_error_m`) widens its protection volume by that bound: the contract between the
radio gateway and avoidance (docs/radio.md, docs/avoidance.md)."""

from __future__ import annotations

import msgspec
import pytest

from swarm_node.core.safety.ttc import BadTrackError, Track, approaches, kinematic
from swarm_proto import VehicleStatus

T = 1.75e9


def _status(vid: int, lat: float, lon: float, **kw: object) -> VehicleStatus:
    return VehicleStatus(
        vehicle_id=vid,
        time_unix_s=T,
        lat_deg=lat,
        lon_deg=lon,
        alt_msl_m=150.0,
        alt_rel_m=100.0,
        **kw,  # type: ignore[arg-type]
    )


def test_a_predicted_status_widens_the_margin_by_its_error_bound() -> None:
    measured = _status(2, 37.41, -5.98)
    predicted = msgspec.structs.replace(measured, position_error_m=12.5, predicted_s=1.4)
    assert Track.from_status(measured).error_m == 0.0
    track = Track.from_status(predicted, max_speed_m_s=35.0)
    assert track.error_m == 12.5
    k = kinematic([track], now=T + 0.2)
    stale = kinematic([Track.from_status(measured, max_speed_m_s=35.0)], now=T + 0.2)
    assert stale.margin_m[0] > 0.0  # 0.2 s old: widened by what it could have manoeuvred
    assert k.margin_m[0] == pytest.approx(12.5 + stale.margin_m[0])  # and by the bound
    own = Track.from_status(_status(1, 37.4095, -5.98))
    a = approaches(own, [track], now=T, horizon_s=30.0)
    b = approaches(own, [Track.from_status(measured)], now=T, horizon_s=30.0)
    assert a.miss_m[0] == pytest.approx(b.miss_m[0]) and a.margin_m[0] == b.margin_m[0] + 12.5


def test_a_negative_or_non_finite_error_is_a_bad_track() -> None:
    with pytest.raises(BadTrackError):
        Track(3, 37.4, -5.9, 100.0, error_m=-1.0)
    with pytest.raises(BadTrackError):
        Track(3, 37.4, -5.9, 100.0, error_m=float("nan"))
