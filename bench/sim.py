"""How many simulated vehicles one core runs at 10x real time, and how fast a whole
simulated swarm runs.

A mixed fleet (VTOL, copter, plane, rover, boat in turn) is flown into the air in fast
time on looping missions (DO_JUMP forever), then measured two ways in the same run:

- baseline, pure cores: CPU seconds per simulated vehicle-second when the vehicles'
  endpoints are stepped deadline to deadline with default telemetry encoded to bytes
  (no sockets). At 10x real time a core has 0.1 CPU-s per simulated second, so the core
  capacity is 1 / (10 * that).
- the real thing: the same fleet served by one VehicleServer thread on TCP at a 10x
  ScaledClock, every vehicle with a client (in another process) reading its stream;
  the worst deadline lateness says whether the server kept up (`kept_pace`: at most
  0.5 simulated s late); only then does process CPU over the wall-clock window give
  `vehicles_per_core_at_10x` (null otherwise).
- the swarm: `swarm_rt_factor` for 10, 50 and 100 vehicles, each with its node core
  and autopilot link, nodes up on the ground, exchanging their status (5 Hz) and info
  (1 Hz): simulated seconds per wall second over 10 simulated seconds after 8 of
  warm-up (every node publishes its status from about 6.2 s; >= 10 keeps pace at 10x:
  `kept_pace_at_10x`); each run counts the swarm messages its nodes heard against what
  every node hearing every peer at those rates makes (`rates_kept`).
  `swarm_rt_factor` runs a LAN swarm (every node sees every peer's liveliness token,
  as Zenoh nodes do) on the machine's two cores (swarm_sim/parallel_fleet.py: FastFleet
  split in two processes, one clock); `swarm_rt_factor_telemetry_peers` the same two
  processes with peers known by their telemetry only (as behind a radio);
  `swarm_rt_factor_one_process` is FastFleet as it is (one process, peers known by
  telemetry), measured in the same run. `cpu_rt_factor`: simulated seconds per CPU
  second of the busiest process (what the run would reach alone on the machine).
"""

from __future__ import annotations

import heapq
import os
import resource
import subprocess
import sys
import time
from typing import Any

from swarm_proto.clock import ScaledClock
from swarm_sim.core import SITL_HOME, FastTimeHarness, HarnessLink, SimOptions
from swarm_sim.core.firmware import mode_number
from swarm_sim.core.geo import LocalFrame
from swarm_sim.core.streams import DEFAULT_INTERVALS_S
from swarm_sim.runtime import VehicleServer, VehicleSpec, spread_homes

MODELS = ("vtol", "copter", "plane", "rover", "boat")
SPEEDUP = 10.0
CORE_VEHICLES = 25
CORE_SIM_S = 300.0
TCP_WALL_S = 10.0
BASE_PORT = 17000
REL = 3
PACE_TOLERANCE_SIM_S = 0.5  # worst deadline lateness of a run that kept pace (50 ms wall at 10x)
SWARM_SIZES = (10, 50, 100)
SWARM_SIM_S = 30.0  # simulated seconds measured, after SWARM_WARM_S
# runs of each swarm, its figure their median: one 10 s window is about a second of wall
# time at 100 vehicles, and on this machine such windows ranged 7.4-11.8x one after the
# other with nothing else running (2026-11-26)
SWARM_RUNS = 3
# every node publishes its status from about 6.2 s (once its autopilot has a position):
# the measured window starts after that, every node hearing every peer at full rate
SWARM_WARM_S = 8.0


def _cmd(h: FastTimeHarness, link: HarnessLink, command: int, *params: float) -> None:
    p = [*params, *([0.0] * (7 - len(params)))]
    link.client.mav.command_long_send(link.autopilot.sysid, 1, command, 0, *p)
    h.run_for(0.2)


