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

import numpy as np
from shapely.geometry import LineString, Polygon
from shapely.ops import unary_union

from swarm_node.core.planning import LocalFrame, heading_to_yaw
from swarm_node.core.planning.area import AreaPlan
from swarm_node.core.profile import VehicleProfile
from swarm_proto import (
    Alert,
    AlertCode,
    Command,
    CommandArgs,
    CommandKind,
    FsmState,
    Geometry,
    GeometryKind,
    GeoPoint,
    LatLon,
    Mission,
    MissionParams,
    MissionState,
    MissionType,
    Selector,
    VehicleStatus,
    VehicleType,
    geodesy,
)

from .core import SITL_HOME
from .fast_fleet import FastFleet

GCS = 900
LANE_NEAR_M = 10.0  # a vehicle this close to one of its lanes, heading along it, flies it


def square(center_lat: float, center_lon: float, half_m: float) -> Geometry:
    corners = [(-half_m, -half_m), (-half_m, half_m), (half_m, half_m), (half_m, -half_m)]
    return Geometry.polygon([geodesy.offset(center_lat, center_lon, n, e) for n, e in corners])


@dataclass
class Tracks:
    """Each vehicle's positions while it flies its share (sortie MISSION, autopilot in
    its mission, near the mission altitude), in a local frame: (x, y, heading, on a
    lane of its share), the last from the vehicle's own plan at the time (within
    LANE_NEAR_M of one of its lanes, heading along it): a transit that happens to run
    along another vehicle's lane is not flying that lane."""

    frame: LocalFrame
    alt_m: float
    points: dict[int, list[tuple[float, float, float, bool]]] = field(default_factory=dict)
    _lanes: dict[int, tuple[object, LocalFrame, np.ndarray]] = field(default_factory=dict)

    def _on_lane(self, vid: int, fleet: FastFleet, lat: float, lon: float, heading: float) -> bool:
        plan = fleet.vehicles[vid].node.manager.fleet_plan
        if plan is None or not isinstance(plan.detail, AreaPlan):
            return False
        cached = self._lanes.get(vid)
        if cached is None or cached[0] is not plan:
            lanes = [
                ln
                for a in plan.detail.split.assignments
                if a.vehicle_id == vid
                for ln in a.path.lanes
            ]
            arr = np.array([(*ln.a, *ln.b) for ln in lanes], dtype=float).reshape(-1, 4)
            cached = (plan, plan.detail.frame, arr)
            self._lanes[vid] = cached
        _plan, frame, arr = cached
        if not len(arr):
            return False
        px, py = frame.to_local(lat, lon)
        a, d = arr[:, :2], arr[:, 2:] - arr[:, :2]
        n2 = np.maximum((d * d).sum(axis=1), 1e-9)
        t = np.clip(((px - a[:, 0]) * d[:, 0] + (py - a[:, 1]) * d[:, 1]) / n2, 0.0, 1.0)
        dist = np.hypot(a[:, 0] + t * d[:, 0] - px, a[:, 1] + t * d[:, 1] - py)
        k = int(np.argmin(dist))
        if dist[k] > LANE_NEAR_M:
            return False
        lane_yaw = math.atan2(d[k, 1], d[k, 0])
        yaw = heading_to_yaw(heading)
        return abs(math.cos(yaw - lane_yaw)) > math.cos(math.radians(30.0))

    def sample(self, fleet: FastFleet) -> None:
        for vid, v in fleet.vehicles.items():
            s = v.link.state
            ground = v.node.profile.vehicle_type in (VehicleType.ROVER, VehicleType.BOAT)
            if (
                v.node.manager.mission_state == MissionState.MISSION
                and v.node.manager.phase.value == "flying"
                and s.lat_deg is not None
                and s.lon_deg is not None
                and (ground or abs((s.alt_rel_m or 0.0) - self.alt_m) < 15.0)
            ):
                x, y = self.frame.to_local(s.lat_deg, s.lon_deg)
                lane = self._on_lane(vid, fleet, s.lat_deg, s.lon_deg, s.heading_deg)
                self.points.setdefault(vid, []).append((x, y, s.heading_deg, lane))


