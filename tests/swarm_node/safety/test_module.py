"""Collision avoidance as a node module (safety/module.py): manoeuvres flown through the
arbiter as owner AVOIDANCE, the mission suspended (by the arbiter) and resumed at the
right item, ADS-B traffic and the zones' ceiling. The take-off and landing at close
pads are the mission manager's (test_pad_sequence.py)."""

from __future__ import annotations

from typing import Any

import msgspec
import pytest

from swarm_node.core.arbiter import AutopilotArbiter, Routed, Send
from swarm_node.core.autopilot.items import ItemKind, Waypoint
from swarm_node.core.autopilot.requests import (
    ApError,
    ApResult,
    ChangeAltitude,
    ChangeSpeed,
    Goto,
    ReturnToLaunch,
    StartMission,
)
from swarm_node.core.autopilot.state import AdsbReport, AutopilotState
from swarm_node.core.outputs import Note, Owner, Publish, Release, Submit, Suspend
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
    return AvoidanceModule(VTOL, items=MISSION_ITEMS), ap()


def suspends(out: list) -> list[bool]:
    """The `passing` of each Suspend in `out`."""
    return [o.passing for o in out if isinstance(o, Suspend)]


def released(out: list) -> bool:
    return Release(Owner.AVOIDANCE) in out


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
    assert suspends(out) == [True]  # on its path: the mission's requests go on under it
    assert m.active and m.suspension is not None and m.suspension.item == 3
    alert = next(o.msg for o in out if isinstance(o, Publish))
    assert isinstance(alert, Alert) and alert.code == AlertCode.COLLISION_RISK
    assert m.on_result(ApResult(climb.request_id, True), T) == []
    m.forget(1, T + 0.2)
    now, resume, out = T, None, []
    while resume is None and now < T + 10:
        now += 0.2
        out = tick(m, state, now)
        reqs = requests(out)
        resume = reqs[0] if reqs else None
    assert isinstance(resume, ChangeAltitude)
    assert resume.alt_rel_m == MISSION_ITEMS[2].alt_rel_m  # the item it flies to
    assert suspends(out) == [False]  # going back: the mission's requests wait for it
    assert now - T >= 3.0  # the clear hold
    assert not released(out)
    assert released(m.on_result(ApResult(resume.request_id, True), now)) and not m.active


def test_under_a_fixed_wings_climb_the_missions_requests_go_on_and_the_climb_is_asked_again() -> (
    None
):
    """The mission's requests are not held while a fixed-wing climbs on its path (the
    arbiter passes them under the manoeuvre), and the climb is asked again at the new
    mission's item. Held, a fleet stacked at a route's end never went home."""
    m, state = flying_vtol()
    arb = AutopilotArbiter()
    m.on_peer(head_on_peer(T), T)
    out = tick(m, state, T)
    (passing,) = suspends(out)
    arb.suspend(Owner.AVOIDANCE, passing=passing)
    (climb,) = requests(out)
    m.on_result(ApResult(climb.request_id, True), T)
    (start,) = arb.submit(Owner.MISSION, StartMission(request_id=6))
    assert isinstance(start, Send) and arb.holder == Owner.AVOIDANCE
    state = msgspec.structs.replace(state, mission_current=1)  # the new mission's first item
    (again,) = requests(tick(m, state, T + 0.2))
    assert isinstance(again, ChangeAltitude) and again.alt_rel_m == climb.alt_rel_m


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
    m = AvoidanceModule(COPTER, items=MISSION_ITEMS)
    state = ap(groundspeed_m_s=10.0, vel_east_m_s=10.0)
    m.on_peer(head_on_peer(T, east_m=300.0, vid=7), T)
    out = m.tick(T, status(8, state, T), state)
    (goto,) = requests(out)
    assert suspends(out) == [False]  # the mission is suspended: its requests are held
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


