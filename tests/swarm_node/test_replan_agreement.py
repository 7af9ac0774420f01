"""A replan is flown only once the survivors agree on it; a roster hash mismatch is an
event (an alert) and the nodes re-synchronise (mission/agreement.py). Node cores in the
fleet harness with scripted autopilots; links that fail one way (`Fleet.drop`)."""

from __future__ import annotations

from swarm_node.core import state_machine
from swarm_node.core.swarm.roster import members_hash
from swarm_proto import Alert, AlertCode, FsmState, MissionState, VehicleInfo, VehicleStatus
from tests.swarm_node.test_mission_defects import area, keep_polling, uploads
from tests.swarm_node.test_node_core import activate, fleet, send

UNDER_WAY = {"mission_reached": 4, "mission_current": 5}


def under_way(n: int) -> object:
    f = fleet(n)
    activate(f)
    f.submitted.clear()
    keep_polling(f, 0.2)
    send(f, area(41))
    keep_polling(f, 4.0)
    assert all(len(uploads(f, i)) == 1 for i in f.nodes)
    keep_polling(f, 4.0, **UNDER_WAY)  # every vehicle under way, its progress published
    return f


def mismatch_alerts(f: object, vid: int) -> list[Alert]:
    return [a for a in f.messages(Alert, sender=vid) if a.code == AlertCode.ROSTER_MISMATCH]  # type: ignore[attr-defined]


def test_a_replan_is_flown_once_every_survivor_published_the_same_roster() -> None:
    """After 3 is lost, vehicle 1 does not hear the VehicleInfo in which 2 says it
    replanned: 1 holds its replanned share (flying on with the old one, REPLAN in its
    status) until 2's roster hash says 2 planned the same; then it flies it. 2 heard
    1's: it flies at once."""
    f = under_way(3)
    f.nodes.pop(3)  # type: ignore[attr-defined]  # vehicle 3 dies
    replanned = members_hash(41, (1, 2), 1)  # the roster hash of the replan for 1 and 2
    blocked = [True]
    f.drop = lambda s, r, m: (  # type: ignore[attr-defined]
        blocked[0]
        and (s, r) == (2, 1)
        and isinstance(m, VehicleInfo)
        and m.members_hash == replanned
    )
    keep_polling(f, 5.0, **UNDER_WAY)
    n1, n2 = f.nodes[1], f.nodes[2]  # type: ignore[attr-defined]
    assert n2.roster.generation == n1.roster.generation == 1
    assert len(uploads(f, 2)) == 2  # 2 heard 1's hash: it flies the replan
    assert len(uploads(f, 1)) == 1  # 1 did not hear 2's: it holds
    assert n1.mission_state == MissionState.REPLAN and n1.fsm.state == FsmState.PLAN
    blocked[0] = False
    keep_polling(f, 2.0, **UNDER_WAY)
    assert len(uploads(f, 1)) == 2
    assert n1.mission_state == MissionState.MISSION and n1.fsm.state == FsmState.GO_MISSION
    assert n1.roster.members_hash == n2.roster.members_hash
    assert not mismatch_alerts(f, 1) and not mismatch_alerts(f, 2)
    assert n1.manager.fleet_plan.shares == n2.manager.fleet_plan.shares


def test_survivors_that_replanned_for_different_rosters_alert_and_converge() -> None:
    """Vehicle 1 hears nothing from 4 any more (a link that fails one way); then 3
    dies: 1 replans for {1, 2} while 2 and 4 replan for {1, 2, 4}: a mismatch. 1 and 2
    alert ROSTER_MISMATCH, drop their replans and plan again from the roster they all
    flew. Then 4 dies too: once 2 has noticed, 1 and 2 fly the same replan for {1, 2}.
    Before, each flew its own replan: 1 and 2 split the lanes for different rosters."""
    f = under_way(4)
    f.drop = lambda s, r, m: (s, r) == (4, 1)  # type: ignore[attr-defined]
    keep_polling(f, 0.6, **UNDER_WAY)
    f.nodes.pop(3)  # type: ignore[attr-defined]
    keep_polling(f, 3.0, **UNDER_WAY)
    n2 = f.nodes[2]  # type: ignore[attr-defined]
    assert n2.roster.planned == (1, 2, 4) and n2.mission_state == MissionState.REPLAN
    f.nodes.pop(4)  # type: ignore[attr-defined]
    keep_polling(f, 8.0, **UNDER_WAY)
    n1, n2 = f.nodes[1], f.nodes[2]  # type: ignore[attr-defined]
    assert mismatch_alerts(f, 1) and mismatch_alerts(f, 2)
    for n in (n1, n2):
        assert n.roster.planned == (1, 2)
        assert n.fsm.state == FsmState.GO_MISSION and n.mission_state == MissionState.MISSION
    assert n1.roster.members_hash == n2.roster.members_hash
    assert n1.manager.fleet_plan.shares == n2.manager.fleet_plan.shares
    assert n1.manager.fleet_plan.roster == (1, 2)
    assert len(uploads(f, 1)) == len(uploads(f, 2)) == 2  # one replan flown, the agreed one


