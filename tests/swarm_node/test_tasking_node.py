"""Voting wired into the node (mission/tasking.py) in the fleet harness: node cores,
scripted autopilots, seeded loss. A QUANTITY mission to idle vehicles and to a flying
fleet; a target report; a ballot that fails."""

from __future__ import annotations

import msgspec
import pytest
from typer.testing import CliRunner

from swarm_node.core.mission.scoring import Candidate, PaperScore, mission_terms
from swarm_node.core.mission.tasking import (
    RetaskError,
    RetaskRules,
    TaskingSettings,
    target_mission_id,
)
from swarm_node.core.mission.voting import rank, score_key
from swarm_node.core.node import NodeCore, NodeSettings, Received
from swarm_node.database import SwarmDatabase, seed_payload_classes
from swarm_node.testing import Fleet
from swarm_proto import (
    AckReason,
    Alert,
    AlertCode,
    FsmState,
    Geometry,
    GeoPoint,
    LatLon,
    Mission,
    MissionParams,
    MissionState,
    MissionType,
    Selector,
    SelectorKind,
    TargetReport,
    TargetSource,
    VehicleStatus,
    Vote,
)
from tests.swarm_node.test_mission_defects import area, uploads
from tests.swarm_node.test_node_core import GCS, acks, activate, flying, profile, send

# distinct batteries (distinct scores), each enough for a share of the area: the split
# gives a vehicle only what its battery flies (a 3.3 Ah quadcopter at 60 % gets nothing)
BATTERY = {1: 95, 2: 80, 3: 88, 4: 84, 5: 78, 6: 99}
UNDER_WAY = dict(mission_reached=4, mission_current=5)


def settings() -> TaskingSettings:
    with SwarmDatabase.memory() as db:
        return TaskingSettings(
            db.module_params("voting"), db.module_params("target re-tasking"), db.payload_classes()
        )


def tasking_fleet(n: int, **kw: object) -> Fleet:
    profiles = {i: profile(i) for i in range(1, n + 1)}
    nodes = {
        i: NodeCore(
            profiles[i],
            NodeSettings(plan_timeout_s=30.0, avoidance=False),  # co-located synthetic vehicles
            fleet_profiles=profiles,
            tasking_settings=settings(),
        )
        for i in profiles
    }
    f = Fleet(nodes, **kw)  # type: ignore[arg-type]
    poll(f, 0.0)
    return f


def poll(f: Fleet, seconds: float, battery: dict[int, int] = BATTERY, **kw: object) -> None:
    """Feed every node its autopilot at 5 Hz: each its own battery (distinct scores)."""
    end = f.now + seconds
    while True:
        for i in f.nodes:
            f.set_autopilot(i, flying(battery_pct=battery[i], **kw))
        if f.now >= end:
            return
        f.run_until(min(end, f.now + 0.2))


def target(mid: int, count: int, payload: str = "") -> Mission:
    sel = Selector(SelectorKind.QUANTITY, quantity=count, payload_model=payload)
    where = Geometry.point(37.4140, -5.9889)  # 310 m north of home
    return Mission(mid, GCS, MissionType.TARGET, where, MissionParams(duration_s=60.0), sel)


def expected_winners(
    f: Fleet, mission: Mission, count: int, among: tuple[int, ...]
) -> tuple[int, ...]:
    """The paper's formula computed here, from each vehicle's own profile and state."""
    score = PaperScore.from_params(settings().voting)
    keys = {}
    for v in among:
        node = f.nodes[v]
        ap = node.autopilot
        me = Candidate.of(node.profile, LatLon(ap.lat_deg, ap.lon_deg), float(ap.battery_pct))  # type: ignore[arg-type]
        keys[v] = score_key(mission_terms(score, mission, me, seed_payload_classes()).score)
    return rank(keys, count)


# ---------------------------------------------------------------------- idle vehicles


def test_idle_vehicles_vote_and_only_the_winners_fly() -> None:
    f = tasking_fleet(4)
    activate(f)
    m = target(51, 2)
    send(f, m)
    poll(f, 6.0)
    assert all(a.accepted for a in acks(f, 51).values())
    want = expected_winners(f, m, 2, (1, 2, 3, 4))
    assert want == (1, 3)  # all at one place: the batteries decide (95 %, 88 %)
    for v in (1, 2, 3, 4):
        n = f.nodes[v]
        if v in want:
            assert n.fsm.mission_id == 51 and n.roster.members == tuple(sorted(want))
            assert len(uploads(f, v)) == 1
        else:
            assert n.fsm.state == FsmState.GO_MISSION and n.fsm.mission_id is None
            assert n.manager.mission_state == MissionState.IDLE and not uploads(f, v)
    # every vehicle decided the same, from the same table
    outcomes = {f.nodes[v].tasking.outcomes[51] for v in (1, 2, 3, 4)}
    assert len(outcomes) == 1 and next(iter(outcomes)).winners == want
    states = {s.mission_state for s in f.messages(VehicleStatus)}
    assert MissionState.VOTING in states


