"""Collision avoidance as a node module (safety/module.py): manoeuvres flown through the
arbiter as owner AVOIDANCE, the mission suspended and resumed at the right item, the
mission's requests held meanwhile, ADS-B traffic, the zones' ceiling, and the take-off
and landing deconfliction at neighbouring pads."""

from __future__ import annotations

from typing import Any

import msgspec
import pytest

from swarm_node.core.arbiter import AutopilotArbiter, Routed
from swarm_node.core.autopilot.items import ItemKind, Waypoint
from swarm_node.core.autopilot.requests import (
    ApResult,
    Arm,
    ChangeAltitude,
    ChangeSpeed,
    Goto,
    Land,
    ReturnToLaunch,
    StartMission,
    UploadMission,
)
from swarm_node.core.autopilot.state import AdsbReport, AutopilotState
from swarm_node.core.outputs import Note, Owner, Publish, Submit
from swarm_node.core.profile import VehicleProfile
from swarm_node.core.safety.module import AvoidanceModule
from swarm_node.database import seed_profiles
from swarm_proto import (
    Alert,
    AlertCode,
    GeoPoint,
    MissionState,
    NoFlyZone,
    Severity,
    VehicleStatus,
    geodesy,
)

LAT, LON, HOME_MSL = 37.41, -5.99, 10.0
HOME = GeoPoint(LAT, LON, HOME_MSL)
T = 1.8e9


def profile(model: str, vid: int) -> VehicleProfile:
    return msgspec.structs.replace(seed_profiles()[model], vehicle_id=vid, user_id=f"U{vid}")


VTOL = profile("Albatross 250 VTOL", 2)
COPTER = profile("Generic Quadcopter", 8)


def at(north_m: float, east_m: float) -> tuple[float, float]:
    return geodesy.offset(LAT, LON, north_m, east_m)


def ap(**kw: Any) -> AutopilotState:
    lat, lon = at(kw.pop("north", 0.0), kw.pop("east", 0.0))
    rel = kw.pop("alt_rel_m", 60.0)
    base: dict[str, Any] = dict(
        sysid=2,
        link_ok=True,
        armed=True,
        lat_deg=lat,
        lon_deg=lon,
        alt_msl_m=HOME_MSL + rel,
        alt_rel_m=rel,
        home=HOME,
        mode_name="AUTO",
        mission_current=3,
        groundspeed_m_s=25.0,
        vel_east_m_s=25.0,
    )
    base.update(kw)
    return AutopilotState(**base)


def status(vid: int, state: AutopilotState, now: float) -> VehicleStatus:
    assert state.lat_deg is not None and state.lon_deg is not None
    return VehicleStatus(
        vehicle_id=vid,
        time_unix_s=now,
        lat_deg=state.lat_deg,
        lon_deg=state.lon_deg,
        alt_msl_m=state.alt_msl_m or 0.0,
        alt_rel_m=state.alt_rel_m or 0.0,
        vel_north_m_s=state.vel_north_m_s,
        vel_east_m_s=state.vel_east_m_s,
        vel_down_m_s=state.vel_down_m_s,
        armed=state.armed,
        mission_state=MissionState.MISSION,
    )


def head_on_peer(now: float, east_m: float = 600.0, vid: int = 1) -> VehicleStatus:
    return status(vid, ap(east=east_m, vel_east_m_s=-25.0), now)


MISSION_ITEMS = tuple(
    Waypoint(ItemKind.WAYPOINT, *at(0.0, 300.0 * k), 60.0 + 5 * k) for k in range(1, 6)
)


def requests(out: list) -> list:
    return [o.request for o in out if isinstance(o, Submit)]


def tick(m: AvoidanceModule, state: AutopilotState, now: float, **kw: Any) -> list:
    return m.tick(now, status(m.profile.vehicle_id, state, now), state, **kw)


def flying_vtol() -> tuple[AvoidanceModule, AutopilotState]:
    m = AvoidanceModule(VTOL)
    state = ap()
    assert m.on_submit(Submit(UploadMission(items=MISSION_ITEMS), Owner.MISSION), state, T) is None
    return m, state


