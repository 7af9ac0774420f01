"""StateTracker: the source lock, validation (ranges, NaN), link-loss deadlines, events,
GPS time and reboots, with injected time."""

from __future__ import annotations

import math
from typing import Any

import pytest
from hypothesis import given
from hypothesis import strategies as st
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from swarm_node.core.autopilot.events import (
    ArmedChanged,
    AutopilotFound,
    AutopilotRebooted,
    LinkLost,
    LinkRestored,
    ModeChanged,
    StatusText,
)
from swarm_node.core.autopilot.framing import BadFrame, MavEncoder, MavFramer
from swarm_node.core.autopilot.status import to_vehicle_status
from swarm_node.core.autopilot.tracker import HANDLED, IGNORED, PROTOCOL, StateTracker, Verdict
from swarm_proto import VehicleType, validate

T0 = 1000.0


def wire(msg: Any, sysid: int = 1, compid: int = 1) -> Any:
    """Encode with pymavlink and decode again: what the link really receives."""
    data = MavEncoder(sysid, compid).encode(msg)
    (decoded,) = MavFramer().feed(data)
    return decoded


def hb(mode: int = 0, armed: bool = False, mav_type: int = 2, autopilot: int = 3) -> Any:
    return mavlink.MAVLink_heartbeat_message(
        mav_type, autopilot, 1 | (128 if armed else 0), mode, 3, 3
    )


def gpi(
    lat: float = 37.4112, lon: float = -5.9889, rel: float = 30.0, boot_ms: int = 10_000
) -> Any:
    return mavlink.MAVLink_global_position_int_message(
        boot_ms,
        round(lat * 1e7),
        round(lon * 1e7),
        round((rel + 10) * 1000),
        round(rel * 1000),
        100,
        -50,
        20,
        27000,
    )


def gps(fix: int = 3) -> Any:
    return mavlink.MAVLink_gps_raw_int_message(0, fix, 0, 0, 0, 65535, 65535, 0, 0, 0)


def tracker(fixed: bool = True, **kw: Any) -> StateTracker:
    t = StateTracker(**kw)
    v, _ = t.handle(wire(hb()), T0)
    assert v is Verdict.ACCEPTED
    if fixed:  # a GPS fix: positions count from now on
        t.handle(wire(gps()), T0)
    return t


def test_a_position_near_zero_before_the_fix_is_no_position() -> None:
    """Real ArduPilot (the QuadPlane sortie) sends positions drifting
    near (0, 0) before its fix (0.0003, 0.00002, fix NO_GPS): not a position until a 2-D
    fix or an EKF absolute position is seen; a reboot forgets it."""
    t = tracker(fixed=False)
    t.handle(wire(gps(fix=0)), T0)
    t.handle(wire(gpi(lat=-0.0000153, lon=0.0003226, rel=-0.2)), T0 + 0.1)
    assert t.state.lat_deg is None and not t.state.has_position
    t.handle(wire(gps(fix=1)), T0 + 0.2)
    t.handle(wire(gpi(lat=0.0003, lon=0.00002)), T0 + 0.3)
    assert not t.state.has_position
    t.handle(wire(gps(fix=3)), T0 + 0.4)
    t.handle(wire(gpi()), T0 + 0.5)
    assert (t.state.lat_deg, t.state.lon_deg) == (37.4112, -5.9889)
    t.handle(wire(gps(fix=0)), T0 + 0.6)  # a later loss keeps the EKF's estimate
    t.handle(wire(gpi(lat=37.4113)), T0 + 0.7)
    assert t.state.lat_deg == 37.4113
    t.handle(wire(gpi(lat=0.0003, lon=0.00002, boot_ms=1)), T0 + 0.8)  # rebooted
    assert not t.state.has_position and not t.state.position_trusted
    ekf_abs = 0x33F  # EKF using GPS: attitude, velocities, absolute position
    t.handle(wire(mavlink.MAVLink_ekf_status_report_message(ekf_abs, 0, 0, 0, 0, 0)), T0 + 1)
    t.handle(wire(gpi(boot_ms=2)), T0 + 1.1)
    assert t.state.lat_deg == 37.4112


