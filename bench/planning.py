"""Planning off the node's control loop: which worker keeps the
loop's rate while a 4,000-vertex area mission is planned.

A stand-in for the node's loop ticks every 10 ms (what it needs: 5 Hz status, 5 Hz
state machine, commands as they come) while the same plan job (`run_plan`) runs
inline (today's defect), in a thread (the GIL is shared with the loop) and in a
spawn-context process pool of one (the runtime's `PlanWorker`, warmed up first).
Figures per worker: plan wall time, the loop's ticks achieved over ticks expected
(`tick_ratio`) and its longest gap (`max_gap_s`)."""

from __future__ import annotations

import itertools
import math
import multiprocessing
import threading
import time
from concurrent.futures import Executor, ProcessPoolExecutor, ThreadPoolExecutor
from typing import Any

from swarm_node.core.mission.share import Member, PlanRequest, run_plan
from swarm_node.database import seed_fleet
from swarm_proto import Geometry, GeoPoint, Mission, MissionParams, MissionType, geodesy

TICK_S = 0.01


def request(n: int = 4000) -> PlanRequest:
    profiles = {p.vehicle_id: p for p in seed_fleet()}
    lat0, lon0 = 37.4140, -5.9889
    pts = []
    for i in range(n):
        a = 2 * math.pi * i / n
        r = 150 + 20 * math.sin(7 * a)
        pts.append(geodesy.offset(lat0, lon0, r * math.sin(a), r * math.cos(a)))
    mission = Mission(
        1, 900, MissionType.AREA, Geometry.polygon(pts), MissionParams(altitude_rel_m=50.0)
    )
    members = (
        Member(profiles[7], GeoPoint(37.4112, -5.9889, 10.0)),
        Member(profiles[8], GeoPoint(37.4112, -5.9885, 10.0)),
    )
    return PlanRequest(1, mission, members, (), 0.0, 10.0)


def _loop_while(work: Any) -> dict[str, float]:
    """Tick every TICK_S while `work()` (which blocks until the plan is done) runs."""
    done = threading.Event()
    ticks: list[float] = []

    def loop() -> None:
        nxt = time.perf_counter()
        while not done.is_set():
            ticks.append(time.perf_counter())
            nxt += TICK_S
            time.sleep(max(0.0, nxt - time.perf_counter()))

    t = threading.Thread(target=loop)
    t.start()
    t0 = time.perf_counter()
    work()
    wall = time.perf_counter() - t0
    done.set()
    t.join()
    gaps = [b - a for a, b in itertools.pairwise(ticks)] or [wall]
    return {
        "plan_wall_s": round(wall, 2),
        "tick_ratio": round(len(ticks) / max(1.0, wall / TICK_S), 2),
        "max_gap_s": round(max(gaps), 3),
    }


def _inline(req: PlanRequest) -> dict[str, float]:
    # the loop itself plans: it cannot tick meanwhile
    t0 = time.perf_counter()
    run_plan(req)
    wall = time.perf_counter() - t0
    return {"plan_wall_s": round(wall, 2), "tick_ratio": 0.0, "max_gap_s": round(wall, 3)}


def _pooled(req: PlanRequest, pool: Executor) -> dict[str, float]:
    pool.submit(run_plan, PlanRequest(0, req.mission, req.members[:1], (), 0.0, 10.0)).result()
    return _loop_while(lambda: pool.submit(run_plan, req).result())


def run() -> dict[str, Any]:
    req = request()
    with ThreadPoolExecutor(1) as threads:
        thread = _pooled(req, threads)
    ctx = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(1, mp_context=ctx) as procs:
        process = _pooled(req, procs)
    return {
        "vertices": len(req.mission.geometry.points),
        "inline": _inline(req),
        "thread": thread,
        "process": process,
        "chosen": "process",
    }


if __name__ == "__main__":
    import json

    print(json.dumps(run(), indent=2))