def test_a_fixed_wing_in_its_mission_climbs_on_its_path_and_comes_back_to_its_item() -> None:
    """A fixed-wing keeps flying its mission (AUTO: its flyable path and schedule), higher:
    a Goto to its item cut the turns, circled it, resumed past it and put a PREMISSION
    fleet 18 s late at its entries (test_premission_flown)."""
    m, state = flying_vtol()
    m.on_peer(head_on_peer(T), T)
    out = tick(m, state, T)
    (climb,) = requests(out)
    assert isinstance(climb, ChangeAltitude) and climb.alt_rel_m > state.alt_rel_m
    assert [o.owner for o in out if isinstance(o, Submit)] == [Owner.AVOIDANCE]
    assert m.active and m.suspension is not None and m.suspension.item == 3
    alert = next(o.msg for o in out if isinstance(o, Publish))
    assert isinstance(alert, Alert) and alert.code == AlertCode.COLLISION_RISK
    assert m.on_result(ApResult(climb.request_id, True), T) == []
    m.forget(1, T + 0.2)
    now, resume = T, None
    while resume is None and now < T + 10:
        now += 0.2
        reqs = requests(tick(m, state, now))
        resume = reqs[0] if reqs else None
    assert isinstance(resume, ChangeAltitude)
    assert resume.alt_rel_m == MISSION_ITEMS[2].alt_rel_m  # the item it flies to
    assert now - T >= 3.0  # the clear hold
    assert not m.release_due
    m.on_result(ApResult(resume.request_id, True), now)
    assert m.release_due and not m.active


def test_under_a_fixed_wings_climb_the_missions_requests_go_on_at_once() -> None:
    """The mission's requests are not held while a fixed-wing climbs on its path: they
    go on ranked as the manoeuvre (results to the mission), and the climb is asked again
    at the new mission's item. Held, a fleet stacked at a route's end never went home."""
    m, state = flying_vtol()
    m.on_peer(head_on_peer(T), T)
    (climb,) = requests(tick(m, state, T))
    m.on_result(ApResult(climb.request_id, True), T)
    home = (
        Waypoint(ItemKind.WAYPOINT, *at(0.0, 100.0), 60.0),
        Waypoint(ItemKind.RTL, 0.0, 0.0, 0.0),
    )
    subs, answer = m.on_submit(
        Submit(UploadMission(items=home, request_id=5), Owner.MISSION), state, T
    ) or ([], None)
    assert answer is None and [(o.owner, o.route) for o in subs] == [
        (Owner.AVOIDANCE, Owner.MISSION)
    ]
    (up,) = subs
    assert isinstance(up, Submit) and isinstance(up.request, UploadMission)
    assert up.request.items[-1].kind == ItemKind.LAND  # home to its pad, as without avoidance
    assert m.on_submit(up, state, T) is None  # passed on: not intercepted twice
    start = Submit(StartMission(request_id=6), Owner.MISSION)
    assert m.on_submit(start, state, T) == (
        [Submit(start.request, Owner.AVOIDANCE, Owner.MISSION)],
        None,
    )
    arb = AutopilotArbiter(holder=Owner.AVOIDANCE)
    assert not isinstance(arb.submit(Owner.AVOIDANCE, start.request, Owner.MISSION), Routed)
    state = msgspec.structs.replace(state, mission_current=1)  # the new mission's first item
    (again,) = requests(tick(m, state, T + 0.2))
    assert isinstance(again, ChangeAltitude) and again.alt_rel_m == climb.alt_rel_m
    assert m.held == []


def test_with_a_zone_a_fixed_wing_flies_its_mission_on_at_the_new_altitude() -> None:
    """With a zone in force a Goto could cut the flyable turns and circle the item into
    it: the fixed-wing keeps flying its mission in AUTO at the avoidance altitude, asked
    again at each new item (each brings its own altitude), and back to its item's when
    clear."""
    from swarm_proto import Geometry

    m, state = flying_vtol()
    zone = NoFlyZone(1, Geometry.circle(*at(2000.0, 2000.0), 35.0))  # any zone in force
    m.on_peer(head_on_peer(T), T)
    out = tick(m, state, T, zones={1: zone})
    (climb,) = requests(out)
    assert isinstance(climb, ChangeAltitude) and climb.alt_rel_m > state.alt_rel_m
    m.on_result(ApResult(climb.request_id, True), T)
    state = msgspec.structs.replace(state, mission_current=4)  # the next item: asked again
    (again,) = requests(tick(m, state, T + 0.2, zones={1: zone}))
    assert isinstance(again, ChangeAltitude) and again.alt_rel_m == climb.alt_rel_m
    m.on_result(ApResult(again.request_id, True), T + 0.2)
    m.forget(1, T + 0.2)
    now, resume = T + 0.2, None
    while resume is None and now < T + 10:
        now += 0.2
        reqs = requests(tick(m, state, now, zones={1: zone}))
        resume = reqs[0] if reqs else None
    assert isinstance(resume, ChangeAltitude) and resume.alt_rel_m == MISSION_ITEMS[3].alt_rel_m


