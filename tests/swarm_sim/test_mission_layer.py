"""The mission layer in fast time (simulated ArduPilot vehicles, the real autopilot link
and node cores, real MAVLink bytes): progress along a sortie, a fixed-wing target
mission's duration."""

from __future__ import annotations

from swarm_proto import (
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
from tests.swarm_sim.test_fast_fleet import square

GCS = 900


def ready_fleet(members: list[int], profiles: dict) -> FastFleet:
    fleet = FastFleet.build(members, profiles)
    fleet.run_until(lambda: all(v.link.state.ekf_has_position for v in fleet.vehicles.values()), 60)
    base = GeoPoint(SITL_HOME.lat_deg, SITL_HOME.lon_deg, SITL_HOME.alt_m)
    fleet.broadcast(Command(GCS, 1, CommandKind.SET_BASE, args=CommandArgs(point=base)))
    assert fleet.run_until(
        lambda: all(v.node.fsm.state == FsmState.GO_MISSION for v in fleet.vehicles.values()), 30
    )
    return fleet


def landed(fleet: FastFleet) -> bool:
    return all(v.node.fsm.state == FsmState.INACTIVE for v in fleet.vehicles.values())


def test_progress_never_falls_during_a_sortie(fleet_profiles: dict) -> None:
    """Defect 5: progress fell from 95-100 % to 0 % on the way home while the state
    still said GO_MISSION."""
    fleet = ready_fleet([7], fleet_profiles)
    area = square(SITL_HOME.lat_deg + 0.0015, SITL_HOME.lon_deg, 60.0)
    fleet.broadcast(Mission(5, GCS, MissionType.AREA, area, MissionParams(altitude_rel_m=40.0)))
    assert fleet.run_until(lambda: landed(fleet), 900)
    progress = [s.mission_progress_pct for s in fleet.messages(VehicleStatus, sender=7)]
    start = next(i for i, p in enumerate(progress) if p > 0)
    flown = progress[start:]
    assert flown == sorted(flown), flown
    assert flown[-1] == 100


def test_a_fixed_wing_target_mission_ends_after_its_duration(fleet_profiles: dict) -> None:
    """Defect 5: `--duration` of a fixed-wing target mission was ignored (endless
    orbit): the mission completes after orbiting for the duration, then the way home."""
    fleet = ready_fleet([1], fleet_profiles)
    target = Geometry.point(SITL_HOME.lat_deg + 0.006, SITL_HOME.lon_deg)
    params = MissionParams(altitude_rel_m=80.0, duration_s=90.0)
    fleet.broadcast(Mission(6, GCS, MissionType.TARGET, target, params, Selector.ids(1)))
    t0 = fleet.now
    done = fleet.run_until(
        lambda: any(a.code == AlertCode.MISSION_COMPLETE for a in fleet.messages(Alert)), 900
    )
    assert done, fleet.notes[-10:]
    assert fleet.now - t0 > 90.0
    assert fleet.run_until(lambda: landed(fleet), 900)


def test_two_missions_with_no_selector_in_a_row_on_the_same_nodes(fleet_profiles: dict) -> None:
    """A mission to ALL, flown and landed; the operator activates the fleet again; a
    second mission to ALL on the same nodes is shared by the same two and flown too
    (a second mission used to "complete" 200 ms after it started)."""
    from swarm_proto import Ack

    fleet = ready_fleet([7, 8], fleet_profiles)
    area = square(SITL_HOME.lat_deg + 0.0012, SITL_HOME.lon_deg, 40.0)
    for mid in (41, 42):
        fleet.broadcast(
            Mission(mid, GCS, MissionType.AREA, area, MissionParams(altitude_rel_m=25.0))
        )
        assert fleet.run_until(lambda: landed(fleet), 900), fleet.notes[-10:]
        done = {
            a.vehicle_id
            for a in fleet.messages(Alert)
            if a.code == AlertCode.MISSION_COMPLETE and a.text == f"mission {mid}"
        }
        assert done == {7, 8}, (mid, done)
        planned = [
            t
            for _t, _v, t in fleet.notes
            if t.startswith(f"mission {mid}: planned for fleet [7, 8]")
        ]
        assert len(planned) == 2, planned
        progress = [s.mission_progress_pct for s in fleet.messages(VehicleStatus, sender=7)]
        assert progress[-1] == 100
        fleet.broadcast(Command(GCS, 200 + mid, CommandKind.ACTIVATE))
        assert fleet.run_until(
            lambda: all(v.node.fsm.state == FsmState.GO_MISSION for v in fleet.vehicles.values()),
            30,
        )
    assert [a.reason for a in fleet.messages(Ack) if a.ref_id == 42]
