"""A short stall costs what it must, not the vehicle (docs/reliability.md): a node
stopped 3 s mid-survey (SIGSTOP; its aircraft flies on) is lost by its peers after 2 s,
but its share is held; back within the hold, flying the same roster, it is a member
again on every node: nobody replans, it flies its own share on instead of going
home."""

from __future__ import annotations

from swarm_sim.faults import MISSION_ID, MISSIONS, _at_progress, start_run


def test_a_node_stalled_3_s_flies_its_share_on_and_nobody_replans(fleet_profiles: dict) -> None:
    spec = MISSIONS[1]  # two quadcopters and a VTOL
    run = start_run(fleet_profiles, spec)
    assert _at_progress(run)
    f, vid = run.fleet, spec.victim
    before = run.share_fraction(vid)
    f.stall(vid, 3.0)
    run.run_for(3.5)
    run.run_for(20.0)
    for v in f.vehicles.values():
        n = v.node
        assert n.roster.generation == 0 and not n.roster.lost and not n.mission.held
        assert n.fsm.mission_id == MISSION_ID and n.manager.phase.value == "flying"
    assert run.share_fraction(vid) > before  # its own share, flown on
