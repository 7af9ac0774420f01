"""Vehicle monitoring: thresholds, hysteresis, severities, readiness, geofence."""

from __future__ import annotations

import dataclasses

import pytest

from swarm_node.core.autopilot.state import AutopilotState
from swarm_node.core.monitoring import Thresholds, VehicleMonitor, inside
from swarm_node.core.node import NodeCore
from swarm_node.core.profile import VehicleProfile
from swarm_node.database import SwarmDatabase
from swarm_node.database.seed import GROUND_STATION, SEED_MODELS
from swarm_proto import (
    AlertCode,
    AlertFlag,
    Geometry,
    GeoPoint,
    GpsFix,
    NoFlyZone,
    Severity,
    VehicleType,
)

HOME = GeoPoint(37.4112, -5.9889, 10.0)


def healthy(**kw: object) -> AutopilotState:
    base: dict[str, object] = dict(
        link_ok=True,
        lat_deg=37.4112,
        lon_deg=-5.9889,
        alt_msl_m=110.0,
        alt_rel_m=100.0,
        battery_pct=90,
        battery_v=25.0,
        gps_fix=GpsFix.FIX_3D,
        gps_sats=14,
        ekf_ok=True,
        home=HOME,
        armed=True,
    )
    base.update(kw)
    return AutopilotState(**base)  # type: ignore[arg-type]


def run(
    mon: VehicleMonitor, states: list[tuple[float, AutopilotState]]
) -> list[tuple[float, AlertCode, Severity]]:
    out = []
    for t, s in states:
        out += [(t, a.code, a.severity) for a in mon.update(s, t)]
    return out


def test_ready_needs_link_gps_ekf_and_home() -> None:
    mon = VehicleMonitor(3)
    mon.update(healthy(), 0.0)
    assert mon.ready
    for bad in (
        dict(home=None),
        dict(ekf_ok=False),
        dict(gps_fix=GpsFix.FIX_2D),
        dict(link_ok=False),
    ):
        m = VehicleMonitor(3)
        m.update(healthy(**bad), 0.0)
        assert not m.ready, bad


def test_battery_thresholds_with_hysteresis() -> None:
    mon = VehicleMonitor(
        3,
        Thresholds(
            battery_low_pct=30, battery_critical_pct=15, raise_after_s=1.0, clear_after_s=3.0
        ),
    )
    events = run(
        mon,
        [
            (0.0, healthy(battery_pct=25)),
            (0.5, healthy(battery_pct=25)),  # not yet: needs 1 s
            (1.0, healthy(battery_pct=25)),  # raised
            (1.5, healthy(battery_pct=12)),  # critical starts
            (2.6, healthy(battery_pct=12)),  # critical raised
        ],
    )
    assert events == [
        (1.0, AlertCode.BATTERY_LOW, Severity.WARNING),
        (2.6, AlertCode.BATTERY_CRITICAL, Severity.CRITICAL),
    ]
    assert mon.emergency is not None and mon.emergency.code == AlertCode.BATTERY_CRITICAL
    assert AlertFlag.BATTERY_CRITICAL in mon.flags and not mon.ready


def test_a_short_sag_does_not_raise() -> None:
    mon = VehicleMonitor(3)
    assert (
        run(mon, [(0.0, healthy(battery_pct=10)), (0.5, healthy()), (2.0, healthy(battery_pct=10))])
        == []
    )


def test_link_loss_is_a_warning_at_once_and_an_emergency_when_it_lasts() -> None:
    mon = VehicleMonitor(3)
    mon.update(healthy(), 0.0)
    lost = healthy(link_ok=False)
    events = run(mon, [(0.2, lost), (1.2, lost), (2.1, lost), (5.1, lost)])
    assert events == [(0.2, AlertCode.AUTOPILOT_LINK_LOSS, Severity.WARNING)]
    assert AlertFlag.AUTOPILOT_LINK_LOSS in mon.flags and mon.emergency is None
    # lasted link_emergency_after_s: 5 s, ArduPilot's FS_GCS_TIMEOUT / FS_LONG_TIMEOUT
    events = run(mon, [(5.2, lost)])
    assert events == [(5.2, AlertCode.AUTOPILOT_LINK_LOSS, Severity.EMERGENCY)]
    assert mon.emergency is not None and mon.emergency.severity == Severity.EMERGENCY
    events = run(mon, [(5.4, healthy())])
    assert events == [(5.4, AlertCode.CONDITION_CLEARED, Severity.INFO)]
    assert mon.emergency is None


