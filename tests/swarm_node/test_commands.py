"""The command manager inside node cores (fleet harness, scripted autopilot): what each
operator command asks of the autopilot AND what it does to the state machine (paper
section 2.3.4, STATE_GO_MISSION cases; section 3.5.1: emergency landing on a given
route, abort landing, parachute all), and the emergency procedures."""

from __future__ import annotations

import math

import msgspec
import pytest

from swarm_node.core.autopilot.items import ItemKind
from swarm_node.core.autopilot.requests import (
    ApRequest,
    ApResult,
    Arm,
    Calibrate,
    Goto,
    Land,
    Parachute,
    ReturnToLaunch,
    SetMode,
    StartMission,
    UploadMission,
)
from swarm_node.core.commands import emergency_requests
from swarm_node.core.mission_manager import Phase
from swarm_node.core.node import NodeCore, NodeSettings
from swarm_node.core.profile import VehicleProfile
from swarm_node.database import seed_profiles
from swarm_node.testing import Fleet
from swarm_proto import (
    AckReason,
    Alert,
    AlertCode,
    CommandKind,
    FsmState,
    Geometry,
    GeoPoint,
    Mission,
    MissionParams,
    MissionState,
    MissionType,
    NoFlyZone,
    Selector,
    Severity,
    VehicleStatus,
    VehicleType,
)
from tests.swarm_node.test_node_core import GCS, HOME, acks, command, flying, send

SEED = seed_profiles()
VTOL, QUAD = SEED["Albatross 250 VTOL"], SEED["Generic Quadcopter"]
ROVER, BOAT = SEED["Generic Rover"], SEED["Generic Boat"]


# every vehicle at one synthetic position (`flying()`): collision avoidance, which would
# rightly climb them apart, is off here (its own tests: tests/swarm_node/safety)
SETTINGS = NodeSettings(plan_timeout_s=20.0, avoidance=False)


def as_vehicle(p: VehicleProfile, vid: int) -> VehicleProfile:
    return msgspec.structs.replace(p, vehicle_id=vid)


def fleet_of(*models: VehicleProfile) -> Fleet:
    """Vehicles 1..n of these seed models, flying at 100 m, each in GO_MISSION."""
    profiles = {i: as_vehicle(p, i) for i, p in enumerate(models, start=1)}
    nodes = {i: NodeCore(p, SETTINGS, fleet_profiles=profiles) for i, p in profiles.items()}
    f = Fleet(nodes)
    for i in nodes:
        f.set_autopilot(i, flying())
    f.run_until(0.5)
    send(f, command(100, CommandKind.SET_BASE, point=HOME))
    f.run_until(1.5)
    assert all(n.fsm.state == FsmState.GO_MISSION for n in f.nodes.values())
    return f


def on_mission(f: Fleet, mid: int = 50) -> None:
    """Every vehicle flies mission `mid` (objectives north of home): in GO_MISSION, flying."""
    target = Geometry.point(HOME.lat_deg + 0.004, HOME.lon_deg)
    m = Mission(
        mid,
        GCS,
        MissionType.OBJECTIVE,
        target,
        MissionParams(altitude_rel_m=60.0),
        Selector.ids(*f.nodes),
    )
    send(f, m)
    f.run_until(f.now + 3.0)
    for n in f.nodes.values():
        assert (n.fsm.state, n.fsm.mission_id, n.manager.phase) == (
            FsmState.GO_MISSION,
            mid,
            Phase.FLYING,
        )


def requests(f: Fleet, vid: int, since: float, cls: type | None = None) -> list[ApRequest]:
    return [
        r
        for t, n, r in f.submitted
        if n == vid and t >= since and (cls is None or isinstance(r, cls))
    ]


def land(f: Fleet, vid: int) -> None:
    """The autopilot reports the vehicle down and disarmed."""
    f.set_autopilot(vid, flying(armed=False, alt_rel_m=0.0, alt_msl_m=10.0))
    f.run_until(f.now + 1.0)