def test_a_vote_with_loss_still_chooses_the_same_winners_everywhere() -> None:
    f = tasking_fleet(4, seed=5, loss=0.2, delay_s=(0.001, 0.02))
    activate(f)
    m = target(52, 1)
    for _ in range(3):  # the ground station repeats a mission until it is answered
        send(f, m)
        poll(f, 1.0)
    poll(f, 12.0)
    decided = {v: f.nodes[v].tasking.outcomes.get(52) for v in (1, 2, 3, 4)}
    assert all(o is not None for o in decided.values()), decided
    assert {o.winners for o in decided.values() if o} == {(1,)}  # 95 %: the best
    assert f.nodes[1].fsm.mission_id == 52
    assert all(f.nodes[v].fsm.mission_id is None for v in (2, 3, 4))


# ---------------------------------------------------------------------- a flying fleet


def fly_area(f: Fleet, mid: int = 41) -> None:
    activate(f)
    send(f, area(mid, half_m=100.0))
    poll(f, 5.0)
    assert all(f.nodes[v].fsm.state == FsmState.GO_MISSION for v in f.nodes)
    poll(f, 3.0, mission_reached=4, mission_current=5)  # under way, progress published


def test_a_flying_fleet_votes_winners_leave_and_the_others_replan() -> None:
    f = tasking_fleet(4)
    fly_area(f)
    m = target(61, 2)
    send(f, m)
    poll(f, 8.0, mission_reached=4, mission_current=5)
    want = expected_winners(f, m, 2, (1, 2, 3, 4))
    stay = tuple(v for v in (1, 2, 3, 4) if v not in want)
    for v in want:
        n = f.nodes[v]
        assert n.fsm.mission_id == 61 and n.roster.mission_id == 61
        assert n.roster.members == tuple(sorted(want)), n.roster.members
        assert 41 not in n.missions
    for v in stay:
        n = f.nodes[v]
        assert n.fsm.mission_id == 41 and n.fsm.state == FsmState.GO_MISSION
        assert n.roster.lost == {w: "voted out" for w in want}
        assert n.roster.planned == stay and n.roster.generation == 1
        assert len(uploads(f, v)) == 2  # the area's share, then the replanned one
    hashes = {f.nodes[v].roster.members_hash for v in stay}
    assert len(hashes) == 1
    chosen = [a for a in f.messages(Alert) if "chosen for mission 61" in a.text]
    assert sorted(a.vehicle_id for a in chosen) == sorted(want)


def test_a_vote_that_cannot_agree_fails_with_an_alert_and_the_fleet_flies_on() -> None:
    f = tasking_fleet(3)
    fly_area(f)
    deliver = f.deliver

    def no_votes(node_id: int, event: object, at: float | None = None) -> None:
        if not (isinstance(event, Received) and isinstance(event.msg, Vote)):
            deliver(node_id, event, at)  # type: ignore[arg-type]

    f.deliver = no_votes  # type: ignore[method-assign]  # every vote is lost, nothing else
    send(f, target(62, 1))
    poll(f, 25.0, mission_reached=4, mission_current=5)
    failed = [a for a in f.messages(Alert) if a.code == AlertCode.MISSION_FAILED]
    assert {a.vehicle_id for a in failed} == {1, 2, 3}
    assert all("vote for mission 62 failed" in a.text for a in failed)
    for v in (1, 2, 3):
        assert f.nodes[v].fsm.mission_id == 41 and 62 not in f.nodes[v].missions


def test_an_idle_vehicle_is_not_a_candidate_while_a_fleet_flies() -> None:
    f = tasking_fleet(4)
    activate(f)
    send(f, area(43, Selector.ids(1, 2, 3), half_m=100.0))
    poll(f, 5.0, mission_reached=4, mission_current=5)
    send(f, target(63, 1))
    poll(f, 1.0, mission_reached=4, mission_current=5)
    a = acks(f, 63)
    assert a[4].reason == AckReason.NOT_ADDRESSED and "mission 43" in a[4].text
    assert all(a[v].accepted for v in (1, 2, 3))


# ---------------------------------------------------------------------- target re-tasking


def report(
    target_id: int, source: int = 2, conf: float = 0.9, klass: str = "person", dlat: float = 0.0
) -> TargetReport:
    return TargetReport(
        target_id,
        source,
        TargetSource.PAYLOAD,
        1000.0,
        GeoPoint(37.4132 + dlat, -5.9889, 10.0),
        klass,
        conf,
    )


