"""Every rule of the paper's state machine, table-driven, plus reachability."""

from __future__ import annotations

from dataclasses import dataclass, field

import pytest

from swarm_node.core.state_machine import (
    ACTION_TARGET,
    RETURN_MISSION,
    RULES,
    TICK_S,
    Action,
    Activated,
    BeginPlan,
    Cancelled,
    Deactivated,
    Emergency,
    Event,
    Facts,
    FollowOperator,
    LandingComplete,
    LeaveFleet,
    LeftFleet,
    MissionComplete,
    MissionFinished,
    MissionStarted,
    NewMission,
    PlanFailed,
    PlanSucceeded,
    RaiseAlert,
    Reattached,
    Rebooted,
    Recalled,
    ReleaseMission,
    Replan,
    Resume,
    ReturnHome,
    Shutdown,
    StandDown,
    StartEmergency,
    StateMachine,
    Unassigned,
    mermaid,
)
from swarm_proto import AlertCode, FsmState, Severity

P, G, E, INACT = FsmState.PLAN, FsmState.GO_MISSION, FsmState.EMERGENCY, FsmState.INACTIVE
OK = Facts(active=True, base_set=True, vehicle_ready=True)
BATT = Emergency(AlertCode.BATTERY_CRITICAL, Severity.CRITICAL)
LINK = Emergency(AlertCode.AUTOPILOT_LINK_LOSS, Severity.EMERGENCY)


def machine(state: FsmState, mission: int | None = 7, released: bool = False) -> StateMachine:
    fsm = StateMachine(plan_timeout_s=30.0, now=0.0)
    fsm.state, fsm.mission_id, fsm.released = state, mission, released
    if state == E:
        fsm.emergency = Emergency(AlertCode.GPS_LOSS, Severity.WARNING)
    return fsm


@dataclass
class Case:
    rule: str
    start: FsmState
    facts: Facts = OK
    events: list[Event] = field(default_factory=list)
    now: float = 1.0
    expect: FsmState = G
    outputs: tuple[type, ...] = ()
    released: bool = False
    mission: int | None = 7
    emergency: Emergency | None = None  # in EMERGENCY: the one it started with


