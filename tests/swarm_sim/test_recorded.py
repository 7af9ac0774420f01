"""The simulator against real ArduPilot: the recorded SITL sorties in
../shared/data/ardupilot-sitl are flown again in the simulator by a client doing what
the recording script did (same message intervals, same mission shape, same commands),
and the two streams are compared: message types, HEARTBEAT type/autopilot/base_mode/
custom_mode, system ids, COMMAND_ACK results, mission-protocol exchanges, MISSION_ITEM_
REACHED, and the STATUSTEXT wording for take-off, transition and landing."""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import pytest
from pymavlink import mavutil

from tests.swarm_sim.conftest import Pilot, make_pilot

# the recordings are read and flown once (module fixtures): every test here on one worker
pytestmark = pytest.mark.xdist_group("recorded")

REL = 3
# What the recording script asked for (the copter stream has exactly these periodic
# messages; their rates at SITL speed-up 4 give the sim-time intervals).
INTERVALS_US = {
    33: 200_000,
    30: 200_000,
    74: 200_000,
    24: 500_000,
    1: 1_000_000,
    147: 1_000_000,
    2: 1_000_000,
    42: 1_000_000,
    193: 1_000_000,
    242: 2_000_000,
}
PROTOCOL = {
    "COMMAND_ACK",
    "MISSION_ACK",
    "MISSION_REQUEST",
    "MISSION_ITEM_REACHED",
    "STATUSTEXT",
    "HEARTBEAT",
    "PARAM_VALUE",
    "GPS_GLOBAL_ORIGIN",
    "TIMESYNC",
    "HOME_POSITION",
}
# The simulator's additions to a stream (documented in docs/simulator.md)
SIM_EXTRAS = {"EXTENDED_SYS_STATE"}
# The recorded QuadPlane had no battery monitor (SYS_STATUS voltage 0, remaining -1), so
# it sent no BATTERY_STATUS; the simulated Albatross has a battery.
PLANE_EXTRAS = SIM_EXTRAS | {"BATTERY_STATUS"}
# ArduPlane SITL's SR0_ default streams and sensor/SITL-physics messages: not emulated
PLANE_SITL_ONLY = {
    "AHRS",
    "AHRS2",
    "AIRSPEED",
    "AOA_SSA",
    "ESC_TELEMETRY_1_TO_4",
    "ESC_TELEMETRY_5_TO_8",
    "LOCAL_POSITION_NED",
    "MEMINFO",
    "NAV_CONTROLLER_OUTPUT",
    "POSITION_TARGET_GLOBAL_INT",
    "POWER_STATUS",
    "RAW_IMU",
    "RC_CHANNELS",
    "SCALED_IMU2",
    "SCALED_IMU3",
    "SCALED_PRESSURE",
    "SCALED_PRESSURE2",
    "SERVO_OUTPUT_RAW",
    "SIMSTATE",
    "TERRAIN_REPORT",
    "TERRAIN_REQUEST",
    "VIBRATION",
    "WIND",
}
# Texts from SITL's simulated sensors and RC that have no counterpart in the simulator
SITL_ONLY_TEXTS = {
    "RC7: SaveWaypoint LOW",
    "EKF3 IMU0 MAG0 in-flight yaw alignment complete",
    "EKF3 IMU1 MAG0 in-flight yaw alignment complete",
}


def read_tlog(path: Path) -> list[Any]:
    conn = mavutil.mavlink_connection(str(path), dialect="ardupilotmega")
    out = []
    while (msg := conn.recv_match()) is not None:
        if msg.get_type() != "BAD_DATA":
            out.append(msg)
    return out


def types(msgs: list[Any]) -> set[str]:
    return {m.get_type() for m in msgs}


def mode_sequence(msgs: list[Any]) -> list[int]:
    seq: list[int] = []
    for m in msgs:
        if m.get_type() == "HEARTBEAT" and (not seq or seq[-1] != m.custom_mode):
            seq.append(m.custom_mode)
    return seq


def heartbeat_pairs(msgs: list[Any]) -> set[tuple[int, int, int, int]]:
    return {
        (m.type, m.autopilot, m.custom_mode, m.base_mode)
        for m in msgs
        if m.get_type() == "HEARTBEAT"
    }


def acks(msgs: list[Any]) -> list[tuple[int, int]]:
    return [(m.command, m.result) for m in msgs if m.get_type() == "COMMAND_ACK"]


def texts(msgs: list[Any]) -> list[str]:
    return [m.text for m in msgs if m.get_type() == "STATUSTEXT"]


