"""The own vehicle's take-off and landing at close pads (safety/pad_sequence.py), and how
the mission manager flies them: the launch held until the pad is clear, the way home
ending on the own pad at its holding layer, the descent gated, a new mission ending the
landing, and the mission manager's own requests around an avoidance suspension."""

from __future__ import annotations

from typing import Any

import msgspec

from swarm_node.core.autopilot.items import ItemKind, Waypoint
from swarm_node.core.autopilot.requests import (
    ApResult,
    Arm,
    ChangeAltitude,
    Land,
    ReturnToLaunch,
    StartMission,
    UploadMission,
)
from swarm_node.core.autopilot.state import AutopilotState
from swarm_node.core.mission_manager import MissionManager, Phase
from swarm_node.core.outputs import Note, Owner, Publish, Submit
from swarm_node.core.profile import VehicleProfile
from swarm_node.core.safety.pad_sequence import PadSequence
from swarm_node.database import seed_profiles
from swarm_proto import GeoPoint, MissionState, VehicleStatus, geodesy

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


def parked(vid: int, east_m: float, state: MissionState) -> tuple[VehicleStatus, GeoPoint]:
    s = status(vid, ap(east=east_m, alt_rel_m=0.0, armed=False, vel_east_m_s=0.0), T)
    s = msgspec.structs.replace(s, mission_state=state)
    lat, lon = at(0.0, east_m)
    return s, GeoPoint(lat, lon, HOME_MSL)


MISSION_ITEMS = tuple(
    Waypoint(ItemKind.WAYPOINT, *at(0.0, 300.0 * k), 60.0 + 5 * k) for k in range(1, 6)
)


def requests(out: list) -> list:
    return [o.request for o in out if isinstance(o, Submit)]


def test_the_launch_waits_for_a_neighbour_with_priority() -> None:
    first = parked(1, 8.0, MissionState.PREMISSION)
    peers = [first]
    pads = PadSequence(VTOL, peers=lambda: peers, pads=lambda: {1: first[1]})  # id 2 on HOME
    ground = ap(armed=False, alt_rel_m=0.0, mode_name="GUIDED")
    arm = Arm(request_id=5)
    note = pads.hold_launch(arm, ground, T)
    assert note is not None and "1 takes off first" in note.text and pads.launch == arm
    # vehicle 1 climbs past 30 m: the held Arm goes on
    peers[0] = (
        msgspec.structs.replace(first[0], armed=True, alt_rel_m=31.0, alt_msl_m=41.0),
        first[1],
    )
    launched, _, reqs = pads.tick(ground, T + 0.2)
    assert launched == arm and pads.launch is None and reqs == ()
    assert pads.hold_launch(arm, ground, T + 0.2) is None  # now it passes


def test_the_return_lands_on_the_own_pad_at_its_holding_layer() -> None:
    lat, lon = at(0.0, -8.0)
    low_peers: list = []
    pads = PadSequence(
        VTOL, peers=lambda: low_peers, pads=lambda: {1: GeoPoint(lat, lon, HOME_MSL)}
    )
    state = ap(mode_name="AUTO", north=800.0)
    home = pads.home(state)
    assert home is not None
    _, (upload, start) = home
    assert isinstance(upload, UploadMission) and isinstance(start, StartMission)
    there, hold, land = upload.items
    assert [w.kind for w in upload.items] == [
        ItemKind.WAYPOINT,
        ItemKind.LOITER_UNLIMITED,
        ItemKind.LAND,
    ]
    assert (land.lat_deg, land.lon_deg) == (LAT, LON)  # its own pad, not the base
    assert hold.alt_rel_m == there.alt_rel_m == 60.0  # second in its cluster: 30 + 30
    assert pads.answers_land  # the mission manager's Land later is answered at once
    # at the hold, the descent starts once no neighbour is low near the pad
    over = ap(mode_name="AUTO", mission_current=2, alt_rel_m=60.0)
    low_peers.append((status(1, ap(east=-8.0, alt_rel_m=10.0), T), GeoPoint(lat, lon, HOME_MSL)))
    assert pads.tick(over, T + 1)[2] == ()
    low_peers.clear()
    (down,) = pads.tick(over, T + 2)[2]  # a fixed-wing circles down to the lowest layer first
    assert isinstance(down, ChangeAltitude) and down.alt_rel_m == 30.0
    low = msgspec.structs.replace(over, alt_rel_m=33.0, alt_msl_m=HOME_MSL + 33.0)
    (go,) = pads.tick(low, T + 9)[2]
    assert isinstance(go, StartMission) and go.first_item == 3


def test_a_circling_vtol_does_not_descend_onto_a_neighbour_landing_60_m_away() -> None:
    """The demo's near-collision (4.78 m, story time 708 s): VTOL 6, holding over its
    pad, was let down while VTOL 4 (pad 60 m west) flew its slow landing approach 130 m
    from 6's pad, and circled down through it. Now 6 holds until 4 is down."""
    pad4 = GeoPoint(*at(0.0, -60.0), HOME_MSL)
    peers: list = []
    pads = PadSequence(
        profile("Albatross 250 VTOL", 6), peers=lambda: peers, pads=lambda: {4: pad4}
    )
    pads.home(ap(mode_name="AUTO", north=800.0))
    assert pads.landing is not None and pads.landing.hold_alt_rel_m == 60.0
    over = ap(mode_name="AUTO", mission_current=2, alt_rel_m=60.0)  # circling its hold
    approach = ap(
        north=126.0,
        east=-33.0,
        alt_rel_m=35.0,
        groundspeed_m_s=5.0,
        vel_east_m_s=0.0,
        vel_north_m_s=-5.0,
    )
    peers[:] = [(status(4, approach, T), pad4)]
    _, out, reqs = pads.tick(over, T + 1)
    assert reqs == (), "6 descends while 4 lands 60 m from its pad"
    assert any(isinstance(o, Note) and "4 below" in o.text for o in out)
    down = ap(east=-60.0, alt_rel_m=0.0, armed=False, groundspeed_m_s=0.0, vel_east_m_s=0.0)
    peers[:] = [(status(4, down, T + 30), pad4)]
    (lower,) = pads.tick(over, T + 30)[2]
    assert isinstance(lower, ChangeAltitude) and lower.alt_rel_m == 30.0