CASES = [
    Case("activate", INACT, expect=G, outputs=(Activated,)),
    Case(
        "deactivate",
        G,
        facts=Facts(active=False, base_set=True, vehicle_ready=True),
        expect=INACT,
        outputs=(Deactivated,),
    ),
    Case(
        "deactivate",
        P,
        facts=Facts(active=True, base_set=False, vehicle_ready=True),
        expect=INACT,
        outputs=(Deactivated,),
    ),
    Case(
        "deactivate",
        E,
        facts=Facts(active=False, base_set=True),
        expect=INACT,
        outputs=(Deactivated,),
    ),
    Case("emergency", G, facts=Facts(True, True, True, BATT), expect=E, outputs=(StartEmergency,)),
    Case("emergency", P, facts=Facts(True, True, True, BATT), expect=E, outputs=(StartEmergency,)),
    Case("escalate", E, facts=Facts(True, True, True, BATT), expect=E, outputs=(StartEmergency,)),
    Case(
        "landed",
        G,
        events=[LandingComplete()],
        expect=INACT,
        outputs=(MissionFinished, Shutdown, Deactivated),
    ),
    Case(
        "mission complete",
        G,
        events=[MissionComplete(7)],
        expect=P,
        outputs=(MissionFinished, BeginPlan),
    ),
    Case(
        "left fleet",
        G,
        events=[LeftFleet("lost")],
        expect=P,
        outputs=(LeaveFleet, RaiseAlert, BeginPlan),
    ),
    Case(
        "cancelled",
        G,
        events=[Cancelled(7)],
        expect=P,
        outputs=(LeaveFleet, RaiseAlert, FollowOperator, BeginPlan),
    ),
    Case(
        "cancelled",
        P,
        events=[Cancelled(7)],
        expect=P,
        outputs=(LeaveFleet, RaiseAlert, FollowOperator, BeginPlan),
    ),
    Case(
        "recalled",
        G,
        events=[Recalled("operator RTL")],
        expect=G,
        outputs=(LeaveFleet, RaiseAlert, FollowOperator),
    ),
    Case(
        "recalled",
        P,
        events=[Recalled("operator LAND")],
        expect=G,
        outputs=(LeaveFleet, RaiseAlert, FollowOperator),
    ),
    Case(
        "autopilot rebooted",
        G,
        events=[Rebooted()],
        expect=G,
        outputs=(LeaveFleet, RaiseAlert, FollowOperator),
    ),
    Case(
        "autopilot rebooted",
        P,
        events=[Rebooted()],
        expect=G,
        outputs=(LeaveFleet, RaiseAlert, FollowOperator),
    ),
    Case("new mission", G, events=[NewMission(9)], expect=P, outputs=(BeginPlan,)),
    Case("new mission", P, events=[NewMission(9)], expect=P, outputs=(BeginPlan,)),
    Case("replan", G, events=[Replan(7)], expect=P, outputs=(BeginPlan,)),
    Case("replan", P, events=[Replan(7)], expect=P, outputs=(BeginPlan,)),
    Case(
        "plan ok", P, events=[PlanSucceeded(7)], expect=G, outputs=(MissionStarted,), released=True
    ),
    Case(
        "plan failed",
        P,
        events=[PlanFailed(7, "no route")],
        expect=G,
        outputs=(RaiseAlert, LeaveFleet, ReturnHome),
    ),
    Case("not chosen", P, events=[Unassigned(7, "not chosen")], expect=G, outputs=(StandDown,)),
    Case("plan timeout", P, now=31.0, expect=G, outputs=(RaiseAlert, LeaveFleet, ReturnHome)),
    Case(
        "fleet synced",
        P,
        facts=Facts(True, True, True, None, fleet_ready=True),
        expect=P,
        outputs=(ReleaseMission,),
    ),
    # an autopilot link-loss emergency ends when the link is back
    Case(
        "link back",
        E,
        facts=Facts(True, True, True, armed=True),
        emergency=LINK,
        expect=P,
        outputs=(LeaveFleet, RaiseAlert, BeginPlan),
    ),
    Case("link back on the ground", E, emergency=LINK, expect=G, outputs=(LeaveFleet, RaiseAlert)),
    Case(
        "reattached",
        G,
        events=[Reattached(7)],
        mission=None,
        expect=G,
        outputs=(Resume, MissionStarted),
    ),
]


def test_an_emergency_other_than_link_loss_does_not_end_when_it_clears() -> None:
    fsm = machine(E)  # a GPS loss
    assert fsm.tick(1.0, Facts(True, True, True, armed=True)) is None and fsm.state == E
    fsm = machine(E)
    fsm.emergency = LINK
    still = Facts(True, True, True, LINK, armed=True)  # the link still down
    assert fsm.tick(1.0, still) is None and fsm.state == E


def test_reattached_is_ignored_with_a_mission_already_in_hand() -> None:
    fsm = machine(G, mission=7)
    fsm.post(Reattached(9))
    assert fsm.tick(1.0, OK) is None and fsm.mission_id == 7


@pytest.mark.parametrize("case", CASES, ids=lambda c: f"{c.start.name}:{c.rule}")
def test_every_transition(case: Case) -> None:
    fsm = machine(case.start, mission=case.mission, released=case.released)
    if case.emergency is not None:
        fsm.emergency = case.emergency
    for ev in case.events:
        fsm.post(ev)
    t = fsm.tick(case.now, case.facts)
    assert t is not None and t.rule == case.rule
    target = ACTION_TARGET[t.action]
    assert fsm.state == case.expect == (case.start if target is None else target)
    assert tuple(type(o) for o in t.outputs) == case.outputs


def test_every_rule_and_state_pair_is_covered() -> None:
    covered = {(c.rule, c.start) for c in CASES}
    for rule in RULES:
        for s in rule.states:
            assert (rule.name, s) in covered, f"no test for {rule.name} in {s.name}"


def test_every_state_is_reachable_from_inactive() -> None:
    seen, frontier = {INACT}, [INACT]
    while frontier:
        s = frontier.pop()
        for rule in RULES:
            if s in rule.states:
                target = ACTION_TARGET[rule.action]
                t = s if target is None else target
                if t not in seen:
                    seen.add(t)
                    frontier.append(t)
    assert seen == set(FsmState)


