"""`make demo`: the paper's experiment 1 (swarm_sim/story.py) flown by real processes,
narrated live, recorded and reported (swarm_sim/demo_report.py).

    simulated ArduPilot vehicles (MAVLink on TCP, a process)       swarm_sim.runtime
      <-> one `swarm-node run` process per vehicle                 swarm_node
      <-> Zenoh on 127.0.0.1 (or the emulated 900 MHz radio)
      <-> the ground station (this process): the story's script,   gcs_cli.ground
          the narrator, the flight recorder

The shell: the ground station's subscriptions put every VehicleStatus, VehicleInfo,
Alert, Ack and Vote heard on one queue; the loop hands each to the story (which says
what the operator does next), the narrator (what each vehicle does and why) and the
recorder (the flight CSV), on the shared scaled clock; it carries out the story's
actions (publish a message, make a vehicle fail: SIGKILL its node and take its aircraft
out of the simulator) and stops when the story has finished. Then the fleet is stopped
and the report is built in `out`."""

from __future__ import annotations

import contextlib
import datetime
import os
import queue
import shutil
import signal
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from rich.console import Console
from rich.text import Text

from gcs_cli.ground import GroundStation
from gcs_cli.render import fleet_table
from swarm_node.database import SwarmDatabase
from swarm_proto import (
    Ack,
    Alert,
    GeoPoint,
    ScaledClock,
    TargetReport,
    VehicleInfo,
    VehicleStatus,
    Vote,
    validate,
)
from swarm_proto.clock import clock_from_spec
from swarm_proto.messages import RadioStats
from swarm_proto.session import Mode, SwarmBus, ZenohSettings
from swarm_proto.topics import ACK, ALERT, INFO, RADIO_STATS, STATUS, VOTE

from . import demo
from .core import SITL_HOME
from .demo_report import FlightRecorder, build
from .narrator import Line, Narrator
from .story import AREA_ID, PERIMETER_ID, ROUTE_ID, Fail, Finished, Say, Send, Story, StoryPlan

EXPERIMENT_FLEET = (1, 2, 3, 4, 5, 6)  # the seed database's six Albatross 250 VTOLs
MIXED_EXTRA = (7, 8, 9, 10, 12)  # --mixed: three quadcopters, a rover, a boat
PAD_SPACING_M = 30.0  # the paper's pads
# `swarm-sim demo` without --speedup or --radio. Planning is wall time (a replan 1-3 s on
# a loaded 2-core machine): at 5x that is 5-15 s of flight on the old share and the
# replan's 15 s agreement window is 3 s of wall time (docs/demo.md, "Options")
DEFAULT_SPEEDUP = 3.0
TICK_S = 0.1  # wall seconds between the story's timers when nothing is heard
COLORS = (
    "cyan",
    "green",
    "yellow",
    "magenta",
    "blue",
    "bright_red",
    "bright_green",
    "bright_yellow",
    "bright_magenta",
    "bright_cyan",
    "white",
    "bright_blue",
)


def _clock_now(spec: str) -> Callable[[], float]:
    clock = clock_from_spec(spec)
    return clock.now


class Shell:
    """The ground station's side of the demo: one queue of everything heard."""

    def __init__(
        self, endpoint: str, lans: dict[int, str] | None = None, mode: Mode = "peer"
    ) -> None:
        self.gs = GroundStation(ZenohSettings(mode=mode, connect=(endpoint,)), gcs_id=demo.GCS_ID)
        self.heard: queue.SimpleQueue[object] = queue.SimpleQueue()
        for topic in (STATUS, INFO, ALERT, ACK, VOTE):
            self.gs.bus.subscribe(topic, lambda m, k: self.heard.put(m))
        self.endpoint = endpoint
        self.lans = lans or {}
        self._onboard: dict[int, SwarmBus] = {}

    def publish(self, msg: Any) -> None:
        """What the operator sends, on the ground station's network; a vehicle's camera
        report on that vehicle's own (with --radio its gateway puts it on air: a gateway
        sends only what its own node originated, so the ground station's would not)."""
        validate(msg)
        src = msg.source_id if isinstance(msg, TargetReport) else None
        lan = self.lans.get(src) if src is not None else None
        if src is None or lan is None or lan == self.endpoint:
            self.gs.bus.publish(msg)
            return
        bus = self._onboard.get(src)
        if bus is None:
            bus = self._onboard[src] = SwarmBus.open(ZenohSettings(connect=(lan,)))
        bus.publish(msg)

    def close(self) -> None:
        for bus in self._onboard.values():
            bus.close()
        self.gs.close()


