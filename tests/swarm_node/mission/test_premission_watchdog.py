"""The PREMISSION watchdog: a demo VTOL started its leg and circled a point
for 50 simulated minutes until BATTERY_LOW, its node silent (the autopilot flew round
the leg's first waypoint, past it while the leg was uploaded, and never reached it).
A member still on its leg well past the meet time gives up the meet and flies its share
from where it is, with an alert (`FleetSync.overdue`, `MissionManager._leg_overdue`)."""

from __future__ import annotations

import pytest

from swarm_node.core.autopilot.requests import ApResult, StartMission, UploadMission
from swarm_node.core.mission import fleet_sync
from swarm_node.core.mission.fleet_sync import FleetSync
from swarm_node.core.mission.share import Member, run_plan
from swarm_node.core.mission_manager import MissionManager, Phase
from swarm_node.core.outputs import Note, PlanJob, Publish, Submit
from swarm_proto import Alert, GeoPoint, MissionState
from tests.swarm_node.test_mission_defects import area
from tests.swarm_node.test_node_core import HOME, flying, profile

VTOL = "Albatross 250 VTOL"


def _submitted(outs: list) -> Submit:
    return next(o for o in outs if isinstance(o, Submit))


def _on_its_leg() -> tuple[MissionManager, float]:
    """Vehicle 1 of a pair of airborne VTOLs, its PREMISSION leg uploaded and started;
    returns the manager and the meet time."""
    manager = MissionManager(profile(1, VTOL))
    ap = flying(home=HOME, heading_deg=90.0, groundspeed_m_s=26.0, airspeed_m_s=26.0)
    manager.on_autopilot(ap, 0.0)
    members = [
        Member(profile(1, VTOL), HOME),
        Member(profile(2, VTOL), GeoPoint(37.4112, -5.9880, 10.0)),
    ]
    outs = manager.release(area(41, half_m=150.0), members, [], ap, 0.0)
    job = next(o for o in outs if isinstance(o, PlanJob))
    manager.on_plan(run_plan(job.request), ap, 0.0)
    assert manager.sync.active and manager.phase == Phase.MEETING
    # no ETA from 2 heard: after META_WAIT_S the leg is planned with what was heard
    assert manager.on_autopilot(ap, 1.0) == []
    now = 1.0 + fleet_sync.META_WAIT_S
    up = _submitted(manager.on_autopilot(ap, now))
    assert isinstance(up.request, UploadMission)
    manager.on_result(ApResult(up.request.request_id, True), now)
    start = _submitted(manager.on_autopilot(ap, max(now, manager.sync.depart_unix_s)))
    assert isinstance(start.request, StartMission)
    manager.on_result(ApResult(start.request.request_id, True), now)
    assert manager.phase == Phase.FLYING and manager.sync.flying_leg
    assert manager.mission_state == MissionState.PREMISSION
    return manager, manager.sync.meet_unix_s


def test_a_leg_that_never_reaches_its_entry_is_given_up_for_the_share_with_an_alert() -> None:
    manager, meet = _on_its_leg()
    # the autopilot circles where it is: no item of the leg ever reached
    circling = flying(home=HOME, heading_deg=200.0, groundspeed_m_s=29.6, airspeed_m_s=29.6)
    t = meet - 10.0
    while t < meet + 30.0:  # late, within the grace (LEG_OVERDUE_S): it keeps trying
        outs = manager.on_autopilot(circling, t)
        assert not any(isinstance(o, Publish) for o in outs), t
        t += 1.0
    t = meet + 600.0  # ten minutes on (the demo: fifty)
    outs = manager.on_autopilot(circling, t)
    alerts = [o.msg for o in outs if isinstance(o, Publish) and isinstance(o.msg, Alert)]
    assert alerts and "PREMISSION leg" in alerts[0].text, outs
    assert any(isinstance(o, Note) and "PREMISSION leg" in o.text for o in outs)
    up = _submitted(outs)
    assert isinstance(up.request, UploadMission)  # the share, with an approach from here
    assert not manager.sync.active  # the meet given up
    outs = manager.on_result(ApResult(up.request.request_id, True), t)
    start = _submitted(outs)
    assert isinstance(start.request, StartMission)
    manager.on_result(ApResult(start.request.request_id, True), t)
    assert manager.phase == Phase.FLYING and manager.mission_state == MissionState.MISSION


def test_the_watchdog_waits_longer_for_a_long_leg() -> None:
    assert fleet_sync.LEG_OVERDUE_S == 30.0  # the grace the test above flies through
    s = FleetSync(1, profile(1, VTOL))
    assert s.overdue(1000.0, 0.0) is None  # no leg
    s.group, s.plan = (1, 2), object()  # type: ignore[assignment]
    s.leg = object()  # type: ignore[assignment]
    s.depart_unix_s, s.meet_unix_s = 0.0, 300.0  # a 5-minute leg: 150 s of grace
    assert s.overdue(300.0 + 149.0, 300.0) is None
    assert s.overdue(300.0 + 151.0, 300.0) == pytest.approx(151.0)
    assert s.overdue(300.0 + 151.0, 400.0) is None  # the meet moved later
    s.arrived_at = 320.0  # at the entry: the leg is flown
    assert s.overdue(1000.0, 300.0) is None
