"""Each model flies arm -> take-off -> uploaded mission -> RTL -> land in fast time, driven
by a pymavlink client over real MAVLink bytes (no sockets: the fast-time harness)."""

from __future__ import annotations

import math

import pytest

from tests.swarm_sim.conftest import Pilot, make_pilot

REL = 3  # MAV_FRAME_GLOBAL_RELATIVE_ALT
WP, TAKEOFF, RTL, VTOL_TAKEOFF, LAND, VTOL_LAND = 16, 22, 20, 84, 21, 85


def fly_mission(p: Pilot, items: list[tuple[int, int, float, float, float]]) -> None:
    ack = p.upload(items)
    assert ack is not None and ack.type == 0, ack
    assert "Flight plan received" in p.c.texts()


def assert_landed_home(p: Pilot, tolerance_m: float) -> None:
    b = p.ap.body
    assert b.on_ground and not p.ap.armed
    assert math.hypot(b.n - p.ap.home_ne[0], b.e - p.ap.home_ne[1]) < tolerance_m


def test_copter_sortie_like_the_recording() -> None:
    p = make_pilot("copter")
    p.wait_ready()
    fly_mission(
        p,
        [
            (WP, 0, 0, 0, 0),
            (TAKEOFF, REL, 0, 0, 30),
            (WP, REL, 150, 0, 30),
            (WP, REL, 150, 130, 30),
            (WP, REL, 0, 130, 30),
            (RTL, REL, 0, 0, 0),
        ],
    )
    assert p.set_mode("GUIDED") == 0
    assert p.arm() == 0
    assert p.command(22, 0, 0, 0, 0, 0, 0, 30) == 0
    assert p.h.run_until(lambda: p.ap.rel_alt_m > 29.5, 60)
    assert p.set_mode("AUTO") == 0
    assert p.command(300) == 0
    assert p.h.run_until(lambda: not p.ap.armed, 600)
    assert_landed_home(p, 2.0)
    reached = [m.seq for m in p.c.seen("MISSION_ITEM_REACHED")]
    assert reached == [1, 2, 3, 4, 5]
    texts = p.c.texts()
    for text in (
        "Arming motors",
        "Mission: 1 Takeoff",
        "Reached command #2",
        "Mission: 5 RTL",
        "Disarming motors",
    ):
        assert text in texts
    assert texts.index("Mission: 5 RTL") < texts.index("Disarming motors")


def test_vtol_sortie_vertical_takeoff_transition_rtl_qland() -> None:
    p = make_pilot("vtol")
    p.wait_ready()
    fly_mission(
        p,
        [
            (WP, 0, 0, 0, 0),
            (VTOL_TAKEOFF, REL, 0, 0, 40),
            (WP, REL, 600, 0, 60),
            (WP, REL, 600, 600, 60),
            (WP, REL, 0, 600, 60),
            (RTL, REL, 0, 0, 0),
        ],
    )
    assert p.set_mode("AUTO") == 0
    assert p.arm() == 0
    assert p.h.run_until(lambda: p.ap.mode_name == "RTL", 600)
    texts = p.c.texts()
    order = [
        "Mission: 1 VTOLTakeoff",
        "Throttle armed",
        "Mission: 2 WP",
        "Transition done",
        "Reached waypoint #2 dist",
        "Mission: 5 RTL",
    ]
    positions = [next(i for i, t in enumerate(texts) if t.startswith(o)) for o in order]
    assert positions == sorted(positions)
    assert any(t.startswith("Transition started airspeed") for t in texts)
    assert any(t.startswith("Transition airspeed reached") for t in texts)
    p.h.run_for(120)  # loiters at home at the RTL altitude
    assert p.ap.armed and not p.ap.body.on_ground
    assert p.set_mode("QLAND") == 0
    assert p.h.run_until(lambda: not p.ap.armed, 600)
    assert p.c.texts()[-2:] == ["Land complete", "Throttle disarmed"]
    assert_landed_home(p, 250.0)  # QLAND lands where it stops, on the loiter circle
    assert [m.seq for m in p.c.seen("MISSION_ITEM_REACHED")] == [1, 2, 3, 4]


