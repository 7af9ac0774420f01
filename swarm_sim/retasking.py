"""The paper's re-tasking experiment (section 3, Figures 33-35) in fast time, over real
MAVLink bytes: a fleet surveys an area; a payload reports a target; the swarm votes with
no leader which vehicles go (`count.<class>` of the database's re-tasking rules, the
reporting vehicle's payload model); the winners fly the target mission, the others
replan the area and finish it; everyone lands. Measured the same way by the tests and
the benchmark (`tests/swarm_sim/test_retasking.py`, `bench/voting.py`).

Coverage is measured from the flown tracks (swath: the camera footprint at the survey
altitude), as `scenarios.inheritance` does. Every vehicle's score is snapshotted at the
moment its node scores itself (its autopilot state then), so a test can check the
winners against the paper's formula computed on its own."""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

from shapely.geometry import LineString, Polygon
from shapely.ops import unary_union

from swarm_node.core.autopilot.state import AutopilotState
from swarm_node.core.mission.tasking import target_mission_id
from swarm_node.core.mission.voting import BallotOutcome
from swarm_node.core.planning import LocalFrame
from swarm_node.core.profile import VehicleProfile
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
    MissionState,
    MissionType,
    TargetReport,
    TargetSource,
)

from .core import SITL_HOME
from .fast_fleet import FastFleet
from .scenarios import GCS, Tracks, square

AREA_ID = 70


def coverage(tracks: Tracks, area: Geometry, profile: VehicleProfile, alt_m: float) -> float:
    """The fraction of `area` under the flown tracks' camera swath (`profile`'s camera
    at `alt_m`)."""
    camera = profile.camera
    assert camera is not None
    swath = 2.0 * alt_m * math.tan(math.radians(camera.hfov_deg) / 2.0)
    poly = Polygon([tracks.frame.to_local(p.lat_deg, p.lon_deg) for p in area.points])
    flown = unary_union(
        [
            LineString([(p[0], p[1]) for p in pts]).buffer(swath / 2.0)
            for pts in tracks.points.values()
            if len(pts) > 1
        ]
    )
    return float(flown.intersection(poly).area / poly.area)


@dataclass
class Retasking:
    mission_id: int  # the target mission the report asked for
    target: tuple[float, float]  # where the target was reported (lat, lon)
    outcome: dict[int, BallotOutcome]  # each vehicle's decision
    scored: dict[int, AutopilotState]  # each vehicle's autopilot when it scored itself
    winners: tuple[int, ...]
    stayers: tuple[int, ...]
    report_to_decided_s: float  # report -> the last vehicle decided (simulated)
    report_to_flying_s: float  # report -> both winners flying the target mission
    report_to_replanned_s: float  # report -> every stayer flying its new share
    coverage: float  # area under the flown tracks' swath (stayers and winners before)
    completed: dict[int, set[int]] = field(default_factory=dict)  # mission -> vehicles
    landed: frozenset[int] = frozenset()
    same_plan: bool = False  # the stayers replanned the same plan
    notes: list[tuple[float, int, str]] = field(default_factory=list)