def _say(console: Console, t_s: float, who: str, text: str, style: str | None = None) -> None:
    m, s = divmod(round(max(0.0, t_s), 1), 60.0)  # rounded first: never "3:60.0"
    line = Text(f"{int(m):3d}:{s:04.1f} ", style="dim")
    line.append(f"{who:<11}", style=style or "bold")
    line.append(text, style=None if style != "bold cyan" else "cyan")
    console.print(line)


def run(
    members: tuple[int, ...] = EXPERIMENT_FLEET,
    *,
    speedup: float = 5.0,
    timeout_s: float = 1800.0,
    keep: bool = False,
    radio: bool = False,
    out: Path = Path("demo-out"),
    console: Console | None = None,
    plan_kw: dict[str, Any] | None = None,
    avoidance: bool = True,
) -> int:
    """Fly the story with `members`; write the report to `out`; 0 when it passed.
    Collision avoidance and the close pads' take-off and landing sequencing are on (the
    nodes' default), as in the paper's experiment."""
    console = console or (Console() if sys.stdout.isatty() else Console(width=140))
    if len(members) < 4:
        console.print(
            "[red]the story needs at least 4 vehicles (2 to the target, one "
            "that fails, one to inherit)[/]"
        )
        return 2
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    for name in ("report.json", "flight.csv", "top.png", "altitude.png", "separation.png"):
        with contextlib.suppress(FileNotFoundError):
            (out / name).unlink()
    tmp = Path(tempfile.mkdtemp(prefix="bandada-demo-"))
    link = "the emulated 900 MHz TDM radio" if radio else "Zenoh on 127.0.0.1"
    console.rule("[bold]bandada demo: the paper's experiment 1")
    console.print(
        f"{len(members)} simulated vehicles, {speedup:g}x real time, {link}; "
        f"report in {out}/, logs in {tmp}"
    )
    wall0 = time.monotonic()
    fleet = demo.start(
        members, speedup, tmp, console, radio=radio, avoidance=avoidance, spacing_m=PAD_SPACING_M
    )
    console.print(  # the operator's live map on the demo's network (docs/ground-station.md)
        f"  map: BANDADA_DB={tmp / 'swarm.db'} gcs --connect {fleet.endpoint} --mode "
        f"{'peer' if radio else 'client'} --gcs-id {demo.GCS_ID + 1} map  "
        "(then open the URL it prints)",
        soft_wrap=True,
    )
    clock = ScaledClock(speedup)
    now = _clock_now(fleet.clock_spec) if fleet.clock_spec else clock.now
    # on the LAN a client of the demo's router, as the nodes are (demo.zenoh_role)
    shell = Shell(fleet.endpoint, fleet.lans, mode="peer" if radio else "client")
    radio_stats: dict[int, RadioStats] = {}
    stats_bus = None
    configuring: dict[str, int] = {}
    if radio:
        stats_bus = SwarmBus.open(ZenohSettings(connect=(fleet.endpoint,)))
        stats_bus.subscribe(RADIO_STATS, lambda m, k: radio_stats.__setitem__(m.node_id, m))
    plan = StoryPlan.experiment_one(
        members,
        (SITL_HOME.lat_deg, SITL_HOME.lon_deg),
        repeat_s=max(1.0, speedup),
        planning_s=demo.plan_timeout_s(speedup, len(members)),
        **(plan_kw or {}),
    )
    recorder = FlightRecorder(out / "flight.csv")
    story = Story(plan, now())
    names = {
        AREA_ID: "the survey",
        plan.target_mission_id: "the target",
        PERIMETER_ID: "the perimeter",
        ROUTE_ID: "the route",
    }
    narrator = Narrator(now(), names)
    colors = {v: COLORS[i % len(COLORS)] for i, v in enumerate(members)}
    homes: dict[int, GeoPoint] = {}
    base: GeoPoint | None = None
    finished: Finished | None = None
    sim0 = now()

    def show(lines: list[Line], t0: float) -> None:
        for ln in lines:
            style = "red" if ln.severity >= 2 else colors.get(ln.vehicle_id)
            _say(console, ln.t_s + (narrator.t0 - t0), f"vehicle {ln.vehicle_id}", ln.text, style)

    try:
        if radio:
            console.print("  radio: the gateways configure their modules over AT commands ...")
            configuring = demo.radio_up(radio_stats, members, fleet, console)
        live = None
        if console.is_terminal:
            from rich.live import Live

            live = Live(
                fleet_table(shell.gs.snapshot()),
                console=console,
                refresh_per_second=2,
                transient=True,
            )
            live.start()
        last_table = 0.0
        try:
            while finished is None and time.monotonic() - wall0 < timeout_s:
                try:
                    msg = shell.heard.get(timeout=TICK_S)
                except queue.Empty:
                    msg = None
                t = now()
                actions = []
                batch = [msg] if msg is not None else []
                while True:  # everything already heard, then the timers
                    try:
                        batch.append(shell.heard.get_nowait())
                    except queue.Empty:
                        break
                for m in batch:
                    if isinstance(m, VehicleInfo) and m.vehicle_id in members:
                        if m.home is not None:
                            homes[m.vehicle_id] = m.home
                        if m.base is not None:
                            base = m.base
                    if isinstance(m, VehicleStatus | VehicleInfo):
                        recorder.handle(m)
                    if isinstance(m, VehicleStatus | VehicleInfo | Alert | Vote):
                        show(narrator.handle(m, t), sim0)
                    if isinstance(m, VehicleStatus | VehicleInfo | Alert | Ack | Vote):
                        actions += story.handle(m, t)
                actions += story.on_timer(t)
                for a in actions:
                    if isinstance(a, Send):
                        shell.publish(a.msg)
                    elif isinstance(a, Say):
                        _say(console, t - sim0, "operator", a.text, "bold cyan")
                    elif isinstance(a, Fail):
                        narrator.lost(a.vehicle_id)
                        _fail(fleet, a.vehicle_id)
                    elif isinstance(a, Finished):
                        finished = a
                if live is not None and time.monotonic() - last_table > 0.5:
                    last_table = time.monotonic()
                    live.update(fleet_table(shell.gs.snapshot(), title="fleet (live)"))
        finally:
            if live is not None:
                live.stop()
        if finished is None:
            story.record.outcome = f"{story.phase.value}: the demo's {timeout_s:g} s wall timeout"
            console.print(f"[red]{story.record.outcome}[/]")
        elif finished.ok:
            _say(
                console,
                now() - sim0,
                "operator",
                "every vehicle is down: the story is over",
                "bold cyan",
            )
        else:
            console.print(f"[red]the story stopped: {finished.why}[/]")
        console.print(fleet_table(shell.gs.snapshot(), title="fleet at the end"))
        radio_report = None
        if radio:
            radio_report = _radio_figures(radio_stats.get(demo.GCS_ID), fleet, configuring)
            demo.radio_report(radio_stats.get(demo.GCS_ID), fleet, configuring, console)
    except KeyboardInterrupt:
        console.print("[yellow]interrupted[/]")
        story.record.outcome = story.record.outcome or "interrupted"
        radio_report = None
    finally:
        sim_s = now() - sim0
        recorder.close()
        if stats_bus is not None:
            stats_bus.close()
        shell.close()
        demo.stop(fleet)
    wall_s = time.monotonic() - wall0
    console.print(
        f"[dim]flown: {sim_s / 60:.1f} simulated minutes in {wall_s:.0f} s; "
        "measuring the flight ...[/]"
    )
    with SwarmDatabase.open(tmp / "swarm.db") as db:
        profiles = {v: db.vehicle_profile(v) for v in members}
    meta = {
        "date_utc": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        "speedup": speedup,
        "radio": radio,
        "wall_s": round(wall_s, 1),
        "sim_s": round(sim_s, 1),
        "cpus": os.cpu_count(),
        "load_avg_1min": round(os.getloadavg()[0], 2),
    }
    report = build(
        out,
        plan=plan,
        record=story.record,
        flight_csv=out / "flight.csv",
        profiles=profiles,
        homes=homes,
        base=base,
        meta=meta,
        radio=radio_report,
    )
    _summary(console, report, out)
    if keep or not report["ok"]:
        console.print(f"node logs kept in {tmp}")
    else:
        shutil.rmtree(tmp, ignore_errors=True)
    return 0 if report["ok"] else 1


