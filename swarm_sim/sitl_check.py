"""`make sitl-check`: bandada against real ArduPilot SITL, as a new user would run it.

Starts ArduCopter (`--model +`, instance 0, tcp 5760) and an ArduPlane QuadPlane
(`--model quadplane`, instance 1, tcp 5770) from `ARDUPILOT_SITL_BIN` with the default
parameter files of the ArduPilot tree, a Zenoh router (`swarm-node router`) and one
`swarm-node run` per vehicle, then drives them with the ground station library and
checks, per vehicle type, against what ArduPilot itself reports on a second and third
MAVLink port of each SITL (SERIAL1 +2: telemetry, SERIAL2 +3: mission downloads):

- status: the node's VehicleStatus matches SITL (type, mode, armed, position)
- rally: SET_BASE -> the rally point ArduPilot holds: its own pad, at a safe altitude
- fence: a zone -> ArduPilot's fence holds it, enabled, with no failed enable
- survey: an area survey around the zone flown with no breach (least clearance from
  the track ArduPilot reports at 10 Hz)
- way home: after the survey, the way home flown, landed, disarmed
- rtl/land: GUIDED, arm, take-off, then `rtl` and `land` commands obeyed
- link loss: SITL frozen (SIGSTOP) -> the node reports AUTOPILOT_LINK_LOSS; back after
  SIGCONT

It prints a PASS/FAIL table and writes bench/results/sitl.json. `--sim` runs the same
against swarm-sim vehicles (no ArduPilot needed). The processes, the observers and the
downloaders are sitl_rig.py's (shared with `make sitl-fleet`). Times (`*_s`) are wall seconds
(SITL runs `--speedup` times faster than real time). docs/sitl.md tells how to build
SITL.
"""

from __future__ import annotations

import argparse
import contextlib
import functools
import json
import os
import signal
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from rich.console import Console
from rich.table import Table

from swarm_node.core.margins import FIXED_WING_FLOWN_CLEARANCE_M, MULTIROTOR_FLOWN_CLEARANCE_M
from swarm_proto import (
    Ack,
    AlertCode,
    AlertFlag,
    CommandArgs,
    CommandKind,
    GeoPoint,
    Mission,
    MissionParams,
    MissionType,
    NoFlyZone,
    Selector,
)

from .sitl_rig import HOME, SWARM, Rig, Vehicle, copter, distance_m, quadplane
from .sitl_rig import opt as _opt

# what each vehicle type keeps from the zone as ArduPilot flies it (swarm_node margins)
ZONE_CLEARANCE_M = {
    "copter": MULTIROTOR_FLOWN_CLEARANCE_M,
    "quadplane": FIXED_WING_FLOWN_CLEARANCE_M,
}
WAY_HOME_WAIT_S = 120.0  # wall: a vehicle not home-bound this long after its survey is stuck
SAFE_RALLY_ALT_M = 15.0
SURVEY_ALT_M = {
    "copter": 40.0,
    "quadplane": 60.0,
}  # a rally point below this (above home) is not a safe way home
RESULTS = Path(__file__).resolve().parent.parent / "bench" / "results" / "sitl.json"
CHECKS = ("status", "rally", "fence", "survey", "way home", "rtl/land", "link loss", "passthrough")
CHECK_TEXT = {
    "status": "status matches SITL",
    "rally": "base -> rally point on its pad, safe altitude",
    "fence": "zone -> fence enabled first try",
    "survey": "survey around the zone, no breach",
    "way home": "way home flown, landed, disarmed",
    "rtl/land": "RTL / LAND commands",
    "link loss": "link loss reported, link back",
    "passthrough": "pymavlink via gcs mavlink: params, mission",
}


# the seed database's quadcopter (7) and Albatross VTOL (1), the QuadPlane 30 m east
VEHICLES = (copter(7, 0), quadplane(1, 1, home_east_m=30.0))


