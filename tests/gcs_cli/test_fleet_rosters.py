"""`gcs fleets` shows what each node believes its fleet is (gcs_cli/monitor.py
`rosters_of`): the vehicles of a mission grouped by the roster hash each publishes; a
mission flown under two rosters is a split fleet."""

from __future__ import annotations

from gcs_cli.monitor import rosters_of
from swarm_proto import FsmState, VehicleInfo, VehicleType


def _info(vid: int, mission: int, roster: int) -> VehicleInfo:
    return VehicleInfo(
        vid,
        VehicleType.COPTER,
        "q",
        f"U{vid}",
        mission_id=mission,
        fsm_state=FsmState.GO_MISSION,
        members_hash=roster,
    )


def test_one_roster_is_one_fleet_and_two_are_a_split() -> None:
    assert rosters_of([_info(7, 92, 0x1A2B), _info(8, 92, 0x1A2B), _info(9, 0, 0)]) == [
        {"mission": 92, "roster": "0x1a2b", "vehicles": [7, 8], "split": False}
    ]
    split = rosters_of([_info(7, 92, 0x1A2B), _info(9, 92, 0x1A2B), _info(8, 92, 0x0C0D)])
    assert split == [
        {"mission": 92, "roster": "0x0c0d", "vehicles": [8], "split": True},
        {"mission": 92, "roster": "0x1a2b", "vehicles": [7, 9], "split": True},
    ]
