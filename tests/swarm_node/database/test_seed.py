"""The seed data: the paper's Albatross 250 VTOL and its camera, the generic quadcopter,
rover, boat and ground station, several of each; and the cheap seed views for tests."""

from __future__ import annotations

import math
from collections import Counter

from swarm_node.database import (
    ALBATROSS,
    BOAT,
    GCS_NODE_ID,
    GROUND_STATION,
    LATEST_VERSION,
    QUADCOPTER,
    ROVER,
    SEED_MODELS,
    SwarmDatabase,
    seed_fleet,
    seed_payload_classes,
    seed_profiles,
)
from swarm_node.database import seed as seed_module
from swarm_proto import VehicleInfo, VehicleType, validate


def test_the_albatross_has_the_papers_figures() -> None:
    alb = seed_profiles()[ALBATROSS]
    assert alb.vehicle_type is VehicleType.VTOL
    assert (alb.system_type, alb.system_subtype) == ("UAV", "VTOL")
    assert alb.cruise_speed_m_s == 26.0
    assert alb.min_speed_m_s == 15.5  # stall at 12.5 kg
    assert alb.max_altitude_m == 4800.0
    assert alb.wingspan_m == 2.5
    assert alb.max_wind_m_s == 10.8
    assert alb.min_speed_m_s < alb.cruise_speed_m_s < alb.max_speed_m_s
    # turn radius at cruise and 45 deg bank: 69 m, above the 60 m loiter radius
    assert math.isclose(alb.turn_radius_m(), 68.9, abs_tol=0.1)
    assert alb.loiter_radius_m == 60.0


def test_the_albatross_camera_is_a_two_axis_1_5_mpx() -> None:
    alb = seed_profiles()[ALBATROSS]
    cam = alb.camera
    assert cam is not None
    w, h = cam.resolution_px
    assert 1.4e6 <= w * h <= 1.6e6
    assert cam.gimbal_axes == 2
    assert 0 < cam.vfov_deg < cam.hfov_deg < 180
    # a rectilinear 4:3 sensor: tan(v/2) = tan(h/2) * h_px / w_px
    expected_v = 2 * math.degrees(math.atan(math.tan(math.radians(cam.hfov_deg / 2)) * h / w))
    assert math.isclose(cam.vfov_deg, expected_v, abs_tol=1.0)
    assert (alb.payload_type, alb.payload_subtype) == ("optical", "visible camera")
    with SwarmDatabase.memory() as db:
        gimbal = db.get("payload.gimbals", "2-axis roll/tilt")
        assert gimbal["pan_axis"] is None and gimbal["tilt_axis"] and gimbal["roll_axis"]


def test_several_of_each_vehicle_and_a_ground_station() -> None:
    fleet = seed_fleet()
    per_model = Counter(p.model for p in fleet)
    assert per_model[ALBATROSS] == 6  # the paper's simulated experiment
    for model in (QUADCOPTER, ROVER, BOAT):
        assert per_model[model] >= 2
    assert per_model[GROUND_STATION] == 1
    assert set(per_model) == set(SEED_MODELS)
    types = {p.model: p.vehicle_type for p in fleet}
    assert types[QUADCOPTER] is VehicleType.COPTER
    assert types[ROVER] is VehicleType.ROVER
    assert types[BOAT] is VehicleType.BOAT
    assert types[GROUND_STATION] is VehicleType.GCS
    gcs = next(p for p in fleet if p.vehicle_type is VehicleType.GCS)
    assert gcs.vehicle_id == GCS_NODE_ID


def test_every_seed_system_resolves_into_a_valid_message() -> None:
    with SwarmDatabase.memory() as db:
        for p in seed_fleet():
            assert p == db.vehicle_profile(p.vehicle_id)
            info = VehicleInfo(
                vehicle_id=p.vehicle_id,
                vehicle_type=p.vehicle_type,
                model=p.model,
                user_id=p.user_id,
                payload_model=p.payload_model,
                payload_subtype=p.payload_subtype,
                payload_type=p.payload_type,
                cruise_speed_m_s=p.cruise_speed_m_s,
            )
            validate(info)  # names fit, ids fit
            if p.vehicle_type is not VehicleType.GCS:
                sysid = int(db.system_params(p.vehicle_id)["mav_sysid"])
                assert 1 <= sysid <= 255
            assert p.battery_critical_pct < p.battery_low_pct


def test_hover_capable_vehicles_turn_on_the_spot() -> None:
    profiles = seed_profiles()
    for model in (QUADCOPTER, ROVER, BOAT):
        assert profiles[model].turn_radius_m() == 0.0
        assert profiles[model].min_speed_m_s == 0.0


def test_seed_views_are_built_once() -> None:
    assert seed_profiles() == seed_profiles()
    assert seed_profiles()[ALBATROSS] is seed_profiles()[ALBATROSS]
    classes = seed_payload_classes()
    assert classes["SDR receiver"].type == "radio frequency"
    assert {c.type for c in classes.values()} == {"optical", "radio frequency", "sound"}


def test_seed_document_is_current_and_idempotent() -> None:
    doc = seed_module.document()
    assert doc["schema_version"] == LATEST_VERSION
    with SwarmDatabase.memory() as db:
        before = db.export()
        db.import_document(doc)  # every record exists: replaced by itself
        assert db.export() == before
