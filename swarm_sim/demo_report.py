"""The demo's report: what the ground station heard, recorded and measured.

    FlightRecorder   every VehicleStatus heard -> the flight CSV (swarm_proto/trajectory.py
                     format: time_s, vehicle, lat, lon, alt_m, then FLIGHT_COLUMNS), with
                     the mission each vehicle's VehicleInfo last showed
    read_flight      the CSV back, with those columns
    coverage         the area under the flown tracks' camera swath (the samples flying the
                     area mission at its altitude), as FastFleet's scenarios measure it
    build            report.json and the pictures: top.png (plans, zones, flown tracks:
                     `gcs plot`'s drawing), altitude.png (height above home against time,
                     the story's steps marked), separation.png (`gcs analyze separation`'s
                     event map and distances, airborne pairs)

Separation is the paper's analysis (gcs_cli/separation.py: ECEF-exact distances, risk
10-40 m, danger 5-10 m, near-collision < 5 m) on a uniform 0.2 s grid, over the whole
record and "once airborne" (only samples where both vehicles are armed and more than
AIRBORNE_M above their homes: pads 30 m apart are a risk-band pair on the ground).

The demo passes when every mission was completed (every vehicle still flying it at the
end reported MISSION_COMPLETE), no airborne pair came within the near-collision
distance, the area's coverage is at least MIN_COVERAGE and the story ran to its end."""

from __future__ import annotations

import csv
import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
from shapely.geometry import LineString
from shapely.geometry.base import BaseGeometry
from shapely.ops import unary_union

from gcs_cli.separation import SeparationReport, analyze
from swarm_node.core.planning.area import AreaPlan
from swarm_node.core.planning.coverage import decompose
from swarm_node.core.planning.fleet_plan import FleetPlan
from swarm_node.core.planning.geo import LocalFrame
from swarm_node.core.planning.zones import ZoneSet
from swarm_node.core.profile import VehicleProfile
from swarm_proto import GeoPoint, Severity, VehicleInfo, VehicleStatus
from swarm_proto.trajectory import Trajectory, TrajectoryError, TrajectoryWriter

from .story import AREA_ID, PERIMETER_ID, ROUTE_ID, Record, StoryPlan

FLIGHT_COLUMNS = (
    "alt_rel_m",
    "groundspeed_m_s",
    "heading_deg",
    "battery_pct",
    "fsm",
    "mission",
    "progress_pct",
    "armed",
    "mission_id",
)
AIRBORNE_M = 1.0
MIN_COVERAGE = 0.99
GRID_S = 0.2  # separation grid (the statuses' 5 Hz)
ALT_BAND_M = 15.0  # a sample this close to the survey altitude counts for coverage
GAP_S = 2.0  # a track is broken where samples are further apart


# --------------------------------------------------------------------------- recording


class FlightRecorder:
    """Writes each VehicleStatus heard once (a repeat of the same sample is skipped),
    with the mission id of the vehicle's latest VehicleInfo."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.writer = TrajectoryWriter(path, FLIGHT_COLUMNS, flush_every=200)
        self.mission: dict[int, int] = {}
        self._last: dict[int, float] = {}

    def handle(self, msg: object) -> None:
        if isinstance(msg, VehicleInfo):
            self.mission[msg.vehicle_id] = msg.mission_id
        elif isinstance(msg, VehicleStatus):
            if self._last.get(msg.vehicle_id) == msg.time_unix_s:
                return
            self._last[msg.vehicle_id] = msg.time_unix_s
            s = msg
            self.writer.write(
                s.time_unix_s,
                s.vehicle_id,
                s.lat_deg,
                s.lon_deg,
                s.alt_msl_m,
                f"{s.alt_rel_m:.2f}",
                f"{s.groundspeed_m_s:.2f}",
                f"{s.heading_deg:.1f}",
                s.battery_pct,
                s.fsm_state.name,
                s.mission_state.name,
                s.mission_progress_pct,
                int(s.armed),
                self.mission.get(s.vehicle_id, 0),
            )

    def close(self) -> None:
        self.writer.close()


@dataclass(frozen=True)
class Flight:
    """The flight CSV's columns (rows in file order)."""

    t: npt.NDArray[np.float64]  # time_s as written
    vehicle: npt.NDArray[np.int64]
    lat: npt.NDArray[np.float64]
    lon: npt.NDArray[np.float64]
    alt_m: npt.NDArray[np.float64]
    alt_rel_m: npt.NDArray[np.float64]
    armed: npt.NDArray[np.bool_]
    state: npt.NDArray[np.str_]  # mission state name
    mission_id: npt.NDArray[np.int64]
    battery_pct: npt.NDArray[np.int64]

    @property
    def vehicles(self) -> list[int]:
        return sorted({int(v) for v in self.vehicle})

    def trajectory(self, mask: npt.NDArray[np.bool_] | None = None) -> Trajectory:
        m = np.ones(len(self.t), dtype=bool) if mask is None else mask
        return Trajectory(self.t[m], self.vehicle[m], self.lat[m], self.lon[m], self.alt_m[m])

    def airborne(self) -> npt.NDArray[np.bool_]:
        return self.armed & (self.alt_rel_m > AIRBORNE_M)