def lane_runs(
    pts: Sequence[tuple[float, float, float, bool]],
    axis_deg: float,
    min_len_m: float = 30.0,
    width_m: float = 6.0,
) -> list[LineString]:
    """Straight runs along the lane axis on the vehicle's own lanes: consecutive
    samples on a lane of its share whose cross-track coordinate stays within `width_m`
    over at least `min_len_m`."""
    ux, uy = math.sin(math.radians(axis_deg)), math.cos(math.radians(axis_deg))
    out: list[LineString] = []
    cur: list[tuple[float, float, float]] = []
    for x, y, _h, on_lane in pts:
        c = x * uy - y * ux
        if cur and (
            not on_lane or abs(c - cur[0][2]) > width_m / 2 or math.dist(cur[-1][:2], (x, y)) > 50
        ):
            if math.dist(cur[0][:2], cur[-1][:2]) >= min_len_m:
                out.append(LineString([q[:2] for q in cur]))
            cur = []
        if on_lane:
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
    noticed_s: float  # loss -> the first survivor noticed it (silence: the stale timeout)
    survivors: tuple[int, ...]
    completed: frozenset[int]
    replan_seen: bool
    same_plan: bool
    hashes: int  # distinct members hashes among the survivors (1: they agree)
    pairs: dict[tuple[int, int], float] = field(default_factory=dict)  # double flown by pair
    battery_critical: tuple[int, ...] = ()  # members that raised BATTERY_CRITICAL
    tracks: Tracks | None = field(default=None, repr=False)  # what was flown (plots, debugging)


def inheritance(
    profiles: Mapping[int, VehicleProfile],
    members: Sequence[int] = (1, 2, 3, 4, 5, 6),
    victim: int = 3,
    at_fraction: float = 0.4,
    *,
    half_m: float = 350.0,
    alt_m: float = 60.0,
    north_m: float = 0.006 * 111_320.0,
    side_overlap: float = MissionParams().side_overlap,
    spacing_m: float = 60.0,
) -> Inheritance:
    """`members` fly an area mission sent to ALL: a square of `half_m` half side
    `north_m` north of their homes (`spacing_m` apart), at `alt_m`; `victim` is killed
    at `at_fraction` of its share. Coverage: the flown tracks under the camera swath
    (the narrowest camera of the fleet at `alt_m`, what the planner spaced the lanes
    for; a ground vehicle's track counts with the same swath)."""
    fleet = FastFleet.build(list(members), profiles, spacing_m=spacing_m)
    fleet.run_until(lambda: all(v.link.state.ekf_has_position for v in fleet.vehicles.values()), 60)
    base = GeoPoint(SITL_HOME.lat_deg, SITL_HOME.lon_deg, SITL_HOME.alt_m)
    fleet.broadcast(Command(GCS, 1, CommandKind.SET_BASE, args=CommandArgs(point=base)))
    assert fleet.run_until(
        lambda: all(v.node.fsm.state == FsmState.GO_MISSION for v in fleet.vehicles.values()), 30
    )
    area = square(SITL_HOME.lat_deg + north_m / 111_320.0, SITL_HOME.lon_deg, half_m)
    params = MissionParams(altitude_rel_m=alt_m, side_overlap=side_overlap)
    fleet.broadcast(Mission(70, GCS, MissionType.AREA, area, params))
    frame = LocalFrame.at(list(area.points))
    tracks = Tracks(frame, alt_m)
    lost = fleet.vehicles[victim]

    def at_fraction_of_share() -> bool:
        tracks.sample(fleet)
        share = lost.node.manager.share
        return (
            share is not None
            and lost.node.manager.share_progress_m() >= at_fraction * share.length_m
        )

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
    noticed_s = (
        min(
            (
                t
                for t, _v, text in fleet.notes
                if t >= killed_at and text.startswith(f"mission 70: member {victim} lost")
            ),
            default=fleet.now,
        )
        - killed_at
    )
    hashes = len({fleet.vehicles[m].node.roster.members_hash for m in survivors})
    survivor_plans = [fleet.vehicles[m].node.manager.fleet_plan for m in survivors]
    plans = {
        tuple(sorted((v, s.waypoints) for v, s in p.shares.items()))
        for p in survivor_plans
        if p is not None
    }
    replan_seen = MissionState.REPLAN in {
        s.mission_state for s in fleet.messages(VehicleStatus) if s.vehicle_id in survivors
    }

    def done() -> bool:
        tracks.sample(fleet)
        return all(fleet.vehicles[m].node.fsm.mission_id != 70 for m in survivors)

    assert fleet.run_until(done, 3000), fleet.notes[-20:]
    hfov = min(c.hfov_deg for m in members if (c := profiles[m].camera) is not None)
    swath = 2.0 * alt_m * math.tan(math.radians(hfov) / 2.0)
    poly = Polygon([frame.to_local(p.lat_deg, p.lon_deg) for p in area.points])
    flown = unary_union(
        [
            LineString([(x, y) for x, y, _h, _lane in pts]).buffer(swath / 2.0)
            for pts in tracks.points.values()
            if len(pts) > 1
        ]
    )
    spacing = swath * (1.0 - side_overlap)
    along = {
        # flat ends: two runs meeting where a split cut a lane do not overlap
        vid: unary_union(lane_runs(pts, axis))
        .buffer(spacing / 2.0 * 0.9, cap_style="flat")
        .intersection(poly)
        for vid, pts in tracks.points.items()
    }
    ids = sorted(along)
    pairs = {
        (a, b): along[a].intersection(along[b]).area / poly.area
        for i, a in enumerate(ids)
        for b in ids[i + 1 :]
    }
    overlap = sum(pairs.values()) * poly.area
    completed = frozenset(
        a.vehicle_id for a in fleet.messages(Alert) if a.code == AlertCode.MISSION_COMPLETE
    )
    return Inheritance(
        coverage=flown.intersection(poly).area / poly.area,
        double_flown=overlap / poly.area,
        lanes_cover=unary_union(list(along.values())).area / poly.area,
        agree_s=agree_s,
        noticed_s=noticed_s,
        survivors=survivors,
        completed=completed,
        replan_seen=replan_seen,
        same_plan=len(plans) == 1,
        hashes=hashes,
        pairs=pairs,
        battery_critical=tuple(
            sorted(
                {
                    a.vehicle_id
                    for a in fleet.messages(Alert)
                    if a.code == AlertCode.BATTERY_CRITICAL
                }
            )
        ),
        tracks=tracks,
    )