def test_a_short_link_gap_is_no_emergency() -> None:
    """On a loaded host the link was silent 0.8 s and back 0.4 s
    later; that made an EMERGENCY and ended a mission ArduPilot flew fine."""
    mon = VehicleMonitor(3)
    mon.update(healthy(), 0.0)
    lost = healthy(link_ok=False)
    events = run(mon, [(t, lost) for t in (0.8, 1.0, 1.2)] + [(1.2, healthy())])
    assert [e[2] for e in events] == [Severity.WARNING, Severity.INFO]  # raised, cleared
    assert mon.emergency is None and mon.flags == AlertFlag.NONE


def test_no_link_at_start_is_not_a_loss_until_the_grace_period() -> None:
    """A link that never came up is "no autopilot yet", a WARNING after the
    grace period and never worse (a slow start on a loaded host raised a CRITICAL link
    loss on the ground 91 ms after the link opened); a link lost after it was up is a
    loss, CRITICAL on the ground once it lasts 5 s."""
    mon = VehicleMonitor(3, Thresholds(link_grace_s=10.0))
    down = healthy(link_ok=False, armed=False, last_message_s=None)
    assert run(mon, [(0.0, down), (5.0, down)]) == []
    assert run(mon, [(10.0, down)]) == [(10.0, AlertCode.AUTOPILOT_LINK_LOSS, Severity.WARNING)]
    assert run(mon, [(16.0, down), (60.0, down)]) == []  # never CRITICAL: it never was up
    assert mon.emergency is None
    mon2 = VehicleMonitor(3)
    assert run(mon2, [(0.0, down), (1.0, healthy(armed=False))]) == []
    lost = healthy(link_ok=False, armed=False)
    assert run(mon2, [(2.0, lost)]) == [(2.0, AlertCode.AUTOPILOT_LINK_LOSS, Severity.WARNING)]
    assert run(mon2, [(7.0, lost)]) == [(7.0, AlertCode.AUTOPILOT_LINK_LOSS, Severity.CRITICAL)]


def test_the_nodes_own_stall_does_not_count_toward_a_link_loss() -> None:
    """1 s of real link gap, then the node itself stalls 3 s (its loop not
    served: a loaded host): the loss has lasted 1 s of the link's time, not 4 s."""
    mon = VehicleMonitor(3)
    mon.update(healthy(), 0.0)
    lost = healthy(link_ok=False)
    assert run(mon, [(0.2, lost), (1.2, lost)]) == [
        (0.2, AlertCode.AUTOPILOT_LINK_LOSS, Severity.WARNING)
    ]
    mon.note_stall(3.0)
    assert run(mon, [(4.2, lost), (5.1, lost)]) == []  # 2.0 s and 1.9 s of loss: a WARNING
    assert mon.emergency is None
    assert run(mon, [(8.3, lost)]) == [(8.3, AlertCode.AUTOPILOT_LINK_LOSS, Severity.EMERGENCY)]


def test_gps_loss_only_after_a_fix() -> None:
    mon = VehicleMonitor(3)
    no_fix = healthy(gps_fix=GpsFix.NO_FIX, armed=False)
    assert run(mon, [(0.0, no_fix), (5.0, no_fix)]) == []  # never had a fix: not ready, no alert
    assert not mon.ready
    events = run(
        mon,
        [
            (6.0, healthy()),
            (7.0, healthy(gps_fix=GpsFix.NO_FIX)),
            (8.0, healthy(gps_fix=GpsFix.NO_FIX)),
        ],
    )
    assert events == [(8.0, AlertCode.GPS_LOSS, Severity.CRITICAL)]


