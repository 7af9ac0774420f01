"""Mission planning library (paper section 2.3.5 and its algorithm summary): pure
functions over geometry, no I/O. The mission manager calls the `plan_*` functions with
the mission geometry (geodetic), the no-fly zones, the mission parameters and the
vehicles (profile + current pose); each returns a frozen plan whose `vehicles` hold the
geodetic waypoint lists the autopilot link uploads, plus its metrics.

Errors: every planner raises a `PlanningError` subclass (also a ValueError) for input it
cannot plan. See docs/planners.md.
"""

from .area import AreaPlan, plan_area, replan_area
from .autoland import AutolandPlan, LandingSlot, plan_autoland
from .context import PlanContext
from .coverage import (
    CoveragePath,
    Lane,
    LanePlan,
    Region,
    SweepCost,
    connect,
    coverage_ratio,
    decompose,
    lane_spacing_m,
    lanes,
    order,
    overlap_ratio,
    plan_lanes,
    sweep_angle,
    sweep_angles,
)
from .dubins import DubinsPath, Pose, Word, batch_lengths, path_length, shortest_path
from .errors import (
    EmptyAreaError,
    InfeasibleTimingError,
    InvalidGeometryError,
    InvalidParameterError,
    NoSafeRouteError,
    NoVehiclesError,
    PlanningError,
    TargetInZoneError,
)
from .flight import (
    FIXED_WING_ACCEPT_M,
    Course,
    FlownPath,
    flight_problems,
    flyable_course,
    flyable_plan,
    flyable_waypoints,
    predict_flight,
)
from .formation import Trim, cyclic_slots, respace
from .geo import LocalFrame, VehiclePose, heading_to_yaw, yaw_to_heading
from .mumt import LeadState, MumtPlan, Offset, plan_mumt, vee_offsets
from .objective import ObjectivePlan, plan_objective
from .perimeter import PerimeterPlan, plan_perimeter, respace_perimeter, smooth_loop
from .route import Arrival, Leg, RoutePlan, leg_for, plan_route, synchronize
from .split import MakespanCost, SplitPlan, Worker, remaining_lanes, replan, split_lanes
from .target import TargetPlan, plan_target, respace_orbit
from .turns import DubinsTurns, PointTurns, TurnModel, turn_model_for
from .vehicles import PlanVehicle, VehiclePlan, common_speed
from .zones import Conflict, Obstacles, Track, Zone, ZoneSet, circle_points, visibility_path

__all__ = [
    "FIXED_WING_ACCEPT_M",
    "AreaPlan",
    "Arrival",
    "AutolandPlan",
    "Conflict",
    "Course",
    "CoveragePath",
    "DubinsPath",
    "DubinsTurns",
    "EmptyAreaError",
    "FlownPath",
    "InfeasibleTimingError",
    "InvalidGeometryError",
    "InvalidParameterError",
    "LandingSlot",
    "Lane",
    "LanePlan",
    "LeadState",
    "Leg",
    "LocalFrame",
    "MakespanCost",
    "MumtPlan",
    "NoSafeRouteError",
    "NoVehiclesError",
    "ObjectivePlan",
    "Obstacles",
    "Offset",
    "PerimeterPlan",
    "PlanContext",
    "PlanVehicle",
    "PlanningError",
    "PointTurns",
    "Pose",
    "Region",
    "RoutePlan",
    "SplitPlan",
    "SweepCost",
    "TargetInZoneError",
    "TargetPlan",
    "Track",
    "Trim",
    "TurnModel",
    "VehiclePlan",
    "VehiclePose",
    "Word",
    "Worker",
    "Zone",
    "ZoneSet",
    "batch_lengths",
    "circle_points",
    "common_speed",
    "connect",
    "coverage_ratio",
    "cyclic_slots",
    "decompose",
    "flight_problems",
    "flyable_course",
    "flyable_plan",
    "flyable_waypoints",
    "heading_to_yaw",
    "lane_spacing_m",
    "lanes",
    "leg_for",
    "order",
    "overlap_ratio",
    "path_length",
    "plan_area",
    "plan_autoland",
    "plan_lanes",
    "plan_mumt",
    "plan_objective",
    "plan_perimeter",
    "plan_route",
    "plan_target",
    "predict_flight",
    "remaining_lanes",
    "replan",
    "replan_area",
    "respace",
    "respace_orbit",
    "respace_perimeter",
    "shortest_path",
    "smooth_loop",
    "split_lanes",
    "sweep_angle",
    "sweep_angles",
    "synchronize",
    "turn_model_for",
    "vee_offsets",
    "visibility_path",
    "yaw_to_heading",
]
