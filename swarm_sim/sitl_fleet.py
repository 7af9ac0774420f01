"""`make sitl-fleet`: the paper's experiment flown by several real ArduPilot SITL vehicles
at once (default two QuadPlanes and two copters), one `swarm-node run` each, a Zenoh
router and the ground station library, as a script with a PASS/FAIL row per step:

    up          every node's status matches its SITL (type, mode, armed, position)
    base        SET_BASE: every autopilot holds one rally point, on its own pad, safe
    zones       the no-fly zones: every autopilot's fence holds them, enabled
    survey      one area survey to all: accepted, every vehicle flies its share, the
                shares split (no two vehicles on the same lanes), the fleet agreed
    target      a camera reports a person: the vote sends two, they fly to it, the
                others re-split the area
    node kill   a surveying node SIGKILLed: its aircraft flies on (ArduPilot's
                positions), the survivors inherit its share
    finish      the survey completed; coverage from the tracks flown; the zones kept
                clear by each vehicle type's margin (QuadPlane 10 m, copter 2 m);
                no fence breached
    dead node's aircraft  the GCS failsafe its node set takes it home (RTL within
                the failsafe's 10 s and a margin), it lands on its own pad, and no
                peer came within 15 m of it from the kill to its landing
    landing     every vehicle landed on its own pad, neighbours in turn
    head-on     two vehicles at one altitude flown at each other (GOTO): avoidance
                keeps them apart
    separation  the whole run: no airborne pair under 10 m (danger) or 5 m (near)
    down        everything landed and disarmed

Every figure comes from ArduPilot's own positions (an observer on each SITL's
SERIAL1), never from the nodes' telemetry (sitl_figures.py). Times are simulated
seconds (wall seconds x speed-up) unless named `_wall_s`. The nodes (and swarm-sim
vehicles) run on one clock `--speedup` times faster than the wall clock, as SITL does.
Writes bench/results/sitl_fleet.json. `--sim` flies the same against swarm-sim
vehicles. docs/sitl.md tells how to build SITL and what fits on a machine.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import queue
import signal
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from rich.console import Console
from rich.table import Table

from swarm_node.core.margins import FIXED_WING_FLOWN_CLEARANCE_M, MULTIROTOR_FLOWN_CLEARANCE_M
from swarm_node.core.mission.tasking import target_mission_id
from swarm_node.core.planning import PlanVehicle
from swarm_node.core.planning.coverage import lane_spacing_m
from swarm_node.core.planning.fleet_plan import flyable, zone_margin_m
from swarm_node.core.planning.geo import LocalFrame
from swarm_node.database import seed_fleet
from swarm_proto import (
    AckRef,
    AlertCode,
    CommandArgs,
    CommandKind,
    Geometry,
    GeoPoint,
    Mission,
    MissionParams,
    MissionState,
    MissionType,
    NoFlyZone,
    Selector,
    TargetReport,
    TargetSource,
    VehicleStatus,
    VehicleType,
)
from swarm_proto.ardupilot import mode_number
from swarm_proto.clock import ScaledClock

from . import sitl_figures as fig
from .sitl_rig import HOME, Rig, Vehicle, copter, distance_m, quadplane

RESULTS = Path(__file__).resolve().parent.parent / "bench" / "results" / "sitl_fleet.json"
ROWS = (
    "up",
    "base",
    "zones",
    "survey",
    "target",
    "node kill",
    "finish",
    "dead node's aircraft",
    "landing",
    "head-on",
    "separation",
    "down",
)
ROW_TEXT = {
    "up": "every node's status matches its SITL",
    "base": "base -> each autopilot's rally point on its own pad",
    "zones": "zones -> every autopilot's fence, enabled",
    "survey": "area survey to all: split, flown, agreed",
    "target": "target report: vote, winners fly to it, others re-split",
    "node kill": "a node SIGKILLed: its aircraft flies on, survivors inherit",
    "finish": "survey complete: coverage, zone margins, no breach",
    "dead node's aircraft": "its failsafe takes it home to its own pad, no peer within 15 m",
    "landing": "landed on their own pads, in turn",
    "head-on": "head-on pair at one altitude: avoidance",
    "separation": "no airborne pair under 10 m (danger) / 5 m (near)",
    "down": "everything landed and disarmed",
}
GCS_ID = 900
AREA_ID = 301
TARGET_ID = 7
PAD_SPACING_M = 30.0  # the paper's pads, east of the base
# what each vehicle type keeps from a zone, as ArduPilot flies it (issue: QuadPlane 10 m)
ZONE_MARGIN_M = {
    "quadplane": FIXED_WING_FLOWN_CLEARANCE_M,
    "copter": MULTIROTOR_FLOWN_CLEARANCE_M,
}
SURVEY_ALT_M = 60.0
SURVEY_STEP_M = 10.0
SIDE_OVERLAP = 0.5
COVERAGE_MIN = 0.99
SPLIT_MAX = 0.10  # of the survey track length flown over another's lanes
HEAD_ON_ALT_M = 40.0
HEAD_ON_BEYOND_M = 200.0  # each is sent this far beyond the other
LANDED_ON_PAD_M = 10.0
DEAD_CLEAR_M = 15.0  # no peer this close to a dead node's aircraft (issue: 15 m)
FAILSAFE_MARGIN_S = 10.0  # beyond the node's FS timeout (10 s), simulated seconds
SEED_ROLES = {"quadplane": range(1, 7), "copter": range(7, 10)}  # seed database systems


@dataclass(frozen=True)
class Field:
    """The experiment's places, in metres east/north of the base (vehicle 1's pad)."""

    corners: tuple[tuple[float, float], ...] = ((-400, 300), (600, 300), (600, 900), (-400, 900))
    # one zone in the field, one beside the way to the target (the target's orbit, 150 m
    # round it, keeps clear of it)
    zones: tuple[tuple[float, float, float], ...] = ((200.0, 600.0, 40.0), (760.0, 480.0, 30.0))
    target: tuple[float, float] = (900.0, 700.0)
    # 1200 m apart: a circling QuadPlane predicted straight on (26 m/s, avoidance's 30 s
    # horizon) does not reach the other before they are sent at each other
    head_on: tuple[tuple[float, float], tuple[float, float]] = ((-600.0, 150.0), (600.0, 150.0))


def parse_vehicles(text: str) -> list[tuple[str, int]]:
    """ "quadplane:1,quadplane:2,copter:7,copter:8" -> [(kind, node id)]."""
    out: list[tuple[str, int]] = []
    for item in text.split(","):
        kind, _, vid = item.strip().partition(":")
        if kind not in SEED_ROLES:
            raise ValueError(f"{item!r}: a vehicle is quadplane:ID or copter:ID")
        try:
            n = int(vid)
        except ValueError:
            raise ValueError(f"{item!r}: the id must be a number") from None
        if n not in SEED_ROLES[kind]:
            ids = SEED_ROLES[kind]
            raise ValueError(f"{item!r}: a {kind} is one of the seed's systems {ids[0]}-{ids[-1]}")
        out.append((kind, n))
    if len(out) < 3:
        raise ValueError("a fleet is at least 3 vehicles")
    if len({n for _, n in out}) != len(out):
        raise ValueError("each vehicle once")
    return out


@dataclass
class Timeline:
    """The nodes' states as the ground station heard them (a recorder thread):
    per vehicle (wall time, mission_state, on the area survey) transitions."""

    states: dict[int, list[tuple[float, MissionState, int]]] = field(default_factory=dict)

    def note(self, t: float, s: VehicleStatus, mission_id: int) -> None:
        seq = self.states.setdefault(s.vehicle_id, [])
        key = (s.mission_state, mission_id)
        if not seq or (seq[-1][1], seq[-1][2]) != key:
            seq.append((t, s.mission_state, mission_id))

    def spans(self, vid: int, mission_id: int, end: float) -> list[tuple[float, float]]:
        """When the vehicle flew `mission_id` (MISSION state)."""
        out, start = [], None
        for t, st, mid in self.states.get(vid, []):
            on = st == MissionState.MISSION and mid == mission_id
            if on and start is None:
                start = t
            elif not on and start is not None:
                out.append((start, t))
                start = None
        if start is not None:
            out.append((start, end))
        return out

    def seen(self, vid: int, state: MissionState, since: float) -> float | None:
        return next(
            (t for t, st, _ in self.states.get(vid, []) if st == state and t >= since), None
        )


class FleetRun(Rig):
    prefix = "bandada-sitl-fleet-"

    def __init__(self, args: argparse.Namespace, console: Console) -> None:
        clock = ScaledClock(args.speedup).spec() if args.speedup != 1.0 else ""
        super().__init__(args, console, clock)
        self.field = Field()
        self.frame = LocalFrame(HOME[0], HOME[1])
        self.vehicles: dict[int, Vehicle] = {}
        self.rows: dict[str, tuple[bool, str]] = {}
        self.figures: dict[str, Any] = {}
        self.timeline = Timeline()
        self.marks: dict[str, float] = {}  # wall (monotonic) times of the script's steps
        self.killed: int | None = None
        self.winners: list[int] = []
        self.stayers: list[int] = []
        self.survivors: list[int] = []
        self.profiles = {p.vehicle_id: p for p in seed_fleet()}
        self._stop = threading.Event()
        self._recorder: threading.Thread | None = None

    # ----------------------------------------------------------------- places
    def geo(self, e: float, n: float) -> tuple[float, float]:
        return self.frame.to_geodetic(e, n)

    def zones(self) -> list[NoFlyZone]:
        return [
            NoFlyZone(
                k + 1,
                Geometry.circle(*self.geo(e, n), r),
                floor_alt_msl_m=-100.0,
                ceiling_alt_msl_m=1000.0,
                name=f"zone {k + 1}",
                issuer_id=GCS_ID,
            )
            for k, (e, n, r) in enumerate(self.field.zones)
        ]

    def sim_s(self, wall_s: float) -> float:
        return wall_s * self.args.speedup

    def wall_s(self, sim_s: float) -> float:
        return sim_s / self.args.speedup

    def profile(self, vid: int) -> Any:
        return self.profiles[vid]

    # ----------------------------------------------------------------- start
    def start(self) -> None:
        self.start_router()
        for i, (kind, vid) in enumerate(self.args.fleet):
            make = quadplane if kind == "quadplane" else copter
            spec = make(vid, self.args.first_instance + i, home_east_m=PAD_SPACING_M * i)
            self.vehicles[vid] = self.start_vehicle(spec, f"{kind}{vid}")
        if self.args.sim:
            for v in self.vehicles.values():
                self.attach(v)
        time.sleep(2.0)
        for v in self.vehicles.values():
            self.start_node(v)
        time.sleep(1.0)
        if not self.args.sim:
            for v in self.vehicles.values():
                self.attach(v)
        self.connect_ground()
        self._recorder = threading.Thread(target=self._record, daemon=True, name="recorder")
        self._recorder.start()

    def _record(self) -> None:
        feed = self.ground.status_feed()
        while not self._stop.is_set():
            try:
                s = feed.get(timeout=0.5)
            except queue.Empty:
                continue
            info = self.ground.snapshot().info.get(s.vehicle_id)
            self.timeline.note(time.monotonic(), s, info.mission_id if info else 0)

    def close(self) -> None:
        self._stop.set()
        if self._recorder is not None:
            self._recorder.join(2.0)
        self.close_vehicles(list(self.vehicles.values()))

    # ----------------------------------------------------------------- views
    def status(self, vid: int) -> VehicleStatus | None:
        return self.ground.snapshot().status.get(vid)

    def mission_of(self, vid: int) -> int:
        info = self.ground.snapshot().info.get(vid)
        return info.mission_id if info else 0

    def flying_share(self, vid: int, mid: int) -> bool:
        s = self.status(vid)
        return (
            s is not None
            and s.armed
            and s.mission_state == MissionState.MISSION
            and self.mission_of(vid) == mid
        )

    def alive(self) -> list[int]:
        return [v for v in self.vehicles if v != self.killed]

    def track(self, vid: int, since: float = 0.0) -> list[fig.Fix]:
        obs = self.vehicles[vid].observer
        assert obs is not None
        out = []
        for s in obs.since(since):
            e, n = self.frame.to_local(s.lat, s.lon)
            out.append(fig.Fix(s.t, e, n, s.alt_rel, s.alt_msl, s.armed))
        return out

    def pad(self, vid: int) -> tuple[float, float]:
        return self.frame.to_local(*self.vehicles[vid].home)

    def landed(self, vid: int) -> bool:
        obs = self.vehicles[vid].observer
        here = obs.here() if obs else None
        return bool(obs and here and not obs.armed and here.alt_rel < 2.0)

    def row(self, name: str, ok: bool, detail: str) -> None:
        self.rows[name] = (ok, detail)
        colour = "green" if ok else "red"
        self.console.print(f"[{colour}]{'PASS' if ok else 'FAIL'}[/] {name}: {detail}")

    def mark(self, name: str) -> float:
        self.marks[name] = t = time.monotonic()
        return t

    def sim_since(self, name: str, t: float | None = None) -> float:
        return round(self.sim_s((t if t is not None else time.monotonic()) - self.marks[name]), 1)

    # ----------------------------------------------------------------- steps
    def step_up(self) -> bool:
        self.log("waiting for every vehicle: a GPS fix, a home, ArduPilot's EKF on GPS")
        ids = list(self.vehicles)

        def ready() -> bool:
            v = self.ground.snapshot()
            for i in ids:
                s, info = v.status.get(i), v.info.get(i)
                if s is None or s.gps_fix < 3 or info is None or info.home is None:
                    return False
                obs = self.vehicles[i].observer
                if not self.args.sim and not (
                    obs and any("is using GPS" in t for _, t in obs.texts)
                ):
                    return False
            return True

        up = self.wait(ready, self.wall_s(400.0) + 60.0)
        time.sleep(self.wall_s(10.0))  # the EKF's origin, the nodes' readiness
        view = self.ground.snapshot()
        problems = []
        for vid, v in self.vehicles.items():
            st, info, obs = view.status.get(vid), view.info.get(vid), v.observer
            here = obs.here() if obs else None
            if st is None or info is None or here is None or obs is None:
                problems.append(f"{vid}: not heard")
                continue
            d = distance_m(st.lat_deg, st.lon_deg, here.lat, here.lon)
            if info.vehicle_type != v.spec.vehicle_type:
                problems.append(f"{vid}: type {info.vehicle_type.name}")
            if st.ap_mode != obs.mode or st.armed != obs.armed or d > 5.0:
                problems.append(f"{vid}: mode {st.ap_mode}/{obs.mode} {d:.1f} m off")
        ok = up and not problems
        self.row("up", ok, "; ".join(problems) or f"{len(ids)} vehicles ready")
        return ok

    def step_base(self) -> None:
        base = GeoPoint(HOME[0], HOME[1], HOME[2])
        acks = self.ground.command(
            CommandKind.SET_BASE, Selector(), CommandArgs(point=base), timeout_s=30.0
        )
        answered = {a.vehicle_id: a for a in acks}
        time.sleep(2.0)
        problems, alts = [], []
        for vid, v in self.vehicles.items():
            a = answered.get(vid)
            assert v.downloader is not None
            items = None
            for _ in range(5):
                items = v.downloader.download(2)
                if items:
                    break
                time.sleep(2.0)
            if a is None or not a.accepted:
                problems.append(f"{vid}: SET_BASE {a.reason.name if a else 'no answer'}")
            elif not items or len(items) != 1:
                problems.append(f"{vid}: {len(items or [])} rally points")
            else:
                item = items[0]
                alt = float(item.z) - (HOME[2] if item.frame in (0, 5) else 0.0)
                d = distance_m(item.x / 1e7, item.y / 1e7, *v.home)
                alts.append(alt)
                if d > 2.0 or alt < 15.0:
                    problems.append(f"{vid}: rally {d:.1f} m from its pad, {alt:.0f} m up")
        self.row(
            "base",
            not problems,
            "; ".join(problems)
            or f"each on its own pad, {min(alts):.0f}-{max(alts):.0f} m above home",
        )

    def step_zones(self) -> None:
        zones = self.zones()
        t0 = time.monotonic()
        held: dict[int, set[int]] = {}
        for z in zones:
            held[z.zone_id] = set(self.ground.declare_zone(z, timeout_s=30.0))
        self.wait(
            lambda: all(
                v.observer is not None and v.observer.fence_enabled for v in self.vehicles.values()
            ),
            30.0,
        )
        time.sleep(2.0)
        problems = []
        for vid, v in self.vehicles.items():
            assert v.downloader is not None and v.observer is not None
            items = v.downloader.download(1) or []
            circles = [i for i in items if i.command == 5004]
            missing = [z.zone_id for z in zones if vid not in held[z.zone_id]]
            if missing or len(circles) != len(zones) or not v.observer.fence_enabled:
                problems.append(
                    f"{vid}: not held {missing}, {len(circles)} circles, "
                    f"fence {'on' if v.observer.fence_enabled else 'off'}"
                )
        self.figures["fence_enabled_wall_s"] = round(time.monotonic() - t0, 1)
        self.row(
            "zones",
            not problems,
            "; ".join(problems) or f"{len(zones)} exclusion circles on every autopilot, enabled",
        )

    def area_mission(self) -> Mission:
        return Mission(
            AREA_ID,
            GCS_ID,
            MissionType.AREA,
            Geometry.polygon([self.geo(e, n) for e, n in self.field.corners]),
            MissionParams(
                altitude_rel_m=SURVEY_ALT_M,
                side_overlap=SIDE_OVERLAP,
                altitude_step_m=SURVEY_STEP_M,
            ),
            Selector.ids(*self.vehicles),
            "sitl fleet survey",
            self.node_now(),
        )

    def step_survey(self) -> bool:
        ids = list(self.vehicles)
        self.log(f"area survey to {ids} ({SURVEY_ALT_M:g} m, {SURVEY_STEP_M:g} m layers)")
        t0 = self.mark("survey sent")
        acks = {a.vehicle_id: a for a in self.ground.mission(self.area_mission(), timeout_s=30.0)}
        refused = [f"{v}: {a.reason.name} {a.text}" for v, a in acks.items() if not a.accepted]
        if refused or set(acks) != set(ids):
            self.row("survey", False, "; ".join(refused) or f"answers from {sorted(acks)}")
            return False

        def agreed() -> bool:
            v = self.ground.snapshot()
            hashes = {v.info[i].members_hash for i in ids if i in v.info}
            return len(hashes) == 1 and 0 not in hashes and len(v.info) >= len(ids)

        agree = self.wait(agreed, self.wall_s(300.0))
        t_agree = time.monotonic()

        def started() -> list[float]:
            """When each vehicle began flying its share (the take-offs go in turn)."""
            now = time.monotonic()
            firsts = [self.timeline.spans(v, AREA_ID, now) for v in ids]
            return [f[0][0] for f in firsts if f]

        flying = self.wait(lambda: len(started()) == len(ids), self.wall_s(900.0))
        t_fly = max(started(), default=time.monotonic())
        self.marks["survey flying"] = t_fly
        self.figures["agreement_s"] = {
            "survey_roster": round(self.sim_s(t_agree - t0), 1) if agree else None,
            "survey_all_flying": round(self.sim_s(t_fly - t0), 1) if flying else None,
        }
        ok = agree and flying
        detail = (
            f"roster agreed {self.sim_s(t_agree - t0):.0f} s, the last to take off on its "
            f"share {self.sim_s(t_fly - t0):.0f} s after the mission"
            if ok
            else f"agreed {agree}, {len(started())} of {len(ids)} flew their shares"
        )
        self.rows["survey"] = (ok, detail)  # the split is judged at the report (step_target)
        return ok

    def step_target(self) -> bool:
        p = self.args
        ids = list(self.vehicles)

        def progress() -> int:
            """The survey's progress while every vehicle flies its share (the least of
            theirs; -1 while one is not on it: a vote among vehicles some of which have
            finished their shares leaves those nothing to re-split)."""
            if not all(self.flying_share(v, AREA_ID) for v in ids):
                return -1
            return min(self.status(v).mission_progress_pct for v in ids)  # type: ignore[union-attr]

        self.wait(lambda: progress() >= p.target_at_pct, self.wall_s(1200.0), 0.5)
        t_report = self.mark("report")
        self._judge_split(self.marks["survey flying"], t_report)
        reporter = ids[len(ids) // 2]
        te, tn = self.field.target
        lat, lon = self.geo(te, tn)
        report = TargetReport(
            TARGET_ID,
            reporter,
            TargetSource.PAYLOAD,
            self.node_now(),
            GeoPoint(lat, lon, 0.0),
            "person",
            0.93,
        )
        mid = target_mission_id(reporter, TARGET_ID)
        self.log(f"vehicle {reporter}'s camera reports a person at {te:.0f} E {tn:.0f} N")

        def chosen() -> list[int]:
            return [v for v in ids if self.mission_of(v) == mid]

        end = time.monotonic() + 30.0
        while time.monotonic() < end:  # repeated until answered (a repeat is the same target)
            self.ground.bus.publish(report)
            got = {
                a.vehicle_id
                for a in self.ground.snapshot().acks
                if a.ref == AckRef.MISSION and a.ref_id == mid
            }
            if set(ids) <= got or len(chosen()) >= 2:
                break
            self.wait(lambda: len(chosen()) >= 2, 1.0, 0.05)

        voted = self.wait(lambda: len(chosen()) >= 2, self.wall_s(300.0))
        t_vote = self.mark("voted")
        self.winners = chosen()
        self.stayers = [v for v in ids if v not in self.winners]
        self.log(f"voted to the target: {self.winners}; {self.stayers} re-split the area")
        resplit = self.wait(
            lambda: all(
                self.timeline.seen(v, MissionState.REPLAN, t_report) is not None
                and self.flying_share(v, AREA_ID)
                for v in self.stayers
            ),
            self.wall_s(400.0),
        )
        t_resplit = self.mark("resplit")
        radius = 150.0

        def at_target(v: int) -> bool:
            tr = self.track(v, t_vote)
            return any(math.hypot(f.e - te, f.n - tn) < radius + 60.0 for f in tr)

        there = self.wait(lambda: all(at_target(v) for v in self.winners), self.wall_s(400.0))
        self.figures["agreement_s"] |= {
            "vote": round(self.sim_s(t_vote - t_report), 1) if voted else None,
            "resplit": round(self.sim_s(t_resplit - t_vote), 1) if resplit else None,
        }
        ok = voted and resplit and there and len(self.winners) == 2
        self.row(
            "target",
            ok,
            f"winners {self.winners} chosen {self.sim_s(t_vote - t_report):.0f} s after the "
            f"report, {'at' if there else 'not at'} the target; stayers {self.stayers} "
            f"re-split {'in ' + format(self.sim_s(t_resplit - t_vote), '.0f') + ' s' if resplit else 'no'}",
        )
        return ok

    def _judge_split(self, t0: float, t1: float) -> None:
        """The survey row's split: survey tracks flown before the report."""
        ok0, detail = self.rows.get("survey", (False, ""))
        stretches = {v: fig.within(self.track(v, t0), [(t0, t1)]) for v in self.vehicles}
        twice = fig.flown_twice(stretches, self.spacing_m())
        self.figures["flown_twice_before_report"] = round(twice, 4)
        ok = ok0 and twice <= SPLIT_MAX
        self.row("survey", ok, f"{detail}; {twice:.1%} of the tracks on another's lanes")

    def spacing_m(self) -> float:
        """The survey's lane spacing (the narrowest camera at the lowest layer)."""
        out = []
        for v in self.vehicles:
            cam = self.profile(v).camera
            if cam is not None:
                out.append(lane_spacing_m(SURVEY_ALT_M, cam.hfov_deg, SIDE_OVERLAP))
        return min(out) if out else 40.0

    def step_kill(self) -> bool:
        time.sleep(self.wall_s(self.args.fail_after))
        copters = [v for v in self.stayers if self.vehicles[v].spec.kind == "copter"]
        victim = self.args.victim or max(copters or self.stayers)
        self.killed = victim
        self.survivors = [v for v in self.stayers if v != victim]
        node = self.vehicles[victim].node
        assert node is not None
        self.log(f"node {victim} SIGKILLed: its aircraft flies on; {self.survivors} inherit")
        t_kill = self.mark("kill")
        os.kill(node.pid, signal.SIGKILL)
        inherited = self.wait(
            lambda: all(
                self.timeline.seen(v, MissionState.REPLAN, t_kill) is not None
                and self.flying_share(v, AREA_ID)
                for v in self.survivors
            ),
            self.wall_s(400.0),
        )
        t_inh = self.mark("inherited")
        time.sleep(max(0.0, self.wall_s(30.0) - (time.monotonic() - t_kill)))
        after = [f for f in self.track(victim, t_kill) if f.t <= t_kill + self.wall_s(30.0)]
        moved = (
            math.hypot(after[-1].e - after[0].e, after[-1].n - after[0].n)
            if len(after) > 1
            else 0.0
        )
        flew_on = bool(after) and all(f.armed for f in after) and moved > 30.0
        self.figures["agreement_s"]["inherit"] = (
            round(self.sim_s(t_inh - t_kill), 1) if inherited else None
        )
        ok = flew_on and inherited and bool(self.survivors)
        self.row(
            "node kill",
            ok,
            f"node {victim} killed: its aircraft {'flew on' if flew_on else 'did not fly on'} "
            f"({moved:.0f} m in 30 s); survivors {self.survivors} "
            + (
                f"inherited in {self.sim_s(t_inh - t_kill):.0f} s"
                if inherited
                else "did not inherit"
            ),
        )
        return ok

    def step_finish(self) -> None:
        alive = self.alive()
        done = self.wait(
            lambda: (
                all(
                    self.alerts_of(v, AlertCode.MISSION_COMPLETE, "survey sent")
                    for v in self.survivors
                )
                and all(self.landed(v) for v in alive)
            ),
            self.wall_s(2400.0),
            1.0,
        )
        t_done = self.mark("finished")
        # coverage: what the swarm's plan flew (the victim's aircraft until its node died)
        # of the coverable area: the field less the zones and the margin the fleet's
        # plan keeps from them (its widest vehicle's: lanes stop there)
        margin = zone_margin_m([PlanVehicle(flyable(self.profile(v))) for v in self.vehicles])
        inflated = [(e, n, r + margin) for e, n, r in self.field.zones]
        field_poly = fig.field_polygon(self.field.corners)
        region = fig.coverable(field_poly, inflated)
        stretches = {}
        hfov = {}
        for v in self.vehicles:
            end = self.marks["kill"] if v == self.killed else t_done
            spans = [(a, min(b, end)) for a, b in self.timeline.spans(v, AREA_ID, end)]
            stretches[v] = fig.within(self.track(v), spans)
            cam = self.profile(v).camera
            hfov[v] = cam.hfov_deg if cam else 60.0
        cover = fig.coverage(stretches, hfov, region)
        cover_all = fig.coverage(stretches, hfov, fig.coverable(field_poly, self.field.zones))
        # the dead node's aircraft flew lanes the survivors were given again
        t_kill = self.marks["kill"]
        after = {v: fig.within(self.track(v), [(t_kill, t_done)]) for v in self.survivors}
        if self.killed is not None:
            after[self.killed] = fig.within(self.track(self.killed), [(t_kill, t_done)])
        twice_after = fig.flown_twice(after, self.spacing_m())
        clear: dict[int, float | None] = {}
        breaches = 0
        for v in self.vehicles:
            tr = self.track(v)
            clear[v] = fig.zone_clearance(tr, self.field.zones)
            breaches += fig.inside_zones(tr, self.field.zones)
            obs = self.vehicles[v].observer
            assert obs is not None
            breaches += sum(1 for _, t in obs.texts if "ence" in t and "reach" in t)
            breaches += len(self.alerts_of(v, AlertCode.GEOFENCE_BREACH, "survey sent"))
        self.figures |= {
            "coverage": round(cover, 4),
            "coverable_m2": round(region.area),
            "plan_zone_margin_m": round(margin, 1),
            "coverage_of_field_outside_zones": round(cover_all, 4),
            "flown_twice_after_kill": round(twice_after, 4),
            "fence_breaches": breaches,
            "min_zone_clearance_m": {
                str(v): None if c is None else round(c, 2) for v, c in clear.items()
            },
        }
        short = [
            f"{v} {c:.1f} m"
            for v, c in clear.items()
            if c is not None and c < ZONE_MARGIN_M[self.vehicles[v].spec.kind]
        ]
        ok = done and cover >= COVERAGE_MIN and not short and breaches == 0
        margins = ", ".join(f"{v} {c:.1f}" for v, c in clear.items() if c is not None)
        self.row(
            "finish",
            ok,
            f"{'complete' if done else 'not complete'}; coverage {cover:.1%}; zone clearance "
            f"(m) {margins}{' under the margin: ' + ', '.join(short) if short else ''}; "
            f"{breaches} breaches",
        )

    def alerts_of(self, vid: int, code: AlertCode, since_mark: str) -> list[Any]:
        since = self.marks[since_mark]
        since_unix = self.node_now() - self.sim_s(time.monotonic() - since)
        return self.alerts(vid, code, since_unix)

    def step_dead_aircraft(self) -> None:
        """The dead node's aircraft, from ArduPilot's own positions and modes: the GCS
        failsafe its node set (docs/reliability.md: RTL 10 s after the node's last
        HEARTBEAT) takes it home, it lands on its own pad, and no survivor comes within
        15 m of it meanwhile. An operator's RTL straight to its autopilot brings it down
        only when the failsafe did not (the row fails)."""
        vid = self.killed
        if vid is None:
            self.row("dead node's aircraft", False, "no node was killed")
            return
        v = self.vehicles[vid]
        obs = v.observer
        assert obs is not None
        t_kill = self.marks["kill"]
        vt = v.spec.vehicle_type
        names = {
            VehicleType.COPTER: ("RTL", "LAND"),
            VehicleType.VTOL: ("RTL", "QRTL", "QLAND"),
        }.get(vt, ("RTL",))
        home_modes = {mode_number(vt, n) for n in names}
        down = self.wait(lambda: self.landed(vid), self.wall_s(900.0), 1.0)
        t_down = time.monotonic()
        fs = next(((t, m) for t, m in list(obs.modes) if t >= t_kill and m in home_modes), None)
        fs_s = self.sim_s(fs[0] - t_kill) if fs else None
        by_failsafe = fs_s is not None and fs_s <= 10.0 + FAILSAFE_MARGIN_S
        if not down:
            self.log(f"operator: RTL straight to vehicle {vid}'s autopilot (its failsafe did not)")
            down = self.bring_down(vid)
            t_down = time.monotonic()
        here = obs.here()
        d = distance_m(here.lat, here.lon, *v.home) if here else math.inf
        peers = {u: self.track(u) for u in self.vehicles if u != vid}
        seps = [
            s
            for s in fig.separations({vid: self.track(vid)} | peers, t_kill, t_down)
            if vid in (s.a, s.b)
        ]
        closest = min((s.min_m for s in seps), default=math.inf)
        self.figures["dead_aircraft_failsafe_s"] = None if fs_s is None else round(fs_s, 1)
        self.figures["dead_aircraft_from_pad_m"] = round(d, 1)
        self.figures["dead_aircraft_closest_peer_m"] = (
            None if math.isinf(closest) else round(closest, 1)
        )
        ok = by_failsafe and down and d < LANDED_ON_PAD_M and closest >= DEAD_CLEAR_M
        self.row(
            "dead node's aircraft",
            ok,
            (f"failsafe home {fs_s:.0f} s after the kill" if fs_s is not None else "no failsafe")
            + f"; {'landed' if down else 'not landed'} {d:.1f} m from its own pad; closest "
            + ("peer: none airborne" if math.isinf(closest) else f"peer {closest:.1f} m"),
        )

    def _near_pad(self, vid: int, r: float) -> bool:
        obs = self.vehicles[vid].observer
        h = obs.here() if obs else None
        return h is not None and distance_m(h.lat, h.lon, *self.vehicles[vid].home) < r

    def step_landing(self) -> None:
        t0 = self.marks.get("survey flying", self.marks["survey sent"])
        t1 = time.monotonic()
        pads = {v: self.pad(v) for v in self.vehicles}
        problems, dist = [], {}
        for v in self.vehicles:
            tr = self.track(v, t0)
            last = tr[-1] if tr else None
            if last is None or last.armed or last.alt_rel > 2.0:
                problems.append(f"{v}: not down")
                continue
            near = min(pads, key=lambda p: math.dist(pads[p], (last.e, last.n)))
            dist[v] = math.dist(pads[v], (last.e, last.n))
            if near != v or dist[v] > LANDED_ON_PAD_M:
                problems.append(f"{v}: {dist[v]:.1f} m from its pad (on {near}'s)")
        tracks = {v: self.track(v, t0) for v in self.vehicles}
        together = fig.simultaneous_low(tracks, pads, t0, t1)
        problems += [f"{a}+{b} low together {self.sim_s(s):.0f} s" for a, b, s in together]
        self.figures["landed_from_pad_m"] = {str(v): round(d, 1) for v, d in dist.items()}
        self.row(
            "landing",
            not problems,
            "; ".join(problems)
            or "each on its own pad ("
            + ", ".join(f"{v} {d:.1f} m" for v, d in dist.items())
            + "), in turn",
        )

    def step_head_on(self) -> None:
        """Two vehicles take off, go to points either side of the pads, then each is
        sent to a point beyond the other on the line through both, at one altitude."""
        alive = self.alive()
        if self.args.head_on:
            pair = list(self.args.head_on)
        else:
            planes = [v for v in alive if self.vehicles[v].spec.kind == "quadplane"]
            copters = [v for v in alive if self.vehicles[v].spec.kind == "copter"]
            pair = (planes[:1] + copters[:1]) if planes and copters else alive[:2]
        a, b = pair
        self.log(f"head-on: {a} and {b} take off to {HEAD_ON_ALT_M:g} m")
        steps: list[str] = []
        for v in pair:
            for kind, args in (
                (CommandKind.SET_MODE, {"text": "GUIDED"}),
                (CommandKind.ARM, {}),
                (CommandKind.TAKEOFF, {"value": HEAD_ON_ALT_M}),
            ):
                ok, text = self.command_ids(kind, v, **args)
                if not ok:
                    steps.append(f"{v} {text}")
                    break
        if steps:
            self.row("head-on", False, "; ".join(steps))
            return
        self.wait(lambda: all(self._alt(v) > HEAD_ON_ALT_M - 8.0 for v in pair), self.wall_s(180.0))
        (we, wn), (ee, en) = self.field.head_on
        start = {a: (we, wn), b: (ee, en)}
        for v in pair:
            self.goto(v, start[v])
        self.wait(
            lambda: all(math.dist(self._local(v), start[v]) < 150.0 for v in pair),
            self.wall_s(300.0),
        )
        # a circling fixed-wing is sent when it heads at the other: it then flies the
        # line through both (sent from elsewhere on its circle it turns onto a parallel
        # line, 46 m aside)
        self.wait(
            lambda: self._heading_at(a, b) < 20.0 and self._heading_at(b, a) < 20.0,
            self.wall_s(120.0),
            0.05,
        )
        pa, pb = self._local(a), self._local(b)
        d = math.dist(pa, pb) or 1.0
        ux, uy = (pb[0] - pa[0]) / d, (pb[1] - pa[1]) / d
        goal = {
            a: (pb[0] + ux * HEAD_ON_BEYOND_M, pb[1] + uy * HEAD_ON_BEYOND_M),
            b: (pa[0] - ux * HEAD_ON_BEYOND_M, pa[1] - uy * HEAD_ON_BEYOND_M),
        }
        self.log(
            f"head-on: {a} and {b}, {d:.0f} m apart, sent at each other at {HEAD_ON_ALT_M:g} m"
        )
        t0 = self.mark("head-on")
        sent = [self.goto(v, goal[v]) for v in pair]
        self.figures["head_on_goto"] = sent

        def passed() -> bool:
            """Each is beyond where the other is (on the line through both)."""
            qa, qb = self._local(a), self._local(b)
            along_a = (qa[0] - pa[0]) * ux + (qa[1] - pa[1]) * uy
            along_b = (qb[0] - pa[0]) * ux + (qb[1] - pa[1]) * uy
            return along_a > along_b + 50.0

        crossed = self.wait(passed, self.wall_s(300.0))
        t1 = time.monotonic()
        (sep,) = fig.separations({a: self.track(a, t0), b: self.track(b, t0)}, t0, t1)
        self.figures["head_on"] = {
            "pair": [a, b],
            "apart_at_start_m": round(d, 1),
            "crossed": crossed,
            "min_separation_m": None if math.isinf(sep.min_m) else round(sep.min_m, 1),
            "horizontal_m": None if sep.horizontal_m is None else round(sep.horizontal_m, 1),
            "vertical_m": None if sep.vertical_m is None else round(sep.vertical_m, 1),
        }
        home = all([self.bring_down(v) for v in pair])
        ok = crossed and sep.min_m >= fig.DANGER_M and home
        self.row(
            "head-on",
            ok,
            f"{a} and {b} from {d:.0f} m apart: {'crossed' if crossed else 'did not cross'}, "
            f"least {sep.min_m:.1f} m ({sep.horizontal_m or 0:.1f} m apart, "
            f"{sep.vertical_m or 0:.1f} m above); {'home and down' if home else 'not down'}",
        )

    def goto(self, vid: int, at: tuple[float, float]) -> str:
        """GOTO through the node, again while refused (a manoeuvre holding control
        refuses the operator's: "preempted by AVOIDANCE"), at most 5 times."""
        text = ""
        for _ in range(5):
            ok, text = self.command_ids(CommandKind.GOTO, vid, point=self._point(*at))
            if ok:
                return text
            time.sleep(1.0)
        return text

    def _heading_at(self, vid: int, other: int) -> float:
        """Degrees between `vid`'s course over the last second and the bearing to
        `other` (180 when not known, 0 for a vehicle hovering still)."""
        tr = self.track(vid, time.monotonic() - 1.5)
        if len(tr) < 2:
            return 180.0
        de, dn = tr[-1].e - tr[0].e, tr[-1].n - tr[0].n
        if math.hypot(de, dn) < 2.0:
            return 0.0
        oe, on = self._local(other)
        want = math.atan2(oe - tr[-1].e, on - tr[-1].n)
        have = math.atan2(de, dn)
        return abs(math.degrees((want - have + math.pi) % (2 * math.pi) - math.pi))

    def _local(self, vid: int) -> tuple[float, float]:
        o = self.vehicles[vid].observer
        h = o.here() if o else None
        return self.frame.to_local(h.lat, h.lon) if h else (math.nan, math.nan)

    def _alt(self, vid: int) -> float:
        o = self.vehicles[vid].observer
        h = o.here() if o else None
        return h.alt_rel if h else 0.0

    def bring_down(self, vid: int) -> bool:
        """Home and landed, commanded straight to its autopilot as an operator's own
        ground station would: RTL, and QRTL for a QuadPlane (its RTL circles the rally
        point for good with Q_RTL_MODE 0; QRTL flies to it and lands there vertically;
        a QLAND over the pad lands where it is on its circle, 77 m off). True when down."""
        if self.landed(vid):
            return True
        v = self.vehicles[vid]
        obs = v.observer
        assert obs is not None
        vt = v.spec.vehicle_type
        mode = mode_number(vt, "QRTL" if vt == VehicleType.VTOL else "RTL")
        for _ in range(5):
            obs.set_mode(mode)
            if self.wait(lambda: obs.mode == mode, 3.0):
                break
        return self.wait(lambda: self.landed(vid), self.wall_s(600.0), 1.0)

    def _point(self, e: float, n: float) -> GeoPoint:
        lat, lon = self.geo(e, n)
        return GeoPoint(lat, lon, HOME[2] + HEAD_ON_ALT_M)

    def step_separation(self, t_start: float) -> None:
        seps = fig.separations({v: self.track(v) for v in self.vehicles}, t_start, time.monotonic())
        finite = [s for s in seps if not math.isinf(s.min_m)]
        danger = [s for s in finite if s.min_m < fig.DANGER_M]
        near = [s for s in finite if s.min_m < fig.NEAR_M]
        self.figures |= {
            "danger": len(danger),
            "near": len(near),
            "min_separation_m": {
                f"{s.a}-{s.b}": None if math.isinf(s.min_m) else round(s.min_m, 1) for s in seps
            },
        }
        least = min(finite, key=lambda s: s.min_m) if finite else None
        self.row(
            "separation",
            not danger,
            f"{len(danger)} danger, {len(near)} near; least "
            + (f"{least.min_m:.1f} m ({least.a}-{least.b})" if least else "-"),
        )

    def step_down(self) -> None:
        for v in self.vehicles:  # a vehicle still up (a step that failed) is brought down
            if not self.landed(v):
                self.bring_down(v)
        down = all(self.landed(v) for v in self.vehicles)
        self.row(
            "down",
            down,
            "every vehicle on the ground, disarmed"
            if down
            else f"still up: {[v for v in self.vehicles if not self.landed(v)]}",
        )

    # ----------------------------------------------------------------- all
    def _guarded(self, row: str, step: Callable[[], object]) -> object:
        try:
            return step()
        except Exception as exc:
            self.console.print_exception()
            self.rows.setdefault(row, (False, f"error: {exc}"[:160]))
            return None

    def run_all(self) -> None:
        self.start()
        t_start = time.monotonic()
        if not self._guarded("up", self.step_up):
            return
        self._guarded("base", self.step_base)
        self._guarded("zones", self.step_zones)
        if (
            self._guarded("survey", self.step_survey)
            and self._guarded("target", self.step_target) is not None
        ):
            self._guarded("node kill", self.step_kill)
            self._guarded("finish", self.step_finish)
        self._guarded("dead node's aircraft", self.step_dead_aircraft)
        self._guarded("landing", self.step_landing)
        self._guarded("head-on", self.step_head_on)
        self._guarded("separation", lambda: self.step_separation(t_start))
        self._guarded("down", self.step_down)
        speeds = [s for v in self.vehicles.values() if v.observer and (s := v.observer.speedup())]
        self.figures["speedup_measured"] = round(min(speeds), 2) if speeds else None
        self.figures["wall_s"] = round(time.monotonic() - t_start)


