"""The sortie table (mission/sortie.py): the wire MissionState as a checked table."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from swarm_node.core.mission.sortie import TRANSITIONS, IllegalMove, Sortie, Trigger, mermaid
from swarm_proto import MissionState
from tests.conftest import REPO


def test_every_used_state_is_reachable_from_idle() -> None:
    seen, todo = {MissionState.IDLE}, [MissionState.IDLE]
    while todo:
        s = todo.pop()
        for (a, _t), b in TRANSITIONS.items():
            if a == s and b not in seen:
                seen.add(b)
                todo.append(b)
    used = {s for s, _ in TRANSITIONS} | set(TRANSITIONS.values())
    assert seen == used
    # the add/swap states have no moves yet
    assert set(MissionState) - used == {MissionState.SENDING_MISSION, MissionState.WAITING_MISSION}


def test_an_illegal_move_raises() -> None:
    s = Sortie()
    with pytest.raises(IllegalMove):
        s.go(Trigger.STARTED)
    s.begin(keep_progress=False)
    s.go(Trigger.RELEASED)
    s.go(Trigger.STARTED)
    assert s.state == MissionState.MISSION
    assert [m.trigger for m in s.history] == [Trigger.PLAN, Trigger.RELEASED, Trigger.STARTED]


@given(st.lists(st.floats(min_value=0, max_value=2000), max_size=30))
def test_progress_never_falls(samples: list[float]) -> None:
    s = Sortie(state=MissionState.MISSION, path_m=1000.0)
    before = (0.0, 0)
    for x in samples:
        s.advance(x)
        assert (s.progress_m, s.progress_pct) >= before
        assert 0 <= s.progress_pct <= 100 and s.progress_m <= 1000.0
        before = (s.progress_m, s.progress_pct)


def test_the_way_home_keeps_the_progress() -> None:
    s = Sortie(state=MissionState.MISSION, path_m=500.0)
    s.advance(500.0)
    s.begin(keep_progress=True)
    assert s.progress_pct == 100
    s.begin(keep_progress=False)
    assert s.progress_pct == 0 and s.progress_m == 0.0


def test_the_documented_diagram_is_the_table() -> None:
    assert mermaid() in (REPO / "docs" / "state-machine.md").read_text(), "run make docs"


def test_a_mission_started_while_a_replan_runs_stays_in_replan() -> None:
    """A member is lost while this vehicle's StartMission is still on its way: the sortie
    is in REPLAN when the autopilot's answer comes back. The share is flown meanwhile and
    the sortie stays in REPLAN until the replan's outcome (seen in a demo on a loaded
    machine: `IllegalMove: no sortie transition from REPLAN on started` stopped a node)."""
    from swarm_node.core.autopilot.requests import ApResult, StartMission
    from swarm_node.core.mission.share import Member, run_plan
    from swarm_node.core.mission_manager import MissionManager, Phase
    from swarm_node.core.outputs import PlanJob, Submit
    from tests.swarm_node.test_mission_defects import area
    from tests.swarm_node.test_node_core import HOME, flying, profile

    manager = MissionManager(profile(7))
    ap = flying(home=HOME)  # armed and in the air: upload, then StartMission
    mission = area(41, half_m=40.0)  # what one 3.3 Ah quadcopter flies
    outs = manager.release(mission, [Member(profile(7), HOME)], [], ap, 0.0)
    job = next(o for o in outs if isinstance(o, PlanJob))
    outs = manager.on_plan(run_plan(job.request), ap, 0.0)
    for _ in range(5):
        sub = next(o for o in outs if isinstance(o, Submit))
        if isinstance(sub.request, StartMission):
            break
        outs = manager.on_result(ApResult(sub.request.request_id, True), 0.0)
    assert isinstance(sub.request, StartMission)
    manager.begin_replan(0.5)
    assert manager.mission_state == MissionState.REPLAN
    manager.on_result(ApResult(sub.request.request_id, True), 1.0)
    assert manager.phase == Phase.FLYING and manager.mission_state == MissionState.REPLAN


def test_a_mission_started_while_a_replan_began_does_not_crash_the_node() -> None:
    """A member was lost while this
    vehicle's StartMission was in flight; the sortie went REPLAN, then the StartMission
    result raised IllegalMove (REPLAN on started) and the node process died."""
    from swarm_node.core.autopilot.requests import ApResult, StartMission
    from swarm_node.core.mission.sortie import Trigger
    from swarm_node.core.mission_manager import MissionManager, Phase
    from swarm_node.database import seed_profiles
    from swarm_proto import MissionState

    m = MissionManager(seed_profiles()["Generic Quadcopter"])
    m.sortie.begin(keep_progress=False)
    m.sortie.go(Trigger.RELEASED)
    m.phase, m.mission_id, m._steps = Phase.STARTING, 5, [StartMission()]
    (submit,) = m._next(0.0)
    m.begin_replan()
    assert m.sortie.state == MissionState.REPLAN
    m.on_result(ApResult(submit.request.request_id, True), 1.0)  # type: ignore[attr-defined]
    assert m.sortie.state == MissionState.REPLAN and m.phase == Phase.FLYING