def shape(text: str) -> str:
    """A text with its numbers blanked: "Reached waypoint #2 dist 84m" -> "Reached waypoint #N dist Nm"."""
    return re.sub(r"-?\d+(\.\d+)?", "N", text)


def mission_exchange(msgs: list[Any]) -> list[str]:
    return [
        f"{m.get_type()}:{getattr(m, 'seq', getattr(m, 'type', ''))}"
        for m in msgs
        if m.get_type() in ("MISSION_REQUEST", "MISSION_REQUEST_INT", "MISSION_ACK")
    ]


def start_like_the_script(p: Pilot) -> None:
    # the recorded script uploaded after "ArduPilot Ready": before it, ArduPilot (and
    # the simulator) refuse a MISSION_COUNT with NO_SPACE
    assert p.h.run_until(lambda: p.ap.ready, 10)
    for msg_id, interval in INTERVALS_US.items():
        assert p.command(511, msg_id, interval) == 0
    p.c.mav.mission_clear_all_send(p.ap.sysid, 1, 0)
    ack = p.h.wait_for(p.c, "MISSION_ACK", 5)
    assert ack is not None and ack.type == 0


@pytest.fixture(scope="module")
def recorded_copter(shared_dir_module: Path) -> list[Any]:
    return read_tlog(shared_dir_module / "data/ardupilot-sitl/arducopter-sortie.tlog")


@pytest.fixture(scope="module")
def recorded_plane(shared_dir_module: Path) -> list[Any]:
    return read_tlog(shared_dir_module / "data/ardupilot-sitl/arduplane-quadplane-sortie.tlog")


@pytest.fixture(scope="module")
def shared_dir_module() -> Path:
    from tests.conftest import SHARED

    if not (SHARED / "data/ardupilot-sitl").is_dir():
        pytest.skip(f"recorded SITL data not found under {SHARED}")
    return SHARED


@pytest.fixture(scope="module")
def sim_copter() -> list[Any]:
    """The recorded copter script, flown in the simulator."""
    p = make_pilot("copter")
    start_like_the_script(p)
    ack = p.upload(
        [
            (16, 0, 0, 0, 0),
            (22, REL, 0, 0, 30),
            (16, REL, 167, 0, 30),
            (16, REL, 167, 133, 30),
            (16, REL, 0, 133, 30),
            (20, REL, 0, 0, 0),
        ],
    )
    assert ack is not None and ack.type == 0
    p.wait_ready()
    assert p.set_mode("GUIDED") == 0
    assert p.arm() == 0
    assert p.command(22, 0, 0, 0, 0, 0, 0, 30) == 0
    assert p.h.run_until(lambda: p.ap.rel_alt_m > 29.5, 60)
    assert p.set_mode("AUTO") == 0
    assert p.command(300) == 0
    assert p.h.run_until(lambda: not p.ap.armed, 600)
    p.h.run_for(15)
    assert p.set_mode("GUIDED") == 0
    x, y = p.latlon(100, 100)
    assert p.command_int(192, 6, -1, 1, 0, 0, x=x, y=y, z=20) == 0
    p.h.run_for(60)
    assert p.command(178, 1, 5) == 0
    p.h.run_for(40)
    assert p.set_mode("RTL") == 0
    p.h.run_for(120)
    assert p.set_mode("LAND") == 0
    p.h.run_for(60)
    return [m for _, m in p.c.history]


@pytest.fixture(scope="module")
def sim_plane() -> list[Any]:
    """The recorded QuadPlane script, flown in the simulator."""
    p = make_pilot("vtol")
    start_like_the_script(p)
    ack = p.upload(
        [
            (16, 0, 0, 0, 0),
            (84, REL, 0, 0, 40),
            (16, REL, 500, 300, 50),
            (16, REL, 500, 800, 50),
            (16, REL, 0, 800, 50),
            (20, REL, 0, 0, 0),
        ],
    )
    assert ack is not None and ack.type == 0
    p.wait_ready()
    assert p.set_mode("AUTO") == 0
    assert p.arm() == 0
    assert p.h.run_until(lambda: p.ap.mode_name == "RTL", 600)
    p.h.run_for(120)
    assert p.set_mode("GUIDED") == 0
    x, y = p.latlon(-500, 0)
    assert p.command_int(192, 6, -1, 1, 0, 0, x=x, y=y, z=50) == 0
    assert p.h.run_until(
        lambda: (
            bool(p.c.seen("MISSION_ITEM_REACHED")) and p.c.seen("MISSION_ITEM_REACHED")[-1].seq == 0
        ),
        300,
    )
    p.h.run_for(30)
    assert p.command(178, 0, 20) == 0
    p.h.run_for(40)
    assert p.set_mode("RTL") == 0
    p.h.run_for(160)
    assert p.set_mode("QLAND") == 0
    assert p.h.run_until(lambda: not p.ap.armed, 600)
    p.h.run_for(40)
    return [m for _, m in p.c.history]


