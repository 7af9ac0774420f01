"""The fault campaign over real processes (faults.py has the FastFleet part):
`swarm-node` processes flying simulated quadcopters (MAVLink on TCP, the simulator in
this process), Zenoh on 127.0.0.1 through a router, a ground station, in real time.

Each row is one survey by two quadcopters with one fault injected into vehicle 8's node
or autopilot: none, kill -9 (restarted 5 s later), SIGSTOP 3 s, an autopilot restart on
the ground (empty stores), the system clock stepped +1 h (`stepping:` clock), the disk
full under its database (a tmpfs mounted for the run with no byte free: root only; then
a kill and a restart),
and its database file corrupted while it was down (the node refuses it with a one-line
error; started again on a new file). Four rows fly three quadcopters (7, 8, 9), each
node with its own database, as a field engineer tries them: node 8 SIGTERMed for 10 s
while its aircraft flies on (no peer may come within 15 m of aircraft 8), the router
closed and opened again on its endpoint 3 s later (within the silent hold) and 20 s
later (every node replanned alone: the fleet must merge back), one fleet again within 10
s of the nodes' reconnection, and autopilot 8 rebooted in flight (its share handed on
within 5 s, then node 9 killed and restarted for an unrelated replan; it must not arm
again). Message loss and a partition between nodes need a network namespace with netem
and are measured in FastFleet only.

Truth is the simulator's (it runs in this process): every 0.2 s a sampler reads each
simulated vehicle's true position, its arming and its node's last reported mission
state; the closest two vehicles came (`min_true_sep_m`, a pair with at least one in
the air), the coverage (true positions while its node says MISSION) and the arms of a
rebooted autopilot with no operator declaration since (`unexpected_arms`) come from
it, not from the nodes' telemetry.
"""

from __future__ import annotations

import contextlib
import math
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from shapely.geometry import LineString, Polygon
from shapely.ops import unary_union

from swarm_node.core.declared import DeclaredBook
from swarm_node.core.planning import LocalFrame
from swarm_node.database import SwarmDatabase, seed_profiles
from swarm_proto import (
    Alert,
    AlertCode,
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
    SystemClock,
    VehicleInfo,
    VehicleStatus,
)
from swarm_proto.session import SwarmBus, ZenohSettings, open_session
from swarm_proto.topics import ALERT, INFO, STATUS

from .core import SITL_HOME
from .fault_row import FaultRow
from .runtime import VehicleServer, VehicleSpec, spread_homes
from .scenarios import square

MEMBERS = (7, 8)
THREE = (7, 8, 9)
VICTIM = 8
CLEAR_OF_VICTIM_M = 15.0  # no peer this close to a dead node's aircraft
ONE_FLEET_S = 10.0  # one fleet again this soon after the nodes reconnect
HANDED_ON_S = 5.0  # a rebooted autopilot's share handed on this soon
ALT_M = 25.0
HALF_M = 40.0
MISSION_ID = 170
GCS_ID = 900


def mission_name(members: tuple[int, ...]) -> str:
    return f"survey, {len(members)} quadcopters (real processes, 1x)"


def _free_port() -> int:
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@dataclass
class Node:
    vid: int
    args: list[str]
    env: dict[str, str]
    log: Path
    proc: subprocess.Popen[bytes] | None = None
    _pump: threading.Thread | None = None

    def start(self) -> None:
        # output through a pipe, written here (the node's own disk may be full)
        self.proc = subprocess.Popen(
            self.args, env=self.env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT
        )
        out = self.proc.stdout
        assert out is not None

        def pump() -> None:
            with self.log.open("ab") as f:
                for line in out:
                    f.write(line)
                    f.flush()

        self._pump = threading.Thread(target=pump, daemon=True)
        self._pump.start()

    def signal(self, sig: int) -> None:
        if self.proc is not None and self.proc.poll() is None:
            os.kill(self.proc.pid, sig)

    def stop(self) -> int:
        p = self.proc
        if p is None:
            return 0
        if p.poll() is None:
            with contextlib.suppress(ProcessLookupError):
                os.kill(p.pid, signal.SIGCONT)
                p.send_signal(signal.SIGINT)
            try:
                p.wait(15)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()
        if self._pump is not None:
            self._pump.join(5)
        return p.returncode


