"""The behaviour recordings (real ArduPilot SITL, master of 2025-09-16:
`../shared/data/ardupilot-sitl/behaviours.md`) replayed as bytes through the autopilot
link: every message is valid to it, and what it reports matches an independent pymavlink
reading. (The simulator's behaviour is compared with the same recordings in
tests/swarm_sim/test_recorded_behaviours.py.)"""

from __future__ import annotations

import itertools
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pytest
from pymavlink import mavutil

from swarm_node.core.autopilot.events import ApEvent, MissionCurrentChanged, StatusText
from swarm_node.core.autopilot.link import Emit, LinkCore, LinkSettings
from swarm_node.core.autopilot.status import to_vehicle_status
from swarm_proto import VehicleType, validate

SENSOR_GEOFENCE = 1 << 20  # MAV_SYS_STATUS_GEOFENCE
# each recording is replayed once per process (`replay`'s cache): on one worker, once
pytestmark = pytest.mark.xdist_group("behaviour-replay")
RECORDINGS = (
    "fence-enable-after-upload",
    "mission-start-in-auto",
    "mission-start-in-auto-mode-switch",
    "copter-corner-cutting",
    "plane-rtl-rally-alt-zero",
    "plane-rtl-rally-alt-60",
)


@dataclass
class Replayed:
    core: LinkCore
    meta: dict[str, Any]
    events: list[ApEvent] = field(default_factory=list)
    raw: list[Any] = field(default_factory=list)  # (time, pymavlink message) from our autopilot
    ready_seen_at: float | None = None  # our state's autopilot_ready first True
    ready_text_at: float | None = None  # the recorded "ArduPilot Ready"
    statuses: list[tuple[float, Any]] = field(default_factory=list)


@pytest.fixture(scope="module")
def base() -> Path:
    from tests.conftest import SHARED

    path = SHARED / "data/ardupilot-sitl"
    if not (path / "mission-start-in-auto.tlog").is_file():
        pytest.skip(f"behaviour recordings not found under {path}")
    return path


_cache: dict[str, Replayed] = {}


def replay(base: Path, name: str) -> Replayed:
    if name in _cache:
        return _cache[name]
    meta = json.loads((base / f"{name}.events.json").read_text())
    vtype = VehicleType.VTOL if meta["kind"] == "quadplane" else VehicleType.COPTER
    core = LinkCore(LinkSettings(vehicle_type=vtype), 0.0)
    r = Replayed(core, meta)
    conn = mavutil.mavlink_connection(str(base / f"{name}.tlog"))
    try:
        while (msg := conn.recv_match()) is not None:
            now = msg._timestamp
            out = core.receive(bytes(msg.get_msgbuf()), now)
            r.events += [o.event for o in out if isinstance(o, Emit)]
            if msg.get_srcComponent() == 1:
                r.raw.append((now, msg))
            if msg.get_type() == "STATUSTEXT" and msg.text == "ArduPilot Ready":
                r.ready_text_at = r.ready_text_at or now
            if core.state.autopilot_ready and r.ready_seen_at is None:
                r.ready_seen_at = now
            if msg.get_type() == "GLOBAL_POSITION_INT":
                st = to_vehicle_status(core.state, vehicle_id=1, now_unix_s=now)
                if st is not None:
                    validate(st)
                    r.statuses.append((now, st))
    finally:
        conn.close()
    _cache[name] = r
    return r


@pytest.mark.parametrize("name", RECORDINGS)
def test_every_message_is_valid_and_the_autopilot_is_ready_when_it_says(
    base: Path, name: str
) -> None:
    """No message of real ArduPilot is refused (once MISSION_CURRENT with the
    old current item beyond the new mission's total was dropped as invalid), and the link
    counts the autopilot booted exactly when it says "ArduPilot Ready" (or its next
    HEARTBEAT in STANDBY): uploads wait for that."""
    r = replay(base, name)
    s = r.core.state
    assert (s.bad_packets, s.foreign_packets) == (0, 0), r.core.tracker.last_bad_reason
    assert r.ready_text_at is not None and r.ready_seen_at is not None
    # (the QuadPlane's first STANDBY HEARTBEAT comes a fraction of a ms before the text)
    assert -0.05 <= r.ready_seen_at - r.ready_text_at < 0.5
    booting = [m for t, m in r.raw if m.get_type() == "HEARTBEAT" and t < r.ready_seen_at]
    assert booting and all(m.system_status in (1, 2) for m in booting)  # BOOT / CALIBRATING


@pytest.mark.parametrize("name", ["mission-start-in-auto", "mission-start-in-auto-mode-switch"])
def test_mission_current_after_the_upload_in_auto(base: Path, name: str) -> None:
    r = replay(base, name)
    recorded: list[int] = []
    for _, m in r.raw:
        if m.get_type() == "MISSION_CURRENT" and (not recorded or recorded[-1] != m.seq):
            recorded.append(int(m.seq))
    ours = [e.seq for e in r.events if isinstance(e, MissionCurrentChanged)]
    assert ours == recorded[1:]  # every change (the first report is the initial value)
    texts = [e.text for e in r.events if isinstance(e, StatusText)]
    assert "Auto mission changed but failed to restart command" in texts
    i = ours.index(5)  # loitering at the end of mission 1 ...
    assert ours[i : i + 4] == [5, 1, 2, 3]  # ... then mission 2 from item 1
    assert r.core.state.mission_count == 4  # mission 2: home + 3 items


def test_fence_present_and_enabled_as_sys_status_says(base: Path) -> None:
    r = replay(base, "fence-enable-after-upload")
    assert r.core.state.sensors_present & SENSOR_GEOFENCE  # FENCE_TYPE 7: present throughout
    enabled = [
        bool(m.onboard_control_sensors_enabled & SENSOR_GEOFENCE)
        for _, m in r.raw
        if m.get_type() == "SYS_STATUS"
    ]
    flips = [b for a, b in itertools.pairwise(enabled) if a != b]
    assert flips == [True, False] * 3  # three rounds: DO_FENCE_ENABLE 1, then 0
    acks = [m.result for _, m in r.raw if m.get_type() == "COMMAND_ACK" and m.command == 207]
    assert acks == [0] * 6


@pytest.mark.parametrize(
    ("name", "lowest_m"), [("plane-rtl-rally-alt-zero", 0.5), ("plane-rtl-rally-alt-60", 57.0)]
)
def test_the_statuses_show_the_rtl_to_the_rally_altitude(
    base: Path, name: str, lowest_m: float
) -> None:
    """The QuadPlane's RTL to a rally point at 0 m: our statuses go down to the ground
    (recorded minimum 0.03 m above home); at 60 m they stay above 57 m."""
    r = replay(base, name)
    plane_rtl = 11  # ArduPlane's RTL custom_mode (the recordings end in QLAND, landing)
    after = [st.alt_rel_m for _, st in r.statuses if st.ap_mode == plane_rtl]
    recorded_min = r.meta["min_rel_alt_after_rtl_m"]
    assert min(after) == pytest.approx(recorded_min, abs=0.05)
    assert (min(after) < lowest_m) if lowest_m < 1 else (min(after) > lowest_m)
