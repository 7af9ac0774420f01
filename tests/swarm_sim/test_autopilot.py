"""ArduPilot behaviour of the simulated autopilot, command by command: modes, arming,
take-off rules per firmware, guided control, speed, parachute, fence, streams and
parameters. Fast time, real MAVLink bytes."""

from __future__ import annotations

import math

import pytest

from swarm_sim.core import SimOptions, StartupTimes
from swarm_sim.core.firmware import Behaviour
from tests.swarm_sim.conftest import MODELS, Pilot, make_pilot

REL, LOCAL_OFFSET_NED = 6, 7
ACCEPTED, DENIED, UNSUPPORTED, FAILED = 0, 2, 3, 4


def airborne_copter(alt: float = 20.0) -> Pilot:
    p = make_pilot("copter")
    p.wait_ready()
    assert p.set_mode("GUIDED") == ACCEPTED and p.arm() == ACCEPTED
    assert p.command(22, 0, 0, 0, 0, 0, 0, alt) == ACCEPTED
    assert p.h.run_until(lambda: p.ap.rel_alt_m > alt - 0.5, 60)
    return p


@pytest.mark.parametrize(
    ("model", "mode"),
    [
        ("copter", "GUIDED"),
        ("vtol", "AUTO"),
        ("plane", "GUIDED"),
        ("rover", "GUIDED"),
        ("boat", "AUTO"),
    ],
)
def test_position_modes_and_arming_refused_until_the_ekf_has_a_position(
    model: str, mode: str
) -> None:
    p = make_pilot(model)
    assert p.h.run_until(lambda: p.ap.ready, 10)
    assert not p.ap.ekf_position
    assert p.set_mode(mode) == FAILED
    assert f"Mode change to {mode} failed: requires position" in p.c.texts()
    assert p.arm() == FAILED
    assert any(t.startswith("PreArm: ") for t in p.c.texts())
    assert not p.ap.armed
    p.wait_ready()
    assert p.set_mode(mode) == ACCEPTED
    assert p.ap.mode_name == mode


def test_mode_change_is_followed_by_a_heartbeat_and_set_mode_is_acked_as_command_11() -> None:
    p = make_pilot("copter")
    p.wait_ready()
    p.c.clear()
    assert p.set_mode("LOITER") == ACCEPTED
    after_ack = p.c.inbox
    hb = next(m for m in after_ack if m.get_type() == "HEARTBEAT")
    assert hb.custom_mode == 5
    p.c.mav.set_mode_send(1, 1, 4)  # the SET_MODE message: base_mode custom flag, GUIDED
    ack = p.h.wait_for(p.c, "COMMAND_ACK", cond=lambda m: m.command == 11)
    assert ack is not None and ack.result == ACCEPTED and p.ap.mode_name == "GUIDED"
    p.c.mav.set_mode_send(1, 0, 4)  # no custom-mode flag: DENIED, as ArduPilot
    assert p.h.wait_for(p.c, "COMMAND_ACK", cond=lambda m: m.command == 11).result == DENIED


def test_unknown_modes() -> None:
    p = make_pilot("copter")
    p.wait_ready()
    assert p.command(176, 1, 99) == FAILED and "No such mode 99" in p.c.texts()
    plane = make_pilot("plane")
    plane.wait_ready()
    assert plane.set_mode("QHOVER") == FAILED and "Q_ENABLE 0" in plane.c.texts()
    vtol = make_pilot("vtol")
    vtol.wait_ready()
    assert vtol.set_mode("QHOVER") == ACCEPTED


def test_arming_checks_and_forced_arming() -> None:
    p = make_pilot("copter")
    p.wait_ready()
    assert p.set_mode("AUTO") == ACCEPTED
    assert p.arm() == FAILED
    assert "Arm: AUTO mode not armable" in p.c.texts()  # ArduCopter: an arm check
    assert p.command(400, 1, 2989) == ACCEPTED  # forced
    assert p.ap.armed
    p2 = make_pilot("vtol")
    p2.wait_ready()
    assert p2.set_mode("QLAND") == ACCEPTED and p2.arm() == FAILED
    assert "PreArm: QLAND mode not armable" in p2.c.texts()
    # failing checks are repeated every 30 s while disarmed
    p2.h.run_for(65)
    assert p2.c.texts().count("PreArm: QLAND mode not armable") >= 3


