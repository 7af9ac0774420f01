"""The fault campaign: a table of faults x missions, each flown start to
finish with one fault injected, measured the same way every time.

    make faults                     # both parts, writes bench/results/faults.json
    make bench BENCH=faults         # the same (BANDADA_FAULTS=fast: FastFleet only)
    python -m swarm_sim.faults --env fast --only "SIGSTOP a node 3 s"   # rows as JSON

Faults (`FAULTS`): kill -9 a node (restarted 5 s later on its database), SIGSTOP a node
for 3 s, an autopilot restart (on the ground, empty stores), 30 % of the swarm's
messages dropped, the swarm partitioned in two for 20 s, a clock jump on one node, the
database's disk full, a corrupted database file at start (the node refuses it; started
again on a new file). Missions (`MISSIONS`): an area survey by three VTOLs, and by two
quadcopters and a VTOL. FastFleet (`env fast`: node cores, link cores and simulated
ArduPilots over MAVLink bytes, in simulated time) runs every fault it can model;
real processes (`env processes`: `swarm-node` processes, simulated vehicles on TCP,
Zenoh on 127.0.0.1, the demo's harness at 1x) run the faults that need a real
process, clock or file (processes.py).

Every row (`FaultRow`): mission completed, coverage (from the flown tracks, the
camera's swath), declared state lost (declarations a node does not hold as the
operator last made them: must be 0), false emergencies (STATE_EMERGENCY or an EMERGENCY
alert: none of these faults endangers a vehicle, must be 0), the alerts raised, whether
the swarm recovered and how long it took (simulated seconds from the fault to the
fault's own recovery event, `recover_s`, defined per fault in docs/reliability.md).
"""

from __future__ import annotations

import math
import time
from collections import Counter
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

import msgspec
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
    NoFlyZone,
    Selector,
    SelectorKind,
    Severity,
    VehicleInfo,
    VehicleType,
)

from .core import SITL_HOME
from .fast_fleet import FastFleet
from .fault_row import FaultRow
from .scenarios import GCS, square

ALT_M = 60.0
MISSION_ID = 160


@dataclass(frozen=True)
class MissionSpec:
    name: str
    members: tuple[int, ...]
    half_m: float  # the survey square's half side
    victim: int  # the vehicle the fault hits


MISSIONS: tuple[MissionSpec, ...] = (
    MissionSpec("survey, 3 VTOLs", (1, 2, 3), 220.0, 3),
    MissionSpec("survey, 2 quadcopters + 1 VTOL", (7, 8, 1), 120.0, 8),
)


# ----------------------------------------------------------------------------- FastFleet


