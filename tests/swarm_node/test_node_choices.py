"""Two choices docs/paper-choices.md names, each held by a test: setting the base uploads the
vehicle's own landing point at the base as the autopilot's rally point (its pad: so
ArduPilot's own RTL brings it home to its pad, never onto another's), and
every mission ends on an unlimited loiter (so a plane never RTLs by itself, through a
no-fly zone, when its mission ends). Pure node cores first, then end to end in fast
time (FastFleet: the simulated ArduPilot holds them)."""

from __future__ import annotations

import math

import pytest

from swarm_node.core.autopilot.items import ItemKind
from swarm_node.core.autopilot.requests import ApResult, UploadMission, UploadRally
from swarm_node.core.node import (
    AutopilotResult,
    AutopilotUpdate,
    NodeCore,
    Publish,
    Received,
    Submit,
)
from swarm_node.database import seed_profiles
from swarm_proto import (
    Ack,
    Command,
    CommandArgs,
    CommandKind,
    FsmState,
    Geometry,
    GeoPoint,
    Mission,
    MissionParams,
    MissionType,
    Selector,
)
from swarm_sim.core import SITL_HOME
from swarm_sim.fast_fleet import FastFleet
from tests.swarm_node.test_node_core import GCS, HOME, flying
from tests.swarm_node.test_node_fences_sim import Operator, north

NAV_RALLY_POINT, NAV_LOITER_UNLIM = 5100, 17
BASE = GeoPoint(HOME.lat_deg + 0.001, HOME.lon_deg, HOME.alt_msl_m + 5.0)


def test_set_base_uploads_the_own_pad_as_the_rally_point_and_answers_after_it() -> None:
    node = NodeCore(seed_profiles()["Generic Quadcopter"], now=0.0)
    node.handle(AutopilotUpdate(flying()), 0.0)
    out = node.handle(
        Received(Command(GCS, 1, CommandKind.SET_BASE, args=CommandArgs(point=BASE))), 0.0
    )
    (rally,) = [o.request for o in out if isinstance(o, Submit)]
    assert isinstance(rally, UploadRally)
    # its pad (home, 111 m from the base), at the base's altitude (5 m above home)
    # raised to the quadcopter's safe floor (ArduCopter's RTL_ALT default)
    assert rally.points == ((HOME.lat_deg, HOME.lon_deg, pytest.approx(15.0)),)
    assert not [o for o in out if isinstance(o, Publish) and isinstance(o.msg, Ack)]
    assert node.base == BASE  # the base is set at once, the Ack waits for the autopilot
    out = node.handle(AutopilotResult(ApResult(rally.request_id, True)), 0.1)
    (ack,) = [o.msg for o in out if isinstance(o, Publish)]
    assert isinstance(ack, Ack) and ack.accepted and ack.ref_id == 1
    # without an autopilot home (or link) there is nothing to upload: answered at once
    bare = NodeCore(seed_profiles()["Generic Quadcopter"], now=0.0)
    bare.handle(AutopilotUpdate(flying(home=None)), 0.0)
    out = bare.handle(
        Received(Command(GCS, 2, CommandKind.SET_BASE, args=CommandArgs(point=BASE))), 0.0
    )
    assert not [o for o in out if isinstance(o, Submit)]
    assert [o.msg.accepted for o in out if isinstance(o, Publish)] == [True]  # type: ignore[attr-defined]


@pytest.mark.parametrize(
    ("model", "base_above_home_m", "rally_m"),
    [
        ("Albatross 250 VTOL", 0.0, 40.0),  # the recorded crash: a rally point at 0 m
        ("Albatross 250 VTOL", 75.0, 75.0),  # the operator's altitude when higher
        ("Generic Quadcopter", -3.0, 15.0),
        ("Generic Quadcopter", 25.0, 25.0),
    ],
)
def test_the_rally_point_is_never_below_a_safe_altitude(
    model: str, base_above_home_m: float, rally_m: float
) -> None:
    """SET_BASE uploaded base - home altitude, 0 m when the operator
    gave none; ArduPlane's RTL flew the QuadPlane into the ground at that rally point."""
    node = NodeCore(seed_profiles()[model], now=0.0)
    node.handle(AutopilotUpdate(flying()), 0.0)
    base = GeoPoint(BASE.lat_deg, BASE.lon_deg, HOME.alt_msl_m + base_above_home_m)
    out = node.handle(
        Received(Command(GCS, 1, CommandKind.SET_BASE, args=CommandArgs(point=base))), 0.0
    )
    (rally,) = [o.request for o in out if isinstance(o, Submit)]
    assert isinstance(rally, UploadRally) and rally.points[0][2] == pytest.approx(rally_m)


