"""Fast-time mission scenarios measured the same way by the tests and the benchmarks
(`tests/swarm_sim/test_inheritance.py`, `bench/mission.py`).

`inheritance`: a fleet flies an area mission sent to ALL; one member is killed at a
fraction of its share; the survivors replan and finish. Coverage is measured from the
flown tracks (swath: the camera footprint at the mission altitude), double flying from
the straight runs flown along the lanes (turns and transits left out)."""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

from shapely.geometry import LineString, Polygon
from shapely.ops import unary_union

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
    VehicleStatus,
    geodesy,
)

from .core import SITL_HOME
from .fast_fleet import FastFleet

GCS = 900


def square(center_lat: float, center_lon: float, half_m: float) -> Geometry:
    corners = [(-half_m, -half_m), (-half_m, half_m), (half_m, half_m), (half_m, -half_m)]
    return Geometry.polygon([geodesy.offset(center_lat, center_lon, n, e) for n, e in corners])


@dataclass
class Tracks:
    """Each vehicle's positions while it flies its share (sortie MISSION, autopilot in
    its mission, near the mission altitude), in a local frame."""

    frame: LocalFrame
    alt_m: float
    points: dict[int, list[tuple[float, float, float]]] = field(default_factory=dict)

    def sample(self, fleet: FastFleet) -> None:
        for vid, v in fleet.vehicles.items():
            s = v.link.state
            if (
                v.node.manager.mission_state == MissionState.MISSION
                and v.node.manager.phase.value == "flying"
                and s.lat_deg is not None
                and s.lon_deg is not None
                and abs((s.alt_rel_m or 0.0) - self.alt_m) < 15.0
            ):
                x, y = self.frame.to_local(s.lat_deg, s.lon_deg)
                self.points.setdefault(vid, []).append((x, y, s.heading_deg))


def lane_runs(
    pts: Sequence[tuple[float, float, float]], axis_deg: float, min_len_m: float = 100.0,
    width_m: float = 6.0,
) -> list[LineString]:  # fmt: skip
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
    weight: dict[int, float] = {}
    for share in plan.shares.values():
        pts = [(w.lat_deg, w.lon_deg) for w in share.waypoints if w.lat_deg]
        for (a, b), (c, d) in itertools.pairwise(pts):
            k = round(geodesy.bearing_deg(a, b, c, d) % 180.0)
            weight[k] = weight.get(k, 0.0) + geodesy.distance_m(a, b, c, d)
    return float(max(weight, key=weight.__getitem__))


@dataclass
class Inheritance:
    coverage: float  # fraction of the area under the flown tracks' camera swath
    double_flown: float  # fraction of the area whose lanes two vehicles flew
    lanes_cover: float  # fraction of the area the lane runs found cover (sanity)
    agree_s: float  # loss -> every survivor flying its new share (simulated)
    survivors: tuple[int, ...]
    completed: frozenset[int]
    replan_seen: bool
    same_plan: bool
    hashes: int  # distinct members hashes among the survivors (1: they agree)


def inheritance(
    profiles: Mapping[int, VehicleProfile],
    members: Sequence[int] = (1, 2, 3, 4, 5, 6),
    victim: int = 3,
    at_fraction: float = 0.4,
    *,
    half_m: float = 350.0,
    alt_m: float = 60.0,
) -> Inheritance:
    fleet = FastFleet.build(list(members), profiles, spacing_m=60.0)
    fleet.run_until(lambda: all(v.link.state.ekf_has_position for v in fleet.vehicles.values()), 60)
    base = GeoPoint(SITL_HOME.lat_deg, SITL_HOME.lon_deg, SITL_HOME.alt_m)
    fleet.broadcast(Command(GCS, 1, CommandKind.SET_BASE, args=CommandArgs(point=base)))
    assert fleet.run_until(
        lambda: all(v.node.fsm.state == FsmState.GO_MISSION for v in fleet.vehicles.values()), 30
    )
    area = square(SITL_HOME.lat_deg + 0.006, SITL_HOME.lon_deg, half_m)
    fleet.broadcast(Mission(70, GCS, MissionType.AREA, area, MissionParams(altitude_rel_m=alt_m)))
    frame = LocalFrame.at(list(area.points))
    tracks = Tracks(frame, alt_m)
    lost = fleet.vehicles[victim]

    def at_fraction_of_share() -> bool:
        tracks.sample(fleet)
        share = lost.node.manager.share
        return share is not None and lost.node.manager.share_progress_m() >= at_fraction * share.length_m

    assert fleet.run_until(at_fraction_of_share, 900), fleet.notes[-10:]
    axis = lane_axis_deg(fleet)  # from the first plan
    killed_at = fleet.now
    fleet.kill(victim)
    survivors = tuple(m for m in members if m != victim)

    def replanned() -> bool:
        tracks.sample(fleet)
        return all(
            fleet.vehicles[m].node.roster.generation >= 1
            and fleet.vehicles[m].node.manager.mission_state == MissionState.MISSION
            for m in survivors
        )

    assert fleet.run_until(replanned, 120), fleet.notes[-20:]
    agree_s = fleet.now - killed_at
    hashes = len({fleet.vehicles[m].node.roster.members_hash for m in survivors})
    plans = {
        tuple(sorted((v, s.waypoints) for v, s in fleet.vehicles[m].node.manager.fleet_plan.shares.items()))  # type: ignore[union-attr]
        for m in survivors
    }
    replan_seen = MissionState.REPLAN in {
        s.mission_state for s in fleet.messages(VehicleStatus) if s.vehicle_id in survivors
    }

    def done() -> bool:
        tracks.sample(fleet)
        return all(fleet.vehicles[m].node.fsm.mission_id != 70 for m in survivors)

    assert fleet.run_until(done, 3000), fleet.notes[-20:]
    camera = profiles[members[0]].camera
    assert camera is not None
    swath = 2.0 * alt_m * math.tan(math.radians(camera.hfov_deg) / 2.0)
    poly = Polygon([frame.to_local(p.lat_deg, p.lon_deg) for p in area.points])
    flown = unary_union(
        [LineString([(x, y) for x, y, _h in pts]).buffer(swath / 2.0)
         for pts in tracks.points.values() if len(pts) > 1]
    )  # fmt: skip
    spacing = swath * (1.0 - MissionParams().side_overlap)
    along = {
        vid: unary_union(lane_runs(pts, axis)).buffer(spacing / 2.0 * 0.9).intersection(poly)
        for vid, pts in tracks.points.items()
    }
    ids = sorted(along)
    overlap = sum(along[a].intersection(along[b]).area for i, a in enumerate(ids) for b in ids[i + 1 :])
    completed = frozenset(
        a.vehicle_id for a in fleet.messages(Alert) if a.code == AlertCode.MISSION_COMPLETE
    )
    return Inheritance(
        coverage=flown.intersection(poly).area / poly.area,
        double_flown=overlap / poly.area,
        lanes_cover=unary_union(list(along.values())).area / poly.area,
        agree_s=agree_s,
        survivors=survivors,
        completed=completed,
        replan_seen=replan_seen,
        same_plan=len(plans) == 1,
        hashes=hashes,
    )