@dataclass
class Run:
    """One FastFleet mission flight: the fleet, what the operator declared, the tracks."""

    fleet: FastFleet
    spec: MissionSpec
    area: Geometry
    frame: LocalFrame
    base: GeoPoint
    zones: dict[int, NoFlyZone]
    fleets: dict[int, int]  # vehicle -> fleet id declared
    points: dict[int, list[tuple[float, float]]] = field(default_factory=dict)
    emergencies: set[tuple[int, str]] = field(default_factory=set)  # (vehicle, code)
    gcs_alive: bool = True
    mission_sent_at: float | None = None
    _next_gcs: float = 0.0
    # arms of a vehicle whose autopilot rebooted, with no mission or command declared
    # since the reboot: nothing may arm it but the operator (docs/reliability.md)
    unexpected_arms: int = 0
    declared_at: float = -math.inf  # the operator's last declaration
    rebooted_at: dict[int, float] = field(default_factory=dict)
    _armed: dict[int, bool] = field(default_factory=dict)
    # the closest two aircraft came, from the simulator's true positions (not the
    # nodes' telemetry), over every step with at least one of the pair in the air;
    # a dead node's aircraft counts (it flies on)
    min_true_sep_m: float = math.inf

    def tick(self) -> None:
        """Per step: sample tracks, note emergencies, the ground station's 1 Hz info."""
        f = self.fleet
        for vid, v in f.vehicles.items():
            armed = v.endpoint.autopilot.armed
            if armed and not self._armed.get(vid, False):
                since = self.rebooted_at.get(vid)
                self.unexpected_arms += since is not None and self.declared_at < since
            self._armed[vid] = armed
            e = v.node.fsm.emergency
            if v.node.fsm.state == FsmState.EMERGENCY and e is not None:
                self.emergencies.add((vid, e.code.name))
            s = v.link.state
            m = v.node.manager
            if (
                m.mission_state == MissionState.MISSION
                and m.phase.value == "flying"
                and m.mission_id == MISSION_ID
                and s.lat_deg is not None
                and s.lon_deg is not None
                and abs((s.alt_rel_m or 0.0) - ALT_M) < 15.0
            ):
                self.points.setdefault(vid, []).append(self.frame.to_local(s.lat_deg, s.lon_deg))
        self._separation()
        if self.gcs_alive and f.now >= self._next_gcs:
            self._next_gcs = f.now + 1.0
            f.broadcast(VehicleInfo(GCS, VehicleType.GCS, "ground station", "gcs"))

    def _separation(self) -> None:
        at = []
        for v in self.fleet.vehicles.values():
            sim = v.endpoint.autopilot
            n, e = self.frame.to_local(*sim.latlon)
            at.append((n, e, sim.body.alt, not sim.body.on_ground))
        for i, (n1, e1, a1, up1) in enumerate(at):
            for n2, e2, a2, up2 in at[i + 1 :]:
                if up1 or up2:
                    d = math.sqrt((n1 - n2) ** 2 + (e1 - e2) ** 2 + (a1 - a2) ** 2)
                    self.min_true_sep_m = min(self.min_true_sep_m, d)

    def run_until(self, pred: Callable[[], bool], timeout_s: float) -> bool:
        def check() -> bool:
            self.tick()
            return pred()

        return self.fleet.run_until(check, timeout_s)

    def run_for(self, seconds: float) -> None:
        end = self.fleet.now + seconds
        self.run_until(lambda: self.fleet.now >= end, seconds + 1.0)

    def share_fraction(self, vid: int) -> float:
        m = self.fleet.vehicles[vid].node.manager
        if m.share is None or m.share.length_m <= 0 or m.mission_id != MISSION_ID:
            return 0.0
        return m.share_progress_m() / m.share.length_m

    def landed(self) -> bool:
        return all(
            not v.endpoint.autopilot.armed and v.node.manager.phase.value == "idle"
            for v in self.fleet.vehicles.values()
            if not v.down
        )

    def coverage(self, profiles: Mapping[int, VehicleProfile]) -> float:
        cams = [c for c in (profiles[m].camera for m in self.spec.members) if c is not None]
        hfov = min(c.hfov_deg for c in cams) if cams else 60.0
        swath = 2.0 * ALT_M * math.tan(math.radians(hfov) / 2.0)
        poly = Polygon([self.frame.to_local(p.lat_deg, p.lon_deg) for p in self.area.points])
        lines = [LineString(p).buffer(swath / 2.0) for p in self.points.values() if len(p) > 1]
        if not lines:
            return 0.0
        return float(unary_union(lines).intersection(poly).area / poly.area)

    def declared_lost(self) -> int:
        """Declarations a live node does not hold as the operator last made them: its
        base, its fleet assignment (as its declared book resolves it: leaving a
        mission's fleet is the state machine's rule, the assignment stays declared),
        every zone in its book and in force in its monitoring."""
        lost = 0
        for vid, v in self.fleet.vehicles.items():
            if v.down:
                continue
            n = v.node
            base, _, fleet, _ = n.declarations.book.resolve(vid)
            lost += n.base != self.base or base != self.base
            lost += fleet != self.fleets.get(vid, 0)
            for zid, z in self.zones.items():
                lost += n.zones.get(zid) != z
        return lost


def declare(run: Run, msg: msgspec.Struct, to: Sequence[int] | None = None) -> msgspec.Struct:
    """The ground station declares (stamped with its clock), to the live nodes."""
    f = run.fleet
    msg = msgspec.structs.replace(msg, time_unix_s=f.now)
    run.declared_at = f.now
    f.broadcast(msg, to=[v for v in (to or f.vehicles) if not f.vehicles[v].down])
    return msg


