"""The demo's fleet: simulated ArduPilot vehicles and one `swarm-node run` process per
vehicle, on this machine, in fast time, through the real stack; `make demo` flies the
paper's experiment 1 with it (swarm_sim/experiment.py, story.py).

    simulated ArduPilot vehicles (MAVLink on TCP, one thread)     swarm_sim.runtime
      <-> one `swarm-node run` process per vehicle                 swarm_node
      <-> Zenoh on 127.0.0.1 (a router-mode session here)
      <-> the ground station (the demo's process)                  gcs_cli.ground

With `radio=True` (`swarm-sim demo --radio`) nothing crosses Zenoh between vehicles:
each vehicle's node and its `radio-gateway run` process share a Zenoh network of their
own (as on a companion computer), the ground station and its gateway another, and the
gateways talk over the emulated XTend channel (pseudo-terminals, TDM slots, framing,
authentication), after configuring their modules through AT command mode.

Every process shares one simulated clock (BANDADA_CLOCK) and one seeded swarm database
(BANDADA_DB) in a temporary directory. `demo_area` is the earlier demo's survey (a
reference scenario of tests and benchmarks).
"""

from __future__ import annotations

import dataclasses
import multiprocessing
import multiprocessing.process
import os
import queue
import random
import signal
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from rich.console import Console

from swarm_node.database import SwarmDatabase
from swarm_proto import (
    Geometry,
    NoFlyZone,
    ScaledClock,
    geodesy,
)
from swarm_proto.clock import ENV_VAR as CLOCK_ENV
from swarm_proto.clock import clock_from_spec
from swarm_proto.messages import RadioStats
from swarm_proto.session import ZenohSettings, open_session

from .core import SITL_HOME
from .fast_fleet import MODEL_OF_TYPE
from .runtime import VehicleServer, VehicleSpec, spread_homes

if TYPE_CHECKING:
    from .radio_channel.pty import ChannelProcess

DEFAULT_FLEET = (1, 2, 3, 7, 8)  # seed ids: three Albatross 250 VTOL, two quadcopters
GCS_ID = 900
MISSION_ID = 1001
ZONE_ID = 1


#: a node's plan timeout on a computer of its own (the node's default, NodeConfig)
NODE_PLAN_TIMEOUT_S = 60.0


def plan_timeout_s(speedup: float, nodes: int = 1, cpus: int | None = None) -> float:
    """The nodes' planning time limit on the scaled clock. Planning is real work in wall
    time, so the node's 60 s is wall time (at 5x, 60 s of simulated time would leave
    12 s). And the demo runs `nodes` companion computers on this machine's `cpus`
    cores: every node plans the whole fleet's plan at once (leaderless), each with
    cpus/nodes of a core where it would have its own; the 60 s are stretched by as much
    (eleven nodes on two cores: 330 s of wall time; their survey plan took 52 s with
    the machine's load at 19, and a run missed the unstretched 60 s)."""
    share = max(1.0, nodes / max(1, cpus or os.cpu_count() or 1))
    return min(3600.0, NODE_PLAN_TIMEOUT_S * max(1.0, speedup) * share)


def link_timeout_s(speedup: float) -> float:
    """The nodes' autopilot link timeout, in simulated seconds: 2 s of wall time. A real
    vehicle uses 0.6 s; in fast time on a shared laptop a busy moment of a few hundred
    milliseconds would otherwise count as a lost autopilot and put the fleet in
    STATE_EMERGENCY."""
    return min(30.0, max(0.6, 2.0 * speedup))


def free_tcp_port(rng: random.Random | None = None) -> int:
    """A free loopback TCP port for another process to listen on, chosen below the
    kernel's ephemeral range: the kernel's own pick (port 0) comes from that range, which
    every outgoing connection on a busy host draws from too, so it could be taken
    before the listener binds it."""
    rng = rng or random.Random()
    low = _ephemeral_low()
    for _ in range(50):
        port = rng.randrange(max(1024, low - 12_000), low)
        with socket.socket() as s:
            try:
                s.bind(("127.0.0.1", port))
            except OSError:
                continue
            return port
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def open_router(tries: int = 5) -> tuple[str, Any]:
    """A router-mode Zenoh session listening on a free loopback port: its endpoint and
    the session (another port while the one picked was taken before the bind)."""
    import zenoh

    for attempt in range(tries):
        endpoint = f"tcp/127.0.0.1:{free_tcp_port()}"
        try:
            return endpoint, open_session(ZenohSettings(mode="router", listen=(endpoint,)))
        except zenoh.ZError:
            if attempt == tries - 1:
                raise
    raise AssertionError("unreachable")


