"""One source of vehicle parameters for every planning test.

The profiles come from the paper's reference aircraft (Albatross 250 VTOL: cruise
26 m/s, stall 15.5 m/s, two-axis 1.5 Mpx camera) and a generic quadcopter. When the
swarm database's seed data lands, this fixture switches to the seed profiles: the
planning tests take their parameters from here, never from constants of their own.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import msgspec
import pytest

from swarm_node.core.planning import PlanVehicle, VehiclePose
from swarm_node.core.profile import CameraProfile, VehicleProfile
from swarm_proto import VehicleType

ORIGIN = (40.4168, -3.7038)  # test missions are built around here

_PROFILES = {
    "fixed_wing": VehicleProfile(
        vehicle_id=1,
        user_id="ALB-1",
        model="Albatross 250 VTOL",
        vehicle_type=VehicleType.VTOL,
        system_type="UAV",
        system_subtype="fixed-wing",
        payload_model="2-axis gimbal 1.5 Mpx",
        payload_subtype="EO",
        payload_type="camera",
        cruise_speed_m_s=26.0,
        min_speed_m_s=15.5,  # stall
        max_speed_m_s=30.0,
        max_bank_deg=45.0,
        climb_rate_m_s=5.0,
        sink_rate_m_s=3.0,
        loiter_radius_m=80.0,
        camera=CameraProfile(
            hfov_deg=60.0, vfov_deg=47.0, resolution_px=(1440, 1080), gimbal_axes=2
        ),
    ),
    "multirotor": VehicleProfile(
        vehicle_id=101,
        user_id="QUAD-1",
        model="generic quadcopter",
        vehicle_type=VehicleType.COPTER,
        system_type="UAV",
        system_subtype="multirotor",
        payload_model="fixed camera",
        payload_type="camera",
        cruise_speed_m_s=10.0,
        min_speed_m_s=0.0,
        max_speed_m_s=15.0,
        max_bank_deg=35.0,
        climb_rate_m_s=3.0,
        sink_rate_m_s=2.0,
        camera=CameraProfile(hfov_deg=84.0, vfov_deg=62.0, resolution_px=(4000, 3000)),
    ),
}


@pytest.fixture(scope="session")
def profiles() -> dict[str, VehicleProfile]:
    """Vehicle profiles by role: "fixed_wing" and "multirotor"."""
    return dict(_PROFILES)


def make_fleet(
    profiles: dict[str, VehicleProfile],
    roles: list[str],
    poses: list[VehiclePose | None] | None = None,
) -> list[PlanVehicle]:
    """Vehicles with distinct ids (role profile + index) at `poses`."""
    out = []
    for i, role in enumerate(roles):
        prof = msgspec.structs.replace(profiles[role], vehicle_id=profiles[role].vehicle_id + i)
        out.append(PlanVehicle(prof, poses[i] if poses else None))
    return out


@pytest.fixture
def fleet(profiles: dict[str, VehicleProfile]) -> Callable[..., list[PlanVehicle]]:
    def build(roles: list[str], poses: list[VehiclePose | None] | None = None) -> list[PlanVehicle]:
        return make_fleet(profiles, roles, poses)

    return build


@pytest.fixture(scope="session")
def coverage_refs() -> dict[str, Any]:
    from tests.conftest import SHARED

    path = Path(SHARED) / "bench" / "coverage_polygons.json"
    if not path.is_file():
        pytest.skip(f"{path} not found")
    data: dict[str, Any] = json.loads(path.read_text())
    return data