def test_a_multirotor_in_its_mission_stops_at_its_item_and_resumes_there() -> None:
    m = AvoidanceModule(COPTER)
    state = ap(groundspeed_m_s=10.0, vel_east_m_s=10.0)
    m.on_submit(Submit(UploadMission(items=MISSION_ITEMS), Owner.MISSION), state, T)
    m.on_peer(head_on_peer(T, east_m=300.0, vid=7), T)
    (goto,) = requests(m.tick(T, status(8, state, T), state))
    w = MISSION_ITEMS[2]  # on its leg to item 3 (zone-safe), higher, stopping there
    assert isinstance(goto, Goto) and (goto.lat_deg, goto.lon_deg) == (w.lat_deg, w.lon_deg)
    m.on_result(ApResult(goto.request_id, True), T)
    state = msgspec.structs.replace(state, mode_name="GUIDED")
    m.forget(7, T)
    now, resume = T, None
    while resume is None and now < T + 10:
        now += 0.2
        reqs = requests(m.tick(now, status(8, state, now), state))
        resume = reqs[0] if reqs else None
    assert isinstance(resume, StartMission) and resume.first_item == 3


def test_the_missions_requests_wait_and_go_on_after_the_manoeuvre() -> None:
    """What the mission manager asks meanwhile is held (not refused: its sortie must
    not fail for it) and goes on, instead of the module's own resume, once clear: a
    multirotor stopped at its item (Goto)."""
    m = AvoidanceModule(COPTER)
    state = ap(groundspeed_m_s=10.0, vel_east_m_s=10.0)
    m.on_submit(Submit(UploadMission(items=MISSION_ITEMS), Owner.MISSION), state, T)
    m.on_peer(head_on_peer(T, east_m=300.0, vid=1), T)
    (goto,) = requests(tick(m, state, T))
    assert isinstance(goto, Goto)
    m.on_result(ApResult(goto.request_id, True), T)
    state = msgspec.structs.replace(state, mode_name="GUIDED")
    held = Submit(StartMission(request_id=7), Owner.MISSION)
    assert m.on_submit(held, state, T) == ([], None)
    fence_like = Submit(UploadMission(items=MISSION_ITEMS), Owner.OPERATOR)
    assert m.on_submit(fence_like, state, T) is None  # not the mission's: the arbiter decides
    m.forget(1, T)
    now = T
    while not m.release_due and now < T + 10:
        now += 0.2
        assert requests(tick(m, state, now)) == []
    assert m.release_due and m.take_held() == [held]


def test_a_mission_started_just_before_a_manoeuvre_is_started_again_after_it() -> None:
    """The mission's StartMission passed on, and a manoeuvre begins before the autopilot
    shows AUTO (a VTOL's PREMISSION leg sent from its hover over the pad, levelled there
    for a neighbour): the resume goes to that mission, not back to the GUIDED hover it
    saw. Before, a mixed demo's VTOL hovered over its pad until the story timed out."""
    m = AvoidanceModule(VTOL)
    hover = ap(mode_name="GUIDED", groundspeed_m_s=0.0, vel_east_m_s=0.0, mission_current=0)
    m.on_submit(Submit(UploadMission(items=MISSION_ITEMS), Owner.MISSION), hover, T)
    start = Submit(StartMission(first_item=0, request_id=9), Owner.MISSION)
    assert m.on_submit(start, hover, T) is None  # passed on to the arbiter
    m.on_peer(head_on_peer(T, east_m=60.0, vid=1), T + 0.2)
    (goto,) = requests(tick(m, hover, T + 0.2))  # still GUIDED in the state it sees
    assert isinstance(goto, Goto) and m.suspension is not None
    assert m.suspension.mode == "GUIDED"
    m.on_result(ApResult(goto.request_id, True), T + 0.2)
    m.forget(1, T + 0.4)
    now, sent = T + 0.4, []
    while not m.release_due and now < T + 10:
        now += 0.2
        sent += requests(tick(m, hover, now))
    assert not any(isinstance(r, Goto) for r in sent)  # no hover over the pad again
    assert m.release_due and m.take_held() == [start]


def test_a_manoeuvre_long_after_the_mission_started_resumes_as_it_saw() -> None:
    """Only a StartMission the autopilot's state may not show yet is asked again: one
    that long passed (the vehicle in GUIDED since, for a reason of its own) is not."""
    m = AvoidanceModule(COPTER)
    state = ap(groundspeed_m_s=10.0, vel_east_m_s=10.0)
    m.on_submit(Submit(UploadMission(items=MISSION_ITEMS), Owner.MISSION), state, T)
    m.on_submit(Submit(StartMission(first_item=1, request_id=9), Owner.MISSION), state, T)
    later = T + 60.0
    guided = msgspec.structs.replace(state, mode_name="GUIDED")
    m.on_peer(head_on_peer(later, east_m=300.0, vid=7), later)
    (goto,) = requests(m.tick(later, status(8, guided, later), guided))
    assert isinstance(goto, Goto) and m.held == []


