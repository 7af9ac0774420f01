"""A `swarm-sim demo --radio` at load 10-20 replanned three times at launch,
"the fleet changed", and flew 0 of 4 missions: peers behind the radio went stale for a
moment. Behind the radio a node knows its peers only by the telemetry its own gateway
republishes (5 Hz: what it heard, and its predictions between); when that gateway's
process is descheduled for a couple of seconds, every peer falls silent at once. Here
(FastFleet, liveliness off: peers known by telemetry, as behind the radio) one node
hears nothing for 2.5 s while the others still hear it (their gateways go on predicting
it), at the worst moments of a launch: no member may be lost, no replan."""

from __future__ import annotations

import pytest

from swarm_proto import (
    Mission,
    MissionParams,
    MissionState,
    MissionType,
)
from swarm_sim.core import SITL_HOME
from swarm_sim.fast_fleet import FastFleet
from swarm_sim.scenarios import ready_fleet, square

GCS = 900
MEMBERS = (1, 2, 3)  # seed Albatross VTOLs, pads 30 m apart: they take off in turn


def _fleet(fleet_profiles: dict) -> FastFleet:
    fleet = ready_fleet(MEMBERS, fleet_profiles, spacing_m=30.0)
    assert not fleet.liveliness  # peers known by their telemetry, as behind the radio
    area = square(SITL_HOME.lat_deg + 0.004, SITL_HOME.lon_deg, 200.0)
    params = MissionParams(altitude_rel_m=60.0, side_overlap=0.5, altitude_step_m=10.0)
    fleet.broadcast(Mission(71, GCS, MissionType.AREA, area, params))
    return fleet


@pytest.mark.parametrize("when", ["planning", "launching"])
def test_a_node_deaf_for_2_5_s_at_launch_loses_nobody_and_nobody_replans(
    fleet_profiles: dict, when: str
) -> None:
    fleet = _fleet(fleet_profiles)
    vs = fleet.vehicles
    if when == "planning":  # the roster froze: every node plans
        assert fleet.run_until(lambda: all(v.node.roster.frozen for v in vs.values()), 30)
    else:  # the first vehicle is climbing, the others wait for their turn on the pad
        assert fleet.run_until(lambda: any(v.link.state.armed for v in vs.values()), 120)
    deaf = 2
    fleet.deaf[deaf] = fleet.now + 2.5
    flying = lambda: all(  # noqa: E731
        v.node.manager.mission_state in (MissionState.PREMISSION, MissionState.MISSION)
        and v.link.state.armed
        for v in vs.values()
    )
    assert fleet.run_until(flying, 300), fleet.notes[-20:]
    fleet.run_for(10.0)
    lost = [(vid, t) for _, vid, t in fleet.notes if " lost " in t or "replan" in t]
    assert not lost, lost
    assert all(v.node.roster.generation == 0 for v in vs.values())
