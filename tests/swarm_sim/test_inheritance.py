"""Mission inheritance (paper Fig. 14 and 17) in fast time, over real MAVLink bytes: a
fleet flies an area mission sent to ALL; one member is killed at 40 % of its share; the
survivors replan what is left from its last published progress, agree without a
leader and fly it (`swarm_sim.scenarios.inheritance`: coverage from the flown tracks,
swath the camera footprint; double flying from the straight runs each vehicle flew on
its own lanes)."""

from __future__ import annotations

import pytest

from swarm_sim.scenarios import inheritance


@pytest.mark.soak  # about a minute; `make bench BENCH=mission` measures the same
def test_six_vtols_inherit_the_share_of_one_killed_at_40_percent(fleet_profiles: dict) -> None:
    r = inheritance(fleet_profiles, (1, 2, 3, 4, 5, 6), victim=3, at_fraction=0.4)
    print(
        f"coverage {r.coverage:.4f}, double flown {r.double_flown:.4f} (lane runs cover "
        f"{r.lanes_cover:.2f}), replan agreed {r.agree_s:.1f} s after the loss"
    )
    assert r.replan_seen and r.same_plan and r.hashes == 1
    assert r.completed == set(r.survivors)
    assert r.lanes_cover > 0.7  # the runs found are the lanes: the measure means something
    assert r.coverage >= 0.99
    assert r.double_flown < 0.02  # the lost member's last second (1 Hz VehicleInfo) again


NO_RESERVE = pytest.mark.xfail(
    strict=True,
    reason="on the 160 m field the first split gives rover 10 no lanes: a member given "
    "nothing now stays on its pad and leaves the mission, so it is "
    "no reserve the survivors' replan can hand the lost member's rest to",
)


@pytest.mark.soak  # inheritance: test_demo_story.py, test_faults_smoke.py (kill -9 a node)
def test_two_quadcopters_and_a_rover_with_shares_inherit_the_share_of_a_quadcopter(
    fleet_profiles: dict,
) -> None:
    """The issue's second fleet on a 200 m field 150 m north, where the first split gives
    each of the three a share: quadcopter 8 killed at 40 % of its share, quadcopter 7 and
    the rover cover the field (as on the 160 m field before members given nothing stayed
    on their pads: test_two_quadcopters_and_a_rover_inherit_the_share_of_one_killed_at_40_percent)."""
    r = inheritance(
        fleet_profiles,
        (7, 8, 10),
        victim=8,
        at_fraction=0.4,
        half_m=100.0,
        alt_m=40.0,
        north_m=150.0,
    )
    assert r.replan_seen and r.same_plan and r.hashes == 1
    assert r.completed == set(r.survivors) == {7, 10}
    assert r.lanes_cover > 0.7
    assert r.coverage >= 0.99
    assert r.double_flown < 0.02
    assert r.battery_critical == ()


@pytest.mark.parametrize(
    "victim",
    [
        pytest.param(8, marks=[pytest.mark.soak, NO_RESERVE]),
        pytest.param(10, marks=[pytest.mark.soak, NO_RESERVE]),
    ],
)
def test_two_quadcopters_and_a_rover_inherit_the_share_of_one_killed_at_40_percent(
    fleet_profiles: dict, victim: int
) -> None:
    """The issue's second fleet: quadcopters 7 and 8 (3.3 Ah) and rover 10 (2 m/s) on
    a 160 m field at 40 m; a quadcopter or the rover is killed at 40 % of its share.
    The survivors cover the field from their flown tracks, nobody flies another's lanes
    (what is counted twice is the lost member's last second before it was noticed, and
    where a lane cut by the split is met from both ends), and the quadcopter that
    inherits lanes gets no more than its battery flies home (by the model every node
    computes alike: before, the surviving quadcopter on a 240 m field ran into
    BATTERY_CRITICAL)."""
    r = inheritance(
        fleet_profiles,
        (7, 8, 10),
        victim=victim,
        at_fraction=0.4,
        half_m=80.0,
        alt_m=40.0,
        north_m=150.0,
    )
    print(
        f"coverage {r.coverage:.4f}, double flown {r.double_flown:.4f} {r.pairs}, "
        f"agreed {r.agree_s:.1f} s after the loss"
    )
    assert r.replan_seen and r.same_plan and r.hashes == 1
    assert r.completed == set(r.survivors)
    assert r.lanes_cover > 0.7
    assert r.coverage >= 0.99
    assert r.double_flown < 0.02
    assert r.battery_critical == ()


@pytest.mark.soak  # the rover then drives for 15 simulated minutes
def test_a_quadcopter_inherits_no_more_than_its_battery_flies(fleet_profiles: dict) -> None:
    """On a 240 m field the quadcopter left would need more than its charge for the
    lost one's lanes: the replan gives the rest to the rover."""
    r = inheritance(
        fleet_profiles,
        (7, 8, 10),
        victim=8,
        at_fraction=0.4,
        half_m=120.0,
        alt_m=40.0,
        north_m=200.0,
    )
    assert r.battery_critical == ()
    assert r.completed == {7, 10}
    assert r.coverage >= 0.99
