"""Node cores joined in a fleet harness: membership, commands and acks, mission
acceptance, fleet synchronisation in PLAN, link loss -> emergency."""

from __future__ import annotations

import msgspec
import pytest

from swarm_node.core.autopilot.requests import (
    ApRequest,
    ApResult,
    Goto,
    Land,
    ReturnToLaunch,
    SetMode,
    UploadMission,
)
from swarm_node.core.autopilot.state import AutopilotState
from swarm_node.core.commands import AnswerCache
from swarm_node.core.identity import IdentityNews
from swarm_node.core.node import AutopilotResult, BadInput, NodeCore, NodeSettings, Received
from swarm_node.core.profile import VehicleProfile
from swarm_node.database import SwarmDatabase, seed_profiles
from swarm_node.runtime.node import mission_defaults_of
from swarm_node.testing import Fleet
from swarm_proto import (
    Ack,
    AckReason,
    AckRef,
    Alert,
    AlertCode,
    Command,
    CommandArgs,
    CommandKind,
    FsmState,
    Geometry,
    GeoPoint,
    GpsFix,
    Mission,
    MissionParams,
    MissionType,
    Selector,
    SelectorKind,
    Severity,
)

HOME = GeoPoint(37.4112, -5.9889, 10.0)
GCS = 900


# every vehicle at one synthetic position (`flying()`): collision avoidance, which would
# rightly climb them apart, is off here (its own tests: tests/swarm_node/safety); a lost
# member's share is replanned at once, as if its aircraft were known out of the way
# (the hold of a silent member's share: test_silent_member.py)
SETTINGS = NodeSettings(plan_timeout_s=20.0, avoidance=False, silent_hold_s=0.0)


def profile(vid: int, model: str = "Generic Quadcopter") -> VehicleProfile:
    """Vehicle `vid` with the parameters of a seed model (the swarm database's seed data,
    never constants of the tests' own)."""
    return msgspec.structs.replace(seed_profiles()[model], vehicle_id=vid, user_id=f"U{vid}")


def flying(**kw: object) -> AutopilotState:
    base: dict[str, object] = dict(
        sysid=1,
        link_ok=True,
        lat_deg=37.4112,
        lon_deg=-5.9889,
        alt_msl_m=110.0,
        alt_rel_m=100.0,
        battery_pct=90,
        battery_v=16.0,
        gps_fix=GpsFix.FIX_3D,
        gps_sats=12,
        ekf_ok=True,
        home=HOME,
        armed=True,
        mode_number=4,
    )
    base.update(kw)
    return AutopilotState(**base)  # type: ignore[arg-type]


def fleet(n: int = 3, **kw: object) -> Fleet:
    profiles = {i: profile(i) for i in range(1, n + 1)}
    nodes = {i: NodeCore(profiles[i], SETTINGS, fleet_profiles=profiles) for i in profiles}
    f = Fleet(nodes, **kw)  # type: ignore[arg-type]
    for i in nodes:
        f.set_autopilot(i, flying())
    return f


def command(seq: int, kind: CommandKind, target: Selector | None = None, **args: object) -> Command:
    return Command(GCS, seq, kind, target or Selector(), CommandArgs(**args))  # type: ignore[arg-type]


def send(f: Fleet, msg: object, to: list[int] | None = None) -> None:
    for nid in to or list(f.nodes):
        f.deliver(nid, Received(msg))  # type: ignore[arg-type]


def acks(f: Fleet, seq: int) -> dict[int, Ack]:
    return {a.vehicle_id: a for a in f.messages(Ack) if a.ref_id == seq}


def test_every_node_lists_the_others() -> None:
    f = fleet(4)
    f.run_until(1.0)
    for nid, node in f.nodes.items():
        assert node.members.live_ids() == [i for i in f.nodes if i != nid]


def test_commands_get_exactly_one_ack_each() -> None:
    f = fleet(3)
    f.run_until(0.5)
    send(f, command(1, CommandKind.SET_BASE, point=HOME))
    send(f, command(2, CommandKind.GOTO, Selector.ids(2), point=GeoPoint(37.42, -5.98, 60.0)))
    send(f, command(3, CommandKind.PARACHUTE, Selector.fleet(5)))  # nobody in fleet 5
    send(f, command(4, CommandKind.SET_SPEED, Selector.ids(1)))  # no value
    f.run_until(1.0)
    assert {v: a.accepted for v, a in acks(f, 1).items()} == {1: True, 2: True, 3: True}
    assert list(acks(f, 2)) == [2] and acks(f, 2)[2].accepted
    goto = [r for _, n, r in f.submitted if n == 2 and isinstance(r, Goto)]
    assert goto and goto[0].alt_rel_m == pytest.approx(50.0)
    assert acks(f, 3) == {}
    assert acks(f, 4)[1].reason == AckReason.INVALID