def test_without_agreement_every_survivor_flies_on_with_its_share() -> None:
    """Vehicle 1 never hears 4 again (one way): it replans for {1, 2}, 2 and 4 for
    {1, 2, 4}. No agreement can come: after the re-synchronisations or the timeout the
    replan is abandoned with an alert; every vehicle flies on with the share it had
    (nobody flies another's lanes; 3's rest stays unflown) and nobody leaves the
    mission (the state machine's plan timeout would have sent them home)."""
    f = under_way(4)
    f.nodes.pop(3)  # type: ignore[attr-defined]
    f.drop = lambda s, r, m: (s, r) == (4, 1)  # type: ignore[attr-defined]
    keep_polling(f, 25.0, **UNDER_WAY)
    for vid in (1, 2, 4):
        n = f.nodes[vid]  # type: ignore[attr-defined]
        assert mismatch_alerts(f, vid), vid
        assert n.fsm.state == FsmState.GO_MISSION and n.fsm.mission_id == 41, vid
        assert n.mission_state == MissionState.MISSION, vid
        assert len(uploads(f, vid)) == 1, vid  # no replan flown
        states = {s.mission_state for s in f.messages(VehicleStatus, sender=vid)}
        assert MissionState.REPLAN in states
    texts = [a.text for a in mismatch_alerts(f, 2)]
    assert any("no replan agreed" in t for t in texts), texts


def fsm_return_mission() -> int:
    return state_machine.RETURN_MISSION


def no_agreement_alerts(f: object, vid: int) -> list[str]:
    return [a.text for a in mismatch_alerts(f, vid) if "no replan agreed" in a.text]


def test_a_replan_slower_than_the_agreement_window_is_still_flown() -> None:
    """Planning is the host's work (wall time): in the demo at 3x on a loaded 2-core
    machine a replan took more than the window's 15 s of simulated time, every
    survivor gave the replan up and flew on with its old share (the lost member's rest
    unflown: 98.4 % covered). The window waits for the others, not for planning: a
    replan made 18 s after the loss is agreed and flown."""
    f = under_way(3)
    f.plan_delay_s = 18.0  # type: ignore[attr-defined]  # the plan timeout: 20 s
    f.nodes.pop(3)  # type: ignore[attr-defined]
    keep_polling(f, 30.0, **UNDER_WAY)
    n1, n2 = f.nodes[1], f.nodes[2]  # type: ignore[attr-defined]
    for vid, n in ((1, n1), (2, n2)):
        assert not no_agreement_alerts(f, vid), vid
        assert len(uploads(f, vid)) == 2, vid  # the replan flown
        assert n.mission_state == MissionState.MISSION and n.fsm.state == FsmState.GO_MISSION
    assert n1.manager.fleet_plan.roster == n2.manager.fleet_plan.roster == (1, 2)
    assert n1.manager.agreement.agreed_in_s[-1] >= 18.0


def test_a_survivor_whose_replan_is_slow_flies_the_replan_the_others_fly() -> None:
    """One node's replan takes 18 s, the other's 0.2 s (one host busier than the other).
    Each publishes the new roster's hash as it starts planning: the fast one agrees and
    flies the replan at once. The slow one, its window counting its planning, gave the
    replan up at 15 s and flew on with its old share: two rosters flown, the lost
    member's rest half unflown. Its planning is not waiting: it flies the same replan."""
    f = under_way(3)
    f.plan_delays = {1: 0.2, 2: 18.0}  # type: ignore[attr-defined]  # plan timeout: 20 s
    f.nodes.pop(3)  # type: ignore[attr-defined]
    keep_polling(f, 10.0, **UNDER_WAY)
    n1, n2 = f.nodes[1], f.nodes[2]  # type: ignore[attr-defined]
    assert len(uploads(f, 1)) == 2 and n1.mission_state == MissionState.MISSION
    assert n2.mission_state == MissionState.REPLAN  # still planning
    keep_polling(f, 15.0, **UNDER_WAY)
    for vid, n in ((1, n1), (2, n2)):
        assert not no_agreement_alerts(f, vid), vid
        assert len(uploads(f, vid)) == 2, vid
        assert n.mission_state == MissionState.MISSION, vid
    assert n1.roster.members_hash == n2.roster.members_hash
    assert n1.manager.fleet_plan.shares == n2.manager.fleet_plan.shares


def test_a_held_replan_is_given_up_when_a_survivor_flies_on_without_replanning() -> None:
    """The window still ends a wait for a survivor that is not planning: vehicle 2
    never hears that 3 is lost (3's liveliness and VehicleInfo reach it, a link that
    fails one way for 1 only), so it flies on in GO_MISSION with the roster all flew.
    1's replan, made at once, is given up 15 s after it was made: 1 flies on."""
    f = under_way(3)
    f.drop = lambda s, r, m: (s, r) == (3, 1)  # type: ignore[attr-defined]
    keep_polling(f, 25.0, **UNDER_WAY)
    n1 = f.nodes[1]  # type: ignore[attr-defined]
    assert n1.mission_state == MissionState.MISSION and n1.fsm.state == FsmState.GO_MISSION
    assert no_agreement_alerts(f, 1) or mismatch_alerts(f, 1)
    assert len(uploads(f, 1)) == 1


def test_a_replan_outcome_after_the_plan_timeout_sent_the_vehicle_home_is_dropped() -> None:
    """A replan slower than the plan timeout: the state machine sends the vehicle home;
    the plan job's outcome, coming after, is an abandoned job's (before, it was taken
    as the mission's plan: an illegal sortie move, MISSION on 'released', raised in the
    node's core)."""
    f = under_way(3)
    f.plan_delay_s = 25.0  # type: ignore[attr-defined]  # the plan timeout: 20 s
    f.nodes.pop(3)  # type: ignore[attr-defined]
    keep_polling(f, 30.0, **UNDER_WAY)
    for vid in (1, 2):
        n = f.nodes[vid]  # type: ignore[attr-defined]
        assert n.manager.mission_id == fsm_return_mission(), vid
        assert len(uploads(f, vid)) == 1, vid  # no replan flown