@dataclass
class Result:
    checks: dict[str, tuple[bool, str]] = field(default_factory=dict)
    figures: dict[str, float | None] = field(
        default_factory=lambda: {
            "min_zone_clearance_m": None,
            "rally_alt_rel_m": None,
            "fence_enabled_after_s": None,
            "way_home_started_s": None,
        }
    )

    def set(self, check: str, ok: bool, detail: str) -> None:
        self.checks[check] = (ok, detail)


@dataclass
class Run(Vehicle):
    result: Result = field(default_factory=Result)


class Harness(Rig):
    def __init__(self, args: argparse.Namespace, console: Console) -> None:
        super().__init__(args, console)
        self.runs: list[Run] = []

    def start(self) -> None:
        import dataclasses

        self.start_router()
        for base in VEHICLES:
            spec = dataclasses.replace(base, instance=base.instance + self.args.first_instance)
            v = self.start_vehicle(spec)
            self.runs.append(Run(v.spec, v.proc, v.home))
        if self.args.sim:  # the simulator's battery set before its node reads it
            for run in self.runs:
                self.attach(run)
        time.sleep(2.0)
        for run in self.runs:
            self.start_node(run)
        time.sleep(1.0)
        if not self.args.sim:  # SITL runs once its first client (the node) is there
            for run in self.runs:
                self.attach(run)
        self.connect_ground()

    def close(self) -> None:
        self.close_vehicles(list(self.runs))

    def command(self, kind: CommandKind, run: Run, **args: Any) -> tuple[bool, str]:
        return self.command_ids(kind, run.spec.node_id, **args)

    # ----------------------------------------------------------------- checks
    def check_status(self) -> bool:
        self.log("waiting for both vehicles: node status with a GPS fix and home")
        ids = [r.spec.node_id for r in self.runs]

        def ready() -> bool:
            v = self.ground.snapshot()
            return all(
                i in v.status
                and v.status[i].gps_fix >= 3
                and i in v.info
                and v.info[i].home is not None
                for i in ids
            )

        up = self.wait(ready, self.args.boot_timeout)
        view = self.ground.snapshot()
        for run in self.runs:
            vid, obs = run.spec.node_id, run.observer
            assert obs is not None
            st = view.status.get(vid)
            info = view.info.get(vid)
            here = obs.here()
            if not up or st is None or info is None or here is None:
                run.result.set("status", False, "no status with a GPS fix from the node")
                continue
            d = distance_m(st.lat_deg, st.lon_deg, here.lat, here.lon)
            problems = []
            if info.vehicle_type != run.spec.vehicle_type:
                problems.append(f"type {info.vehicle_type.name}")
            if st.ap_mode != obs.mode:
                problems.append(f"mode {st.ap_mode} != {obs.mode}")
            if st.armed != obs.armed:
                problems.append("armed differs")
            if d > 5.0:
                problems.append(f"position {d:.1f} m off")
            run.result.set(
                "status",
                not problems,
                "; ".join(problems)
                or f"{info.vehicle_type.name}, mode {st.ap_mode}, position within {d:.1f} m",
            )
        return up

    def check_rally(self) -> None:
        base = GeoPoint(HOME[0], HOME[1], HOME[2])
        self.log(f"set the base at {base.lat_deg}, {base.lon_deg}, {base.alt_msl_m} m MSL")
        acks = self.ground.command(
            CommandKind.SET_BASE, Selector(), CommandArgs(point=base), timeout_s=15.0
        )
        answered = {a.vehicle_id: a for a in acks}
        time.sleep(3.0)  # the node uploads the rally point
        for run in self.runs:
            a = answered.get(run.spec.node_id)
            assert run.downloader is not None
            items = None
            for _ in range(5):
                items = run.downloader.download(2)  # MAV_MISSION_TYPE_RALLY
                if items:
                    break
                time.sleep(2.0)
            if a is None or not a.accepted:
                run.result.set("rally", False, f"SET_BASE not accepted: {a}")
                continue
            if not items:
                run.result.set("rally", False, "no rally point in ArduPilot")
                continue
            item = items[0]
            alt = float(item.z)
            if item.frame in (0, 5):  # GLOBAL (MSL): relative to home
                alt -= HOME[2]
            # its own pad (its home): ArduPilot's RTL must never land it on another's
            d = distance_m(item.x / 1e7, item.y / 1e7, *run.home)
            run.result.figures["rally_alt_rel_m"] = round(alt, 2)
            ok = d < 2.0 and alt >= SAFE_RALLY_ALT_M
            run.result.set(
                "rally",
                ok,
                f"{len(items)} item(s), {d:.1f} m from its pad, "
                f"{alt:.1f} m above home (safe: >= {SAFE_RALLY_ALT_M:g})",
            )

    def check_fence(self, zone: NoFlyZone) -> None:
        self.log("declare the no-fly zone (35 m circle) in the survey field")
        t0, t0_unix = time.monotonic(), self.node_now()
        held = self.ground.declare_zone(zone, timeout_s=15.0)
        self.wait(
            lambda: all(r.observer is not None and r.observer.fence_enabled for r in self.runs),
            30.0,
        )
        time.sleep(2.0)  # a late failed enable would be reported by now
        for run in self.runs:
            obs, dl = run.observer, run.downloader
            assert obs is not None and dl is not None
            items = dl.download(1) or []  # MAV_MISSION_TYPE_FENCE
            circles = [i for i in items if i.command == 5004]  # FENCE_CIRCLE_EXCLUSION
            enabled_at = obs.fence_enabled_at
            after = None if enabled_at is None or enabled_at < t0 else enabled_at - t0
            run.result.figures["fence_enabled_after_s"] = None if after is None else round(after, 2)
            refused = [
                a
                for a in self.alerts(run.spec.node_id, AlertCode.NO_FLY_ZONE, t0_unix)
                if "fence" in a.text
            ]
            ok = (
                run.spec.node_id in held
                and len(circles) == 1
                and abs(circles[0].param1 - 35.0) < 0.5
                and after is not None
                and not refused
            )
            detail = (
                f"held: {run.spec.node_id in held}; fence items {len(items)} "
                f"({len(circles)} exclusion circle); enabled "
                f"{_opt(after, 'after {:.1f} s', 'never')}"
            )
            if refused:
                detail += f"; node alert: {refused[0].text}"
            run.result.set("fence", ok, detail)

    def check_survey(self, area: Any, zone: NoFlyZone) -> None:
        """Each vehicle surveys the field alone (at the same time), so that each plan
        keeps its own vehicle type's margin from the zone (a mixed fleet's plan keeps
        the largest, the fixed-wing's)."""
        t0, t0_unix = time.monotonic(), self.node_now()
        acks: dict[int, Ack] = {}
        for run in self.runs:
            vid = run.spec.node_id
            alt = SURVEY_ALT_M[run.spec.kind]
            mission = Mission(
                4200 + vid,
                self.ground.gcs_id,
                MissionType.AREA,
                area,
                MissionParams(altitude_rel_m=alt, side_overlap=0.6),
                Selector.ids(vid),
                f"sitl-check {run.spec.kind}",
                self.node_now(),
            )
            self.log(f"{run.spec.kind}: area survey around the zone, {alt:g} m above home")
            for answer in self.ground.mission(mission, timeout_s=15.0):
                if answer.vehicle_id == vid:  # the others answer NOT_ADDRESSED
                    acks[vid] = answer
        centre = zone.geometry.points[0]
        radius = zone.geometry.radius_m or 0.0

        def down(run: Run) -> bool:
            obs = run.observer
            here = obs.here() if obs is not None else None
            flew = bool(
                obs is not None and obs.since(t0) and max(s.alt_rel for s in obs.since(t0)) > 10
            )
            return bool(flew and obs is not None and not obs.armed and here and here.alt_rel < 2.0)

        def stuck(run: Run) -> bool:
            """Its survey completed WAY_HOME_WAIT_S ago and it is still not home-bound."""
            done = self.alerts(run.spec.node_id, AlertCode.MISSION_COMPLETE, t0_unix)
            if not done or self.node_now() - done[0].time_unix_s < WAY_HOME_WAIT_S:
                return False
            obs = run.observer
            here = obs.here() if obs is not None else None
            return here is not None and distance_m(here.lat, here.lon, *run.home) > 150.0

        def failed(run: Run) -> bool:
            """Its mission was refused, or planning failed: nothing will fly."""
            a = acks.get(run.spec.node_id)
            return (a is not None and not a.accepted) or bool(
                self.alerts(run.spec.node_id, AlertCode.PLAN_FAILED, t0_unix)
            )

        self.wait(
            lambda: all(down(r) or stuck(r) or failed(r) for r in self.runs),
            self.args.survey_timeout,
            1.0,
        )
        for run in self.runs:
            vid = run.spec.node_id
            obs = run.observer
            assert obs is not None
            a = acks.get(vid)
            track = [s for s in obs.since(t0) if s.alt_rel > 2.0]
            clearance = min(
                (distance_m(s.lat, s.lon, centre.lat_deg, centre.lon_deg) - radius for s in track),
                default=None,
            )
            run.result.figures["min_zone_clearance_m"] = (
                None if clearance is None else round(clearance, 2)
            )
            breaches = self.alerts(vid, AlertCode.GEOFENCE_BREACH, t0_unix)
            fence_texts = [t for tt, t in obs.texts if tt >= t0 and "ence" in t and "reach" in t]
            complete = self.alerts(vid, AlertCode.MISSION_COMPLETE, t0_unix)
            ok = (
                a is not None
                and a.accepted
                and clearance is not None
                and clearance >= ZONE_CLEARANCE_M[run.spec.kind]
                and not breaches
                and not fence_texts
                and bool(complete)
            )
            detail = (
                f"ack {a.reason.name if a else 'none'}; least clearance "
                f"{_opt(clearance, '{:.1f} m', '-')} (>= {ZONE_CLEARANCE_M[run.spec.kind]:g}); "
                f"{len(breaches)} breach alerts; "
                f"{'complete' if complete else 'not complete'}"
            )
            if fence_texts:
                detail += f"; ArduPilot: {fence_texts[0]}"
            run.result.set("survey", ok, detail)
            # the way home: from MISSION_COMPLETE, distance to home shrinking; landed, disarmed
            if not complete:
                run.result.set("way home", False, "the survey did not complete")
                continue
            t_done = time.monotonic() - (self.node_now() - complete[0].time_unix_s)
            after = [s for s in track if s.t >= t_done]
            started = None
            if after:
                d0 = distance_m(after[0].lat, after[0].lon, *run.home)
                for s in after:  # halfway home (a final loiter never gets there)
                    if distance_m(s.lat, s.lon, *run.home) < min(0.5 * d0, d0 - 20.0):
                        started = s.t - t_done
                        break
            run.result.figures["way_home_started_s"] = (
                None if started is None else round(started, 2)
            )
            here = obs.here()
            at_home = here is not None and distance_m(here.lat, here.lon, *run.home) < 100.0
            landed = down(run)
            run.result.set(
                "way home",
                started is not None and landed and at_home,
                f"halfway home {_opt(started, 'after {:.1f} s', 'never')}; "
                f"{'landed and disarmed' if landed else 'not landed/disarmed'}"
                f"{' near home' if at_home else ' away from home'}",
            )

    def check_rtl_land(self, run: Run) -> None:
        obs = run.observer
        assert obs is not None
        from swarm_proto.ardupilot import mode_number

        vt = run.spec.vehicle_type
        steps: list[str] = []

        def mode_is(*names: str) -> Callable[[], bool]:
            nums = set()
            for n in names:
                with contextlib.suppress(ValueError):
                    nums.add(mode_number(vt, n))
            return lambda: obs.mode in nums

        for kind, args in (
            (CommandKind.SET_MODE, {"text": "GUIDED"}),
            (CommandKind.ARM, {}),
            (CommandKind.TAKEOFF, {"value": 30.0}),
        ):
            ok, text = self.command(kind, run, **args)
            steps.append(text)
            if not ok:
                run.result.set("rtl/land", False, "; ".join(steps))
                return
        climbed = self.wait(lambda: (h := obs.here()) is not None and h.alt_rel > 20.0, 120.0)
        ok, text = self.command(CommandKind.RTL, run)
        steps.append(text)
        rtl = ok and self.wait(mode_is("RTL", "QRTL"), 15.0)
        time.sleep(5.0)
        ok, text = self.command(CommandKind.LAND, run)
        steps.append(text)
        land = ok and self.wait(mode_is("LAND", "QLAND"), 15.0)
        disarmed = self.wait(lambda: not obs.armed, 240.0, 1.0)
        good = climbed and rtl and land and disarmed
        run.result.set(
            "rtl/land", good, f"climbed {climbed}, RTL {rtl}, LAND {land}, disarmed {disarmed}"
        )

    def check_link_loss(self, run: Run) -> None:
        vid = run.spec.node_id
        t0_unix = self.node_now()
        os.kill(run.proc.pid, signal.SIGSTOP)
        try:
            lost = self.wait(
                lambda: bool(self.alerts(vid, AlertCode.AUTOPILOT_LINK_LOSS, t0_unix)), 10.0
            )
        finally:
            os.kill(run.proc.pid, signal.SIGCONT)
        t1 = time.monotonic()

        def back_up() -> bool:
            view = self.ground.snapshot()
            s = view.status.get(vid)
            return (
                s is not None
                and view.heard_at.get(vid, 0.0) > t1 + 1.0
                and not s.alerts & AlertFlag.AUTOPILOT_LINK_LOSS
            )

        back = self.wait(back_up, 30.0)
        run.result.set("link loss", lost and back, f"reported {lost}, link back {back}")

    # ----------------------------------------------------------------- all
    def _guarded(self, check: str, step: Callable[[], object]) -> None:
        """A check that raises fails its row (for every vehicle without a result)."""
        try:
            step()
        except Exception as exc:
            self.console.print_exception()
            for run in self.runs:
                run.result.checks.setdefault(check, (False, f"error: {exc}"[:120]))

    def run_all(self) -> None:
        from swarm_sim.demo import demo_area

        self.start()
        if not self.check_status():
            return
        self._guarded("rally", self.check_rally)
        area, zone = demo_area()
        self._guarded("fence", lambda: self.check_fence(zone))
        self._guarded("survey", lambda: self.check_survey(area, zone))
        for run in self.runs:
            self.log(f"{run.spec.kind}: take-off, RTL, LAND")
            self._guarded("rtl/land", functools.partial(self.check_rtl_land, run))
        for run in self.runs:
            self.log(f"{run.spec.kind}: SITL frozen (SIGSTOP) to lose the link")
            self._guarded("link loss", functools.partial(self.check_link_loss, run))
        for run in self.runs:
            self.log(f"{run.spec.kind}: pymavlink through `gcs mavlink`")
            self._guarded("passthrough", functools.partial(self.check_passthrough, run))

    def check_passthrough(self, run: Run) -> None:
        from .passthrough_check import check

        ok, detail = check(
            f"tcp/127.0.0.1:{self.router_port}",
            SWARM,
            run.spec.node_id,
            self.tmp / f"gcs-mavlink-{run.spec.node_id}.log",
            run.downloader,
        )
        run.result.set("passthrough", ok, detail)


