"""Collision avoidance and pad sequencing in the node, flown in fast time by FastFleet
(simulated ArduPilot vehicles, the real autopilot link and node cores, real MAVLink
bytes), measured by the flight recorder and `gcs analyze separation`.

Default run: one short check per scenario kind (a head-on convergence, a simultaneous
take-off from close pads, six VTOLs taking off from the paper's 30 m pads), the
avoider's rate while a plan is made, and an ADS-B intruder heard by the autopilot.
`make soak`: the paper's whole experiments and the eight-aircraft stress case, on and
off (the figures: `make bench BENCH=separation`)."""

from __future__ import annotations

import math

import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from gcs_cli.separation import analyze
from swarm_node.core.node import NodeSettings
from swarm_node.core.outputs import Owner
from swarm_proto import (
    Alert,
    AlertCode,
    AlertFlag,
    Command,
    CommandArgs,
    CommandKind,
    FsmState,
    GeoPoint,
    Mission,
    MissionParams,
    MissionState,
    MissionType,
    VehicleStatus,
    geodesy,
)
from swarm_proto.trajectory import read_trajectory
from swarm_sim.core import SITL_HOME
from swarm_sim.fast_fleet import FastFleet
from swarm_sim.recording import status_rows, write_trajectory
from swarm_sim.separation import (
    _at,
    _polyline,
    _square,
    exp1_six_vtol,
    exp2_takeoff_three_vtol,
    stress_eight_headon,
)

GCS = 900


def airborne_report(fleet: FastFleet, t0: float, tmp_path) -> object:  # type: ignore[no-untyped-def]
    path = tmp_path / "flight.csv"
    write_trajectory(status_rows(fleet.published, t0=t0, airborne_only=True), path)
    return analyze(read_trajectory(path))


@pytest.mark.soak  # eight head on in fast time: test_avoidance.py
def test_four_aircraft_head_on_keep_apart_with_avoidance_and_meet_without(
    fleet_profiles: dict,
) -> None:
    """The stress case, short: four fixed-wing aircraft sent through the centre of a
    600 m circle at one altitude in the same instant."""
    on = stress_eight_headon(fleet_profiles, avoid=True, count=4, radius_m=300.0)
    off = stress_eight_headon(fleet_profiles, avoid=False, count=4, radius_m=300.0)
    assert on.completed == off.completed == frozenset(range(21, 25))
    tot_on, tot_off = on.airborne.totals(), off.airborne.totals()
    assert tot_on["near"] == tot_on["danger"] == 0 and on.airborne.min_sep_m >= 10.0
    assert tot_off["near"] + tot_off["danger"] > 0 and off.airborne.min_sep_m < 10.0
    assert on.manoeuvres > 0 and off.manoeuvres == 0


def test_three_vtols_on_pads_8_m_apart_take_off_in_turn(fleet_profiles: dict) -> None:
    """Experiment 2's take-off, short: one route mission released to three VTOLs on
    pads 8 m apart; they climb off in id order, each when the one before is 30 m up,
    and no two airborne come within 10 m (the flight is cut once all three fly their
    route; the whole flight with its landings is the soak test)."""
    fleet = FastFleet.build(
        [1, 2, 3], fleet_profiles, spacing_m=8.0, settings=NodeSettings(plan_timeout_s=120.0)
    )
    fleet.run_until(lambda: all(v.link.state.ekf_has_position for v in fleet.vehicles.values()), 60)
    base = GeoPoint(SITL_HOME.lat_deg, SITL_HOME.lon_deg, SITL_HOME.alt_m)
    fleet.broadcast(Command(GCS, 1, CommandKind.SET_BASE, args=CommandArgs(point=base)))
    assert fleet.run_until(
        lambda: all(v.node.fsm.state == FsmState.GO_MISSION for v in fleet.vehicles.values()), 30
    )
    t0 = fleet.now
    route = Mission(
        201,
        GCS,
        MissionType.ROUTE,
        _polyline(_at(400, -300), _at(900, 300)),
        MissionParams(altitude_rel_m=60.0),
    )
    fleet.broadcast(route)
    assert fleet.run_until(
        lambda: all(v.node.manager.phase.value == "flying" for v in fleet.vehicles.values()), 150
    ), fleet.notes[-10:]
    armed_at = {}
    for t, vid, msg in fleet.published:
        if isinstance(msg, VehicleStatus) and msg.armed and vid not in armed_at and t >= t0:
            armed_at[vid] = t
    assert sorted(armed_at, key=armed_at.__getitem__) == [1, 2, 3]
    assert armed_at[2] - armed_at[1] > 8.0 and armed_at[3] - armed_at[2] > 8.0
    waits = [n for _t, v, n in fleet.notes if n.startswith("take-off: waiting")]
    assert len(waits) == 2  # 2 and 3 waited, 1 went at once
    path = [(t, v, m) for t, v, m in fleet.published if t >= t0]
    rows = status_rows(path, t0=t0, airborne_only=True)
    import tempfile
    from pathlib import Path

    with tempfile.TemporaryDirectory() as tmp:
        write_trajectory(rows, Path(tmp) / "t.csv")
        report = analyze(read_trajectory(Path(tmp) / "t.csv"))
    tot = report.totals()
    assert tot["near"] == tot["danger"] == 0 and report.min_sep_m >= 10.0, report.as_dict()
    whole = status_rows(path, t0=t0)
    assert min(analyze_min(whole), 99.0) >= 5.0  # nothing near, on the pads or above