# -- copter -------------------------------------------------------------------------


def test_copter_message_set(recorded_copter: list[Any], sim_copter: list[Any]) -> None:
    rec, sim = types(recorded_copter), types(sim_copter)
    assert rec <= sim, f"recorded but never sent by the simulator: {sorted(rec - sim)}"
    assert sim - rec <= SIM_EXTRAS, (
        f"sent by the simulator, not by ArduPilot: {sorted(sim - rec - SIM_EXTRAS)}"
    )


def test_copter_ids_and_heartbeats(recorded_copter: list[Any], sim_copter: list[Any]) -> None:
    assert {(m.get_srcSystem(), m.get_srcComponent()) for m in recorded_copter} == {(1, 1)}
    assert {(m.get_srcSystem(), m.get_srcComponent()) for m in sim_copter} == {(1, 1)}
    rec_pairs, sim_pairs = heartbeat_pairs(recorded_copter), heartbeat_pairs(sim_copter)
    assert sim_pairs <= rec_pairs, sorted(sim_pairs - rec_pairs)
    # disarmed STABILIZE/AUTO, GUIDED/LAND, armed GUIDED/AUTO: as recorded
    assert {
        (2, 3, 0, 81),
        (2, 3, 3, 81),
        (2, 3, 4, 89),
        (2, 3, 9, 89),
        (2, 3, 4, 217),
        (2, 3, 3, 217),
    } <= sim_pairs
    assert mode_sequence(recorded_copter) == mode_sequence(sim_copter) == [0, 4, 3, 4, 6, 9]
    rec_status = {m.system_status for m in recorded_copter if m.get_type() == "HEARTBEAT"} - {1}
    sim_status = {m.system_status for m in sim_copter if m.get_type() == "HEARTBEAT"} - {1}
    assert rec_status == sim_status == {3, 4}


def test_copter_command_acks(recorded_copter: list[Any], sim_copter: list[Any]) -> None:
    assert acks(sim_copter) == acks(recorded_copter)


def test_copter_mission_protocol(recorded_copter: list[Any], sim_copter: list[Any]) -> None:
    expected = ["MISSION_ACK:0", *[f"MISSION_REQUEST:{i}" for i in range(6)], "MISSION_ACK:0"]
    assert mission_exchange(recorded_copter) == expected
    assert mission_exchange(sim_copter) == expected
    rec = [m.seq for m in recorded_copter if m.get_type() == "MISSION_ITEM_REACHED"]
    assert (
        rec
        == [m.seq for m in sim_copter if m.get_type() == "MISSION_ITEM_REACHED"]
        == [1, 2, 3, 4, 5]
    )


def test_copter_texts(recorded_copter: list[Any], sim_copter: list[Any]) -> None:
    rec = {shape(t) for t in texts(recorded_copter)} - {shape(t) for t in SITL_ONLY_TEXTS}
    sim = {shape(t) for t in texts(sim_copter)}
    assert rec <= sim, sorted(rec - sim)
    order = [
        "Arming motors",
        "Mission: 1 Takeoff",
        "Reached command #2",
        "Mission: 5 RTL",
        "SIM Hit ground at",
        "Disarming motors",
    ]
    for stream in (texts(recorded_copter), texts(sim_copter)):
        idx = [next(i for i, t in enumerate(stream) if t.startswith(o)) for o in order]
        assert idx == sorted(idx)


def test_copter_field_conventions(recorded_copter: list[Any], sim_copter: list[Any]) -> None:
    for stream in (recorded_copter, sim_copter):
        times = [m.time_unix_usec for m in stream if m.get_type() == "SYSTEM_TIME"]
        assert times[0] == 0 and times[-1] > 1.6e15  # GPS time once locked
        gpi = [m for m in stream if m.get_type() == "GLOBAL_POSITION_INT"]
        assert gpi[0].lat == 0 and gpi[-1].lat != 0  # no position before the EKF has one
        mc = [m for m in stream if m.get_type() == "MISSION_CURRENT"]
        assert mc[-1].total == 5  # items without home
        ekf = {m.flags for m in stream if m.get_type() == "EKF_STATUS_REPORT"}
        assert {1024, 831} <= ekf
        home = [m for m in stream if m.get_type() == "HOME_POSITION"]
        assert home and abs(home[-1].latitude - 374112000) < 50


