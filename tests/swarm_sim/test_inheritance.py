"""Mission inheritance (paper Fig. 14 and 17) in fast time, over real MAVLink bytes: six
VTOLs fly an area mission sent to ALL; one is killed at 40 % of its share; the
survivors replan what is left from its last published progress, agree without a
leader and fly it. Coverage is measured from the flown tracks (swath: the camera
footprint), double flying from the tracks flown along the lanes."""

from __future__ import annotations

import itertools
import math
from collections import Counter
from dataclasses import dataclass, field

from shapely.geometry import LineString, Polygon
from shapely.ops import unary_union

from swarm_node.core.planning import LocalFrame
from swarm_proto import (
    Alert,
    AlertCode,
    Command,
    CommandArgs,
    FsmState,
    GeoPoint,
    Mission,
    MissionParams,
    MissionState,
    MissionType,
    VehicleStatus,
)
from swarm_proto import CommandKind as K
from swarm_sim.core import SITL_HOME
from swarm_sim.fast_fleet import FastFleet
from tests.swarm_sim.test_fast_fleet import square

GCS = 900
ALT_M = 60.0


@dataclass
class Tracks:
    """Each vehicle's positions while it flies its share (sortie MISSION, autopilot in
    its mission), in a local frame."""

    frame: LocalFrame
    points: dict[int, list[tuple[float, float, float]]] = field(default_factory=dict)

    def sample(self, fleet: FastFleet) -> None:
        for vid, v in fleet.vehicles.items():
            s = v.link.state
            flying = (
                v.node.manager.mission_state == MissionState.MISSION
                and v.node.manager.phase.value == "flying"
                and s.lat_deg is not None
                and s.lon_deg is not None
                and abs((s.alt_rel_m or 0.0) - ALT_M) < 15.0
            )
            if flying:
                x, y = self.frame.to_local(s.lat_deg, s.lon_deg)  # type: ignore[arg-type]
                self.points.setdefault(vid, []).append((x, y, s.heading_deg))


def lane_runs(
    pts: list[tuple[float, float, float]], axis_deg: float, min_len_m: float = 100.0,
    width_m: float = 6.0,
) -> list[LineString]:
    """Straight runs along the lane axis: consecutive samples whose cross-track
    coordinate stays within `width_m` over at least `min_len_m`."""
    ux, uy = math.sin(math.radians(axis_deg)), math.cos(math.radians(axis_deg))
    out: list[LineString] = []
    cur: list[tuple[float, float, float]] = []
    for x, y, _h in pts:
        c = x * uy - y * ux
        if cur and (abs(c - cur[0][2]) > width_m / 2 or math.dist(cur[-1][:2], (x, y)) > 50):
            if math.dist(cur[0][:2], cur[-1][:2]) >= min_len_m:
                out.append(LineString([q[:2] for q in cur]))
            cur = []
        cur.append((x, y, c))
    if len(cur) > 1 and math.dist(cur[0][:2], cur[-1][:2]) >= min_len_m:
        out.append(LineString([q[:2] for q in cur]))
    return out


def lane_axis_deg(fleet: FastFleet) -> float:
    """The lanes' direction (mod 180, degrees from north): the direction the plan's legs
    take most, by length (lanes dominate)."""
    v = next(iter(fleet.vehicles.values()))
    plan = v.node.manager.fleet_plan
    assert plan is not None
    weight: Counter[int] = Counter()
    for share in plan.shares.values():
        pts = [(w.lat_deg, w.lon_deg) for w in share.waypoints if w.lat_deg]
        for (a, b), (c, d) in itertools.pairwise(pts):
            dn, de = (c - a) * 111_320.0, (d - b) * 111_320.0 * math.cos(math.radians(a))
            weight[round(math.degrees(math.atan2(de, dn)) % 180.0)] += math.hypot(dn, de)
    return float(weight.most_common(1)[0][0])