def analyze_min(rows: list) -> float:
    import tempfile
    from pathlib import Path

    with tempfile.TemporaryDirectory() as tmp:
        write_trajectory(rows, Path(tmp) / "w.csv")
        return analyze(read_trajectory(Path(tmp) / "w.csv")).min_sep_m


@pytest.mark.soak  # take-off in turn: three VTOLs below; six on the demo's pads: test_demo_story.py
def test_six_vtols_on_30_m_pads_take_off_in_turn_and_keep_clear(fleet_profiles: dict) -> None:
    """Experiment 1's start, short: six VTOLs on the paper's pads 30 m apart (inside the
    40 m risk band: neighbours) released for one route at once take off in id order,
    and no two airborne come within 10 m until all fly it (the whole experiment, area
    and re-tasking: the soak test)."""
    fleet = FastFleet.build(
        [1, 2, 3, 4, 5, 6],
        fleet_profiles,
        spacing_m=30.0,
        settings=NodeSettings(plan_timeout_s=180.0),
    )
    fleet.run_until(lambda: all(v.link.state.ekf_has_position for v in fleet.vehicles.values()), 60)
    base = GeoPoint(SITL_HOME.lat_deg, SITL_HOME.lon_deg, SITL_HOME.alt_m)
    fleet.broadcast(Command(GCS, 1, CommandKind.SET_BASE, args=CommandArgs(point=base)))
    assert fleet.run_until(
        lambda: all(v.node.fsm.state == FsmState.GO_MISSION for v in fleet.vehicles.values()), 30
    )
    t0 = fleet.now
    route = Mission(
        101,
        GCS,
        MissionType.ROUTE,
        _polyline(_at(500, -200), _at(1000, 400)),
        MissionParams(altitude_rel_m=60.0),
    )
    fleet.broadcast(route)
    flown: set[int] = set()

    def all_have_flown() -> bool:
        flown.update(i for i, v in fleet.vehicles.items() if v.node.manager.phase.value == "flying")
        return len(flown) == 6

    assert fleet.run_until(all_have_flown, 240), fleet.notes[-10:]
    fleet.run_for(20.0)
    armed_at: dict[int, float] = {}
    for t, vid, msg in fleet.published:
        if isinstance(msg, VehicleStatus) and msg.armed and vid not in armed_at and t >= t0:
            armed_at[vid] = t
    assert sorted(armed_at, key=armed_at.__getitem__) == [1, 2, 3, 4, 5, 6]
    assert len([n for _t, _v, n in fleet.notes if n.startswith("take-off: waiting")]) == 5
    rows = status_rows([p for p in fleet.published if p[0] >= t0], t0=t0, airborne_only=True)
    assert analyze_min(rows) >= 10.0


