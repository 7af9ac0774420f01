"""Flown as planned (deliver 6): the demo's survey flown in fast time by the
fleet 1, 7, 8 (an Albatross VTOL and two 3.3 Ah quadcopters). The split knows each
vehicle's endurance and what its waypoints and turns cost, so nobody reaches
BATTERY_CRITICAL on the way home (before, the quadcopter given more lanes did) and the
makespan flown is within 15 % of the one planned. The measuring code is the
benchmark's (bench/mission.py `survey`)."""

from __future__ import annotations

import pytest

from bench.mission import survey


# the split within the batteries: test_endurance.py; the makespan: make bench BENCH=mission
@pytest.mark.soak
def test_the_fleet_1_7_8_lands_above_critical_and_flies_its_planned_makespan(
    fleet_profiles: dict,
) -> None:
    got = survey(fleet_profiles)
    assert got["finished"], got
    assert got["battery_critical_alerts"] == [], got
    for vid, v in got["vehicles"].items():
        if v["share_planned_s"] == 0.0:
            continue  # the plan gave it nothing: it stayed down
        assert v["battery_at_landing_pct"] > v["critical_pct"], (vid, v)
        assert v["flown_s"] is not None, (vid, v)
    assert 0.85 <= got["makespan_planned_vs_flown"] <= 1.15, got


@pytest.mark.soak  # arrivals within 2 s: test_premission_flown.py
def test_premission_legs_bring_scattered_vtols_to_their_entries_together(
    fleet_profiles: dict,
) -> None:
    """Three Albatross VTOLs circling at scattered points fly their PREMISSION legs
    (Dubins from their pose and heading, arrival speed, a waiting orbit) in fast time,
    their airspeed set every second to what brings them to their entry at the
    predicted time: they pass their entry points within 2 s of each other (flying the
    same legs at cruise they would be 40 s apart)."""
    from bench.mission import premission_flight

    got = premission_flight(fleet_profiles)
    assert got["finished"], got
    assert got["predicted_spread_s"] <= 2.0
    assert got["premission_arrival_spread_s"] <= 2.0, got
    assert got["baseline_unsynchronized_spread_s"] > 5 * got["premission_arrival_spread_s"]
    for vid, t in got["arrivals_s"].items():
        assert abs(t - got["predicted_arrival_s"]) <= 2.0, (vid, t)