def test_six_vtols_inherit_the_share_of_one_killed_at_40_percent(fleet_profiles: dict) -> None:
    members = [1, 2, 3, 4, 5, 6]
    fleet = FastFleet.build(members, fleet_profiles, spacing_m=60.0)
    fleet.run_until(lambda: all(v.link.state.ekf_has_position for v in fleet.vehicles.values()), 60)
    base = GeoPoint(SITL_HOME.lat_deg, SITL_HOME.lon_deg, SITL_HOME.alt_m)
    fleet.broadcast(Command(GCS, 1, K.SET_BASE, args=CommandArgs(point=base)))
    assert fleet.run_until(
        lambda: all(v.node.fsm.state == FsmState.GO_MISSION for v in fleet.vehicles.values()), 30
    )
    area = square(SITL_HOME.lat_deg + 0.006, SITL_HOME.lon_deg, 350.0)
    fleet.broadcast(Mission(70, GCS, MissionType.AREA, area, MissionParams(altitude_rel_m=ALT_M)))
    frame = LocalFrame.at(list(area.points))
    tracks = Tracks(frame)
    victim = 3
    v3 = fleet.vehicles[victim]

    def victim_at_40() -> bool:
        tracks.sample(fleet)
        share = v3.node.manager.share
        return share is not None and v3.node.manager.share_progress_m() >= 0.4 * share.length_m

    assert fleet.run_until(victim_at_40, 900), fleet.notes[-10:]
    axis = lane_axis_deg(fleet)  # from the first plan: its longest legs are lanes
    killed_at = fleet.now
    fleet.kill(victim)
    survivors = [m for m in members if m != victim]
    replanned = fleet.run_until(
        lambda: (tracks.sample(fleet) or True)
        and all(fleet.vehicles[m].node.roster.generation == 1 for m in survivors)
        and all(
            fleet.vehicles[m].node.manager.mission_state == MissionState.MISSION
            for m in survivors
        ),
        120,
    )
    assert replanned, fleet.notes[-20:]
    agree_s = fleet.now - killed_at
    hashes = {fleet.vehicles[m].node.roster.members_hash for m in survivors}
    assert len(hashes) == 1
    plans = {fleet.vehicles[m].node.manager.fleet_plan.roster for m in survivors}  # type: ignore[union-attr]
    assert plans == {tuple(survivors)}
    states = {s.mission_state for s in fleet.messages(VehicleStatus) if s.vehicle_id in survivors}
    assert MissionState.REPLAN in states

    def done() -> bool:
        tracks.sample(fleet)
        return all(fleet.vehicles[m].node.fsm.mission_id != 70 for m in survivors)

    assert fleet.run_until(done, 3000), fleet.notes[-20:]
    # coverage from the flown tracks, swath = the camera footprint at the mission altitude
    hfov = fleet_profiles[1].camera.hfov_deg
    swath = 2.0 * ALT_M * math.tan(math.radians(hfov) / 2.0)
    poly = Polygon([frame.to_local(p.lat_deg, p.lon_deg) for p in area.points])
    flown = unary_union([
        LineString([(x, y) for x, y, _h in pts]).buffer(swath / 2.0)
        for pts in tracks.points.values() if len(pts) > 1
    ])  # fmt: skip
    coverage = flown.intersection(poly).area / poly.area
    # double flying: the straight runs flown along the lanes (at least 100 m within a
    # 6 m wide corridor of the lane axis: turns and transits left out), each a lane
    # spacing wide, overlapping between vehicles inside the area
    spacing = swath * (1.0 - MissionParams().side_overlap)
    along = {
        vid: unary_union(lane_runs(pts, axis)).buffer(spacing / 2.0 * 0.9).intersection(poly)
        for vid, pts in tracks.points.items()
    }
    ids = sorted(along)
    overlap = sum(along[a].intersection(along[b]).area for i, a in enumerate(ids) for b in ids[i + 1 :])
    double = overlap / poly.area
    lanes_cover = unary_union(list(along.values())).area / poly.area
    print(f"coverage {coverage:.4f}, double flown {double:.4f} (lane runs cover {lanes_cover:.2f}, "
          f"axis {axis:.1f} deg), replan agreed {agree_s:.1f} s")  # fmt: skip
    assert lanes_cover > 0.7  # the runs found are the lanes: the measure means something
    completed = {a.vehicle_id for a in fleet.messages(Alert) if a.code == AlertCode.MISSION_COMPLETE}
    assert completed == set(survivors)
    assert coverage >= 0.99
    assert double < 0.02  # the lost member's last second (1 Hz VehicleInfo) is flown again
