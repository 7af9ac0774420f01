"""Regression tests for the mission-layer defects (each failed on the code
before the fix): fleet missions shared, a second mission flown, mission_state in PLAN,
progress kept on the way home, a cancelled mission not reported as failed."""

from __future__ import annotations

import itertools
import math

from swarm_node.core.autopilot.requests import StartMission, UploadMission
from swarm_node.testing import Fleet
from swarm_proto import (
    Alert,
    AlertCode,
    CommandKind,
    FsmState,
    Geometry,
    Mission,
    MissionParams,
    MissionState,
    MissionType,
    Selector,
    VehicleStatus,
)
from tests.swarm_node.test_node_core import GCS, activate, command, fleet, flying, send


def square(half_m: float = 80.0, lat: float = 37.4130, lon: float = -5.9889) -> Geometry:
    dlat = half_m / 111_320.0
    dlon = half_m / (111_320.0 * math.cos(math.radians(lat)))
    return Geometry.polygon(
        [
            (lat - dlat, lon - dlon),
            (lat - dlat, lon + dlon),
            (lat + dlat, lon + dlon),
            (lat + dlat, lon - dlon),
        ]
    )


def area(mid: int, selection: Selector | None = None, half_m: float = 80.0) -> Mission:
    return Mission(
        mid,
        GCS,
        MissionType.AREA,
        square(half_m),
        MissionParams(altitude_rel_m=50.0),
        selection=selection or Selector(),
    )


def uploads(f: Fleet, vid: int) -> list[UploadMission]:
    return [r for _, n, r in f.submitted if n == vid and isinstance(r, UploadMission)]


def lanes(up: UploadMission) -> set[frozenset[tuple[float, float]]]:
    """The share's legs (pairs of consecutive waypoints; the leg from the start, where
    every vehicle is, left out). A lane cut by the split ends one share's leg and starts
    another's: a shared point, not a shared leg."""
    pts = [(round(w.lat_deg, 6), round(w.lon_deg, 6)) for w in up.items if w.lat_deg]
    return {frozenset(p) for p in itertools.pairwise(pts[1:]) if p[0] != p[1]}


def keep_polling(f: Fleet, seconds: float, **kw: object) -> None:
    """Advance time feeding every node its autopilot state at 5 Hz, as the runtime does."""
    end = f.now + seconds
    while f.now < end:
        for i in f.nodes:
            f.set_autopilot(i, flying(**kw))
        f.run_until(min(end, f.now + 0.2))


def test_a_mission_to_all_is_shared_by_the_fleet() -> None:
    """Defect 1: every node planned the whole area for itself (fleet_members = (self,))."""
    f = fleet(3)
    activate(f)
    send(f, area(21))  # no selector: ALL
    keep_polling(f, 5.0)
    ups = {i: uploads(f, i) for i in (1, 2, 3)}
    assert all(len(u) == 1 for u in ups.values()), ups
    shares = {i: lanes(u[0]) for i, u in ups.items()}
    # three different shares, no waypoint flown by two vehicles
    assert shares[1] and shares[2] and shares[3]
    assert (
        not (shares[1] & shares[2]) and not (shares[2] & shares[3]) and not (shares[1] & shares[3])
    )
    for i in (1, 2, 3):
        assert f.nodes[i].roster.members == (1, 2, 3)


def test_a_mission_to_a_fleet_is_shared_by_its_members_only() -> None:
    f = fleet(3)
    activate(f)
    send(f, command(30, CommandKind.SET_FLEET, Selector.ids(1, 2), fleet_id=2))
    f.run_until(f.now + 1.0)
    send(f, area(22, Selector.fleet(2)))
    keep_polling(f, 5.0)
    assert not uploads(f, 3)
    s1, s2 = lanes(uploads(f, 1)[0]), lanes(uploads(f, 2)[0])
    assert s1 and s2 and not (s1 & s2)
    assert f.nodes[1].roster.members == f.nodes[2].roster.members == (1, 2)
    assert f.nodes[1].roster.members_hash == f.nodes[2].roster.members_hash != 0


def test_a_second_mission_is_flown_not_completed_at_once() -> None:
    """Defect 2: the last MISSION_ITEM_REACHED of the first mission (here 60) completed
    the second one as soon as it started."""
    f = fleet(1)
    activate(f)
    send(f, area(23, half_m=40.0))
    keep_polling(f, 3.0, mission_reached=60, mission_current=61)
    assert any(isinstance(r, StartMission) for _, _, r in f.submitted)
    done = [a for a in f.messages(Alert) if a.code == AlertCode.MISSION_COMPLETE]
    assert not done
    assert f.nodes[1].fsm.state == FsmState.GO_MISSION and f.nodes[1].fsm.mission_id == 23


def test_mission_state_is_planning_while_the_fleet_syncs() -> None:
    """Defect 3: mission_state showed IDLE in STATE_PLAN (overwritten at each autopilot
    update)."""
    f = fleet(2)
    activate(f)
    send(f, area(24, Selector.ids(1, 2)), to=[1])  # 2 never hears it: 1 waits in PLAN
    keep_polling(f, 3.0)
    assert f.nodes[1].fsm.state == FsmState.PLAN
    last = [s for s in f.messages(VehicleStatus, sender=1)][-1]
    assert last.mission_state == MissionState.PLANNING


def test_a_cancelled_mission_is_not_reported_as_failed() -> None:
    """Defect 5: CANCEL_MISSION raised MISSION_FAILED."""
    f = fleet(1)
    activate(f)
    send(f, area(25, half_m=40.0))
    keep_polling(f, 3.0)
    assert f.nodes[1].fsm.mission_id == 25
    send(f, command(31, CommandKind.CANCEL_MISSION, mission_id=25))
    keep_polling(f, 2.0)
    codes = [a.code for a in f.messages(Alert, sender=1)]
    assert AlertCode.MISSION_FAILED not in codes
    assert AlertCode.MISSION_CANCELLED in codes