def read_flight(path: Path) -> Flight:
    """The demo's flight CSV; TrajectoryError (one line) when it is not one."""
    cols: dict[str, list[str]] = {}
    try:
        with path.open(newline="", encoding="utf-8") as f:
            reader = csv.DictReader(f)
            want = ("time_s", "vehicle", "lat", "lon", "alt_m", *FLIGHT_COLUMNS)
            missing = [c for c in want if c not in (reader.fieldnames or ())]
            if missing:
                raise TrajectoryError(f"{path}: missing column(s) {', '.join(missing)}")
            cols = {c: [] for c in want}
            for row in reader:
                for c in want:
                    cols[c].append(row[c])
    except (OSError, UnicodeDecodeError) as exc:
        raise TrajectoryError(f"{path}: cannot read: {exc}") from None
    if not cols["time_s"]:
        raise TrajectoryError(f"{path}: no samples")
    try:
        return Flight(
            np.array(cols["time_s"], dtype=np.float64),
            np.array(cols["vehicle"], dtype=np.int64),
            np.array(cols["lat"], dtype=np.float64),
            np.array(cols["lon"], dtype=np.float64),
            np.array(cols["alt_m"], dtype=np.float64),
            np.array(cols["alt_rel_m"], dtype=np.float64),
            np.array(cols["armed"], dtype=np.int64) != 0,
            np.array(cols["mission"], dtype=np.str_),
            np.array(cols["mission_id"], dtype=np.int64),
            np.array(cols["battery_pct"], dtype=np.int64),
        )
    except ValueError as exc:
        raise TrajectoryError(f"{path}: {exc}") from None


# --------------------------------------------------------------------------- measures


def swath_m(profiles: Sequence[VehicleProfile], alt_m: float) -> float:
    """The camera footprint the planner spaced the lanes for: the narrowest camera."""
    hfov = min(p.camera.hfov_deg for p in profiles if p.camera is not None)
    return 2.0 * alt_m * math.tan(math.radians(hfov) / 2.0)


def survey_runs(
    flight: Flight, mission_id: int, alt_m: float, top_m: float | None = None
) -> dict[int, list[npt.NDArray[np.float64]]]:
    """Each vehicle's runs of samples flying `mission_id` (MISSION, or REPLAN: it flies
    its share meanwhile) within ALT_BAND_M of the survey's heights (`alt_m`, the lowest
    member, to `top_m`, the highest), as (n, 2) lat/lon arrays, broken where the samples
    are more than GAP_S apart."""
    top = alt_m if top_m is None else top_m
    ok = (
        (flight.mission_id == mission_id)
        & np.isin(flight.state, ("MISSION", "REPLAN"))
        & (flight.alt_rel_m > alt_m - ALT_BAND_M)
        & (flight.alt_rel_m < top + ALT_BAND_M)
        & flight.armed
    )
    out: dict[int, list[npt.NDArray[np.float64]]] = {}
    for vid in flight.vehicles:
        sel = np.flatnonzero((flight.vehicle == vid) & ok)
        if len(sel) < 2:
            continue
        sel = sel[np.argsort(flight.t[sel], kind="stable")]
        t = flight.t[sel]
        breaks = np.flatnonzero(np.diff(t) > GAP_S) + 1
        for part in np.split(sel, breaks):
            if len(part) > 1:
                out.setdefault(vid, []).append(
                    np.column_stack([flight.lat[part], flight.lon[part]])
                )
    return out


