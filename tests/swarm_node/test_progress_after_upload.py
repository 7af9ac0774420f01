"""A share's progress counts only items the autopilot reached flying that share.

Uploading a mission to an autopilot that flies one in AUTO keeps its current item
index (AP_Mission restarts the new mission's item at that index) until the node's
StartMission sets the first item: meanwhile the autopilot may report that item (deep in
the new share) reached. A `make demo` survivor of the vote (vehicle 5) counted such a
report: its progress jumped 1,500 m down its new share (the field's whole top lane) in
the second it started flying it; lost 20 s later, the inheritance replan took that lane
as flown and nobody flew it (coverage 97.4 %)."""

from __future__ import annotations

import pytest

from swarm_node.core.autopilot.requests import (
    ApRequest,
    ApResult,
    Arm,
    StartMission,
    Takeoff,
    UploadMission,
)
from swarm_node.core.node import AutopilotResult
from swarm_proto import MissionState, VehicleType
from tests.swarm_node.test_mission_defects import area, keep_polling, uploads
from tests.swarm_node.test_node_core import activate, fleet, flying, send

UNDER_WAY = {"mission_reached": 4, "mission_current": 5}


@pytest.mark.parametrize("heard_before_answer", [True, False])
def test_an_item_reported_before_the_replanned_share_starts_is_not_progress(
    heard_before_answer: bool,
) -> None:
    """`heard_before_answer`: the node polled the state with the report before the
    StartMission's answer came (False: the runtime polls at 5 Hz, answers come at once:
    the first state it sees after the answer is the first to hold the report)."""
    held: list[StartMission] = []
    hold = {"on": False}

    def autopilot(node_id: int, req: ApRequest) -> ApResult | None:
        if node_id == 1 and hold["on"] and isinstance(req, StartMission):
            held.append(req)
            return None  # answered below, after the stray report
        return ApResult(req.request_id, True)

    f = fleet(3, autopilot=autopilot)
    activate(f)
    send(f, area(42))
    keep_polling(f, 4.0)
    keep_polling(f, 4.0, **UNDER_WAY)  # every vehicle under way, its progress published
    f.nodes.pop(3)  # vehicle 3 dies: 1 and 2 replan its share
    hold["on"] = True
    end = f.now + 10.0
    while not held and f.now < end:
        keep_polling(f, 0.2, **UNDER_WAY)
    assert held, "vehicle 1 never started its replanned share"
    manager = f.nodes[1].manager
    up = uploads(f, 1)[-1]
    assert isinstance(up, UploadMission) and manager.sortie.state == MissionState.PREMISSION
    # the autopilot flies the new mission from the index it had and reports an item of it
    # reached there, late in the new share, before the StartMission is answered
    stray = manager.last_item - 2
    assert manager.along_m[stray] > 50.0
    if heard_before_answer:
        f.set_autopilot(1, flying(mission_reached=stray, mission_current=stray + 1))
        f.run_until(f.now + 0.2)
    f.deliver(1, AutopilotResult(ApResult(held[0].request_id, True)))
    for _ in range(10):  # flying the share from its first item now
        f.set_autopilot(1, flying(mission_reached=stray, mission_current=1))
        f.set_autopilot(2, flying(**UNDER_WAY))
        f.run_until(f.now + 0.2)
    assert manager.sortie.state == MissionState.MISSION
    assert manager.share_progress_m() < 1.0, manager.share_progress_m()
    # the items it reaches flying the share count again
    f.set_autopilot(1, flying(mission_reached=3, mission_current=4))
    f.run_until(f.now + 0.2)
    assert manager.share_progress_m() > 0.0


def test_the_simulator_reports_an_item_of_a_mission_uploaded_in_auto_before_it_starts() -> None:
    """The premise, over real MAVLink bytes: a plane flying a mission in AUTO gets a new
    one; the simulator (AP_Mission keeps the item index) flies the new item 2 from where
    the old item 2 was, finds it passed and reports it reached, 330 m before the vehicle
    gets there; after StartMission the state shows that item at or beyond the current
    one, which `MissionManager._reached_item` does not count."""
    from swarm_node.core.autopilot.items import Waypoint
    from tests.swarm_node.autopilot.test_flights import SimFlight, offset, ready

    f = SimFlight("plane", VehicleType.PLANE)
    ready(f)

    def wps(*points: tuple[float, float]) -> tuple[Waypoint, ...]:
        return tuple(
            Waypoint(lat_deg=p[0], lon_deg=p[1], alt_rel_m=80.0)
            for p in (offset(n, e) for n, e in points)
        )

    assert f.do(UploadMission(items=wps((600, 0), (1600, 0), (2600, 0)))).ok
    assert f.do(Arm()).ok and f.do(Takeoff(alt_rel_m=60.0)).ok
    f.wait(lambda: (f.state.alt_rel_m or 0.0) > 55.0, 180, "climb")
    assert f.do(StartMission()).ok
    f.wait(
        lambda: f.state.mission_current == 2 and f.state.lat_deg > offset(950, 0)[0], 300, "leg 2"
    )
    assert f.state.mission_reached == 1
    assert f.do(UploadMission(items=wps((900, -800), (1300, 0), (1300, 800)))).ok
    end = f.now + 0.3  # the node's StartMission follows the upload's answer
    while f.now < end:
        f.step()
    assert f.state.mission_reached == 2  # never flown: the vehicle is 300 m short of it
    assert f.do(StartMission()).ok
    assert (f.state.mission_reached, f.state.mission_current) == (2, 1)
