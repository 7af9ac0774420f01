"""Survivors behind the radio replan from the same inputs to the bit (a `--radio`
demo covered 98.2 % before).

Each node used its own progress at full precision and its peers' as the radio carries
them (0.01 m): the inputs of the survivors' replans differed by millimetres, the area
split is not continuous in them (a lane's cut point, which vehicle takes which block),
and in the demo the three survivors each flew a share of a different plan: two flew
the same southern lanes, the middle of the field was nobody's. Now every node publishes
its progress and home on the radio's grid and replans from what it publishes, with the
formula its peers use (mission/published.py)."""

from __future__ import annotations

import math

import pytest

from swarm_node.core.mission.published import along_share, published_home, published_progress
from swarm_proto import CommandKind, GeoPoint, Selector, VehicleInfo, radio
from tests.swarm_node.test_mission_defects import area, keep_polling, uploads
from tests.swarm_node.test_node_core import acks, activate, command, fleet, send
from tests.swarm_node.test_regroup_node import UNDER_WAY, fly, poll, same_fleet
from tests.swarm_node.test_regroup_node import area as fleet_area
from tests.swarm_node.test_tasking_node import tasking_fleet


def on_grid(x: float) -> bool:
    return radio.on_air(VehicleInfo, "mission_progress_m", x) == x


def test_survivors_behind_the_radio_replan_from_the_same_inputs_and_plan() -> None:
    f = fleet(3, over_air=True)
    activate(f)
    send(f, area(41))
    keep_polling(f, 4.0)
    assert all(len(uploads(f, i)) == 1 for i in (1, 2, 3))
    keep_polling(f, 4.0, mission_reached=4, mission_current=5)  # under way, VehicleInfo out
    exact = {i: f.nodes[i].manager.sortie.progress_m for i in (1, 2, 3)}
    assert not all(on_grid(p) for p in exact.values()), exact  # the case: off the grid
    f.nodes.pop(3)  # vehicle 3 dies
    keep_polling(f, 6.0, mission_reached=4, mission_current=5)
    assert all(len(uploads(f, i)) == 2 for i in (1, 2))  # the replanned shares
    used = [f.nodes[i].manager.replanned_from for i in (1, 2)]
    assert used[0] == used[1], used  # to the bit: ours as the others hear it
    p1, p2 = (f.nodes[i].manager.fleet_plan for i in (1, 2))
    assert p1 is not None and p2 is not None and p1.roster == p2.roster == (1, 2)
    assert p1.shares == p2.shares and p1.digest() == p2.digest()  # what the nodes log
    # what a node publishes is on the grid: LAN and radio receivers hear the same
    for i in (1, 2):
        info = f.nodes[i].info()
        assert on_grid(info.mission_progress_m) and on_grid(info.mission_path_m)
        assert radio.quantized(info) == info


def test_a_vehicle_joining_over_the_radio_replays_the_fleets_plan_exactly() -> None:
    """The lineage a joiner replays carries the replan's inputs at the radio's
    resolution: they are on that grid on every member already (before: four nodes,
    four different whole-fleet plans)."""
    f = tasking_fleet(4, over_air=True)
    fly(f, radio.quantized(fleet_area(41, (1, 2, 3))))  # the mission as the radio carries it
    send(f, command(70, CommandKind.JOIN_MISSION, Selector.ids(4), mission_id=41))
    poll(f, 8.0, **UNDER_WAY)
    assert acks(f, 70)[4].accepted
    same_fleet(f, 41, (1, 2, 3, 4))  # one roster, one plan to the waypoint on every node


def test_a_node_counts_its_own_progress_as_its_peers_count_it() -> None:
    """`along_share` is the one formula: from the published (progress, path) the same
    (metres along the share, metres flown before it) on every node; nothing heard is
    nothing flown; out-of-range values clamp into the share."""
    p, path = published_progress(1234.56789, 1200.004 + 5000.0)
    assert (p, path) == (1234.57, 6200.0)
    done, before = along_share(5000.0, p, path)
    assert before == pytest.approx(1200.0) and done == pytest.approx(34.57)
    assert along_share(5000.0, 0.0, 0.0) == (0.0, 0.0)
    assert along_share(5000.0, 9000.0, 6200.0) == (5000.0, 1200.0)
    assert along_share(5000.0, 100.0, 6200.0) == (0.0, 1200.0)
    assert published_progress(math.nan, -3.0) == (0.0, 0.0)
    assert published_progress(math.inf, 2.0e6) == (0.0, 1.0e6)


def test_a_node_publishes_its_home_as_the_radio_carries_it() -> None:
    home = GeoPoint(37.411200004, -5.988560712, 10.13)
    heard = published_home(home)
    assert heard == GeoPoint(37.4112, -5.9885607, 10.25)
    assert published_home(heard) == heard and published_home(None) is None