def test_attitude_and_severity_on_the_ground() -> None:
    mon = VehicleMonitor(3, Thresholds(max_tilt_deg=45.0))
    events = run(mon, [(0.0, healthy(roll_deg=70.0)), (1.0, healthy(roll_deg=70.0))])
    assert events == [(1.0, AlertCode.ATTITUDE_ABNORMAL, Severity.CRITICAL)]
    mon2 = VehicleMonitor(3)
    assert run(
        mon2,
        [(0.0, healthy(battery_pct=5, armed=False)), (1.0, healthy(battery_pct=5, armed=False))],
    ) == [(1.0, AlertCode.BATTERY_CRITICAL, Severity.WARNING)]
    assert mon2.emergency is None  # critical battery on the ground is not an emergency
    # arming escalates it
    assert run(mon2, [(2.0, healthy(battery_pct=5))]) == [
        (2.0, AlertCode.BATTERY_CRITICAL, Severity.CRITICAL)
    ]


def test_geofence_breach_in_a_zone_between_floor_and_ceiling() -> None:
    zone = NoFlyZone(
        1, Geometry.circle(37.4112, -5.9889, 200.0), floor_alt_msl_m=0.0, ceiling_alt_msl_m=300.0
    )
    mon = VehicleMonitor(3, Thresholds(raise_after_s=0.0), zones={1: zone})
    assert run(mon, [(0.0, healthy(alt_msl_m=500.0))]) == []  # above the ceiling
    assert run(mon, [(1.0, healthy(alt_msl_m=100.0))]) == [
        (1.0, AlertCode.GEOFENCE_BREACH, Severity.CRITICAL)
    ]


def test_leaving_the_operating_area() -> None:
    area = Geometry.polygon([(37.40, -6.00), (37.40, -5.97), (37.42, -5.97), (37.42, -6.00)])
    assert inside(area, 37.41, -5.99) and not inside(area, 37.43, -5.99)
    zone = NoFlyZone(2, area, floor_alt_msl_m=0.0, ceiling_alt_msl_m=1.0, operating_area=True)
    mon = VehicleMonitor(3, Thresholds(raise_after_s=0.0), zones={2: zone})
    assert run(mon, [(0.0, healthy())]) == []  # 2-D: its floor and ceiling do not matter
    assert run(mon, [(1.0, healthy(lat_deg=37.43))]) == [
        (1.0, AlertCode.GEOFENCE_BREACH, Severity.CRITICAL)
    ]
    # with two areas, the vehicle must be inside both (as ArduPilot's inclusion fences)
    west = Geometry.polygon([(37.40, -6.00), (37.40, -5.985), (37.42, -5.985), (37.42, -6.00)])
    mon.zones[5] = NoFlyZone(5, west, operating_area=True)
    assert run(mon, [(2.0, healthy()), (5.5, healthy()), (6.0, healthy(lon_deg=-5.98))]) == [
        (5.5, AlertCode.CONDITION_CLEARED, Severity.INFO),
        (6.0, AlertCode.GEOFENCE_BREACH, Severity.CRITICAL),
    ]
    assert mon._breach_text == "left operating area 5"


# ----------------------------------------------------------------------- per model


def test_thresholds_from_a_profile() -> None:
    p = VehicleProfile(
        1,
        "U1",
        "m",
        VehicleType.ROVER,
        battery_low_pct=25,
        battery_critical_pct=10,
        max_tilt_deg=35.0,
    )
    t = Thresholds.from_profile(p)
    assert (t.battery_low_pct, t.battery_critical_pct, t.max_tilt_deg) == (25, 10, 35.0)
    assert (t.min_sats, t.raise_after_s, t.clear_after_s) == (6, 1.0, 3.0)  # not per model


