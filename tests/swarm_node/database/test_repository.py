"""The repository API: records by key (add, get, remove) with clear errors, and what a
node resolves (profiles, payload classes, parameters)."""

from __future__ import annotations

import math
import threading

import pytest

from swarm_node.core.profile import PayloadClass
from swarm_node.database import (
    ALBATROSS,
    QUADCOPTER,
    AmbiguousError,
    ConstraintError,
    DuplicateError,
    InUseError,
    InvalidValueError,
    NotFoundError,
    ProfileError,
    RecordError,
    SwarmDatabase,
    UnknownReferenceError,
    UnknownTableError,
)
from swarm_proto import MissionType, VehicleType

ALB_LAYOUT = "Albatross 250 VTOL + EO 1.5 Mpx"


def test_add_get_remove_a_named_record(seeded: SwarmDatabase) -> None:
    added = seeded.add("payload.types", {"name": "delivery", "description": "drops"})
    assert added == {"name": "delivery", "description": "drops"}
    assert seeded.get("payload.types", "delivery") == added
    assert seeded.remove("payload.types", "delivery") == added
    with pytest.raises(NotFoundError, match="no record with name='delivery'"):
        seeded.get("payload.types", "delivery")


def test_a_new_system_gets_the_lowest_free_node_id(seeded: SwarmDatabase) -> None:
    rec = seeded.add("systems.systems", {"user_id": "ALB-07", "layout": ALB_LAYOUT})
    assert rec["id"] == 14  # vehicles are 1..13, the ground station 900
    seeded.remove("systems.systems", 3)
    assert seeded.add("systems.systems", {"user_id": "ALB-08", "layout": ALB_LAYOUT})["id"] == 3
    assert (
        seeded.add("systems.systems", {"id": 500, "user_id": "X", "layout": ALB_LAYOUT})["id"]
        == 500
    )


def test_unknown_model_is_a_clear_error(seeded: SwarmDatabase) -> None:
    with pytest.raises(
        UnknownReferenceError,
        match=r"model 'Albatros 250' not found in systems.models; did you mean 'Albatross 250 VTOL'",
    ):
        seeded.add("systems.layouts", {"name": "new", "model": "Albatros 250"})
    with pytest.raises(UnknownReferenceError, match=r"not found in systems\.layouts"):
        seeded.add("systems.systems", {"user_id": "X", "layout": "nope"})
    with pytest.raises(UnknownReferenceError, match=r"system 999 not found in systems\.systems"):
        seeded.add("systems.params", {"system": 999, "name": "a", "value": "b"})


def test_duplicate_user_id_and_layout_is_refused(seeded: SwarmDatabase) -> None:
    with pytest.raises(DuplicateError, match=r"same user_id \+ layout exists \(user_id='ALB-01'"):
        seeded.add("systems.systems", {"user_id": "ALB-01", "layout": ALB_LAYOUT})
    # the same user id on another layout is another system
    seeded.add("systems.systems", {"user_id": "ALB-01", "layout": "Quadcopter + EO 1080p"})
    with pytest.raises(DuplicateError, match="user_id"):
        seeded.add("payload.payloads", {"user_id": "CAM-01", "layout": "EO 1.5 Mpx 2-axis"})


def test_duplicate_model_name_and_node_id_are_refused(seeded: SwarmDatabase) -> None:
    with pytest.raises(DuplicateError, match="same name exists"):
        seeded.add("systems.models", {"name": ALBATROSS, "subtype": "VTOL"})
    with pytest.raises(DuplicateError, match="same id exists"):
        seeded.add("systems.systems", {"id": 1, "user_id": "NEW", "layout": ALB_LAYOUT})