@dataclass
class Rig:
    tmp: Path
    swarm: str
    endpoint: str
    router: object
    server: VehicleServer
    nodes: dict[int, Node]
    bus: SwarmBus
    gs: object  # GroundStation
    area: Geometry
    frame: LocalFrame
    base: GeoPoint
    members: tuple[int, ...] = MEMBERS
    router_endpoint: str = ""
    zones: dict[int, NoFlyZone] = field(default_factory=dict)
    fleets: dict[int, int] = field(default_factory=dict)
    heard_at: dict[int, float] = field(default_factory=dict)  # monotonic: last INFO
    # the closest any other vehicle came to the victim's aircraft since `watch_victim`
    victim_closest_m: float = math.inf
    victim_watched: bool = False
    statuses: list[VehicleStatus] = field(default_factory=list)
    infos: list[VehicleInfo] = field(default_factory=list)
    alerts: list[Alert] = field(default_factory=list)
    lock: threading.Lock = field(default_factory=threading.Lock)
    # the truth, from the simulator (`sample_truth`)
    min_true_sep_m: float = math.inf
    unexpected_arms: int = 0
    declared_at: float = -math.inf  # monotonic: the operator's last declaration
    rebooted_at: dict[int, float] = field(default_factory=dict)  # monotonic, by vehicle
    true_tracks: dict[int, list[tuple[float, float]]] = field(default_factory=dict)
    _armed: dict[int, bool] = field(default_factory=dict)
    _stop: threading.Event = field(default_factory=threading.Event)

    # -------------------------------------------------------------- the truth
    def sample_truth(self) -> None:
        """One sample of every simulated vehicle (the sampler thread's step)."""
        at = []
        for e in self.server.endpoints:
            sim = e.autopilot
            vid = sim.sysid
            n, east = self.frame.to_local(*sim.latlon)
            up = not sim.body.on_ground
            at.append((vid, n, east, sim.body.alt, up))
            armed = bool(sim.armed)
            if armed and not self._armed.get(vid, False):
                since = self.rebooted_at.get(vid)
                self.unexpected_arms += since is not None and self.declared_at < since
            self._armed[vid] = armed
            st = self.status(vid)
            if (
                st is not None
                and st.mission_state == MissionState.MISSION
                and abs(sim.body.height - ALT_M) < 6.0
            ):
                with self.lock:
                    self.true_tracks.setdefault(vid, []).append((n, east))
        for i, (v1, n1, e1, a1, up1) in enumerate(at):
            for v2, n2, e2, a2, up2 in at[i + 1 :]:
                if up1 or up2:
                    d = math.sqrt((n1 - n2) ** 2 + (e1 - e2) ** 2 + (a1 - a2) ** 2)
                    self.min_true_sep_m = min(self.min_true_sep_m, d)
                    if self.victim_watched and VICTIM in (v1, v2):
                        self.victim_closest_m = min(self.victim_closest_m, d)

    def watch_truth(self) -> None:
        """Sample the truth every 0.2 s until `close`."""

        def loop() -> None:
            while not self._stop.wait(0.2):
                with contextlib.suppress(Exception):  # a vehicle rebooting under us
                    self.sample_truth()

        threading.Thread(target=loop, name="truth", daemon=True).start()

    def declared(self) -> None:
        self.declared_at = time.monotonic()

    def watch_victim(self) -> None:
        """From now on, also the closest any vehicle comes to the victim's aircraft."""
        self.victim_watched = True

    def restart_router(self, down_s: float) -> float:
        """Close the router and open it again `down_s` later on the same endpoint (what
        a restarted lab router does); the monotonic time it is back."""
        self.router.close()  # type: ignore[attr-defined]
        time.sleep(down_s)
        self.router = open_session(ZenohSettings(mode="router", listen=(self.router_endpoint,)))
        return time.monotonic()

    def fresh_infos(self, since: float) -> dict[int, VehicleInfo]:
        """Each member's last VehicleInfo, if it came after `since` (monotonic)."""
        out = {}
        for vid in self.members:
            i = self.info(vid)
            if i is not None and self.heard_at.get(vid, -math.inf) > since:
                out[vid] = i
        return out

    # -------------------------------------------------------------- observation
    def info(self, vid: int) -> VehicleInfo | None:
        with self.lock:
            return next((i for i in reversed(self.infos) if i.vehicle_id == vid), None)

    def status(self, vid: int) -> VehicleStatus | None:
        with self.lock:
            return next((s for s in reversed(self.statuses) if s.vehicle_id == vid), None)

    def wait(self, pred: Callable[[], bool], timeout_s: float, period_s: float = 0.2) -> bool:
        end = time.monotonic() + timeout_s
        while time.monotonic() < end:
            if pred():
                return True
            time.sleep(period_s)
        return pred()

    def progress(self, vid: int) -> float:
        i = self.info(vid)
        if i is None or i.mission_id != MISSION_ID or i.mission_path_m <= 0:
            return 0.0
        return i.mission_progress_m / i.mission_path_m

    def landed(self) -> bool:
        return all(
            (s := self.status(v)) is not None
            and not s.armed
            and s.alt_rel_m < 2.0
            and s.mission_state == MissionState.IDLE
            for v in self.members
        )

    def coverage(self) -> float:
        """The share of the area the cameras saw, from the true tracks."""
        cam = seed_profiles()["Generic Quadcopter"].camera
        hfov = cam.hfov_deg if cam is not None else 60.0
        swath = 2.0 * ALT_M * math.tan(math.radians(hfov) / 2.0)
        with self.lock:
            tracks = {v: list(p) for v, p in self.true_tracks.items()}
        poly = Polygon([self.frame.to_local(p.lat_deg, p.lon_deg) for p in self.area.points])
        lines = [LineString(p).buffer(swath / 2.0) for p in tracks.values() if len(p) > 1]
        return float(unary_union(lines).intersection(poly).area / poly.area) if lines else 0.0

    def declared_lost(self) -> int:
        """Declarations a running node does not hold as the operator last made them
        (asked of each node's DECLARED queryable)."""
        lost = 0
        for vid, n in self.nodes.items():
            if n.proc is None or n.proc.poll() is not None:
                continue
            state = self.gs.declared_state(vid, timeout_s=3.0)  # type: ignore[attr-defined]
            if state is None:
                lost += 1 + len(self.zones)
                continue
            base, _, fleet, _ = DeclaredBook.of([state], time.time()).resolve(vid)
            lost += state.base != self.base or base != self.base
            lost += fleet != self.fleets.get(vid, 0)
            held = {z.zone_id: z for z in state.zones}
            lost += sum(held.get(zid) != z for zid, z in self.zones.items())
        return lost

    def close(self) -> None:
        self._stop.set()
        for n in self.nodes.values():
            n.stop()
        self.gs.close()  # type: ignore[attr-defined]
        self.bus.close()
        self.server.close()
        self.router.close()  # type: ignore[attr-defined]


