"""Fleet missions over real processes: simulated quadcopters (their own process, MAVLink
on TCP), one `swarm-node` process each, Zenoh on 127.0.0.1, a ground station, all at
5x real time (the demo's harness). A `--fleet` mission is split between the fleet's
members; a second mission on the same nodes is flown; SIGKILLing a node's process
mid-mission hands its share on to the survivor (mission inheritance)."""

from __future__ import annotations

import os
import re
import signal
import time
from pathlib import Path

import pytest
from rich.console import Console

from gcs_cli.ground import FleetView, GroundStation
from swarm_proto import (
    AckReason,
    AlertCode,
    CommandArgs,
    CommandKind,
    FsmState,
    GeoPoint,
    Mission,
    MissionParams,
    MissionState,
    MissionType,
    Selector,
)
from swarm_proto.session import ZenohSettings
from swarm_sim.core import SITL_HOME
from swarm_sim.demo import GCS_ID, start, stop
from tests.swarm_sim.test_fast_fleet import square

pytestmark = [pytest.mark.network, pytest.mark.timeout(900)]
SPEEDUP = 5.0


def completed(view: FleetView, vid: int, mid: int) -> bool:
    return any(
        a.vehicle_id == vid and a.code == AlertCode.MISSION_COMPLETE and a.text == f"mission {mid}"
        for a in view.alerts
    )


def info_of(view: FleetView, vid: int, mid: int) -> bool:
    return vid in view.info and view.info[vid].mission_id == mid


@pytest.mark.soak  # split, again, inherit: test_mission_layer.py, test_faults_smoke.py (FastFleet)
@pytest.mark.timeout(240)
def test_fleet_missions_split_fly_again_and_inherit_quickly(tmp_path: Path, swarm_db: Path) -> None:
    """The default run's shorter check, two quadcopters on their node processes: a
    `--fleet` mission is split (both plan for [7, 8], the same roster hash, both fly);
    a second mission with no selector on the same nodes, sent while they fly, is
    planned for both and flown; SIGKILLing node 8 mid-mission makes 7 notice, replan
    for itself and take on 8's lanes. Nothing is flown to the end (the soak test
    does)."""
    members = (7, 8)
    fleet = start(members, SPEEDUP, tmp_path, Console(file=open(os.devnull, "w")))  # noqa: SIM115
    gs = GroundStation(ZenohSettings(connect=(fleet.endpoint,)), gcs_id=GCS_ID)
    try:
        assert gs.wait_for(
            lambda v: all(
                i in v.info
                and v.info[i].home is not None
                and i in v.status
                and v.status[i].gps_fix >= 3
                for i in members
            ),
            120,
        )
        base = GeoPoint(SITL_HOME.lat_deg, SITL_HOME.lon_deg, SITL_HOME.alt_m)
        gs.command(CommandKind.SET_BASE, Selector(), CommandArgs(point=base), timeout_s=10.0)
        assert gs.wait_for(
            lambda v: all(v.fsm_state(i) == FsmState.GO_MISSION for i in members), 60
        )
        acks = gs.command(
            CommandKind.SET_FLEET, Selector.ids(7, 8), CommandArgs(fleet_id=3), timeout_s=10.0
        )
        assert sorted(a.vehicle_id for a in acks if a.accepted) == [7, 8]
        time.sleep(1.0)
        area = square(SITL_HOME.lat_deg + 0.0012, SITL_HOME.lon_deg, 45.0)
        params = MissionParams(altitude_rel_m=20.0)
        acks = gs.mission(
            Mission(91, GCS_ID, MissionType.AREA, area, params, Selector.fleet(3)), timeout_s=10.0
        )
        assert sorted(a.vehicle_id for a in acks if a.accepted) == [7, 8]
        assert gs.wait_for(
            lambda v: all(
                v.status[i].mission_state == MissionState.MISSION and info_of(v, i, 91)
                for i in members
            ),
            90,
        )
        view = gs.snapshot()
        assert view.info[7].members_hash == view.info[8].members_hash != 0
        for vid in members:
            assert (
                "mission 91: planned for fleet [7, 8]" in (tmp_path / f"node-{vid}.log").read_text()
            )
        # a second mission, no selector, on the same nodes while they fly the first
        acks = gs.mission(Mission(92, GCS_ID, MissionType.AREA, area, params), timeout_s=10.0)
        assert sorted(a.vehicle_id for a in acks if a.accepted) == [7, 8]
        assert gs.wait_for(
            lambda v: all(
                info_of(v, i, 92)
                and v.status[i].mission_state == MissionState.MISSION
                and v.status[i].mission_progress_pct >= 10
                for i in members
            ),
            120,
        )
        for vid in members:
            assert (
                "mission 92: planned for fleet [7, 8]" in (tmp_path / f"node-{vid}.log").read_text()
            )
        path_before = gs.snapshot().info[7].mission_path_m
        fleet.nodes[8].send_signal(signal.SIGKILL)
        assert gs.wait_for(lambda v: v.info[7].mission_path_m > path_before + 1.0, 60)
        log = (tmp_path / "node-7.log").read_text()
        assert re.search(r"mission 92: member 8 lost", log), log[-2000:]
        assert "mission 92: replanning for [7]" in log
        assert gs.wait_for(lambda v: v.status[7].mission_state == MissionState.MISSION, 30)
    finally:
        gs.close()
        stop(fleet)


