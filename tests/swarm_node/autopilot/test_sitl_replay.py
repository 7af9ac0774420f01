"""Real ArduPilot data: the SITL sorties in ../shared/data/ardupilot-sitl, replayed as
bytes into the link core, must give the right VehicleStatus at every position sample
(checked against values decoded independently with pymavlink's own mavutil and mode
tables) and the right events at the right times (checked against the events.json
timeline the recording script wrote)."""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pytest
from pymavlink import mavutil

from swarm_node.core.autopilot.events import (
    ApEvent,
    ArmedChanged,
    MissionItemReached,
    ModeChanged,
    StatusText,
)
from swarm_node.core.autopilot.link import Emit, LinkCore, LinkSettings
from swarm_node.core.autopilot.status import to_vehicle_status
from swarm_proto import VehicleType, validate

SORTIES = {
    "copter": ("arducopter-sortie", VehicleType.COPTER),
    "quadplane": ("arduplane-quadplane-sortie", VehicleType.VTOL),
}
# each sortie is replayed once per process (a module fixture): on one worker, once
pytestmark = pytest.mark.xdist_group("sitl-replay")


@dataclass
class Expected:
    """What an independent reader of the tlog says, message by message."""

    mode: str = ""
    armed: bool = False
    lat: float | None = None
    lon: float | None = None
    alt_msl: float | None = None
    alt_rel: float | None = None
    battery: int = -1
    unix_at_boot: float | None = None
    gps_time: float | None = None
    total: int = 0
    current: int = 0
    reached: int = -1
    reached_all: list[int] = field(default_factory=list)
    first_heartbeat_t: float | None = None
    samples: int = 0
    trusted: bool = False  # a 2-D fix or an EKF absolute position seen
    untrusted_nonzero: int = 0  # non-zero positions before that (drift near 0, 0)

    def update(self, msg: Any) -> None:
        t = msg.get_type()
        if t == "HEARTBEAT":
            self.mode = mavutil.mode_string_v10(msg)  # pymavlink's tables, not ours
            self.armed = bool(msg.base_mode & mavutil.mavlink.MAV_MODE_FLAG_SAFETY_ARMED)
            if self.first_heartbeat_t is None:
                self.first_heartbeat_t = msg._timestamp
        elif (t == "GPS_RAW_INT" and msg.fix_type >= 2) or (
            t == "EKF_STATUS_REPORT" and msg.flags & 16 and not msg.flags & (128 | 1024)
        ):
            self.trusted = True
        elif t == "GLOBAL_POSITION_INT":
            if (msg.lat or msg.lon) and not self.trusted:
                self.untrusted_nonzero += 1
            if (msg.lat == 0 and msg.lon == 0) or not self.trusted:
                self.lat = self.lon = self.alt_msl = self.alt_rel = None
            else:
                self.lat, self.lon = msg.lat * 1e-7, msg.lon * 1e-7
                self.alt_msl, self.alt_rel = msg.alt * 1e-3, msg.relative_alt * 1e-3
            self.gps_time = (
                None if self.unix_at_boot is None else self.unix_at_boot + msg.time_boot_ms * 1e-3
            )
        elif t == "SYSTEM_TIME" and msg.time_unix_usec:
            self.unix_at_boot = msg.time_unix_usec * 1e-6 - msg.time_boot_ms * 1e-3
        elif t == "SYS_STATUS" or (t == "BATTERY_STATUS" and msg.id == 0):
            self.battery = msg.battery_remaining
        elif t == "MISSION_CURRENT":
            self.current, self.total = msg.seq, msg.total
        elif t == "MISSION_ITEM_REACHED":
            self.reached = msg.seq
            self.reached_all.append(msg.seq)

    def progress(self) -> int:
        if self.total < 1:
            return 0
        done = max(self.current - 1, self.reached, 0)
        return min(100, round(100 * done / self.total))


@dataclass
class Replay:
    events: list[ApEvent]
    expected: Expected
    offset_s: float  # tlog time - events.json time
    timeline: list[tuple[float, str]]


def replay(shared_dir: Path, sortie: str) -> Replay:
    name, vtype = SORTIES[sortie]
    base = shared_dir / "data" / "ardupilot-sitl"
    conn = mavutil.mavlink_connection(str(base / f"{name}.tlog"))
    core = LinkCore(LinkSettings(vehicle_type=vtype), 0.0)
    exp = Expected()
    events: list[ApEvent] = []
    try:
        while True:
            msg = conn.recv_match()
            if msg is None:
                break
            now = msg._timestamp
            out = core.receive(bytes(msg.get_msgbuf()), now)
            events += [o.event for o in out if isinstance(o, Emit)]
            exp.update(msg)
            if msg.get_type() == "GLOBAL_POSITION_INT" and exp.first_heartbeat_t is not None:
                check_sample(core, exp, now, msg)
    finally:
        conn.close()
    assert core.state.bad_packets == 0 and core.state.foreign_packets == 0
    timeline = [
        (float(t), str(what))
        for t, what in json.loads((base / f"{name}.events.json").read_text())["events"]
    ]
    assert exp.first_heartbeat_t is not None
    offset = exp.first_heartbeat_t - next(t for t, w in timeline if w.startswith("heartbeat"))
    return Replay(events, exp, offset, timeline)