def test_a_target_report_tasks_the_rules_count_once() -> None:
    f = tasking_fleet(4)
    fly_area(f)
    send(f, report(7))
    poll(f, 0.2, mission_reached=4, mission_current=5)
    send(f, report(7))  # the detector reports it again
    send(f, report(9, source=3, dlat=0.0002))  # another vehicle sees the same person
    send(f, report(11, conf=0.2, dlat=0.01))  # too unsure
    send(f, report(12, klass="animal", dlat=0.02))  # no rule for animals
    poll(f, 8.0, mission_reached=4, mission_current=5)
    mid = target_mission_id(2, 7)
    assert mid & 0x8000_0000
    outcomes = {f.nodes[v].tasking.outcomes.get(mid) for v in (1, 2, 3, 4)}
    assert len(outcomes) == 1 and None not in outcomes
    (oc,) = outcomes
    assert oc is not None and len(oc.winners) == settings().rules.rule("person")[0] == 2
    for v in oc.winners:
        m = f.nodes[v].missions[mid]
        assert m.mission_type == MissionType.TARGET and m.selection.vehicle_ids == oc.winners
    ids = {v.mission_id for v in f.messages(Vote)}
    assert ids == {mid}  # one mission: the repeat and the duplicate started nothing
    assert f.nodes[1].tasking.counts["target_duplicate"] == 1
    assert f.nodes[1].tasking.counts["target_repeat"] == 1
    assert f.nodes[1].tasking.counts["target_low_confidence"] == 1
    assert f.nodes[1].tasking.counts["target_no_rule"] == 1


def test_the_earliest_report_of_a_target_is_the_one_tasked_whatever_the_order() -> None:
    f = tasking_fleet(3)
    fly_area(f)
    early = msgspec.structs.replace(report(5, source=3, dlat=0.0001), time_unix_s=990.0)
    late = report(4, source=2)
    send(f, late, to=[1, 2])
    send(f, early, to=[3])
    poll(f, 0.1, mission_reached=4, mission_current=5)
    send(f, early, to=[1, 2])
    send(f, late, to=[3])
    poll(f, 8.0, mission_reached=4, mission_current=5)
    ids = {v.mission_id for v in f.messages(Vote)}
    assert ids == {target_mission_id(3, 5)}


def test_retask_rules_from_the_database_and_bad_ones() -> None:
    rules = settings().rules
    assert rules.rule("person") == (2, 0.8) and rules.rule("animal")[0] == 0
    r = RetaskRules.from_params({"count": 1, "count.fire": 3, "min_confidence.fire": 0.5})
    assert r.rule("fire") == (3, 0.5) and r.rule("boat") == (1, 1.0)
    for bad in (
        {"count": 1.5},
        {"count": -1},
        {"min_confidence": 2.0},
        {"speed.person": 1.0},
        {"colour": 1.0},
        {"hold_s": float("nan")},
    ):
        with pytest.raises(RetaskError):
            RetaskRules.from_params(bad)


@pytest.mark.parametrize(
    ("module", "name", "value", "says"),
    [
        ("target re-tasking", "count.person", 1.5, "count.person must be a whole number"),
        ("target re-tasking", "min_confidence", 3.0, "min_confidence must be in [0, 1]"),
        ("voting", "weight_payload", -1.0, "voting weights"),
    ],
)
def test_a_node_refuses_to_start_on_bad_voting_or_retasking_parameters(
    swarm_db: object, module: str, name: str, value: float, says: str
) -> None:
    """The database's parameters are checked when the node starts: one line, exit 2."""
    import sqlite3

    from swarm_node.cli import app as node_app

    with sqlite3.connect(str(swarm_db)) as c:
        c.execute(
            "UPDATE module_params SET value = ? WHERE name = ? AND module_id = "
            "(SELECT id FROM modules WHERE name = ?)",
            (value, name, module),
        )
    r = CliRunner().invoke(node_app, ["run", "--id", "1", "--connect", "tcp/127.0.0.1:1"])
    assert r.exit_code == 2, r.output
    assert says in r.output and "Traceback" not in r.output


def test_twice_in_a_row_the_fleet_the_first_vote_made_votes_next() -> None:
    """Two QUANTITY missions one after the other on the same nodes: the first is voted by
    the idle vehicles, the second by the fleet the first made (the only fleet flying);
    the idle ones are not candidates for it."""
    f = tasking_fleet(4)
    activate(f)
    send(f, target(81, 2))
    poll(f, 6.0, **UNDER_WAY)
    first = f.nodes[1].tasking.outcomes[81].winners
    assert set(first) == {1, 3}
    send(f, target(82, 1))
    poll(f, 8.0, **UNDER_WAY)
    a = acks(f, 82)
    assert a[2].reason == a[4].reason == AckReason.NOT_ADDRESSED and "mission 81" in a[2].text
    assert a[1].accepted and a[3].accepted
    assert f.nodes[1].fsm.mission_id == 82  # 95 % beats 88 %
    assert f.nodes[3].fsm.mission_id == 81 and f.nodes[3].roster.planned == (3,)
    assert f.nodes[3].roster.lost == {1: "voted out"}


def test_a_voter_lost_mid_vote_is_not_waited_for() -> None:
    """The best-placed voter dies as the mission arrives: the others hear it go silent
    (2 s), stop waiting for it and decide among themselves, the same everywhere."""
    f = tasking_fleet(4)
    fly_area(f)
    send(f, target(83, 1), to=[2, 3, 4])  # vehicle 1 (95 %) never gets it: it dies now
    f.nodes.pop(1)
    poll(f, 10.0, **UNDER_WAY)
    outcomes = {f.nodes[v].tasking.outcomes[83] for v in (2, 3, 4)}
    assert len(outcomes) == 1
    (oc,) = outcomes
    assert oc.winners == (3,) and 1 in oc.absent  # 88 %: the best of the living
