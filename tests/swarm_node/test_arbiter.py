"""AutopilotArbiter: request ids, results routed to their owner, the precedence table
(EMERGENCY > AVOIDANCE > OPERATOR > MISSION > the modules that never fly), avoidance's
suspension of the mission and the operator's delegation to the mission manager."""

from __future__ import annotations

from hypothesis import given
from hypothesis import strategies as st

from swarm_node.core.arbiter import (
    PRECEDENCE,
    AutopilotArbiter,
    Outcome,
    Routed,
    Send,
    Suspended,
)
from swarm_node.core.autopilot.requests import (
    ApError,
    ApRequest,
    ApResult,
    ChangeAltitude,
    ChangeSpeed,
    DownloadMission,
    Goto,
    Land,
    ReturnToLaunch,
    StartMission,
    UploadFence,
)
from swarm_node.core.outputs import Owner

GOTO = Goto(lat_deg=1.0, lon_deg=2.0, alt_rel_m=30.0)


def sent(outcomes: list[Outcome]) -> ApRequest:
    (one,) = outcomes
    assert isinstance(one, Send)
    return one.request


def test_the_table_is_the_precedence() -> None:
    """One table, highest first, every owner once, in the order of their ranks."""
    owners = [seat.owner for seat in PRECEDENCE]
    assert owners == sorted(Owner, reverse=True)


def test_ids_are_the_arbiters_and_results_go_back_with_the_owners_id() -> None:
    a = AutopilotArbiter()
    m = sent(a.submit(Owner.MISSION, StartMission(request_id=5)))
    f = sent(a.submit(Owner.FENCE, UploadFence(request_id=5)))
    b = sent(a.submit(Owner.BACKSTOP, DownloadMission(request_id=5)))
    r = sent(a.submit(Owner.REATTACH, DownloadMission(request_id=5)))
    c = sent(a.submit(Owner.OPERATOR, Goto(request_id=5, lat_deg=1.0, lon_deg=2.0, alt_rel_m=3.0)))
    assert len({x.request_id for x in (m, f, b, r, c)}) == 5  # all used 5: no id ranges
    assert a.on_result(ApResult(c.request_id, True)) == Routed(Owner.OPERATOR, ApResult(5, True))
    assert a.on_result(ApResult(b.request_id, True)) == Routed(Owner.BACKSTOP, ApResult(5, True))
    assert a.on_result(ApResult(r.request_id, True)) == Routed(Owner.REATTACH, ApResult(5, True))
    assert a.on_result(ApResult(f.request_id, True)) == Routed(Owner.FENCE, ApResult(5, True))
    assert a.on_result(ApResult(m.request_id, False, "x")) == Routed(
        Owner.MISSION, ApResult(5, False, "x")
    )
    assert a.on_result(ApResult(m.request_id, True)) is None and a.stray == 1


def test_a_lower_owner_is_refused_while_a_higher_one_holds_control() -> None:
    a = AutopilotArbiter()
    a.take(Owner.EMERGENCY)
    refused = a.submit(Owner.OPERATOR, ReturnToLaunch(request_id=3))
    assert refused == [
        Routed(
            Owner.OPERATOR, ApResult(3, False, "preempted by EMERGENCY", error=ApError.PREEMPTED)
        )
    ]
    # fence work does not fly the vehicle: never refused
    assert isinstance(sent(a.submit(Owner.FENCE, UploadFence(request_id=1))), UploadFence)
    # the emergency's own requests go out and their results come back to it
    land = sent(a.submit(Owner.EMERGENCY, Land(request_id=1)))
    assert a.on_result(ApResult(land.request_id, False, "denied")) == Routed(
        Owner.EMERGENCY, ApResult(1, False, "denied")
    )
    a.release(Owner.EMERGENCY)
    sent(a.submit(Owner.OPERATOR, ReturnToLaunch(request_id=4)))
    assert a.holder == Owner.OPERATOR
    assert isinstance(a.submit(Owner.MISSION, StartMission(request_id=9))[0], Routed)


def test_the_mission_manager_lands_a_recalled_vehicle_with_the_operators_rank() -> None:
    a = AutopilotArbiter()
    sent(a.submit(Owner.OPERATOR, ReturnToLaunch(request_id=4)))
    a.delegate(Owner.MISSION, Owner.OPERATOR)
    land = sent(a.submit(Owner.MISSION, Land(request_id=9)))
    assert a.holder == Owner.OPERATOR
    assert a.on_result(ApResult(land.request_id, True)) == Routed(Owner.MISSION, ApResult(9, True))
    a.release(Owner.OPERATOR)  # a new mission: the delegation ends with the operator's control
    assert a.holder is None and a.rank(Owner.MISSION) == Owner.MISSION


