"""A mission sent to a vehicle that is landing (the last stage of its way home).

Found flying the paper's experiment 1 over processes (`make demo`): a VTOL that had
finished its share of the survey was in its final descent when the route mission
came; it took it as if it were flying (armed), uploaded its PREMISSION leg and set
AUTO, and sat armed on its pad for ever (a QuadPlane does not take off from a
waypoint), holding its fleet's route. A vehicle landing now answers BUSY ("landing"):
the mission is for after the landing (ACTIVATE, then send it again)."""

from __future__ import annotations

from swarm_node.core.mission_manager import Phase
from swarm_proto import (
    Ack,
    AckReason,
    Command,
    CommandArgs,
    CommandKind,
    FsmState,
    Geometry,
    GeoPoint,
    Mission,
    MissionParams,
    MissionType,
)
from swarm_sim.core import SITL_HOME
from swarm_sim.fast_fleet import FastFleet

GCS = 900


def test_a_vtol_landing_answers_a_new_mission_busy_and_lands(fleet_profiles: dict) -> None:
    fleet = FastFleet.build([1], fleet_profiles)
    v = fleet.vehicles[1]
    fleet.run_until(lambda: v.link.state.ekf_has_position, 60)
    base = GeoPoint(SITL_HOME.lat_deg, SITL_HOME.lon_deg, SITL_HOME.alt_m)
    fleet.broadcast(Command(GCS, 1, CommandKind.SET_BASE, args=CommandArgs(point=base)))
    assert fleet.run_until(lambda: v.node.fsm.state == FsmState.GO_MISSION, 30)
    point = Geometry.point(SITL_HOME.lat_deg + 0.004, SITL_HOME.lon_deg)
    fleet.broadcast(
        Mission(
            41, GCS, MissionType.TARGET, point, MissionParams(altitude_rel_m=40.0, duration_s=10.0)
        )
    )
    assert fleet.run_until(lambda: v.node.manager.phase == Phase.LANDING, 900), fleet.notes[-10:]
    assert v.link.state.armed
    fleet.broadcast(Mission(42, GCS, MissionType.TARGET, point, MissionParams(altitude_rel_m=40.0)))
    fleet.run_for(2.0)
    (ack,) = [a for a in fleet.messages(Ack) if a.ref_id == 42]
    assert not ack.accepted and ack.reason == AckReason.BUSY and "landing" in ack.text
    assert fleet.run_until(
        lambda: v.node.fsm.state == FsmState.INACTIVE and not v.link.state.armed, 600
    ), fleet.notes[-10:]
    assert (v.link.state.alt_rel_m or 0.0) < 1.0
