"""Property: every node of a fleet, given the same inputs in any order,
computes the same roster and the same plan (and the same replan after a loss). Each
node hears the answers in its own order, then plans with the members in its own order
(`mission.share.plan_fleet`, what the node's plan job runs)."""

from __future__ import annotations

import random

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from swarm_node.core.mission.share import Member, PlanRequest, plan_fleet, run_plan
from swarm_node.core.planning import PlanningError
from swarm_node.core.swarm.roster import Roster
from swarm_proto import (
    Geometry,
    GeometryKind,
    GeoPoint,
    LatLon,
    Mission,
    MissionParams,
    MissionType,
    Selector,
)
from tests.conftest import examples
from tests.swarm_node.test_roster import ack, info, peers_of

MID = 77
LA, LO = 37.4120, -5.9889
SEED_IDS = (1, 2, 3, 7, 8, 10)
GEOMETRY = {
    MissionType.AREA: Geometry.polygon(
        [
            (LA + 0.002, LO - 0.002),
            (LA + 0.002, LO + 0.002),
            (LA + 0.004, LO + 0.002),
            (LA + 0.004, LO - 0.002),
        ]
    ),
    MissionType.TARGET: Geometry.point(LA + 0.004, LO),
    MissionType.PERIMETER: Geometry.circle(LA + 0.004, LO, 150.0),
    MissionType.OBJECTIVE: Geometry(
        GeometryKind.POINTS, (LatLon(LA + 0.004, LO), LatLon(LA + 0.005, LO + 0.002))
    ),
    MissionType.AUTOLAND: Geometry.point(LA - 0.001, LO),
}


@st.composite
def fleets(draw: st.DrawFn) -> tuple[list[int], dict[int, bool], list[list[int]]]:
    ids = draw(st.lists(st.sampled_from(SEED_IDS), min_size=2, max_size=4, unique=True))
    accepts = {i: draw(st.booleans()) for i in ids}
    accepts[ids[0]] = accepts[ids[1]] = True
    orders = [draw(st.permutations([j for j in ids if j != i])) for i in ids]
    return ids, accepts, orders


@settings(max_examples=examples(12), deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(fleets(), st.sampled_from(sorted(GEOMETRY)), st.randoms(use_true_random=False))
def test_every_node_computes_the_same_roster_plan_and_replan(
    fleet_profiles: dict, data: tuple, kind: MissionType, rnd: random.Random
) -> None:
    ids, accepts, orders = data
    homes = {v: GeoPoint(LA, LO + 0.0006 * k, 0.0) for k, v in enumerate(sorted(ids))}
    params = MissionParams(altitude_rel_m=60.0, altitude_step_m=10.0, side_overlap=0.2, loops=1)
    mission = Mission(MID, 900, kind, GEOMETRY[kind], params, Selector())
    rosters, plans, replans = set(), set(), set()
    for me, order in zip(ids, orders, strict=True):
        if not accepts[me]:
            continue
        r = Roster(me)
        r.open(MID, Selector())
        for j in order:  # answers in this node's order, some as VehicleInfo
            if accepts[j] and rnd.random() < 0.5:
                r.on_info(info(j))
            r.on_ack(ack(j, accepts[j]))
        peers = peers_of([j for j in ids if j != me], {j: info(j) for j in ids if accepts[j]})
        assert r.ready(peers)
        members = list(r.freeze(peers))
        rosters.add((tuple(members), r.members_hash))
        rnd.shuffle(members)  # the node lists its members in its own order
        try:
            plan = plan_fleet(
                mission, [Member(fleet_profiles[v], homes[v]) for v in members], [], 0.0, 0.0
            )
        except ValueError as exc:  # the same inputs fail alike everywhere
            plans.add(("failed", str(exc)))
            continue
        plans.add(tuple(sorted((v, s.waypoints) for v, s in plan.shares.items())))
        # the first member is lost at 30 % of its share: every survivor replans alike
        lost = min(plan.roster)
        progress = {v: 0.3 * s.length_m for v, s in plan.shares.items()}
        survivors = [v for v in plan.roster if v != lost]
        rnd.shuffle(survivors)
        posed = []
        for v in survivors:
            try:
                _k, lat, lon = plan.shares[v].at(progress[v])
                posed.append(Member(fleet_profiles[v], GeoPoint(lat, lon, 0.0)))
            except PlanningError:  # nothing to fly (a rover given no lanes): at home
                posed.append(Member(fleet_profiles[v], homes[v]))
        progress_in_order = dict(rnd.sample(sorted(progress.items()), len(progress)))
        out = run_plan(
            PlanRequest(
                2, mission, tuple(posed), (), 0.0, 0.0, base=plan, progress_m=progress_in_order
            )
        )
        replans.add(
            (out.error,)
            if out.plan is None
            else tuple(sorted((v, s.waypoints) for v, s in out.plan.shares.items()))
        )
    assert len(rosters) == 1
    assert len(plans) == 1
    assert len(replans) <= 1