def test_avoidance_suspends_the_mission_and_gives_control_back() -> None:
    """The mission's flight requests are held (the newest speed only), not refused; the
    operator's are refused; on release the holder before has control again and the
    held requests are ruled on, in order."""
    a = AutopilotArbiter()
    sent(a.submit(Owner.MISSION, StartMission(request_id=1)))
    assert a.suspend(Owner.AVOIDANCE, passing=False) == [Suspended(Owner.MISSION, True)]
    sent(a.submit(Owner.AVOIDANCE, GOTO))
    assert a.holder == Owner.AVOIDANCE and a.suspended_by == Owner.AVOIDANCE
    assert a.submit(Owner.MISSION, ChangeSpeed(speed_m_s=20.0, request_id=2)) == []
    assert a.submit(Owner.MISSION, StartMission(request_id=3)) == []
    assert a.submit(Owner.MISSION, ChangeSpeed(speed_m_s=22.0, request_id=4)) == []
    assert [r.request_id for r in a.held()] == [3, 4]
    assert a.will_steer()
    refused = a.submit(Owner.OPERATOR, GOTO)
    assert isinstance(refused[0], Routed) and "AVOIDANCE" in refused[0].result.reason
    out = a.release(Owner.AVOIDANCE)
    assert out[0] == Suspended(Owner.MISSION, False)
    assert [o.request.request_id for o in out[1:] if isinstance(o, Send)] != []
    assert [type(o.request) for o in out[1:] if isinstance(o, Send)] == [StartMission, ChangeSpeed]
    assert a.holder == Owner.MISSION and a.held() == []


def test_under_a_manoeuvre_flown_on_the_missions_path_its_requests_go_on() -> None:
    a = AutopilotArbiter()
    a.suspend(Owner.AVOIDANCE, passing=True)
    sent(a.submit(Owner.AVOIDANCE, ChangeAltitude(alt_rel_m=80.0)))
    up = sent(a.submit(Owner.MISSION, StartMission(request_id=6)))
    assert a.holder == Owner.AVOIDANCE
    assert a.on_result(ApResult(up.request_id, True)) == Routed(Owner.MISSION, ApResult(6, True))
    a.suspend(Owner.AVOIDANCE, passing=False)  # resuming: held again
    assert a.submit(Owner.MISSION, StartMission(request_id=7)) == []


def test_a_held_request_the_holder_before_outranks_does_not_steer() -> None:
    """The operator held the autopilot when the manoeuvre began: the mission's request
    held meanwhile will be refused when control goes back, so it will not steer (the
    manoeuvre resumes by itself), and is refused on release."""
    a = AutopilotArbiter()
    sent(a.submit(Owner.OPERATOR, GOTO))
    a.suspend(Owner.AVOIDANCE, passing=False)
    assert a.submit(Owner.MISSION, StartMission(request_id=3)) == []
    assert not a.will_steer()
    out = a.release(Owner.AVOIDANCE)
    assert a.holder == Owner.OPERATOR
    assert (
        Routed(Owner.MISSION, ApResult(3, False, "preempted by OPERATOR", error=ApError.PREEMPTED))
        in out
    )


def test_an_emergency_ends_the_suspension_and_drops_what_was_held() -> None:
    a = AutopilotArbiter()
    a.suspend(Owner.AVOIDANCE, passing=False)
    assert a.submit(Owner.MISSION, StartMission(request_id=3)) == []
    assert a.take(Owner.EMERGENCY) == [Suspended(Owner.MISSION, False)]
    assert a.held() == [] and a.suspended_by is None and a.holder == Owner.EMERGENCY
    assert a.release(Owner.AVOIDANCE) == [] and a.holder == Owner.EMERGENCY
    # nothing to suspend under an emergency
    assert a.suspend(Owner.AVOIDANCE, passing=False) == [] and a.holder == Owner.EMERGENCY


@given(
    st.lists(
        st.tuples(st.sampled_from(list(Owner)), st.sampled_from(["submit", "release", "take"])),
        max_size=40,
    )
)
def test_control_never_goes_to_a_lower_owner(steps: list[tuple[Owner, str]]) -> None:
    a = AutopilotArbiter()
    for owner, what in steps:
        before = a.holder
        if what == "release":
            a.release(owner)
            continue
        if what == "take":
            a.take(owner)
            assert a.holder is not None and (before is None or a.holder >= before)
            continue
        out = a.submit(owner, StartMission())
        if before is not None and before > owner:
            assert isinstance(out[0], Routed) and a.holder == before
        else:
            assert isinstance(out[-1], Send) and a.holder == owner
