"""Planning library figures (issue 5): coverage against the Fields2Cover reference
polygons, exact Dubins against OMPL, heterogeneous split makespan.

Coverage: lanes, coverage at the lane spacing, overlap, path length with R = 30 m
turns, sweep-direction search time (median), whole lane-plan time; the reference
figures (Fields2Cover 2.1.0, ../shared/bench/coverage_polygons.json) beside ours.
Dubins: 100k random pose pairs, batch (numpy) time per path vs OMPL's
DubinsStateSpace.distance per call through its Python bindings, in the same run, and
the largest length difference. Split: speeds 18/18/12 m/s, makespan / ideal - 1 with
ideal = single-vehicle path / sum of speeds.
"""

from __future__ import annotations

import json
import math
import statistics
import time
from pathlib import Path
from typing import Any

import numpy as np
from shapely.geometry import Polygon

from swarm_node.core.planning import (
    DubinsTurns,
    SweepCost,
    Worker,
    batch_lengths,
    decompose,
    lane_spacing_m,
    plan_lanes,
    split_lanes,
    sweep_angles,
)

REPO = Path(__file__).resolve().parents[1]
REFS = REPO.parent / "shared" / "bench" / "coverage_polygons.json"
R_M = 30.0
N_PAIRS = 100_000


def _median_ms(fn: Any, repeat: int = 7) -> float:
    samples = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        samples.append((time.perf_counter() - t0) * 1e3)
    return round(statistics.median(samples), 2)


def coverage(refs: dict[str, Any]) -> dict[str, Any]:
    cam = refs["camera"]
    spacing = lane_spacing_m(cam["altitude_m"], cam["hfov_deg"], cam["side_overlap"])
    turns = DubinsTurns(R_M)
    cost = SweepCost.for_turns(turns, spacing)
    out: dict[str, Any] = {}
    for name, poly in refs["polygons"].items():
        region = decompose(Polygon(poly["shell"], poly["holes"]))
        sweep_ms = _median_ms(lambda region=region: sweep_angles(region, spacing, cost))
        t0 = time.perf_counter()
        lp = plan_lanes(region, spacing, turns)
        plan_ms = round((time.perf_counter() - t0) * 1e3, 1)
        ref = poly["reference"]
        out[name] = {
            "lanes": len(lp.lanes),
            "coverage": round(lp.coverage, 4),
            "overlap": round(lp.overlap, 4),
            "path_m": round(lp.path.length_m, 1),
            "sweep_ms": sweep_ms,
            "plan_ms": plan_ms,
            "sweep_deg": round(math.degrees(lp.angle_rad), 2),
            "lane_extension": lp.extend,
            "reference": ref,
        }
    return out


def dubins() -> dict[str, Any]:
    from ompl import base as ob

    rng = np.random.default_rng(2024)
    s = np.column_stack(
        [
            rng.uniform(-500, 500, N_PAIRS),
            rng.uniform(-500, 500, N_PAIRS),
            rng.uniform(-math.pi, math.pi, N_PAIRS),
        ]
    )
    g = np.column_stack(
        [
            rng.uniform(-500, 500, N_PAIRS),
            rng.uniform(-500, 500, N_PAIRS),
            rng.uniform(-math.pi, math.pi, N_PAIRS),
        ]
    )
    space = ob.DubinsStateSpace(R_M)
    a, b = space.allocState(), space.allocState()
    ref = np.empty(N_PAIRS)
    t0 = time.perf_counter()
    for i in range(N_PAIRS):
        a.setX(s[i, 0])
        a.setY(s[i, 1])
        a.setYaw(s[i, 2])
        b.setX(g[i, 0])
        b.setY(g[i, 1])
        b.setYaw(g[i, 2])
        ref[i] = space.distance(a, b)
    ompl_us = (time.perf_counter() - t0) / N_PAIRS * 1e6
    batch_ms = _median_ms(lambda: batch_lengths(s, g, R_M), repeat=5)
    got = batch_lengths(s, g, R_M)
    assert isinstance(got, np.ndarray)
    return {
        "pairs": N_PAIRS,
        "dubins_batch_us_per_path": round(batch_ms * 1e3 / N_PAIRS, 4),
        "ompl_us_per_call": round(ompl_us, 3),
        "dubins_max_err_m": float(np.abs(got - ref).max()),
    }


def split(refs: dict[str, Any]) -> dict[str, Any]:
    cam = refs["camera"]
    spacing = lane_spacing_m(cam["altitude_m"], cam["hfov_deg"], cam["side_overlap"])
    turns = DubinsTurns(R_M)
    out: dict[str, Any] = {}
    for key, ref in refs["split_reference"].items():
        if not isinstance(ref, dict):
            continue
        name = key.split("_speeds_")[0]
        speeds = [float(v) for v in key.split("_speeds_")[1].split("_")]
        poly = refs["polygons"][name]
        lp = plan_lanes(decompose(Polygon(poly["shell"], poly["holes"])), spacing, turns)
        t0 = time.perf_counter()
        plan = split_lanes(lp.lanes, [Worker(i + 1, v, turns) for i, v in enumerate(speeds)])
        ms = round((time.perf_counter() - t0) * 1e3, 1)
        ideal = lp.path.length_m / sum(speeds)
        out[key] = {
            "split_imbalance": round(plan.makespan_s / ideal - 1.0, 4),
            "makespan_s": round(plan.makespan_s, 1),
            "ideal_s": round(ideal, 1),
            "vehicle_times_s": [round(a.time_s, 1) for a in plan.assignments],
            "split_ms": ms,
            "reference": {
                **ref,
                "imbalance": round(ref["optimal_contiguous_s"] / ref["ideal_s"] - 1.0, 4),
            },
        }
    return out


def run() -> dict[str, Any]:
    refs = json.loads(REFS.read_text())
    cov = coverage(refs)
    return {
        "turn_radius_m": R_M,
        "polygons": cov,
        **dubins(),
        "split_imbalance": split(refs),
    }