@pytest.mark.parametrize(
    ("kind", "request_type", "phase"),
    [
        (CommandKind.RTL, ReturnToLaunch, Phase.RETURNING),
        (CommandKind.LAND, Land, Phase.LANDING),
    ],
)
def test_rtl_or_land_during_a_mission_end_it_with_the_landing(
    kind: CommandKind, request_type: type, phase: Phase
) -> None:
    f = fleet_of(QUAD, QUAD)
    on_mission(f)
    t = f.now
    send(f, command(60, kind, Selector.ids(1)))
    f.run_until(f.now + 1.0)
    node = f.nodes[1]
    assert acks(f, 60)[1].accepted
    assert len(requests(f, 1, t, request_type)) == 1
    # the state machine left the mission and the fleet; it waits for the landing
    assert (node.fsm.state, node.fsm.mission_id, node.manager.phase) == (
        FsmState.GO_MISSION,
        -1,
        phase,
    )
    assert node.fleet_id == 0 and 50 not in node.missions
    assert any(a.code == AlertCode.MISSION_FAILED for a in f.messages(Alert, sender=1))
    assert f.nodes[2].fsm.mission_id == 50  # the other vehicle flies on
    land(f, 1)
    assert node.fsm.state == FsmState.INACTIVE and not node.active
    assert not [a for a in f.messages(Alert, sender=1) if a.code == AlertCode.MISSION_COMPLETE]
    assert f.nodes[2].fsm.state == FsmState.GO_MISSION


def test_rtl_outside_a_mission_only_commands_the_autopilot() -> None:
    f = fleet_of(QUAD)
    send(f, command(61, CommandKind.RTL))
    f.run_until(f.now + 1.0)
    node = f.nodes[1]
    assert acks(f, 61)[1].accepted and requests(f, 1, 0.0, ReturnToLaunch)
    assert (node.fsm.state, node.fsm.mission_id, node.manager.phase) == (
        FsmState.GO_MISSION,
        None,
        Phase.IDLE,
    )


def test_emergency_land_flies_the_given_route_around_zones_and_lands_there() -> None:
    f = fleet_of(QUAD)
    on_mission(f)
    here = f.nodes[1].autopilot
    assert here.lat_deg is not None and here.lon_deg is not None
    # the landing point 400 m east, a no-fly zone (ground to sky) half way
    k = 111_320.0 * math.cos(math.radians(HOME.lat_deg))
    point = GeoPoint(here.lat_deg, here.lon_deg + 400.0 / k, HOME.alt_msl_m)
    zone = NoFlyZone(4, Geometry.circle(here.lat_deg, here.lon_deg + 200.0 / k, 50.0))
    send(f, zone)
    f.run_until(f.now + 0.5)
    send(f, command(62, CommandKind.EMERGENCY_LAND))  # no route: refused, asks for it
    on_ground = fleet_of(QUAD)
    on_ground.set_autopilot(1, flying(armed=False, alt_rel_m=0.0))
    send(on_ground, command(63, CommandKind.EMERGENCY_LAND, point=point))
    t = f.now
    send(f, command(64, CommandKind.EMERGENCY_LAND, point=point))
    f.run_until(f.now + 1.0)
    on_ground.run_until(on_ground.now + 1.0)
    no_route, grounded, ok = acks(f, 62)[1], acks(on_ground, 63)[1], acks(f, 64)[1]
    assert (no_route.reason, "landing point" in no_route.text) == (AckReason.INVALID, True)
    assert grounded.reason == AckReason.NOT_READY
    assert ok.accepted  # after the autopilot took the route and started it
    (upload,) = requests(f, 1, t, UploadMission)
    assert isinstance(upload, UploadMission) and requests(f, 1, t, StartMission)
    *leg, last = upload.items
    assert (last.kind, last.lat_deg, last.lon_deg) == (ItemKind.LAND, point.lat_deg, point.lon_deg)
    assert leg, "the straight line crosses the zone: the route goes round it"
    for w in leg:  # every leg waypoint is clear of the zone
        d = math.hypot(
            (w.lat_deg - here.lat_deg) * 111_320.0,
            (w.lon_deg - zone.geometry.points[0].lon_deg) * k,
        )
        assert d > 50.0
    node = f.nodes[1]
    assert node.fsm.state == FsmState.GO_MISSION and node.fsm.mission_id == -1
    assert node.manager.phase == Phase.LANDING
    land(f, 1)
    assert node.fsm.state == FsmState.INACTIVE


