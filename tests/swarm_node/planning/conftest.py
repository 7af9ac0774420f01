"""One source of vehicle parameters for every planning test: the swarm database's seed
data (the paper's Albatross 250 VTOL with its two-axis 1.5 Mpx camera, and the generic
quadcopter), never constants of the tests' own.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import msgspec
import pytest

from swarm_node.core.planning import PlanVehicle, VehiclePose
from swarm_node.core.profile import VehicleProfile
from swarm_node.database import seed_profiles

ORIGIN = (40.4168, -3.7038)  # test missions are built around here

#: role -> (seed model, base vehicle id: fleets number vehicles base + index, and the two
#: bases are far apart so mixed fleets never repeat an id)
_ROLES = {"fixed_wing": ("Albatross 250 VTOL", 1), "multirotor": ("Generic Quadcopter", 101)}


@pytest.fixture(scope="session")
def profiles() -> dict[str, VehicleProfile]:
    """Vehicle profiles by role, from the database seed: "fixed_wing" and "multirotor"."""
    seed = seed_profiles()
    return {
        role: msgspec.structs.replace(seed[model], vehicle_id=base)
        for role, (model, base) in _ROLES.items()
    }


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