def test_a_speed_the_mission_asks_meanwhile_waits_for_the_resume() -> None:
    """The speed rule's ChangeSpeed (every second) is held, only its newest, and goes on
    after the module's own resume: taken for the mission's newest intent, it left VTOLs
    circling their avoidance Goto in GUIDED for good (test_premission_flown)."""
    m = AvoidanceModule(COPTER)
    state = ap(groundspeed_m_s=10.0, vel_east_m_s=10.0)
    m.on_submit(Submit(UploadMission(items=MISSION_ITEMS), Owner.MISSION), state, T)
    m.on_peer(head_on_peer(T, east_m=300.0, vid=1), T)
    (goto,) = requests(tick(m, state, T))
    m.on_result(ApResult(goto.request_id, True), T)
    state = msgspec.structs.replace(state, mode_name="GUIDED")
    for k, speed in enumerate((20.0, 21.0, 22.0)):
        sp = Submit(ChangeSpeed(speed_m_s=speed, request_id=10 + k), Owner.MISSION)
        assert m.on_submit(sp, state, T) == ([], None)
    m.forget(1, T)
    now, resume = T, None
    while resume is None and now < T + 10:
        now += 0.2
        reqs = requests(tick(m, state, now))
        resume = reqs[0] if reqs else None
    assert isinstance(resume, StartMission) and resume.first_item == 3
    m.on_result(ApResult(resume.request_id, True), now)
    (held,) = m.take_held() if m.release_due else []
    assert isinstance(held, Submit) and isinstance(held.request, ChangeSpeed)
    assert held.request.speed_m_s == 22.0


def test_the_arbiter_gives_avoidance_precedence_and_control_back() -> None:
    """EMERGENCY > AVOIDANCE > OPERATOR > MISSION: while avoidance flies, the operator is
    refused; when it is done the holder before it (the operator) has control again."""
    arb = AutopilotArbiter()
    arb.submit(Owner.OPERATOR, Goto(lat_deg=LAT, lon_deg=LON, alt_rel_m=50.0))
    m, state = flying_vtol()
    m.on_peer(head_on_peer(T), T)
    out = m.tick(T, status(2, state, T), state, holder=arb.holder)
    for r in requests(out):
        assert not isinstance(arb.submit(Owner.AVOIDANCE, r), Routed)
    assert arb.holder == Owner.AVOIDANCE
    refused = arb.submit(Owner.OPERATOR, Goto(lat_deg=LAT, lon_deg=LON, alt_rel_m=50.0))
    assert isinstance(refused, Routed) and "AVOIDANCE" in refused.result.reason
    assert m.suspension is not None and m.suspension.holder == Owner.OPERATOR
    m._end("test")
    assert m.release_due and m.restore == Owner.OPERATOR


def test_an_emergency_pre_empts_the_manoeuvre() -> None:
    m, state = flying_vtol()
    m.on_peer(head_on_peer(T), T)
    out = m.tick(T, status(2, state, T), state, holder=Owner.EMERGENCY)
    assert requests(out) == [] and not m.active
    assert any(isinstance(o, Note) and "EMERGENCY" in o.text for o in out)
    # a request refused by the arbiter for a higher owner: the manoeuvre is dropped
    m2, state = flying_vtol()
    m2.on_peer(head_on_peer(T), T)
    (goto,) = requests(tick(m2, state, T))
    m2.on_result(ApResult(goto.request_id, False, "preempted by EMERGENCY"), T)
    assert not m2.active and m2.held == []


def test_a_multirotor_holds_over_itself_and_goes_back_to_what_it_did() -> None:
    m = AvoidanceModule(COPTER)
    state = ap(mode_name="RTL", groundspeed_m_s=10.0, vel_east_m_s=10.0)
    m.on_peer(head_on_peer(T, east_m=300.0, vid=7), T)
    (goto,) = requests(m.tick(T, status(8, state, T), state))
    assert isinstance(goto, Goto) and (goto.lat_deg, goto.lon_deg) == (state.lat_deg, state.lon_deg)
    m.on_result(ApResult(goto.request_id, True), T)
    state = msgspec.structs.replace(state, mode_name="GUIDED")
    m.forget(7, T)
    now, resume = T, None
    while resume is None and now < T + 10:
        now += 0.2
        reqs = requests(m.tick(now, status(8, state, now), state))
        resume = reqs[0] if reqs else None
    assert isinstance(resume, ReturnToLaunch)