@pytest.mark.parametrize(
    ("record", "match"),
    [
        ({"model": "M", "cruise_speed_m_s": "fast", "max_speed_m_s": 1.0}, "expected a number"),
        ({"model": "M", "cruise_speed_m_s": math.nan, "max_speed_m_s": 1.0}, "finite"),
        ({"model": "M", "cruise_speed_m_s": math.inf, "max_speed_m_s": 1.0}, "finite"),
        ({"model": "M", "cruise_speed_m_s": True, "max_speed_m_s": 1.0}, "expected a number"),
        ({"model": "M", "cruise_speed_m_s": 1.0}, "field 'max_speed_m_s' is required"),
        (
            {"model": "M", "cruise_speed_m_s": 1.0, "max_speed_m_s": 2.0, "colour": "red"},
            "unknown field 'colour'",
        ),
        (
            {"model": "M", "cruise_speed_m_s": 1.0, "max_speed_m_s": 2.0, "battery_low_pct": 2.5},
            "expected an integer",
        ),
        (
            {"model": "M", "cruise_speed_m_s": 1.0, "max_speed_m_s": 2.0, "has_parachute": "maybe"},
            "expected true or false",
        ),
    ],
)
def test_invalid_values_are_refused_before_sqlite(
    seeded: SwarmDatabase, record: dict[str, object], match: str
) -> None:
    seeded.add("systems.models", {"name": "M", "subtype": "multirotor"})
    with pytest.raises(InvalidValueError, match=match):
        seeded.add("systems.model-params", record)


def test_rules_of_the_schema_come_back_as_constraint_errors(seeded: SwarmDatabase) -> None:
    seeded.add("systems.models", {"name": "Slow", "subtype": "fixed-wing"})
    with pytest.raises(ConstraintError, match="speeds_ordered"):
        seeded.add(
            "systems.model-params",
            {
                "model": "Slow",
                "cruise_speed_m_s": 10.0,
                "min_speed_m_s": 12.0,
                "max_speed_m_s": 20.0,
            },
        )
    with pytest.raises(ConstraintError, match="battery_critical_pct"):
        seeded.add(
            "systems.model-params",
            {
                "model": "Slow",
                "cruise_speed_m_s": 10.0,
                "max_speed_m_s": 20.0,
                "battery_low_pct": 10,
                "battery_critical_pct": 10,
            },
        )
    with pytest.raises(ConstraintError, match="system payload"):
        seeded.add(
            "systems.systems", {"user_id": "Z", "layout": ALB_LAYOUT, "payload": 10}
        )  # an SDR
    assert seeded.counts()["systems.model-params"] == 5  # nothing written


def test_removing_a_record_in_use_says_who_uses_it(seeded: SwarmDatabase) -> None:
    with pytest.raises(
        InUseError,
        match=r"Generic Rover is still used by 1 record\(s\) of systems.layouts \(Rover \+ SDR\)",
    ):
        seeded.remove("systems.models", "Generic Rover")
    with pytest.raises(InUseError, match="used by 1 record"):
        seeded.remove("payload.payloads", 1)  # mounted on ALB-01
    before = seeded.counts()
    removed = seeded.remove("systems.systems", "QUAD-01")
    assert removed["id"] == 7
    after = seeded.counts()
    assert after["systems.params"] == before["systems.params"] - 2  # its own params went too
    assert after["common.comms"] == before["common.comms"] - 1
    seeded.remove("payload.payloads", removed["payload"])  # no longer mounted


def test_lookup_by_user_id_or_id(seeded: SwarmDatabase) -> None:
    assert seeded.get("systems.systems", "ALB-02")["id"] == 2
    assert seeded.get("systems.systems", "2", text=True)["user_id"] == "ALB-02"
    assert seeded.get("systems.params", 1, "mav_sysid") == {
        "system": 1,
        "name": "mav_sysid",
        "value": "1",
    }
    assert seeded.get("systems.params", "1", "mav_sysid", text=True)["value"] == "1"
    seeded.add("systems.systems", {"user_id": "ALB-02", "layout": "Rover + SDR"})
    with pytest.raises(AmbiguousError, match="names several records"):
        seeded.get("systems.systems", "ALB-02")
    with pytest.raises(InvalidValueError, match="named by system \\+ name"):
        seeded.get("systems.params", 1)
    with pytest.raises(NotFoundError):
        seeded.get("systems.models", "nope")
    with pytest.raises(UnknownTableError, match="tables: types, subtypes"):
        seeded.records("systems.vehicles")
    with pytest.raises(UnknownTableError, match="groups: systems, swarm, payload, common"):
        seeded.records("fleet.systems")