def table(run: FleetRun) -> Table:
    t = Table(title=f"sitl-fleet ({len(run.vehicles)} vehicles)")
    t.add_column("step")
    t.add_column("result")
    for r in ROWS:
        got = run.rows.get(r)
        if got is None:
            t.add_row(ROW_TEXT[r], "[yellow]not run[/]")
        else:
            ok, detail = got
            t.add_row(ROW_TEXT[r], f"[green]PASS[/] {detail}" if ok else f"[red]FAIL[/] {detail}")
    return t


def results(run: FleetRun) -> dict[str, Any]:
    from datetime import UTC, datetime

    a = run.args
    out: dict[str, Any] = {
        "_meta": {
            "command": "make sitl-fleet" + (f" SITL_ARGS='{' '.join(a.argv)}'" if a.argv else ""),
            "date_utc": datetime.now(UTC).isoformat(timespec="seconds"),
        },
        "target": "swarm-sim" if a.sim else "ardupilot-sitl",
        "ardupilot": {}
        if a.sim
        else {
            str(vid): (v.observer.version if v.observer else "") for vid, v in run.vehicles.items()
        },
        "speedup": a.speedup,
        "times": "simulated seconds (wall x speed-up) unless _wall_s",
        "vehicles": {
            str(vid): {"kind": v.spec.kind, "pad_east_m": round(run.pad(vid)[0], 1)}
            for vid, v in run.vehicles.items()
        },
        "killed": run.killed,
        "winners": run.winners,
        "survivors": run.survivors,
        "steps": {
            r: {"pass": run.rows[r][0], "detail": run.rows[r][1]}
            if r in run.rows
            else {"pass": False, "detail": "not run"}
            for r in ROWS
        },
        "figures": run.figures,
    }
    out["passed"] = all(s["pass"] for s in out["steps"].values())
    return out