def test_plane_sortie_takeoff_mission_and_landing() -> None:
    p = make_pilot("plane")
    p.wait_ready()
    fly_mission(
        p,
        [
            (WP, 0, 0, 0, 0),
            (TAKEOFF, REL, 0, 0, 40),
            (WP, REL, 800, 0, 80),
            (WP, REL, 800, 800, 80),
            (WP, REL, -600, 0, 40),
            (LAND, REL, 0.5, 0, 0),
        ],
    )
    assert p.set_mode("AUTO") == 0
    assert p.arm() == 0
    assert p.h.run_until(lambda: not p.ap.armed, 900)
    assert_landed_home(p, 150.0)
    assert [m.seq for m in p.c.seen("MISSION_ITEM_REACHED")] == [1, 2, 3, 4, 5]
    texts = p.c.texts()
    assert "Land complete" in texts and texts[-1] == "Throttle disarmed"
    # a fixed-wing never flew below its minimum airspeed while airborne
    assert p.ap.crashed is False


def test_plane_rtl_mode_returns_and_loiters_at_home() -> None:
    p = make_pilot("plane")
    p.wait_ready()
    fly_mission(p, [(WP, 0, 0, 0, 0), (TAKEOFF, REL, 0, 0, 50), (WP, REL, 1500, 0, 80)])
    assert p.set_mode("AUTO") == 0 and p.arm() == 0
    assert p.h.run_until(lambda: p.ap.mission_seq == 2 and p.ap.rel_alt_m > 70, 300)
    assert p.command(20) == 0  # NAV_RETURN_TO_LAUNCH
    assert p.ap.mode_name == "RTL"
    p.h.run_for(300)
    b = p.ap.body
    d = math.hypot(b.n, b.e)
    assert 30 < d < 110, d  # circling home at WP_LOITER_RAD (60 m)
    assert abs(p.ap.rel_alt_m - 100) < 3  # RTL_ALTITUDE


@pytest.mark.parametrize("model", ["rover", "boat"])
def test_ground_vehicle_sortie(model: str) -> None:
    p = make_pilot(model)
    p.wait_ready()
    fly_mission(
        p,
        [
            (WP, 0, 0, 0, 0),
            (WP, REL, 60, 0, 0),
            (WP, REL, 60, 60, 0),
            (WP, REL, 0, 60, 0),
            (RTL, REL, 0, 0, 0),
        ],
    )
    assert p.set_mode("AUTO") == 0
    assert p.arm() == 0
    assert p.h.run_until(lambda: "Mission Complete" in p.c.texts(), 900)
    p.h.run_for(10)
    assert p.ap.mode_name == "AUTO" and p.ap.body.groundspeed < 0.05  # stopped, still in AUTO
    b = p.ap.body
    assert math.hypot(b.n, b.e) < 4.0
    assert b.alt == p.ap.home_alt  # 2-D
    assert [m.seq for m in p.c.seen("MISSION_ITEM_REACHED")] == [1, 2, 3, 4]


@pytest.mark.parametrize(("q_rtl_mode", "lands"), [(0, False), (1, True)])
def test_a_quadplanes_rtl_circles_its_point_or_lands_there_with_q_rtl_mode_1(
    q_rtl_mode: int, lands: bool
) -> None:
    """ArduPlane's ModeRTL: a QuadPlane at its RTL point circles it for good
    (Q_RTL_MODE 0, the default) or switches to QRTL and lands there (1: what the node
    sets for its failsafe, failsafe.py)."""
    p = make_pilot("vtol")
    p.wait_ready()
    p.c.mav.param_set_send(1, 1, b"Q_RTL_MODE", float(q_rtl_mode), 2)
    fly_mission(p, [(WP, 0, 0, 0, 0), (VTOL_TAKEOFF, REL, 0, 0, 40), (WP, REL, 1200, 0, 60)])
    assert p.set_mode("AUTO") == 0 and p.arm() == 0
    assert p.h.run_until(lambda: p.ap.mission_seq == 2 and p.ap.rel_alt_m > 50, 300)
    assert p.set_mode("RTL") == 0
    p.h.run_for(400)
    if lands:
        assert p.ap.mode_name == "QRTL"
        assert_landed_home(p, 10.0)
    else:
        assert p.ap.mode_name == "RTL" and p.ap.armed and p.ap.rel_alt_m > 20