def coverable(plan: StoryPlan, first: FleetPlan | None) -> tuple[LocalFrame, BaseGeometry]:
    """What the survey can cover, in a local frame: the area less the no-fly zones
    grown by the planner's margin (`decompose(...).target`, what the planner measures
    its own coverage on: lanes stop at a zone's margin, the band within it is seen only
    incidentally). Without the plan: the area less the zones themselves."""
    if first is not None and isinstance(first.detail, AreaPlan):
        d = first.detail
        return d.frame, decompose(d.frame.shape(plan.area), d.zones).target
    frame = LocalFrame.for_geometry(plan.area)
    zs = ZoneSet.from_messages(plan.zones, frame, now_unix_s=0.0)
    return frame, decompose(frame.shape(plan.area), zs).target


def coverage(
    flight: Flight, plan: StoryPlan, swath: float, frame: LocalFrame, target: BaseGeometry
) -> float:
    """The fraction of `target` (in `frame`) under the flown survey tracks' swath (the
    lowest member's: the higher ones see more)."""
    lines = []
    top = plan.area_alt_m + plan.area_layer_m * max(len(plan.members) - 1, 0)
    for runs in survey_runs(flight, AREA_ID, plan.area_alt_m, top).values():
        for run in runs:
            lines.append(LineString(frame.to_local_many(run.tolist())).buffer(swath / 2.0))
    if not lines or target.area <= 0.0:
        return 0.0
    return float(unary_union(lines).intersection(target).area / target.area)


def first_plan(
    plan: StoryPlan, profiles: Mapping[int, VehicleProfile], homes: Mapping[int, GeoPoint]
) -> FleetPlan | None:
    """The survey's first plan, as every member made it (from the pads: `gcs plot`
    recomputes shares the same way); None if it cannot be made here."""
    from swarm_node.core.mission.share import Member, plan_fleet

    try:
        members = [Member(profiles[v], homes.get(v)) for v in plan.members]
        first = homes.get(plan.members[0])
        return plan_fleet(
            plan.area_mission(0.0),
            members,
            list(plan.zones),
            0.0,
            first.alt_msl_m if first else 0.0,
        )
    except Exception:
        return None


def separation(flight: Flight, *, airborne: bool) -> SeparationReport | None:
    mask = flight.airborne() if airborne else None
    tr = flight.trajectory(mask)
    if len(set(tr.vehicle.tolist())) < 2:
        return None
    return analyze(tr, step_s=GRID_S)


def _sep_dict(rep: SeparationReport | None, t0: float) -> dict[str, Any] | None:
    if rep is None:
        return None
    d = rep.as_dict()
    tot = rep.totals()
    for p in d["pairs"]:
        if p["min_time_s"] == p["min_time_s"]:  # not NaN
            p["min_time_s"] = round(p["min_time_s"] - t0, 2)
    if d["min_time_s"] is not None:
        d["min_time_s"] = round(d["min_time_s"] - t0, 2)
    d.update({"risk": tot["risk"], "danger": tot["danger"], "near": tot["near"], "grid_s": GRID_S})
    return d


# --------------------------------------------------------------------------- the record


def mission_rows(plan: StoryPlan, record: Record) -> list[dict[str, Any]]:
    kinds = {
        AREA_ID: "area",
        PERIMETER_ID: "perimeter",
        ROUTE_ID: "route",
        plan.target_mission_id: "target",
    }
    failed = set(record.failed)
    rows = []
    for mid in (AREA_ID, plan.target_mission_id, PERIMETER_ID, ROUTE_ID):
        rec = record.missions.get(mid)
        if rec is None:
            rows.append({"mission_id": mid, "kind": kinds[mid], "sent": False, "completed": False})
            continue
        rows.append(
            {
                "mission_id": mid,
                "kind": kinds[mid],
                "sent": True,
                "sent_at_s": rec.sent_at,
                "flown_by": sorted(rec.flew),
                "left_for_another": sorted(rec.left),
                "failed": sorted(failed & rec.flew),
                "completed_by": sorted(rec.completed),
                "completed_at_s": {str(v): round(t, 1) for v, t in sorted(rec.completed.items())},
                "completed": rec.done(failed),
            }
        )
    return rows