def test_a_fixed_wing_outside_a_mission_changes_altitude_only() -> None:
    m = AvoidanceModule(VTOL)
    state = ap(mode_name="RTL")
    m.on_peer(head_on_peer(T), T)
    (req,) = requests(tick(m, state, T))
    assert isinstance(req, ChangeAltitude) and req.alt_rel_m > 60.0


def test_a_failed_resume_is_retried_then_alerted_and_control_given_back() -> None:
    m, state = flying_vtol()
    m.on_peer(head_on_peer(T), T)
    (goto,) = requests(tick(m, state, T))
    m.on_result(ApResult(goto.request_id, True), T)
    state = msgspec.structs.replace(state, mode_name="GUIDED")
    m.forget(1, T)
    now, resume = T, None
    while resume is None:
        now += 0.2
        reqs = requests(tick(m, state, now))
        resume = reqs[0] if reqs else None
    alerts: list = []
    for _ in range(5):
        out = m.on_result(ApResult(resume.request_id, False, "timeout"), now)
        alerts += [o.msg for o in out if isinstance(o, Publish)]
        again = requests(out)
        if not again:
            break
        resume = again[0]
    assert m.release_due and not m.active
    assert alerts[-1].severity == Severity.CRITICAL and "resume" in alerts[-1].text


def test_adsb_traffic_from_the_autopilot_is_climbed_over() -> None:
    """A non-cooperative aircraft the autopilot reports (ADSB_VEHICLE) at our altitude,
    head-on: even the lowest id climbs (traffic will not manoeuvre)."""
    m = AvoidanceModule(profile("Albatross 250 VTOL", 1))
    lat, lon = at(0.0, 800.0)
    intruder = AdsbReport(0xABC123, lat, lon, HOME_MSL + 60.0, 0.0, -40.0, 0.0, T)
    state = ap(traffic=(intruder,), mode_name="LOITER")
    out = m.tick(T, status(1, state, T), state)
    (req,) = requests(out)
    assert isinstance(req, ChangeAltitude) and req.alt_rel_m > 60.0
    assert "ICAO ABC123" in next(o.msg.text for o in out if isinstance(o, Publish))


def test_the_climb_stops_under_a_zone_floor_above() -> None:
    m = AvoidanceModule(VTOL)
    state = ap(mode_name="LOITER")
    corners = [at(n, e) for n, e in ((-500, -500), (-500, 1500), (500, 1500), (500, -500))]
    from swarm_proto import Geometry

    zone = NoFlyZone(1, Geometry.polygon(corners), floor_alt_msl_m=HOME_MSL + 70.0)
    m.on_peer(head_on_peer(T), T)
    out = m.tick(T, status(2, state, T), state, zones={1: zone})
    (req,) = requests(out)
    assert isinstance(req, ChangeAltitude) and req.alt_rel_m == pytest.approx(65.0)  # 5 m under
    alert = next(o.msg for o in out if isinstance(o, Publish))
    assert alert.severity == Severity.CRITICAL and "ceiling" in alert.text


def test_off_passes_everything_and_never_ticks() -> None:
    m = AvoidanceModule(VTOL, enabled=False)
    state = ap()
    m.on_peer(head_on_peer(T), T)
    assert m.next_deadline() is None and tick(m, state, T) == []
    assert m.on_submit(Submit(Arm(), Owner.MISSION), ap(armed=False), T) is None


# ---------------------------------------------------------------------- pads


def parked(vid: int, east_m: float, state: MissionState) -> tuple[VehicleStatus, GeoPoint]:
    s = status(vid, ap(east=east_m, alt_rel_m=0.0, armed=False, vel_east_m_s=0.0), T)
    s = msgspec.structs.replace(s, mission_state=state)
    lat, lon = at(0.0, east_m)
    return s, GeoPoint(lat, lon, HOME_MSL)