def test_abort_landing_cancels_the_return_and_holds_above() -> None:
    f = fleet_of(QUAD)
    send(f, command(65, CommandKind.ABORT_LANDING))  # nothing to abort
    f.run_until(f.now + 0.5)
    assert acks(f, 65)[1].reason == AckReason.NOT_FOUND
    on_mission(f)
    node = f.nodes[1]
    # the mission completes: the node flies its own way home (RETURNING)
    f.set_autopilot(1, flying(mission_reached=node.manager.last_item, alt_rel_m=12.0))
    f.run_until(f.now + 2.0)
    assert node.manager.phase == Phase.RETURNING and node.fsm.mission_id == -1
    t = f.now
    send(f, command(66, CommandKind.ABORT_LANDING))
    f.run_until(f.now + 1.0)
    assert acks(f, 66)[1].accepted
    mode, goto = requests(f, 1, t)
    assert isinstance(mode, SetMode) and mode.mode == "GUIDED"
    assert isinstance(goto, Goto) and goto.alt_rel_m == 30.0  # climbs to at least 30 m
    assert node.manager.phase == Phase.IDLE and node.fsm.state == FsmState.GO_MISSION
    # over home now: the node does not land it (the operator holds it) ...
    f.set_autopilot(1, flying(alt_rel_m=30.0))
    f.run_until(f.now + 2.0)
    assert not requests(f, 1, t, Land)
    # ... until the operator lands it, which ends the sortie
    send(f, command(67, CommandKind.LAND))
    f.run_until(f.now + 1.0)
    assert requests(f, 1, t, Land) and node.manager.phase == Phase.LANDING
    land(f, 1)
    assert node.fsm.state == FsmState.INACTIVE
    # an operator's own landing (mode QLAND) can be aborted too
    g = fleet_of(VTOL)
    g.set_autopilot(1, flying(mode_name="QLAND"))
    send(g, command(68, CommandKind.ABORT_LANDING))
    g.run_until(g.now + 1.0)
    assert acks(g, 68)[1].accepted


def test_parachute_all_engages_only_fitted_parachutes_and_leaves_the_mission() -> None:
    f = fleet_of(VTOL, QUAD)  # the seed's Albatross carries a parachute, the quad none
    on_mission(f)
    t = f.now
    send(f, command(70, CommandKind.PARACHUTE))  # "Parachute All"
    f.run_until(f.now + 1.0)
    answers = acks(f, 70)
    assert answers[1].accepted and len(requests(f, 1, t, Parachute)) == 1
    assert (answers[2].accepted, answers[2].reason) == (False, AckReason.UNSUPPORTED)
    assert not requests(f, 2, t, Parachute)
    vtol = f.nodes[1]
    assert vtol.manager.phase == Phase.PARACHUTE and vtol.fsm.mission_id == -1
    last = [s for s in f.messages(VehicleStatus, sender=1)][-1]
    assert last.mission_state == MissionState.PARACHUTE
    assert f.nodes[2].fsm.mission_id == 50
    land(f, 1)
    assert vtol.fsm.state == FsmState.INACTIVE