def test_the_handler_table_covers_what_the_issue_lists() -> None:
    t = StateTracker()
    wanted = {
        "HEARTBEAT",
        "GLOBAL_POSITION_INT",
        "SYS_STATUS",
        "BATTERY_STATUS",
        "GPS_RAW_INT",
        "ATTITUDE",
        "VFR_HUD",
        "HOME_POSITION",
        "SYSTEM_TIME",
        "MISSION_CURRENT",
        "MISSION_ITEM_REACHED",
        "STATUSTEXT",
        "EKF_STATUS_REPORT",
        "EXTENDED_SYS_STATE",
        "ADSB_VEHICLE",
    }
    assert set(t.handlers) == wanted == set(HANDLED)
    assert not (wanted & IGNORED) and not (wanted & PROTOCOL) and not (IGNORED & PROTOCOL)


def test_locks_onto_the_first_autopilot_and_counts_the_rest() -> None:
    t = StateTracker()
    # a GCS heartbeat and telemetry before any autopilot: ignored, not locked
    assert t.handle(wire(hb(autopilot=8, mav_type=6), sysid=255), T0)[0] is Verdict.WAITING
    assert t.handle(wire(gpi(), sysid=1), T0)[0] is Verdict.WAITING
    verdict, events = t.handle(wire(hb(mode=4), sysid=3, compid=1), T0)
    assert verdict is Verdict.ACCEPTED
    assert isinstance(events[0], AutopilotFound) and events[0].sysid == 3
    assert t.state.sysid == 3 and t.state.link_ok and t.state.mode_name == "GUIDED"
    before = t.state
    for sysid, compid in ((1, 1), (3, 154), (255, 190)):
        assert t.handle(wire(gpi(lat=10.0), sysid, compid), T0)[0] is Verdict.FOREIGN
    assert t.state.foreign_packets == 3
    assert t.state.lat_deg == before.lat_deg  # nothing from them was applied


def test_target_sysid_is_respected() -> None:
    t = StateTracker(target_sysid=7)
    assert t.handle(wire(hb(), sysid=1), T0)[0] is Verdict.FOREIGN
    assert t.handle(wire(hb(), sysid=7), T0)[0] is Verdict.ACCEPTED
    assert t.state.sysid == 7


def test_configured_vehicle_type_wins_for_a_quadplane() -> None:
    t = StateTracker(vehicle_type=VehicleType.VTOL)
    _, events = t.handle(wire(hb(mode=20, mav_type=1)), T0)
    assert t.state.vehicle_type == VehicleType.VTOL and t.state.mode_name == "QLAND"
    found = events[0]
    assert isinstance(found, AutopilotFound) and found.mav_type == 1
    assert StateTracker().handle(wire(hb(mav_type=1)), T0)[1][0].vehicle_type == VehicleType.PLANE  # type: ignore[union-attr]


def test_mode_and_armed_changes_are_events() -> None:
    t = tracker()
    _, events = t.handle(wire(hb(mode=4, armed=True)), T0 + 1)
    kinds = {type(e) for e in events}
    assert kinds == {ModeChanged, ArmedChanged}
    mode = next(e for e in events if isinstance(e, ModeChanged))
    assert (mode.old_mode, mode.mode, mode.mode_number) == ("STABILIZE", "GUIDED", 4)
    assert t.handle(wire(hb(mode=4, armed=True)), T0 + 2)[1] == []


