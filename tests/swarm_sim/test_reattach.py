"""a node restarted while its vehicle flies (kill -9, then a new process on the
same database), in fast time: it reattaches without sending the vehicle home and
without arming anything; alone on its mission it continues its share and completes it,
in a fleet whose survivors already took its share over it
hands it on and flies home."""

from __future__ import annotations

import pytest

from swarm_node.core.autopilot.requests import DownloadMission
from swarm_node.core.reattach import Decision
from swarm_proto import (
    Alert,
    AlertCode,
    Command,
    CommandArgs,
    CommandKind,
    FsmState,
    GeoPoint,
    Mission,
    MissionParams,
    MissionType,
)
from swarm_sim.core import SITL_HOME
from swarm_sim.fast_fleet import FastFleet
from swarm_sim.scenarios import GCS, square

BASE = GeoPoint(SITL_HOME.lat_deg, SITL_HOME.lon_deg, SITL_HOME.alt_m)


def on_mission(profiles: dict, members: list[int], half_m: float) -> FastFleet:
    fleet = FastFleet.build(members, profiles, spacing_m=60.0)
    assert fleet.run_until(
        lambda: all(v.link.state.ekf_has_position for v in fleet.vehicles.values()), 60
    )
    fleet.broadcast(
        Command(GCS, 1, CommandKind.SET_BASE, args=CommandArgs(point=BASE), time_unix_s=fleet.now)
    )
    assert fleet.run_until(
        lambda: all(v.node.fsm.state == FsmState.GO_MISSION for v in fleet.vehicles.values()), 30
    )
    area = square(SITL_HOME.lat_deg + 0.004, SITL_HOME.lon_deg, half_m)
    fleet.broadcast(
        Mission(
            70,
            GCS,
            MissionType.AREA,
            area,
            MissionParams(altitude_rel_m=60.0),
            time_unix_s=fleet.now,
        )
    )
    return fleet


def restarted_at(fleet: FastFleet, vid: int, fraction: float, down_s: float) -> float:
    v = fleet.vehicles[vid]

    def far_enough() -> bool:
        m = v.node.manager
        return m.share is not None and m.share_progress_m() >= fraction * m.share.length_m

    assert fleet.run_until(far_enough, 900)
    fleet.kill_node(vid)
    fleet.run_for(down_s)
    t = fleet.now
    fleet.restart_node(vid)
    return t


def after(fleet: FastFleet, vid: int, t: float) -> list[str]:
    """The kinds of request the node sent its autopilot since `t`."""
    return [type(r).__name__ for at, v, r in fleet.submitted if v == vid and at >= t]


def test_alone_on_its_mission_it_continues_its_share(fleet_profiles: dict) -> None:
    fleet = on_mission(fleet_profiles, [1], 150.0)
    v = fleet.vehicles[1]
    t = restarted_at(fleet, 1, 0.4, down_s=3.0)
    assert v.endpoint.autopilot.mode_name == "AUTO" and v.endpoint.autopilot.armed
    modes: set[str] = set()

    def completed() -> bool:
        modes.add(v.endpoint.autopilot.mode_name)
        return any(a.code == AlertCode.MISSION_COMPLETE for a in fleet.messages(Alert, sender=1))

    assert fleet.run_until(completed, 900)
    assert v.node.reattach.decision == Decision.CONTINUE
    assert modes == {"AUTO"}  # flown on as it was, never sent anywhere
    # reattaching only read the autopilot (the mission, then the backstop's checks)
    assert set(after(fleet, 1, t)) <= {DownloadMission.__name__, "UploadFence", "SetParam"}
    assert v.node.manager.sortie.progress_m >= 0.99 * v.node.manager.sortie.path_m
    # then home as usual, and down
    assert fleet.run_until(lambda: not v.endpoint.autopilot.armed, 900)
    assert "Arm" not in after(fleet, 1, t) and "Takeoff" not in after(fleet, 1, t)


@pytest.mark.soak  # the fault campaign's smoke rows fly the same (test_faults_smoke.py)
def test_in_a_fleet_that_took_its_share_it_hands_it_on(fleet_profiles: dict) -> None:
    fleet = on_mission(fleet_profiles, [1, 3], 150.0)
    v = fleet.vehicles[3]
    t = restarted_at(fleet, 3, 0.4, down_s=3.0)
    assert fleet.run_until(lambda: v.node.reattach.decision is not None, 30)
    assert v.node.reattach.decision == Decision.HAND_ON, v.node.reattach.why
    assert fleet.run_until(lambda: not v.endpoint.autopilot.armed, 900)  # home and down
    sent = after(fleet, 3, t)
    assert "Arm" not in sent and "Takeoff" not in sent
    assert fleet.run_until(
        lambda: any(a.code == AlertCode.MISSION_COMPLETE for a in fleet.messages(Alert, sender=1)),
        900,
    )


def test_a_replan_in_the_air_keeps_the_share_on_record_until_it_is_flown(
    fleet_profiles: dict,
) -> None:
    """While a replan's share is not flown yet (its upload held by an avoidance
    manoeuvre: the manager STARTING it in the air), the autopilot still holds the share
    on record, and so does the database: a node killed then finds it and hands on (a
    restart that found no share on record left its copter hovering until its battery
    ran out: the campaign's reboot in flight over real processes)."""
    from swarm_node.core.mission.phases import Phase

    fleet = on_mission(fleet_profiles, [1, 3], 150.0)
    v = fleet.vehicles[3]

    def far_enough() -> bool:
        m = v.node.manager
        return m.share is not None and m.share_progress_m() >= 0.3 * m.share.length_m

    assert fleet.run_until(far_enough, 900)
    flown = v.node.mission.record
    assert flown is not None and flown.mission_id == 70
    m = v.node.manager
    m.phase, m.items = Phase.STARTING, flown.items + 4  # the replan's share, uploading
    v.node.mission.keep_record(fleet.now)
    assert v.node.mission.record == flown
    m.phase = Phase.FLYING  # flown: recorded
    v.node.mission.keep_record(fleet.now)
    assert v.node.mission.record is not None and v.node.mission.record.items == flown.items + 4
