"""What a node restarted in flight does with its vehicle (reattach.py `decide`, pure):
the cases the fault campaign's real processes met besides the FastFleet flights of
tests/swarm_sim/test_reattach.py. A node killed while an avoidance manoeuvre held its
replan's upload found its copter in GUIDED with its old share on the autopilot and its
peers flying on: it must hand the share on (home and down), not leave the vehicle
hovering until its battery runs out."""

from __future__ import annotations

import pytest

from swarm_node.core.autopilot.mission_item import MavCmd, MissionItem
from swarm_node.core.autopilot.state import AutopilotState
from swarm_node.core.declared import SortieRecord
from swarm_node.core.reattach import Decision, decide
from swarm_proto import FsmState, VehicleInfo, VehicleType

ME, PEER, MISSION = 9, 7, 170


def share(n: int) -> tuple[MissionItem, ...]:
    """A share as a node uploads it: home, waypoints, the unlimited loiter at its end."""
    items = [MissionItem(0, MavCmd.NAV_WAYPOINT)]
    items += [MissionItem(k, MavCmd.NAV_WAYPOINT, lat_deg=37.4, lon_deg=-5.9) for k in range(1, n)]
    return (*items, MissionItem(n, MavCmd.NAV_LOITER_UNLIM))


def peer(fsm: FsmState = FsmState.GO_MISSION, members_hash: int = 0x1234) -> VehicleInfo:
    return VehicleInfo(
        vehicle_id=PEER,
        vehicle_type=VehicleType.COPTER,
        model="Generic Quadcopter",
        user_id="QUAD-01",
        mission_id=MISSION,
        fsm_state=fsm,
        members_hash=members_hash,
    )


def flying(mode: str) -> AutopilotState:
    return AutopilotState(sysid=ME, link_ok=True, armed=True, mode_name=mode, alt_rel_m=40.0)


def record(items: int, members_hash: int = 0x1234) -> SortieRecord:
    return SortieRecord(
        MISSION, (7, 9), (7, 9), 1, members_hash, items, items - 1, 500.0, 200.0, 0.0
    )


@pytest.mark.parametrize("mode", ["AUTO", "GUIDED"])
def test_no_record_our_share_flown_by_the_node_while_peers_fly_hands_on(mode: str) -> None:
    d, why = decide(ME, None, share(12), flying(mode), [peer()])
    assert d == Decision.HAND_ON and mode in why


def test_no_record_in_a_pilots_mode_is_left_to_the_operator() -> None:
    assert decide(ME, None, share(12), flying("LOITER"), [peer()])[0] == Decision.LEAVE


def test_no_record_and_no_peer_flying_is_left_to_the_operator() -> None:
    idle = peer(FsmState.INACTIVE)
    assert decide(ME, None, share(12), flying("AUTO"), [idle])[0] == Decision.LEAVE
    assert decide(ME, None, share(12), flying("AUTO"), [])[0] == Decision.LEAVE


def test_a_mission_not_ours_on_the_autopilot_is_left_to_the_operator() -> None:
    theirs = share(12)[:-1]  # no loiter at its end: not a share a node uploaded
    assert decide(ME, None, theirs, flying("AUTO"), [peer()])[0] == Decision.LEAVE
    assert decide(ME, record(13), theirs, flying("AUTO"), [peer()])[0] == Decision.LEAVE


def test_a_share_of_ours_other_than_on_record_while_peers_fly_hands_on() -> None:
    """A replan's share uploaded as the node died (the record still the old one)."""
    d, why = decide(ME, record(20), share(12), flying("AUTO"), [peer()])
    assert d == Decision.HAND_ON and "not the 20 on record" in why


def test_the_share_on_record_in_guided_while_peers_replanned_hands_on() -> None:
    d, why = decide(ME, record(13), share(12), flying("GUIDED"), [peer(members_hash=0x9999)])
    assert d == Decision.HAND_ON and "newer roster" in why


def test_the_share_on_record_alone_continues() -> None:
    d, _ = decide(ME, record(13), share(12), flying("AUTO"), [peer()])
    assert d == Decision.CONTINUE