@pytest.mark.parametrize(
    ("model", "mode", "armable"),
    [
        ("vtol", "QLAND", False),
        ("vtol", "QRTL", False),
        ("vtol", "RTL", False),  # ArduPlane ModeRTL: _pre_arm_checks() false
        ("vtol", "QAUTOTUNE", True),
        ("vtol", "QLOITER", True),
        ("vtol", "GUIDED", True),
        ("copter", "LAND", False),
        ("copter", "RTL", False),
        ("copter", "GUIDED", True),
        ("copter", "LOITER", True),
    ],
)
def test_arming_is_refused_in_the_modes_ardupilot_refuses(
    model: str, mode: str, armable: bool
) -> None:
    p = make_pilot(model)
    p.wait_ready()
    assert p.set_mode(mode) == ACCEPTED
    assert (p.arm() == ACCEPTED) == armable, p.c.texts()


def test_a_refusals_reason_comes_after_its_command_ack() -> None:
    """As ArduPilot sends them (seen against SITL): the COMMAND_ACK at once, the
    STATUSTEXT that explains a refusal from its queue after it."""
    p = make_pilot("copter")
    p.wait_ready()
    assert p.set_mode("LAND") == ACCEPTED
    p.c.clear()
    p.c.mav.command_long_send(p.ap.sysid, 1, 400, 0, 1, 0, 0, 0, 0, 0, 0)  # arm
    p.h.run_for(1.0)
    kinds = [
        m.get_type()
        for m in p.c.inbox
        if m.get_type() == "COMMAND_ACK" or (m.get_type() == "STATUSTEXT" and "Arm" in m.text)
    ]
    assert kinds[:2] == ["COMMAND_ACK", "STATUSTEXT"]


def test_copter_disarms_itself_when_it_does_not_take_off() -> None:
    p = make_pilot("copter")
    p.wait_ready()
    assert p.set_mode("GUIDED") == ACCEPTED and p.arm() == ACCEPTED
    t0 = p.h.now
    assert p.h.run_until(lambda: not p.ap.armed, 30)
    assert 9.5 <= p.h.now - t0 <= 11  # DISARM_DELAY
    assert "Disarming motors" in p.c.texts()


def test_disarm_in_flight_is_refused_unless_forced() -> None:
    p = airborne_copter(30)
    assert p.command(400, 0) == FAILED and p.ap.armed
    assert p.command(400, 0, 21196) == ACCEPTED and not p.ap.armed
    assert p.h.run_until(lambda: p.ap.body.on_ground, 30)
    assert p.ap.crashed and "Crash: Disarming" not in p.c.texts()  # already disarmed
    assert any(t.startswith("SIM Hit ground at") for t in p.c.texts())


@pytest.mark.parametrize(
    ("model", "mode", "frame_long", "result"),
    [
        ("copter", "STABILIZE", None, FAILED),
        ("rover", "GUIDED", None, UNSUPPORTED),
        ("plane", "GUIDED", None, FAILED),
        ("vtol", "FBWA", None, FAILED),
    ],
)
def test_takeoff_refused(model: str, mode: str, frame_long: None, result: int) -> None:
    p = make_pilot(model)
    p.wait_ready()
    assert p.set_mode(mode) == ACCEPTED
    p.command(400, 1, 2989)
    assert p.command(22, 0, 0, 0, 0, 0, 0, 30) == result
    if model == "vtol":
        assert "User Takeoff only in GUIDED mode" in p.c.texts()