def test_plane_rtl_then_land_via_do_land_start() -> None:
    """ArduPlane's way home and down: RTL with RTL_AUTOLAND=1 flies home, then jumps to
    the mission's DO_LAND_START sequence and lands."""
    p = make_pilot("plane")
    p.wait_ready()
    p.c.mav.param_set_send(1, 1, b"RTL_AUTOLAND", 1, 2)
    fly_mission(
        p,
        [
            (WP, 0, 0, 0, 0),
            (TAKEOFF, REL, 0, 0, 40),
            (WP, REL, 1500, 0, 80),
            (WP, REL, 1500, 1500, 80),
            (189, REL, 0, 0, 0),
            (WP, REL, -700, 0, 40),
            (LAND, REL, 0.5, 0, 0),
        ],
    )
    assert p.set_mode("AUTO") == 0 and p.arm() == 0
    assert p.h.run_until(lambda: p.ap.mission_seq == 3, 300)
    assert p.set_mode("RTL") == 0  # before the end of the mission
    assert p.h.run_until(lambda: p.ap.mode_name == "AUTO", 300)
    assert "Landing sequence start" in p.c.texts()
    assert p.h.run_until(lambda: not p.ap.armed, 600)
    assert_landed_home(p, 150.0)
    assert [m.seq for m in p.c.seen("MISSION_ITEM_REACHED")][-2:] == [5, 6]
    assert p.set_mode("FBWA") == 0
    assert p.command(189) == 0 and p.ap.mode_name == "AUTO"  # MAV_CMD_DO_LAND_START
    assert p.ap.mission_seq == 5


def test_a_quadplane_landed_by_its_mission_arms_only_once_its_current_item_is_set() -> None:
    """Seen against SITL: after a landing its mission flew, ArduPlane refuses to arm
    ("Arm: In landing sequence", AP_Mission's flag) until DO_SET_MISSION_CURRENT."""
    p = make_pilot("vtol")
    p.wait_ready()
    fly_mission(p, [(WP, 0, 0, 0, 0), (VTOL_TAKEOFF, REL, 0, 0, 30), (VTOL_LAND, REL, 0, 0, 0)])
    assert p.set_mode("AUTO") == 0 and p.arm() == 0
    assert p.h.run_until(lambda: not p.ap.armed, 600)
    assert p.set_mode("QLOITER") == 0
    assert p.arm() != 0
    assert "Arm: In landing sequence" in p.c.texts()
    assert p.command(224, 1) == 0  # MAV_CMD_DO_SET_MISSION_CURRENT
    assert p.arm() == 0


def test_vtol_mission_ends_with_a_vertical_landing() -> None:
    p = make_pilot("vtol")
    p.wait_ready()
    fly_mission(
        p,
        [
            (WP, 0, 0, 0, 0),
            (VTOL_TAKEOFF, REL, 0, 0, 40),
            (WP, REL, 1000, 0, 60),
            (VTOL_LAND, REL, 1000, 800, 0),
        ],
    )
    assert p.set_mode("AUTO") == 0 and p.arm() == 0
    assert p.h.run_until(lambda: not p.ap.armed, 900)
    b = p.ap.body
    assert b.on_ground and math.hypot(b.n - 1000, b.e - 800) < 3.0
    assert [m.seq for m in p.c.seen("MISSION_ITEM_REACHED")] == [1, 2, 3]
    texts = p.c.texts()
    assert (
        texts.index("Mission: 3 VTOLLand")
        < texts.index("Land complete")
        < texts.index("Throttle disarmed")
    )


def test_vtol_qrtl_returns_and_lands_vertically() -> None:
    p = make_pilot("vtol")
    p.wait_ready()
    fly_mission(p, [(WP, 0, 0, 0, 0), (VTOL_TAKEOFF, REL, 0, 0, 40), (WP, REL, 2000, 0, 80)])
    assert p.set_mode("AUTO") == 0 and p.arm() == 0
    assert p.h.run_until(lambda: p.ap.body.n > 1200, 300)
    assert p.set_mode("QRTL") == 0
    assert p.h.run_until(lambda: not p.ap.armed, 900)
    assert_landed_home(p, 3.0)