def test_calibrate_only_on_the_ground_and_off_mission() -> None:
    f = fleet_of(QUAD)
    send(f, command(80, CommandKind.CALIBRATE, text="baro"))  # flying: armed
    f.set_autopilot(1, flying(armed=False, alt_rel_m=0.0))
    f.run_until(f.now + 0.5)
    send(f, command(81, CommandKind.CALIBRATE, text="baro"))
    send(f, command(82, CommandKind.CALIBRATE, text="flux capacitor"))
    send(f, command(83, CommandKind.CALIBRATE))  # default: gyro
    f.run_until(f.now + 1.0)
    assert acks(f, 80)[1].reason == AckReason.BUSY
    assert acks(f, 81)[1].accepted and acks(f, 83)[1].accepted
    assert acks(f, 82)[1].reason == AckReason.INVALID
    assert [r.what for r in requests(f, 1, 0.0, Calibrate)] == ["baro", "gyro"]  # type: ignore[attr-defined]
    send(
        f,
        Mission(
            84, GCS, MissionType.OBJECTIVE, Geometry.point(37.42, -5.98), selection=Selector.ids(1)
        ),
    )
    f.run_until(f.now + 0.5)
    send(f, command(85, CommandKind.CALIBRATE, text="baro"))
    f.run_until(f.now + 0.5)
    assert acks(f, 85)[1].reason == AckReason.BUSY and "mission 84" in acks(f, 85)[1].text


@pytest.mark.parametrize(
    ("code", "profile", "expected"),
    [
        (AlertCode.AUTOPILOT_LINK_LOSS, QUAD, ()),  # nothing can be sent
        (AlertCode.ATTITUDE_ABNORMAL, VTOL, (Parachute,)),  # fitted
        (AlertCode.ATTITUDE_ABNORMAL, QUAD, ()),
        (AlertCode.GEOFENCE_BREACH, QUAD, (ReturnToLaunch,)),
        (AlertCode.GEOFENCE_BREACH, VTOL, (ReturnToLaunch,)),
        (AlertCode.BATTERY_CRITICAL, QUAD, (Land,)),  # land where it is
        (AlertCode.BATTERY_CRITICAL, VTOL, (Land,)),  # a VTOL lands vertically
        (AlertCode.GPS_LOSS, QUAD, (Land,)),
        (AlertCode.EKF_FAILURE, VTOL, (Land,)),
        (AlertCode.BATTERY_CRITICAL, ROVER, (SetMode,)),  # HOLD
        (AlertCode.GPS_LOSS, BOAT, (SetMode,)),
        (AlertCode.GENERIC, QUAD, (ReturnToLaunch,)),
    ],
)
def test_emergency_procedures(code: AlertCode, profile: VehicleProfile, expected: tuple) -> None:
    got = emergency_requests(code, profile)
    assert tuple(type(r) for r in got) == expected
    if expected == (SetMode,):
        assert got[0].mode == "HOLD"  # type: ignore[attr-defined]


def test_emergency_procedures_of_a_plane() -> None:
    plane = msgspec.structs.replace(VTOL, vehicle_type=VehicleType.PLANE, has_parachute=False)
    assert [type(r) for r in emergency_requests(AlertCode.BATTERY_CRITICAL, plane)] == [
        ReturnToLaunch
    ]  # a plane cannot land where it is: home
    assert emergency_requests(AlertCode.GPS_LOSS, plane) == ()  # ArduPlane's own failsafe
    assert emergency_requests(AlertCode.ATTITUDE_ABNORMAL, plane) == ()


