"""AutopilotArbiter: request ids, results routed to their owner, precedence
EMERGENCY > AVOIDANCE > OPERATOR > MISSION > FENCE."""

from __future__ import annotations

from hypothesis import given
from hypothesis import strategies as st

from swarm_node.core.arbiter import AutopilotArbiter, Routed
from swarm_node.core.autopilot.requests import (
    ApRequest,
    ApResult,
    Goto,
    Land,
    ReturnToLaunch,
    StartMission,
    UploadFence,
)
from swarm_node.core.outputs import Owner


def test_ids_are_the_arbiters_and_results_go_back_with_the_owners_id() -> None:
    a = AutopilotArbiter()
    m = a.submit(Owner.MISSION, StartMission(request_id=5))
    c = a.submit(Owner.OPERATOR, Goto(request_id=5, lat_deg=1.0, lon_deg=2.0, alt_rel_m=30.0))
    assert isinstance(m, ApRequest) and isinstance(c, ApRequest)
    assert m.request_id != c.request_id  # both owners used 5: no id ranges needed
    assert a.on_result(ApResult(c.request_id, True)) == Routed(Owner.OPERATOR, ApResult(5, True))
    assert a.on_result(ApResult(m.request_id, False, "x")) == Routed(
        Owner.MISSION, ApResult(5, False, "x")
    )
    assert a.on_result(ApResult(m.request_id, True)) is None and a.stray == 1


def test_a_lower_owner_is_refused_while_a_higher_one_holds_control() -> None:
    a = AutopilotArbiter()
    a.take(Owner.EMERGENCY)
    refused = a.submit(Owner.OPERATOR, ReturnToLaunch(request_id=3))
    assert refused == Routed(Owner.OPERATOR, ApResult(3, False, "preempted by EMERGENCY"))
    # fence work does not fly the vehicle: never refused
    assert isinstance(a.submit(Owner.FENCE, UploadFence(request_id=1)), ApRequest)
    # the emergency's own requests go out and their results come back to it
    land = a.submit(Owner.EMERGENCY, Land(request_id=1))
    assert isinstance(land, ApRequest)
    assert a.on_result(ApResult(land.request_id, False, "denied")) == Routed(
        Owner.EMERGENCY, ApResult(1, False, "denied")
    )
    a.release(Owner.EMERGENCY)
    assert isinstance(a.submit(Owner.OPERATOR, ReturnToLaunch(request_id=4)), ApRequest)
    assert a.holder == Owner.OPERATOR
    assert isinstance(a.submit(Owner.MISSION, StartMission(request_id=9)), Routed)
    # the mission manager landing a recalled vehicle asks with the operator's rank
    sent = a.submit(Owner.OPERATOR, Land(request_id=9), route=Owner.MISSION)
    assert isinstance(sent, ApRequest)
    assert a.on_result(ApResult(sent.request_id, True)) == Routed(Owner.MISSION, ApResult(9, True))


@given(st.lists(st.tuples(st.sampled_from(list(Owner)), st.booleans()), max_size=40))
def test_control_never_goes_to_a_lower_owner(steps: list[tuple[Owner, bool]]) -> None:
    a = AutopilotArbiter()
    for owner, release in steps:
        before = a.holder
        if release:
            a.release(owner)
            continue
        sent = a.submit(owner, StartMission())
        if before is not None and before > owner:
            assert isinstance(sent, Routed) and a.holder == before
        else:
            assert isinstance(sent, ApRequest) and a.holder == owner
