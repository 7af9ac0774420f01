"""The AUTOLAND turns and the MUM-T follower as cores (mission/landing.py,
mission/follow.py)."""

from __future__ import annotations

import pytest

from swarm_node.core.autopilot.requests import ChangeSpeed, Goto
from swarm_node.core.autopilot.state import AutopilotState
from swarm_node.core.mission.follow import LEAD_TIMEOUT_S, UPDATE_S, Follow
from swarm_node.core.mission.landing import LandingTurn
from swarm_node.core.mission.share import Member, plan_fleet
from swarm_node.core.swarm.roster import Roster
from swarm_proto import Geometry, GeoPoint, Mission, MissionParams, MissionType, VehicleStatus

LA, LO = 37.4120, -5.9889


def members(profiles: dict, ids: tuple[int, ...]) -> list[Member]:
    return [Member(profiles[v], GeoPoint(LA, LO + 0.0007 * i, 0.0)) for i, v in enumerate(ids)]


def test_each_lands_in_its_turn_once_the_one_before_has_landed(fleet_profiles: dict) -> None:
    mission = Mission(
        5,
        900,
        MissionType.AUTOLAND,
        Geometry.point(LA - 0.002, LO),
        MissionParams(altitude_rel_m=60.0, separation_s=300.0),
    )
    plan = plan_fleet(mission, members(fleet_profiles, (7, 8)), [], 0.0, 0.0)
    order = [s.vehicle_id for s in sorted(plan.detail.slots, key=lambda s: s.sequence)]  # type: ignore[attr-defined]
    first, second = (LandingTurn.of(plan, v, plan.share(v).waypoints) for v in order)
    assert first is not None and second is not None
    assert first.before is None and second.before == order[0]
    assert 0.0 < second.wait_s < 300.0  # the separation less its own final approach
    roster = Roster(order[1])
    assert not first.release(first.hold_seq - 1, roster, 10.0)  # not in its hold yet
    assert first.release(first.hold_seq, roster, 11.0)  # the first goes at once
    assert not first.release(first.hold_seq, roster, 12.0)  # once
    assert not second.release(second.hold_seq, roster, 20.0)  # the first has not landed
    roster.finished.add(order[0])
    assert not second.release(second.hold_seq, roster, 100.0)  # it has: the wait begins
    assert not second.release(second.hold_seq, roster, 100.0 + second.wait_s - 0.1)
    assert second.release(second.hold_seq, roster, 100.0 + second.wait_s)
    lost = LandingTurn.of(plan, order[1], plan.share(order[1]).waypoints)
    assert lost is not None
    roster.finished.clear()
    roster.lost[order[0]] = "stale"  # the one before is lost: it holds nobody up
    lost.release(lost.hold_seq, roster, 200.0)
    assert lost.release(lost.hold_seq, roster, 200.0 + lost.wait_s)


def test_a_follower_goes_to_its_slot_and_stops_without_its_lead(fleet_profiles: dict) -> None:
    params = MissionParams(altitude_rel_m=40.0, lead_vehicle_id=9, duration_s=60.0)
    mission = Mission(6, 900, MissionType.MUMT, Geometry.point(LA, LO), params)
    plan = plan_fleet(mission, members(fleet_profiles, (7, 8)), [], 0.0, 0.0)
    f7, f8 = Follow.of(plan, fleet_profiles[7]), Follow.of(plan, fleet_profiles[8])
    assert f7 is not None and f8 is not None and {f7.slot, f8.slot} == {0, 1}
    ap = AutopilotState(lat_deg=LA, lon_deg=LO, alt_rel_m=40.0, armed=True)
    f7.begin(0.0)
    assert f7.step(ap, 0.0, [], 0.0) == []  # no lead heard yet
    lead = VehicleStatus(9, 0.5, LA + 0.001, LO, 600.0, 30.0, vel_north_m_s=8.0)
    f7.on_status(lead, 0.5)
    f7.on_status(VehicleStatus(3, 0.5, LA, LO, 600.0, 30.0), 0.5)  # not the lead
    reqs = f7.step(ap, 1.0, [], 0.0)
    assert [type(r) for r in reqs] == [Goto, ChangeSpeed]
    goto, speed = reqs
    assert isinstance(goto, Goto) and isinstance(speed, ChangeSpeed)
    assert goto.alt_rel_m == pytest.approx(30.0 + f7.offsets[f7.slot].up_m)
    assert goto.lat_deg < LA + 0.001  # behind the lead (a vee behind it)
    assert f7.step(ap, 1.0 + UPDATE_S / 2, [], 0.0) == []  # not before UPDATE_S
    assert f7.over(1.0) is None
    assert f7.over(0.5 + LEAD_TIMEOUT_S) is not None  # the lead is no longer heard
    f7.on_status(lead, 50.0)
    assert f7.over(59.0) is None
    assert "60" in (f7.over(60.0) or "")  # its duration
