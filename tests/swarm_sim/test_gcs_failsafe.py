"""A dead node's aircraft flies on, as ArduPilot does (docs/reliability.md): the node
sets and verifies its autopilot's GCS failsafe; when the node dies mid-survey its
quadcopter flies on as it was told (its mission in AUTO), then goes home (RTL) once the node's
HEARTBEATs have been gone for the failsafe's timeout. A node back before the timeout
(a restart) leaves it flying."""

from __future__ import annotations

from swarm_node.core.failsafe import COMPANION_TIMEOUT_S, failsafe_params
from swarm_proto import VehicleType
from swarm_sim.faults import MissionSpec, _at_progress, start_run

COPTERS = MissionSpec("survey, 3 quadcopters", (7, 8, 9), 30.0, 8)


def test_a_dead_nodes_copter_flies_its_mission_then_its_failsafe_takes_it_home(
    fleet_profiles: dict,
) -> None:
    run = start_run(fleet_profiles, COPTERS)
    f = run.fleet
    for v in f.vehicles.values():
        assert v.node.fences.failsafe.done
        for name, value in failsafe_params(VehicleType.COPTER):
            assert v.endpoint.autopilot.params.value(name) == value, name
    assert _at_progress(run)
    sim = f.vehicles[8].endpoint.autopilot
    mode = sim.mode_name  # what the node last told it (AUTO, or GUIDED on a leg)
    f.kill_node(8)
    run.run_for(COMPANION_TIMEOUT_S - 1.0)
    assert sim.armed and sim.mode_name == mode  # flown on, as told
    run.run_for(2.0)
    assert sim.mode_name == "RTL" and sim.failsafes.gcs_lost


def test_a_node_back_within_the_timeout_leaves_its_aircraft_flying(fleet_profiles: dict) -> None:
    run = start_run(fleet_profiles, COPTERS)
    assert _at_progress(run)
    f = run.fleet
    sim = f.vehicles[8].endpoint.autopilot
    f.kill_node(8)
    run.run_for(5.0)
    f.restart_node(8)
    run.run_for(COMPANION_TIMEOUT_S)
    assert sim.mode_name != "RTL" and not sim.failsafes.gcs_lost