def test_autopilot_refusal_and_silence_become_acks() -> None:
    def refuse_modes(nid: int, req: ApRequest) -> ApResult | None:
        if isinstance(req, SetMode):
            return ApResult(req.request_id, False, "COMMAND_ACK FAILED (EKF has no position)", 4)
        if isinstance(req, Land):
            return None  # the link never answers
        return ApResult(req.request_id, True)

    f = fleet(1, autopilot=refuse_modes)
    send(f, command(7, CommandKind.SET_MODE, text="guided"))
    send(f, command(8, CommandKind.LAND))
    f.run_until(40.0)
    a7, a8 = acks(f, 7)[1], acks(f, 8)[1]
    assert (a7.accepted, a7.reason) == (False, AckReason.AUTOPILOT_REJECTED) and "EKF" in a7.text
    assert (a8.accepted, a8.reason) == (False, AckReason.TIMEOUT)


def test_commands_need_the_autopilot_link() -> None:
    f = fleet(1)
    f.set_autopilot(1, flying(link_ok=False))
    send(f, command(9, CommandKind.RTL))
    f.run_until(1.0)
    assert acks(f, 9)[1].reason == AckReason.NOT_READY


def test_a_repeated_command_is_answered_again_not_carried_out_twice() -> None:
    slow: list[ApRequest] = []  # the Goto's answer is held back until released

    def hold_goto(nid: int, req: ApRequest) -> ApResult | None:
        if isinstance(req, Goto):
            slow.append(req)
            return None
        return ApResult(req.request_id, True)

    f = fleet(1, autopilot=hold_goto)
    goto = command(21, CommandKind.GOTO, point=GeoPoint(37.42, -5.98, 60.0))
    send(f, goto)
    f.run_until(0.5)
    send(f, goto)  # the ground station repeats it while the autopilot works
    f.run_until(1.0)
    assert len(slow) == 1 and acks(f, 21) == {}
    f.deliver(1, AutopilotResult(ApResult(slow[0].request_id, True)))
    f.run_until(1.5)
    first = [a for a in f.messages(Ack) if a.ref_id == 21]
    assert len(first) == 1 and first[0].accepted
    send(f, goto)  # repeated once more: the answer is lost on the way back, say
    send(f, command(22, CommandKind.SET_FLEET, fleet_id=4))
    send(f, command(22, CommandKind.SET_FLEET, fleet_id=4))
    f.run_until(2.0)
    assert [a for a in f.messages(Ack) if a.ref_id == 21] == first * 2
    assert len(slow) == 1  # one Goto reached the autopilot
    assert [a.accepted for a in f.messages(Ack) if a.ref_id == 22] == [True, True]


def test_a_repeated_mission_is_accepted_once_and_a_rejected_one_checked_again() -> None:
    f = fleet(1)
    f.run_until(0.5)
    send(f, mission(31, (1,)))
    f.run_until(1.0)
    assert acks(f, 31)[1].reason == AckReason.NO_BASE
    send(f, command(30, CommandKind.SET_BASE, point=HOME))
    f.run_until(1.5)
    send(f, mission(31, (1,)))  # fixed: sent again, same id
    f.run_until(2.0)
    send(f, mission(31, (1,)))  # a repeat of the accepted mission
    f.run_until(2.5)
    reasons = [a.reason for a in f.messages(Ack) if a.ref == AckRef.MISSION]
    assert reasons == [AckReason.NO_BASE, AckReason.OK, AckReason.OK]
    assert sum("(new mission)" in t for _, _, t in f.notes) == 1


def test_the_answer_cache_is_bounded() -> None:
    cache = AnswerCache(size=3)
    for seq in range(5):
        cache.taken((AckRef.COMMAND, GCS, seq))
    cache.answered(Ack(1, GCS, AckRef.COMMAND, 4, True))
    assert [cache.seen((AckRef.COMMAND, GCS, s)) for s in range(5)] == [False] * 2 + [True] * 3
    assert cache.answer_of((AckRef.COMMAND, GCS, 4)) == Ack(1, GCS, AckRef.COMMAND, 4, True)
    assert cache.answer_of((AckRef.COMMAND, GCS, 3)) is None


