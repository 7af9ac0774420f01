"""Waypoint -> MAVLink mission items per vehicle type; fence and rally items;
AutopilotState -> VehicleStatus."""

from __future__ import annotations

import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from swarm_node.core.autopilot.conversion import (
    ConversionError,
    fence_items,
    mission_items,
    mission_items_with_index,
    rally_items,
)
from swarm_node.core.autopilot.items import ItemKind, Waypoint
from swarm_node.core.autopilot.mission_item import MavCmd, MavFrame
from swarm_node.core.autopilot.requests import UploadFence, UploadRally
from swarm_node.core.autopilot.state import AutopilotState
from swarm_node.core.autopilot.status import mission_progress_pct, to_vehicle_status
from swarm_proto import FsmState, GeoPoint, MissionState, VehicleType, validate

HOME = GeoPoint(37.4112, -5.9889, 10.0)
ROUTE = (
    Waypoint(ItemKind.TAKEOFF, alt_rel_m=40),
    Waypoint(lat_deg=37.415, lon_deg=-5.985, alt_rel_m=60, acceptance_radius_m=5),
    Waypoint(
        ItemKind.LOITER_TURNS,
        lat_deg=37.416,
        lon_deg=-5.984,
        alt_rel_m=60,
        turns=2,
        loiter_radius_m=-80,
    ),
    Waypoint(ItemKind.LOITER_TIME, lat_deg=37.417, lon_deg=-5.983, alt_rel_m=60, hold_s=30),
    Waypoint(ItemKind.CHANGE_SPEED, speed_m_s=18),
    Waypoint(ItemKind.LAND, lat_deg=37.4112, lon_deg=-5.9889),
)


@pytest.mark.parametrize(
    ("vt", "commands"),
    [
        (VehicleType.COPTER, [16, 22, 16, 18, 19, 178, 21]),
        (VehicleType.VTOL, [16, 84, 16, 18, 19, 178, 85]),
        (VehicleType.PLANE, [16, 22, 16, 18, 19, 178, 189, 21]),
        (VehicleType.ROVER, [16, 16, 16, 19, 178, 16]),
        (VehicleType.BOAT, [16, 16, 16, 19, 178, 16]),
    ],
)
def test_each_vehicle_type_gets_what_ardupilot_expects(
    vt: VehicleType, commands: list[int]
) -> None:
    items, index = mission_items_with_index(ROUTE, vt, HOME)
    assert [i.command for i in items] == commands
    assert [i.seq for i in items] == list(range(len(items)))
    assert items[0].frame == MavFrame.GLOBAL and items[0].lat_deg == HOME.lat_deg
    assert len(index) == len(ROUTE) and index == sorted(index)
    loiter = (
        next(i for i in items if i.command == MavCmd.NAV_LOITER_TURNS)
        if vt not in (VehicleType.ROVER, VehicleType.BOAT)
        else None
    )
    if loiter is not None:
        assert (loiter.param1, loiter.param3) == (2.0, -80.0)  # counter-clockwise kept
    speed = next(i for i in items if i.command == MavCmd.DO_CHANGE_SPEED)
    assert speed.param1 == (0 if vt in (VehicleType.PLANE, VehicleType.VTOL) else 1)
    assert speed.param2 == 18 and speed.frame == MavFrame.MISSION
    if vt == VehicleType.PLANE:
        assert items[1].param1 == 15.0  # take-off pitch
    for it in items:
        assert it.problem() is None


def test_a_waypoint_speed_comes_before_it_and_rtl_has_no_position() -> None:
    items = mission_items(
        (Waypoint(lat_deg=1, lon_deg=2, alt_rel_m=3, speed_m_s=9), Waypoint(ItemKind.RTL)),
        VehicleType.COPTER,
    )
    assert [i.command for i in items] == [16, 178, 16, 20]
    assert items[-1].frame == MavFrame.GLOBAL_RELATIVE_ALT


@pytest.mark.parametrize(
    "wp",
    [
        Waypoint(lat_deg=95, lon_deg=0),
        Waypoint(lat_deg=0, lon_deg=math.nan),
        Waypoint(alt_rel_m=math.inf, lat_deg=1, lon_deg=1),
        Waypoint(ItemKind.TAKEOFF, alt_rel_m=-5),
        Waypoint(ItemKind.CHANGE_SPEED),
        Waypoint(ItemKind.CHANGE_SPEED, speed_m_s=0),
        Waypoint(ItemKind.LOITER_TURNS, lat_deg=1, lon_deg=1, turns=0),
    ],
)
def test_bad_waypoints_raise(wp: Waypoint) -> None:
    with pytest.raises(ConversionError):
        mission_items((wp,), VehicleType.COPTER)


def test_no_mission_for_unknown_vehicles() -> None:
    with pytest.raises(ConversionError):
        mission_items((), VehicleType.GCS)


