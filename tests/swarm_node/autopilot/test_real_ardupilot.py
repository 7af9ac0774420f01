"""What real ArduPilot SITL did to the autopilot link, reproduced with the
simulator (which now behaves that way) and with the scripted fake. Each test failed on
the link before the fix.

- defect 3: a mission uploaded while the vehicle is in AUTO did not start (MISSION_START
  is accepted and ignored): StartMission sets the current item and checks MISSION_CURRENT;
- defect 4: DO_FENCE_ENABLE right after the fence upload was refused (ArduPilot has not
  loaded the fence yet): the enable waits for SYS_STATUS to show the fence present;
- an upload before "ArduPilot Ready" was refused (MISSION_ACK NO_SPACE): transfers wait.
"""

from __future__ import annotations

from swarm_node.core.autopilot import requests as rq
from swarm_node.core.autopilot.events import StatusText
from swarm_node.core.autopilot.items import ItemKind, Waypoint
from swarm_node.core.autopilot.link import LinkCore, LinkSettings
from swarm_node.core.autopilot.requests import ApError
from swarm_proto import VehicleType

from .fake_autopilot import FakeAutopilot, Harness
from .test_flights import SimFlight, distance_m, offset, ready


def _leg(*points: tuple[float, float], alt: float = 20.0) -> list[Waypoint]:
    out = []
    for north, east in points:
        lat, lon = offset(north, east)
        out.append(Waypoint(lat_deg=lat, lon_deg=lon, alt_rel_m=alt))
    return out


def _loiter_at(north: float, east: float, alt: float = 20.0) -> Waypoint:
    lat, lon = offset(north, east)
    return Waypoint(ItemKind.LOITER_UNLIMITED, lat, lon, alt)


def loitering_after_mission_1() -> SimFlight:
    """A simulated copter flown in AUTO to the unlimited loiter ending mission 1."""
    f = SimFlight("copter", VehicleType.COPTER)
    ready(f)
    first = [*_leg((100, 0), (200, 0)), _loiter_at(200, 0)]
    assert f.do(rq.UploadMission(items=tuple(first))).ok
    assert f.do(rq.SetMode(mode="GUIDED")).ok
    assert f.do(rq.Arm()).ok
    assert f.do(rq.Takeoff(alt_rel_m=20.0)).ok
    f.wait(lambda: (f.state.alt_rel_m or 0) > 18.0, 60, "climb")
    assert f.do(rq.StartMission()).ok
    f.wait(lambda: f.state.mission_current == 3, 300, "loitering at the end of mission 1")
    return f


def test_a_mission_uploaded_in_auto_is_started() -> None:
    """Recorded (`mission-start-in-auto`): a copter loitering at the end of mission 1 in
    AUTO gets mission 2; "Auto mission changed but failed to restart command";
    MISSION_START alone leaves it loitering; the link's StartMission flies mission 2."""
    f = loitering_after_mission_1()
    # the way home: uploaded while in AUTO
    second = _leg((150, 60), (40, 60))
    assert f.do(rq.UploadMission(items=tuple(second))).ok
    assert any(
        isinstance(e, StatusText) and "failed to restart command" in e.text for e in f.events
    )
    end = f.now + 10.0
    f.wait(lambda: f.now >= end, 20, "10 s")
    assert f.state.mission_current == 3  # still loitering: nothing started it
    started = f.do(rq.StartMission())
    assert started.ok, started
    target = offset(150, 60)
    f.wait(
        lambda: distance_m(f.state.lat_deg, f.state.lon_deg, *target) < 5.0,
        120,
        "flying mission 2",
    )
    # DO_SET_MISSION_CURRENT 1, then MISSION_START (already in AUTO: no mode change)
    assert f.commands()[-2:] == [("COMMAND_LONG", 224), ("COMMAND_LONG", 300)]