def _ephemeral_low(path: str = "/proc/sys/net/ipv4/ip_local_port_range") -> int:
    try:
        with open(path) as f:
            return max(2048, int(f.read().split()[0]))
    except (OSError, ValueError, IndexError):
        return 32768  # Linux's default


def offset(lat: float, lon: float, north_m: float, east_m: float) -> tuple[float, float]:
    return geodesy.offset(lat, lon, north_m, east_m)  # the one geodesy (swarm_proto.geodesy)


def demo_area() -> tuple[Geometry, NoFlyZone]:
    """A 300 m x 260 m field north of the vehicles, with a 35 m no-fly zone inside it."""
    lat0, lon0 = offset(SITL_HOME.lat_deg, SITL_HOME.lon_deg, 200.0, 0.0)
    corners = [offset(lat0, lon0, n, e) for n, e in ((0, -150), (0, 150), (260, 150), (260, -150))]
    zlat, zlon = offset(lat0, lon0, 130.0, 40.0)
    zone = NoFlyZone(
        ZONE_ID,
        Geometry.circle(zlat, zlon, 35.0),
        floor_alt_msl_m=-100.0,
        ceiling_alt_msl_m=500.0,
        name="demo zone",
    )
    return Geometry.polygon(corners), zone


@dataclass
class Fleet:
    tmp: Path
    router: object | None  # the Zenoh router (LAN mode)
    simulator: multiprocessing.process.BaseProcess
    stop_simulator: object
    nodes: dict[int, subprocess.Popen[bytes]]
    endpoint: str  # where the ground station connects
    gateways: dict[int, subprocess.Popen[bytes]] = field(default_factory=dict)
    channel: ChannelProcess | None = None  # the emulated radio channel (radio mode)
    clock_spec: str = ""  # the shared simulated clock (BANDADA_CLOCK)
    crashes: Any = None  # a queue to the simulator: system ids of vehicles that crash
    lans: dict[int, str] = field(default_factory=dict)  # each node's Zenoh network (radio: its own)

    def crash(self, vid: int) -> None:
        """Take the vehicle's aircraft out of the simulator (`VehicleServer.remove`)."""
        if self.crashes is not None:
            self.crashes.put(vid)


# In radio mode the gateways and the channel keep the default priority and everything
# else yields to them, as on a vehicle (deploy/systemd/radio-gateway.service: Nice=-10):
# TDM slots leave a 5 ms guard, and a laptop running a whole swarm is busy.
YIELD_TO_RADIO = 5


def _spawn(
    cmd: list[str], log_path: Path, env: dict[str, str], *, nice: int = 0
) -> subprocess.Popen[bytes]:
    log = open(log_path, "wb")  # noqa: SIM115
    try:
        proc = subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT, env=env)
    finally:
        log.close()
    if nice:
        os.setpriority(os.PRIO_PROCESS, proc.pid, nice)
    return proc