def mission(mid: int, ids: tuple[int, ...]) -> Mission:
    return Mission(
        mid, GCS, MissionType.OBJECTIVE, Geometry.point(37.42, -5.98), selection=Selector.ids(*ids)
    )


def activate(f: Fleet) -> None:
    send(f, command(100, CommandKind.SET_BASE, point=HOME))
    f.run_until(f.now + 1.0)
    assert all(n.fsm.state == FsmState.GO_MISSION for n in f.nodes.values())


def test_mission_acceptance_checks_in_the_papers_order() -> None:
    """Every node answers every mission: NOT_ADDRESSED first (whatever else is wrong
    with a vehicle the mission does not address), then home, base, emergency, ready."""
    f = fleet(4)
    f.set_autopilot(1, flying(home=None))
    f.run_until(0.5)
    send(f, mission(5, (1, 2, 3)))
    f.run_until(1.0)
    reasons = {v: a.reason for v, a in acks(f, 5).items()}
    assert reasons == {
        1: AckReason.HOME_NOT_SET,
        2: AckReason.NO_BASE,
        3: AckReason.NO_BASE,
        4: AckReason.NOT_ADDRESSED,
    }
    # vehicles 2, 3 and 4 get a base; 3's EKF fails: it has a base but is not ready
    send(f, command(100, CommandKind.SET_BASE, point=HOME), to=[2, 3, 4])
    f.set_autopilot(3, flying(ekf_ok=False))
    f.run_until(2.0)
    assert f.nodes[3].base is not None and not f.nodes[3].monitor.ready
    send(f, mission(6, (1, 2, 3)))
    f.run_until(3.0)
    reasons = {v: a.reason for v, a in acks(f, 6).items()}
    assert reasons == {
        1: AckReason.HOME_NOT_SET,
        2: AckReason.OK,
        3: AckReason.NOT_READY,
        4: AckReason.NOT_ADDRESSED,
    }
    # the accepted one answers once the fleet's plan is made, after the refusals
    assert {v: a.accepted for v, a in acks(f, 6).items()} == {1: False, 2: True, 3: False, 4: False}
    # an emergency comes before "not ready"; vehicle 1 is not addressed: NOT_ADDRESSED,
    # although it has no home either
    f.set_autopilot(4, flying(link_ok=False))
    f.run_until(8.5)  # a link loss is an emergency once it lasts 5 s (16)
    assert f.nodes[4].fsm.state == FsmState.EMERGENCY
    send(f, mission(7, (4,)))
    f.run_until(9.5)
    reasons = {v: a.reason for v, a in acks(f, 7).items()}
    assert reasons == {
        1: AckReason.NOT_ADDRESSED,
        2: AckReason.NOT_ADDRESSED,
        3: AckReason.NOT_ADDRESSED,
        4: AckReason.EMERGENCY,
    }


def test_quantity_commands_are_unsupported_and_quantity_missions_have_candidates() -> None:
    """Voting chooses vehicles for missions (mission/tasking.py; test_tasking_node.py):
    the candidates accept, the others answer NOT_ADDRESSED; a command to a voted
    quantity is UNSUPPORTED (commands are answered by the vehicles they address only)."""
    f = fleet(3)
    activate(f)
    send(f, command(40, CommandKind.SET_FLEET, Selector.ids(3), fleet_id=2))
    f.run_until(f.now + 0.5)
    one_of_fleet_2 = Selector(SelectorKind.QUANTITY, fleet_id=2, quantity=1)
    geometry = Geometry.point(37.42, -5.98)
    send(f, Mission(42, GCS, MissionType.OBJECTIVE, geometry, selection=one_of_fleet_2))
    send(f, command(43, CommandKind.RTL, one_of_fleet_2))
    f.run_until(f.now + 1.0)
    assert {v: a.reason for v, a in acks(f, 42).items()} == {
        1: AckReason.NOT_ADDRESSED,
        2: AckReason.NOT_ADDRESSED,
        3: AckReason.OK,
    }
    assert {v: a.reason for v, a in acks(f, 43).items()} == {3: AckReason.UNSUPPORTED}
    assert not any(isinstance(r, ReturnToLaunch) for _, _, r in f.submitted)
    assert f.nodes[3].fsm.mission_id == 42  # the only candidate: chosen
    assert f.nodes[3].tasking.outcomes[42].winners == (3,)