def check_sample(core: LinkCore, exp: Expected, now: float, msg: Any) -> None:
    s = core.state
    status = to_vehicle_status(s, vehicle_id=1, now_unix_s=now)
    assert s.mode_name == exp.mode, msg
    assert s.armed == exp.armed
    if exp.lat is None:
        assert status is None
        return
    assert status is not None
    validate(status)
    exp.samples += 1
    assert status.lat_deg == pytest.approx(exp.lat, abs=1e-9)
    assert status.lon_deg == pytest.approx(exp.lon, abs=1e-9)
    assert status.alt_msl_m == pytest.approx(exp.alt_msl, abs=1e-6)
    assert status.alt_rel_m == pytest.approx(exp.alt_rel, abs=1e-6)
    assert status.armed == exp.armed
    assert status.battery_pct == exp.battery
    assert status.mission_progress_pct == exp.progress()
    assert status.vel_north_m_s == pytest.approx(msg.vx / 100)
    if exp.gps_time is None:
        assert s.position_time_unix_s is None and status.time_unix_s == now
    else:
        assert status.time_unix_s == pytest.approx(exp.gps_time, abs=1e-6)


@pytest.fixture(scope="module", params=sorted(SORTIES))
def sortie(request: pytest.FixtureRequest, shared_dir_module: Path) -> tuple[str, Replay]:
    return request.param, replay(shared_dir_module, request.param)


@pytest.fixture(scope="module")
def shared_dir_module() -> Path:
    from tests.conftest import SHARED

    if not SHARED.is_dir():
        pytest.skip(f"../shared not found at {SHARED}")
    return SHARED


def at(r: Replay, kind: type, pred: Any = lambda e: True) -> list[float]:
    """events.json times of our events of `kind`."""
    return [e.time_s - r.offset_s for e in r.events if isinstance(e, kind) and pred(e)]


def test_every_position_sample_matches_the_independent_reading(sortie: tuple[str, Replay]) -> None:
    _, r = sortie
    assert r.expected.samples > 1000


def test_no_position_before_the_fix(sortie: tuple[str, Replay]) -> None:
    """Before its GPS fix the QuadPlane sent positions drifting near
    (0, 0) (-0.0000153, 0.0003226 with fix NO_GPS, EKF uninitialised); none of them is a
    position (check_sample asserts no status for each), not only exact zeros."""
    name, r = sortie
    if name == "quadplane":
        assert r.expected.untrusted_nonzero > 20


def test_commanded_modes_appear_when_acknowledged(sortie: tuple[str, Replay]) -> None:
    _, r = sortie
    commanded = [
        (t, w.split()[2]) for t, w in r.timeline if w.startswith("set mode") and w.endswith("ack 0")
    ]
    assert commanded
    for t, mode in commanded:
        times = at(r, ModeChanged, lambda e, m=mode: e.mode == m)
        assert any(abs(x - t) < 0.5 for x in times), (mode, t, times)


def test_armed_exactly_between_arm_and_disarm(sortie: tuple[str, Replay]) -> None:
    name, r = sortie
    t_arm = next(t for t, w in r.timeline if w == "armed=True")
    disarm_text = {
        "copter": "STATUSTEXT Disarming motors",
        "quadplane": "STATUSTEXT Throttle disarmed",
    }[name]
    t_disarm = next(t for t, w in r.timeline if w == disarm_text)
    arms = [(e.time_s - r.offset_s, e.armed) for e in r.events if isinstance(e, ArmedChanged)]
    assert [a for _, a in arms] == [True, False]
    assert abs(arms[0][0] - t_arm) < 0.5
    assert abs(arms[1][0] - t_disarm) < 1.0


def test_mission_items_reached_in_order_on_time(sortie: tuple[str, Replay]) -> None:
    _, r = sortie
    wanted = [(t, int(w.split()[1])) for t, w in r.timeline if w.startswith("reached ")]
    ours = [(e.time_s - r.offset_s, e.seq) for e in r.events if isinstance(e, MissionItemReached)]
    # the script missed one while it waited for an ACK: its list is a subsequence of ours
    assert wanted and len(ours) >= len(wanted)
    rest = iter(ours)
    for t, seq in wanted:
        assert any(s == seq and abs(x - t) < 0.5 for x, s in rest), (t, seq, ours)
    assert [s for _, s in ours] == r.expected.reached_all


def test_statustexts_are_reported(sortie: tuple[str, Replay]) -> None:
    _, r = sortie
    ours = [e.text for e in r.events if isinstance(e, StatusText)]
    theirs = [w[len("STATUSTEXT ") :] for _, w in r.timeline if w.startswith("STATUSTEXT ")]
    it = iter(ours)
    assert all(text in it for text in theirs)  # theirs is a subsequence of ours


def test_sortie_ends_where_it_should(sortie: tuple[str, Replay]) -> None:
    name, r = sortie
    e = r.expected
    assert not e.armed
    assert e.gps_time is not None and e.gps_time > 1.7e9
    if name == "copter":
        assert e.mode == "LAND" and e.reached == 5 and e.progress() == 100
        assert 0 <= e.battery < 100
    else:
        assert e.mode == "QLAND" and e.battery == -1