@pytest.mark.soak
def test_fleet_missions_split_fly_again_and_inherit(tmp_path: Path, swarm_db: Path) -> None:
    members = (7, 8, 9)
    fleet = start(members, SPEEDUP, tmp_path, Console(file=open(os.devnull, "w")))  # noqa: SIM115
    gs = GroundStation(ZenohSettings(connect=(fleet.endpoint,)), gcs_id=GCS_ID)
    try:
        assert gs.wait_for(
            lambda v: all(
                i in v.info
                and v.info[i].home is not None
                and i in v.status
                and v.status[i].gps_fix >= 3
                for i in members
            ),
            120,
        )
        base = GeoPoint(SITL_HOME.lat_deg, SITL_HOME.lon_deg, SITL_HOME.alt_m)
        gs.command(CommandKind.SET_BASE, Selector(), CommandArgs(point=base), timeout_s=10.0)
        assert gs.wait_for(
            lambda v: all(v.fsm_state(i) == FsmState.GO_MISSION for i in members), 60
        )
        acks = gs.command(
            CommandKind.SET_FLEET, Selector.ids(7, 8), CommandArgs(fleet_id=2), timeout_s=10.0
        )
        assert sorted(a.vehicle_id for a in acks if a.accepted) == [7, 8]
        time.sleep(1.0)
        area = square(SITL_HOME.lat_deg + 0.0012, SITL_HOME.lon_deg, 45.0)
        params = MissionParams(altitude_rel_m=25.0)
        # 1: a mission to fleet 2 is split between 7 and 8 (9 is not addressed)
        acks = gs.mission(
            Mission(81, GCS_ID, MissionType.AREA, area, params, Selector.fleet(2)), timeout_s=10.0
        )
        answers = {a.vehicle_id: a.reason for a in acks}
        assert answers[7] == answers[8] == AckReason.OK, answers
        # 9's NOT_ADDRESSED may come after the addressed vehicles' answers were in
        assert answers.get(9, AckReason.NOT_ADDRESSED) == AckReason.NOT_ADDRESSED
        assert gs.wait_for(lambda v: all(v.info[i].members_hash for i in (7, 8)), 60)
        view = gs.snapshot()
        assert view.info[7].members_hash == view.info[8].members_hash
        assert gs.wait_for(lambda v: completed(v, 7, 81) and completed(v, 8, 81), 240)
        for vid in (7, 8):
            log = (tmp_path / f"node-{vid}.log").read_text()
            assert "mission 81: planned for fleet [7, 8]" in log
        # 2: after landing, activated again, a second mission on the same nodes is flown
        assert gs.wait_for(lambda v: all(v.fsm_state(i) == FsmState.INACTIVE for i in (7, 8)), 240)
        gs.command(CommandKind.ACTIVATE, Selector.ids(7, 8), timeout_s=10.0)
        assert gs.wait_for(lambda v: all(v.fsm_state(i) == FsmState.GO_MISSION for i in (7, 8)), 60)
        # no fresh batteries: a smaller field, so that 7 has the charge to take on 8's rest
        small = square(SITL_HOME.lat_deg + 0.0012, SITL_HOME.lon_deg, 30.0)
        acks = gs.mission(
            Mission(82, GCS_ID, MissionType.AREA, small, params, Selector.fleet(2)), timeout_s=10.0
        )
        assert sorted(a.vehicle_id for a in acks if a.accepted) == [7, 8]
        # 3: node 8 is SIGKILLed mid-mission: 7 replans and flies 8's share too
        assert gs.wait_for(
            lambda v: all(
                v.status[i].mission_state == MissionState.MISSION
                and v.status[i].mission_progress_pct >= 25
                for i in (7, 8)
            ),
            240,
        )
        path_before = gs.snapshot().info[7].mission_path_m
        fleet.nodes[8].send_signal(signal.SIGKILL)
        seen_replan = gs.wait_for(lambda v: v.status[7].mission_state == MissionState.REPLAN, 60)
        assert gs.wait_for(lambda v: completed(v, 7, 82), 300)
        assert not completed(gs.snapshot(), 8, 82)
        log = (tmp_path / "node-7.log").read_text()
        assert re.search(r"mission 82: member 8 lost", log), log[-2000:]
        assert "mission 82: replanning for [7]" in log
        assert seen_replan or "REPLAN" in log
        assert gs.snapshot().info[7].mission_path_m > path_before  # it took on 8's lanes
    finally:
        gs.close()
        stop(fleet)