def test_fleet_waits_in_plan_until_all_members_are_there() -> None:
    f = fleet(3)
    activate(f)
    m = mission(11, (1, 2, 3))
    send(f, m, to=[1, 2])  # vehicle 3 has not heard of it yet
    f.run_until(f.now + 5.0)
    assert [f.nodes[i].fsm.state for i in (1, 2)] == [FsmState.PLAN, FsmState.PLAN]
    assert not any(f.nodes[i].fsm.released for i in (1, 2))
    send(f, m, to=[3])
    f.run_until(f.now + 3.0)
    # all three released the mission, planned their share, uploaded it and started it
    for i in (1, 2, 3):
        assert any("PLAN -> GO_MISSION (plan ok)" in t for _, n, t in f.notes if n == i)
        uploads = [r for _, n, r in f.submitted if n == i and isinstance(r, UploadMission)]
        assert len(uploads) == 1 and uploads[0].items
        assert f.nodes[i].fsm.state == FsmState.GO_MISSION


def test_a_lost_member_does_not_hold_the_fleet_back() -> None:
    f = fleet(3)
    activate(f)
    send(f, mission(12, (1, 2, 3)), to=[1, 2])
    f.nodes.pop(3)  # vehicle 3 dies before it hears the mission
    f.run_until(f.now + 4.0)
    for i in (1, 2):
        assert any(n == i and "peer 3 lost" in t for _, n, t in f.notes)
        assert any(n == i and "(fleet synced)" in t for _, n, t in f.notes)


def test_plan_timeout_sends_the_vehicle_home() -> None:
    f = fleet(2)
    activate(f)
    send(f, mission(13, (1, 2)), to=[1])
    f.run_until(f.now + 25.0)  # plan timeout is 20 s; vehicle 2 never plans
    assert any(a.code == AlertCode.PLAN_TIMEOUT for a in f.messages(Alert, sender=1))
    assert any(isinstance(r, ReturnToLaunch) for _, n, r in f.submitted if n == 1)


def test_link_loss_drives_emergency_when_it_lasts_five_seconds() -> None:
    f = fleet(1)
    activate(f)
    t_loss = f.now
    f.set_autopilot(1, flying(link_ok=False))
    f.run_until(t_loss + 4.0)
    node = f.nodes[1]
    assert node.fsm.state != FsmState.EMERGENCY  # a WARNING first (16)
    f.run_until(t_loss + 6.0)
    assert node.fsm.state == FsmState.EMERGENCY
    t_emergency = next(t for t, n, text in f.notes if "-> EMERGENCY" in text)
    # link_emergency_after_s (ArduPilot's 5 s FS_GCS_TIMEOUT), the next 5 Hz tick
    assert 5.0 <= t_emergency - t_loss <= 5.4
    assert any(a.code == AlertCode.AUTOPILOT_LINK_LOSS for a in f.messages(Alert))


def test_bad_input_is_counted() -> None:
    f = fleet(1)
    f.deliver(1, BadInput("bandada/default/cmd/900", "invalid Command"))
    f.run_until(0.5)
    assert f.nodes[1].bad_input["bandada/default/cmd/900"] == 1
    assert f.nodes[1].fsm.state == FsmState.INACTIVE


def test_status_and_info_rates() -> None:
    f = fleet(1)
    f.run_until(10.0)
    from swarm_proto import VehicleInfo, VehicleStatus

    assert 49 <= len(f.messages(VehicleStatus)) <= 52
    assert 10 <= len(f.messages(VehicleInfo)) <= 11


def test_messy_network_still_converges() -> None:
    f = fleet(5, seed=3, loss=0.3, delay_s=(0.0, 0.3))
    f.run_until(5.0)
    for nid, node in f.nodes.items():
        assert node.members.live_ids() == [i for i in f.nodes if i != nid]


def test_unset_mission_parameters_come_from_the_database() -> None:
    with SwarmDatabase.memory() as db:
        defaults = mission_defaults_of(db)
        db.remove("swarm.mission-params", "target", "radius_m")
        db.add(
            "swarm.mission-params",
            {"mission": "target", "name": "radius_m", "value": 175.0, "unit": "m"},
        )
        changed = mission_defaults_of(db)
    assert defaults[MissionType.TARGET] == {
        "altitude_rel_m": 100.0,
        "radius_m": 150.0,
        "altitude_step_m": 10.0,
    }
    profiles = {i: profile(i) for i in (1, 2)}
    f = Fleet(
        {
            i: NodeCore(p, fleet_profiles=profiles, mission_defaults=changed)
            for i, p in profiles.items()
        }
    )
    for i in f.nodes:
        f.set_autopilot(i, flying())
    activate(f)
    point, circle = Geometry.point(37.42, -5.98), Geometry.circle(37.42, -5.98, 60.0)
    send(f, Mission(90, GCS, MissionType.TARGET, point, selection=Selector.ids(1)))
    send(
        f,
        Mission(91, GCS, MissionType.TARGET, point, MissionParams(radius_m=80.0), Selector.ids(2)),
    )
    f.run_until(f.now + 0.5)
    assert f.nodes[1].missions[90].params.radius_m == 175.0  # unset: the database's
    assert f.nodes[2].missions[91].params.radius_m == 80.0  # the operator's
    # a circle's radius is its own; 0 s between landings is "not given" for autoland
    send(f, Mission(92, GCS, MissionType.TARGET, circle, selection=Selector.ids(1)))
    send(f, Mission(93, GCS, MissionType.AUTOLAND, point, selection=Selector.ids(2)))
    f.run_until(f.now + 0.5)
    assert f.nodes[1].missions[92].params.radius_m is None
    assert f.nodes[2].missions[93].params.separation_s == 30.0