def start_run(profiles: Mapping[int, VehicleProfile], spec: MissionSpec, *, seed: int = 1) -> Run:
    fleet = FastFleet.build(list(spec.members), profiles, spacing_m=60.0)
    fleet.seed = seed
    area = square(SITL_HOME.lat_deg + 0.005, SITL_HOME.lon_deg, spec.half_m)
    run = Run(
        fleet,
        spec,
        area,
        LocalFrame.at(list(area.points)),
        GeoPoint(SITL_HOME.lat_deg, SITL_HOME.lon_deg, SITL_HOME.alt_m),
        {},
        {},
    )
    assert run.run_until(
        lambda: all(
            v.link.state.ekf_has_position and v.link.state.home for v in fleet.vehicles.values()
        ),
        60,
    )
    declare(run, Command(GCS, 1, CommandKind.SET_BASE, args=CommandArgs(point=run.base)))
    ids = spec.members[:2]
    declare(
        run,
        Command(
            GCS, 2, CommandKind.SET_FLEET, Selector(SelectorKind.IDS, ids), CommandArgs(fleet_id=4)
        ),
    )
    run.fleets = dict.fromkeys(ids, 4)
    # a tower outside the field (a fence in every autopilot), and the field's operating area
    tlat, tlon = SITL_HOME.lat_deg - 0.002, SITL_HOME.lon_deg + 0.002
    zone = declare(run, NoFlyZone(1, Geometry.circle(tlat, tlon, 30.0), name="tower"))
    oa = declare(
        run,
        NoFlyZone(
            2,
            Geometry.circle(SITL_HOME.lat_deg + 0.003, SITL_HOME.lon_deg, 2500.0),
            name="field",
            operating_area=True,
        ),
    )
    assert isinstance(zone, NoFlyZone) and isinstance(oa, NoFlyZone)
    run.zones = {1: zone, 2: oa}
    assert run.run_until(
        lambda: all(v.node.fsm.state == FsmState.GO_MISSION for v in fleet.vehicles.values()), 30
    )
    run.run_for(3.0)
    return run


def send_mission(run: Run) -> None:
    """The operator sends the survey (every fault calls it where it belongs)."""
    declare(
        run,
        Mission(MISSION_ID, GCS, MissionType.AREA, run.area, MissionParams(altitude_rel_m=ALT_M)),
    )
    run.mission_sent_at = run.fleet.now


@dataclass
class Injected:
    """What a fault did: its recovery time (None: did not recover) and a note."""

    recover_s: float | None
    note: str = ""
    ok: bool = True


def _at_progress(run: Run, fraction: float = 0.4, *, send: bool = True) -> bool:
    if send:
        send_mission(run)
    return run.run_until(lambda: run.share_fraction(run.spec.victim) >= fraction, 1500)


def _hashes_agree(run: Run) -> bool:
    hs = {
        v.node.roster.members_hash
        for v in run.fleet.vehicles.values()
        if not v.down and v.node.fsm.mission_id == MISSION_ID
    }
    return len(hs) <= 1


def fault_none(run: Run) -> Injected:
    send_mission(run)
    return Injected(0.0, "no fault (the baseline)")


def fault_kill(run: Run, send: bool = True) -> Injected:
    """kill -9 a node at 40 % of its share; a new process 5 s later, on its database."""
    vid = run.spec.victim
    if not _at_progress(run, send=send):
        return Injected(None, "never reached 40 %", ok=False)
    t0 = run.fleet.now
    run.fleet.kill_node(vid)
    run.run_for(5.0)
    node = run.fleet.restart_node(vid)
    ok = run.run_until(lambda: node.reattach.decision is not None, 60)
    d = node.reattach.decision
    return Injected(
        run.fleet.now - t0 if ok else None,
        f"restarted 5 s later: {d.value if d else 'no decision'} ({node.reattach.why})",
        ok=ok,
    )


def fault_node_down_10s(run: Run) -> Injected:
    """A node dead for 10 s at 40 % of its share (SIGTERM, started again 10 s later on
    its database): its aircraft flies on, unseen by its peers, until its failsafe or
    its node's return."""
    vid = run.spec.victim
    if not _at_progress(run):
        return Injected(None, "never reached 40 %", ok=False)
    t0 = run.fleet.now
    run.fleet.kill_node(vid)
    run.run_for(10.0)
    node = run.fleet.restart_node(vid)
    ok = run.run_until(lambda: node.reattach.decision is not None, 60)
    d = node.reattach.decision
    mode = run.fleet.vehicles[vid].endpoint.autopilot.mode_name
    return Injected(
        run.fleet.now - t0 if ok else None,
        f"restarted 10 s later: {d.value if d else 'no decision'} ({node.reattach.why}); "
        f"its autopilot in {mode}",
        ok=ok,
    )