def table(runs: list[Run]) -> Table:
    t = Table(title="sitl-check")
    t.add_column("check")
    for run in runs:
        t.add_column(run.spec.kind)
    for check in CHECKS:
        row = [CHECK_TEXT[check]]
        for run in runs:
            got = run.result.checks.get(check)
            if got is None:
                row.append("[yellow]not run[/]")
            else:
                ok, detail = got
                row.append(f"[green]PASS[/] {detail}" if ok else f"[red]FAIL[/] {detail}")
        t.add_row(*row)
    return t


def results(h: Harness) -> dict[str, Any]:
    from datetime import UTC, datetime

    out: dict[str, Any] = {
        "_meta": {
            "command": "make sitl-check" + (" SITL_ARGS=--sim" if h.args.sim else ""),
            "date_utc": datetime.now(UTC).isoformat(timespec="seconds"),
        },
        "target": "swarm-sim" if h.args.sim else "ardupilot-sitl",
        "ardupilot": {r.spec.kind: (r.observer.version if r.observer else "") for r in h.runs}
        if not h.args.sim
        else {},
        "speedup": h.args.speedup,
        "times": "wall seconds",
        "vehicles": {},
    }
    for run in h.runs:
        out["vehicles"][run.spec.kind] = {
            "node_id": run.spec.node_id,
            "checks": {
                c: {"pass": run.result.checks[c][0], "detail": run.result.checks[c][1]}
                if c in run.result.checks
                else {"pass": False, "detail": "not run"}
                for c in CHECKS
            },
            **run.result.figures,
        }
    out["passed"] = all(
        v["checks"][c]["pass"] for v in out["vehicles"].values() for c in CHECKS
    ) and bool(out["vehicles"])
    return out