def test_mission_loiters_speed_change_and_jumps() -> None:
    p = make_pilot("copter")
    p.wait_ready()
    fly_mission(
        p,
        [
            (WP, 0, 0, 0, 0),
            (TAKEOFF, REL, 0, 0, 20),
            (178, 0, 0, 0, 0),
            (19, REL, 50, 0, 20),
            (WP, REL, 250, 0, 20),
            (177, 0, 0, 0, 0),
            (RTL, REL, 0, 0, 0),
        ],
    )
    # set the params the simple upload helper leaves at 0
    items = p.ap.mission_items
    from dataclasses import replace

    items[2] = replace(items[2], param1=1, param2=4.0)  # DO_CHANGE_SPEED ground speed 4 m/s
    items[3] = replace(items[3], param1=20.0)  # LOITER_TIME 20 s
    items[5] = replace(items[5], param1=4, param2=1)  # DO_JUMP to 4, once
    assert p.set_mode("GUIDED") == 0 and p.arm() == 0
    assert p.command(22, 0, 0, 0, 0, 0, 0, 20) == 0
    assert p.h.run_until(lambda: p.ap.rel_alt_m > 19.5, 60)
    assert p.set_mode("AUTO") == 0 and p.command(300) == 0
    assert p.h.run_until(lambda: p.ap.mission_seq == 3, 120)
    assert p.h.run_until(lambda: p.ap.mission_seq == 4, 120)
    arrive = next(
        t
        for t, m in p.c.history
        if m.get_type() == "STATUSTEXT" and m.text == "Mission: 3 LoitTime"
    )
    left = next(
        t for t, m in p.c.history if m.get_type() == "STATUSTEXT" and m.text == "Mission: 4 WP"
    )
    assert left - arrive >= 20.0
    p.h.run_for(20)
    assert abs(p.ap.body.groundspeed - 4.0) < 0.3  # DO_CHANGE_SPEED applies
    assert p.h.run_until(lambda: not p.ap.armed, 900)
    reached = [m.seq for m in p.c.seen("MISSION_ITEM_REACHED")]
    assert reached == [1, 3, 4, 4, 6]  # the jump flew waypoint 4 twice


def test_plane_loiter_turns() -> None:
    p = make_pilot("plane")
    p.wait_ready()
    fly_mission(
        p, [(WP, 0, 0, 0, 0), (TAKEOFF, REL, 0, 0, 40), (18, REL, 800, 0, 60), (WP, REL, 0, 0, 60)]
    )
    from dataclasses import replace

    p.ap.mission_items[2] = replace(
        p.ap.mission_items[2], param1=2.0, param3=-100.0
    )  # 2 turns ccw r=100
    assert p.set_mode("AUTO") == 0 and p.arm() == 0
    assert p.h.run_until(lambda: p.ap.mission_seq == 2, 300)
    start = p.h.now
    assert p.h.run_until(lambda: p.ap.mission_seq == 3, 600)
    circling = p.h.now - start
    one_turn = 2 * math.pi * 100 / p.ap.airframe.cruise_speed_m_s
    assert 2 * one_turn * 0.9 < circling < 2 * one_turn + 120


def test_rover_rtl_mode() -> None:
    p = make_pilot("rover")
    p.wait_ready()
    assert p.set_mode("GUIDED") == 0 and p.arm() == 0
    x, y = p.latlon(40, 30)
    assert p.command_int(192, 6, -1, 0, 0, 0, x=x, y=y, z=0) == 0
    assert p.h.run_until(lambda: math.hypot(p.ap.body.n - 40, p.ap.body.e - 30) < 2.5, 120)
    assert p.set_mode("RTL") == 0
    assert p.h.run_until(lambda: "Reached destination" in p.c.texts(), 120)
    assert math.hypot(p.ap.body.n, p.ap.body.e) < 2.5 and p.ap.armed  # rovers never auto-disarm


def test_plane_takeoff_mode_climbs_out_then_loiters() -> None:
    p = make_pilot("plane")
    p.wait_ready()
    assert p.set_mode("TAKEOFF") == 0 and p.arm() == 0
    assert p.h.run_until(lambda: p.ap.rel_alt_m > 49, 120)  # TKOFF_ALT
    p.h.run_for(120)
    b = p.ap.body
    assert abs(p.ap.rel_alt_m - 50) < 2 and b.airspeed >= p.ap.airframe.min_airspeed_m_s
    assert p.ap.mode_name == "TAKEOFF" and p.ap.armed
