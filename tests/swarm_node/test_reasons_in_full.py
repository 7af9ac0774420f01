"""Reasons in full from the node: a refusal names who refused (the node's arbiter or
the autopilot), a plan the batteries cannot fly raises PLAN_FAILED with its numbers
(what each vehicle needs against what it has), and a collision alert carries the other
vehicle, the distance and the time, its text cut at a word with "…"."""

from __future__ import annotations

import msgspec

from swarm_node.core.arbiter import AutopilotArbiter, Claim, Owner, Routed, Submit
from swarm_node.core.autopilot.requests import ApError, ApResult, Land
from swarm_node.core.commands import CommandTracker
from swarm_node.core.mission.share import Member, PlanRequest, run_plan
from swarm_node.database import seed_profiles
from swarm_proto import (
    Ack,
    AckReason,
    AckRef,
    Alert,
    AlertCode,
    Command,
    CommandArgs,
    CommandKind,
    DetailCode,
    Geometry,
    GeoPoint,
    Mission,
    MissionParams,
    MissionType,
    Selector,
    lan,
    radio,
)
from swarm_proto.text import ELLIPSIS
from tests.swarm_node.test_node_core import GCS, HOME, activate, fleet, send

QUAD = seed_profiles()["Generic Quadcopter"]


def square(side_m: float) -> Geometry:
    d_lat, d_lon = side_m / 111_320.0, side_m / (111_320.0 * 0.7943)
    lat, lon = HOME.lat_deg + 0.0005, HOME.lon_deg
    return Geometry.polygon(
        [(lat, lon), (lat, lon + d_lon), (lat + d_lat, lon + d_lon), (lat + d_lat, lon)]
    )


def test_a_refusal_names_who_refused_the_node_or_the_autopilot() -> None:
    """`land` refused during avoidance read "AUTOPILOT_REJECTED: the autopilot refused
    it: preempted by AVOIDANCE" when the node's arbiter had refused it. The arbiter
    marks its refusal (`ApError.PREEMPTED`); no text is read to tell them apart."""
    arbiter = AutopilotArbiter()
    arbiter.rule(Claim(Owner.AVOIDANCE))
    tracker = CommandTracker(7)
    cmd = Command(GCS, 5, CommandKind.LAND, Selector(), CommandArgs())
    (sent,) = tracker.start(cmd, (Land(),), 0.0)
    (refused,) = arbiter.rule(Submit(sent, Owner.OPERATOR))
    assert isinstance(refused, Routed) and refused.result.error == ApError.PREEMPTED
    _, (ack,) = tracker.on_result(refused.result, 0.1)
    assert (ack.accepted, ack.reason) == (False, AckReason.PREEMPTED)
    assert ack.text == "preempted by AVOIDANCE"
    (sent,) = tracker.start(msgspec.structs.replace(cmd, seq=6), (Land(),), 1.0)
    # the autopilot's own words never pass for the arbiter's, whatever they say
    words = ApResult(sent.request_id, False, "preempted by the pilot", error=ApError.DENIED)
    _, (ack,) = tracker.on_result(words, 1.1)
    assert ack.reason == AckReason.AUTOPILOT_REJECTED


def test_a_plan_the_batteries_cannot_fly_says_by_how_much() -> None:
    """The planner's refusal carries the budgets: each vehicle needs more at cruise
    than its battery allows (the figures the text had to cut)."""
    m = Mission(9, GCS, MissionType.AREA, square(1000.0), MissionParams(altitude_rel_m=50.0))
    members = tuple(
        Member(
            msgspec.structs.replace(QUAD, vehicle_id=v), GeoPoint(HOME.lat_deg, HOME.lon_deg, 10)
        )
        for v in (7, 8, 9)
    )
    out = run_plan(PlanRequest(1, m, members, (), 1.75e9, 10.0))
    assert out.plan is None and "endurance" in out.error
    d = out.detail
    assert d is not None and d.code == DetailCode.ENDURANCE and d.vehicle_id == 0
    assert d.needed_s > 2 * d.available_s > 0.0, d
    alone = run_plan(PlanRequest(2, m, members[:1], (), 1.75e9, 10.0)).detail
    assert alone is not None and alone.vehicle_id == 7 and alone.needed_s > d.needed_s