def _interrupt(signum: int, frame: object) -> None:
    raise KeyboardInterrupt


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(
        prog="python -m swarm_sim.sitl_check", description=__doc__.split("\n")[0]
    )
    p.add_argument(
        "--bin",
        default=os.environ.get("ARDUPILOT_SITL_BIN", ""),
        help="directory with arducopter and arduplane (default $ARDUPILOT_SITL_BIN)",
    )
    p.add_argument("--sim", action="store_true", help="swarm-sim vehicles instead of SITL")
    p.add_argument("--speedup", type=float, default=5.0)
    p.add_argument(
        "--first-instance",
        type=int,
        default=0,
        help="SITL -I of the copter (the QuadPlane is the next); ports 5760+10*I",
    )
    p.add_argument("--boot-timeout", type=float, default=180.0)
    p.add_argument("--survey-timeout", type=float, default=900.0)
    p.add_argument("--out", default=str(RESULTS))
    p.add_argument("--keep", action="store_true", help="keep the logs directory")
    args = p.parse_args(argv)
    console = Console() if sys.stdout.isatty() else Console(width=200)
    if not args.sim and not args.bin:
        console.print("[red]sitl-check: set ARDUPILOT_SITL_BIN (see docs/sitl.md) or use --sim[/]")
        return 2
    h = Harness(args, console)
    # a SIGTERM (a background job never gets SIGINT) stops it the same way: the
    # processes stopped, what was measured written
    signal.signal(signal.SIGTERM, _interrupt)
    try:
        h.run_all()
    except KeyboardInterrupt:
        console.print("[yellow]interrupted[/]")
    finally:
        h.close()
    console.print(table(h.runs))
    out = results(h)
    path = Path(args.out)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(out, indent=2) + "\n")
    console.print(f"wrote {path}; logs in {h.tmp}")
    if not args.keep and out["passed"]:
        import shutil

        shutil.rmtree(h.tmp, ignore_errors=True)
    console.print("[bold green]PASS[/]" if out["passed"] else "[bold red]FAIL[/]")
    return 0 if out["passed"] else 1


if __name__ == "__main__":
    sys.exit(main())