def vote_rows(plan: StoryPlan, record: Record) -> list[dict[str, Any]]:
    from gcs_cli.tasking import result_of

    out = []
    for mid, votes in sorted(record.votes.items()):
        went = set(record.chosen.get(mid, {}))
        r = result_of(mid, votes, 2 if mid == plan.target_mission_id else None, went)
        out.append(
            {
                "mission_id": mid,
                "voters": sorted(r.voters),
                "scores": {str(v): round(s, 4) for v, s in sorted(r.scores.items())},
                "decided": r.decided,
                "winners": list(r.winners) if r.winners is not None else sorted(went),
                "said_chosen": sorted(went),
                "chosen_alerts": {str(v): t for v, t in sorted(record.chosen.get(mid, {}).items())},
            }
        )
    return out


def critical_rows(record: Record) -> list[dict[str, Any]]:
    """Every CRITICAL alert heard (an emergency's cause among them)."""
    return [
        {"t_s": round(t, 1), "vehicle": a.vehicle_id, "code": a.code.name, "text": a.text}
        for t, a in record.alerts
        if a.severity >= Severity.CRITICAL
    ]


def replan_rows(record: Record) -> list[dict[str, Any]]:
    """The replans the vehicles went through (REPLAN in their status), one event per
    mission and cause: who replanned, when, why. The cause is the story's step when a
    vehicle entered REPLAN (the vote's replan spans the VOTE and REPLAN steps: the
    vehicles enter it within a second of each other, the step changes between them)."""
    events: list[dict[str, Any]] = []
    victim = next(iter(record.failed), None)
    for t, mid, vid, phase in sorted(record.replans):
        if mid != AREA_ID:  # the story changes only the survey's fleet
            cause, why = "other", "a member of its fleet was lost (or in an emergency)"
        elif phase in ("vote", "replan", "fail"):
            cause = "vote"
            why = (
                f"vehicles {', '.join(map(str, record.winners))} voted out to the target: "
                "the others re-split what is left"
            )
        elif phase in ("inherit", "finish") and victim is not None:
            cause = "lost"
            why = f"vehicle {victim} lost: the survivors share out the rest of its share"
        else:
            cause, why = phase, "the fleet changed"
        last = next((e for e in reversed(events) if e["mission_id"] == mid), None)
        if last is not None and last["cause"] == cause and t - last["t_s"] < 30.0:
            last["vehicles"].append(vid)
            continue
        events.append(
            {
                "t_s": round(t, 1),
                "mission_id": mid,
                "phase": phase,
                "cause": cause,
                "vehicles": [vid],
                "why": why,
            }
        )
    for e in events:
        e["vehicles"] = sorted(set(e["vehicles"]))
    return events


# --------------------------------------------------------------------------- pictures


def draw_top(
    out: Path,
    plan: StoryPlan,
    flight: Flight,
    profiles: Mapping[int, VehicleProfile],
    homes: Mapping[int, GeoPoint],
    base: GeoPoint | None,
    record: Record,
    first: FleetPlan | None,
) -> dict[str, int]:
    """Plans, zones and flown tracks from above (`gcs plot`'s drawing): the survey's
    first plan as each vehicle planned it (dashed), every mission's geometry, the
    tracks while airborne."""
    from gcs_cli.plot import draw
    from gcs_cli.recovery import SwarmState, VehicleState
    from swarm_proto import Geometry, Mission, MissionParams, MissionType, Selector

    pair = record.winners or plan.members[:2]
    missions = [
        plan.area_mission(0.0),
        plan.perimeter_mission(pair, 0.0),
        plan.route_mission(pair, 0.0),
        Mission(
            plan.target_mission_id,
            900,
            MissionType.TARGET,
            Geometry.point(*plan.target),
            MissionParams(),
            Selector(),
            "target",
        ),
    ]
    vehicles = [
        VehicleState(v, profiles[v].vehicle_type, profiles[v].model, homes.get(v))
        for v in plan.members
        if v in profiles
    ]
    state = SwarmState(base=base, zones=list(plan.zones), missions=missions, vehicles=vehicles)
    shares: dict[int, list[tuple[float, float]]] = {}
    if first is not None:
        shares = {
            vid: [(w.lat_deg, w.lon_deg) for w in s.waypoints if w.lat_deg or w.lon_deg]
            for vid, s in first.shares.items()
        }
    track = flight.trajectory(flight.airborne())
    return draw(
        out,
        state,
        track if len(track.time_s) else None,
        shares=shares,
        title="experiment 1: survey plan (dashed), missions, zones and flown tracks",
    )