def start_radio(
    members: tuple[int, ...], clock: ScaledClock, tmp: Path, env: dict[str, str]
) -> tuple[ChannelProcess, dict[int, str], dict[int, subprocess.Popen[bytes]]]:
    """The emulated channel (its own process) and one gateway per node: returns the
    channel, the Zenoh endpoint each node's gateway listens on, and the gateways."""
    import secrets

    from .radio_channel.model import ChannelParams
    from .radio_channel.pty import ChannelProcess

    ids = (*members, GCS_ID)
    # modules straight from the factory (9600 baud): each gateway configures its own
    channel = ChannelProcess(len(ids), ChannelParams(seed=1), clock, registers=None)
    key = tmp / "swarm.key"
    key.write_text(secrets.token_hex(32) + "\n")
    key.chmod(0o600)
    ports = dict(zip(ids, channel.ports, strict=True))

    def spawn(nid: int) -> tuple[str, subprocess.Popen[bytes]]:
        endpoint = f"tcp/127.0.0.1:{free_tcp_port()}"
        argv = [sys.executable, "-m", "radio_gateway.cli", "run", "--node-id", str(nid)]
        argv += ["--port", ports[nid], "--key-file", str(key), "--listen", endpoint]
        argv += ["--members", ",".join(map(str, ids)), "--configure"]
        return endpoint, _spawn(argv, tmp / f"radio-{nid}.log", env)

    started = {nid: spawn(nid) for nid in ids}
    endpoints: dict[int, str] = {}
    gateways: dict[int, subprocess.Popen[bytes]] = {}
    try:
        for nid in ids:
            endpoints[nid], gateways[nid] = _listening(nid, started[nid], spawn, tmp)
    except BaseException:
        for _, proc in started.values():
            proc.kill()
        for proc in gateways.values():
            proc.kill()
        channel.close()
        raise
    return channel, endpoints, gateways


def _listening(
    nid: int,
    started: tuple[str, subprocess.Popen[bytes]],
    spawn: Callable[[int], tuple[str, subprocess.Popen[bytes]]],
    tmp: Path,
    timeout_s: float = 60.0,
    tries: int = 5,
) -> tuple[str, subprocess.Popen[bytes]]:
    """The gateway of node `nid` once it listens on its endpoint (its log says "zenoh
    session open"), started again on another port while the one picked for it was taken
    before it could bind: between `free_tcp_port` and the gateway's bind another process
    on a busy host may listen there, and a node connected to it would join a stranger's
    network. SystemExit with the gateway's last words if it fails otherwise."""
    from radio_gateway.runtime.gateway import EXIT_ZENOH

    log = tmp / f"radio-{nid}.log"
    endpoint, proc = started
    for _ in range(tries):
        end = time.monotonic() + timeout_s
        while time.monotonic() < end and proc.poll() is None:
            if b"zenoh session open" in log.read_bytes():
                return endpoint, proc
            time.sleep(0.05)
        code = proc.poll()
        if code != EXIT_ZENOH:
            proc.kill()
            tail = log.read_text(errors="replace").strip().splitlines()[-5:]
            raise SystemExit(
                f"radio gateway {nid} did not start (exit {code}):\n  " + "\n  ".join(tail)
            )
        started = spawn(nid)  # its endpoint was taken: another port
        endpoint, proc = started
    raise SystemExit(f"radio gateway {nid}: no free endpoint in {tries} tries")


def serve_vehicles(
    specs: list[VehicleSpec],
    clock_spec: str,
    stop: threading.Event,
    nice: int = 0,
    crashes: Any = None,
    bound: Any = None,
) -> None:
    """The simulated vehicles, in a process of their own (spawned): the ground station
    and Zenoh in the demo process must not slow the vehicles' clock-driven loop.
    `crashes`: a queue of system ids whose aircraft are taken away; `bound`: a queue
    that gets the list of ports the vehicles listen on once they do."""
    if nice:
        os.nice(nice)
    with VehicleServer(specs, clock_from_spec(clock_spec)) as server:
        if bound is not None:
            bound.put(server.ports)
        while not stop.wait(0.2):
            while crashes is not None:
                try:
                    server.remove(int(crashes.get_nowait()))
                except queue.Empty:
                    break


def _bound_ports(bound: Any, simulator: Any, timeout_s: float = 120.0) -> list[int]:
    """The ports the simulator process listens on, or SystemExit if it died first.
    (Ports picked free here and bound there were a race: another process on a busy
    machine took one in between, and every node found no autopilot.)"""
    end = time.monotonic() + timeout_s
    while time.monotonic() < end:
        try:
            return list(bound.get(timeout=0.5))
        except queue.Empty:
            if not simulator.is_alive():
                raise SystemExit(f"the simulator stopped (exit {simulator.exitcode})") from None
    raise SystemExit("the simulator did not start its vehicles in time")


