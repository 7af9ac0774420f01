"""Mission inheritance in the fleet harness (node cores, scripted autopilots): a member
lost in flight; the survivors enter REPLAN, agree on the same new plan from the same
published progress, without a leader, and upload their new shares."""

from __future__ import annotations

from swarm_node.core.autopilot.requests import UploadMission
from swarm_proto import FsmState, MissionState, VehicleStatus
from tests.swarm_node.test_mission_defects import area, keep_polling, uploads
from tests.swarm_node.test_node_core import activate, fleet


def test_survivors_replan_the_lost_members_share_and_agree() -> None:
    f = fleet(3)
    activate(f)
    f.submitted.clear()
    keep_polling(f, 0.2)
    from tests.swarm_node.test_node_core import send

    send(f, area(41))
    keep_polling(f, 4.0)
    assert all(len(uploads(f, i)) == 1 for i in (1, 2, 3))
    keep_polling(f, 3.0, mission_reached=4, mission_current=5)  # every vehicle under way
    progress = {i: f.nodes[i].manager.share_progress_m() for i in (1, 2, 3)}
    assert all(p > 0 for p in progress.values()), progress
    keep_polling(f, 1.0, mission_reached=4, mission_current=5)  # its VehicleInfo is out
    lost_at = f.nodes[3].manager.share_progress_m()
    f.nodes.pop(3)  # vehicle 3 dies
    keep_polling(f, 6.0, mission_reached=4, mission_current=5)
    for i in (1, 2):
        n = f.nodes[i]
        assert n.roster.lost == {3: "stale"}
        assert n.roster.generation == 1 and n.roster.planned == (1, 2)
        assert n.fsm.state == FsmState.GO_MISSION and n.fsm.mission_id == 41
        assert len(uploads(f, i)) == 2  # the new share
        states = [s.mission_state for s in f.messages(VehicleStatus, sender=i)]
        assert MissionState.REPLAN in states
    # every survivor replanned from the same progress: 3's as it last published it
    used = [f.nodes[i].manager.replanned_from for i in (1, 2)]
    assert used[0] == used[1] and abs(used[0][3] - lost_at) < 1.0, (used, lost_at)
    p1, p2 = (f.nodes[i].manager.fleet_plan for i in (1, 2))
    assert p1 is not None and p2 is not None
    assert p1.roster == p2.roster == (1, 2)
    assert {v: s.waypoints for v, s in p1.shares.items()} == {
        v: s.waypoints for v, s in p2.shares.items()
    }
    assert f.nodes[1].roster.members_hash == f.nodes[2].roster.members_hash
    # the new shares are longer than what the survivors had left: they took 3's lanes
    for i in (1, 2):
        up = uploads(f, i)[-1]
        assert isinstance(up, UploadMission) and up.items


def test_a_replan_gives_the_survivors_the_battery_the_model_says_they_have_left(
    fleet_profiles: dict,
) -> None:
    """Every survivor estimates every survivor's battery alike from the published
    progress (the model: climb, then the share's planned time to its progress and what
    it flew before at its speed); it falls with the metres flown and is what
    `Endurance.left_pct` says."""
    from swarm_node.core.mission.share import Member, plan_fleet
    from swarm_node.core.mission_manager import replan_battery
    from swarm_node.core.planning.endurance import Endurance
    from swarm_proto import GeoPoint, Mission, MissionParams, MissionType
    from tests.swarm_node.test_mission_defects import square

    members = [
        Member(fleet_profiles[v], GeoPoint(37.4120, -5.9889 + 0.0005 * i, 0.0))
        for i, v in enumerate((7, 8))
    ]
    mission = Mission(9, 900, MissionType.AREA, square(60.0), MissionParams(altitude_rel_m=40.0))
    base = plan_fleet(mission, members, [], 0.0, 0.0)
    s7 = base.share(7)
    early = replan_battery(base, members, {7: 0.1 * s7.length_m}, {}, 40.0)
    late = replan_battery(base, members, {7: 0.9 * s7.length_m}, {}, 40.0)
    later = replan_battery(base, members, {7: 0.9 * s7.length_m}, {7: 500.0}, 40.0)
    assert 0.0 < later[7] < late[7] < early[7] < 100.0
    expect = Endurance.of(fleet_profiles[7], 40.0).left_pct(
        s7.planned_s_at(0.9 * s7.length_m), fleet_profiles[7].battery_capacity_mah
    )
    assert late[7] == expect
    assert early[8] == late[8]  # 8 flew nothing in both