def test_a_target_mission_derived_from_a_report_gets_the_database_altitude_step() -> None:
    """Found flying the paper's experiment 1 (`make demo`): the two VTOLs voted out to a
    reported person orbited it at the same height, their phases drifted together (an
    ArduPilot loiter holds no phase) and they came within 1.7 m. The mission derived
    from the report carried altitude step 0, which counted as given, so the database's
    target step (10 m, "vertical separation between vehicles") never applied. A target
    mission's step of 0 is now unset, as AUTOLAND's and MUM-T's are."""
    from swarm_node.core.mission.tasking import target_mission_id
    from swarm_node.runtime.node import tasking_settings_of
    from swarm_proto import GeoPoint, TargetReport, TargetSource

    with SwarmDatabase.memory() as db:
        defaults = mission_defaults_of(db)
        tasking = tasking_settings_of(db)
    step = defaults[MissionType.TARGET]["altitude_step_m"]
    assert step > 0
    profiles = {i: profile(i) for i in (1, 2, 3)}
    f = Fleet(
        {
            i: NodeCore(
                p, fleet_profiles=profiles, mission_defaults=defaults, tasking_settings=tasking
            )
            for i, p in profiles.items()
        }
    )
    for i in f.nodes:
        f.set_autopilot(i, flying())
    activate(f)
    report = TargetReport(
        7, GCS, TargetSource.OPERATOR, f.now, GeoPoint(37.42, -5.98, 0.0), "person", 0.95
    )
    send(f, report)
    f.run_until(f.now + 1.0)
    mid = target_mission_id(GCS, 7)
    held = [n.missions[mid] for n in f.nodes.values() if mid in n.missions]
    assert held, "no vehicle took the target mission up"
    assert all(m.params.altitude_step_m == step for m in held)
    # an operator's step is the operator's
    send(
        f,
        Mission(
            95,
            GCS,
            MissionType.TARGET,
            Geometry.point(37.42, -5.98),
            MissionParams(altitude_step_m=25.0),
            Selector.ids(1),
        ),
    )
    f.run_until(f.now + 0.5)
    assert f.nodes[1].missions[95].params.altitude_step_m == 25.0


def test_an_identity_conflict_refuses_missions_and_untrusted_peers_are_not_members() -> None:

    f = fleet(2)
    f.run_until(0.5)
    send(f, command(40, CommandKind.SET_BASE, point=HOME))
    f.run_until(1.0)
    f.deliver(1, IdentityNews("id 1 also used by session 3f2a9c1d", frozenset()))
    f.deliver(2, IdentityNews("", frozenset({1})))
    f.run_until(1.5)
    alerts = [a for a in f.messages(Alert, 1) if a.code == AlertCode.IDENTITY_CONFLICT]
    assert [(a.severity, a.text) for a in alerts] == [
        (Severity.CRITICAL, "id 1 also used by session 3f2a9c1d")
    ]
    send(f, mission(41, (1, 2)))
    f.run_until(3.0)
    answers = {a.vehicle_id: a for a in f.messages(Ack) if a.ref == AckRef.MISSION}
    assert answers[1].reason == AckReason.NOT_READY
    assert answers[1].text.startswith("identity conflict: id 1 also used")
    assert answers[2].accepted
    assert f.nodes[1].fsm.state != FsmState.EMERGENCY
    assert f.nodes[2].roster.accepted(f.nodes[2].members.peers) == (2,)  # 1 is not a member
    f.deliver(1, IdentityNews("", frozenset()))  # the other source went silent
    f.run_until(3.5)
    assert f.nodes[1].monitor.ready