def test_an_arm_refused_at_a_missions_start_is_reported_as_the_autopilots_refusal() -> None:
    """Not as a planning failure: under its own code, with ArduPilot's reason."""
    why = "Arm: COMMAND_ACK FAILED (PreArm: QLAND mode not armable)"

    def refuse_arm(node_id: int, req: ApRequest) -> ApResult:
        return ApResult(req.request_id, not isinstance(req, Arm), why)

    profiles = {1: as_vehicle(seed_profiles()["Albatross 250 VTOL"], 1)}
    f = Fleet({1: NodeCore(profiles[1], SETTINGS, fleet_profiles=profiles)}, autopilot=refuse_arm)
    f.set_autopilot(1, flying(armed=False, alt_rel_m=0.0, alt_msl_m=HOME.alt_msl_m))
    f.run_until(0.5)
    send(f, command(100, CommandKind.SET_BASE, point=HOME))
    f.run_until(1.5)
    target = Geometry.point(HOME.lat_deg + 0.004, HOME.lon_deg)
    send(f, Mission(51, GCS, MissionType.OBJECTIVE, target, MissionParams(altitude_rel_m=60.0)))
    f.run_until(f.now + 5.0)
    alerts = [a for a in f.messages(Alert, sender=1) if a.severity >= Severity.WARNING]
    assert [(a.code, a.text) for a in alerts if a.code == AlertCode.AUTOPILOT_REFUSED] == [
        (AlertCode.AUTOPILOT_REFUSED, "Arm: COMMAND_ACK FAILED (PreArm: QLAND mode not armable)")
    ]
    assert not [a for a in alerts if a.code == AlertCode.PLAN_FAILED]


def test_shutdown_in_the_air_sends_the_vehicle_home_and_shuts_down_once_landed() -> None:
    """SHUTDOWN during a mission left vehicle 9 INACTIVE, loitering at 40 m with no
    owner: now it leaves the mission as RTL does, flies home, and the landing shuts the
    node down."""
    f = fleet_of(QUAD, QUAD)
    on_mission(f)
    t = f.now
    send(f, command(63, CommandKind.SHUTDOWN, Selector.ids(1)))
    f.run_until(f.now + 1.0)
    node = f.nodes[1]
    assert acks(f, 63)[1].accepted
    assert len(requests(f, 1, t, ReturnToLaunch)) == 1
    assert (node.fsm.state, node.manager.phase) == (FsmState.GO_MISSION, Phase.RETURNING)
    assert node.active  # still the swarm's until it is down
    assert f.nodes[2].fsm.mission_id == 50  # the other vehicle flies on
    land(f, 1)
    assert node.fsm.state == FsmState.INACTIVE and not node.active
    assert not [a for a in f.messages(Alert, sender=1) if a.code == AlertCode.MISSION_COMPLETE]


def test_shutdown_in_the_air_outside_a_mission_sends_it_home_first() -> None:
    f = fleet_of(QUAD)
    send(f, command(64, CommandKind.SHUTDOWN, Selector.ids(1)))
    f.run_until(f.now + 1.0)
    assert acks(f, 64)[1].accepted and requests(f, 1, 0.0, ReturnToLaunch)
    assert not f.nodes[1].active


def test_shutdown_on_the_ground_only_shuts_down() -> None:
    f = fleet_of(QUAD)
    land(f, 1)
    t = f.now
    send(f, command(65, CommandKind.SHUTDOWN, Selector.ids(1)))
    f.run_until(f.now + 1.0)
    assert acks(f, 65)[1].accepted and not requests(f, 1, t, ReturnToLaunch)
    assert not f.nodes[1].active and f.nodes[1].fsm.state == FsmState.INACTIVE


def test_shutdown_in_the_air_without_the_autopilot_link_is_refused() -> None:
    """It could not be sent home: refused with the reason, the node stays active."""
    f = fleet_of(QUAD)
    f.set_autopilot(1, flying(link_ok=False))
    f.run_until(f.now + 0.5)
    send(f, command(66, CommandKind.SHUTDOWN, Selector.ids(1)))
    f.run_until(f.now + 1.0)
    ack = acks(f, 66)[1]
    assert (ack.accepted, ack.reason) == (False, AckReason.NOT_READY)
    assert "home" in ack.text and f.nodes[1].active
