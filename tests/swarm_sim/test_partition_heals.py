"""A fleet heals after a partition (docs/reliability.md): four VTOLs surveying one
area are cut in two for longer than the hold; each half replans the whole rest
without the other; when they meet again (ROSTER_MISMATCH) they merge back into one
plan of what neither half flew, the same on every node: one roster again, the area
covered, and no lane flown twice after the heal."""

from __future__ import annotations

import math

import pytest
from shapely.geometry import LineString, Polygon
from shapely.ops import unary_union

from swarm_sim.faults import ALT_M, MissionSpec, _at_progress, start_run

SPEC = MissionSpec("survey, 4 VTOLs", (1, 2, 3, 4), 180.0, 4)
CUT_S = 30.0  # longer than the hold (15 s) and both halves' replans


def _lanes(tracks: dict[int, list[tuple[float, float]]]) -> object:
    """The straight runs of the tracks (lanes, transits; not the turns between
    lanes, which cross flown ground), each as wide as half a narrow camera's swath."""
    half = ALT_M * math.tan(math.radians(60.0) / 2.0) / 2.0
    runs: list[object] = []
    for pts in tracks.values():
        for a, b, c in zip(pts, pts[1:], pts[2:], strict=False):
            h1 = math.atan2(b[1] - a[1], b[0] - a[0])
            h2 = math.atan2(c[1] - b[1], c[0] - b[0])
            turn = abs((h2 - h1 + math.pi) % (2 * math.pi) - math.pi)
            if turn < math.radians(3.0) and math.dist(a, c) > 1.0:
                runs.append(LineString([a, b, c]).buffer(half / 2.0, cap_style="flat"))
    return unary_union(runs)


# 20 s of CPU (a whole survey by four VTOLs); the merge itself is proved in
# tests/swarm_node/planning/test_merge.py
@pytest.mark.soak
def test_two_halves_that_replanned_apart_merge_into_one_plan(fleet_profiles: dict) -> None:
    run = start_run(fleet_profiles, SPEC)
    assert _at_progress(run, 0.25)
    f = run.fleet
    f.groups = {1: 0, 2: 0, 3: 1, 4: 1}
    run.run_for(CUT_S)
    nodes = {vid: v.node for vid, v in f.vehicles.items()}
    assert {nodes[v].roster.planned for v in (1, 2)} == {(1, 2)}
    assert {nodes[v].roster.planned for v in (3, 4)} == {(3, 4)}
    f.groups = None
    heal_at = f.now

    def one_plan() -> bool:
        plans = [n.manager.fleet_plan for n in nodes.values()]
        return (
            len({p.digest() for p in plans if p is not None}) == 1
            and all(p is not None and p.roster == (1, 2, 3, 4) for p in plans)
            and len({n.roster.members_hash for n in nodes.values()}) == 1
        )

    healed = run.run_until(one_plan, 60)
    assert healed, {v: (n.roster.planned, hex(n.roster.members_hash)) for v, n in nodes.items()}
    assert f.now - heal_at < 10.0  # one fleet again within 10 s of the parts meeting
    assert all(n.mission.heal.merged == 1 for n in nodes.values())
    before = {v: list(p) for v, p in run.points.items()}
    assert run.run_until(run.landed, 1500)
    after = {v: p[len(before.get(v, [])) :] for v, p in run.points.items()}
    poly = Polygon([run.frame.to_local(p.lat_deg, p.lon_deg) for p in run.area.points])
    assert run.coverage(fleet_profiles) >= 0.99
    twice = _lanes(before).intersection(_lanes(after)).intersection(poly)
    assert twice.area / poly.area < 0.05, twice.area / poly.area  # transits across lanes
