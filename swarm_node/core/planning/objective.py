"""Objective / multi-objective missions: the vehicles are spread evenly over one or
several points (counts differ by at most one; extra vehicles go to the points nearest
the fleet), each vehicle going to the point that keeps the total travel least; at each
point its vehicles form a target formation (see target.py)."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from swarm_proto import Geometry, GeometryKind

from .context import PlanContext
from .errors import InvalidGeometryError, TargetInZoneError
from .formation import assign_min_cost
from .geo import LocalFrame
from .target import TargetPlan, plan_target
from .vehicles import PlanVehicle, VehiclePlan, require_vehicles
from .zones import Track


@dataclass(frozen=True, slots=True)
class ObjectivePlan:
    frame: LocalFrame
    groups: tuple[tuple[int, tuple[int, ...]], ...]  # point index -> vehicle ids
    targets: tuple[tuple[int, TargetPlan], ...]  # point index -> its formation
    unserved: tuple[int, ...]  # point indexes with no vehicle (fewer vehicles than points)

    def group_of(self, point: int) -> tuple[int, ...]:
        return dict(self.groups).get(point, ())

    @property
    def vehicles(self) -> tuple[VehiclePlan, ...]:
        """Every vehicle's share, like the other plans."""
        return tuple(v for _, target in self.targets for v in target.vehicles)

    @property
    def tracks(self) -> tuple[Track, ...]:
        """Every path flown (each point's formation), densely sampled (zone checks)."""
        return tuple(t for _, target in self.targets for t in target.tracks)


def even_counts(n_vehicles: int, n_points: int) -> list[int]:
    base, extra = divmod(n_vehicles, n_points)
    return [base + (1 if i < extra else 0) for i in range(n_points)]


def plan_objective(ctx: PlanContext) -> ObjectivePlan:
    geometry, vehicles, params = ctx.geometry, ctx.vehicles, ctx.params
    require_vehicles(vehicles)
    if geometry.kind not in (GeometryKind.POINT, GeometryKind.POINTS):
        raise InvalidGeometryError(f"objectives are POINT or POINTS, got {geometry.kind.name}")
    frame = ctx.local_frame()
    pts = frame.ring(geometry.points)
    zs = ctx.zone_set(frame)
    for i, (x, y) in enumerate(pts):
        z = zs.zone_containing(x, y, params.altitude_rel_m)
        if z is not None:
            raise TargetInZoneError(f"objective {i} is inside no-fly zone {z.zone_id}")
    xy = np.array(
        [frame.to_local(v.pose.lat_deg, v.pose.lon_deg) if v.pose else (0.0, 0.0) for v in vehicles]
    )
    centroid = xy.mean(axis=0)
    by_near = sorted(range(len(pts)), key=lambda i: math.dist(pts[i], centroid))
    counts = even_counts(len(vehicles), len(pts))
    count_of = {p: counts[rank] for rank, p in enumerate(by_near)}
    columns = [p for p in range(len(pts)) for _ in range(count_of[p])]
    cost = np.array([[math.dist(xy[i], pts[p]) for p in columns] for i in range(len(vehicles))])
    cols = assign_min_cost(cost)
    groups: dict[int, list[PlanVehicle]] = {}
    for i, c in enumerate(cols):
        groups.setdefault(columns[c], []).append(vehicles[i])
    targets = []
    for p, group in sorted(groups.items()):
        la, lo = geometry.points[p].lat_deg, geometry.points[p].lon_deg
        targets.append(
            (
                p,
                plan_target(
                    dataclasses.replace(
                        ctx, geometry=Geometry.point(la, lo), vehicles=group, frame=frame
                    )
                ),
            )
        )
    return ObjectivePlan(
        frame,
        tuple((p, tuple(v.vehicle_id for v in g)) for p, g in sorted(groups.items())),
        tuple(targets),
        tuple(p for p in range(len(pts)) if p not in groups),
    )
