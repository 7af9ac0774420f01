"""The benchmarks stay runnable and their results carry the figures the issues name.

Nothing here times anything: `make bench` measures, these tests check that what it
measures is complete (a benchmark that crashes on a new message type, or a results file
missing a figure, fails here instead of in somebody's `make bench`)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

from bench.__main__ import main, topics
from swarm_proto import MESSAGE_TYPES, lan, radio
from tests.conftest import REPO

RESULTS = REPO / "bench" / "results"

# figures each issue names, per results file (nested keys joined with "/")
NAMED: dict[str, tuple[str, ...]] = {
    "voting": (
        "agree_ms/n_6/loss_0/median",
        "agree_ms/n_6/loss_20/median",
        "agree_ms/n_20/loss_0/median",
        "agree_ms/n_20/loss_20/median",
        "agree_ms/n_50/loss_0/median",
        "agree_ms/n_50/loss_20/median",
        "agree_ms_radio_6",
        "double_assignments",
        "left_out",
    ),
    "proto": (
        "status_radio_bytes",
        "status_frame_bytes",
        "status_lan_bytes",
        "high_latency2_bytes",
        "high_latency2_signed_bytes",
        "status_encode_us",
        "status_decode_us",
        "high_latency2_encode_us",
        "high_latency2_decode_us",
        "status_encode_vs_high_latency2",
        "status_decode_vs_high_latency2",
    ),
    "sim": (
        "kept_pace",
        "swarm_rt_factor/vehicles_10",
        "swarm_rt_factor/vehicles_50",
        "swarm_rt_factor/vehicles_100",
        "swarm/vehicles_10/kept_pace_at_10x",
        "swarm/vehicles_50/kept_pace_at_10x",
        "swarm/vehicles_100/kept_pace_at_10x",
        "swarm/vehicles_10/rates_kept",
        "swarm/vehicles_50/rates_kept",
        "swarm/vehicles_100/rates_kept",
        "swarm_rt_factor_one_process/vehicles_100",
        "swarm_rt_factor_telemetry_peers/vehicles_100",
    ),
    "radio_scale": (
        "bare_limit_ratio",
        *(
            f"scale/n_{n}/loss_{loss}/{scheme}/{k}"
            for n in (14, 25, 50)
            for loss in ("0", "0.1")
            for scheme in ("tdm5", "gateway")
            for k in (
                "position_error_p99_m",
                "position_error_max_m",
                "airtime_used",
                "collisions",
                "cmd_latency_p99_ms",
            )
        ),
    ),
    "deploy": (
        "status_latency_ms_p50",
        "status_latency_ms_p99",
        "tls/status_latency_ms_p50",
        "tls/status_latency_ms_p99",
        "join_s",
    ),
    "node": (
        "cpu_s_per_sim_s/peers_10",
        "cpu_s_per_sim_s/peers_50",
        "cpu_s_per_sim_s/peers_100",
        "core_cpu_pct_at_peers/peers_10",
        "core_cpu_pct_at_peers/peers_100",
        "core_cpu_pct_at_peers/peers_1000",
        "real_processes_cpu_pct/nodes_10",
    ),
    "gcs": ("rtl_all_ms/10", "rtl_all_ms/25", "rtl_all_ms/50", "raw_zenoh_ms/10", "nodes/50"),
    "map": tuple(
        f"sizes/{n}/{k}"
        for n in (6, 50)
        for k in ("lag_ms_p50", "lag_ms_p99", "server_cpu_pct", "frame_ms_p99")
    ),
    "separation": (
        "avoid_cpu_us_per_tick/peers_10",
        "avoid_cpu_us_per_tick/peers_50",
        *(
            f"{scenario}/{side}/{k}"
            for scenario in ("exp1_six_vtol", "exp2_takeoff_three_vtol", "stress_eight_headon")
            for side in ("on", "on_no_intent", "off")
            for k in ("min_sep_m", "risk", "danger", "near")
        ),
    ),
    "planners": (
        "dubins_batch_us_per_path",
        "ompl_us_per_call",
        "dubins_max_err_m",
        "split_imbalance",
        "gis_4000/full_plan_ms",
    ),
    "identity": (
        "conflict_detect_ms",
        "untrusted_detect_ms",
        "rss_growth_pct",
        "malformed_alerts/node_7",
        "malformed_alerts/node_8",
        "dropped_by_reason/invalid",
        "dropped_by_reason/key_mismatch",
        "status_hz_during/node_7",
    ),
    "demo": ("wall_s", "sim_s", "coverage", "near", "danger", "min_sep_m", "missions_completed"),
    "faults": ("faults", "recovered", "declared_state_lost", "false_emergencies", "coverage_min"),
    "mission": (
        "battery_min_pct_at_landing",
        "makespan_planned_vs_flown",
        "inherit_coverage",
        "double_flown_fraction",
        "replan_agree_ms",
        "baseline/battery_min_pct_at_landing",
        "baseline/makespan_planned_vs_flown",
        "baseline/inherit_coverage",
        "premission_arrival_spread_s",
        "baseline/premission_arrival_spread_s",
        "premission_area_arrival_spread_s",
        "baseline/premission_area_arrival_spread_s",
        "makespan_planned_vs_flown_by_fleet/survey_1_7_8",
        "makespan_planned_vs_flown_by_fleet/premission_route_1_2_3",
        "makespan_planned_vs_flown_by_fleet/premission_area_1_2_3",
        "inherit_quads_rover/victim_8/coverage",
        "inherit_quads_rover/victim_8/double_flown_fraction",
        "autoland/touchdown_gaps_s",
        "mumt/slot_error_max_m",
    ),
    "passthrough": (
        "lan/round_trips/passthrough/param_request_read/median_ms",
        "lan/round_trips/passthrough/command_long_do_set_servo/median_ms",
        "lan/round_trips/passthrough/command_long_do_set_mode/median_ms",
        "lan/round_trips/direct/param_request_read/median_ms",
        "lan/mission_100/download_s",
        "lan/streaming/node_extra_cpu_pct",
        "radio/vehicle_bytes_per_s",
    ),
}
FAULT_ROW = ("recovered", "recover_s", "coverage", "declared_state_lost", "false_emergencies")
RADIO_ROW = (
    "rf_bps",
    "guard_ms",
    "msg_bytes",
    "limit_nodes",
    "achieved_nodes",
    "collisions",
    "auth_overhead_bytes",
)


def _load(topic: str) -> dict[str, Any]:
    data: dict[str, Any] = json.loads((RESULTS / f"{topic}.json").read_text())
    return data


def _get(data: dict[str, Any], path: str) -> Any:
    for part in path.split("/"):
        data = data[part]
    return data


def test_every_topic_has_a_results_file_with_its_command() -> None:
    for topic in topics():
        meta = _load(topic)["_meta"]
        assert meta["command"] == f"make bench BENCH={topic}"


@pytest.mark.parametrize("topic", sorted(NAMED))
def test_results_carry_the_named_figures(topic: str) -> None:
    data = _load(topic)
    for path in NAMED[topic]:
        value = _get(data, path)
        assert value is not None and not isinstance(value, str), (topic, path)


def test_planner_results_per_reference_polygon() -> None:
    polygons = _load("planners")["polygons"]
    assert len(polygons) == 4
    for name, figures in polygons.items():
        for key in ("lanes", "coverage", "overlap", "path_m", "sweep_ms", "full_plan_ms"):
            assert key in figures, (name, key)


def test_radio_rows() -> None:
    rows = _load("radio")["rows"]
    sizes = {(r["msg_bytes"], r["guard_ms"]) for r in rows}
    assert sizes == {(m, g) for m in (32, 48, 64, 128) for g in (2, 5, 10)}
    for row in rows:
        assert all(k in row for k in RADIO_ROW), row


def test_proto_benchmark_has_a_sample_of_every_message() -> None:
    from bench.proto import NOW, SAMPLES

    assert set(SAMPLES) == set(MESSAGE_TYPES)
    for cls, msg in SAMPLES.items():
        assert isinstance(msg, cls)
        assert type(radio.decode(radio.encode(msg), now_unix_s=NOW)) is cls
        assert lan.decode(lan.encode(msg), cls) == msg


def test_proto_results_match_the_messages_measured() -> None:
    measured = _load("proto")["messages"]
    assert set(measured) == {c.__name__ for c in MESSAGE_TYPES}


def test_voting_trials_never_assign_twice_nor_leave_out() -> None:
    data = _load("voting")
    assert data["trials"] == 200
    assert data["double_assignments"] == data["left_out"] == data["disagreements"] == 0


def test_an_unknown_benchmark_is_refused(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["no_such_topic"]) == 2
    assert "unknown benchmark" in capsys.readouterr().err


def test_docs_quote_every_topic() -> None:
    doc = (REPO / "docs" / "benchmarks.md").read_text()
    for topic in topics():
        assert f"make bench BENCH={topic}" in doc, topic


def test_results_directory_is_the_one_bench_writes() -> None:
    from bench import __main__ as runner

    assert Path(runner.RESULTS) == RESULTS


def test_separation_figures_show_what_avoidance_changes() -> None:
    """Checks on the FastFleet figures: with avoidance on, no danger or near
    sample once airborne in all three scenarios and no near sample at all in the
    take-off case; with it off, the stress case has conflicts."""
    data = _load("separation")
    for name in ("exp1_six_vtol", "exp2_takeoff_three_vtol", "stress_eight_headon"):
        on = data[name]["on"]["airborne"]
        assert on["near"] == 0 and on["danger"] == 0, name
    assert data["exp2_takeoff_three_vtol"]["on"]["near"] == 0
    assert (
        data["stress_eight_headon"]["off"]["near"] + data["stress_eight_headon"]["off"]["danger"]
        > 0
    )
    pointmass = data["stress_eight_headon_pointmass"]
    assert pointmass["on"]["near"] == 0 and pointmass["off"]["near"] > 0


def test_radio_scale_rows_have_no_collisions() -> None:
    data = _load("radio_scale")
    assert data["bare_limit_ratio"] >= 0.95
    for by_loss in data["scale"].values():
        for by_scheme in by_loss.values():
            for row in by_scheme.values():
                assert row["collisions"] == 0, row


def test_fault_campaign_rows() -> None:
    """One row per fault (and mission) with the named figures; nothing declared
    is lost and no emergency is false in any row."""
    data = _load("faults")
    rows = data["rows"]
    assert {r["fault"] for r in rows} >= {
        "none",
        "kill -9 a node (restarted after 5 s)",
        "SIGSTOP a node 3 s",
        "restart an autopilot (empty stores)",
        "drop 30 % of swarm messages",
        "partition the swarm in two for 20 s",
        "clock jump +1 h on one node",
        "disk full on the database",
        "corrupted database at start (new one)",
    }
    assert {r["env"] for r in rows} == {"fast", "processes"}
    # a dead node, a router restart, a reboot in flight over real processes: three quadcopters, judged from true positions
    over_processes = {r["fault"]: r for r in rows if r["env"] == "processes"}
    for fault in (
        "node down 10 s (its aircraft flies on)",
        "restart the router (down 3 s)",
        "restart the router (down 20 s)",
        "reboot an autopilot in flight",
    ):
        row = over_processes[fault]
        assert row["recovered"] and row["mission"].startswith("survey, 3 quadcopters"), row
        assert row["unexpected_arms"] == 0 and row["min_true_sep_m"] >= 10.0, row
    for row in rows:
        assert all(k in row for k in FAULT_ROW), row
        assert isinstance(row["recovered"], bool)
        assert row["declared_state_lost"] == 0 and row["false_emergencies"] == 0, row
    assert data["baseline"] and all(r["fault"] == "none" for r in data["baseline"])
    # README: every fault recovered, no two aircraft under 10 m, no rebooted autopilot armed
    assert data["recovered"] == data["faults"] == sum(r["fault"] != "none" for r in rows)
    assert data["min_true_sep_m"] >= 10.0 and data["unexpected_arms"] == 0


def test_the_demo_figures_are_a_passing_run() -> None:
    """The demo's figures come from a run that passed (every mission, no
    near-collision, the area covered), beside the fast-time flight of the same story."""
    data = _load("demo")
    assert data["ok"] and data["exit_code"] == 0, data["failures"]
    assert data["missions_completed"] == data["missions_total"] == 4
    assert data["near"] == 0 and data["coverage"] >= 0.99
    assert data["fast_time"]["ok"] and data["fast_time"]["near"] == 0
    assert "near" in data["baseline_no_avoidance"]