def fill_a_disk(where: Path, db: Path) -> Path:
    """A filesystem with the database on it and no byte free (a tmpfs mounted for the
    run: needs root; the disk full fault is skipped otherwise): every write the node
    makes to its database then fails as on a full disk (ENOSPC, SQLITE_FULL)."""
    where.mkdir(exist_ok=True)
    size = db.stat().st_size + 256 * 1024
    subprocess.run(
        ["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(where)],
        check=True,
        capture_output=True,
    )
    target = where / db.name
    shutil.copyfile(db, target)
    fd = os.open(where / "filler", os.O_WRONLY | os.O_CREAT)
    try:
        while os.write(fd, b"\0" * 4096) > 0:
            pass
    except OSError:
        pass  # ENOSPC: full
    finally:
        os.close(fd)
    return target


def free_the_disk(where: Path) -> None:
    with contextlib.suppress(OSError):
        (where / "filler").unlink()


def unmount(where: Path) -> None:
    if where.is_dir():
        done = subprocess.run(["umount", str(where)], check=False, capture_output=True)
        if done.returncode != 0:  # still busy: detach it now, freed when released
            subprocess.run(["umount", "-l", str(where)], check=False, capture_output=True)


def _node(
    vid: int,
    rig_tmp: Path,
    swarm: str,
    endpoint: str,
    port: int,
    env: dict[str, str],
    db: Path | None = None,
) -> Node:
    # a client of the rig's router, as in the demo (demo.zenoh_role)
    args = [
        sys.executable,
        "-m",
        "swarm_node.cli",
        "run",
        "--id",
        str(vid),
        "--swarm",
        swarm,
        "--autopilot",
        f"tcp:127.0.0.1:{port}",
        "--connect",
        endpoint,
        "--mode",
        "client",
    ]
    if db is not None:
        args += ["--db", str(db)]
    return Node(vid, args, env, rig_tmp / f"node-{vid}.log")


def start_rig(
    tmp: Path,
    *,
    victim_env: dict[str, str] | None = None,
    victim_db: bool = False,
    victim_limit: bool = False,
    members: tuple[int, ...] = MEMBERS,
    own_dbs: bool = False,
) -> Rig:
    from gcs_cli.ground import GroundStation

    swarm = f"f{os.getpid()}{int(time.time()) % 10000}"
    endpoint = f"tcp/127.0.0.1:{_free_port()}"
    router = open_session(ZenohSettings(mode="router", listen=(endpoint,)))
    homes = spread_homes(SITL_HOME, len(members), 30.0)
    specs = [
        VehicleSpec("copter", instance=i, port=_free_port(), home=homes[i], sysid=vid)
        for i, vid in enumerate(members)
    ]
    server = VehicleServer(specs, SystemClock())
    server.start_thread()
    shared = tmp / "swarm.db"
    SwarmDatabase.open(shared).close()
    env = {**os.environ, "BANDADA_DB": str(shared), "PYTHONUNBUFFERED": "1"}
    env.pop("BANDADA_CLOCK", None)
    nodes: dict[int, Node] = {}
    for vid, spec in zip(members, specs, strict=True):
        own_db = None
        if own_dbs:  # each node its own database, as on separate vehicles
            own_db = tmp / f"node-{vid}.db"
            shutil.copyfile(shared, own_db)
        if vid == VICTIM and (victim_db or victim_limit):
            own_db = tmp / "victim.db"
            shutil.copyfile(shared, own_db)
        e = {**env, **(victim_env or {})} if vid == VICTIM else env
        nodes[vid] = _node(vid, tmp, swarm, endpoint, spec.tcp_port, e, own_db)
        if vid == VICTIM and victim_limit and own_db is not None:
            full = fill_a_disk(tmp / "full-disk", own_db)
            nodes[vid].args[nodes[vid].args.index("--db") + 1] = str(full)
        nodes[vid].start()
    bus = SwarmBus.open(ZenohSettings(mode="client", connect=(endpoint,)), swarm)
    gs = GroundStation(ZenohSettings(mode="client", connect=(endpoint,)), swarm, GCS_ID)
    area = square(SITL_HOME.lat_deg + 0.0012, SITL_HOME.lon_deg, HALF_M)
    rig = Rig(
        tmp,
        swarm,
        endpoint,
        router,
        server,
        nodes,
        bus,
        gs,
        area,
        LocalFrame.at(list(area.points)),
        GeoPoint(SITL_HOME.lat_deg, SITL_HOME.lon_deg, SITL_HOME.alt_m),
        members=members,
        router_endpoint=endpoint,
    )

    def keep(into: list, msg: object, key: str) -> None:
        with rig.lock:
            into.append(msg)

    def keep_info(msg: VehicleInfo, key: str) -> None:
        with rig.lock:
            rig.infos.append(msg)
            rig.heard_at[msg.vehicle_id] = time.monotonic()

    bus.subscribe(STATUS, lambda m, k: keep(rig.statuses, m, k))
    bus.subscribe(INFO, keep_info)
    bus.subscribe(ALERT, lambda m, k: keep(rig.alerts, m, k))
    rig.watch_truth()
    return rig


def declare_all(rig: Rig) -> None:
    gs = rig.gs
    ok = gs.wait_for(  # type: ignore[attr-defined]
        lambda v: all(
            i in v.status
            and v.status[i].gps_fix >= 3
            and i in v.info
            and v.info[i].home is not None
            for i in rig.members
        ),
        120,
    )
    if not ok:
        raise RuntimeError("vehicles never got a position")
    rig.declared()
    gs.command(CommandKind.SET_BASE, Selector(), CommandArgs(point=rig.base), timeout_s=15.0)  # type: ignore[attr-defined]
    gs.command(  # type: ignore[attr-defined]
        CommandKind.SET_FLEET,
        Selector(SelectorKind.IDS, rig.members),
        CommandArgs(fleet_id=4),
        timeout_s=15.0,
    )
    rig.fleets = dict.fromkeys(rig.members, 4)
    tower = NoFlyZone(
        1, Geometry.circle(SITL_HOME.lat_deg - 0.002, SITL_HOME.lon_deg + 0.002, 30.0), name="tower"
    )
    field_ = NoFlyZone(
        2,
        Geometry.circle(SITL_HOME.lat_deg, SITL_HOME.lon_deg, 2500.0),
        name="field",
        operating_area=True,
    )
    for z in (tower, field_):
        gs.declare_zone(z, timeout_s=15.0)  # type: ignore[attr-defined]
    # as the nodes hold them (the ground station stamped them)
    for z in (tower, field_):
        held = gs.zones_held(z.zone_id, timeout_s=2.0)  # type: ignore[attr-defined]
        rig.zones[z.zone_id] = next(iter(held.values()))
    if not gs.wait_for(  # type: ignore[attr-defined]
        lambda v: all(v.fsm_state(i) == FsmState.GO_MISSION for i in rig.members), 60
    ):
        raise RuntimeError("vehicles never became ready")


def send_mission(rig: Rig) -> float:
    m = Mission(
        MISSION_ID,
        GCS_ID,
        MissionType.AREA,
        rig.area,
        MissionParams(altitude_rel_m=ALT_M),
        Selector.fleet(4),
        time_unix_s=time.time(),
    )
    rig.declared()
    rig.gs.mission(m, timeout_s=15.0)  # type: ignore[attr-defined]
    return time.monotonic()


@dataclass
class Outcome:
    recover_s: float | None
    note: str
    ok: bool = True


def _at(rig: Rig, fraction: float = 0.4) -> bool:
    send_mission(rig)
    return rig.wait(lambda: rig.progress(VICTIM) >= fraction, 600)


def p_none(rig: Rig) -> Outcome:
    send_mission(rig)
    return Outcome(0.0, "no fault (the baseline)")


def _reattach_seen(n: Node) -> bool:
    return "reattached:" in n.log.read_text(errors="replace")


def _reattached(n: Node) -> str:
    """The restarted node's reattach decision, as it logged it."""
    line = next(
        (ln for ln in n.log.read_text(errors="replace").splitlines() if "reattached:" in ln), ""
    )
    return line.split(f"node {n.vid}: ")[-1][:120]


def p_kill(rig: Rig) -> Outcome:
    if not _at(rig):
        return Outcome(None, "never reached 40 %", ok=False)
    n = rig.nodes[VICTIM]
    t0 = time.monotonic()
    n.signal(signal.SIGKILL)
    n.proc.wait(10)  # type: ignore[union-attr]
    time.sleep(5.0)
    n.start()
    ok = rig.wait(lambda: _reattach_seen(n), 90)
    return Outcome(
        time.monotonic() - t0 if ok else None, f"restarted 5 s later: {_reattached(n)}", ok
    )


def p_sigstop(rig: Rig) -> Outcome:
    if not _at(rig):
        return Outcome(None, "never reached 40 %", ok=False)
    n = rig.nodes[VICTIM]
    t0 = time.monotonic()
    n.signal(signal.SIGSTOP)
    time.sleep(3.0)
    n.signal(signal.SIGCONT)

    def agreed() -> bool:
        a, b = rig.info(7), rig.info(8)
        return (
            a is not None
            and b is not None
            and (a.members_hash == b.members_hash or b.mission_id != MISSION_ID)
            and time.monotonic() - t0 > 3.5
        )

    ok = rig.wait(agreed, 60)
    recover = time.monotonic() - t0

    def reported() -> list[str]:
        with rig.lock:
            return [a.text for a in rig.alerts if a.vehicle_id == VICTIM and "stalled" in a.text]

    rig.wait(lambda: bool(reported()), 10)  # reported a second after the stall
    stalled = reported()
    return Outcome(
        recover if ok else None, f"stopped 3 s: {stalled[0] if stalled else 'no stall report'}", ok
    )


def p_autopilot(rig: Rig) -> Outcome:
    def sim_of() -> Any:
        return next(e.autopilot for e in rig.server.endpoints if e.autopilot.sysid == VICTIM)

    def stores() -> tuple[list[tuple[int, int, int, float]], list[tuple[int, int, float]]]:
        sim = sim_of()
        return (
            [(i.command, i.x, i.y, i.param1) for i in sim.fence_items],
            [(i.x, i.y, i.z) for i in sim.rally_items],
        )

    # the node's uploads done first (a reboot in the middle of one is another story):
    # both zones fenced (the tower, the field), the rally point, the fence enabled
    def uploaded() -> bool:
        fence, rally = stores()
        sim = sim_of()
        return (
            len(fence) == len(rig.zones)
            and bool(rally)
            and sim.fence_present()
            and (sim.params["FENCE_ENABLE"][0] == 1.0)
        )

    if not rig.wait(uploaded, 60):
        return Outcome(None, "the fence and rally point never reached the autopilot", ok=False)
    time.sleep(3.0)  # and the node's own check of the new base's rally point
    before = stores()
    t0 = time.monotonic()
    rig.rebooted_at[VICTIM] = t0
    rig.server.reboot(VICTIM)
    rig.wait(lambda: not stores()[0], 10)
    ok = rig.wait(lambda: stores() == before and sim_of().fence_present(), 90)
    dt = time.monotonic() - t0
    rig.wait(
        lambda: (
            sum(
                "restored and verified" in a.text
                for a in list(rig.alerts)
                if a.vehicle_id == VICTIM
            )
            >= 2
        ),
        20,
    )
    with rig.lock:
        said = sorted(
            {a.text for a in rig.alerts if a.vehicle_id == VICTIM and "verified" in a.text}
        )
    rig.gs.wait_for(lambda v: v.fsm_state(VICTIM) == FsmState.GO_MISSION, 60)  # type: ignore[attr-defined]
    send_mission(rig)
    return Outcome(
        dt if ok else None,
        f"before the mission, on the ground: fence "
        f"{len(before[0])} items, rally {len(before[1])} back; {'; '.join(said)}",
        ok and bool(said),
    )


def p_clock(rig: Rig) -> Outcome:
    # the victim was started on a clock that steps +3600 s at 40 % (see run_processes)
    if not _at(rig):
        return Outcome(None, "never reached 40 %", ok=False)
    t0 = time.monotonic()

    def reported() -> bool:
        with rig.lock:
            return any(a.vehicle_id == VICTIM and "clock stepped" in a.text for a in rig.alerts)

    ok = rig.wait(reported, 120)
    return Outcome(
        time.monotonic() - t0 if ok else None,
        "system clock +3600 s: the node kept steady time and reported it",
        ok,
    )


def p_disk_full(rig: Rig) -> Outcome:
    if not _at(rig, 0.3):
        return Outcome(None, "never reached 30 %", ok=False)
    gs = rig.gs
    mast = NoFlyZone(
        3, Geometry.circle(SITL_HOME.lat_deg - 0.003, SITL_HOME.lon_deg - 0.003, 25.0), name="mast"
    )
    rig.declared()
    gs.declare_zone(mast, timeout_s=10.0)  # type: ignore[attr-defined]
    held = gs.zones_held(3, timeout_s=2.0)  # type: ignore[attr-defined]
    rig.zones[3] = next(iter(held.values()))
    time.sleep(2.0)
    full = [a.text for a in rig.alerts if a.vehicle_id == VICTIM and "not stored" in a.text]
    n = rig.nodes[VICTIM]
    t0 = time.monotonic()
    n.signal(signal.SIGKILL)
    n.proc.wait(10)  # type: ignore[union-attr]
    free_the_disk(rig.tmp / "full-disk")  # the disk was cleaned up
    n.start()

    def has_mast() -> bool:
        st = gs.declared_state(VICTIM, timeout_s=1.0)  # type: ignore[attr-defined]
        return st is not None and any(z.zone_id == 3 for z in st.zones)

    ok = rig.wait(has_mast, 60, period_s=0.5)
    return Outcome(
        time.monotonic() - t0 if ok else None,
        f"{full[0] if full else 'no store failure alerted'}; restarted, zone 3 back from its peers",
        ok and bool(full),
    )


def p_corrupt(rig: Rig) -> Outcome:
    if not _at(rig):
        return Outcome(None, "never reached 40 %", ok=False)
    n = rig.nodes[VICTIM]
    n.signal(signal.SIGKILL)
    n.proc.wait(10)  # type: ignore[union-attr]
    db = Path(n.args[n.args.index("--db") + 1])
    with db.open("r+b") as f:  # the header and the first pages overwritten
        f.write(os.urandom(4096))
    n.start()
    code = n.proc.wait(60)  # type: ignore[union-attr]
    refused = n.log.read_text(errors="replace").strip().splitlines()[-1][:160]
    t0 = time.monotonic()
    fresh = rig.tmp / "victim-new.db"
    n.args[n.args.index("--db") + 1] = str(fresh)
    n.start()

    def learned() -> bool:
        st = rig.gs.declared_state(VICTIM, timeout_s=1.0)  # type: ignore[attr-defined]
        return st is not None and st.base == rig.base and len(st.zones) == len(rig.zones)

    ok = rig.wait(learned, 60, period_s=0.5)
    return Outcome(
        time.monotonic() - t0 if ok else None,
        f"refused (exit {code}: {refused.split(': ', 1)[-1][:90]}); on a new file "
        "it learned base and zones from its peer",
        ok and code == 2,
    )


def p_sigterm(rig: Rig) -> Outcome:
    """Node 8 stopped (SIGTERM) for 10 s at 40 % of its share, then started again: its
    aircraft flies on; no peer may come within 15 m of it (`run_process_fault` judges
    that from the true positions to the end of the flight)."""
    if not _at(rig):
        return Outcome(None, "never reached 40 %", ok=False)
    n = rig.nodes[VICTIM]
    rig.watch_victim()
    t0 = time.monotonic()
    n.signal(signal.SIGTERM)
    code = n.proc.wait(15)  # type: ignore[union-attr]
    time.sleep(max(0.0, t0 + 10.0 - time.monotonic()))
    n.start()
    ok = rig.wait(lambda: _reattach_seen(n), 90)
    return Outcome(
        time.monotonic() - t0 if ok else None,
        f"SIGTERM (exit {code}), started 10 s later: {_reattached(n)}",
        ok,
    )


def p_router(rig: Rig, down_s: float = 3.0) -> Outcome:
    """The router closed at 30 % of the victim's share and opened again `down_s` later
    on its endpoint. Recovered when every member flying the mission reports one roster
    hash, counted from the nodes' reconnection (each member heard again): at most 10 s.
    Down 3 s, the members are back within the silent hold (nobody replans); down 20 s,
    each node has replanned alone and the fleet must merge back."""
    if not _at(rig, 0.3):
        return Outcome(None, "never reached 30 %", ok=False)
    with rig.lock:
        before = {i.members_hash for i in rig.infos if i.mission_id == MISSION_ID}
    up = rig.restart_router(down_s)
    back = rig.wait(lambda: len(rig.fresh_infos(up)) == len(rig.members), 60, period_s=0.05)
    if not back:
        return Outcome(None, "the nodes never reconnected to the restarted router", ok=False)
    reconnected = max(rig.heard_at[v] for v in rig.members)

    def one_fleet() -> bool:
        infos = rig.fresh_infos(reconnected)
        flying = [i for i in infos.values() if i.mission_id == MISSION_ID]
        return len(infos) == len(rig.members) and len({i.members_hash for i in flying}) <= 1

    ok = rig.wait(one_fleet, 60, period_s=0.05)
    merged = time.monotonic() - reconnected
    with rig.lock:
        hashes = {i.members_hash for i in rig.infos if i.mission_id == MISSION_ID}
        mismatch = sum(a.code == AlertCode.ROSTER_MISMATCH for a in rig.alerts)
    return Outcome(
        merged if ok else None,
        f"router down {down_s:.0f} s; every node heard {reconnected - up:.1f} s after it was back; "
        f"one fleet {merged:.1f} s after that; {len(hashes - before)} roster(s) besides the "
        f"first, {mismatch} ROSTER_MISMATCH alert(s)",
        ok and merged <= ONE_FLEET_S,
    )


def p_reboot_in_flight(rig: Rig) -> Outcome:
    """Autopilot 8 rebooted at 40 % of its share (it boots again disarmed where it
    stands, `SimAutopilot.rebooted`); recovered when node 8 left the mission and every
    peer flies under a new roster, one for all (at most 5 s). Then node 9 is killed and
    restarted 5 s later, 20 s on (an unrelated replan): nothing may arm vehicle 8."""
    if not _at(rig):
        return Outcome(None, "never reached 40 %", ok=False)
    peers = [v for v in rig.members if v != VICTIM]
    before = {rig.info(v).members_hash for v in peers}  # type: ignore[union-attr]
    t0 = time.monotonic()
    rig.rebooted_at[VICTIM] = t0
    rig.server.reboot(VICTIM)

    def handed_on() -> bool:
        infos = rig.fresh_infos(t0)
        if len(infos) < len(rig.members):
            return False
        st = rig.status(VICTIM)
        left = infos[VICTIM].mission_id != MISSION_ID or (
            st is not None
            and st.mission_state not in (MissionState.MISSION, MissionState.PREMISSION)
        )
        theirs = {infos[v].members_hash for v in peers if infos[v].mission_id == MISSION_ID}
        return left and len(theirs) == 1 and not theirs & before

    ok = rig.wait(handed_on, 60, period_s=0.05)
    recover = time.monotonic() - t0
    time.sleep(20.0)
    other = max(peers)
    n = rig.nodes[other]
    n.signal(signal.SIGKILL)
    n.proc.wait(10)  # type: ignore[union-attr]
    time.sleep(5.0)
    n.start()
    rig.wait(lambda: _reattach_seen(n), 60)
    rig.wait(rig.landed, 600, period_s=0.5)  # every arm counted by the note's end
    return Outcome(
        recover if ok else None,
        f"share handed on {recover:.1f} s after the reboot; node {other} killed and "
        f"restarted 20 s later ({_reattached(n)}); {rig.unexpected_arms} unexpected arm(s)",
        ok and recover <= HANDED_ON_S,
    )


PROCESS_FAULTS: dict[str, Callable[[Rig], Outcome]] = {
    "none": p_none,
    "kill -9 a node (restarted after 5 s)": p_kill,
    "SIGSTOP a node 3 s": p_sigstop,
    "restart an autopilot (empty stores)": p_autopilot,
    "clock jump +1 h on one node": p_clock,
    "disk full on the database": p_disk_full,
    "corrupted database at start (new one)": p_corrupt,
    "node down 10 s (its aircraft flies on)": p_sigterm,
    "restart the router (down 3 s)": p_router,
    "restart the router (down 20 s)": lambda rig: p_router(rig, 20.0),
    "reboot an autopilot in flight": p_reboot_in_flight,
}
# the faults flown by three quadcopters, each node with its own database
ON_THREE = {
    "node down 10 s (its aircraft flies on)",
    "restart the router (down 3 s)",
    "restart the router (down 20 s)",
    "reboot an autopilot in flight",
}


def run_process_fault(name: str, keep: Path | None = None) -> FaultRow:
    t_wall = time.perf_counter()
    tmp = Path(tempfile.mkdtemp(prefix="bandada-fault-"))
    kw: dict[str, object] = {}
    if name.startswith("clock jump"):
        # steps an hour ahead about 60 s after start: during the mission
        kw["victim_env"] = {"BANDADA_CLOCK": f"stepping:{time.time() + 60.0!r}:3600.0"}
    if name.startswith("disk full"):
        if os.geteuid() != 0:
            return FaultRow(
                name,
                mission_name(MEMBERS),
                "processes",
                False,
                None,
                0.0,
                False,
                0,
                0,
                note="skipped: a full filesystem needs root to mount",
            )
        kw["victim_limit"] = True
    if name.startswith("corrupted"):
        kw["victim_db"] = True
    members = THREE if name in ON_THREE else MEMBERS
    if name in ON_THREE:
        kw |= {"members": THREE, "own_dbs": True}
    rig = start_rig(tmp, **kw)  # type: ignore[arg-type]
    note, completed, coverage, lost, false, emerg = "", False, 0.0, 0, 0, Counter[str]()
    outcome = Outcome(None, "not run", ok=False)
    try:
        declare_all(rig)
        outcome = PROCESS_FAULTS[name](rig)

        def flown() -> bool:  # the survey was flown (or began), and everyone is down
            with rig.lock:
                began = any(st.mission_state == MissionState.MISSION for st in rig.statuses)
            return began and rig.landed()

        finished = rig.wait(flown, 900, period_s=0.5)
        with rig.lock:
            alerts = list(rig.alerts)
            infos = list(rig.infos)
        completed = any(
            a.code == AlertCode.MISSION_COMPLETE and a.text == f"mission {MISSION_ID}"
            for a in alerts
        )
        coverage = rig.coverage()
        lost = rig.declared_lost()
        emerg = Counter(
            f"{i.fsm_state.name} (vehicle {i.vehicle_id})"
            for i in infos
            if i.fsm_state == FsmState.EMERGENCY
        )
        false = sum(
            1
            for a in alerts
            if a.code == AlertCode.AUTOPILOT_LINK_LOSS and a.severity >= Severity.CRITICAL
        )
        note = outcome.note + ("" if finished else "; not all landed in time")
        if rig.victim_watched:
            closest = rig.victim_closest_m
            note += f"; closest to aircraft {VICTIM} after the fault: {closest:.1f} m (true)"
            outcome.ok = outcome.ok and closest >= CLEAR_OF_VICTIM_M
        counts = Counter(
            f"{a.severity.name} {a.code.name}" for a in alerts if a.severity >= Severity.WARNING
        )
    except Exception as exc:  # a row that breaks is reported, the campaign goes on
        note, counts, finished = f"{outcome.note}; failed: {exc}", Counter(), False
    finally:
        rig.close()
        unmount(tmp / "full-disk")
        if keep is not None:
            shutil.copytree(
                tmp, keep / name.replace(" ", "_").replace("/", "_"), dirs_exist_ok=True
            )
        shutil.rmtree(tmp, ignore_errors=True)
    recovered = (
        outcome.ok
        and outcome.recover_s is not None
        and finished
        and completed
        and coverage >= 0.95
        and lost == 0
        and false == 0
        and rig.unexpected_arms == 0
    )
    return FaultRow(
        fault=name,
        mission=mission_name(members),
        env="processes",
        recovered=recovered,
        recover_s=None if outcome.recover_s is None else round(outcome.recover_s, 2),
        coverage=round(coverage, 4),
        mission_completed=completed,
        declared_state_lost=lost,
        false_emergencies=false,
        emergencies=dict(emerg),
        alerts=dict(sorted(counts.items())),
        note=note,
        wall_s=round(time.perf_counter() - t_wall, 2),
        unexpected_arms=rig.unexpected_arms,
        min_true_sep_m=round(rig.min_true_sep_m, 1) if math.isfinite(rig.min_true_sep_m) else None,
    )


def campaign_processes(faults: list[str] | None = None) -> list[FaultRow]:
    return [run_process_fault(f) for f in (faults or list(PROCESS_FAULTS))]