def start(
    members: tuple[int, ...],
    speedup: float,
    tmp: Path,
    console: Console,
    *,
    radio: bool = False,
    avoidance: bool = False,
    spacing_m: float = 40.0,
) -> Fleet:
    db_path = tmp / "swarm.db"
    with SwarmDatabase.open(db_path) as db:
        profiles = {p.vehicle_id: p for p in db.profiles()}
    unknown = [
        m for m in members if m not in profiles or profiles[m].vehicle_type not in MODEL_OF_TYPE
    ]
    if unknown:
        raise SystemExit(f"not vehicles of the seed database: {unknown}")
    clock = ScaledClock(speedup)
    homes = spread_homes(SITL_HOME, len(members), spacing_m)
    specs = [
        VehicleSpec(
            MODEL_OF_TYPE[profiles[vid].vehicle_type],
            instance=i,
            home=homes[i],
            sysid=vid,
            port=0,  # the simulator binds free ports and says which (no race for them)
        )
        for i, vid in enumerate(members)
    ]
    ctx = multiprocessing.get_context("spawn")
    stop_simulator = ctx.Event()
    crashes = ctx.Queue()
    bound = ctx.Queue()
    simulator = ctx.Process(
        target=serve_vehicles,
        args=(specs, clock.spec(), stop_simulator, YIELD_TO_RADIO if radio else 0, crashes, bound),
        name="vehicles",
    )
    simulator.start()
    specs = [
        dataclasses.replace(spec, port=port)
        for spec, port in zip(specs, _bound_ports(bound, simulator), strict=True)
    ]
    env = {
        **os.environ,
        CLOCK_ENV: clock.spec(),
        "BANDADA_DB": str(db_path),
        "PYTHONUNBUFFERED": "1",
    }
    router: object | None = None
    channel: ChannelProcess | None = None
    gateways: dict[int, subprocess.Popen[bytes]] = {}
    if radio:  # each node on its own gateway's Zenoh network, the air between them
        channel, lans, gateways = start_radio(members, clock, tmp, env)
    else:  # every node and the ground station on one Zenoh network
        endpoint, router = open_router()
        lans = dict.fromkeys((*members, GCS_ID), endpoint)
    nodes = {}
    for spec, vid in zip(specs, members, strict=True):
        nodes[vid] = _spawn(
            node_argv(
                vid,
                spec.tcp_port,
                lans[vid],
                radio=radio,
                speedup=speedup,
                fleet_size=len(members),
                avoidance=avoidance,
            ),
            tmp / f"node-{vid}.log",
            env,
            nice=YIELD_TO_RADIO if radio else 0,
        )
    for spec, vid in zip(specs, members, strict=True):
        console.print(
            f"  vehicle {vid}: {profiles[vid].model} ({profiles[vid].user_id}), simulated on tcp:127.0.0.1:{spec.tcp_port}"
        )
    if radio:
        console.print(
            f"  radio: {len(members) + 1} emulated XTend modules on one channel "
            "(115.2 kbps, 200 ms TDM cycle), one gateway per node"
        )
    return Fleet(
        tmp,
        router,
        simulator,
        stop_simulator,
        nodes,
        lans[GCS_ID],
        gateways,
        channel,
        clock.spec(),
        crashes,
        lans,
    )


def node_argv(
    vid: int,
    autopilot_port: int,
    connect: str,
    *,
    radio: bool,
    speedup: float,
    fleet_size: int,
    avoidance: bool,
) -> list[str]:
    """The command line of the demo's node for vehicle `vid` (its autopilot simulated on
    `autopilot_port`, its Zenoh network at `connect`)."""
    return [
        sys.executable,
        "-m",
        "swarm_node.cli",
        "run",
        "--id",
        str(vid),
        "--autopilot",
        f"tcp:127.0.0.1:{autopilot_port}",
        "--connect",
        connect,
        *zenoh_role(radio),
        "--link-timeout",
        str(link_timeout_s(speedup)),
        "--plan-timeout",
        str(plan_timeout_s(speedup, fleet_size)),
        "--avoidance" if avoidance else "--no-avoidance",
    ]