# -- QuadPlane ----------------------------------------------------------------------


def test_plane_message_set(recorded_plane: list[Any], sim_plane: list[Any]) -> None:
    rec, sim = types(recorded_plane) - PLANE_SITL_ONLY, types(sim_plane)
    assert rec <= sim, sorted(rec - sim)
    assert sim - rec <= PLANE_EXTRAS, sorted(sim - rec - PLANE_EXTRAS)


def test_plane_heartbeats(recorded_plane: list[Any], sim_plane: list[Any]) -> None:
    rec_pairs, sim_pairs = heartbeat_pairs(recorded_plane), heartbeat_pairs(sim_plane)
    assert sim_pairs <= rec_pairs, sorted(sim_pairs - rec_pairs)
    assert {
        (1, 3, 16, 17),
        (1, 3, 5, 81),
        (1, 3, 10, 89),
        (1, 3, 10, 217),
        (1, 3, 11, 217),
        (1, 3, 15, 217),
        (1, 3, 20, 209),
        (1, 3, 20, 81),
    } <= sim_pairs
    assert (
        mode_sequence(recorded_plane) == mode_sequence(sim_plane) == [16, 0, 5, 10, 11, 15, 11, 20]
    )


def test_plane_command_acks_and_mission(recorded_plane: list[Any], sim_plane: list[Any]) -> None:
    assert acks(sim_plane) == acks(recorded_plane)
    expected = ["MISSION_ACK:0", *[f"MISSION_REQUEST:{i}" for i in range(6)], "MISSION_ACK:0"]
    assert mission_exchange(recorded_plane) == mission_exchange(sim_plane) == expected
    rec = [m.seq for m in recorded_plane if m.get_type() == "MISSION_ITEM_REACHED"]
    assert (
        rec
        == [m.seq for m in sim_plane if m.get_type() == "MISSION_ITEM_REACHED"]
        == [1, 2, 3, 4, 0]
    )


def test_plane_texts(recorded_plane: list[Any], sim_plane: list[Any]) -> None:
    rec = {shape(t) for t in texts(recorded_plane)} - {shape(t) for t in SITL_ONLY_TEXTS}
    sim = {shape(t) for t in texts(sim_plane)}
    assert rec <= sim, sorted(rec - sim)
    order = [
        "Mission: 1 VTOLTakeoff",
        "Throttle armed",
        "Mission: 2 WP",
        "Transition started airspeed",
        "Transition airspeed reached",
        "Transition done",
        "Reached waypoint #2 dist",
        "Mission: 5 RTL",
        "Set airspeed 20 m/s",
        "SIM Hit ground at",
        "Land complete",
        "Throttle disarmed",
        "PreArm: QLAND mode not armable",
    ]
    for stream in (texts(recorded_plane), texts(sim_plane)):
        idx = [next(i for i, t in enumerate(stream) if t.startswith(o)) for o in order]
        assert idx == sorted(idx), stream


def test_both_mission_download_requests_are_answered() -> None:
    """Real ArduPilot answers MISSION_REQUEST_INT with MISSION_ITEM_INT and the legacy
    MISSION_REQUEST with MISSION_ITEM; the simulator does both."""
    p = make_pilot("copter")
    p.wait_ready()
    assert p.upload([(16, 0, 0, 0, 0), (22, REL, 0, 0, 30), (16, REL, 100, 50, 30)]).type == 0
    p.c.mav.mission_request_list_send(1, 1, 0)
    count = p.h.wait_for(p.c, "MISSION_COUNT")
    assert count is not None and count.count == 3
    p.c.mav.mission_request_int_send(1, 1, 2, 0)
    item_int = p.h.wait_for(p.c, "MISSION_ITEM_INT")
    p.c.mav.mission_request_send(1, 1, 2, 0)
    item = p.h.wait_for(p.c, "MISSION_ITEM")
    assert item_int is not None and item is not None
    assert item_int.command == item.command == 16
    assert abs(item_int.x * 1e-7 - item.x) < 1e-6 and item.z == item_int.z == 30
    assert "got MISSION_REQUEST; use MISSION_REQUEST_INT!" in p.c.texts()
    p.c.mav.mission_request_int_send(1, 1, 0, 0)
    home = p.h.wait_for(p.c, "MISSION_ITEM_INT")
    assert home is not None and home.seq == 0 and abs(home.x - 374112000) < 50