def test_a_survivor_inherits_what_its_battery_flies_and_the_rest_is_reported(
    fleet_profiles: dict,
) -> None:
    """Two quadcopters on a field one alone cannot finish: when 8 is lost early, 7 is
    given as much of 8's rest as its battery flies home (not nothing, not all), and the
    plan says how much is left unflown; with a battery to spare it inherits all."""
    from swarm_node.core.mission.share import Member, plan_fleet
    from swarm_node.core.planning import InfeasibleTimingError, PlanVehicle, VehiclePose
    from swarm_proto import GeoPoint, Mission, MissionParams, MissionType
    from tests.swarm_node.test_mission_defects import square

    members = [
        Member(fleet_profiles[v], GeoPoint(37.4120, -5.9889 + 0.0005 * i, 0.0))
        for i, v in enumerate((7, 8))
    ]
    mission = Mission(9, 900, MissionType.AREA, square(35.0), MissionParams(altitude_rel_m=20.0))
    base = plan_fleet(mission, members, [], 0.0, 0.0)
    progress = {7: 0.1 * base.share(7).length_m, 8: 0.1 * base.share(8).length_m}
    _k, lat, lon = base.share(7).at(progress[7])
    posed = [PlanVehicle(base.vehicles[0].profile, VehiclePose(lat, lon, 20.0))]
    kw = {"zones": [], "now_unix_s": 0.0, "home_alt_msl_m": 0.0}
    full = base.replan(progress, posed, battery_pct={7: 90.0}, **kw)  # type: ignore[arg-type]
    assert full.unflown_fraction == 0.0
    part = base.replan(progress, posed, battery_pct={7: 70.0}, **kw)  # type: ignore[arg-type]
    assert 0.0 < part.unflown_fraction < 1.0
    assert part.share(7).length_m < full.share(7).length_m
    try:
        none = base.replan(progress, posed, battery_pct={7: 40.0}, **kw)  # type: ignore[arg-type]
    except InfeasibleTimingError:
        pass  # not even its own rest: no replan (it flies on with its share)
    else:
        assert none.unflown_fraction == 1.0


def test_a_vehicle_that_flew_before_is_planned_with_the_battery_it_has(
    fleet_profiles: dict,
) -> None:
    """A second mission on the same vehicles without fresh batteries: the split gives
    the one at 55 % less than its full-battery twin and no more than its charge flies
    home, and replans count down from it (before, every plan assumed a full battery:
    a quadcopter that inherited lanes on its second mission reached BATTERY_CRITICAL)."""
    from swarm_node.core.mission.share import Member, plan_fleet
    from swarm_node.core.mission_manager import replan_battery
    from swarm_proto import GeoPoint, Mission, MissionParams, MissionType
    from tests.swarm_node.test_mission_defects import square

    homes = [GeoPoint(37.4120, -5.9889 + 0.0005 * i, 0.0) for i in range(2)]
    mission = Mission(9, 900, MissionType.AREA, square(40.0), MissionParams(altitude_rel_m=25.0))
    full = plan_fleet(
        mission,
        [Member(fleet_profiles[v], h) for v, h in zip((7, 8), homes, strict=True)],
        [],
        0.0,
        0.0,
    )
    used = [Member(fleet_profiles[7], homes[0], 55.0), Member(fleet_profiles[8], homes[1], 100.0)]
    part = plan_fleet(mission, used, [], 0.0, 0.0)
    assert part.launch_battery_pct == {7: 55.0, 8: 100.0}
    assert part.share(7).length_m < full.share(7).length_m
    assert part.share(8).length_m > full.share(8).length_m
    left = replan_battery(part, used, {7: 0.0, 8: 0.0}, {}, 25.0)
    assert left[7] < 55.0 < left[8]


def test_the_roster_keeps_the_battery_each_member_published_entering_plan() -> None:
    from swarm_node.core.swarm.roster import Roster
    from swarm_proto import FsmState, Selector, VehicleInfo, VehicleType

    r = Roster(1)
    r.open(5, Selector())

    def info(pct: int, state: FsmState) -> VehicleInfo:
        return VehicleInfo(
            2, VehicleType.COPTER, "q", "U2", mission_id=5, fsm_state=state, battery_pct=pct
        )

    r.on_info(info(80, FsmState.PLAN))
    r.on_info(info(79, FsmState.PLAN))  # a later one: the first is what everyone planned with
    r.on_info(info(60, FsmState.GO_MISSION))
    assert r.plan_battery == {2: 80}
