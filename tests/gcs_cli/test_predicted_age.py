"""A radio peer's status predicted by its gateway is `predicted_s` older in its
data than its time says: `gcs status` shows the age of the autopilot data, not of the
prediction."""

from __future__ import annotations

import msgspec

from gcs_cli.render import data_age_s
from swarm_proto import VehicleStatus


def test_the_data_age_of_a_prediction_counts_how_far_it_was_carried() -> None:
    s = VehicleStatus(
        vehicle_id=3,
        time_unix_s=1000.0,
        lat_deg=37.4,
        lon_deg=-5.9,
        alt_msl_m=100.0,
        alt_rel_m=90.0,
    )
    assert data_age_s(s, 1000.5) == 0.5
    predicted = msgspec.structs.replace(s, predicted_s=2.0, position_error_m=24.0)
    assert data_age_s(predicted, 1000.5) == 2.5