def test_avoidance_keeps_its_5_hz_while_the_fleet_plans(fleet_profiles: dict) -> None:
    """Planning is off the control loop (a plan job; FastFleet delays its outcome by the
    simulated planning time): the avoider ticks at 5 Hz meanwhile."""
    fleet = FastFleet.build([1, 2], fleet_profiles, spacing_m=60.0)
    fleet.plan_delay_s = 8.0
    fleet.run_until(lambda: all(v.link.state.ekf_has_position for v in fleet.vehicles.values()), 60)
    base = GeoPoint(SITL_HOME.lat_deg, SITL_HOME.lon_deg, SITL_HOME.alt_m)
    fleet.broadcast(Command(GCS, 1, CommandKind.SET_BASE, args=CommandArgs(point=base)))
    fleet.run_until(lambda: fleet.vehicles[1].node.fsm.state == FsmState.GO_MISSION, 30)
    fleet.broadcast(
        Mission(
            5,
            GCS,
            MissionType.AREA,
            _square(*_at(600.0, 0.0), 150.0),
            MissionParams(altitude_rel_m=60.0),
        )
    )
    node = fleet.vehicles[1].node
    assert fleet.run_until(lambda: node.manager.mission_state == MissionState.PLANNING, 10)
    fleet.run_until(lambda: node.manager._planning is not None, 10)  # the plan job is out
    ticks, t = node.avoid.counters.get("ticks", 0), fleet.now
    fleet.run_for(6.0)
    assert node.manager._planning is not None  # still planning
    rate = (node.avoid.counters["ticks"] - ticks) / (fleet.now - t)
    assert rate == pytest.approx(5.0, abs=0.2)


def adsb_bytes(
    vid: int, icao: int, lat: float, lon: float, alt_msl: float, heading: float, speed: float
) -> bytes:
    mav = mavlink.MAVLink(None, srcSystem=vid, srcComponent=1)
    msg = mavlink.MAVLink_adsb_vehicle_message(
        icao,
        round(lat * 1e7),
        round(lon * 1e7),
        0,
        round(alt_msl * 1000),
        round(heading * 100) % 36000,
        round(speed * 100),
        0,
        b"INTRUDER",
        1,
        0,
        1 | 2 | 4 | 8,
        0,
    )
    return bytes(msg.pack(mav))


def test_an_adsb_intruder_heard_by_the_autopilot_is_climbed_over(fleet_profiles: dict) -> None:
    """A non-cooperative aircraft (ADSB_VEHICLE, real MAVLink bytes from the autopilot)
    flies head-on at a VTOL's altitude along its route: the VTOL climbs out of its way
    (owner AVOIDANCE, COLLISION_RISK in its status, an Alert naming the ICAO address),
    then resumes and finishes its route."""
    fleet = FastFleet.build([1], fleet_profiles)
    v = fleet.vehicles[1]
    fleet.run_until(lambda: v.link.state.ekf_has_position, 60)
    base = GeoPoint(SITL_HOME.lat_deg, SITL_HOME.lon_deg, SITL_HOME.alt_m)
    fleet.broadcast(Command(GCS, 1, CommandKind.SET_BASE, args=CommandArgs(point=base)))
    fleet.run_until(lambda: v.node.fsm.state == FsmState.GO_MISSION, 30)
    fleet.broadcast(
        Mission(
            7,
            GCS,
            MissionType.ROUTE,
            _polyline(_at(300, 0), _at(3300, 0)),
            MissionParams(altitude_rel_m=60.0),
        )
    )
    assert fleet.run_until(lambda: v.node.manager.phase.value == "flying", 120)
    assert fleet.run_until(lambda: (v.link.state.alt_rel_m or 0.0) > 59.0, 60)
    s0 = v.link.state
    assert s0.lat_deg is not None and s0.lon_deg is not None and s0.alt_msl_m is not None
    start = fleet.now
    # the intruder: 1.5 km ahead on the VTOL's track, flying at it at 30 m/s, same level
    course = math.atan2(s0.vel_east_m_s, s0.vel_north_m_s)
    un, ue = math.cos(course), math.sin(course)
    la, lo = geodesy.offset(s0.lat_deg, s0.lon_deg, 1500.0 * un, 1500.0 * ue)
    alt = s0.alt_msl_m
    heading = (math.degrees(course) + 180.0) % 360.0
    holders, flags, nearest = set(), AlertFlag.NONE, math.inf
    next_report = [fleet.now]

    def step() -> bool:
        nonlocal flags, nearest
        if fleet.now >= next_report[0]:
            dt = fleet.now - start
            lat, lon = geodesy.offset(la, lo, -30.0 * dt * un, -30.0 * dt * ue)
            data = adsb_bytes(1, 0x4B1D5E, lat, lon, alt, heading, 30.0)
            fleet._link_out(1, v.link.receive(data, fleet.now))
            next_report[0] += 1.0  # ADS-B at 1 Hz
            s = v.link.state
            if s.lat_deg is not None and s.alt_msl_m is not None:
                d = geodesy.distance_3d_m(lat, lon, alt, s.lat_deg, s.lon_deg, s.alt_msl_m)
                nearest = min(nearest, d)
        holders.add(v.node.arbiter.holder)
        st = v.node.status(fleet.now)
        if st is not None:
            flags |= AlertFlag(st.alerts)
        return fleet.now - start > 90.0

    fleet.run_until(step, 120)
    alerts = [a for a in fleet.messages(Alert) if a.code == AlertCode.COLLISION_RISK]
    assert any("ICAO 4B1D5E" in a.text for a in alerts)
    assert Owner.AVOIDANCE in holders and flags & AlertFlag.COLLISION_RISK
    assert nearest >= 10.0, nearest
    assert v.node.avoid.counters.get("suspensions", 0) >= 1
    assert fleet.run_until(lambda: v.node.fsm.mission_id != 7, 600)  # the route is finished
    assert any(a.code == AlertCode.MISSION_COMPLETE for a in fleet.messages(Alert))