@pytest.mark.parametrize("missing", ["active", "base_set", "vehicle_ready"])
def test_no_transition_while_inactive_without_a_base_or_ready_vehicle(missing: str) -> None:
    fsm = machine(INACT)
    facts = Facts(**{**dict(active=True, base_set=True, vehicle_ready=True), missing: False})
    fsm.post(NewMission(3))
    for k in range(10):
        assert fsm.tick(k * TICK_S, facts) is None
    assert fsm.state == INACT


def test_stale_plan_results_are_ignored() -> None:
    fsm = machine(P, mission=7)
    fsm.post(PlanSucceeded(6))  # an older mission's answer
    assert fsm.tick(1.0, OK) is None
    assert fsm.state == P and fsm.ignored[-1] == (P, PlanSucceeded(6))


def test_fleet_is_released_once() -> None:
    fsm = machine(P)
    ready = Facts(True, True, True, None, fleet_ready=True)
    assert fsm.tick(0.2, ready) is not None
    assert fsm.tick(0.4, ready) is None  # already released


def test_a_whole_sortie() -> None:
    fsm = StateMachine(plan_timeout_s=30.0)
    t = 0.0

    def tick(facts: Facts = OK) -> list[object]:
        nonlocal t
        t += TICK_S
        tr = fsm.tick(t, facts)
        return tr.outputs if tr else []

    assert tick(Facts(active=True, base_set=False, vehicle_ready=True)) == []
    assert tick() == [Activated()]
    fsm.post(NewMission(11))
    assert tick() == [BeginPlan(11)]
    assert fsm.state == P
    assert tick() == []  # the fleet is not ready yet: wait in PLAN
    assert tick(Facts(True, True, True, None, True)) == [ReleaseMission(11)]
    fsm.post(PlanSucceeded(11))
    assert tick() == [MissionStarted(11)] and fsm.state == G
    fsm.post(MissionComplete(11))
    assert tick() == [MissionFinished(11), BeginPlan(RETURN_MISSION)] and fsm.state == P
    assert tick(Facts(True, True, True, None, True)) == [ReleaseMission(RETURN_MISSION)]
    fsm.post(PlanSucceeded(RETURN_MISSION))
    assert tick() == [MissionStarted(RETURN_MISSION)]
    fsm.post(LandingComplete())
    assert tick() == [MissionFinished(RETURN_MISSION), Shutdown(), Deactivated("landed")]
    assert fsm.state == INACT


def test_an_operator_recall_ends_the_mission_with_the_landing() -> None:
    fsm = machine(G, mission=7)
    fsm.post(Recalled("operator RTL"))
    t = fsm.tick(0.2, OK)
    assert t is not None and t.outputs[-1] == FollowOperator(7, "operator RTL")
    assert (fsm.state, fsm.mission_id) == (G, RETURN_MISSION)
    fsm.post(LandingComplete())
    t = fsm.tick(0.4, OK)
    assert t is not None and t.rule == "landed" and fsm.state == INACT
    assert t.outputs[0] == MissionFinished(RETURN_MISSION)  # mission 7 never completed


def test_a_rebooted_autopilot_leaves_the_mission_and_nothing_replans_it() -> None:
    """Out of the fleet and the mission at once; a later replan of the mission (a peer
    lost) is stale, and only a new mission plans again."""
    fsm = machine(G, mission=7, released=True)
    fsm.post(Rebooted())
    t = fsm.tick(0.2, OK)
    assert t is not None and t.rule == "autopilot rebooted"
    assert t.outputs[0] == LeaveFleet("autopilot rebooted")
    assert t.outputs[-1] == FollowOperator(7, "autopilot rebooted")
    assert (fsm.state, fsm.mission_id, fsm.released) == (G, RETURN_MISSION, False)
    fsm.post(Replan(7))
    assert fsm.tick(0.4, OK) is None and fsm.state == G
    fsm.post(NewMission(9))
    t = fsm.tick(0.6, OK)
    assert t is not None and t.rule == "new mission" and fsm.mission_id == 9


def test_a_reboot_on_the_way_home_ends_no_mission() -> None:
    fsm = machine(G, mission=RETURN_MISSION, released=True)
    fsm.post(Rebooted())
    t = fsm.tick(0.2, OK)
    assert t is not None and t.outputs[-1] == FollowOperator(None, "autopilot rebooted")


