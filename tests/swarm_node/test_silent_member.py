"""A silent member is still an aircraft (docs/reliability.md): its autopilot flies its
share on until its GCS failsafe takes it home, so the survivors hold its share for
`silent_hold_s` and fly their own meanwhile; the hold over, they replan it. A member
heard again within the hold, flying the same roster, is a member again: nobody
replans."""

from __future__ import annotations

import dataclasses

from swarm_node.core.failsafe import COMPANION_TIMEOUT_S
from swarm_node.core.node import NodeCore
from swarm_node.core.settings import NodeSettings
from swarm_node.testing import Fleet
from swarm_proto import FsmState
from tests.swarm_node.test_mission_defects import area, keep_polling, uploads
from tests.swarm_node.test_node_core import SETTINGS, activate, flying, profile, send

HOLD = dataclasses.replace(SETTINGS, silent_hold_s=COMPANION_TIMEOUT_S + 5.0)


def _flying_fleet(settings: NodeSettings = HOLD) -> Fleet:
    profiles = {i: profile(i) for i in (1, 2, 3)}
    nodes = {i: NodeCore(profiles[i], settings, fleet_profiles=profiles) for i in profiles}
    f = Fleet(nodes)
    for i in nodes:
        f.set_autopilot(i, flying())
    activate(f)
    keep_polling(f, 0.2)
    send(f, area(41))
    keep_polling(f, 4.0)
    keep_polling(f, 4.0, mission_reached=4, mission_current=5)  # every vehicle under way
    return f


def test_a_silent_members_share_is_held_then_handed_out() -> None:
    f = _flying_fleet()
    assert all(len(uploads(f, i)) == 1 for i in (1, 2, 3))
    node3 = f.nodes.pop(3)  # its node falls silent; its aircraft flies on
    keep_polling(f, 10.0, mission_reached=4, mission_current=5)
    for i in (1, 2):
        n = f.nodes[i]
        assert n.roster.lost == {3: "stale"} and 3 in n.mission.held
        assert n.roster.generation == 0 and len(uploads(f, i)) == 1  # their own shares
        assert n.fsm.state == FsmState.GO_MISSION and n.fsm.mission_id == 41
    keep_polling(f, 8.0, mission_reached=4, mission_current=5)  # the hold is over
    for i in (1, 2):
        n = f.nodes[i]
        assert 3 not in n.mission.held
        assert n.roster.generation == 1 and n.roster.planned == (1, 2)
        assert len(uploads(f, i)) == 2  # 3's lanes handed out
    assert node3.roster.generation == 0


def test_a_member_back_within_the_hold_flies_its_share_on() -> None:
    f = _flying_fleet()
    silent = True
    # 3 unheard and deaf 5 s (a stall, a radio outage): both sides hold the other's share
    f.drop = lambda sender, receiver, msg: silent and 3 in (sender, receiver)
    keep_polling(f, 5.0, mission_reached=4, mission_current=5)
    assert all(f.nodes[i].roster.lost == {3: "stale"} for i in (1, 2))
    assert set(f.nodes[3].mission.held) == {1, 2}
    silent = False
    keep_polling(f, 15.0, mission_reached=4, mission_current=5)
    for i in (1, 2, 3):
        n = f.nodes[i]
        assert n.roster.lost == {} and not n.mission.held
        assert n.roster.generation == 0 and len(uploads(f, i)) == 1  # nobody replanned
        assert n.fsm.state == FsmState.GO_MISSION and n.fsm.mission_id == 41


def test_avoidance_keeps_a_silent_member_until_heard_again() -> None:
    """A member lost by silence reaches avoidance as silent (routes.py), not
    forgotten: its predicted position is a contact until it is heard again."""
    f = _flying_fleet(dataclasses.replace(HOLD, avoidance=True))
    silent = True
    f.drop = lambda sender, receiver, msg: silent and 3 in (sender, receiver)
    keep_polling(f, 5.0, mission_reached=4, mission_current=5)
    for i in (1, 2):
        av = f.nodes[i].avoid.avoider
        assert av.silent == (3,)
        assert av.predicted(3, f.now) is not None
        assert av.counters["silent"] == 1
    silent = False
    keep_polling(f, 3.0, mission_reached=4, mission_current=5)
    assert all(f.nodes[i].avoid.avoider.silent == () for i in (1, 2))  # heard again
