"""Mission inheritance (paper Fig. 14 and 17) in fast time, over real MAVLink bytes: six
VTOLs fly an area mission sent to ALL; one is killed at 40 % of its share; the
survivors replan what is left from its last published progress, agree without a
leader and fly it (`swarm_sim.scenarios.inheritance`: coverage from the flown tracks,
swath the camera footprint; double flying from the straight runs along the lanes)."""

from __future__ import annotations

import pytest

from swarm_sim.scenarios import inheritance

pytestmark = pytest.mark.soak  # about two minutes; `make bench BENCH=mission` measures the same



def test_six_vtols_inherit_the_share_of_one_killed_at_40_percent(fleet_profiles: dict) -> None:
    r = inheritance(fleet_profiles, (1, 2, 3, 4, 5, 6), victim=3, at_fraction=0.4)
    print(f"coverage {r.coverage:.4f}, double flown {r.double_flown:.4f} (lane runs cover "
          f"{r.lanes_cover:.2f}), replan agreed {r.agree_s:.1f} s after the loss")  # fmt: skip
    assert r.replan_seen and r.same_plan and r.hashes == 1
    assert r.completed == set(r.survivors)
    assert r.lanes_cover > 0.7  # the runs found are the lanes: the measure means something
    assert r.coverage >= 0.99
    assert r.double_flown < 0.02  # the lost member's last second (1 Hz VehicleInfo) again
