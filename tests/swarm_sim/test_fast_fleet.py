"""A heterogeneous fleet flies a whole area mission in fast time: simulated ArduPilot
vehicles, the real autopilot link and node cores, real MAVLink bytes and real swarm
messages, no sockets. From SET_BASE to every vehicle landed and the state machines
deactivated."""

from __future__ import annotations

import math

import pytest

from swarm_node.database.repository import SwarmDatabase
from swarm_proto import (
    Ack,
    Alert,
    AlertCode,
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
    VehicleStatus,
)
from swarm_sim.core import SITL_HOME
from swarm_sim.fast_fleet import FastFleet

GCS = 900


def square(center_lat: float, center_lon: float, half_m: float) -> Geometry:
    dlat = half_m / 111_320.0
    dlon = half_m / (111_320.0 * math.cos(math.radians(center_lat)))
    return Geometry.polygon(
        [
            (center_lat - dlat, center_lon - dlon),
            (center_lat - dlat, center_lon + dlon),
            (center_lat + dlat, center_lon + dlon),
            (center_lat + dlat, center_lon - dlon),
        ]
    )


@pytest.fixture(scope="module")
def profiles() -> dict:
    with SwarmDatabase.memory() as db:
        return {p.vehicle_id: p for p in db.profiles()}


def test_a_mixed_fleet_flies_an_area_mission_and_lands(profiles: dict) -> None:
    members = [1, 7, 8]  # an Albatross VTOL and two quadcopters from the seed
    fleet = FastFleet.build(members, profiles)
    fleet.run_until(lambda: all(v.link.state.ekf_has_position for v in fleet.vehicles.values()), 60)
    base = GeoPoint(SITL_HOME.lat_deg, SITL_HOME.lon_deg, SITL_HOME.alt_m)
    fleet.broadcast(Command(GCS, 1, CommandKind.SET_BASE, args=CommandArgs(point=base)))
    assert fleet.run_until(
        lambda: all(v.node.fsm.state == FsmState.GO_MISSION for v in fleet.vehicles.values()), 30
    )
    area = square(SITL_HOME.lat_deg + 0.003, SITL_HOME.lon_deg, 100.0)  # sized for 6-minute quads
    mission = Mission(
        42, GCS, MissionType.AREA, area, MissionParams(altitude_rel_m=60.0), Selector.ids(*members)
    )
    fleet.broadcast(mission)
    flying = fleet.run_until(
        lambda: all(v.node.manager.phase.value == "flying" for v in fleet.vehicles.values()), 300
    )
    assert flying, fleet.notes[-20:]
    done = fleet.run_until(
        lambda: all(v.node.fsm.state == FsmState.INACTIVE for v in fleet.vehicles.values()), 1800
    )
    assert done, [(v.node.fsm.state, v.node.manager.phase) for v in fleet.vehicles.values()]
    acks = [a for a in fleet.messages(Ack) if a.ref_id == 42]
    assert sorted(a.vehicle_id for a in acks) == members and all(a.accepted for a in acks)
    completed = {
        a.vehicle_id for a in fleet.messages(Alert) if a.code == AlertCode.MISSION_COMPLETE
    }
    assert completed == set(members)
    for vid, v in fleet.vehicles.items():
        s = v.link.state
        assert not s.armed and (s.alt_rel_m or 0.0) < 1.0, vid
    statuses = fleet.messages(VehicleStatus)
    assert max(s.mission_progress_pct for s in statuses) == 100


def test_the_demo_survey_flies_around_its_no_fly_zone(profiles: dict) -> None:
    """The demo's scenario in fast time: three VTOLs and two quadcopters cover the field,
    none ever enters the no-fly zone inside it (lanes, approach legs and the way home),
    all land."""
    from swarm_sim.demo import DEFAULT_FLEET, demo_area

    members = list(DEFAULT_FLEET)
    fleet = FastFleet.build(members, profiles)
    fleet.run_until(lambda: all(v.link.state.ekf_has_position for v in fleet.vehicles.values()), 60)
    base = GeoPoint(SITL_HOME.lat_deg, SITL_HOME.lon_deg, SITL_HOME.alt_m)
    fleet.broadcast(Command(GCS, 1, CommandKind.SET_BASE, args=CommandArgs(point=base)))
    fleet.run_for(2.0)
    area, zone = demo_area()
    fleet.broadcast(zone)
    fleet.broadcast(Mission(7, GCS, MissionType.AREA, area, MissionParams(altitude_rel_m=60.0, side_overlap=0.6),
                            Selector.ids(*members)))  # fmt: skip
    centre, radius = zone.geometry.points[0], zone.geometry.radius_m or 0.0
    closest = {vid: math.inf for vid in members}

    def landed() -> bool:
        for vid, v in fleet.vehicles.items():
            s = v.link.state
            if s.lat_deg is not None and s.lon_deg is not None:
                d = math.hypot(
                    (s.lat_deg - centre.lat_deg) * 111_320.0,
                    (s.lon_deg - centre.lon_deg) * 111_320.0 * math.cos(math.radians(s.lat_deg)),
                )
                closest[vid] = min(closest[vid], d)
        return fleet.now > 1.8e9 + 100 and all(
            v.node.fsm.state == FsmState.INACTIVE for v in fleet.vehicles.values()
        )

    assert fleet.run_until(landed, 900), [
        (v.node.fsm.state, v.node.manager.phase) for v in fleet.vehicles.values()
    ]
    assert min(closest.values()) > radius, closest
    assert not [a for a in fleet.messages(Alert) if a.code == AlertCode.GEOFENCE_BREACH]
    completed = {
        a.vehicle_id for a in fleet.messages(Alert) if a.code == AlertCode.MISSION_COMPLETE
    }
    assert completed == set(members)