def test_copter_takeoff_frames() -> None:
    p = make_pilot("copter")
    p.wait_ready()
    assert p.set_mode("GUIDED") == ACCEPTED and p.arm() == ACCEPTED
    assert p.command_int(22, 0, z=20) == DENIED  # only GLOBAL_RELATIVE_ALT
    assert p.command_int(22, REL, z=20) == ACCEPTED
    assert p.h.run_until(lambda: p.ap.rel_alt_m > 19.5, 60)
    assert p.command_int(22, REL, z=40) == FAILED  # already flying
    assert not p.c.seen("MISSION_ITEM_REACHED")


def test_vtol_guided_takeoff_then_reposition_transitions_to_fixed_wing() -> None:
    p = make_pilot("vtol")
    p.wait_ready()
    assert p.set_mode("GUIDED") == ACCEPTED
    assert p.command_int(22, LOCAL_OFFSET_NED, z=-30) == FAILED
    assert "Must be armed for takeoff" in p.c.texts()
    assert p.arm() == ACCEPTED
    assert p.command_int(22, 3, z=-30) == DENIED  # QuadPlane wants LOCAL_OFFSET_NED
    assert p.command_int(22, LOCAL_OFFSET_NED, z=-30) == ACCEPTED
    assert p.h.run_until(lambda: p.ap.rel_alt_m > 29.4, 60)
    p.h.run_for(5)
    assert abs(p.ap.rel_alt_m - 30) < 1 and p.ap.body.groundspeed < 0.5  # hovering
    x, y = p.latlon(1500, 0)
    assert p.command_int(192, REL, -1, 0, 80, 0, x=x, y=y, z=60) == ACCEPTED
    assert p.h.run_until(lambda: [m.seq for m in p.c.seen("MISSION_ITEM_REACHED")] == [0], 300)
    assert "Transition done" in p.c.texts()
    p.h.run_for(120)
    b = p.ap.body
    assert 60 < math.hypot(b.n - 1500, b.e) < 100  # loitering at the requested radius
    assert b.airspeed >= p.ap.airframe.min_airspeed_m_s


def test_reposition_rules() -> None:
    p = airborne_copter(20)
    x, y = p.latlon(100, 50)
    p.c.mav.command_long_send(1, 1, 192, 0, -1, 1, 0, 0, x * 1e-7, y * 1e-7, 20)
    assert p.h.wait_for(p.c, "COMMAND_ACK", cond=lambda m: m.command == 192).result == UNSUPPORTED
    assert p.set_mode("LOITER") == ACCEPTED
    assert p.command_int(192, REL, -1, 0, 0, 0, x=x, y=y, z=20) == DENIED
    assert p.command_int(192, REL, -1, 1, 0, 0, x=x, y=y, z=25) == ACCEPTED  # change-mode flag
    assert p.ap.mode_name == "GUIDED"
    assert p.h.run_until(lambda: math.hypot(p.ap.body.n - 100, p.ap.body.e - 50) < 1.0, 120)
    assert abs(p.ap.rel_alt_m - 25) < 1.0
    assert p.command_int(192, REL, -1, 0, 0, 0, x=0, y=0, z=25) == DENIED


def test_position_targets_copter_moves_plane_changes_only_altitude() -> None:
    p = airborne_copter(20)
    x, y = p.latlon(-60, 40)
    p.c.mav.set_position_target_global_int_send(
        0, 1, 1, REL, 0b110111111000, x, y, 30, 0, 0, 0, 0, 0, 0, 0, 0
    )
    assert p.h.run_until(lambda: math.hypot(p.ap.body.n + 60, p.ap.body.e - 40) < 1.0, 120)
    assert abs(p.ap.rel_alt_m - 30) < 1.0
    # velocity: 3 m/s east, held for GUID_TIMEOUT then stop
    p.c.mav.set_position_target_global_int_send(
        0, 1, 1, REL, 0b110111000111, 0, 0, 0, 0, 3, 0, 0, 0, 0, 0, 0
    )
    p.h.run_for(1.5)
    assert p.ap.body.ve > 2.0
    plane = make_pilot("plane")
    plane.wait_ready()
    mission = [(16, 0, 0, 0, 0), (22, 3, 0, 0, 50), (16, 3, 3000, 0, 50)]
    assert plane.upload(mission).type == 0
    assert plane.set_mode("AUTO") == ACCEPTED and plane.arm() == ACCEPTED
    assert plane.h.run_until(lambda: plane.ap.mission_seq == 2, 200)
    assert plane.set_mode("GUIDED") == ACCEPTED
    n0, e0 = plane.ap.body.n, plane.ap.body.e
    x, y = plane.latlon(-5000, -5000)
    plane.c.mav.set_position_target_global_int_send(
        0, 1, 1, REL, 0b110111111000, x, y, 90, 0, 0, 0, 0, 0, 0, 0, 0
    )
    plane.h.run_for(60)
    b = plane.ap.body
    assert abs(plane.ap.rel_alt_m - 90) < 3  # altitude taken
    assert math.hypot(b.n - n0, b.e - e0) < 300  # still loitering where GUIDED began