@pytest.mark.parametrize(
    ("model", "rally_m"),
    [
        ("Generic Rover", 0.0),
        ("Generic Boat", 0.0),
        ("Generic Quadcopter", 15.0),
        ("Albatross 250 VTOL", 40.0),
    ],
)
def test_set_base_without_an_altitude_never_puts_the_rally_point_below_home(
    model: str, rally_m: float
) -> None:
    """`gcs cmd set-base --point LAT,LON` sends the base at 0 m above sea
    level; with home 10 m above sea level the rally point went to -10 m relative."""
    node = NodeCore(seed_profiles()[model], now=0.0)
    home = GeoPoint(HOME.lat_deg, HOME.lon_deg, 10.0)
    node.handle(AutopilotUpdate(flying(home=home)), 0.0)
    base = GeoPoint(BASE.lat_deg, BASE.lon_deg, 0.0)  # what the CLI sends without ALT
    out = node.handle(
        Received(Command(GCS, 1, CommandKind.SET_BASE, args=CommandArgs(point=base))), 0.0
    )
    (rally,) = [o.request for o in out if isinstance(o, Submit)]
    assert isinstance(rally, UploadRally) and rally.points[0][2] == pytest.approx(rally_m)
    assert rally.points[0][2] >= 0.0


def test_each_vehicle_returns_to_its_own_landing_point_never_another_s() -> None:
    """ArduPilot's RTL goes to the nearest rally point: with the base as every vehicle's
    rally point, a copter whose node had died landed on another's pad. A vehicle based
    at the base goes to its own pad; one from afar to a slot at the base of its own."""
    from swarm_node.core.landing_point import PAD_AREA_M, landing_point
    from swarm_proto.geodesy import distance_m, offset

    base = GeoPoint(HOME.lat_deg, HOME.lon_deg, HOME.alt_msl_m)
    pads = {
        vid: GeoPoint(*offset(base.lat_deg, base.lon_deg, 0.0, 30.0 * vid), 10.0)
        for vid in (1, 2, 7, 8)
    }
    for vid, pad in pads.items():
        assert landing_point(vid, pad, base) == (pad.lat_deg, pad.lon_deg)
    far = GeoPoint(*offset(base.lat_deg, base.lon_deg, 2 * PAD_AREA_M, 0.0), 10.0)
    slots = [landing_point(vid, far, base) for vid in range(1, 60)]
    for i, a in enumerate(slots):
        assert distance_m(*a, base.lat_deg, base.lon_deg) < 250.0
        for b in slots[i + 1 :]:
            assert distance_m(*a, *b) > 15.0  # every vehicle its own


def test_a_mission_ends_on_an_unlimited_loiter_over_its_last_waypoint() -> None:
    from tests.swarm_node.test_commands import VTOL, fleet_of, on_mission, requests

    f = fleet_of(VTOL)
    on_mission(f)
    (upload,) = requests(f, 1, 0.0, UploadMission)
    assert isinstance(upload, UploadMission)
    loiter = upload.items[-1]
    last_wp = next(w for w in reversed(upload.items) if w.kind == ItemKind.WAYPOINT)
    assert (loiter.kind, loiter.lat_deg, loiter.lon_deg, loiter.alt_rel_m) == (
        ItemKind.LOITER_UNLIMITED,
        last_wp.lat_deg,
        last_wp.lon_deg,
        last_wp.alt_rel_m,
    )
    # reaching the last waypoint (not the loiter, which never ends) completes the mission
    node = f.nodes[1]
    assert node.manager.last_item == len(upload.items) - 1  # item 0 is home
    f.set_autopilot(1, flying(mission_reached=node.manager.last_item))
    f.run_until(f.now + 1.0)
    assert node.fsm.mission_id == -1  # mission complete: the return home began


def test_the_simulated_autopilot_holds_the_base_and_the_final_loiter(fleet_profiles: dict) -> None:
    fleet = FastFleet.build([1], fleet_profiles)  # a seed Albatross VTOL
    v = fleet.vehicles[1]
    sim = v.endpoint.autopilot
    assert fleet.run_until(lambda: v.link.state.ekf_has_position and v.link.state.home, 60)
    op = Operator(fleet)
    base = GeoPoint(*north(30.0), SITL_HOME.alt_m)
    assert op(CommandKind.SET_BASE, point=base).accepted
    # the base at home's altitude: the rally point at the VTOL's safe floor, 40 m above
    # home (at 0 m ArduPlane's RTL flies into the ground)
    assert [(it.command, round(it.z, 3)) for it in sim.rally_items] == [(NAV_RALLY_POINT, 40.0)]
    rally = sim.rally_items[0]
    home = v.link.state.home
    assert math.isclose(rally.lat_deg, home.lat_deg, abs_tol=1e-7)  # its pad, 30 m from base
    assert math.isclose(rally.lon_deg, home.lon_deg, abs_tol=1e-7)
    assert fleet.run_until(lambda: v.node.fsm.state == FsmState.GO_MISSION, 30)
    target = Geometry.point(*north(800.0))
    fleet.broadcast(
        Mission(
            5,
            GCS,
            MissionType.OBJECTIVE,
            target,
            MissionParams(altitude_rel_m=60.0),
            Selector.ids(1),
        )
    )
    assert fleet.run_until(lambda: v.node.manager.phase.value == "flying", 300)
    assert sim.mission_items[-1].command == NAV_LOITER_UNLIM
