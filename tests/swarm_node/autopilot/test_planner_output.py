"""What the planners (swarm_node.core.planning) output is what the autopilot link
uploads: every plan of every mission type (area, target, perimeter, route, objective,
autoland, MUM-T), for a QuadPlane and a quadcopter with the swarm database's seed
parameters, converts and is accepted item by item by the simulated ArduPilot."""

from __future__ import annotations

import pytest

from swarm_node.core.autopilot import requests as rq
from swarm_node.core.planning import LeadState, PlanVehicle, VehiclePose
from swarm_node.core.planning.context import PlanContext
from swarm_node.core.profile import VehicleProfile
from swarm_node.database import seed_profiles
from swarm_proto import Geometry, GeometryKind, LatLon, MissionParams

from .test_flights import HOME, SimFlight, offset, ready

planning = pytest.importorskip("swarm_node.core.planning")

SEED = seed_profiles()
VTOL = SEED["Albatross 250 VTOL"]
QUAD = SEED["Generic Quadcopter"]


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
    objectives = Geometry(GeometryKind.POINTS, (LatLon(*offset(600, 0)), LatLon(*offset(0, 700))))
    lead = LeadState(*offset(400, 0), 90.0, course_deg=90.0, speed_m_s=30.0, time_s=0.0)
    return {
        "area": planning.plan_area(PlanContext(Geometry.polygon(square), v, p, **kw)),
        "target": planning.plan_target(PlanContext(Geometry.point(*offset(600, 0)), v, p, **kw)),
        "perimeter": planning.plan_perimeter(PlanContext(Geometry.polygon(square), v, p, **kw)),
        "route": planning.plan_route(PlanContext(line, v, p, **kw)),
        "objective": planning.plan_objective(PlanContext(objectives, v, p, **kw)),
        "autoland": planning.plan_autoland(PlanContext(Geometry.point(*offset(0, 0)), v, p, **kw)),
        "mumt": planning.plan_mumt(lead, v, p, now_s=0.0, **kw),
    }


def _polyline(points: list[tuple[float, float]]) -> Geometry:
    return Geometry(GeometryKind.POLYLINE, tuple(LatLon(a, b) for a, b in points))


@pytest.mark.parametrize(("model", "profile"), [("vtol", VTOL), ("copter", QUAD)])
def test_every_plan_uploads_to_the_simulated_autopilot(model: str, profile: VehicleProfile) -> None:
    f = SimFlight(model, profile.vehicle_type)
    ready(f)
    uploaded = 0
    made = plans(profile)
    assert set(made) == {"area", "target", "perimeter", "route", "objective", "autoland", "mumt"}
    for name, plan in made.items():
        for vp in plan.vehicles:  # type: ignore[attr-defined]
            assert vp.waypoints, name
            result = f.do(rq.UploadMission(items=vp.waypoints))
            assert result.ok, (name, result.reason)
            assert len(f.ep.autopilot.mission_items) == len(result.items), name
            uploaded += 1
    assert uploaded == 2 * len(made)