@pytest.mark.parametrize(
    "msg",
    [
        gpi(lat=91.0),
        gpi(rel=60_000.0),
        mavlink.MAVLink_attitude_message(1, math.nan, 0, 0, 0, 0, 0),
        mavlink.MAVLink_attitude_message(1, 0, math.inf, 0, 0, 0, 0),
        mavlink.MAVLink_vfr_hud_message(math.nan, 0, 0, 0, 0, 0),
        mavlink.MAVLink_vfr_hud_message(5000.0, 0, 0, 0, 0, 0),
        mavlink.MAVLink_sys_status_message(0, 0, 0, 0, 12000, 0, 120, 0, 0, 0, 0, 0, 0),
        mavlink.MAVLink_gps_raw_int_message(0, 12, 0, 0, 0, 0, 0, 0, 0, 10),
        mavlink.MAVLink_heartbeat_message(2, 3, 1, 300, 3, 3),
        mavlink.MAVLink_system_time_message(5 * 10**6, 1000),  # 1970: not GPS time
        mavlink.MAVLink_statustext_message(9, b"bad severity"),
        mavlink.MAVLink_ekf_status_report_message(831, math.nan, 0, 0, 0, 0),
        mavlink.MAVLink_home_position_message(950_000_000, 0, 0, 0, 0, 0, [1, 0, 0, 0], 0, 0, 0),
        mavlink.MAVLink_extended_sys_state_message(0, 9),
        # (seq beyond total is real: a mission uploaded in AUTO keeps its old item)
        mavlink.MAVLink_mission_current_message(2, 5, 9, 0),  # no MISSION_STATE 9
    ],
    ids=lambda m: m.get_type(),
)
def test_invalid_values_are_dropped_whole_and_counted(msg: Any) -> None:
    t = tracker()
    t.handle(wire(gpi()), T0)
    before = t.state
    verdict, events = t.handle(wire(msg), T0 + 0.5)
    assert verdict is Verdict.INVALID and events == []
    after = t.state
    assert after.bad_packets == before.bad_packets + 1
    assert msgspec_equal_except(before, after, {"bad_packets"})
    assert t.last_bad_reason


def msgspec_equal_except(a: Any, b: Any, fields: set[str]) -> bool:
    import msgspec

    da, db = msgspec.structs.asdict(a), msgspec.structs.asdict(b)
    return all(da[k] == db[k] for k in da if k not in fields)


def test_bad_frames_are_counted() -> None:
    t = tracker()
    assert t.handle(BadFrame(17, "CRC"), T0)[0] is Verdict.INVALID
    assert t.state.bad_packets == 1


def test_position_zeros_mean_no_position_yet() -> None:
    t = tracker()
    t.handle(wire(gpi(lat=0.0, lon=0.0, rel=0.0)), T0)
    assert t.state.lat_deg is None and not t.state.has_position
    t.handle(wire(gpi()), T0 + 0.1)
    s = t.state
    assert (s.lat_deg, s.lon_deg, s.alt_rel_m, s.alt_msl_m) == (37.4112, -5.9889, 30.0, 40.0)
    assert (s.vel_north_m_s, s.vel_east_m_s, s.vel_down_m_s, s.heading_deg) == (
        1.0,
        -0.5,
        0.2,
        270.0,
    )


def test_link_lost_at_the_deadline_and_restored_by_the_next_message() -> None:
    t = tracker(link_timeout_s=0.9)
    t.handle(wire(gpi()), T0 + 0.3)
    assert t.next_deadline() == pytest.approx(T0 + 1.2)
    assert t.on_timer(T0 + 1.19) == []
    (lost,) = t.on_timer(T0 + 1.2)
    assert (
        isinstance(lost, LinkLost) and lost.silent_s == pytest.approx(0.9) and lost.silent_s <= 1.0
    )
    assert not t.state.link_ok and t.state.link_losses == 1 and t.next_deadline() is None
    assert t.on_timer(T0 + 5) == []  # reported once
    _, events = t.handle(wire(gpi()), T0 + 7.0)
    assert isinstance(events[0], LinkRestored) and events[0].down_s == pytest.approx(6.7)
    assert t.state.link_ok


def test_gps_time_of_the_position_sample() -> None:
    t = tracker()
    t.handle(wire(mavlink.MAVLink_system_time_message(1_795_315_038_996_864, 252_159)), T0)
    t.handle(wire(gpi(boot_ms=252_359)), T0)
    assert t.state.gps_time_unix_s == pytest.approx(1_795_315_038.996864)
    assert t.state.position_time_unix_s == pytest.approx(1_795_315_039.196864)
    # an autopilot reboot: time since boot goes back; GPS time is forgotten
    _, events = t.handle(wire(gpi(boot_ms=1_000)), T0 + 1)
    assert any(isinstance(e, AutopilotRebooted) for e in events)
    assert t.state.position_time_unix_s is None


def test_statustext_chunks_are_joined() -> None:
    t = tracker()
    first = "x" * 50
    assert t.handle(wire(mavlink.MAVLink_statustext_message(4, first.encode(), 7, 0)), T0)[1] == []
    _, events = t.handle(wire(mavlink.MAVLink_statustext_message(4, b"end", 7, 1)), T0)
    assert events == [StatusText(time_s=T0, severity=4, text=first + "end")]


