"""AUTOLAND and MUM-T missions flown by the mission manager (issue 12, deliver 7), in
fast time over real MAVLink bytes: a fleet lands at one base in turns, each on its own
pad; followers hold their slots in a vee around a lead node that flies its own
mission."""

from __future__ import annotations

import itertools
import math

from swarm_node.core.planning import AutolandPlan, LocalFrame, heading_to_yaw
from swarm_proto import (
    Ack,
    AckReason,
    Alert,
    AlertCode,
    FsmState,
    Geometry,
    GeometryKind,
    LatLon,
    Mission,
    MissionParams,
    MissionType,
    Selector,
    VehicleStatus,
)
from swarm_sim.core import SITL_HOME
from swarm_sim.fast_fleet import FastFleet
from tests.swarm_sim.test_mission_layer import GCS, ready_fleet


def completed(fleet: FastFleet, mid: int) -> set[int]:
    return {
        a.vehicle_id
        for a in fleet.messages(Alert)
        if a.code == AlertCode.MISSION_COMPLETE and a.text == f"mission {mid}"
    }


def test_a_fleet_lands_at_one_base_in_turns_each_on_its_own_pad(fleet_profiles: dict) -> None:
    """Three VTOLs orbiting a target get an AUTOLAND mission: each flies to the holding
    fix at its own stack level and holds; the first lands at once, each of the others
    leaves its hold when the one before has landed (its final approach is longer than
    the 40 s asked: one vehicle on the final at a time), in the plan's order; each
    lands on its own pad, 15 m from the next; the landing completes the mission."""
    members = [1, 2, 3]
    fleet = ready_fleet(members, fleet_profiles)
    target = Geometry.point(SITL_HOME.lat_deg + 0.008, SITL_HOME.lon_deg + 0.004)
    fleet.broadcast(Mission(20, GCS, MissionType.TARGET, target,
                            MissionParams(altitude_rel_m=70.0, altitude_step_m=10.0)))  # fmt: skip
    assert fleet.run_until(
        lambda: all(v.node.manager.phase.value == "flying" for v in fleet.vehicles.values()), 200
    )
    fleet.run_for(20.0)  # in the air, away from the base
    pad = Geometry.point(SITL_HOME.lat_deg - 0.001, SITL_HOME.lon_deg)
    params = MissionParams(altitude_rel_m=60.0, separation_s=40.0)
    fleet.broadcast(Mission(21, GCS, MissionType.AUTOLAND, pad, params))
    t0 = fleet.now
    landed: dict[int, tuple[float, tuple[float, float]]] = {}
    frame = LocalFrame(pad.points[0].lat_deg, pad.points[0].lon_deg)

    def all_landed() -> bool:
        for vid, v in fleet.vehicles.items():
            s = v.link.state
            if vid not in landed and not s.armed and (s.alt_rel_m or 0.0) < 1.0 and s.lat_deg:
                landed[vid] = (fleet.now - t0, frame.to_local(s.lat_deg, s.lon_deg))
        return len(landed) == len(members) and completed(fleet, 21) == set(members)

    assert fleet.run_until(all_landed, 1200), (landed, fleet.notes[-10:])
    order = sorted(landed, key=lambda v: landed[v][0])
    turns = [vid for _t, vid, text in fleet.notes if text == "mission 21: our turn to land"]
    assert turns == order, (turns, landed)
    times = [landed[v][0] for v in order]
    gaps = [b - a for a, b in itertools.pairwise(times)]
    print(f"touchdowns {[round(t) for t in times]} s, {[round(g) for g in gaps]} s apart")
    assert all(g >= 40.0 for g in gaps), gaps
    spots = [landed[v][1] for v in order]
    for a, b in itertools.pairwise(spots):
        assert 12.0 <= math.dist(a, b) <= 18.0, spots  # its own pad, 15 m from the next
    assert all(math.dist(p, (0.0, 0.0)) <= 20.0 for p in spots), spots
    assert all(v.node.fsm.state == FsmState.INACTIVE for v in fleet.vehicles.values())