def test_the_launch_waits_for_a_neighbour_with_priority() -> None:
    m = AvoidanceModule(VTOL)  # id 2 on HOME
    ground = ap(armed=False, alt_rel_m=0.0, mode_name="GUIDED")
    first = parked(1, 8.0, MissionState.PREMISSION)
    m.tick(T, None, ground, peers=[first], pads={1: first[1]})
    arm = Submit(Arm(request_id=5), Owner.MISSION)
    out, answer = m.on_submit(arm, ground, T)  # type: ignore[misc]
    assert answer is None and m.launch == arm
    assert "1 takes off first" in out[0].text
    # vehicle 1 climbs past 30 m: the held Arm goes on
    up = msgspec.structs.replace(first[0], armed=True, alt_rel_m=31.0, alt_msl_m=41.0)
    out = m.tick(T + 0.2, None, ground, peers=[(up, first[1])], pads={1: first[1]})
    assert arm in out and m.launch is None
    assert m.on_submit(arm, ground, T + 0.2) is None  # now it passes


def test_the_return_lands_on_the_own_pad_at_its_holding_layer() -> None:
    m = AvoidanceModule(VTOL)  # id 2
    state = ap(mode_name="AUTO", north=800.0)
    lat, lon = at(0.0, -8.0)
    m.tick(T, status(2, state, T), state, pads={1: GeoPoint(lat, lon, HOME_MSL)})
    rtl = Submit(ReturnToLaunch(request_id=9), Owner.MISSION)
    subs, answer = m.on_submit(rtl, state, T)  # type: ignore[misc]
    assert answer is not None and answer.owner == Owner.MISSION and answer.result.ok
    upload, start = requests(subs)
    assert isinstance(upload, UploadMission) and isinstance(start, StartMission)
    there, hold, land = upload.items
    assert [w.kind for w in upload.items] == [
        ItemKind.WAYPOINT,
        ItemKind.LOITER_UNLIMITED,
        ItemKind.LAND,
    ]
    assert (land.lat_deg, land.lon_deg) == (LAT, LON)  # its own pad, not the base
    assert hold.alt_rel_m == there.alt_rel_m == 60.0  # second in its cluster: 30 + 30
    # the mission manager's Land later is answered at once: the landing is on its way
    subs, answer = m.on_submit(Submit(Land(request_id=10), Owner.MISSION), state, T)  # type: ignore[misc]
    assert subs == [] and answer is not None and answer.result.ok
    # at the hold, the descent starts once no neighbour is low near the pad
    over = ap(mode_name="AUTO", mission_current=2, alt_rel_m=60.0)
    low = status(1, ap(east=-8.0, alt_rel_m=10.0), T)
    out = m.tick(T + 1, status(2, over, T + 1), over, peers=[(low, GeoPoint(lat, lon, HOME_MSL))])
    assert requests(out) == []
    out = m.tick(T + 2, status(2, over, T + 2), over, peers=[])
    (down,) = requests(out)  # a fixed-wing circles down to the lowest layer first
    assert isinstance(down, ChangeAltitude) and down.alt_rel_m == 30.0
    m.on_result(ApResult(down.request_id, True), T + 2)
    low = msgspec.structs.replace(over, alt_rel_m=33.0, alt_msl_m=HOME_MSL + 33.0)
    (go,) = requests(m.tick(T + 9, status(2, low, T + 9), low, peers=[]))
    assert isinstance(go, StartMission) and go.first_item == 3


def test_a_circling_vtol_does_not_descend_onto_a_neighbour_landing_60_m_away() -> None:
    """The demo's near-collision (4.78 m, story time 708 s): VTOL 6, holding over its
    pad, was let down while VTOL 4 (pad 60 m west) flew its slow landing approach 130 m
    from 6's pad, and circled down through it. Now 6 holds until 4 is down."""
    m = AvoidanceModule(profile("Albatross 250 VTOL", 6))
    pad4 = GeoPoint(*at(0.0, -60.0), HOME_MSL)
    state = ap(mode_name="AUTO", north=800.0)
    m.tick(T, status(6, state, T), state, pads={4: pad4})
    m.on_submit(Submit(ReturnToLaunch(request_id=9), Owner.MISSION), state, T)
    assert m.landing is not None and m.landing.hold_alt_rel_m == 60.0
    over = ap(mode_name="AUTO", mission_current=2, alt_rel_m=60.0)  # circling its hold
    approach = status(
        4,
        ap(
            north=126.0,
            east=-33.0,
            alt_rel_m=35.0,
            groundspeed_m_s=5.0,
            vel_east_m_s=0.0,
            vel_north_m_s=-5.0,
        ),
        T,
    )
    out = m.tick(T + 1, status(6, over, T + 1), over, peers=[(approach, pad4)], pads={4: pad4})
    assert requests(out) == [], "6 descends while 4 lands 60 m from its pad"
    assert any(isinstance(o, Note) and "4 below" in o.text for o in out)
    down = status(
        4, ap(east=-60.0, alt_rel_m=0.0, armed=False, groundspeed_m_s=0.0, vel_east_m_s=0.0), T + 30
    )
    out = m.tick(T + 30, status(6, over, T + 30), over, peers=[(down, pad4)], pads={4: pad4})
    (lower,) = requests(out)
    assert isinstance(lower, ChangeAltitude) and lower.alt_rel_m == 30.0


