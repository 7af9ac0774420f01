"""After a peer's telemetry that changed nothing, NodeCore.next_deadline asks
the membership alone and takes every other module's deadline as last computed. That is
only right if such an input moves no other deadline: checked here on whole missions
(take-off, avoidance, survey, peers lost and stale), the cached answer against the one
computed afresh at every call."""

from __future__ import annotations

import pytest

from swarm_node.core.node import NodeCore
from swarm_proto import (
    Command,
    CommandArgs,
    CommandKind,
    FsmState,
    GeoPoint,
    Mission,
    MissionParams,
    MissionType,
    Selector,
)
from swarm_sim.core import SITL_HOME
from swarm_sim.fast_fleet import FastFleet
from tests.swarm_sim.test_fast_fleet import GCS, square


def test_the_cached_deadline_is_the_deadline_computed_afresh(
    fleet_profiles: dict, monkeypatch: pytest.MonkeyPatch
) -> None:
    cached_calls = 0
    plain = NodeCore.next_deadline

    def checked(self: NodeCore) -> float:
        nonlocal cached_calls
        fresh = self._rest_fresh
        got = plain(self)
        self._rest_fresh = False  # the same question, every module asked
        again = plain(self)
        assert got == again, (self.self_id, self.now, got, again)
        cached_calls += fresh
        return got

    monkeypatch.setattr(NodeCore, "next_deadline", checked)
    members = [1, 2, 7]  # two Albatross VTOLs and a quadcopter from the seed
    fleet = FastFleet.build(members, fleet_profiles)
    fleet.run_until(lambda: all(v.link.state.ekf_has_position for v in fleet.vehicles.values()), 60)
    base = GeoPoint(SITL_HOME.lat_deg, SITL_HOME.lon_deg, SITL_HOME.alt_m)
    fleet.broadcast(Command(GCS, 1, CommandKind.SET_BASE, args=CommandArgs(point=base)))
    assert fleet.run_until(
        lambda: all(v.node.fsm.state == FsmState.GO_MISSION for v in fleet.vehicles.values()), 30
    )
    area = square(SITL_HOME.lat_deg + 0.003, SITL_HOME.lon_deg, 100.0)
    params = MissionParams(altitude_rel_m=60.0)
    fleet.broadcast(Mission(42, GCS, MissionType.AREA, area, params, Selector.ids(*members)))
    assert fleet.run_until(
        lambda: all(v.node.manager.phase.value == "flying" for v in fleet.vehicles.values()), 300
    ), fleet.notes[-20:]
    fleet.run_for(30.0)
    fleet.kill_node(2)  # its peers lose it; telemetry from the others goes on
    fleet.run_for(30.0)
    assert cached_calls > 1000  # the cache was used, and was right every time
