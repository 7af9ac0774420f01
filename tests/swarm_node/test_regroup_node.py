"""Add and swap in the fleet harness (node cores, scripted autopilots): a vehicle joins
a running fleet and the fleet re-splits what is left with it; two fleets exchange
vehicles; a fleet emptied by a swap hands its mission over (swarm/regroup.py)."""

from __future__ import annotations

from swarm_node.testing import Fleet
from swarm_proto import (
    AckReason,
    CommandKind,
    FsmState,
    Geometry,
    Mission,
    MissionParams,
    MissionType,
    PlanLineage,
    Selector,
)
from tests.swarm_node.test_mission_defects import square, uploads
from tests.swarm_node.test_node_core import GCS, acks, activate, command, send
from tests.swarm_node.test_tasking_node import poll as poll_with
from tests.swarm_node.test_tasking_node import tasking_fleet

UNDER_WAY = dict(mission_reached=4, mission_current=5)
FULL = {v: 99 for v in range(1, 7)}  # no share cut short by its battery


def poll(f: Fleet, seconds: float, **kw: object) -> None:
    poll_with(f, seconds, FULL, **kw)


def area(mid: int, ids: tuple[int, ...], north_m: float = 0.0, half_m: float = 100.0) -> Mission:
    geometry: Geometry = square(half_m)
    if north_m:
        geometry = Geometry.polygon(
            [(p.lat_deg + north_m / 111_320.0, p.lon_deg) for p in geometry.points]
        )
    return Mission(
        mid, GCS, MissionType.AREA, geometry, MissionParams(altitude_rel_m=50.0), Selector.ids(*ids)
    )


def fly(f: Fleet, *missions: Mission) -> None:
    activate(f)
    for m in missions:
        send(f, m)
    poll(f, 5.0)
    poll(f, 3.0, **UNDER_WAY)
    for m in missions:
        for v in m.selection.vehicle_ids:
            assert f.nodes[v].fsm.mission_id == m.mission_id, (v, f.notes[-10:])


def same_fleet(f: Fleet, mid: int, ids: tuple[int, ...]) -> None:
    """Every member holds the same roster (hash) and the same whole-fleet plan."""
    nodes = [f.nodes[v] for v in ids]
    assert all(n.fsm.mission_id == mid and n.fsm.state == FsmState.GO_MISSION for n in nodes)
    assert {n.roster.planned for n in nodes} == {tuple(sorted(ids))}
    assert len({n.roster.members_hash for n in nodes}) == 1
    plans = {
        tuple(sorted((v, s.waypoints) for v, s in n.manager.fleet_plan.shares.items()))  # type: ignore[union-attr]
        for n in nodes
    }
    assert len(plans) == 1


def test_a_vehicle_joins_a_running_fleet_and_it_re_splits_what_is_left() -> None:
    f = tasking_fleet(4)
    fly(f, area(41, (1, 2, 3)))
    assert f.nodes[4].fsm.mission_id is None
    send(f, command(70, CommandKind.JOIN_MISSION, Selector.ids(4), mission_id=41))
    poll(f, 8.0, **UNDER_WAY)
    assert acks(f, 70)[4].accepted
    same_fleet(f, 41, (1, 2, 3, 4))
    for v in (1, 2, 3):
        assert f.nodes[v].roster.generation == 1 and len(uploads(f, v)) == 2
    assert len(uploads(f, 4)) == 1  # its share of what was left
    assert f.messages(PlanLineage), "the members told it how the plan came to be"


def test_join_refusals() -> None:
    f = tasking_fleet(4)
    fly(f, area(41, (1, 2, 3)))
    send(f, command(71, CommandKind.JOIN_MISSION, Selector.ids(4), mission_id=99))
    send(f, command(72, CommandKind.JOIN_MISSION, Selector.ids(1), mission_id=41))
    send(
        f,
        command(73, CommandKind.SWAP_MISSION, Selector.ids(4), mission_id=41, other_mission_id=42),
    )
    poll(f, 1.0, **UNDER_WAY)
    assert acks(f, 71)[4].reason == AckReason.NOT_FOUND and "99" in acks(f, 71)[4].text
    assert acks(f, 72)[1].reason == AckReason.DUPLICATE
    assert acks(f, 73)[4].reason == AckReason.NOT_FOUND  # it flies neither
    assert f.nodes[4].fsm.mission_id is None and f.nodes[1].roster.generation == 0


def test_two_fleets_swap_vehicles() -> None:
    f = tasking_fleet(4)
    fly(f, area(41, (1, 2), half_m=60.0), area(42, (3, 4), north_m=250.0, half_m=60.0))
    send(
        f,
        command(
            74, CommandKind.SWAP_MISSION, Selector.ids(2, 3), mission_id=41, other_mission_id=42
        ),
    )
    poll(f, 10.0, **UNDER_WAY)
    assert acks(f, 74)[2].accepted and acks(f, 74)[3].accepted
    same_fleet(f, 41, (1, 3))
    same_fleet(f, 42, (2, 4))


def test_a_fleet_emptied_by_a_swap_hands_its_mission_to_the_other() -> None:
    f = tasking_fleet(3)
    fly(f, area(41, (1,), half_m=50.0), area(42, (2, 3), north_m=250.0, half_m=60.0))
    send(
        f,
        command(75, CommandKind.SWAP_MISSION, Selector.ids(1), mission_id=41, other_mission_id=42),
    )
    poll(f, 8.0, **UNDER_WAY)
    same_fleet(f, 42, (1, 2, 3))
    handed = [m for m in f.messages(PlanLineage) if m.handed_to == 42]
    assert handed and handed[0].mission.mission_id == 41
    assert all(42 in f.nodes[v].regroup.handed for v in (1, 2, 3))
    # each flies its share of 42 to the end, then what is left of 41 (not home)
    poll(f, 3.0, mission_reached=200, mission_current=200)
    poll(f, 3.0, **UNDER_WAY)
    same_fleet(f, 41, (1, 2, 3))