def _launch(h: FastTimeHarness, link: HarnessLink, k: int) -> None:
    ap, c = link.autopilot, link.client
    frame = LocalFrame(ap.frame.lat0, ap.frame.lon0)
    size = {"vtol": 800.0, "plane": 800.0, "copter": 150.0}.get(ap.model.value, 60.0)
    alt = {"vtol": 60.0, "plane": 60.0, "copter": 30.0}.get(ap.model.value, 0.0)
    takeoff = {"vtol": 84, "plane": 22, "copter": 22}.get(ap.model.value)
    items: list[tuple[int, float, float, float, float]] = [(16, 0, 0, 0, 0)]
    if takeoff is not None:
        items.append((takeoff, 0, 0, 40.0, 0))
    first = len(items)
    for n, e in ((size, 0), (size, size), (0, size), (0, 0.5)):
        items.append((16, n, e, alt, 0))
    items.append((177, 0, 0, 0, first))  # DO_JUMP to the first waypoint, forever
    c.mav.mission_count_send(ap.sysid, 1, len(items), 0)
    for _ in range(len(items)):
        req = h.wait_for(c, "MISSION_REQUEST", 5)
        assert req is not None, "vehicle did not ask for mission items"
        cmd, n, e, z, jump = items[req.seq]
        lat, lon = frame.to_latlon(n, e)
        x, y = (round(lat * 1e7), round(lon * 1e7)) if (n or e) else (0, 0)
        p1, p2 = (float(jump), -1.0) if cmd == 177 else (0.0, 0.0)
        c.mav.mission_item_int_send(ap.sysid, 1, req.seq, REL, cmd, 0, 1, p1, p2, 0, 0, x, y, z, 0)
    assert h.wait_for(c, "MISSION_ACK", 5) is not None
    if ap.model.value == "copter":
        _cmd(h, link, 176, 1, mode_number(ap.firmware, "GUIDED"))
        _cmd(h, link, 400, 1)
        _cmd(h, link, 22, 0, 0, 0, 0, 0, 0, 30)
        h.run_until(lambda: ap.rel_alt_m > 29, 60)
        _cmd(h, link, 176, 1, mode_number(ap.firmware, "AUTO"))
        _cmd(h, link, 300)
    else:
        _cmd(h, link, 176, 1, mode_number(ap.firmware, "AUTO"))
        _cmd(h, link, 400, 1)


def fleet(
    n: int, start_time: float, airborne_s: float = 150.0
) -> tuple[FastTimeHarness, list[HarnessLink]]:
    """`n` vehicles flying looping missions, `airborne_s` after launch. Built with
    HEARTBEAT only (fast), then every vehicle gets the default telemetry streams."""
    h = FastTimeHarness(start_time=start_time)
    homes = spread_homes(SITL_HOME, n, 30.0)
    quiet = SimOptions(stream_defaults={0: 1.0})
    links = [
        h.add_vehicle(MODELS[k % len(MODELS)], instance=k, home=homes[k], options=quiet)
        for k in range(n)
    ]
    h.run_until(lambda: all(link.autopilot.ekf_position for link in links), 60)
    for k, link in enumerate(links):
        _launch(h, link, k)
    h.run_for(airborne_s)
    flying = sum(1 for link in links if link.autopilot.armed and link.autopilot.mission_running)
    assert flying == n, f"only {flying}/{n} vehicles flying their missions"
    for link in links:
        link.client.clear()
        link.client.history.clear()
        for msg_id, interval in DEFAULT_INTERVALS_S.items():
            link.autopilot.streams.set_interval(msg_id, interval, h.now)
    return h, links


def core_cpu_per_vehicle_second(n: int, sim_s: float) -> tuple[float, float]:
    """(CPU s per simulated vehicle-second, telemetry messages per vehicle-second)."""
    h, links = fleet(n, 1_700_000_000.0)
    endpoints = [link.endpoint for link in links]
    heap: list[tuple[float, int]] = [
        (ep.next_deadline() or h.now, k) for k, ep in enumerate(endpoints)
    ]
    heapq.heapify(heap)
    end = h.now + sim_s
    tx0 = sum(ep.counters["tx_messages"] for ep in endpoints)
    cpu0 = time.process_time()
    while heap[0][0] <= end:
        t, k = heapq.heappop(heap)
        ep = endpoints[k]
        ep.on_timer(t)  # the bytes a client would get, encoded and dropped
        heapq.heappush(heap, (ep.next_deadline() or t + 1.0, k))
    cpu = time.process_time() - cpu0
    msgs = sum(ep.counters["tx_messages"] for ep in endpoints) - tx0
    return cpu / (n * sim_s), msgs / (n * sim_s)


_READER = """
import selectors, socket, sys, time
ports = [int(p) for p in sys.argv[1].split(',')]
stop_at = time.monotonic() + float(sys.argv[2])
sel = selectors.DefaultSelector()
for port in ports:
    s = socket.create_connection(('127.0.0.1', port))
    s.setblocking(False)
    sel.register(s, selectors.EVENT_READ)
print('connected', flush=True)
total = 0
while time.monotonic() < stop_at:
    for key, _ in sel.select(0.2):
        data = key.fileobj.recv(65536)
        total += len(data)
print(total, flush=True)
"""


