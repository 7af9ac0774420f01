"""What the planners (swarm_node.core.planning) output is what the autopilot link
uploads: every plan of every mission type, for a QuadPlane and a quadcopter, converts
and is accepted item by item by the simulated ArduPilot."""

from __future__ import annotations

import pytest

from swarm_node.core.autopilot import requests as rq
from swarm_node.core.planning import PlanVehicle, VehiclePose
from swarm_node.core.profile import CameraProfile, VehicleProfile
from swarm_proto import Geometry, MissionParams, VehicleType

from .test_flights import HOME, SimFlight, offset, ready

planning = pytest.importorskip("swarm_node.core.planning")

VTOL = VehicleProfile(
    vehicle_id=1, user_id="ALB-1", model="Albatross 250 VTOL", vehicle_type=VehicleType.VTOL,
    cruise_speed_m_s=26.0, min_speed_m_s=15.5, max_speed_m_s=30.0, max_bank_deg=45.0,
    climb_rate_m_s=5.0, sink_rate_m_s=3.0, loiter_radius_m=80.0,
    camera=CameraProfile(hfov_deg=60.0, vfov_deg=47.0, resolution_px=(1440, 1080), gimbal_axes=2),
)  # fmt: skip
QUAD = VehicleProfile(
    vehicle_id=2, user_id="QUAD-1", model="generic quadcopter", vehicle_type=VehicleType.COPTER,
    cruise_speed_m_s=10.0, max_speed_m_s=15.0, max_bank_deg=35.0, climb_rate_m_s=3.0,
    sink_rate_m_s=2.0, camera=CameraProfile(hfov_deg=84.0, vfov_deg=62.0),
)  # fmt: skip


def fleet(profile: VehicleProfile) -> list[PlanVehicle]:
    """Two vehicles of one kind (perimeter and target flights need a common speed)."""
    import msgspec

    return [
        PlanVehicle(profile, VehiclePose(*offset(-300, 0), 60.0, 0.0, profile.cruise_speed_m_s)),
        PlanVehicle(
            msgspec.structs.replace(profile, vehicle_id=profile.vehicle_id + 10),
            VehiclePose(*offset(-200, 60), 60.0, 0.0, profile.cruise_speed_m_s),
        ),
    ]


def plans(profile: VehicleProfile) -> dict[str, object]:
    p = MissionParams(altitude_rel_m=80.0, radius_m=150.0, loops=2, altitude_step_m=10.0)
    square = [offset(200, -300), offset(800, -300), offset(800, 300), offset(200, 300)]
    line = _polyline([offset(300, 0), offset(900, 200), offset(1200, -100)])
    kw = {"home_alt_msl_m": HOME.alt_m}
    v = fleet(profile)
    return {
        "area": planning.plan_area(Geometry.polygon(square), v, p, **kw),
        "target": planning.plan_target(Geometry.point(*offset(600, 0)), v, p, **kw),
        "perimeter": planning.plan_perimeter(Geometry.polygon(square), v, p, **kw),
        "route": planning.plan_route(line, v, p, **kw),
        "autoland": planning.plan_autoland(Geometry.point(*offset(0, 0)), v, p, **kw),
    }


def _polyline(points: list[tuple[float, float]]) -> Geometry:
    from swarm_proto import GeometryKind, LatLon

    return Geometry(GeometryKind.POLYLINE, tuple(LatLon(a, b) for a, b in points))


@pytest.mark.parametrize(("model", "profile"), [("vtol", VTOL), ("copter", QUAD)])
def test_every_plan_uploads_to_the_simulated_autopilot(model: str, profile: VehicleProfile) -> None:
    f = SimFlight(model, profile.vehicle_type)
    ready(f)
    uploaded = 0
    for name, plan in plans(profile).items():
        for vp in plan.vehicles:  # type: ignore[attr-defined]
            assert vp.waypoints, name
            result = f.do(rq.UploadMission(items=vp.waypoints))
            assert result.ok, (name, result.reason)
            assert len(f.ep.autopilot.mission_items) == len(result.items), name
            uploaded += 1
    assert uploaded == 10
