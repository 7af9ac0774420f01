"""A heterogeneous fleet flies a whole area mission in fast time: simulated ArduPilot
vehicles, the real autopilot link and node cores, real MAVLink bytes and real swarm
messages, no sockets. From SET_BASE to every vehicle landed and the state machines
deactivated."""

from __future__ import annotations

import math
from collections.abc import Callable

import pytest

from swarm_proto import (
    Ack,
    AckRef,
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


# the same fleet (1, 7, 8) flies the same kind of survey to the end in
# test_reboot_in_flight.py and test_stall_rejoins.py, and the demo's six VTOLs fly theirs
# to the landing in test_demo_story.py
@pytest.mark.soak
def test_a_mixed_fleet_flies_an_area_mission_and_lands(fleet_profiles: dict) -> None:
    members = [1, 7, 8]  # an Albatross VTOL and two quadcopters from the seed
    fleet = FastFleet.build(members, fleet_profiles)
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


def _fly_demo_survey(
    fleet_profiles: dict, members: list[int], done: Callable[[FastFleet], bool], timeout_s: float
) -> tuple[FastFleet, dict[int, float], float]:
    """The demo's survey (its field and no-fly zone) flown by `members` in fast time
    until `done`; the fleet, each vehicle's closest approach to the zone's centre (m)
    and the zone's radius."""
    from swarm_node.core.node import NodeSettings
    from swarm_sim.demo import demo_area

    # the planners' zone clearance, flown as planned: avoidance off (with it, its climbs
    # cost the 3.3 Ah quadcopters their reserve; the same survey with avoidance on is
    # measured in tests/swarm_sim/test_separation.py and docs/avoidance.md)
    fleet = FastFleet.build(members, fleet_profiles, settings=NodeSettings(avoidance=False))
    fleet.run_until(lambda: all(v.link.state.ekf_has_position for v in fleet.vehicles.values()), 60)
    base = GeoPoint(SITL_HOME.lat_deg, SITL_HOME.lon_deg, SITL_HOME.alt_m)
    fleet.broadcast(Command(GCS, 1, CommandKind.SET_BASE, args=CommandArgs(point=base)))
    fleet.run_for(2.0)
    area, zone = demo_area()
    fleet.broadcast(zone)
    fleet.broadcast(
        Mission(
            7,
            GCS,
            MissionType.AREA,
            area,
            MissionParams(altitude_rel_m=60.0, side_overlap=0.6),
            Selector.ids(*members),
        )
    )
    centre, radius = zone.geometry.points[0], zone.geometry.radius_m or 0.0
    closest = {vid: math.inf for vid in members}
    t0 = fleet.now

    def step() -> bool:
        for vid, v in fleet.vehicles.items():
            s = v.link.state
            if s.lat_deg is not None and s.lon_deg is not None:
                d = math.hypot(
                    (s.lat_deg - centre.lat_deg) * 111_320.0,
                    (s.lon_deg - centre.lon_deg) * 111_320.0 * math.cos(math.radians(s.lat_deg)),
                )
                closest[vid] = min(closest[vid], d)
        return fleet.now > t0 + 60 and done(fleet)

    assert fleet.run_until(step, timeout_s), [
        (v.node.fsm.state, v.node.manager.phase) for v in fleet.vehicles.values()
    ]
    return fleet, closest, radius


@pytest.mark.soak  # the demo's field flown clear of its zone: test_demo_story.py
def test_the_demo_survey_flies_around_its_no_fly_zone(fleet_profiles: dict) -> None:
    """The demo's scenario in fast time: three VTOLs and two quadcopters cover the field,
    none ever enters the no-fly zone inside it (lanes, approach legs and the way home),
    all land."""
    from swarm_sim.demo import DEFAULT_FLEET

    members = list(DEFAULT_FLEET)
    fleet, closest, radius = _fly_demo_survey(
        fleet_profiles,
        members,
        lambda f: all(v.node.fsm.state == FsmState.INACTIVE for v in f.vehicles.values()),
        900,
    )
    assert min(closest.values()) > radius, closest
    assert not [a for a in fleet.messages(Alert) if a.code == AlertCode.GEOFENCE_BREACH]
    completed = {
        a.vehicle_id for a in fleet.messages(Alert) if a.code == AlertCode.MISSION_COMPLETE
    }
    assert completed == set(members)


@pytest.mark.soak  # the uploads predicted clear of the zone: test_flight.py (the demo's surveys)
def test_one_albatross_with_many_lanes_flies_around_the_demo_zone(fleet_profiles: dict) -> None:
    """The demo's survey for one Albatross and two quadcopters: the VTOL gets many lanes
    cut by the zone, joined around it; before the flyable stage its autopilot turned to
    the shorter side at a reversal and looped through the zone. Now it completes its
    share clear of the zone (the quadcopters are sized for a smaller field: the
    second one's battery may run out on the way home, which is not the point here)."""
    members = [1, 7, 8]
    fleet, closest, radius = _fly_demo_survey(
        fleet_profiles,
        members,
        lambda f: all(
            not v.link.state.armed and (v.link.state.alt_rel_m or 0.0) < 1.0
            for v in f.vehicles.values()
        ),
        900,
    )
    assert min(closest.values()) > radius, closest
    assert closest[1] > radius + 10.0, closest
    assert not [a for a in fleet.messages(Alert) if a.code == AlertCode.GEOFENCE_BREACH]
    completed = {
        a.vehicle_id for a in fleet.messages(Alert) if a.code == AlertCode.MISSION_COMPLETE
    }
    assert 1 in completed


def _mission_run(
    fleet_profiles: dict, *, together: bool, latency_s: float, tokens: bool = False
) -> FastFleet:
    members = [1, 7, 8, 10]
    fleet = FastFleet.build(members, fleet_profiles)
    fleet.hear_together, fleet.latency_s = together, latency_s
    if tokens:
        fleet.hold_tokens()
    fleet.run_for(8.0)
    base = GeoPoint(SITL_HOME.lat_deg, SITL_HOME.lon_deg, SITL_HOME.alt_m)
    fleet.broadcast(Command(GCS, 1, CommandKind.SET_BASE, args=CommandArgs(point=base)))
    fleet.run_for(3.0)
    area = square(SITL_HOME.lat_deg + 0.003, SITL_HOME.lon_deg, 100.0)
    mission = Mission(
        42, GCS, MissionType.AREA, area, MissionParams(altitude_rel_m=60.0), Selector.ids(*members)
    )
    fleet.broadcast(mission)
    fleet.run_for(40.0)  # the vote, the plans, the uploads and the take-offs
    return fleet


@pytest.mark.parametrize(
    ("latency_s", "tokens"),
    [
        # in one process and without tokens: the same rule, `make soak`
        pytest.param(0.0, False, marks=pytest.mark.soak),
        pytest.param(0.010, False, marks=pytest.mark.soak),
        (0.010, True),
    ],
)
def test_nodes_hearing_a_batch_together_give_the_same_run(
    fleet_profiles: dict, latency_s: float, tokens: bool
) -> None:
    """FastFleet hands each node what it hears at one time in one call: the
    same messages published at the same times, the same notes and autopilot requests
    as hearing entry by entry, in one process (latency 0) and in a split fleet's
    windows (10 ms), with peers known by their telemetry and (the sim bench's LAN swarm)
    by their liveliness tokens; a run of known peers' statuses is taken at once."""
    together = _mission_run(fleet_profiles, together=True, latency_s=latency_s, tokens=tokens)
    one_by_one = _mission_run(fleet_profiles, together=False, latency_s=latency_s, tokens=tokens)
    assert together.batches_heard > 100 and one_by_one.batches_heard == 0
    phases = {vid: v.node.manager.phase.value for vid, v in together.vehicles.items()}
    # the rover's split share of this field is empty: it stays on its pad
    assert phases == {1: "flying", 7: "flying", 8: "flying", 10: "idle"}
    assert together.published == one_by_one.published
    assert together.notes == one_by_one.notes
    assert together.submitted == one_by_one.submitted


def test_a_lan_swarm_knows_its_peers_by_liveliness_token(fleet_profiles: dict) -> None:
    """FastFleet.hold_tokens (the sim bench's LAN swarm): every node knows
    every peer by its liveliness token (none is watched for staleness); a vanished
    vehicle's token goes a lease later; a partition withdraws the tokens across it a
    lease later and a healed one shows them again at once."""
    members = [1, 7, 8, 10]
    fleet = FastFleet.build(members, fleet_profiles)
    fleet.hold_tokens()
    fleet.run_for(8.0)

    def known(vid: int) -> dict[int, bool]:
        peers = fleet.vehicles[vid].node.members.peers
        return {p: peer.alive_token for p, peer in peers.items() if peer.present}

    for vid in members:
        assert known(vid) == {p: True for p in members if p != vid}
        assert not fleet.vehicles[vid].node.members._watch
    fleet.kill(10)
    fleet.run_for(fleet.lease_s - 0.5)
    assert 10 in known(1)  # its token outlives it by the lease
    fleet.run_for(1.0)
    assert all(10 not in known(vid) for vid in (1, 7, 8))
    fleet.groups = {1: 0, 7: 0, 8: 1}
    fleet.run_for(fleet.lease_s + 0.5)
    assert set(known(1)) == {7} and set(known(8)) == set()
    fleet.groups = None
    fleet.run_for(1.0)
    assert set(known(1)) == {7, 8} and known(8) == {1: True, 7: True}


def test_a_member_the_split_gives_nothing_stays_on_its_pad(fleet_profiles: dict) -> None:
    """A field beyond a quadcopter's battery (1 km away: 3.3 Ah flies it ~1.8 km at
    cruise after its climb and landing): the endurance-aware split gives the quadcopter
    no lanes. It does not take off (before, it climbed, hovered at its take-off altitude
    with an empty mission and reached BATTERY_CRITICAL: the mixed demo's failure), says
    so in its answer (no MISSION_COMPLETE: it flew nothing), and its leaving the mission
    is not a loss the others replan for."""
    from swarm_node.core.node import NodeSettings

    members = [1, 2, 7]  # two Albatross VTOLs and a quadcopter
    fleet = FastFleet.build(members, fleet_profiles, settings=NodeSettings(avoidance=False))
    fleet.run_until(lambda: all(v.link.state.ekf_has_position for v in fleet.vehicles.values()), 60)
    base = GeoPoint(SITL_HOME.lat_deg, SITL_HOME.lon_deg, SITL_HOME.alt_m)
    fleet.broadcast(Command(GCS, 1, CommandKind.SET_BASE, args=CommandArgs(point=base)))
    assert fleet.run_until(
        lambda: all(v.node.fsm.state == FsmState.GO_MISSION for v in fleet.vehicles.values()), 30
    )
    area = square(SITL_HOME.lat_deg + 1200.0 / 111_320.0, SITL_HOME.lon_deg, 150.0)
    fleet.broadcast(
        Mission(
            43,
            GCS,
            MissionType.AREA,
            area,
            MissionParams(altitude_rel_m=60.0),
            Selector.ids(*members),
        )
    )
    done = fleet.run_until(
        lambda: all(v.node.fsm.state == FsmState.INACTIVE for v in fleet.vehicles.values()), 1800
    )
    assert done, [(v.node.fsm.state, v.node.manager.phase) for v in fleet.vehicles.values()]
    quad = [s for s in fleet.messages(VehicleStatus) if s.vehicle_id == 7]
    assert quad and not any(s.armed for s in quad)
    assert fleet.vehicles[7].node.manager.fleet_plan is not None
    completed = {
        a.vehicle_id for a in fleet.messages(Alert) if a.code == AlertCode.MISSION_COMPLETE
    }
    assert completed == {1, 2}  # 7 flew nothing: no MISSION_COMPLETE of its own
    (answer,) = [a for a in fleet.messages(Ack) if a.ref == AckRef.MISSION and a.vehicle_id == 7]
    assert answer.accepted and "stays on its pad" in answer.text, answer
    others = [s for s in fleet.messages(VehicleStatus) if s.vehicle_id != 7]
    assert max(s.mission_progress_pct for s in others) == 100
    assert not any(s.mission_state.name == "REPLAN" for s in others)  # 7 was not lost
    assert not any("lost" in text for _t, vid, text in fleet.notes if vid != 7)
