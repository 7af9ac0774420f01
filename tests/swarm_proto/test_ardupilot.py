from __future__ import annotations

import pytest
from pymavlink import mavutil

from swarm_proto import VehicleType
from swarm_proto.ardupilot import mode_name, mode_number, vehicle_type_from_mav_type


def test_mode_tables_match_pymavlink() -> None:
    for vt, table in (
        (VehicleType.PLANE, mavutil.mode_mapping_apm),
        (VehicleType.COPTER, mavutil.mode_mapping_acm),
        (VehicleType.ROVER, mavutil.mode_mapping_rover),
    ):
        for number, name in table.items():
            if name in ("RATE_ACRO",):  # newer than the dialect we target
                continue
            assert mode_name(vt, number) == name
            assert mode_number(vt, name) == number


def test_unknown_modes() -> None:
    assert mode_name(VehicleType.COPTER, 99) == "MODE(99)"
    with pytest.raises(ValueError, match="no mode"):
        mode_number(VehicleType.COPTER, "QLAND")
    with pytest.raises(ValueError, match="no ArduPilot modes"):
        mode_number(VehicleType.GCS, "AUTO")
    assert mode_number(VehicleType.VTOL, "qland") == 20
    assert mode_number(VehicleType.BOAT, "HOLD") == 4


def test_mav_types() -> None:
    assert vehicle_type_from_mav_type(1) == VehicleType.PLANE
    assert vehicle_type_from_mav_type(2) == VehicleType.COPTER
    assert vehicle_type_from_mav_type(11) == VehicleType.BOAT
    assert vehicle_type_from_mav_type(999) == VehicleType.OTHER