@pytest.mark.parametrize("model", [m for m in SEED_MODELS if m != GROUND_STATION])
def test_each_seed_models_thresholds_reach_the_monitor(model: str) -> None:
    """The database's model parameters (not the defaults) are what the node's monitor
    uses, and they decide when alerts are raised."""
    with SwarmDatabase.memory() as db:
        row = next(r for r in db.group("systems")["model-params"] if r["model"] == model)
        profile = next(p for p in db.profiles() if p.model == model)
    node = NodeCore(profile)
    t = node.monitor.thresholds
    assert (t.battery_low_pct, t.battery_critical_pct, t.max_tilt_deg) == (
        row["battery_low_pct"],
        row["battery_critical_pct"],
        row["max_tilt_deg"],
    )
    mon = VehicleMonitor(3, dataclasses.replace(t, raise_after_s=0.0))
    low, crit, tilt = t.battery_low_pct, t.battery_critical_pct, t.max_tilt_deg
    assert run(mon, [(0.0, healthy(battery_pct=low + 1, roll_deg=tilt - 1))]) == []
    assert run(mon, [(1.0, healthy(battery_pct=low, roll_deg=tilt + 1))]) == [
        (1.0, AlertCode.BATTERY_LOW, Severity.WARNING),
        (1.0, AlertCode.ATTITUDE_ABNORMAL, Severity.CRITICAL),
    ]
    assert (2.0, AlertCode.BATTERY_CRITICAL, Severity.CRITICAL) in run(
        mon, [(2.0, healthy(battery_pct=crit, roll_deg=tilt + 1))]
    )


def test_a_changed_model_parameter_reaches_the_monitor() -> None:
    with SwarmDatabase.memory() as db:
        row = next(r for r in db.group("systems")["model-params"] if r["model"] == "Generic Rover")
        db.remove("systems.model-params", "Generic Rover")
        db.add("systems.model-params", {**row, "battery_low_pct": 42, "max_tilt_deg": 22.0})
        profile = db.vehicle_profile(vehicle_id=10)  # ROVER-01
    t = NodeCore(profile).monitor.thresholds
    assert (t.battery_low_pct, t.max_tilt_deg) == (42, 22.0)


def test_the_autopilots_attitude_limit_sets_the_alarm() -> None:
    """A QuadPlane banked 61 degrees, within ArduPlane's ROLL_LIMIT_DEG 65, is not
    abnormal whatever the database says (60); past the limit and its margin it is."""
    mon = VehicleMonitor(1, Thresholds(max_tilt_deg=60.0))
    got = run(mon, [(t / 10, healthy(roll_deg=61.0, max_bank_deg=65.0)) for t in range(30)])
    assert AlertCode.ATTITUDE_ABNORMAL not in [c for _, c, _ in got]
    got = run(mon, [(3 + t / 10, healthy(roll_deg=76.0, max_bank_deg=65.0)) for t in range(30)])
    assert (AlertCode.ATTITUDE_ABNORMAL, Severity.CRITICAL) in [(c, s) for _, c, s in got]


def test_the_database_disagreeing_with_the_autopilot_is_a_warning_once() -> None:
    mon = VehicleMonitor(7, Thresholds(max_tilt_deg=60.0, database_capacity_mah=3300.0))
    s = healthy(battery_capacity_mah=20000.0, max_bank_deg=30.0)
    alerts = [a for t in range(20) for a in mon.update(s, t / 10)]
    mismatch = [a for a in alerts if a.code == AlertCode.DATABASE_MISMATCH]
    assert len(mismatch) == 1 and mismatch[0].severity == Severity.WARNING  # 30 within 60
    assert mismatch[0].text == "BATT_CAPACITY 20000 mAh, database 3300 mAh: planned with it"
    agree = VehicleMonitor(7, Thresholds(max_tilt_deg=45.0, database_capacity_mah=20000.0))
    assert not [
        a
        for a in agree.update(healthy(battery_capacity_mah=20500.0, max_bank_deg=30.0), 0.0)
        if a.code == AlertCode.DATABASE_MISMATCH
    ]
    plane = VehicleMonitor(1, Thresholds(max_tilt_deg=60.0, database_capacity_mah=22000.0))
    said = plane.update(healthy(max_bank_deg=65.0), 0.0)  # no battery monitor: no capacity
    assert [a.text for a in said if a.code == AlertCode.DATABASE_MISMATCH] == [
        "attitude limit 65 deg, database alarm 60: alarm at 75"
    ]