# --------------------------------------------------------------------------- PREMISSION


def route_line() -> Geometry:
    """A three-point route 900-1800 m north of the vehicles' homes."""
    la, lo = SITL_HOME.lat_deg, SITL_HOME.lon_deg
    pts = [(la + 0.008, lo - 0.004), (la + 0.012, lo + 0.002), (la + 0.016, lo + 0.002)]
    return Geometry(GeometryKind.POLYLINE, tuple(LatLon(a, b) for a, b in pts))


@dataclass
class Meet:
    """A fleet flying its PREMISSION: each member's arrival at its share's entry (the
    closest pass by the entry point, seconds after the mission was sent), their spread,
    and the sortie as flown."""

    arrivals: dict[int, float]
    spread_s: float
    meet_s: float | None  # the meet time the members agreed (None: no PREMISSION)
    entry_miss_m: dict[int, float]  # how close each passed its entry point
    premission_seen: bool  # PREMISSION in the members' statuses while flying the legs
    speed_commands: dict[int, int]  # airspeed commands each node sent
    lateness_spread_s: float  # the widest spread of the members' lateness in MISSION
    completed: frozenset[int] = frozenset()
    makespan_planned_s: float = 0.0
    makespan_flown_s: float | None = None  # from the plan to the last MISSION_COMPLETE