def _interrupt(signum: int, frame: object) -> None:
    raise KeyboardInterrupt


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(
        prog="python -m swarm_sim.sitl_fleet", description=__doc__.split("\n")[0]
    )
    p.add_argument(
        "--bin",
        default=os.environ.get("ARDUPILOT_SITL_BIN", ""),
        help="directory with arducopter and arduplane (default $ARDUPILOT_SITL_BIN)",
    )
    p.add_argument("--sim", action="store_true", help="swarm-sim vehicles instead of SITL")
    p.add_argument(
        "--vehicles",
        default="quadplane:1,quadplane:2,copter:7,copter:8",
        help="KIND:ID,... (quadplane 1-6, copter 7-9: the seed database's systems), >= 3",
    )
    p.add_argument("--speedup", type=float, default=2.0, help="SITL's, and the nodes' clock")
    p.add_argument("--first-instance", type=int, default=0, help="SITL -I of the first vehicle")
    p.add_argument(
        "--target-at-pct", type=int, default=10, help="survey progress at the report (all flying)"
    )
    p.add_argument("--fail-after", type=float, default=40.0, help="s of re-split before the kill")
    p.add_argument("--victim", type=int, default=0, help="whose node is killed (0: a stayer)")
    p.add_argument(
        "--head-on", default="", help="A,B: the head-on pair (default: a QuadPlane, a copter)"
    )
    p.add_argument("--out", default=str(RESULTS))
    p.add_argument("--keep", action="store_true", help="keep the logs directory")
    args = p.parse_args(argv)
    args.argv = list(argv if argv is not None else sys.argv[1:])
    console = Console() if sys.stdout.isatty() else Console(width=200)
    if not args.sim and not args.bin:
        console.print("[red]sitl-fleet: set ARDUPILOT_SITL_BIN (see docs/sitl.md) or use --sim[/]")
        return 2
    try:
        args.fleet = parse_vehicles(args.vehicles)
        args.head_on = tuple(int(x) for x in args.head_on.split(",")) if args.head_on else ()
    except ValueError as exc:
        console.print(f"[red]sitl-fleet: {exc}[/]")
        return 2
    ids = [v for _, v in args.fleet]
    if args.head_on and (len(args.head_on) != 2 or not set(args.head_on) <= set(ids)):
        console.print("[red]sitl-fleet: --head-on is two of the fleet's ids[/]")
        return 2
    if not args.speedup > 0:
        console.print("[red]sitl-fleet: --speedup must be positive[/]")
        return 2
    run = FleetRun(args, console)
    # a SIGTERM (a background job never gets SIGINT) stops it the same way: the
    # processes stopped, what was measured written
    signal.signal(signal.SIGTERM, _interrupt)
    try:
        run.run_all()
    except KeyboardInterrupt:
        console.print("[yellow]interrupted[/]")
    finally:
        run.close()
    console.print(table(run))
    out = results(run)
    path = Path(args.out)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(out, indent=2) + "\n")
    console.print(f"wrote {path}; logs in {run.tmp}")
    if not args.keep and out["passed"]:
        import shutil

        shutil.rmtree(run.tmp, ignore_errors=True)
    console.print("[bold green]PASS[/]" if out["passed"] else "[bold red]FAIL[/]")
    return 0 if out["passed"] else 1


if __name__ == "__main__":
    sys.exit(main())
