"""A waypoint started again while a fixed-wing is already past it (a demo
VTOL circled its PREMISSION leg's first waypoint for 50 minutes, until BATTERY_LOW).

The node uploads a leg in AUTO; the autopilot restarts its current index in the new
mission (recorded: mission-start-in-auto), so the leg's first waypoint is started, and
StartMission's DO_SET_MISSION_CURRENT starts it once more: the previous waypoint is the
point itself. ArduPlane's `set_next_WP` then flies from where the aircraft is
(`Location::line_path_proportion` reads two coincident points as passed, and a
waypoint already passed gets the current location as its previous one), so the
waypoint is passed after at most a turn back. The simulator had no track at all and
only the 15 m acceptance radius: an aircraft that had flown past it with a wider turn
circle circled it for ever. Fast time, real MAVLink bytes."""

from __future__ import annotations

import math
from typing import Any

from tests.swarm_sim.conftest import Pilot, make_pilot

REL = 3  # MAV_FRAME_GLOBAL_RELATIVE_ALT
NAV_WAYPOINT, NAV_VTOL_TAKEOFF, DO_CHANGE_SPEED = 16, 84, 178
MISSION_START, DO_SET_MISSION_CURRENT = 300, 224
ACCEPTED = 0
ACCEPT_M = 15.0  # the node's fixed-wing waypoint acceptance (planning.flight)


def _item(
    p: Pilot,
    cmd: int,
    north: float,
    east: float,
    alt: float,
    params: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0),
) -> tuple[Any, ...]:
    x, y = p.latlon(north, east) if (north or east) else (0, 0)
    return (cmd, REL if (north or east) else 0, params, x, y, alt)


def _cruising_north() -> Pilot:
    """A QuadPlane in AUTO, cruising north at 80 m on its mission's item 2."""
    p = make_pilot("vtol")
    p.wait_ready()
    wp = (0.0, ACCEPT_M, 0.0, 0.0)
    ack = p.upload_raw(
        [
            _item(p, NAV_WAYPOINT, 0, 0, 0),
            _item(p, NAV_VTOL_TAKEOFF, 0, 0, 80),
            _item(p, NAV_WAYPOINT, 5000, 0, 80, wp),
        ]
    )
    assert ack is not None and ack.type == 0
    assert p.set_mode("GUIDED") == ACCEPTED and p.arm() == ACCEPTED
    assert p.set_mode("AUTO") == ACCEPTED and p.command(MISSION_START) == ACCEPTED
    assert p.h.run_until(lambda: p.ap.mission_seq == 2 and p.ap.body.n > 1500.0, 600)
    return p


def test_a_waypoint_started_again_behind_a_fixed_wing_is_flown_from_where_it_is() -> None:
    p = _cruising_north()
    b = p.ap.body
    behind = (b.n - 25.0, b.e + 40.0)  # flown past 25 m ago, 40 m aside: inside its turn circle
    wp = (0.0, ACCEPT_M, 0.0, 0.0)
    ack = p.upload_raw(
        [
            _item(p, NAV_WAYPOINT, 0, 0, 0),
            _item(p, DO_CHANGE_SPEED, 0, 0, 0, (0.0, 30.0, -1.0, 0.0)),  # the leg's speed
            _item(p, NAV_WAYPOINT, *behind, 80, wp),
            _item(p, NAV_WAYPOINT, b.n, b.e - 1500.0, 80, wp),
        ]
    )
    assert ack is not None and ack.type == 0
    assert p.ap.mission_seq == 2  # the upload in AUTO restarted item 2: the waypoint behind
    assert p.command(DO_SET_MISSION_CURRENT, 1) == ACCEPTED  # StartMission
    assert p.command(MISSION_START) == ACCEPTED
    # at most a turn back to it (a 30 m/s turn circle: under 30 s), then on to item 3;
    # without a track it circled the waypoint, 40 m inside its turn circle, for ever
    assert p.h.run_until(lambda: p.ap.mission_seq == 3, 120), (
        f"still on item {p.ap.mission_seq}, "
        f"{math.hypot(p.ap.body.n - behind[0], p.ap.body.e - behind[1]):.0f} m from it"
    )