def premission_meet(
    profiles: Mapping[int, VehicleProfile],
    members: Sequence[int] = (1, 2, 3),
    kind: MissionType = MissionType.ROUTE,
    *,
    to_the_end: bool = False,
    alt_m: float = 80.0,
    timeout_s: float = 900.0,
) -> Meet:
    """`members` (fixed-wing) on the ground at their homes 60 m apart get a mission to
    ALL (a route, `route_line()`, or an area north of them) and fly it in fast time;
    measured from the autopilots' positions: when each passes its share's entry point
    (`planning.premission.entry_index` of the fleet plan), and, with `to_the_end`, the
    whole mission (completion, makespan, the lateness spread under the speed rule)."""
    from swarm_node.core.planning.premission import entry_index

    fleet = FastFleet.build(list(members), profiles, spacing_m=60.0)
    fleet.run_until(lambda: all(v.link.state.ekf_has_position for v in fleet.vehicles.values()), 60)
    base = GeoPoint(SITL_HOME.lat_deg, SITL_HOME.lon_deg, SITL_HOME.alt_m)
    fleet.broadcast(Command(GCS, 1, CommandKind.SET_BASE, args=CommandArgs(point=base)))
    assert fleet.run_until(
        lambda: all(v.node.fsm.state == FsmState.GO_MISSION for v in fleet.vehicles.values()), 30
    )
    if kind == MissionType.ROUTE:
        geometry = route_line()
        params = MissionParams(altitude_rel_m=alt_m, altitude_step_m=10.0)
    else:
        geometry = square(SITL_HOME.lat_deg + 0.006, SITL_HOME.lon_deg, 250.0)
        params = MissionParams(altitude_rel_m=alt_m, side_overlap=0.2)
    mid = 60 + int(kind)
    t0 = fleet.now
    fleet.broadcast(Mission(mid, GCS, kind, geometry, params))
    first = fleet.vehicles[members[0]].node
    assert fleet.run_until(lambda: first.manager.fleet_plan is not None, 30), fleet.notes[-10:]
    plan = first.manager.fleet_plan
    assert plan is not None
    frame = LocalFrame.at(list(geometry.points))
    entries = {}
    for vid in members:
        w = plan.share(vid).waypoints[entry_index(plan, vid)]
        entries[vid] = frame.to_local(w.lat_deg, w.lon_deg)
    closest: dict[int, tuple[float, float]] = {}
    started: dict[int, float] = {}
    premission_seen = False
    late_spread = 0.0

    def sample() -> None:
        nonlocal premission_seen, late_spread
        late: list[float] = []
        for vid, v in fleet.vehicles.items():
            s = v.link.state
            m = v.node.manager
            if m.phase.value in ("starting", "climbing", "meeting", "flying"):
                started.setdefault(vid, fleet.now)
            if m.phase.value == "flying" and m.mission_state == MissionState.PREMISSION:
                premission_seen = True
            if m.phase.value != "flying" or s.lat_deg is None or s.lon_deg is None:
                continue
            d = math.dist(frame.to_local(s.lat_deg, s.lon_deg), entries[vid])
            # the closest pass by the entry: within 60 m of it and 60 s of the first pass
            if vid not in closest or (
                d < closest[vid][0] and d < 60.0 and fleet.now - closest[vid][1] - t0 < 60.0
            ):
                closest[vid] = (d, fleet.now - t0)
            sync = m.sync
            if sync.arrived_at is not None and m.mission_state == MissionState.MISSION:
                meet = sync.meet_unix_s
                late.append(sync.lateness_s(vid, m.share_progress_m(), fleet.now - meet))
        if len(late) == len(members):
            late_spread = max(late_spread, max(late) - min(late))

    def arrived() -> bool:
        sample()
        return all(
            vid in closest and closest[vid][0] < 60.0 and fleet.now - t0 - closest[vid][1] > 20.0
            for vid in members
        )

    assert fleet.run_until(arrived, timeout_s), (closest, fleet.notes[-20:])
    meet = first.manager.sync.meet_unix_s or None
    commands = {vid: fleet.vehicles[vid].node.manager.sync.commands for vid in members}
    flown: float | None = None
    completed: frozenset[int] = frozenset()
    if to_the_end:

        def done() -> bool:
            sample()
            return all(fleet.vehicles[m].node.fsm.mission_id != mid for m in members)

        assert fleet.run_until(done, timeout_s), fleet.notes[-20:]
        ends = {
            a.vehicle_id: a.time_unix_s
            for a in fleet.messages(Alert)
            if a.code == AlertCode.MISSION_COMPLETE and a.text == f"mission {mid}"
        }
        completed = frozenset(ends)
        if ends and started:
            flown = max(ends.values()) - min(started.values())
    times = {vid: t for vid, (_d, t) in closest.items()}
    return Meet(
        arrivals=times,
        spread_s=max(times.values()) - min(times.values()),
        meet_s=meet - t0 if meet else None,
        entry_miss_m={vid: d for vid, (d, _t) in closest.items()},
        premission_seen=premission_seen,
        speed_commands=commands,
        lateness_spread_s=late_spread,
        completed=completed,
        makespan_planned_s=plan.makespan_s,
        makespan_flown_s=flown,
    )