def test_a_new_mission_on_the_way_home_ends_the_landing_on_the_pad() -> None:
    """Found in the demo's logs: VTOL 6 was on its way home after the perimeter when the
    route came; the return's landing was kept, and 3 s into the route (its item 2, the
    old hold's number) its gate said "landing: on its pad" and sent it down towards
    30 m (it dipped 4.5 m before the next item). A new mission ends the landing."""
    m = AvoidanceModule(VTOL)
    state = ap(mode_name="AUTO", north=800.0)
    m.tick(T, status(2, state, T), state)
    home = (*MISSION_ITEMS[:1], Waypoint(ItemKind.RTL, 0.0, 0.0, 0.0))
    (converted,), _ = m.on_submit(  # type: ignore[misc]
        Submit(UploadMission(request_id=5, items=home), Owner.MISSION), state, T
    )
    # the node passes the converted upload through again (NodeCore._route)
    assert m.on_submit(converted, state, T) is None
    assert m.landing is not None and m.landing.hold_seq == 2
    route = UploadMission(request_id=6, items=MISSION_ITEMS)
    assert m.on_submit(Submit(route, Owner.MISSION), state, T) is None
    assert m.landing is None
    flying = ap(mode_name="AUTO", mission_current=2, alt_rel_m=170.0)  # the route's item 2
    assert requests(m.tick(T + 3, status(2, flying, T + 3), flying)) == []
    # the pad return's own upload (its RTL turned into a hold and a landing) keeps it
    subs, _ = m.on_submit(Submit(ReturnToLaunch(request_id=9), Owner.MISSION), state, T + 4)  # type: ignore[misc]
    for o in subs:
        if isinstance(o, Submit):
            assert m.on_submit(o, state, T + 4) is None
    assert m.landing is not None


def test_a_manoeuvre_during_the_landing_starts_the_descent_again() -> None:
    """A fixed-wing circling down to its pad's lowest layer climbs for a conflict; once
    clear the pad's gate starts the descent again (it circled its layer for good)."""
    m = AvoidanceModule(VTOL)
    state = ap(mode_name="AUTO", north=800.0)
    m.tick(T, status(2, state, T), state)
    m.on_submit(Submit(ReturnToLaunch(request_id=9), Owner.MISSION), state, T)
    over = ap(mode_name="AUTO", mission_current=2, alt_rel_m=30.0 + 30.0)
    (down,) = requests(m.tick(T + 1, status(2, over, T + 1), over))
    assert isinstance(down, ChangeAltitude) and down.alt_rel_m == 30.0
    m.on_result(ApResult(down.request_id, True), T + 1)
    m.on_peer(head_on_peer(T + 1.2, vid=1), T + 1.2)
    (climb,) = requests(m.tick(T + 1.2, status(2, over, T + 1.2), over))
    assert isinstance(climb, Goto | ChangeAltitude) and climb.alt_rel_m > 60.0
    m.on_result(ApResult(climb.request_id, True), T + 1.2)
    m.forget(1, T + 1.4)
    now, again = T + 1.2, []
    while not again and now < T + 12:
        now += 0.2
        out = requests(m.tick(now, status(2, over, now), over))
        if any(isinstance(r, ChangeAltitude) and r.alt_rel_m == 30.0 for r in out):
            again = out
        for r in out:
            m.on_result(ApResult(r.request_id, True), now)
    assert again, "the descent was never asked again"


def test_a_multirotor_in_its_mission_gives_the_avoider_its_way_ahead() -> None:
    """In AUTO, the items from the one it flies to, up to the landing; nothing outside
    AUTO, nothing for a fixed-wing (it acts on the straight line)."""
    from swarm_node.core.safety.avoidance import OwnRoute

    m = AvoidanceModule(COPTER)
    state = ap(groundspeed_m_s=10.0, vel_east_m_s=10.0)
    land = Waypoint(ItemKind.LAND, *at(0.0, 0.0), 0.0)
    m.on_submit(Submit(UploadMission(items=(*MISSION_ITEMS, land)), Owner.MISSION), state, T)
    route = m._route(state)  # mission_current 3: items 3, 4, 5, not the landing
    assert route.points == tuple((w.lat_deg, w.lon_deg, w.alt_rel_m) for w in MISSION_ITEMS[2:])
    assert route.speed_m_s == COPTER.cruise_speed_m_s
    assert m._route(msgspec.structs.replace(state, mode_name="GUIDED")) == OwnRoute(None)
    v = AvoidanceModule(VTOL)
    v.on_submit(Submit(UploadMission(items=MISSION_ITEMS), Owner.MISSION), state, T)
    assert v._route(state) == OwnRoute(None)