def zenoh_role(radio: bool) -> tuple[str, ...]:
    """How a demo node joins Zenoh. On the LAN it is a client of the demo's router, which
    routes everything: a zenoh 1.10 peer never re-makes a direct (gossip) link to another
    peer once that link drops (a stall past the lease under load), and the router does
    not carry peer-to-peer traffic, so the two would stay deaf to each other for good;
    a client re-dials its router at once (tests/swarm_proto/test_link_cuts.py). Behind
    the radio a node is a peer of its own gateway."""
    return ("--mode", "peer", "--listen", "tcp/127.0.0.1:0") if radio else ("--mode", "client")


def _interrupt(processes: list[subprocess.Popen[bytes]]) -> None:
    for p in processes:
        if p.poll() is None:
            p.send_signal(signal.SIGINT)
    for p in processes:
        try:
            p.wait(15)
        except subprocess.TimeoutExpired:
            p.kill()


def stop(fleet: Fleet) -> None:
    _interrupt(list(fleet.nodes.values()))
    _interrupt(list(fleet.gateways.values()))
    fleet.stop_simulator.set()  # type: ignore[attr-defined]
    fleet.simulator.join(15)
    if fleet.simulator.is_alive():
        fleet.simulator.kill()
    if fleet.crashes is not None:
        fleet.crashes.close()
        fleet.crashes.join_thread()
    if fleet.channel is not None:
        fleet.channel.close()
    if fleet.router is not None:
        fleet.router.close()  # type: ignore[attr-defined]


def radio_up(
    stats: dict[int, RadioStats], members: tuple[int, ...], fleet: Fleet, console: Console
) -> dict[str, int]:
    """Wait until the ground station's gateway follows a table of every node; return
    the channel's counts until then and count the TDM from zero. Until then the gateways
    were configuring their modules: probing a module's serial rate at the wrong baud
    reaches the air as noise, as it would from a real XTend (docs/radio.md)."""
    want = {*members, GCS_ID}
    end = time.monotonic() + 120.0
    while time.monotonic() < end:
        s = stats.get(GCS_ID)
        if s is not None and s.phase == "member" and set(s.members) == want:
            break
        time.sleep(0.2)
    else:
        console.print("[yellow]radio: the slot table never included every node[/]")
    channel = fleet.channel
    assert channel is not None
    before: dict[str, int] = dict(channel.stats()["channel"])
    channel.reset_stats()
    console.print(
        f"  radio up: {len(want)} nodes in one slot table; before it (AT configuration, "
        f"bootstrap) {before.get('packets', 0)} packets went on air, "
        f"{before.get('collisions', 0)} overlapping"
    )
    return before


def radio_report(
    stats: RadioStats | None, fleet: Fleet, configuring: dict[str, int], console: Console
) -> bool:
    """What the ground station's gateway heard, and what the channel saw since the
    slot table was up (the TDM's promise: no collisions)."""
    assert fleet.channel is not None
    every = fleet.channel.stats()
    channel = every["channel"]
    collisions = int(channel.get("collisions_tdm", 0))  # between packets written on time
    if stats is None:
        console.print("[red]radio: no statistics from the ground station's gateway[/]")
        return False
    peers = ", ".join(
        f"{p.node_id}: {p.packets_per_s:.1f}/s loss {p.loss:.0%}" for p in stats.peers
    )
    console.print(
        f"radio: table {stats.members}, {stats.phase}, slot {stats.slot_s * 1000:.1f} ms; "
        f"heard {peers}; {stats.dropped_forged} forged, {stats.dropped_corrupt} corrupt; "
        f"{channel.get('packets', 0)} packets and {collisions} collisions on the channel "
        "since the table was up"
        + (
            f" ({channel['collisions_late']} more with a packet the emulator, descheduled "
            f"by this machine's load, read late: {every.get('late_reads', 0)} late reads)"
            if channel.get("collisions_late")
            else ""
        )
    )
    return collisions == 0