# --------------------------------------------------------------------------- AUTOLAND, MUM-T


def ready_fleet(
    members: Sequence[int], profiles: Mapping[int, VehicleProfile], spacing_m: float = 60.0
) -> FastFleet:
    """A FastFleet of `members` on pads `spacing_m` apart, positioned, base set, every
    node in GO_MISSION (ready for a mission)."""
    fleet = FastFleet.build(list(members), profiles, spacing_m=spacing_m)
    fleet.run_until(lambda: all(v.link.state.ekf_has_position for v in fleet.vehicles.values()), 60)
    base = GeoPoint(SITL_HOME.lat_deg, SITL_HOME.lon_deg, SITL_HOME.alt_m)
    fleet.broadcast(Command(GCS, 1, CommandKind.SET_BASE, args=CommandArgs(point=base)))
    assert fleet.run_until(
        lambda: all(v.node.fsm.state == FsmState.GO_MISSION for v in fleet.vehicles.values()), 30
    )
    return fleet


_ready = ready_fleet


def _completed(fleet: FastFleet, mid: int) -> set[int]:
    return {
        a.vehicle_id
        for a in fleet.messages(Alert)
        if a.code == AlertCode.MISSION_COMPLETE and a.text == f"mission {mid}"
    }


@dataclass
class Landings:
    """An AUTOLAND mission flown by a fleet in the air: when and where each touched
    down (seconds after the mission, metres from the base), in touchdown order, and the
    order in which the nodes released their holds."""

    touchdowns: dict[int, float]
    spots: dict[int, tuple[float, float]]
    order: list[int]  # by touchdown
    turns: list[int]  # by the nodes' "our turn to land"
    completed: set[int]
    inactive: bool  # every state machine deactivated (landed)

    @property
    def gaps_s(self) -> list[float]:
        times = [self.touchdowns[v] for v in self.order]
        return [b - a for a, b in itertools.pairwise(times)]


def autoland_flight(
    profiles: Mapping[int, VehicleProfile],
    members: Sequence[int] = (1, 2, 3),
    *,
    separation_s: float = 40.0,
    timeout_s: float = 1200.0,
) -> Landings:
    """`members` orbit a target 900 m north of their homes, then get an AUTOLAND
    mission to a base 110 m south of the first home."""
    fleet = _ready(members, profiles)
    target = Geometry.point(SITL_HOME.lat_deg + 0.008, SITL_HOME.lon_deg + 0.004)
    fleet.broadcast(
        Mission(
            20,
            GCS,
            MissionType.TARGET,
            target,
            MissionParams(altitude_rel_m=70.0, altitude_step_m=10.0),
        )
    )
    assert fleet.run_until(
        lambda: all(v.node.manager.phase.value == "flying" for v in fleet.vehicles.values()), 200
    )
    fleet.run_for(20.0)  # in the air, away from the base
    pad = Geometry.point(SITL_HOME.lat_deg - 0.001, SITL_HOME.lon_deg)
    params = MissionParams(altitude_rel_m=60.0, separation_s=separation_s)
    fleet.broadcast(Mission(21, GCS, MissionType.AUTOLAND, pad, params))
    t0 = fleet.now
    landed: dict[int, tuple[float, tuple[float, float]]] = {}
    frame = LocalFrame(pad.points[0].lat_deg, pad.points[0].lon_deg)

    def all_landed() -> bool:
        for vid, v in fleet.vehicles.items():
            s = v.link.state
            if vid not in landed and not s.armed and (s.alt_rel_m or 0.0) < 1.0 and s.lat_deg:
                landed[vid] = (fleet.now - t0, frame.to_local(s.lat_deg, s.lon_deg or 0.0))
        return len(landed) == len(members) and _completed(fleet, 21) == set(members)

    assert fleet.run_until(all_landed, timeout_s), (landed, fleet.notes[-10:])
    return Landings(
        touchdowns={v: t for v, (t, _p) in landed.items()},
        spots={v: p for v, (_t, p) in landed.items()},
        order=sorted(landed, key=lambda v: landed[v][0]),
        turns=[vid for _t, vid, text in fleet.notes if text == "mission 21: our turn to land"],
        completed=_completed(fleet, 21),
        inactive=all(v.node.fsm.state == FsmState.INACTIVE for v in fleet.vehicles.values()),
    )