def test_emergency_holds_until_shutdown() -> None:
    fsm = machine(G)
    assert fsm.tick(0.2, Facts(True, True, True, BATT)) is not None
    fsm.post(NewMission(4))
    fsm.post(LandingComplete())
    for k in range(5):
        fsm.tick(0.4 + k * TICK_S, OK)  # alert cleared: still in emergency
    assert fsm.state == E
    fsm.tick(2.0, Facts(active=False, base_set=True))
    assert fsm.state == INACT


def test_diagram_lists_every_rule() -> None:
    text = mermaid()
    for rule in RULES:
        assert rule.name in text
    assert all(a in ACTION_TARGET for a in Action)


def test_the_documented_diagram_is_the_table() -> None:
    from tests.conftest import REPO

    assert mermaid() in (REPO / "docs" / "state-machine.md").read_text(), (
        "regenerate the diagram in docs/state-machine.md"
    )


def test_a_vehicle_a_vote_did_not_choose_stands_down_with_no_mission() -> None:
    fsm = machine(P, mission=7, released=True)
    fsm.post(Unassigned(6))  # another mission's vote: not ours
    assert fsm.tick(0.2, OK) is None
    fsm.post(Unassigned(7, "not chosen"))
    t = fsm.tick(0.4, OK)
    assert t is not None and t.outputs == [StandDown(7, "not chosen")]
    assert fsm.state == G and fsm.mission_id is None and not fsm.released


def test_a_replan_of_a_mission_a_newer_one_replaced_is_dropped() -> None:
    """A second mission arrives while the fleet flies the first; a member moving to the
    new mission reads as lost to the old one, whose Replan arrives after NewMission: the
    vehicle plans the new mission, not the old one again (found over real processes:
    mission 92 was never flown, 91 was replanned)."""
    fsm = machine(G, mission=91, released=True)
    fsm.post(NewMission(92))
    fsm.post(Replan(91))
    tr = fsm.tick(0.0, OK)
    assert tr is not None and tr.outputs == [BeginPlan(92)] and fsm.mission_id == 92
    assert fsm.tick(1.0, OK) is None  # the stale replan is dropped, not fired
    fsm.post(Replan(92))
    tr = fsm.tick(2.0, OK)
    assert tr is not None and tr.outputs == [BeginPlan(92, replan=True)]


def test_the_take_off_queue_does_not_count_against_the_plan_timeout() -> None:
    """Six VTOLs at close pads take off in turn, each when the one before is 30 m up
    (safety/pads.py): the last waits about a minute with its plan made. Counted as
    planning, the default 60 s plan timeout sent the last two home from their pads
    (`swarm-sim demo --radio`, 1x). The wait in the queue is not planning; the time
    before and after it is."""
    fsm = machine(P)
    queued = Facts(active=True, base_set=True, vehicle_ready=True, launch_queued=True)
    t = 0.0
    for _ in range(int(10.0 / TICK_S)):  # planning: 10 s
        t += TICK_S
        assert fsm.tick(t, OK) is None
    for _ in range(int(100.0 / TICK_S)):  # in the queue: 100 s (the timeout is 30 s)
        t += TICK_S
        assert fsm.tick(t, queued) is None
    assert fsm.state == P and fsm.plan_elapsed_s(t) == pytest.approx(10.0, abs=0.2)
    for _ in range(int(15.0 / TICK_S)):  # launched, still in PLAN: 25 s in all
        t += TICK_S
        assert fsm.tick(t, OK) is None
    fired = None
    while fired is None and t < 200.0:
        t += TICK_S
        fired = fsm.tick(t, OK)
    assert fired is not None and fired.rule == "plan timeout"
    assert fsm.plan_elapsed_s(t) == 0.0  # not in PLAN any more
    assert t == pytest.approx(130.0, abs=0.3)  # 10 + 100 (queued) + 20 s


def test_a_new_plan_state_forgets_the_last_queue() -> None:
    fsm = machine(P)
    queued = Facts(active=True, base_set=True, vehicle_ready=True, launch_queued=True)
    fsm.tick(1.0, queued)
    fsm.tick(20.0, OK)  # 19 s queued
    fsm.post(Replan(7))
    assert fsm.tick(21.0, OK) is not None and fsm.state == P  # PLAN entered again
    assert fsm.plan_elapsed_s(51.5) == pytest.approx(30.5)
