"""The fault campaign's smoke subset (the whole campaign is `make faults`,
docs/reliability.md): three faults on a short survey by two VTOLs in FastFleet, each
flown to the landing: the swarm recovers, the area is covered, nothing declared is
lost and no emergency is raised. "ground station lost": the ground station goes once
the mission is sent and a node restarts mid-mission; every vehicle still finishes and
lands at its base by itself (before, the restarted node had no base and its
vehicle loitered at the end of its share)."""

from __future__ import annotations

import pytest

from swarm_sim.faults import FAST_FAULTS, MISSIONS, MissionSpec, campaign_fast, run_fast

SHORT = MissionSpec("survey, 2 VTOLs (smoke)", (1, 2), 150.0, 2)


@pytest.mark.parametrize(
    "fault",
    [
        "kill -9 a node (restarted after 5 s)",
        # in fast time, fence and rally point checked: test_backstop.py
        pytest.param("restart an autopilot (empty stores)", marks=pytest.mark.soak),
        # the whole campaign flies it (`make faults`); a node restart: the row above
        pytest.param("ground station lost", marks=pytest.mark.soak),
    ],  # a SIGSTOP: test_busy_host.py, test_node_processes.py
)
def test_smoke(fleet_profiles: dict, fault: str) -> None:
    row = run_fast(fault, SHORT, fleet_profiles)
    print(row)
    assert row.recovered, row
    assert row.mission_completed and row.coverage >= 0.95
    assert row.declared_state_lost == 0 and row.false_emergencies == 0
    assert row.recover_s is not None and row.recover_s >= 0.0


@pytest.mark.soak
def test_the_fastfleet_campaign(fleet_profiles: dict) -> None:
    rows = campaign_fast(fleet_profiles)
    assert len(rows) == len(FAST_FAULTS) * len(MISSIONS)
    for row in rows:
        assert row.declared_state_lost == 0 and row.false_emergencies == 0, row
        assert row.mission_completed and row.coverage >= 0.95, row