def test_a_mission_that_starts_with_a_do_item_is_started() -> None:
    """MISSION_CURRENT is the current NAV item: a share that starts with DO_CHANGE_SPEED
    (every fixed-wing share, a replanned share) reports the waypoint after it, never the
    item StartMission set. Found when a replan's shares all failed NOT_STARTED; the old
    current item (the loiter at the end of mission 1) still does not count."""
    f = loitering_after_mission_1()
    second = (Waypoint(ItemKind.CHANGE_SPEED, speed_m_s=8.0), *_leg((150, 60), (40, 60)))
    assert f.do(rq.UploadMission(items=second)).ok
    started = f.do(rq.StartMission())
    assert started.ok, started
    target = offset(150, 60)
    f.wait(
        lambda: distance_m(f.state.lat_deg, f.state.lon_deg, *target) < 5.0,
        120,
        "flying mission 2",
    )


def test_a_mission_whose_first_waypoint_is_at_the_current_index_is_started() -> None:
    """Found flying the paper's experiment 1 over processes (`make demo`): a VTOL two
    items into its way home was sent its next mission, whose first NAV item (after its
    DO_CHANGE_SPEED items) had the very index the way home was at. MISSION_CURRENT went
    on reporting that index, which counted as "did not start" (the old current item),
    so the node left the fleet. The first NAV item of the mission just uploaded counts."""
    f = loitering_after_mission_1()
    assert f.state.mission_current == 3
    second = (
        Waypoint(ItemKind.CHANGE_SPEED, speed_m_s=8.0),
        Waypoint(ItemKind.CHANGE_SPEED, speed_m_s=8.0),
        *_leg((150, 60), (40, 60)),
    )
    assert f.do(rq.UploadMission(items=second)).ok
    started = f.do(rq.StartMission())
    assert started.ok, started
    target = offset(150, 60)
    f.wait(
        lambda: distance_m(f.state.lat_deg, f.state.lon_deg, *target) < 5.0,
        120,
        "flying mission 2",
    )


def test_a_mission_that_does_not_start_is_noticed() -> None:
    """An autopilot that accepts everything but never reports the new current item: the
    request fails NOT_STARTED instead of reporting success (the node then falls back)."""
    core = LinkCore(LinkSettings(vehicle_type=VehicleType.COPTER), 1000.0)
    fake = FakeAutopilot("copter")
    fake.report_current = False
    h = Harness(core, fake)
    assert h.run_until(lambda: core.state.link_ok and core.state.has_position, 10)
    result = h.run_request(1, rq.StartMission(), max_s=30)
    assert result is not None and not result.ok
    assert result.error == ApError.NOT_STARTED and "did not start" in result.reason, result


def test_the_first_fence_enable_is_accepted() -> None:
    """Real SITL refused the node's first DO_FENCE_ENABLE after its upload (FENCE_TYPE 4:
    ArduPilot's AC_Fence::present() needs the uploaded fence loaded, which its fence task
    does a moment later). The enable now waits for SYS_STATUS to report the fence present:
    one DO_FENCE_ENABLE, accepted."""
    f = SimFlight("copter", VehicleType.COPTER)
    ready(f)
    assert f.do(rq.SetParam(name="FENCE_TYPE", value=4)).ok
    lat, lon = offset(300, 0)
    up = f.do(rq.UploadFence(exclusion_circles=((lat, lon, 35.0),), enable=True))
    assert up.ok, up
    enables = [m for m in f.sent if m.get_type() == "COMMAND_LONG" and m.command == 207]
    assert len(enables) == 1 and enables[0].param1 == 1
    ap = f.ep.autopilot
    assert ap.params["FENCE_ENABLE"][0] == 1 and ap.fence_present()
    assert f.state.sensors_present & (1 << 20)


def test_an_upload_before_ardupilot_ready_waits_for_it() -> None:
    """Recorded: a MISSION_COUNT before "ArduPilot Ready" (about 0.3 s after the first
    HEARTBEAT) is refused with MISSION_ACK NO_SPACE ("Only 0 items are supported"). The
    link waits for the autopilot to have booted (HEARTBEAT STANDBY) and uploads once."""
    f = SimFlight("copter", VehicleType.COPTER)
    f.wait(lambda: f.state.link_ok, 10, "first HEARTBEAT")
    assert not f.ep.autopilot.ready and not f.state.autopilot_ready
    result = f.do(rq.UploadMission(items=tuple(_leg((50, 0)))))
    assert result.ok, result
    assert [c for c in f.commands() if c[0] == "MISSION_COUNT"] == [("MISSION_COUNT", 2)]
    assert not any(isinstance(e, StatusText) and "Only 0 items" in e.text for e in f.events)