def test_records_filter_and_show_references_by_key(seeded: SwarmDatabase) -> None:
    layouts = seeded.records("systems.layouts", model=QUADCOPTER)
    assert [r["name"] for r in layouts] == ["Quadcopter + EO 1080p", "Quadcopter + thermal"]
    assert seeded.get("systems.subtypes", "VTOL")["vehicle_type"] == "VTOL"
    assert seeded.get("swarm.missions", "MUM-T")["mission_type"] == "MUMT"


def test_vehicle_profile_by_id_or_by_user_id_and_model(seeded: SwarmDatabase) -> None:
    by_id = seeded.vehicle_profile(3)
    assert by_id == seeded.vehicle_profile(user_id="ALB-03")
    assert by_id == seeded.vehicle_profile(user_id="ALB-03", model=ALBATROSS)
    assert by_id.vehicle_type is VehicleType.VTOL and by_id.is_fixed_wing
    seeded.add("systems.systems", {"user_id": "ALB-03", "layout": "Quadcopter + EO 1080p"})
    with pytest.raises(ProfileError, match="names several systems"):
        seeded.vehicle_profile(user_id="ALB-03")
    assert seeded.vehicle_profile(user_id="ALB-03", model=QUADCOPTER).model == QUADCOPTER
    with pytest.raises(ProfileError, match="no system with id 4242"):
        seeded.vehicle_profile(4242)
    with pytest.raises(TypeError):
        seeded.vehicle_profile()


def test_a_model_without_parameters_cannot_resolve(seeded: SwarmDatabase) -> None:
    seeded.add("systems.models", {"name": "Bare", "subtype": "multirotor"})
    seeded.add("systems.layouts", {"name": "Bare", "model": "Bare"})
    vid = seeded.add("systems.systems", {"user_id": "B-1", "layout": "Bare"})["id"]
    with pytest.raises(ProfileError, match="model 'Bare' has no parameters"):
        seeded.vehicle_profile(vid)


def test_payload_hierarchy_for_voting(seeded: SwarmDatabase) -> None:
    assert seeded.payload_class("Thermal 640 3-axis gimbal") == PayloadClass(
        "optical", "thermal camera", "Thermal 640 3-axis gimbal"
    )
    assert seeded.vehicle_profile(9).payload_class == seeded.payload_class(
        "Thermal 640 3-axis gimbal"
    )
    with pytest.raises(ProfileError, match="unknown payload model"):
        seeded.payload_class("Periscope")


def test_node_parameters(seeded: SwarmDatabase) -> None:
    assert seeded.system_params(1)["mav_sysid"] == "1"
    assert seeded.module_params("voting") == {
        "weight_payload": 0.6,
        "weight_time": 0.2,
        "weight_battery": 0.3,
        "time_scale_per_s": 0.01,
    }
    assert seeded.module_params("collision avoidance (fixed-wing)")["risk_distance_m"] == 40.0
    with pytest.raises(ProfileError, match="did you mean 'voting'"):
        seeded.module_params("votin")
    assert seeded.mission_defaults(MissionType.AREA) == {
        "altitude_rel_m": 100.0,
        "side_overlap": 0.7,
    }


def test_errors_are_record_errors_and_value_errors(seeded: SwarmDatabase) -> None:
    with pytest.raises(ValueError):
        seeded.add("systems.types", {"name": ""})
    with pytest.raises(RecordError):
        seeded.add("systems.types", {"name": " padded"})


def test_a_reader_thread_and_a_writer_share_the_database(seeded: SwarmDatabase) -> None:
    errors: list[BaseException] = []
    stop = threading.Event()

    def reader() -> None:
        try:
            while not stop.is_set():
                assert len(seeded.profiles()) >= 14
        except BaseException as exc:  # pragma: no cover - reported below
            errors.append(exc)

    t = threading.Thread(target=reader)
    t.start()
    try:
        for i in range(30):
            seeded.add("systems.systems", {"user_id": f"T-{i}", "layout": ALB_LAYOUT})
    finally:
        stop.set()
        t.join()
    assert not errors
    assert seeded.counts()["systems.systems"] == 44