def retasking(
    profiles: Mapping[int, VehicleProfile],
    members: Sequence[int] = (1, 2, 3, 4, 5, 6),
    *,
    source: int = 3,
    target_class: str = "person",
    at_progress: float = 0.3,
    half_m: float = 350.0,
    alt_m: float = 60.0,
    to_the_end: bool = True,
    on_step: Callable[[FastFleet], None] | None = None,
) -> Retasking:
    """Fly it. `to_the_end=False` stops once the winners fly the target and the stayers
    their replanned shares (no coverage, no landing): the short check."""
    fleet = FastFleet.build(list(members), profiles, spacing_m=60.0)
    fleet.run_until(lambda: all(v.link.state.ekf_has_position for v in fleet.vehicles.values()), 60)
    base = GeoPoint(SITL_HOME.lat_deg, SITL_HOME.lon_deg, SITL_HOME.alt_m)
    fleet.broadcast(Command(GCS, 1, CommandKind.SET_BASE, args=CommandArgs(point=base)))
    assert fleet.run_until(
        lambda: all(v.node.fsm.state == FsmState.GO_MISSION for v in fleet.vehicles.values()), 30
    )
    area = square(SITL_HOME.lat_deg + 0.006, SITL_HOME.lon_deg, half_m)
    fleet.broadcast(
        Mission(AREA_ID, GCS, MissionType.AREA, area, MissionParams(altitude_rel_m=alt_m))
    )
    frame = LocalFrame.at(list(area.points))
    tracks = Tracks(frame, alt_m)

    def step() -> None:
        tracks.sample(fleet)
        if on_step is not None:
            on_step(fleet)

    def surveyed() -> bool:
        step()
        done = [
            v.node.manager.share_progress_m() / v.node.manager.share.length_m
            for v in fleet.vehicles.values()
            if v.node.manager.share is not None
        ]
        return len(done) == len(members) and min(done) >= at_progress

    assert fleet.run_until(surveyed, 900), fleet.notes[-10:]
    # the target: on the area's east edge, as a camera looking down would see it
    lat, lon = frame.to_geodetic(half_m, 0.0)
    report = TargetReport(
        1,
        source,
        TargetSource.PAYLOAD,
        fleet.now,
        GeoPoint(lat, lon, SITL_HOME.alt_m),
        target_class,
        0.93,
    )
    mid = target_mission_id(source, 1)
    reported = fleet.now
    fleet.broadcast(report)
    scored: dict[int, AutopilotState] = {}

    def decided() -> bool:
        step()
        for vid, v in fleet.vehicles.items():
            if vid not in scored and mid in v.node.tasking.ballots:
                scored[vid] = v.node.autopilot  # what it scored itself with
        return all(mid in v.node.tasking.outcomes for v in fleet.vehicles.values())

    assert fleet.run_until(decided, 60), fleet.notes[-20:]
    decided_s = fleet.now - reported
    outcome = {vid: v.node.tasking.outcomes[mid] for vid, v in fleet.vehicles.items()}
    first = next(iter(outcome.values()))
    winners, stayers = first.winners, tuple(m for m in members if m not in first.winners)

    def flying(vid: int, mission_id: int) -> bool:  # PREMISSION: on its way to the meet
        n = fleet.vehicles[vid].node
        return n.fsm.mission_id == mission_id and n.manager.mission_state in (
            MissionState.PREMISSION,
            MissionState.MISSION,
        )

    flying_s = replanned_s = None
    while flying_s is None or replanned_s is None:
        fleet.step()
        step()
        if flying_s is None and all(flying(w, mid) for w in winners):
            flying_s = fleet.now - reported
        if replanned_s is None and all(
            fleet.vehicles[s].node.roster.generation >= 1 and flying(s, AREA_ID) for s in stayers
        ):
            replanned_s = fleet.now - reported
        assert fleet.now - reported < 300, fleet.notes[-20:]
    plans = set()
    for m in stayers:
        plan = fleet.vehicles[m].node.manager.fleet_plan
        assert plan is not None
        plans.add(tuple(sorted((v, s.waypoints) for v, s in plan.shares.items())))
    result = Retasking(
        mid,
        (lat, lon),
        outcome,
        scored,
        winners,
        stayers,
        decided_s,
        flying_s,
        replanned_s,
        0.0,
        same_plan=len(plans) == 1,
    )
    if not to_the_end:
        result.notes = list(fleet.notes)
        return result

    def landed() -> bool:
        step()
        return all(
            v.node.fsm.state == FsmState.INACTIVE and not v.link.state.armed
            for v in fleet.vehicles.values()
        )

    assert fleet.run_until(landed, 3600), fleet.notes[-20:]
    result.coverage = coverage(tracks, area, profiles[members[0]], alt_m)
    for a in fleet.messages(Alert):
        if a.code == AlertCode.MISSION_COMPLETE:
            m = int(a.text.split()[-1])
            result.completed.setdefault(m, set()).add(a.vehicle_id)
    result.landed = frozenset(
        vid
        for vid, v in fleet.vehicles.items()
        if not v.link.state.armed and (v.link.state.alt_rel_m or 0.0) < 2.0
    )
    result.notes = list(fleet.notes)
    return result