def test_change_speed() -> None:
    p = airborne_copter(20)
    assert p.command(178, 1, 0) == DENIED
    assert p.command(178, 1, 4) == ACCEPTED
    x, y = p.latlon(300, 0)
    assert p.command_int(192, REL, -1, 0, 0, 0, x=x, y=y, z=20) == ACCEPTED
    p.h.run_for(40)
    assert abs(p.ap.body.groundspeed - 4.0) < 0.3
    plane = make_pilot("plane")
    plane.wait_ready()
    assert plane.command(178, 0, 20) == FAILED  # FBWA: not GUIDED/AUTO
    assert plane.set_mode("GUIDED") == ACCEPTED
    assert plane.command(178, 0, 99) == FAILED  # above AIRSPEED_MAX
    assert plane.command(178, 0, 20) == ACCEPTED and "Set airspeed 20 m/s" in plane.c.texts()


def test_parachute_release_in_flight() -> None:
    p = make_pilot("vtol")
    p.wait_ready()
    assert p.set_mode("GUIDED") == ACCEPTED and p.arm() == ACCEPTED
    assert p.command(208, 2) == FAILED or "Parachute: Landed" in p.c.texts()
    assert p.command(22, 0, 0, 0, 0, 0, 0, 60) == ACCEPTED
    assert p.h.run_until(lambda: p.ap.rel_alt_m > 59, 120)
    assert p.command(208, 2) == ACCEPTED
    assert "Parachute: Released" in p.c.texts() and not p.ap.armed
    p.c.clear()
    hb = p.h.wait_for(p.c, "HEARTBEAT")
    assert hb.system_status == 6  # EMERGENCY
    p.h.run_for(3)
    assert 4.0 < p.ap.body.vd < 6.0
    assert p.h.run_until(lambda: p.ap.body.on_ground, 60)
    assert not p.ap.crashed
    assert p.command(208, 2) == FAILED and "Parachute already released" in p.c.texts()


def test_fence_breach_triggers_rtl() -> None:
    p = airborne_copter(20)
    square = [(-100, -100), (-100, 100), (100, 100), (100, -100)]
    fence = [(5001, 3, (4.0, 0, 0, 0), *p.latlon(n, e), 0) for n, e in square]
    assert p.upload_raw(fence, 1).type == 0
    assert p.command(207, 1) == ACCEPTED
    x, y = p.latlon(300, 0)
    assert p.command_int(192, REL, -1, 0, 0, 0, x=x, y=y, z=20) == ACCEPTED
    assert p.h.run_until(lambda: p.ap.mode_name == "RTL", 120)
    assert "Fence Breached" in p.c.texts()
    status = p.h.wait_for(p.c, "FENCE_STATUS", cond=lambda m: m.breach_count == 1)
    assert status is not None and status.breach_type == 3
    assert p.ap.body.n < 110
    assert p.h.run_until(lambda: not p.ap.armed, 200)