def test_battery_status_sums_cells_and_mission_current_counts_items() -> None:
    t = tracker()
    cells = [4100, 4100, 4100] + [65535] * 7
    t.handle(
        wire(mavlink.MAVLink_battery_status_message(0, 0, 0, 32767, cells, -1, -1, -1, 55)), T0
    )
    assert (t.state.battery_pct, t.state.battery_v) == (55, pytest.approx(12.3))
    t.handle(wire(mavlink.MAVLink_battery_status_message(1, 0, 0, 32767, cells, -1, -1, -1, 5)), T0)
    assert t.state.battery_pct == 55  # only the primary battery
    t.handle(wire(mavlink.MAVLink_mission_current_message(2, 5, 3, 0)), T0)
    assert (t.state.mission_current, t.state.mission_count, t.state.mission_state) == (2, 6, 3)


# ---------------------------------------------------------------- properties

i32 = st.integers(-(2**31), 2**31 - 1)
u16 = st.integers(0, 65535)
f32 = st.floats(width=32, allow_nan=True, allow_infinity=True)


@st.composite
def any_message(draw: st.DrawFn) -> Any:
    kind = draw(
        st.sampled_from(
            ["gpi", "att", "vfr", "sys", "gps", "time", "home", "hb", "ekf", "cur", "adsb"]
        )
    )
    if kind == "adsb":
        return mavlink.MAVLink_adsb_vehicle_message(
            draw(st.integers(0, 2**32 - 1)),
            draw(i32),
            draw(i32),
            0,
            draw(i32),
            draw(u16),
            draw(u16),
            draw(st.integers(-32768, 32767)),
            b"X",
            0,
            draw(st.integers(0, 255)),
            draw(u16),
            0,
        )
    if kind == "gpi":
        return mavlink.MAVLink_global_position_int_message(
            draw(st.integers(0, 2**32 - 1)),
            draw(i32),
            draw(i32),
            draw(i32),
            draw(i32),
            draw(st.integers(-32768, 32767)),
            draw(st.integers(-32768, 32767)),
            draw(st.integers(-32768, 32767)),
            draw(u16),
        )
    if kind == "att":
        return mavlink.MAVLink_attitude_message(
            draw(st.integers(0, 2**32 - 1)), *[draw(f32) for _ in range(6)]
        )
    if kind == "vfr":
        return mavlink.MAVLink_vfr_hud_message(
            draw(f32), draw(f32), draw(st.integers(-32768, 32767)), draw(u16), draw(f32), draw(f32)
        )
    if kind == "sys":
        return mavlink.MAVLink_sys_status_message(
            0, 0, 0, 0, draw(u16), 0, draw(st.integers(-128, 127)), 0, 0, 0, 0, 0, 0
        )
    if kind == "gps":
        return mavlink.MAVLink_gps_raw_int_message(
            0,
            draw(st.integers(0, 255)),
            draw(i32),
            draw(i32),
            0,
            0,
            0,
            0,
            0,
            draw(st.integers(0, 255)),
        )
    if kind == "time":
        return mavlink.MAVLink_system_time_message(
            draw(st.integers(0, 2**64 - 1)), draw(st.integers(0, 2**32 - 1))
        )
    if kind == "home":
        return mavlink.MAVLink_home_position_message(
            draw(i32), draw(i32), draw(i32), 0, 0, 0, [1, 0, 0, 0], 0, 0, 0
        )
    if kind == "hb":
        return mavlink.MAVLink_heartbeat_message(
            draw(st.integers(0, 255)),
            3,
            draw(st.integers(0, 255)),
            draw(st.integers(0, 2**32 - 1)),
            draw(st.integers(0, 255)),
            3,
        )
    if kind == "ekf":
        return mavlink.MAVLink_ekf_status_report_message(
            draw(u16), draw(f32), draw(f32), draw(f32), draw(f32), draw(f32)
        )
    return mavlink.MAVLink_mission_current_message(
        draw(u16), draw(u16), draw(st.integers(0, 255)), 0
    )