def _fail(fleet: demo.Fleet, vid: int) -> None:
    """The vehicle fails: its companion computer dies (SIGKILL: no goodbye on Zenoh),
    its radio too; its aircraft flies on in the simulator, as told, until its
    autopilot's GCS failsafe takes it home."""
    for procs in (fleet.nodes, fleet.gateways):
        p = procs.get(vid)
        if p is not None and p.poll() is None:
            p.send_signal(signal.SIGKILL)


def _radio_figures(
    stats: RadioStats | None, fleet: demo.Fleet, configuring: dict[str, int]
) -> dict[str, Any]:
    channel: dict[str, Any] = dict(fleet.channel.stats()["channel"]) if fleet.channel else {}
    out: dict[str, Any] = {"channel_since_table": channel, "before_table": configuring}
    if stats is not None:
        out["gcs_gateway"] = {
            "members": list(stats.members),
            "phase": stats.phase,
            "slot_ms": round(stats.slot_s * 1000.0, 2),
            "dropped_forged": stats.dropped_forged,
            "dropped_corrupt": stats.dropped_corrupt,
            "peers": {
                str(p.node_id): {
                    "packets_per_s": round(p.packets_per_s, 2),
                    "loss": round(p.loss, 4),
                }
                for p in stats.peers
            },
        }
    out["collisions"] = int(channel.get("collisions", 0))
    return out