def test_message_intervals_and_data_streams() -> None:
    p = make_pilot("copter")
    p.wait_ready()

    def rate(mtype: str, seconds: float = 20.0) -> float:
        p.c.clear()
        p.h.run_for(seconds)
        return sum(1 for m in p.c.inbox if m.get_type() == mtype) / seconds

    assert abs(rate("GLOBAL_POSITION_INT") - 4.0) < 0.2  # default
    assert p.command(511, 33, 100_000) == ACCEPTED
    assert abs(rate("GLOBAL_POSITION_INT") - 10.0) < 0.3
    assert p.command(511, 33, -1) == ACCEPTED
    assert rate("GLOBAL_POSITION_INT") == 0
    assert p.command(511, 9999, 100_000) == FAILED  # nothing to stream
    p.c.mav.request_data_stream_send(1, 1, 6, 2, 1)  # MAV_DATA_STREAM_POSITION at 2 Hz
    assert abs(rate("GLOBAL_POSITION_INT") - 2.0) < 0.2
    assert rate("HEARTBEAT") == pytest.approx(1.0, abs=0.1)
    assert p.command(510, 33) == ACCEPTED
    assert p.h.wait_for(p.c, "MESSAGE_INTERVAL").interval_us == 500_000
    assert p.command(512, 148) == ACCEPTED  # REQUEST_MESSAGE AUTOPILOT_VERSION
    version = p.h.wait_for(p.c, "AUTOPILOT_VERSION")
    assert version is not None and version.capabilities & 4  # MISSION_INT
    assert p.command(512, 242) == ACCEPTED and p.h.wait_for(p.c, "HOME_POSITION") is not None


def test_parameters_and_wind() -> None:
    p = make_pilot("plane", options=SimOptions(sysid=1, startup=StartupTimes()))
    p.wait_ready()
    p.c.mav.param_request_list_send(1, 1)
    p.h.run_for(1)
    values = {m.param_id: m for m in p.c.seen("PARAM_VALUE")}
    assert {"SYSID_THISMAV", "AIRSPEED_CRUISE", "RTL_ALTITUDE", "SIM_WIND_SPD"} <= set(values)
    assert all(m.param_count == len(values) for m in values.values())
    p.c.clear()
    p.c.mav.param_set_send(1, 1, b"SIM_WIND_SPD", 8.0, 9)
    echo = p.h.wait_for(p.c, "PARAM_VALUE", cond=lambda m: m.param_id == "SIM_WIND_SPD")
    assert echo is not None and echo.param_value == 8.0
    p.c.mav.param_set_send(1, 1, b"SIM_WIND_DIR", 270.0, 9)  # from the west
    p.h.run_for(1)
    assert p.ap.body.wind_e == pytest.approx(8.0) and abs(p.ap.body.wind_n) < 1e-9
    p.c.mav.param_request_read_send(1, 1, b"NO_SUCH_PARAM", -1)
    p.h.run_for(1)
    assert p.ap.counters["param_unknown"] == 1


def test_plane_holds_its_track_in_a_crosswind() -> None:
    p = make_pilot("plane", options=SimOptions(wind_speed_m_s=10.0, wind_from_deg=270.0))
    p.wait_ready()
    mission = [(16, 0, 0, 0, 0), (22, 3, 0, 0, 50), (16, 3, 400, 0, 50), (16, 3, 3000, 0, 50)]
    assert p.upload(mission).type == 0
    assert p.set_mode("AUTO") == ACCEPTED and p.arm() == ACCEPTED
    assert p.h.run_until(lambda: p.ap.mission_seq == 3 and p.ap.body.n > 1000, 300)
    b = p.ap.body
    assert abs(b.e) < 40  # on track despite 10 m/s of crosswind
    assert abs(b.course_deg - 0) < 5 or abs(b.course_deg - 360) < 5
    assert abs(b.heading_deg - b.course_deg) > 10  # crabbing


def test_system_time_is_the_injected_clock_once_locked() -> None:
    p = make_pilot("rover")
    p.h.run_until(lambda: bool(p.c.seen("SYSTEM_TIME")), 5)
    assert p.c.seen("SYSTEM_TIME")[0].time_unix_usec == 0
    p.wait_ready()
    p.c.clear()
    st = p.h.wait_for(p.c, "SYSTEM_TIME")
    assert abs(st.time_unix_usec / 1e6 - p.h.now) < 1.0