def _cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def tcp_run(n: int, wall_s: float) -> dict[str, Any]:
    """The fleet on TCP at 10x with a reader per vehicle; CPU of this process."""
    h, links = fleet(n, time.time() + 3600.0)
    clock = ScaledClock(SPEEDUP, start_unix_s=h.now + 0.5)  # picks up where fast time ended
    ports = [BASE_PORT + k for k in range(n)]
    specs = [
        VehicleSpec(link.autopilot.model, instance=k, port=ports[k]) for k, link in enumerate(links)
    ]
    server = VehicleServer(specs, clock, endpoints=[link.endpoint for link in links])
    server.start_thread()
    reader = subprocess.Popen(
        [sys.executable, "-c", _READER, ",".join(map(str, ports)), str(wall_s + 4.0)],
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        assert reader.stdout is not None
        assert reader.stdout.readline().strip() == "connected"
        time.sleep(1.0)  # catch-up burst and connection set-up out of the window
        server.max_lag_s = 0.0
        tx0 = sum(ep.counters["tx_messages"] for ep in server.endpoints)
        cpu0, wall0 = _cpu(), time.perf_counter()
        time.sleep(wall_s)
        cpu, wall = _cpu() - cpu0, time.perf_counter() - wall0
        msgs = sum(ep.counters["tx_messages"] for ep in server.endpoints) - tx0
        lag = server.max_lag_s
        kept = lag <= PACE_TOLERANCE_SIM_S
        total_bytes = int(reader.stdout.readline().strip() or 0)
    finally:
        reader.wait(timeout=30)
        server.close()
    return {
        "tcp_vehicles": n,
        "tcp_cpu_fraction_of_a_core": round(cpu / wall, 3),
        "tcp_cpu_s_per_vehicle_second": round(cpu / (n * wall * SPEEDUP), 7),
        "tcp_max_deadline_lag_sim_s": round(lag, 3),
        "tcp_messages_per_vehicle_second": round(msgs / (n * wall * SPEEDUP), 1),
        "tcp_bytes_read_by_clients": total_bytes,
        "kept_pace": kept,
        # only a run that kept pace says how many vehicles a core runs at 10x
        "vehicles_per_core_at_10x": int(n * wall / cpu) if cpu > 0 and kept else None,
    }


def _swarm_profiles(n: int) -> dict[int, Any]:
    """`n` node profiles (ids 1..n), the seed vehicles' profiles in turn."""
    import msgspec

    from swarm_node.database import seed_fleet
    from swarm_sim.fast_fleet import MODEL_OF_TYPE

    seeds = [p for p in seed_fleet() if p.vehicle_type in MODEL_OF_TYPE]  # no ground station
    return {
        vid: msgspec.structs.replace(seeds[(vid - 1) % len(seeds)], vehicle_id=vid)
        for vid in range(1, n + 1)
    }


def swarm_rt(
    n: int,
    sim_s: float = SWARM_SIM_S,
    warm_s: float = SWARM_WARM_S,
    *,
    parts: int = 1,
    liveliness: bool = False,
) -> dict[str, Any]:
    """A whole swarm (vehicles, their links and node cores exchanging real MAVLink and
    swarm messages), on the ground, nodes up and publishing: simulated seconds per wall
    second over `sim_s` after `warm_s`. One part: FastFleet as it is; more: split over
    that many processes (ParallelFleet). `liveliness`: a LAN swarm, every node sees
    every peer's liveliness token (as Zenoh nodes do); otherwise peers are known by
    their telemetry only (as behind a radio). The swarm messages the nodes heard are
    counted against what every node hearing every peer at its rates makes."""
    from swarm_node.core.node import NodeSettings
    from swarm_sim.fast_fleet import FastFleet
    from swarm_sim.parallel_fleet import ParallelFleet

    profiles = _swarm_profiles(n)
    if parts == 1:
        fleet = FastFleet.build(list(range(1, n + 1)), profiles)
        if liveliness:
            fleet.hold_tokens()
        fleet.run_for(warm_s)
        heard0 = fleet.heard_messages
        cpu0, wall0 = time.process_time(), time.perf_counter()
        fleet.run_for(sim_s)
        cpu, wall = time.process_time() - cpu0, time.perf_counter() - wall0
        heard = fleet.heard_messages - heard0
    else:
        with ParallelFleet(range(1, n + 1), profiles, parts=parts, liveliness=liveliness) as pf:
            pf.run_for(warm_s)
            heard0 = pf.heard_messages()
            cpu_warm = _part_cpu(pf)
            wall0 = time.perf_counter()
            pf.run_for(sim_s)
            wall = time.perf_counter() - wall0
            cpu = max(c - c0 for c, c0 in zip(_part_cpu(pf), cpu_warm, strict=True))
            heard = pf.heard_messages() - heard0
    s = NodeSettings()
    expected = n * (n - 1) * (1.0 / s.status_period_s + 1.0 / s.info_period_s)
    return {
        "processes": parts,
        "peers_known_by": "liveliness token" if liveliness else "telemetry",
        "sim_s": sim_s,
        "wall_s": round(wall, 2),
        "rt_factor": round(sim_s / wall, 2),
        "cpu_rt_factor": round(sim_s / cpu, 2) if cpu > 0 else None,
        "kept_pace_at_10x": sim_s / wall >= SPEEDUP,
        # every node hears every peer's status (5 Hz) and info (1 Hz)
        "peer_messages_heard_per_s": round(heard / sim_s),
        "peer_messages_expected_per_s": round(expected),
        "rates_kept": heard / sim_s >= 0.99 * expected,
    }


def median_run(run_once: Any, runs: int = SWARM_RUNS) -> dict[str, Any]:
    """`runs` runs of one swarm: the run with the median wall time, with every run's
    real-time factor beside it (`rt_factor_runs`) and whether all of them kept pace."""
    results = [run_once() for _ in range(runs)]
    mid = sorted(results, key=lambda r: r["wall_s"])[len(results) // 2]
    return {
        **mid,
        "runs": runs,
        "rt_factor_runs": [r["rt_factor"] for r in results],
        "kept_pace_at_10x_every_run": all(r["kept_pace_at_10x"] for r in results),
    }


def _part_cpu(pf: Any) -> list[float]:
    """CPU seconds so far of each part of a ParallelFleet (this process, its workers)."""
    out = [time.process_time()]
    for proc, _conn in pf.workers:
        out.append(_proc_cpu_s(proc.pid))
    return out


def _proc_cpu_s(pid: int) -> float:
    with open(f"/proc/{pid}/stat") as f:
        fields = f.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def run() -> dict[str, Any]:
    per_vs, msgs_per_vs = core_cpu_per_vehicle_second(CORE_VEHICLES, CORE_SIM_S)
    core_capacity = 1.0 / (SPEEDUP * per_vs)
    n_tcp = max(10, min(100, int(0.6 * core_capacity)))
    result = {
        "speedup": SPEEDUP,
        "fleet": "/".join(MODELS) + " in turn, flying looping missions, default telemetry",
        "baseline_cpu_s_per_vehicle_second_1x": round(per_vs, 7),
        "baseline_telemetry_messages_per_vehicle_second": round(msgs_per_vs, 1),
        "core_only_vehicles_per_core_at_10x": int(core_capacity),
    }
    result |= tcp_run(n_tcp, TCP_WALL_S)
    # the baseline: FastFleet as it is (one process, peers known by telemetry); the
    # figure: the LAN swarm on the machine's two cores; beside it, the same two
    # processes with peers known by telemetry only (a swarm behind a radio)
    one = {f"vehicles_{n}": median_run(lambda n=n: swarm_rt(n)) for n in SWARM_SIZES}
    two = {
        f"vehicles_{n}": median_run(lambda n=n: swarm_rt(n, parts=2, liveliness=True))
        for n in SWARM_SIZES
    }
    radio = {
        f"vehicles_{n}": median_run(lambda n=n: swarm_rt(n, parts=2)) for n in SWARM_SIZES[-1:]
    }
    result["swarm"] = two
    result["swarm_rt_factor"] = {k: v["rt_factor"] for k, v in two.items()}
    result["kept_pace_swarm_at_10x"] = {k: v["kept_pace_at_10x"] for k, v in two.items()}
    result["swarm_one_process"] = one
    result["swarm_rt_factor_one_process"] = {k: v["rt_factor"] for k, v in one.items()}
    result["swarm_telemetry_peers"] = radio
    result["swarm_rt_factor_telemetry_peers"] = {k: v["rt_factor"] for k, v in radio.items()}
    result["load_average_1min"] = round(os.getloadavg()[0], 2)
    return result


if __name__ == "__main__":
    import json

    print(json.dumps(run(), indent=2))