@dataclass
class Following:
    """A MUM-T mission: each follower's largest distance from its slot (behind the
    lead where it is now, in its vee) once converged, the answers, and the end."""

    slot_error_m: dict[int, float]
    converged_after_s: dict[int, float]  # first time within 10 m of its slot
    answers: dict[int, object]
    slots: dict[int, int]
    lead_on_route: bool  # the lead kept flying its own mission
    completed: set[int]


def mumt_flight(
    profiles: Mapping[int, VehicleProfile],
    lead: int = 4,
    followers: Sequence[int] = (1, 2),
    *,
    settle_s: float = 120.0,
    duration_s: float = 150.0,
) -> Following:
    """`lead` flies a 4 km route north; a MUM-T mission sent to every vehicle makes the
    others its followers; errors are measured after `settle_s`."""
    from swarm_proto import Ack

    fleet = _ready([*followers, lead], profiles)
    la, lo = SITL_HOME.lat_deg, SITL_HOME.lon_deg
    line = Geometry(GeometryKind.POLYLINE, (LatLon(la + 0.003, lo), LatLon(la + 0.04, lo + 0.01)))
    fleet.broadcast(
        Mission(
            30, GCS, MissionType.ROUTE, line, MissionParams(altitude_rel_m=60.0), Selector.ids(lead)
        )
    )
    fleet.run_for(1.0)
    params = MissionParams(altitude_rel_m=60.0, lead_vehicle_id=lead, duration_s=duration_s)
    fleet.broadcast(Mission(31, GCS, MissionType.MUMT, Geometry.point(la, lo), params))
    t0 = fleet.now
    fleet.run_for(2.0)
    answers = {a.vehicle_id: a.reason for a in fleet.messages(Ack) if a.ref_id == 31}
    slots = {
        vid: f.slot
        for vid in followers
        if (f := fleet.vehicles[vid].node.manager.follow) is not None
    }
    frame = LocalFrame(la, lo)
    errors: dict[int, list[float]] = {vid: [] for vid in followers}
    converged: dict[int, float] = {}
    lead_ok = True

    def sample() -> bool:
        nonlocal lead_ok
        ls = fleet.vehicles[lead].link.state
        if ls.lat_deg is None or ls.lon_deg is None or ls.groundspeed_m_s < 1.0:
            return False
        lead_ok &= fleet.vehicles[lead].node.fsm.mission_id == 30
        lx, ly = frame.to_local(ls.lat_deg, ls.lon_deg)
        yaw = heading_to_yaw(math.degrees(math.atan2(ls.vel_east_m_s, ls.vel_north_m_s)))
        c, sn = math.cos(yaw), math.sin(yaw)
        for vid in followers:
            follow = fleet.vehicles[vid].node.manager.follow
            s = fleet.vehicles[vid].link.state
            if follow is None or follow.started_at is None or s.lat_deg is None:
                continue
            o = follow.offsets[follow.slot]
            slot = (lx + o.ahead_m * c + o.right_m * sn, ly + o.ahead_m * sn - o.right_m * c)
            d = math.dist(frame.to_local(s.lat_deg, s.lon_deg or 0.0), slot)
            if d < 10.0:
                converged.setdefault(vid, fleet.now - t0)
            if fleet.now - t0 >= settle_s:
                errors[vid].append(d)
        return fleet.now - t0 >= duration_s

    assert fleet.run_until(sample, duration_s + 60.0)
    fleet.run_until(lambda: _completed(fleet, 31) == set(followers), 60.0)
    return Following(
        slot_error_m={vid: max(e) if e else math.inf for vid, e in errors.items()},
        converged_after_s=converged,
        answers=answers,
        slots=slots,
        lead_on_route=lead_ok,
        completed=_completed(fleet, 31),
    )