def test_a_new_mission_on_the_way_home_ends_the_landing_on_the_pad() -> None:
    """Found in the demo's logs: VTOL 6 was on its way home after the perimeter when the
    route came; the return's landing was kept, and 3 s into the route (its item 2, the
    old hold's number) its gate said "landing: on its pad" and sent it down towards
    30 m (it dipped 4.5 m before the next item). A new mission ends the landing."""
    pads = PadSequence(VTOL)
    state = ap(mode_name="AUTO", north=800.0)
    home = (*MISSION_ITEMS[:1], Waypoint(ItemKind.RTL, 0.0, 0.0, 0.0))
    converted = pads.upload(UploadMission(request_id=5, items=home), state)
    assert converted.items[-1].kind == ItemKind.LAND
    assert pads.landing is not None and pads.landing.hold_seq == 2
    assert (
        pads.upload(UploadMission(request_id=6, items=MISSION_ITEMS), state).items == MISSION_ITEMS
    )
    assert pads.landing is None
    flying = ap(mode_name="AUTO", mission_current=2, alt_rel_m=170.0)  # the route's item 2
    assert pads.tick(flying, T + 3)[2] == ()
    pads.home(state)  # the pad return's own mission keeps it
    assert pads.landing is not None


def test_a_manoeuvre_during_the_landing_starts_the_descent_again() -> None:
    """A fixed-wing circling down to its pad's lowest layer climbs for a conflict; once
    clear the pad's gate starts the descent again (it circled its layer for good)."""
    pads = PadSequence(VTOL)
    pads.home(ap(mode_name="AUTO", north=800.0))
    over = ap(mode_name="AUTO", mission_current=2, alt_rel_m=30.0 + 30.0)
    (down,) = pads.tick(over, T + 1)[2]
    assert isinstance(down, ChangeAltitude) and down.alt_rel_m == 30.0
    pads.suspended = True  # avoidance climbs it for a conflict: no step meanwhile
    assert pads.tick(over, T + 1.2)[2] == ()
    pads.resumed()  # control given back
    (again,) = pads.tick(over, T + 5)[2]
    assert isinstance(again, ChangeAltitude) and again.alt_rel_m == 30.0


def manager(p: VehicleProfile, state: AutopilotState) -> MissionManager:
    mm = MissionManager(p)
    mm.on_autopilot(state, T)  # the autopilot as last seen
    return mm


def test_the_mission_managers_way_home_is_the_pad_landing_and_its_land_never_leaves() -> None:
    """A multirotor's plain RTL home is flown as the pad's mission (the RTL answered at
    once); near home the mission manager's Land is answered by the landing on the pad,
    never sent (held under a manoeuvre, one left a quadcopter in GUIDED for good:
    test_retasking); a failed pad step falls back to RTL."""
    far = ap(mode_name="AUTO", north=60.0, groundspeed_m_s=5.0, alt_rel_m=50.0)
    mm = manager(COPTER, far)
    out = mm.start_return(far, [], T)
    upload, start = requests(out)
    assert isinstance(upload, UploadMission) and isinstance(start, StartMission)
    assert upload.items[-1].kind == ItemKind.LAND and mm.uploaded == upload.items
    assert not any(isinstance(r, ReturnToLaunch) for r in requests(out))
    assert all(
        isinstance(o, Submit) and o.owner == Owner.MISSION for o in out if isinstance(o, Submit)
    )
    near = ap(mode_name="AUTO", north=5.0, groundspeed_m_s=0.0, alt_rel_m=30.0)
    out = mm.on_autopilot(near, T + 30)
    assert mm.phase == Phase.LANDING and not any(isinstance(r, Land) for r in requests(out))
    failed = mm.on_result(ApResult(upload.request_id, False, "link down"), T + 31)
    assert any(isinstance(o, Publish) for o in failed)
    assert [type(r) for r in requests(failed)] == [ReturnToLaunch]


def test_a_mission_started_just_before_a_suspension_is_asked_again_held() -> None:
    """Our StartMission went out, and avoidance suspends us before the autopilot shows
    AUTO (a VTOL's PREMISSION leg sent from its hover over the pad, levelled there for
    a neighbour): it is asked again, for the arbiter to hold until the resume, which
    goes to that mission, not back to the GUIDED hover the manoeuvre saw. Before, a mixed
    demo's VTOL hovered over its pad until the story timed out. One that long passed
    (the vehicle in GUIDED since, for a reason of its own) is not."""
    hover = ap(mode_name="GUIDED", groundspeed_m_s=0.0, vel_east_m_s=0.0, mission_current=0)
    mm = manager(VTOL, hover)
    (sent,) = requests(mm._ask(StartMission(first_item=0, request_id=9), T))
    assert requests(mm.on_suspended(True, T + 0.2)) == [sent]
    mm.on_suspended(False, T + 5)
    mm = manager(VTOL, hover)
    mm._ask(StartMission(first_item=1, request_id=9), T)
    assert mm.on_suspended(True, T + 60.0) == []