def test_the_missions_requests_held_meanwhile_go_on_instead_of_the_resume() -> None:
    """What the mission manager asks meanwhile is held by the arbiter (not refused: its
    sortie must not fail for it); once clear, when one of them will say where to go,
    the module gives control back without a resume of its own and they go on."""
    m = AvoidanceModule(COPTER, items=MISSION_ITEMS)
    arb = AutopilotArbiter()
    state = ap(groundspeed_m_s=10.0, vel_east_m_s=10.0)
    m.on_peer(head_on_peer(T, east_m=300.0, vid=1), T)
    out = tick(m, state, T, will_steer=arb.will_steer)
    arb.suspend(Owner.AVOIDANCE, passing=suspends(out)[0])
    (goto,) = requests(out)
    assert isinstance(goto, Goto)
    m.on_result(ApResult(goto.request_id, True), T)
    state = msgspec.structs.replace(state, mode_name="GUIDED")
    assert arb.submit(Owner.MISSION, StartMission(request_id=7)) == []  # held
    m.forget(1, T)
    now, out = T, []
    while not released(out) and now < T + 10:
        now += 0.2
        out = tick(m, state, now)
        assert requests(out) == []
    assert released(out)
    (_, start) = arb.release(Owner.AVOIDANCE)
    assert isinstance(start, Send) and isinstance(start.request, StartMission)


def test_a_speed_the_mission_asks_meanwhile_waits_for_the_resume() -> None:
    """The speed rule's ChangeSpeed (every second) is held, only its newest, and goes on
    after the module's own resume: taken for the mission's newest intent, it left VTOLs
    circling their avoidance Goto in GUIDED for good (test_premission_flown)."""
    m = AvoidanceModule(COPTER, items=MISSION_ITEMS)
    arb = AutopilotArbiter()
    state = ap(groundspeed_m_s=10.0, vel_east_m_s=10.0)
    m.on_peer(head_on_peer(T, east_m=300.0, vid=1), T)
    out = tick(m, state, T, will_steer=arb.will_steer)
    arb.suspend(Owner.AVOIDANCE, passing=suspends(out)[0])
    (goto,) = requests(out)
    m.on_result(ApResult(goto.request_id, True), T)
    state = msgspec.structs.replace(state, mode_name="GUIDED")
    for k, speed in enumerate((20.0, 21.0, 22.0)):
        assert arb.submit(Owner.MISSION, ChangeSpeed(speed_m_s=speed, request_id=10 + k)) == []
    m.forget(1, T)
    now, resume = T, None
    while resume is None and now < T + 10:
        now += 0.2
        reqs = requests(tick(m, state, now))
        resume = reqs[0] if reqs else None
    assert isinstance(resume, StartMission) and resume.first_item == 3
    assert released(m.on_result(ApResult(resume.request_id, True), now))
    (_, held) = arb.release(Owner.AVOIDANCE)
    assert isinstance(held, Send) and isinstance(held.request, ChangeSpeed)
    assert held.request.speed_m_s == 22.0


def test_the_arbiter_gives_avoidance_precedence_and_control_back() -> None:
    """EMERGENCY > AVOIDANCE > OPERATOR > MISSION: while avoidance flies, the operator is
    refused; when it is done the holder before it (the operator) has control again."""
    arb = AutopilotArbiter()
    arb.submit(Owner.OPERATOR, Goto(lat_deg=LAT, lon_deg=LON, alt_rel_m=50.0))
    m, state = flying_vtol()
    m.on_peer(head_on_peer(T), T)
    out = m.tick(T, status(2, state, T), state, holder=arb.holder)
    arb.suspend(Owner.AVOIDANCE, passing=suspends(out)[0])
    for r in requests(out):
        assert isinstance(arb.submit(Owner.AVOIDANCE, r)[0], Send)
    assert arb.holder == Owner.AVOIDANCE
    (refused,) = arb.submit(Owner.OPERATOR, Goto(lat_deg=LAT, lon_deg=LON, alt_rel_m=50.0))
    assert isinstance(refused, Routed) and "AVOIDANCE" in refused.result.reason
    assert released(m._end("test"))
    arb.release(Owner.AVOIDANCE)
    assert arb.holder == Owner.OPERATOR


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
    out = m2.on_result(
        ApResult(goto.request_id, False, "preempted by EMERGENCY", error=ApError.PREEMPTED), T
    )
    assert not m2.active and not released(out)


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
    out: list = []
    for _ in range(5):
        out = m.on_result(ApResult(resume.request_id, False, "timeout"), now)
        alerts += [o.msg for o in out if isinstance(o, Publish)]
        again = requests(out)
        if not again:
            break
        resume = again[0]
    assert released(out) and not m.active
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


def test_off_never_ticks() -> None:
    m = AvoidanceModule(VTOL, enabled=False)
    state = ap()
    m.on_peer(head_on_peer(T), T)
    assert m.next_deadline() is None and tick(m, state, T) == []


