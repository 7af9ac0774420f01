"""A rebooted autopilot never flies by itself (docs/reliability.md): two quadcopters
and a VTOL survey an area in FastFleet (the campaign's mission); vehicle 8's autopilot
reboots at 40 % of its share (it
comes back disarmed where it stood). Its node leaves the fleet at once, every peer's
roster loses it within the 5 s the rule allows, and when another member's node dies
and comes back 20 s later (a replan of the fleet), nothing arms vehicle 8 again: it
stays on the ground until the operator sends it something."""

from __future__ import annotations

from swarm_proto import FsmState
from swarm_sim.faults import MISSIONS, run_fast

MIXED = MISSIONS[1]  # 7, 8 (the victim) and the VTOL 1


def test_a_rebooted_autopilot_hands_its_share_on_and_is_never_armed_again(
    fleet_profiles: dict,
) -> None:
    row = run_fast("reboot an autopilot in flight", MIXED, fleet_profiles)
    print(row)
    assert row.unexpected_arms == 0, row
    assert row.recover_s is not None and row.recover_s <= 5.0, row
    assert row.recovered, row
    assert row.mission_completed and row.coverage >= 0.95, row
    # from the simulator's true positions, the rebooted aircraft on the ground included
    assert row.min_true_sep_m is not None and row.min_true_sep_m >= 10.0, row
    assert FsmState.EMERGENCY.name not in str(row.emergencies)


def test_a_reboot_of_an_idle_vehicle_changes_nothing_but_the_backstop(
    fleet_profiles: dict,
) -> None:
    """On the ground with no mission: no fleet to leave, no alert of a left mission."""
    from swarm_proto import Alert, AlertCode
    from swarm_sim.faults import start_run

    run = start_run(fleet_profiles, MIXED)
    v = run.fleet.vehicles[8]
    run.fleet.reboot_autopilot(8)
    run.run_for(20.0)
    assert v.node.fsm.state == FsmState.GO_MISSION and v.node.fsm.mission_id is None
    assert not [a for a in run.fleet.messages(Alert) if a.code == AlertCode.MISSION_FAILED]
