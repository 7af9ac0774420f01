"""A fleet launching from close pads with a plan timeout shorter than the take-off
queue, in fast time over real MAVLink bytes (FastFleet). Found flying `swarm-sim demo --radio` (1x: its
nodes keep the default plan timeout): six VTOLs at pads 30 m apart take off in turn,
each when the one before is 30 m up; the wait for the turn and the climb (held level by
avoidance under the vehicles above) counted as planning, and the last ones were sent home
from their pads or from 46 m (PLAN_TIMEOUT). And a member lost while another waits,
climbed, for its PREMISSION meet: the replan dropped the meet, and the waiting node's
core raised (fleet_sync.plan_leg without a plan)."""

from __future__ import annotations

from swarm_node.core.mission_manager import Phase
from swarm_node.core.node import NodeSettings
from swarm_proto import (
    AlertCode,
    Command,
    CommandArgs,
    CommandKind,
    FsmState,
    GeoPoint,
    Mission,
    MissionParams,
    MissionState,
    MissionType,
)
from swarm_proto.messages import Alert
from swarm_sim.core import SITL_HOME
from swarm_sim.fast_fleet import FastFleet
from swarm_sim.scenarios import square

GCS = 900
VTOLS = (1, 2, 3, 4, 5, 6)  # the seed database's Albatross 250 VTOLs


def _launched(
    fleet_profiles: dict, members: tuple[int, ...], settings: NodeSettings | None = None
) -> FastFleet:
    fleet = FastFleet.build(list(members), fleet_profiles, spacing_m=30.0, settings=settings)
    fleet.run_until(lambda: all(v.link.state.ekf_has_position for v in fleet.vehicles.values()), 60)
    base = GeoPoint(SITL_HOME.lat_deg, SITL_HOME.lon_deg, SITL_HOME.alt_m)
    fleet.broadcast(Command(GCS, 1, CommandKind.SET_BASE, args=CommandArgs(point=base)))
    assert fleet.run_until(
        lambda: all(v.node.fsm.state == FsmState.GO_MISSION for v in fleet.vehicles.values()), 30
    )
    area = square(SITL_HOME.lat_deg + 0.008, SITL_HOME.lon_deg, 400.0)
    params = MissionParams(altitude_rel_m=80.0, side_overlap=0.5, altitude_step_m=10.0)
    fleet.broadcast(Mission(71, GCS, MissionType.AREA, area, params))
    return fleet


def test_six_vtols_at_close_pads_all_launch_within_a_plan_timeout_shorter_than_the_queue(
    fleet_profiles: dict,
) -> None:
    fleet = _launched(fleet_profiles, VTOLS, NodeSettings(plan_timeout_s=45.0))
    flying = lambda: all(  # noqa: E731
        v.node.manager.mission_state in (MissionState.PREMISSION, MissionState.MISSION)
        and v.link.state.armed
        for v in fleet.vehicles.values()
    )
    assert fleet.run_until(flying, 400), fleet.notes[-20:]
    timeouts = [a for a in fleet.messages(Alert) if a.code == AlertCode.PLAN_TIMEOUT]
    assert not timeouts
    held = [t for _, _, t in fleet.notes if t.startswith("take-off: pad clear after")]
    assert len(held) == len(VTOLS) - 1  # every one but the first waited its turn
    assert max(float(t.split()[-2]) for t in held) > 45.0  # the last longer than the timeout


def test_a_member_lost_while_another_waits_for_the_meet_is_replanned_without_it(
    fleet_profiles: dict,
) -> None:
    members = (1, 2, 3)
    fleet = _launched(fleet_profiles, members)
    meeting = lambda: any(  # noqa: E731
        v.node.manager.phase == Phase.MEETING for v in fleet.vehicles.values()
    )
    assert fleet.run_until(meeting, 300)
    waiting = next(
        vid for vid, v in fleet.vehicles.items() if v.node.manager.phase == Phase.MEETING
    )
    victim = max(set(members) - {waiting})
    fleet.kill(victim)
    survivors = [vid for vid in members if vid != victim]
    replanned = lambda: all(  # noqa: E731
        fleet.vehicles[v].node.manager.fleet_plan is not None
        and fleet.vehicles[v].node.manager.fleet_plan.roster == tuple(survivors)
        and fleet.vehicles[v].node.manager.mission_state == MissionState.MISSION
        and fleet.vehicles[v].node.fsm.state == FsmState.GO_MISSION
        for v in survivors
    )
    assert fleet.run_until(replanned, 300), fleet.notes[-20:]