def test_the_fleet_accepts_one_plan_and_a_member_left_nothing_says_so() -> None:
    """Accepted once the plan is made, by every member with the same plan digest; a
    member the split leaves nothing stays on its pad, says so, and raises no
    MISSION_COMPLETE (it flew nothing)."""
    f = fleet(3)
    activate(f)
    m = Mission(
        32,
        GCS,
        MissionType.AREA,
        square(12.0),
        MissionParams(altitude_rel_m=30.0),
        Selector.ids(1, 2, 3),
    )
    send(f, m)
    f.run_until(f.now + 10.0)
    answers = [a for a in f.messages(Ack) if a.ref == AckRef.MISSION and a.ref_id == 32]
    assert sorted(a.vehicle_id for a in answers) == [1, 2, 3]
    assert all(a.accepted and a.reason == AckReason.OK for a in answers)
    assert len({a.text.split(":")[0] for a in answers}) == 1  # "plan <digest>" alike
    idle = [a.vehicle_id for a in answers if "stays on its pad" in a.text]
    assert idle, [a.text for a in answers]
    f.run_until(f.now + 5.0)
    complete = {a.vehicle_id for a in f.messages(Alert) if a.code == AlertCode.MISSION_COMPLETE}
    assert not complete & set(idle)


def test_plan_failed_reaches_the_ground_with_its_numbers() -> None:
    f = fleet(2)
    activate(f)
    m = Mission(
        31,
        GCS,
        MissionType.AREA,
        square(1200.0),
        MissionParams(altitude_rel_m=50.0),
        Selector.ids(1, 2),
    )
    send(f, m)
    f.run_until(f.now + 10.0)
    failed = [a for a in f.messages(Alert) if a.code == AlertCode.PLAN_FAILED]
    assert failed, [a.text for a in f.messages(Alert)]
    # one fleet, one verdict: the mission's answer comes with the plan, refused by every
    # addressed vehicle alike, the endurance budget in it; nobody completes anything
    answers = [a for a in f.messages(Ack) if a.ref == AckRef.MISSION and a.ref_id == 31]
    assert sorted(a.vehicle_id for a in answers) == [1, 2]
    assert {(a.accepted, a.reason, a.text, a.detail) for a in answers} == {
        (False, AckReason.PLAN_FAILED, answers[0].text, answers[0].detail)
    }
    d = answers[0].detail
    assert "endurance" in answers[0].text and d is not None and d.code == DetailCode.ENDURANCE
    assert d.needed_s > d.available_s > 0.0
    assert not [a for a in f.messages(Alert) if a.code == AlertCode.MISSION_COMPLETE]
    for a in failed:
        assert a.detail is not None and a.detail.code == DetailCode.ENDURANCE
        assert a.detail.needed_s > a.detail.available_s > 0.0
        assert len(a.text) <= 64 and (a.text.endswith(ELLIPSIS) or len(a.text) < 64)
        # both encodings carry the numbers
        assert lan.decode(lan.encode(a), Alert) == a
        back = radio.decode(radio.encode(a), now_unix_s=a.time_unix_s)
        assert isinstance(back, Alert) and back.detail is not None
        assert abs(back.detail.needed_s - a.detail.needed_s) < 0.01


def test_a_mission_replaced_before_its_plan_is_answered_so() -> None:
    """Every mission the fleet took up gets an answer: one replaced by a newer before
    its plan was made is refused, naming the newer; the newer is accepted."""
    f = fleet(2)
    activate(f)
    first, second = (
        Mission(n, GCS, MissionType.AREA, square(30.0), MissionParams(altitude_rel_m=30.0))
        for n in (41, 42)
    )
    send(f, msgspec.structs.replace(first, selection=Selector.ids(1, 2)))
    send(f, msgspec.structs.replace(second, selection=Selector.ids(1, 2)))
    f.run_until(f.now + 10.0)
    answers = {(a.ref_id, a.vehicle_id): a for a in f.messages(Ack) if a.ref == AckRef.MISSION}
    for v in (1, 2):
        old, new = answers[(41, v)], answers[(42, v)]
        assert (old.accepted, old.reason) == (False, AckReason.BUSY)
        assert "replaced by mission 42" in old.text
        assert new.accepted, new