def test_autoland_plans_are_the_same_on_every_node(fleet_profiles: dict) -> None:
    """The landing order every node flies by comes from inputs they all have."""
    fleet = ready_fleet([1, 2, 3], fleet_profiles)
    pad = Geometry.point(SITL_HOME.lat_deg - 0.001, SITL_HOME.lon_deg)
    fleet.broadcast(Mission(22, GCS, MissionType.AUTOLAND, pad, MissionParams(altitude_rel_m=60.0)))
    assert fleet.run_until(
        lambda: all(v.node.manager.fleet_plan is not None for v in fleet.vehicles.values()), 30
    )
    plans = [v.node.manager.fleet_plan for v in fleet.vehicles.values()]
    assert all(isinstance(p.detail, AutolandPlan) for p in plans if p is not None)
    assert len({p.detail.slots for p in plans if p is not None}) == 1  # type: ignore[attr-defined]


def test_followers_hold_their_slots_around_a_lead_flying_its_own_mission(
    fleet_profiles: dict,
) -> None:
    """VTOL 4 flies a long route; a MUM-T mission sent to everyone makes 1 and 2 its
    followers (4, the lead, answers NOT_ADDRESSED and flies on): they take off, close
    on their slots of the vee behind the lead (what the planner assigned from their
    homes, the same on every node) and hold them within 10 m once converged; after the
    mission's duration they go home."""
    fleet = ready_fleet([1, 2, 4], fleet_profiles)
    la, lo = SITL_HOME.lat_deg, SITL_HOME.lon_deg
    line = Geometry(GeometryKind.POLYLINE, (LatLon(la + 0.003, lo), LatLon(la + 0.04, lo + 0.01)))
    fleet.broadcast(Mission(30, GCS, MissionType.ROUTE, line, MissionParams(altitude_rel_m=60.0),
                            Selector.ids(4)))  # fmt: skip
    fleet.run_for(1.0)
    params = MissionParams(altitude_rel_m=60.0, lead_vehicle_id=4, duration_s=150.0)
    fleet.broadcast(Mission(31, GCS, MissionType.MUMT, Geometry.point(la, lo), params))
    t0 = fleet.now
    fleet.run_for(2.0)
    answers = {a.vehicle_id: a.reason for a in fleet.messages(Ack) if a.ref_id == 31}
    assert answers == {1: AckReason.OK, 2: AckReason.OK, 4: AckReason.NOT_ADDRESSED}
    slots = {vid: fleet.vehicles[vid].node.manager.follow.slot for vid in (1, 2)}  # type: ignore[union-attr]
    assert sorted(slots.values()) == [0, 1]
    frame = LocalFrame(la, lo)
    errors: dict[int, list[float]] = {1: [], 2: []}

    def converged() -> bool:
        lead = fleet.vehicles[4].link.state
        if fleet.now - t0 < 120.0 or lead.lat_deg is None:
            return False
        lx, ly = frame.to_local(lead.lat_deg, lead.lon_deg)
        yaw = heading_to_yaw(math.degrees(math.atan2(lead.vel_east_m_s, lead.vel_north_m_s)))
        for vid in (1, 2):
            follow = fleet.vehicles[vid].node.manager.follow
            s = fleet.vehicles[vid].link.state
            assert follow is not None and s.lat_deg is not None
            o = follow.offsets[follow.slot]
            c, sn = math.cos(yaw), math.sin(yaw)
            slot = (lx + o.ahead_m * c + o.right_m * sn, ly + o.ahead_m * sn - o.right_m * c)
            errors[vid].append(math.dist(frame.to_local(s.lat_deg, s.lon_deg), slot))
        return fleet.now - t0 > 150.0

    assert fleet.run_until(converged, 300)
    for vid, e in errors.items():
        print(f"follower {vid}: {max(e):.1f} m from its slot at most (t > 120 s)")
        assert max(e) < 10.0, (vid, e)
    statuses = [s for s in fleet.messages(VehicleStatus, sender=4) if s.vehicle_id == 4]
    assert all(s.fsm_state == FsmState.GO_MISSION for s in statuses[-20:])  # still on its route
    assert fleet.run_until(lambda: completed(fleet, 31) == {1, 2}, 60)
