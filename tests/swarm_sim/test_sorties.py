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
        [(WP, 0, 0, 0, 0), (TAKEOFF, REL, 0, 0, 30), (WP, REL, 150, 0, 30),
         (WP, REL, 150, 130, 30), (WP, REL, 0, 130, 30), (RTL, REL, 0, 0, 0)],
    )  # fmt: skip
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
    for text in ("Arming motors", "Mission: 1 Takeoff", "Reached command #2", "Mission: 5 RTL",
                 "Disarming motors"):  # fmt: skip
        assert text in texts
    assert texts.index("Mission: 5 RTL") < texts.index("Disarming motors")


def test_vtol_sortie_vertical_takeoff_transition_rtl_qland() -> None:
    p = make_pilot("vtol")
    p.wait_ready()
    fly_mission(
        p,
        [(WP, 0, 0, 0, 0), (VTOL_TAKEOFF, REL, 0, 0, 40), (WP, REL, 600, 0, 60),
         (WP, REL, 600, 600, 60), (WP, REL, 0, 600, 60), (RTL, REL, 0, 0, 0)],
    )  # fmt: skip
    assert p.set_mode("AUTO") == 0
    assert p.arm() == 0
    assert p.h.run_until(lambda: p.ap.mode_name == "RTL", 600)
    texts = p.c.texts()
    order = ["Mission: 1 VTOLTakeoff", "Throttle armed", "Mission: 2 WP", "Transition done",
             "Reached waypoint #2 dist", "Mission: 5 RTL"]  # fmt: skip
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
        [(WP, 0, 0, 0, 0), (TAKEOFF, REL, 0, 0, 40), (WP, REL, 800, 0, 80),
         (WP, REL, 800, 800, 80), (WP, REL, -600, 0, 40), (LAND, REL, 0.5, 0, 0)],
    )  # fmt: skip
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
        [(WP, 0, 0, 0, 0), (WP, REL, 60, 0, 0), (WP, REL, 60, 60, 0), (WP, REL, 0, 60, 0),
         (RTL, REL, 0, 0, 0)],
    )  # fmt: skip
    assert p.set_mode("AUTO") == 0
    assert p.arm() == 0
    assert p.h.run_until(lambda: p.ap.mode_name == "HOLD", 900)
    assert "Mission Complete" in p.c.texts()
    b = p.ap.body
    assert math.hypot(b.n, b.e) < 4.0
    assert b.alt == p.ap.home_alt  # 2-D
    assert [m.seq for m in p.c.seen("MISSION_ITEM_REACHED")] == [1, 2, 3, 4]