def test_a_land_held_during_a_climb_on_the_way_to_the_pad_does_not_leave_it_in_guided() -> None:
    """Found in test_retasking (quadcopter 9, after the landing rule's fix shifted its
    timing): on its way to its pad (the pad mission, AUTO) it climbed for a neighbour
    (Goto: GUIDED); near home the mission manager asked Land, held; once clear the
    module gave control back with no resume of its own ("the mission asked for
    something else meanwhile") and the held Land, passed on, was answered at once by
    the pad landing ("landing on its pad"): nothing ever sent the quadcopter back to
    AUTO, and it hovered in GUIDED until its battery failsafe. A held request that
    will not reach the autopilot does not replace the module's resume."""
    m = AvoidanceModule(COPTER)
    state = ap(
        mode_name="AUTO",
        north=60.0,
        groundspeed_m_s=5.0,
        vel_east_m_s=0.0,
        vel_north_m_s=-5.0,
        alt_rel_m=50.0,
    )
    m.tick(T, status(8, state, T), state)
    subs, _ = m.on_submit(Submit(ReturnToLaunch(request_id=9), Owner.MISSION), state, T)  # type: ignore[misc]
    for o in subs:
        if isinstance(o, Submit):
            assert m.on_submit(o, state, T) is None
            m.on_result(ApResult(o.request.request_id, True), T)
    assert m.landing is not None
    state = msgspec.structs.replace(state, mission_current=1)
    m.on_peer(
        status(
            7,
            ap(
                north=40.0, alt_rel_m=45.0, groundspeed_m_s=0.0, vel_east_m_s=0.0, vel_down_m_s=-2.0
            ),
            T,
        ),
        T,
    )
    (climb,) = requests(tick(m, state, T + 0.2))
    assert isinstance(climb, Goto) and m.suspension is not None
    m.on_result(ApResult(climb.request_id, True), T + 0.2)
    state = msgspec.structs.replace(state, mode_name="GUIDED")
    land = Submit(Land(request_id=11), Owner.MISSION)
    assert m.on_submit(land, state, T + 1.0) == ([], None)  # held
    m.forget(7, T + 1.2)
    now, resume = T + 1.2, []
    while not m.release_due and now < T + 12:
        now += 0.2
        out = requests(tick(m, state, now))
        resume += out
        for r in out:
            m.on_result(ApResult(r.request_id, True), now)
    assert m.release_due
    assert any(isinstance(r, StartMission) and r.first_item == 1 for r in resume), resume
    # the held Land goes on after the resume: answered, the pad landing flies on
    (held,) = m.take_held()
    subs, answer = m.on_submit(held, state, now)  # type: ignore[misc]
    assert subs == [] and answer is not None and answer.result.ok


def test_a_held_mission_request_the_arbiter_will_refuse_does_not_replace_the_resume() -> None:
    """The operator held the autopilot (a Goto) when the manoeuvre began: the mission's
    request held meanwhile will be refused once control goes back to the operator, so
    the module goes back itself (a Goto over itself at the altitude it left)."""
    m = AvoidanceModule(COPTER)
    state = ap(mode_name="GUIDED", groundspeed_m_s=5.0, vel_east_m_s=5.0)
    m.on_peer(head_on_peer(T, east_m=200.0, vid=7), T)
    (climb,) = requests(tick(m, state, T, holder=Owner.OPERATOR))
    assert isinstance(climb, Goto) and m.suspension is not None
    assert m.suspension.holder == Owner.OPERATOR
    m.on_result(ApResult(climb.request_id, True), T)
    held = Submit(StartMission(request_id=3), Owner.MISSION)
    assert m.on_submit(held, state, T + 0.1) == ([], None)
    m.forget(7, T + 0.2)
    now, resume = T, []
    while not m.release_due and now < T + 12:
        now += 0.2
        out = requests(tick(m, state, now, holder=Owner.AVOIDANCE))
        resume += out
        for r in out:
            m.on_result(ApResult(r.request_id, True), now)
    assert m.release_due and m.restore == Owner.OPERATOR
    assert any(isinstance(r, Goto) and r.alt_rel_m == 60.0 for r in resume), resume
    assert m.take_held() == [held]  # still routed: the arbiter answers it (refused)
