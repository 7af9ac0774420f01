"""The `--radio` demo in fast time: the paper's experiment 1 flown by FastFleet
with every message heard as the radio carries it (`FastFleet.over_air`: floats at the
radio's resolution), the way each node hears the others behind its own gateway.

radio-8 (a `--radio` run on the code before) covered 98.2 % of the survey: the
survivors of the vote and of the loss replanned from progress that differed by the
radio's 0.01 m (their own at full precision) and flew shares of different plans. Every
node logs each plan's digest (`FleetPlan.digest`); here every member of every plan and
replan logs the same one, and the survey is covered."""

from __future__ import annotations

import re
from collections import defaultdict
from pathlib import Path

import pytest

from swarm_proto import GeoPoint, VehicleInfo
from swarm_sim import demo_report as dr
from swarm_sim.core import SITL_HOME
from swarm_sim.story import StoryPlan, fly_fast

MEMBERS = (1, 2, 3, 4, 5, 6)
PLAN_LOG = re.compile(r"mission (\d+): (?:re)?planned for (?:fleet )?(\[[^\]]*\]).*\(plan (\w+)\)")


@pytest.mark.soak
def test_the_story_over_the_air_holds_one_plan_per_replan_and_covers_the_survey(
    tmp_path: Path, fleet_profiles: dict
) -> None:
    plan = StoryPlan.experiment_one(MEMBERS, (SITL_HOME.lat_deg, SITL_HOME.lon_deg))
    profiles = {v: fleet_profiles[v] for v in MEMBERS}
    recorder = dr.FlightRecorder(tmp_path / "flight.csv")
    homes: dict[int, GeoPoint] = {}

    def heard(msg: object, now: float) -> None:
        if isinstance(msg, VehicleInfo) and msg.home is not None:
            homes[msg.vehicle_id] = msg.home
        recorder.handle(msg)

    try:
        run = fly_fast(plan, profiles, on_message=heard, over_air=True)
    finally:
        recorder.close()
    report = dr.build(
        tmp_path,
        plan=plan,
        record=run.story.record,
        flight_csv=tmp_path / "flight.csv",
        profiles=profiles,
        homes=homes,
        base=None,
        meta={"fast_time": True},
        pictures=False,
    )
    digests: dict[tuple[str, str], dict[int, str]] = defaultdict(dict)
    for _t, vid, text in run.fleet.notes:  # type: ignore[attr-defined]
        m = PLAN_LOG.search(text)
        if m:
            digests[(m.group(1), m.group(2))][vid] = m.group(3)
    assert len(digests) >= 4, digests  # the survey, its two replans, the pair's missions
    for key, by_node in digests.items():
        assert len(set(by_node.values())) == 1, (key, by_node)
    assert report["ok"], report["failures"]
    assert report["coverage"] >= 0.99