def test_a_skewed_autopilot_clock_is_a_warning_not_stale_data() -> None:
    """SITL's GPS time ran about 10 s behind the host's clock: said once."""
    mon = VehicleMonitor(8)
    now = 1.8e9
    alerts = [
        a
        for k in range(30)
        for a in mon.update(
            healthy(position_time_unix_s=now + k / 10 - 9.8, last_message_s=now + k / 10),
            now + k / 10,
        )
    ]
    skew = [a for a in alerts if a.code == AlertCode.CLOCK_SKEW]
    assert len(skew) == 1 and skew[0].severity == Severity.WARNING
    assert skew[0].text == "autopilot GPS time 9.8 s behind this node's clock"
    assert mon.ready and not mon.flags
    fine = VehicleMonitor(8)
    ok = healthy(position_time_unix_s=now - 0.1, last_message_s=now)
    assert not [a for a in fine.update(ok, now) if a.code == AlertCode.CLOCK_SKEW]


# ---------------------------------------------------------------- identity


def test_an_autopilot_of_another_mavlink_system_id_is_a_mismatch_and_not_ready() -> None:
    mon = VehicleMonitor(8, mav_sysid=8)
    alerts = mon.update(healthy(sysid=10), 0.0)
    assert [(a.code, a.severity) for a in alerts] == [
        (AlertCode.AUTOPILOT_MISMATCH, Severity.WARNING)
    ]
    assert "MAVLink system 10" in alerts[0].text and "says 8" in alerts[0].text
    assert not mon.ready and mon.emergency is None
    assert mon.not_ready_text(healthy(sysid=10)).startswith("autopilot is MAVLink system 10")
    assert mon.flags & AlertFlag.AUTOPILOT_MISMATCH
    mon.update(healthy(sysid=8), 1.0)  # the right autopilot: ready
    assert mon.ready
    unchecked = VehicleMonitor(8)  # no sysid in the database: not compared
    unchecked.update(healthy(sysid=10), 0.0)
    assert unchecked.ready


def test_an_identity_conflict_is_critical_not_ready_and_never_an_emergency() -> None:
    mon = VehicleMonitor(7)
    mon.update(healthy(), 0.0)
    assert mon.ready
    raised = mon.on_identity("id 7 also used by session 3f2a9c1d", 1.0)
    assert [(a.code, a.severity, a.text) for a in raised] == [
        (AlertCode.IDENTITY_CONFLICT, Severity.CRITICAL, "id 7 also used by session 3f2a9c1d")
    ]
    assert mon.on_identity("id 7 also used by session 3f2a9c1d", 1.2) == []  # once
    mon.update(healthy(), 2.0)
    assert not mon.ready and mon.emergency is None  # flying vehicles go on
    assert mon.not_ready_text(healthy()) == "identity conflict: id 7 also used by session 3f2a9c1d"
    assert mon.flags & AlertFlag.IDENTITY_CONFLICT
    assert AlertCode.IDENTITY_CONFLICT in mon.active_codes
    cleared = mon.on_identity("", 12.0)
    assert [(a.code, a.text) for a in cleared] == [
        (AlertCode.CONDITION_CLEARED, "IDENTITY_CONFLICT cleared")
    ]
    mon.update(healthy(), 12.2)
    assert mon.ready and not mon.flags & AlertFlag.IDENTITY_CONFLICT


def test_no_autopilot_yet_says_why() -> None:
    mon = VehicleMonitor(7, Thresholds(link_grace_s=10.0))
    why = "tcp:127.0.0.1:5799: Connection refused"
    assert mon.update(AutopilotState(link_problem=why), 0.0) == []
    alerts = mon.update(AutopilotState(link_problem=why), 10.0)
    assert [(a.code, a.severity) for a in alerts] == [
        (AlertCode.AUTOPILOT_LINK_LOSS, Severity.WARNING)
    ]
    assert alerts[0].text.startswith("no autopilot yet: tcp:127.0.0.1:5799")