@given(st.lists(any_message(), max_size=30))
def test_any_field_values_never_raise_and_the_status_always_validates(msgs: list[Any]) -> None:
    t = tracker(vehicle_type=VehicleType.COPTER)
    now = T0
    for m in msgs:
        now += 0.05
        t.handle(wire(m), now)
        status = to_vehicle_status(t.state, vehicle_id=1, now_unix_s=now)
        if status is not None:
            validate(status)
    s = t.state
    for v in (s.heading_deg, s.roll_deg, s.pitch_deg, s.airspeed_m_s, s.battery_v):
        assert math.isfinite(v)


def test_heartbeats_alone_do_not_flap_the_link_but_telemetry_makes_it_quick() -> None:
    t = StateTracker(link_timeout_s=0.9, heartbeat_timeout_s=2.5)
    events = []
    for i in range(10):  # an autopilot that sends only 1 Hz HEARTBEATs (no streams yet)
        now = T0 + i
        events += t.on_timer(now) + t.handle(wire(hb()), now)[1]
    assert not any(isinstance(e, LinkLost) for e in events) and t.state.link_ok
    assert t.next_deadline() == pytest.approx(T0 + 9 + 2.5)
    for i in range(10):  # streams start: 10 Hz
        t.handle(wire(gpi()), T0 + 9.1 + i / 10)
    last = T0 + 9.1 + 0.9
    assert t.next_deadline() == pytest.approx(last + 0.9)
    (lost,) = t.on_timer(last + 0.9)
    assert isinstance(lost, LinkLost) and lost.silent_s <= 1.0


def adsb(
    icao: int = 0xABCDEF,
    lat: float = 37.42,
    lon: float = -5.99,
    alt_m: float = 150.0,
    heading_cdeg: int = 9000,
    speed_cm_s: int = 3000,
    climb_cm_s: int = -100,
    flags: int = 1 | 2 | 4 | 8,
    tslc: int = 1,
    callsign: bytes = b"EC123",
) -> Any:
    return mavlink.MAVLink_adsb_vehicle_message(
        icao,
        round(lat * 1e7),
        round(lon * 1e7),
        0,
        round(alt_m * 1000),
        heading_cdeg,
        speed_cm_s,
        climb_cm_s,
        callsign,
        1,
        tslc,
        flags,
        0,
    )


def test_adsb_traffic_is_kept_per_aircraft_and_dropped_when_silent() -> None:
    """ADSB_VEHICLE from the autopilot (or its ADS-B receiver, same system)
    becomes `traffic` for collision avoidance, the latest report per ICAO address."""
    t = tracker()
    v, _ = t.handle(wire(adsb()), T0 + 1)
    assert v is Verdict.ACCEPTED
    (r,) = t.state.traffic
    assert (r.icao_address, r.lat_deg, r.lon_deg, r.alt_msl_m) == (0xABCDEF, 37.42, -5.99, 150.0)
    assert r.vel_east_m_s == pytest.approx(30.0) and abs(r.vel_north_m_s) < 1e-9
    assert r.vel_down_m_s == pytest.approx(1.0) and r.time_s == T0 and r.callsign == "EC123"
    t.handle(wire(adsb(icao=7, flags=1 | 2), sysid=1, compid=156), T0 + 2)  # the receiver
    assert [x.icao_address for x in t.state.traffic] == [7, 0xABCDEF]
    assert t.state.traffic[0].vel_east_m_s == 0.0  # velocity not flagged valid: none
    t.handle(wire(adsb(icao=7, lat=37.43)), T0 + 30)  # the other silent for 29 s: dropped
    assert [(x.icao_address, x.lat_deg) for x in t.state.traffic] == [(7, 37.43)]
    v, _ = t.handle(wire(adsb(icao=9), sysid=2), T0 + 31)  # another system: foreign
    assert v is Verdict.FOREIGN and len(t.state.traffic) == 1


@pytest.mark.parametrize(
    "msg", [adsb(flags=1), adsb(lat=95.0), adsb(tslc=0, flags=0)], ids=["no-alt", "lat", "flags"]
)
def test_adsb_without_a_valid_position_is_invalid_input(msg: Any) -> None:
    t = tracker()
    v, _ = t.handle(wire(msg), T0 + 1)
    assert v is Verdict.INVALID and t.state.traffic == () and t.state.bad_packets == 1