def test_fence_items() -> None:
    fence = UploadFence(
        inclusion_polygons=(
            ((0.0, 0.0), (0.0, 1.0), (1.0, 1.0), (0.0, 0.0)),
        ),  # closed ring: opened
        exclusion_polygons=(((0.2, 0.2), (0.2, 0.3), (0.3, 0.3)),),
        exclusion_circles=((0.5, 0.5, 120.0),),
    )
    items = fence_items(fence)
    assert [(i.command, i.param1) for i in items] == [(5001, 3)] * 3 + [(5002, 3)] * 3 + [
        (5004, 120)
    ]
    assert all(i.mission_type == 1 and i.frame == MavFrame.GLOBAL for i in items)
    with pytest.raises(ConversionError, match="not a simple polygon"):
        fence_items(
            UploadFence(exclusion_polygons=(((0.0, 0.0), (1.0, 1.0), (0.0, 1.0), (1.0, 0.0)),))
        )


def test_rally_items() -> None:
    (item,) = rally_items(UploadRally(points=((37.4, -5.9, 50.0),)))
    assert (item.command, item.mission_type, item.alt_m, item.frame) == (5100, 2, 50.0, 3)


def test_vehicle_status_from_state() -> None:
    state = AutopilotState(
        sysid=1,
        lat_deg=37.4,
        lon_deg=-5.9,
        alt_msl_m=50.0,
        alt_rel_m=40.0,
        heading_deg=359.999,
        mode_number=10,
        armed=True,
        battery_pct=77,
        battery_v=23.1,
        gps_sats=14,
        position_time_unix_s=1.8e9,
        mission_count=6,
        mission_current=3,
        mission_reached=2,
    )
    status = to_vehicle_status(
        state,
        vehicle_id=9,
        now_unix_s=1.0,
        fsm_state=FsmState.GO_MISSION,
        mission_state=MissionState.MISSION,
    )
    assert status is not None
    validate(status)
    assert (status.ap_mode, status.armed, status.time_unix_s, status.mission_progress_pct) == (
        10,
        True,
        1.8e9,
        40,
    )
    assert status.fsm_state == FsmState.GO_MISSION
    assert to_vehicle_status(AutopilotState(), vehicle_id=9, now_unix_s=1.0) is None
    assert (
        to_vehicle_status(
            state, vehicle_id=9, now_unix_s=1.0, mission_progress=7
        ).mission_progress_pct
        == 7
    )  # type: ignore[union-attr]


def test_status_after_a_link_loss_carries_the_time_of_the_last_data() -> None:
    """After a link loss the node republishes the last state; its
    time is the last sample's (GPS time, or without it the last message's), never now."""
    here = {"lat_deg": 37.4, "lon_deg": -5.9, "alt_msl_m": 50.0, "alt_rel_m": 40.0}
    up = AutopilotState(link_ok=True, last_message_s=1000.0, **here)
    down = AutopilotState(link_ok=False, last_message_s=1000.0, **here)
    gps = AutopilotState(link_ok=False, last_message_s=1000.0, position_time_unix_s=999.9, **here)
    assert to_vehicle_status(up, vehicle_id=1, now_unix_s=1000.1).time_unix_s == 1000.1  # type: ignore[union-attr]
    assert to_vehicle_status(down, vehicle_id=1, now_unix_s=1030.0).time_unix_s == 1000.0  # type: ignore[union-attr]
    assert to_vehicle_status(gps, vehicle_id=1, now_unix_s=1030.0).time_unix_s == 999.9  # type: ignore[union-attr]


def test_mission_progress() -> None:
    assert mission_progress_pct(AutopilotState()) == 0
    assert mission_progress_pct(AutopilotState(mission_count=6, mission_current=1)) == 0
    assert (
        mission_progress_pct(AutopilotState(mission_count=6, mission_current=5, mission_reached=4))
        == 80
    )
    assert mission_progress_pct(AutopilotState(mission_count=6, mission_reached=5)) == 100
    assert mission_progress_pct(AutopilotState(mission_count=6, mission_current=50)) == 100


finite = st.floats(-1e7, 1e7)


@given(
    alt=finite,
    vel=finite,
    heading=finite,
    airspeed=finite,
    battery=st.integers(-500, 500),
    volts=finite,
    sats=st.integers(-5, 500),
    mode=st.integers(-5, 5000),
)
def test_vehicle_status_always_validates(
    alt: float,
    vel: float,
    heading: float,
    airspeed: float,
    battery: int,
    volts: float,
    sats: int,
    mode: int,
) -> None:
    state = AutopilotState(
        lat_deg=10.0,
        lon_deg=20.0,
        alt_msl_m=alt,
        alt_rel_m=alt,
        vel_north_m_s=vel,
        heading_deg=heading,
        airspeed_m_s=airspeed,
        battery_pct=battery,
        battery_v=volts,
        gps_sats=sats,
        mode_number=mode,
    )
    status = to_vehicle_status(state, vehicle_id=1, now_unix_s=1.7e9)
    assert status is not None
    validate(status)