def fault_sigstop(run: Run) -> Injected:
    """SIGSTOP a node for 3 s at 40 % of its share (its autopilot flies on)."""
    vid = run.spec.victim
    if not _at_progress(run):
        return Injected(None, "never reached 40 %", ok=False)
    t0 = run.fleet.now
    run.fleet.stall(vid, 3.0)
    run.run_for(3.5)
    ok = run.run_until(lambda: _hashes_agree(run), 120)
    v = run.fleet.vehicles[vid]
    return Injected(
        run.fleet.now - t0 if ok else None,
        f"stall seen {v.node.stalls.meter.max_s:.1f} s by the node, "
        f"{v.link.state.host_stalls} late read(s) by its link",
        ok=ok,
    )


def fault_autopilot_restart(run: Run) -> Injected:
    """Restart an autopilot on the ground (a power cycle, empty stores) before the
    mission: the node puts its fence and rally point back; then the mission is flown."""
    vid = run.spec.victim
    v = run.fleet.vehicles[vid]
    t0 = run.fleet.now
    run.fleet.reboot_autopilot(vid)

    def restored() -> bool:
        sim = v.endpoint.autopilot
        return (
            v.node.backstop.restored >= 2
            and not v.node.backstop.checks
            and bool(sim.rally_items)
            and sim.fence_present()
        )

    ok = run.run_until(restored, 120)
    recover = run.fleet.now - t0
    run.run_until(lambda: v.node.monitor.ready and v.node.fsm.state == FsmState.GO_MISSION, 60)
    sim = v.endpoint.autopilot
    note = (
        f"fence {len(sim.fence_items)} items, rally {len(sim.rally_items)} point(s) "
        f"restored and verified by download ({v.node.backstop.restored} stores)"
    )
    send_mission(run)
    return Injected(recover if ok else None, note, ok=ok)


def fault_autopilot_reboot_in_flight(run: Run) -> Injected:
    """Reboot an autopilot at 40 % of its share (it comes back disarmed where it stood,
    `SimAutopilot.rebooted`), then lose another member 20 s later (an unrelated replan):
    the rebooted vehicle leaves its fleet at once (recovered when every peer's roster
    lost it) and nothing arms it again."""
    vid = run.spec.victim
    if not _at_progress(run):
        return Injected(None, "never reached 40 %", ok=False)
    t0 = run.fleet.now
    run.fleet.reboot_autopilot(vid)
    run.rebooted_at[vid] = t0
    peers = [p for p in run.spec.members if p != vid]

    def handed_on() -> bool:
        return run.fleet.vehicles[vid].node.fsm.mission_id != MISSION_ID and all(
            vid not in run.fleet.vehicles[p].node.roster.flying for p in peers
        )

    ok = run.run_until(handed_on, 60)
    recover = run.fleet.now - t0
    run.run_for(20.0)
    other = max(peers)
    run.fleet.kill_node(other)  # its aircraft flies its share on (FastFleet's model)
    run.run_for(5.0)
    run.fleet.restart_node(other)
    return Injected(
        recover if ok else None,
        f"share handed on {recover:.1f} s after the reboot; node {other} killed and "
        f"restarted 20 s later; {run.unexpected_arms} unexpected arm(s)",
        ok=ok and run.unexpected_arms == 0,
    )


def fault_loss(run: Run) -> Injected:
    """30 % of every swarm message between nodes lost, the whole flight (seeded)."""
    run.fleet.loss = 0.3
    send_mission(run)
    return Injected(0.0, "30 % of node-to-node messages dropped, the whole flight")


def fault_partition(run: Run) -> Injected:
    """The swarm cut in two for 20 s at 40 % of the victim's share."""
    if not _at_progress(run):
        return Injected(None, "never reached 40 %", ok=False)
    members = run.spec.members
    groups = {m: (0 if m == run.spec.victim else 1) for m in members}
    run.fleet.groups = groups
    t0 = run.fleet.now
    run.run_for(20.0)
    run.fleet.groups = None
    for m in members:  # they meet again: liveliness, and they ask each other
        run.fleet.exchange_declared(m)
    heal = run.fleet.now

    def all_see_all() -> bool:
        return all(
            {o for o in members if o != vid} <= {p.node_id for p in v.node.members.live()}
            for vid, v in run.fleet.vehicles.items()
        )

    ok = run.run_until(all_see_all, 60)
    seen = run.fleet.now - heal
    one = ok and run.run_until(lambda: _hashes_agree(run), 60)  # the parts merged back
    return Injected(
        run.fleet.now - t0 if one else None,
        f"cut {sorted(m for m, g in groups.items() if g == 0)} | "
        f"{sorted(m for m, g in groups.items() if g == 1)} for 20 s; "
        f"every node saw every other {seen:.1f} s after, "
        + (f"one roster {run.fleet.now - heal:.1f} s after" if one else "the rosters stayed apart"),
        ok=one,
    )


