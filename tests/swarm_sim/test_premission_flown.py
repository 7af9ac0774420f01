"""PREMISSION flown by the nodes (paper section 2.3.5) in fast time
over real MAVLink bytes: three Albatross VTOLs on the ground get a mission to ALL; each
predicts and publishes when it can be at its share's entry, they meet at the latest
one, and each flies its Dubins leg from where it climbed to, leaving in time and
setting its airspeed every second to arrive on time. Arrivals are measured from the
autopilots' positions (the closest pass by each entry point,
`swarm_sim.scenarios.premission_meet`); the same flights without the meet are the
baseline."""

from __future__ import annotations

import pytest

from swarm_node.core.mission import fleet_sync
from swarm_proto import MissionType
from swarm_sim.scenarios import premission_meet

VTOLS = (1, 2, 3)


@pytest.mark.parametrize(
    "kind",
    # a route's legs meet as an area's do; the demo story flies a route in `make test`
    [pytest.param(MissionType.ROUTE, marks=pytest.mark.soak), MissionType.AREA],
)
def test_a_fixed_wing_fleet_arrives_at_its_entries_within_2_s(
    fleet_profiles: dict, kind: MissionType
) -> None:
    got = premission_meet(fleet_profiles, VTOLS, kind)
    print(f"{kind.name}: arrivals {got.arrivals}, spread {got.spread_s:.2f} s")
    assert got.premission_seen  # mission_state PREMISSION while the legs are flown
    assert got.meet_s is not None
    assert got.spread_s <= 2.0, got
    for vid, t in got.arrivals.items():
        assert abs(t - got.meet_s) <= 2.0, (vid, t, got.meet_s)
        assert got.entry_miss_m[vid] < 15.0  # it passed its entry (the waypoint acceptance)


@pytest.mark.soak  # the baseline of the test above (the bench measures it too)
@pytest.mark.parametrize(
    "kind",
    # a route's legs meet as an area's do; the demo story flies a route in `make test`
    [pytest.param(MissionType.ROUTE, marks=pytest.mark.soak), MissionType.AREA],
)
def test_without_the_meet_the_fleet_arrives_far_apart(
    fleet_profiles: dict, kind: MissionType, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(fleet_sync, "PREMISSION", False)
    before = premission_meet(fleet_profiles, VTOLS, kind)
    print(f"without the meet: spread {before.spread_s:.2f} s")
    assert not before.premission_seen and before.spread_s > 10.0


def test_the_mission_speed_rule_keeps_the_members_on_one_schedule(fleet_profiles: dict) -> None:
    """Past the entry each member's lateness against its share's schedule from the meet
    time stays within a few seconds of the others' (without the rule, the members with
    more turns fall 11 s behind: the soak test below, and the bench); the mission is
    completed by all."""
    got = premission_meet(fleet_profiles, VTOLS, MissionType.AREA, to_the_end=True)
    print(f"lateness spread {got.lateness_spread_s:.2f} s")
    assert got.completed == set(VTOLS)
    assert got.lateness_spread_s <= 3.0


@pytest.mark.soak
def test_without_the_speed_rule_the_members_drift_apart(
    fleet_profiles: dict, monkeypatch: pytest.MonkeyPatch
) -> None:
    got = premission_meet(fleet_profiles, VTOLS, MissionType.AREA, to_the_end=True)
    monkeypatch.setattr(fleet_sync, "SPEED_RULE", False)
    without = premission_meet(fleet_profiles, VTOLS, MissionType.AREA, to_the_end=True)
    print(
        f"lateness spread {got.lateness_spread_s:.2f} s, without the rule {without.lateness_spread_s:.2f} s"
    )
    assert without.lateness_spread_s > 2.0 * got.lateness_spread_s