def draw_altitude(out: Path, flight: Flight, record: Record, t0: float) -> None:
    """Height above home against time, one line per vehicle, the story's steps marked."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from gcs_cli.plot import vehicle_colors

    colors = vehicle_colors(flight.vehicles)
    fig, ax = plt.subplots(figsize=(10, 4.5), dpi=100)
    for vid in flight.vehicles:
        sel = flight.vehicle == vid
        order = np.argsort(flight.t[sel], kind="stable")
        t = (flight.t[sel][order] - t0) / 60.0
        ax.plot(
            t,
            flight.alt_rel_m[sel][order],
            color=colors[vid],
            linewidth=1.2,
            label=f"vehicle {vid}",
        )
        if vid in record.failed:
            ax.plot(
                t[-1],
                flight.alt_rel_m[sel][order][-1],
                marker="X",
                markersize=12,
                color="red",
                markeredgecolor="black",
                zorder=5,
            )
    marks = {
        "survey": "survey",
        "vote": "target reported",
        "fail": "replanned",
        "inherit": "vehicle lost",
        "finish": "inherited",
        "home": "all missions flown",
    }
    top = max(float(flight.alt_rel_m.max()) if len(flight.alt_rel_m) else 100.0, 50.0)
    k = 0
    for t, step in record.steps:
        if step in marks:
            ax.axvline(t / 60.0, color="grey", linestyle=":", linewidth=0.8)
            ax.text(
                t / 60.0,
                top * (1.02 + 0.07 * (k % 4)),
                f" {marks[step]}",
                fontsize=7,
                va="bottom",
                ha="left",
                color="dimgrey",
            )
            k += 1
    ax.set_xlabel("time since the base was set, min")
    ax.set_ylabel("height above home, m")
    ax.set_ylim(-5, top * 1.35)
    ax.grid(True, linewidth=0.3)
    ax.legend(fontsize=7, ncol=3, loc="lower center")
    fig.tight_layout()
    fig.savefig(out, format="png")
    plt.close(fig)


def draw_separation(out: Path, rep: SeparationReport, t0: float) -> None:
    """`gcs analyze separation --png`'s picture, times since the base was set."""
    import dataclasses

    from gcs_cli.analyze import draw

    pairs = tuple(
        dataclasses.replace(p, times_s=p.times_s - t0, min_time_s=p.min_time_s - t0)
        for p in rep.pairs
    )
    draw(dataclasses.replace(rep, pairs=pairs), out)


# --------------------------------------------------------------------------- build