def fault_disk_full(run: Run) -> Injected:
    """The victim's disk is full all along; a zone declared mid-flight; the node is
    killed and restarted (its database missed the zone): the peers give it back."""
    vid = run.spec.victim
    v = run.fleet.vehicles[vid]
    v.store.full = True
    if not _at_progress(run, 0.3):
        return Injected(None, "never reached 30 %", ok=False)
    zone = declare(
        run,
        NoFlyZone(
            3,
            Geometry.circle(SITL_HOME.lat_deg - 0.003, SITL_HOME.lon_deg - 0.003, 25.0),
            name="mast",
        ),
    )
    assert isinstance(zone, NoFlyZone)
    run.zones[3] = zone
    run.run_for(2.0)
    t0 = run.fleet.now
    run.fleet.kill_node(vid)
    run.run_for(2.0)
    node = run.fleet.restart_node(vid)
    ok = run.run_until(lambda: node.monitor.zones.get(3) == zone, 30)
    return Injected(
        run.fleet.now - t0 if ok else None,
        f"{v.store.failures} failed stores; the restarted node learned zone 3 from its peers",
        ok=ok,
    )


def fault_new_database(run: Run) -> Injected:
    """The victim's database is unusable at a restart (refused: real processes show
    it): the node starts on a new, empty file and learns everything from its peers."""
    vid = run.spec.victim
    if not _at_progress(run):
        return Injected(None, "never reached 40 %", ok=False)
    t0 = run.fleet.now
    run.fleet.kill_node(vid)
    run.run_for(3.0)
    node = run.fleet.restart_node(vid, keep_database=False)
    ok = run.run_until(lambda: node.base == run.base and node.monitor.zones == run.zones, 30)
    d = node.reattach.decision
    return Injected(
        run.fleet.now - t0 if ok else None,
        f"new empty database: base, zones and fleet from the peers; "
        f"{d.value if d else 'no decision yet'}",
        ok=ok,
    )


def fault_ground_station_lost(run: Run) -> Injected:
    """The ground station is gone once the mission is sent (and a node restarts
    mid-mission: nobody but its database and its peers can give it the base)."""
    from swarm_node.core.node import PeerAlive

    send_mission(run)
    run.fleet.run_for(2.0)
    run.gcs_alive = False
    for vid in run.fleet.vehicles:
        run.fleet.deliver(vid, PeerAlive(GCS, False), run.fleet.now)
    injected = fault_kill(run, send=False)
    return Injected(
        injected.recover_s,
        "ground station gone after the mission was sent; " + injected.note,
        ok=injected.ok,
    )


FAST_FAULTS: dict[str, Callable[[Run], Injected]] = {
    "none": fault_none,
    "kill -9 a node (restarted after 5 s)": fault_kill,
    "node down 10 s (its aircraft flies on)": fault_node_down_10s,
    "SIGSTOP a node 3 s": fault_sigstop,
    "restart an autopilot (empty stores)": fault_autopilot_restart,
    "reboot an autopilot in flight": fault_autopilot_reboot_in_flight,
    "drop 30 % of swarm messages": fault_loss,
    "partition the swarm in two for 20 s": fault_partition,
    "disk full on the database": fault_disk_full,
    "corrupted database at start (new one)": fault_new_database,
    "ground station lost": fault_ground_station_lost,
}


