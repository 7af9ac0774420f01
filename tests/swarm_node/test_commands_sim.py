"""Operator commands end to end in fast time (FastFleet: node core, autopilot link,
simulated ArduPilot, real MAVLink): an emergency landing on a given point during a
mission lands the quadcopter there and ends its sortie; a parachute released on the
seed's Albatross brings it down and ends its sortie."""

from __future__ import annotations

import math

from swarm_proto import (
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
from tests.swarm_node.test_node_fences_sim import GCS, Operator, north


def flying_a_mission(fleet_profiles: dict, vid: int) -> tuple[FastFleet, Operator]:
    fleet = FastFleet.build([vid], fleet_profiles)
    v = fleet.vehicles[vid]
    assert fleet.run_until(lambda: v.link.state.ekf_has_position and v.link.state.home, 60)
    op = Operator(fleet)
    base = GeoPoint(SITL_HOME.lat_deg, SITL_HOME.lon_deg, SITL_HOME.alt_m)
    assert op(CommandKind.SET_BASE, point=base).accepted
    assert fleet.run_until(lambda: v.node.fsm.state == FsmState.GO_MISSION, 30)
    far = Geometry.point(*north(1500.0))
    fleet.broadcast(
        Mission(
            9,
            GCS,
            MissionType.OBJECTIVE,
            far,
            MissionParams(altitude_rel_m=50.0),
            Selector.ids(vid),
        )
    )
    assert fleet.run_until(lambda: v.node.manager.phase.value == "flying", 300)
    assert fleet.run_until(lambda: (v.link.state.alt_rel_m or 0.0) > 45.0, 120)
    return fleet, op


def test_an_emergency_landing_lands_on_the_given_point(fleet_profiles: dict) -> None:
    fleet, op = flying_a_mission(fleet_profiles, 7)  # a seed quadcopter
    v = fleet.vehicles[7]
    k = 111_320.0 * math.cos(math.radians(SITL_HOME.lat_deg))
    assert v.link.state.lat_deg is not None and v.link.state.lon_deg is not None
    point = GeoPoint(v.link.state.lat_deg, v.link.state.lon_deg + 150.0 / k, SITL_HOME.alt_m)
    assert op(CommandKind.EMERGENCY_LAND, point=point).accepted
    assert fleet.run_until(lambda: v.node.fsm.state == FsmState.INACTIVE, 300)
    s = v.link.state
    assert s.lat_deg is not None and s.lon_deg is not None and not s.armed
    miss = math.hypot((s.lat_deg - point.lat_deg) * 111_320.0, (s.lon_deg - point.lon_deg) * k)
    assert miss < 5.0, miss
    assert not v.node.active  # the sortie is over: ACTIVATE starts the next


def test_a_released_parachute_ends_the_sortie(fleet_profiles: dict) -> None:
    fleet, op = flying_a_mission(fleet_profiles, 1)  # a seed Albatross: parachute fitted
    v = fleet.vehicles[1]
    assert op(CommandKind.PARACHUTE).accepted
    assert v.node.mission_state.name == "PARACHUTE"
    assert fleet.run_until(lambda: v.node.fsm.state == FsmState.INACTIVE, 300)
    assert not v.link.state.armed and (v.link.state.alt_rel_m or 0.0) < 2.0


def test_shutdown_mid_mission_brings_the_vehicle_down_at_its_base(fleet_profiles: dict) -> None:
    """SHUTDOWN during a mission left the vehicle INACTIVE, loitering at 40 m with no
    owner: now it flies home and lands, and the node shuts down on the ground."""
    fleet, op = flying_a_mission(fleet_profiles, 7)  # a seed quadcopter
    v = fleet.vehicles[7]
    assert op(CommandKind.SHUTDOWN).accepted
    assert fleet.run_until(lambda: v.node.fsm.state == FsmState.INACTIVE, 600)
    s = v.link.state
    assert not s.armed and (s.alt_rel_m or 0.0) < 1.0 and not v.node.active
    assert s.lat_deg is not None and s.lon_deg is not None
    k = 111_320.0 * math.cos(math.radians(SITL_HOME.lat_deg))
    off = math.hypot(
        (s.lat_deg - SITL_HOME.lat_deg) * 111_320.0, (s.lon_deg - SITL_HOME.lon_deg) * k
    )
    assert off < 10.0, off  # at its base (the home the simulator starts on)