# ---------------------------------------------------------------------- soak


@pytest.mark.soak
@pytest.mark.parametrize(
    "run", [exp1_six_vtol, exp2_takeoff_three_vtol, stress_eight_headon], ids=lambda f: f.__name__
)
def test_the_papers_experiments_and_the_stress_case(fleet_profiles: dict, run) -> None:  # type: ignore[no-untyped-def]
    """Checks on whole flights: with avoidance on, 0 near and 0 danger
    samples once airborne, and 0 near samples at all in the take-off case; every
    vehicle finishes its mission (and, but for the planes left circling the base, is
    back on its pad); with avoidance off the stress case has conflicts."""
    on = run(fleet_profiles, avoid=True)
    air = on.airborne.totals()
    assert air["near"] == 0 and air["danger"] == 0, on.figures()
    if run is exp2_takeoff_three_vtol:
        assert on.whole.totals()["near"] == 0
    if run is not stress_eight_headon:
        assert on.landed == on.completed == frozenset(on.landed), on.figures()
    else:
        off = run(fleet_profiles, avoid=False)
        assert off.airborne.totals()["near"] > 0, off.figures()


def test_the_demo_takes_avoidance_as_an_option() -> None:
    """`swarm-sim demo --avoidance/--no-avoidance` parses (a bad --vehicles stops it
    before anything starts) and reaches the nodes: their command line, as `swarm-node
    run` parses it, carries the choice."""
    import typer
    from typer.testing import CliRunner

    from swarm_node.cli import app as node_app
    from swarm_sim import demo
    from swarm_sim.cli import app

    runner = CliRunner()
    for flag in ("--avoidance", "--no-avoidance"):
        result = runner.invoke(app, ["demo", flag, "--vehicles", "one,two"])
        assert result.exit_code == 2 and "vehicles" in result.output, result.output
    assert runner.invoke(app, ["demo", "--avoidance=maybe"]).exit_code == 2
    run = typer.main.get_command(node_app).commands["run"]
    for radio in (False, True):
        for avoidance in (False, True):
            argv = demo.node_argv(
                3,
                5760,
                "tcp/127.0.0.1:7447",
                radio=radio,
                speedup=5.0,
                fleet_size=4,
                avoidance=avoidance,
            )
            assert argv[1:4] == ["-m", "swarm_node.cli", "run"]
            params = run.make_context("run", argv[4:]).params
            assert params["avoidance"] is avoidance
            assert params["node_id"] == 3 and params["autopilot"] == "tcp:127.0.0.1:5760"