def test_a_multirotor_in_its_mission_gives_the_avoider_its_way_ahead() -> None:
    """In AUTO, the items from the one it flies to, up to the landing; nothing outside
    AUTO, nothing for a fixed-wing (it acts on the straight line)."""
    from swarm_node.core.safety.avoidance import OwnRoute

    land = Waypoint(ItemKind.LAND, *at(0.0, 0.0), 0.0)
    m = AvoidanceModule(COPTER, items=(*MISSION_ITEMS, land))
    state = ap(groundspeed_m_s=10.0, vel_east_m_s=10.0)
    route = m._route(state)  # mission_current 3: items 3, 4, 5, not the landing
    assert route.points == tuple((w.lat_deg, w.lon_deg, w.alt_rel_m) for w in MISSION_ITEMS[2:])
    assert route.speed_m_s == COPTER.cruise_speed_m_s
    assert m._route(msgspec.structs.replace(state, mode_name="GUIDED")) == OwnRoute(None)
    v = AvoidanceModule(VTOL, items=MISSION_ITEMS)
    assert v._route(state) == OwnRoute(None)


def test_a_held_mission_request_the_arbiter_will_refuse_does_not_replace_the_resume() -> None:
    """The operator held the autopilot (a Goto) when the manoeuvre began: the mission's
    request held meanwhile will be refused once control goes back to the operator, so
    the module goes back itself (a Goto over itself at the altitude it left)."""
    m = AvoidanceModule(COPTER)
    arb = AutopilotArbiter()
    arb.submit(Owner.OPERATOR, Goto(lat_deg=LAT, lon_deg=LON, alt_rel_m=60.0))
    state = ap(mode_name="GUIDED", groundspeed_m_s=5.0, vel_east_m_s=5.0)
    m.on_peer(head_on_peer(T, east_m=200.0, vid=7), T)
    out = tick(m, state, T, holder=arb.holder, will_steer=arb.will_steer)
    arb.suspend(Owner.AVOIDANCE, passing=suspends(out)[0])
    (climb,) = requests(out)
    assert isinstance(climb, Goto) and m.suspension is not None
    m.on_result(ApResult(climb.request_id, True), T)
    assert arb.submit(Owner.MISSION, StartMission(request_id=3)) == []  # held
    m.forget(7, T + 0.2)
    now, resume, out = T, [], []
    while not released(out) and now < T + 12:
        now += 0.2
        got = tick(m, state, now, holder=Owner.AVOIDANCE)
        resume += requests(got)
        out = got
        for r in requests(got):
            out = out + m.on_result(ApResult(r.request_id, True), now)
    assert released(out)
    assert any(isinstance(r, Goto) and r.alt_rel_m == 60.0 for r in resume), resume
    refused = arb.release(Owner.AVOIDANCE)  # still ruled on: refused by the operator
    assert (
        Routed(Owner.MISSION, ApResult(3, False, "preempted by OPERATOR", error=ApError.PREEMPTED))
        in refused
    )


def test_with_no_own_position_nothing_is_flown_on_the_last_status() -> None:
    """An autopilot rebooted in flight comes back with no fix (the node's status is
    None): the avoider does not manoeuvre on the last status it had (armed, 60 m up),
    and a manoeuvre under way ends; a fix back, it flies again (found over real
    processes: a rebooted copter asked to climb)."""
    m = AvoidanceModule(COPTER, items=MISSION_ITEMS)
    state = ap(groundspeed_m_s=10.0, vel_east_m_s=10.0)
    m.on_peer(head_on_peer(T, east_m=300.0, vid=7), T)
    assert requests(m.tick(T, status(8, state, T), state))  # a manoeuvre
    rebooted = AutopilotState(sysid=8, link_ok=True, armed=False, mode_name="STABILIZE")
    now, out = T, []
    for _ in range(10):
        now += 0.2
        m.on_peer(head_on_peer(now, east_m=300.0, vid=7), now)
        out += m.tick(now, None, rebooted)
    assert not requests(out)
    assert m.avoider.manoeuvring is None and m.suspension is None
    assert any(isinstance(o, Publish) and "off" in getattr(o.msg, "text", "") for o in out)
    # a peer still head-on, nothing manoeuvres from an unknown position: a fix back, it does
    now += 0.2
    m.on_peer(head_on_peer(now, east_m=300.0, vid=7), now)
    assert requests(m.tick(now, status(8, state, now), state))