def test_system_time_can_run_behind_the_clock_as_sitls_gps_time_did() -> None:
    """SITL's GPS time ran 7.5-10.5 s behind the host's clock (make sitl-fleet): the
    simulator can do the same (the node warns CLOCK_SKEW once, test_monitoring)."""
    p = make_pilot("copter", options=SimOptions(gps_time_offset_s=-9.8))
    p.wait_ready()
    p.c.clear()
    st = p.h.wait_for(p.c, "SYSTEM_TIME")
    assert st.time_unix_usec / 1e6 - p.h.now == pytest.approx(-9.8, abs=0.5)


@pytest.mark.parametrize("model", MODELS)
def test_battery_drains_faster_when_moving(model: str) -> None:
    p = make_pilot(model)
    p.wait_ready()
    before = p.ap.battery.consumed_mah
    p.h.run_for(60)
    idle = p.ap.battery.consumed_mah - before
    assert idle > 0
    status = p.h.wait_for(p.c, "BATTERY_STATUS")
    assert (
        status.battery_remaining <= 100 and status.voltages[0] > 3000 * p.ap.airframe.battery.cells
    )
    # now under way: take off where it flies, then a long leg north
    ground = model in ("rover", "boat")
    items = [(16, 0, 0, 0, 0)] + ([] if ground else [(22, 3, 0, 0, 40)])
    items += [(16, 3, 5000, 0, 40)]
    assert p.upload(items).type == 0
    if model == "copter":  # ArduCopter arms in GUIDED, then AUTO and MISSION_START
        assert p.set_mode("GUIDED") == ACCEPTED and p.arm() == ACCEPTED
        assert p.set_mode("AUTO") == ACCEPTED and p.command(300) == ACCEPTED
    else:
        assert p.set_mode("AUTO") == ACCEPTED and p.arm() == ACCEPTED
    assert p.h.run_until(lambda: p.ap.body.groundspeed > 1.0, 120), "never got under way"
    before = p.ap.battery.consumed_mah
    p.h.run_for(60)
    moving = p.ap.battery.consumed_mah - before
    assert moving > 5 * idle, (idle, moving)
    p.c.clear()
    later = p.h.wait_for(p.c, "BATTERY_STATUS")
    assert later.current_battery > 100 * p.ap.airframe.battery.idle_current_a  # cA


def test_timesync_is_answered() -> None:
    p = make_pilot("copter")
    p.c.mav.timesync_send(0, 123456789)
    reply = p.h.wait_for(p.c, "TIMESYNC", cond=lambda m: m.ts1 == 123456789)
    assert reply is not None and reply.tc1 > 0


def test_modes_table_covers_every_behaviour() -> None:
    from swarm_sim.core.firmware import MODES

    used = {spec.behaviour for table in MODES.values() for spec in table.values()}
    assert used == set(Behaviour)


def test_copter_auto_from_the_ground_needs_a_takeoff_item() -> None:
    p = make_pilot("copter")
    p.wait_ready()
    assert p.upload([(16, 0, 0, 0, 0), (16, 6, 50, 0, 20)]).type == 0
    assert p.set_mode("GUIDED") == ACCEPTED and p.arm() == ACCEPTED
    assert p.set_mode("AUTO") == FAILED and "Auto: Missing Takeoff Cmd" in p.c.texts()
    assert p.upload([(16, 0, 0, 0, 0), (22, 6, 0, 0, 20), (16, 6, 50, 0, 20)]).type == 0
    assert p.set_mode("AUTO") == ACCEPTED and p.command(300) == ACCEPTED
    assert p.h.run_until(lambda: [m.seq for m in p.c.seen("MISSION_ITEM_REACHED")] == [1, 2], 120)
    assert p.ap.armed and abs(p.ap.rel_alt_m - 20) < 1