def build(
    out: Path,
    *,
    plan: StoryPlan,
    record: Record,
    flight_csv: Path,
    profiles: Mapping[int, VehicleProfile],
    homes: Mapping[int, GeoPoint],
    base: GeoPoint | None,
    meta: Mapping[str, Any],
    radio: Mapping[str, Any] | None = None,
    pictures: bool = True,
) -> dict[str, Any]:
    """Measure the flight, write report.json (and the pictures) in `out`; returns the
    report (`ok`, `failures`)."""
    out.mkdir(parents=True, exist_ok=True)
    failures: list[str] = []
    t0 = record.t0 or 0.0
    flight: Flight | None
    try:
        flight = read_flight(flight_csv)
    except TrajectoryError as exc:
        flight, cov = None, 0.0
        failures.append(f"no flight record: {exc}")
    missions = mission_rows(plan, record)
    done = [m for m in missions if m["completed"]]
    for m in missions:
        if not m["completed"]:
            failures.append(f"mission {m['mission_id']} ({m['kind']}) not completed")
    area_profiles = [profiles[v] for v in plan.members if v in profiles]
    swath = swath_m(area_profiles, plan.area_alt_m) if area_profiles else 0.0
    whole = airborne = None
    first = first_plan(plan, profiles, homes)
    frame, target = coverable(plan, first)
    cov_polygon = 0.0
    if flight is not None:
        cov = coverage(flight, plan, swath, frame, target)
        cov_polygon = coverage(flight, plan, swath, frame, frame.shape(plan.area))
        whole = separation(flight, airborne=False)
        airborne = separation(flight, airborne=True)
    if cov < MIN_COVERAGE:
        failures.append(f"area coverage {cov:.1%} < {MIN_COVERAGE:.0%}")
    near = airborne.totals()["near"] if airborne is not None else 0
    if near:
        failures.append(f"{near} near-collision samples (< 5 m) between airborne vehicles")
    if not record.outcome or record.outcome != "every vehicle landed":
        failures.append(f"the story did not finish: {record.outcome or 'interrupted'}")
    pics: dict[str, str] = {}
    if pictures and flight is not None:
        draw_top(out / "top.png", plan, flight, profiles, homes, base, record, first)
        draw_altitude(out / "altitude.png", flight, record, t0)
        pics = {"top": "top.png", "altitude": "altitude.png"}
        if airborne is not None:
            draw_separation(out / "separation.png", airborne, t0)
            pics["separation"] = "separation.png"
    sep_air = _sep_dict(airborne, t0)
    report: dict[str, Any] = {
        "ok": not failures,
        "failures": failures,
        **dict(meta),
        "vehicles": list(plan.members),
        "missions": missions,
        "missions_completed": len(done),
        "missions_total": len(missions),
        "coverage": round(cov, 4),
        "coverage_detail": {
            "mission_id": AREA_ID,
            "measured_on": "the area less the no-fly zones grown by the planner's margin",
            "coverable_m2": round(float(target.area)),
            "area_m2": round(float(frame.shape(plan.area).area)),
            "of_whole_area": round(cov_polygon, 4),
            "swath_m": round(swath, 1),
            "altitude_rel_m": plan.area_alt_m,
            "side_overlap": plan.side_overlap,
        },
        "votes": vote_rows(plan, record),
        "winners": list(record.winners),
        "replans": replan_rows(record),
        "failed": {str(v): round(t, 1) for v, t in record.failed.items()},
        "critical_alerts": critical_rows(record),
        "landed": sorted(record.landed),
        "timeline": [{"t_s": round(t, 1), "step": s} for t, s in record.steps],
        "outcome": record.outcome,
        "separation": {
            "near": sep_air["near"] if sep_air else None,
            "danger": sep_air["danger"] if sep_air else None,
            "risk": sep_air["risk"] if sep_air else None,
            "min_sep_m": sep_air["min_sep_m"] if sep_air else None,
            "airborne": sep_air,
            "whole": _sep_dict(whole, t0),
        },
        "radio": dict(radio) if radio is not None else None,
        "files": {"flight": flight_csv.name, **pics},
    }
    (out / "report.json").write_text(json.dumps(report, indent=2) + "\n")
    return report


# --------------------------------------------------------------------------- fast time


def fast_report(
    plan: StoryPlan,
    profiles: Mapping[int, VehicleProfile],
    out: Path,
    *,
    pictures: bool = True,
    settings: object | None = None,
    over_air: bool = False,
) -> dict[str, Any]:
    """The story flown against FastFleet (`story.fly_fast`: simulated vehicles, real
    MAVLink bytes, the node cores; no processes, no sockets) and reported as the demo
    reports it: report.json, flight.csv and the pictures in `out`. The tests' and the
    benchmark's shorter, deterministic demo."""
    import time

    from swarm_proto import VehicleInfo

    from .story import fly_fast

    out.mkdir(parents=True, exist_ok=True)
    recorder = FlightRecorder(out / "flight.csv")
    homes: dict[int, GeoPoint] = {}
    base: list[GeoPoint] = []

    def heard(msg: object, now: float) -> None:
        if isinstance(msg, VehicleInfo) and msg.vehicle_id in plan.members:
            if msg.home is not None:
                homes[msg.vehicle_id] = msg.home
            if msg.base is not None:
                base[:] = [msg.base]
        recorder.handle(msg)

    wall0 = time.perf_counter()
    try:
        run = fly_fast(plan, profiles, on_message=heard, settings=settings, over_air=over_air)
    finally:
        recorder.close()
    meta = {
        "fast_time": True,
        "wall_s": round(time.perf_counter() - wall0, 1),
        "sim_s": round(run.duration_s, 1),
    }
    return build(
        out,
        plan=plan,
        record=run.story.record,
        flight_csv=out / "flight.csv",
        profiles=profiles,
        homes=homes,
        base=base[0] if base else None,
        meta=meta,
        pictures=pictures,
    )
