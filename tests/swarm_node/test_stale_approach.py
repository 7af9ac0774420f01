"""A share's approach is planned from where the vehicle is; when its upload takes long
(held under an avoidance manoeuvre, a slow link, a loaded host) a fixed-wing has flown
on, and started on the old approach it turns back to it, through whatever the approach
went around. The
mission manager plans the approach again from where the vehicle is before starting it."""

from __future__ import annotations

from swarm_node.core.autopilot.requests import ApResult, StartMission, UploadMission
from swarm_node.core.mission.share import Member, run_plan
from swarm_node.core.mission_manager import MissionManager
from swarm_node.core.outputs import Note, PlanJob, Submit
from swarm_proto import geodesy
from tests.swarm_node.test_mission_defects import area
from tests.swarm_node.test_node_core import HOME, flying, profile

VTOL = "Albatross 250 VTOL"


def _uploading(model: str) -> tuple[MissionManager, Submit]:
    """An airborne vehicle given a share: its upload submitted, StartMission next."""
    manager = MissionManager(profile(1, model))
    ap = flying(home=HOME, heading_deg=90.0, groundspeed_m_s=26.0)
    manager.on_autopilot(ap, 0.0)
    mission = area(41, half_m=150.0 if model == VTOL else 40.0)  # what one can fly
    outs = manager.release(mission, [Member(profile(1, model), HOME)], [], ap, 0.0)
    job = next(o for o in outs if isinstance(o, PlanJob))
    outs = manager.on_plan(run_plan(job.request), ap, 0.0)
    sub = next(o for o in outs if isinstance(o, Submit))
    assert isinstance(sub.request, UploadMission)
    return manager, sub


def _moved(east_m: float) -> dict[str, float]:
    lat, lon = geodesy.offset(37.4112, -5.9889, 0.0, east_m)
    return {"lat_deg": lat, "lon_deg": lon}


def test_a_fixed_wing_that_flew_on_while_uploading_gets_its_approach_planned_again() -> None:
    manager, sub = _uploading(VTOL)
    first = sub.request.items  # type: ignore[attr-defined]
    manager.on_autopilot(flying(home=HOME, heading_deg=90.0, **_moved(150.0)), 5.0)
    outs = manager.on_result(ApResult(sub.request.request_id, True), 5.0)
    again = next(o for o in outs if isinstance(o, Submit))
    assert isinstance(again.request, UploadMission)  # not started on the stale approach
    assert again.request.items != first
    assert any(isinstance(o, Note) and "approach planned again" in o.text for o in outs)
    # uploaded again in time: started
    outs = manager.on_result(ApResult(again.request.request_id, True), 6.0)
    assert isinstance(next(o for o in outs if isinstance(o, Submit)).request, StartMission)


def test_a_vehicle_that_stayed_close_starts_its_share_as_uploaded() -> None:
    for model in (VTOL, "Generic Quadcopter"):
        manager, sub = _uploading(model)
        manager.on_autopilot(flying(home=HOME, heading_deg=90.0, **_moved(5.0)), 1.0)
        outs = manager.on_result(ApResult(sub.request.request_id, True), 1.0)
        assert isinstance(next(o for o in outs if isinstance(o, Submit)).request, StartMission)


def test_planning_again_gives_up_after_three_tries() -> None:
    manager, sub = _uploading(VTOL)
    for k in range(1, 5):
        manager.on_autopilot(flying(home=HOME, heading_deg=90.0, **_moved(150.0 * k)), 5.0 * k)
        outs = manager.on_result(ApResult(sub.request.request_id, True), 5.0 * k)
        sub = next(o for o in outs if isinstance(o, Submit))
        if k <= 3:
            assert isinstance(sub.request, UploadMission), k
    assert isinstance(sub.request, StartMission)  # the autopilot flies to the leg's next item