def run_fast(
    name: str, spec: MissionSpec, profiles: Mapping[int, VehicleProfile], *, seed: int = 1
) -> FaultRow:
    t_wall = time.perf_counter()
    run = start_run(profiles, spec, seed=seed)
    injected = FAST_FAULTS[name](run)
    sent = run.mission_sent_at if run.mission_sent_at is not None else run.fleet.now
    finished = run.run_until(lambda: run.landed() and run.fleet.now - sent > 30.0, 3000)
    completed = any(
        a.code == AlertCode.MISSION_COMPLETE and a.text == f"mission {MISSION_ID}"
        for a in run.fleet.messages(Alert)
    )
    coverage = run.coverage(profiles)
    alerts = Counter(
        f"{a.severity.name} {a.code.name}"
        for a in run.fleet.messages(Alert)
        if a.severity >= Severity.WARNING
    )
    emergencies = Counter(f"{code} (vehicle {vid})" for vid, code in sorted(run.emergencies))
    # no fault here silences an autopilot for the 5 s a link-loss emergency takes
    false = sum(1 for _, code in run.emergencies if code == "AUTOPILOT_LINK_LOSS") + sum(
        1
        for a in run.fleet.messages(Alert)
        if a.code == AlertCode.AUTOPILOT_LINK_LOSS and a.severity >= Severity.CRITICAL
    )
    lost = run.declared_lost()
    recovered = (
        injected.ok
        and injected.recover_s is not None
        and finished
        and completed
        and coverage >= 0.95
        and lost == 0
        and false == 0
        and run.unexpected_arms == 0
    )
    note = injected.note + ("" if finished else "; not all landed in time")
    return FaultRow(
        fault=name,
        mission=spec.name,
        env="fast",
        recovered=recovered,
        recover_s=None if injected.recover_s is None else round(injected.recover_s, 2),
        coverage=round(coverage, 4),
        mission_completed=completed,
        declared_state_lost=lost,
        false_emergencies=false,
        unexpected_arms=run.unexpected_arms,
        min_true_sep_m=None if math.isinf(run.min_true_sep_m) else round(run.min_true_sep_m, 1),
        emergencies=dict(sorted(emergencies.items())),
        alerts=dict(sorted(alerts.items())),
        note=note,
        wall_s=round(time.perf_counter() - t_wall, 2),
    )


def campaign_fast(
    profiles: Mapping[int, VehicleProfile],
    faults: Sequence[str] | None = None,
    missions: Sequence[MissionSpec] = MISSIONS,
) -> list[FaultRow]:
    return [run_fast(f, m, profiles) for m in missions for f in (faults or list(FAST_FAULTS))]


def main(argv: Sequence[str] | None = None) -> int:
    import argparse
    import dataclasses
    import json

    from swarm_node.database import seed_fleet

    from .fault_processes import PROCESS_FAULTS, run_process_fault

    ap = argparse.ArgumentParser(
        prog="python -m swarm_sim.faults", description=__doc__.split("\n")[0]
    )
    ap.add_argument("--env", choices=("fast", "processes", "all"), default="fast")
    ap.add_argument("--only", action="append", default=[], help="a fault's name (repeat)")
    args = ap.parse_args(argv)
    known = set(FAST_FAULTS) | set(PROCESS_FAULTS)
    unknown = [f for f in args.only if f not in known]
    if unknown:
        ap.error(f"unknown fault(s) {unknown}; known: {sorted(known)}")
    profiles = {p.vehicle_id: p for p in seed_fleet()}
    if args.env in ("fast", "all"):
        for spec in MISSIONS:
            for name in [f for f in FAST_FAULTS if not args.only or f in args.only]:
                print(json.dumps(dataclasses.asdict(run_fast(name, spec, profiles))), flush=True)
    if args.env in ("processes", "all"):
        for name in [f for f in PROCESS_FAULTS if not args.only or f in args.only]:
            print(json.dumps(dataclasses.asdict(run_process_fault(name))), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())


def markdown(rows: Sequence[dict[str, object]]) -> str:
    """The fault table of docs/reliability.md from bench/results/faults.json's rows."""
    head = (
        "| fault | mission | where | recovered | recover s | coverage | declared lost "
        "| false emergencies | closest m (true) | unexpected arms | emergencies "
        "| alerts (WARNING+) |"
    )
    lines = [head, "|" + "---|" * 12]
    for r in rows:
        alerts = ", ".join(f"{k} x{v}" for k, v in dict(r["alerts"]).items()) or "-"  # type: ignore[call-overload]
        emerg = ", ".join(f"{k} x{v}" for k, v in dict(r["emergencies"]).items()) or "-"  # type: ignore[call-overload]
        rec = r["recover_s"]
        lines.append(
            f"| {r['fault']} | {r['mission']} | {'FastFleet' if r['env'] == 'fast' else 'processes'} "
            f"| {'yes' if r['recovered'] else 'NO'} | {'-' if rec is None else rec} "
            f"| {r['coverage']} | {r['declared_state_lost']} | {r['false_emergencies']} "
            f"| {'-' if r.get('min_true_sep_m') is None else r['min_true_sep_m']} "
            f"| {r.get('unexpected_arms', 0)} | {emerg} | {alerts} |"
        )
    return "\n".join(lines) + "\n"