def _summary(console: Console, r: dict[str, Any], out: Path) -> None:
    from rich.table import Table

    t = Table(title="experiment 1: what was flown", title_justify="left")
    t.add_column("mission")
    t.add_column("flown by")
    t.add_column("completed")
    for m in r["missions"]:
        t.add_row(
            f"{m['kind']} {m['mission_id']}",
            ", ".join(map(str, m.get("flown_by", []))),
            "yes" if m["completed"] else "[red]NO[/]",
        )
    console.print(t)
    sep = r["separation"]
    for v in r["votes"]:
        scores = ", ".join(
            f"{k}: {s:.3f}" for k, s in sorted(v["scores"].items(), key=lambda kv: -kv[1])
        )
        console.print(
            f"vote for mission {v['mission_id']}: {scores}; winners "
            f"{', '.join(map(str, v['winners']))}"
        )
    for e in r["replans"]:
        console.print(
            f"replan of mission {e['mission_id']} at {e['t_s']:.0f} s by "
            f"{', '.join(map(str, e['vehicles']))}: {e['why']}"
        )
    console.print(
        f"coverage {r['coverage']:.1%} of the coverable area "
        f"({r['coverage_detail']['of_whole_area']:.1%} of the whole field); separation once "
        f"airborne: min {sep['min_sep_m']} m, risk {sep['risk']}, danger {sep['danger']}, "
        f"near-collision {sep['near']} samples"
    )
    files = ", ".join(str(out / f) for f in r["files"].values())
    console.print(f"report: {out / 'report.json'}; {files}")
    if r["ok"]:
        console.print(
            "[bold green]demo passed: every mission completed, no near-collision, "
            "the area covered[/]"
        )
    else:
        console.print("[bold red]demo failed:[/] " + "; ".join(r["failures"]))
