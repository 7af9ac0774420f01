"""The tasking core alone (mission/tasking.py): who is a candidate, which fleet votes,
the electorate, derived target missions and their ids, duplicates; hypothesis
properties for the derivation."""

from __future__ import annotations

from hypothesis import given
from hypothesis import strategies as st

from swarm_node.core.mission.scoring import Candidate
from swarm_node.core.mission.tasking import (
    RetaskRules,
    Standing,
    Tasking,
    TaskingSettings,
    target_mission,
    target_mission_id,
)
from swarm_node.database import seed_fleet, seed_payload_classes
from swarm_proto import (
    AckReason,
    Geometry,
    GeoPoint,
    LatLon,
    Mission,
    MissionType,
    Selector,
    SelectorKind,
    TargetReport,
    TargetSource,
)

PROFILES = {p.vehicle_id: p for p in seed_fleet()}


def me(vid: int = 1) -> Candidate:
    return Candidate.of(PROFILES[vid], LatLon(37.41, -5.98), 80.0)


def quantity(mid: int = 90, count: int = 2, payload: str = "", fleet: int = 0) -> Mission:
    sel = Selector(SelectorKind.QUANTITY, quantity=count, payload_model=payload, fleet_id=fleet)
    return Mission(mid, 900, MissionType.TARGET, Geometry.point(37.42, -5.98), selection=sel)


def tasking() -> Tasking:
    return Tasking(1, TaskingSettings(payload_classes=seed_payload_classes()), PROFILES)


def test_which_fleet_votes() -> None:
    t = tasking()
    # idle, nobody flying: a candidate (the idle vehicles synchronise in PLAN)
    assert t.answer(quantity(), Standing(1, 0, me(), idle=True))[0] == AckReason.OK
    # peers in PLAN for this very mission are no fleet flying
    st = Standing(1, 0, me(), idle=True, peer_missions={2: 90, 3: 90})
    assert t.answer(quantity(), st)[0] == AckReason.OK
    # idle while a fleet flies: that fleet votes
    st = Standing(1, 0, me(), idle=True, peer_missions={2: 41, 3: 41})
    assert t.answer(quantity(), st) == (AckReason.NOT_ADDRESSED, "the fleet of mission 41 votes")
    # two fleets: the larger votes, whatever the ids
    big = Standing(
        1, 0, me(), flying=70, fleet=(1, 2, 3), peer_missions={2: 70, 3: 70, 4: 41, 5: 41}
    )
    small = Standing(
        4, 0, me(4), flying=41, fleet=(4, 5), peer_missions={1: 70, 2: 70, 3: 70, 5: 41}
    )
    assert t.answer(quantity(), big)[0] == AckReason.OK
    assert t.answer(quantity(), small) == (AckReason.NOT_ADDRESSED, "the fleet of mission 70 votes")
    # a tie: the lower mission id
    tie = Standing(1, 0, me(), flying=70, fleet=(1, 2), peer_missions={2: 70, 4: 41, 5: 41})
    assert t.answer(quantity(), tie)[0] == AckReason.NOT_ADDRESSED
    # the selector's fleet: only its vehicles count
    st = Standing(
        1,
        3,
        me(),
        flying=70,
        fleet=(1, 2),
        peer_fleets={2: 3, 4: 0, 5: 0},
        peer_missions={2: 70, 4: 41, 5: 41},
    )
    assert t.answer(quantity(fleet=3), st)[0] == AckReason.OK
    # replanning, returning: busy; an unknown payload: invalid
    assert (
        t.answer(quantity(), Standing(1, 0, me(), flying=70, replanning=True))[0] == AckReason.BUSY
    )
    assert t.answer(quantity(), Standing(1, 0, me()))[0] == AckReason.BUSY
    assert t.answer(quantity(payload="no such camera"), Standing(1, 0, me(), idle=True))[0] == (
        AckReason.INVALID
    )


def test_one_vote_at_a_time_and_the_electorate() -> None:
    t = tasking()
    st = Standing(
        1,
        0,
        me(),
        flying=70,
        fleet=(1, 2, 3, 4),
        away=frozenset({4}),
        peer_fleets={2: 0, 3: 5, 4: 0},
    )
    electorate, lost = t.electorate(quantity(), st)
    assert electorate == {1, 2, 3, 4} and lost == {4}
    assert t.electorate(quantity(fleet=5), st)[0] == {1, 3}
    out = t.start(quantity(), electorate, lost, me(), 0.0, home=70)
    assert any(type(o).__name__ == "Publish" for o in out)  # our first vote, at once
    assert t.answer(quantity(91), st) == (AckReason.BUSY, "voting for mission 90")
    assert t.answer(quantity(90), st)[0] == AckReason.OK  # the same mission again


def report(tid: int = 5, source: int = 3, cls: str = "person", conf: float = 0.9) -> TargetReport:
    return TargetReport(
        tid, source, TargetSource.PAYLOAD, 100.0, GeoPoint(37.42, -5.98, 0.0), cls, conf
    )


@given(st.integers(1, 65534), st.integers(0, 2**32 - 1))
def test_every_vehicle_derives_the_same_mission_id(source: int, target: int) -> None:
    mid = target_mission_id(source, target)
    assert mid == target_mission_id(source, target)
    assert 0x8000_0000 <= mid <= 0xFFFF_FFFF


def test_a_target_mission_asks_for_the_reporters_payload() -> None:
    rules = RetaskRules.from_params({"count.person": 2, "min_confidence": 0.5, "duration_s": 90})
    m = target_mission(report(), rules, PROFILES, 2)
    assert m.mission_id == target_mission_id(3, 5) and m.issuer_id == 3
    assert m.selection.kind == SelectorKind.QUANTITY and m.selection.quantity == 2
    assert m.selection.payload_model == PROFILES[3].payload_model
    assert m.params.duration_s == 90.0 and m.mission_type == MissionType.TARGET
    operator = TargetReport(5, 900, TargetSource.OPERATOR, 1.0, GeoPoint(37.42, -5.98, 0.0))
    assert target_mission(operator, rules, PROFILES, 2).selection.payload_model == ""


def test_duplicates_and_repeats_start_one_mission() -> None:
    t = tasking()
    t.settings = TaskingSettings(retask={"count": 2, "min_confidence": 0.5, "hold_s": 0.5})
    assert t.on_target(report(5), 0.0) == []
    assert t.on_target(report(5), 0.1) == []  # a repeat
    assert t.on_target(report(6, source=4), 0.2)  # near: a duplicate (a note)
    out = t.on_timer(0.6)
    derived = [o for o in out if type(o).__name__ == "Derived"]
    assert len(derived) == 1 and derived[0].mission.mission_id == target_mission_id(3, 5)
    assert t.counts["target_repeat"] == 1 and t.counts["target_duplicate"] == 1
    assert t.on_target(report(5), 1.0) == [] and t.on_timer(2.0) == []  # still remembered
