"""End to end in fast time (swarm_sim's FastFleet: node core, the real autopilot link, a
simulated ArduPilot, real MAVLink bytes): a declared no-fly zone ends up in the
autopilot as an enabled fence, the autopilot turns a vehicle flown at it back by itself
(the backstop), and a withdrawn zone leaves the autopilot's fence empty and disabled."""

from __future__ import annotations

import math

import pytest

from swarm_proto import (
    Ack,
    Alert,
    AlertCode,
    Command,
    CommandArgs,
    CommandKind,
    Geometry,
    GeoPoint,
    NoFlyZone,
)
from swarm_sim.core import SITL_HOME
from swarm_sim.fast_fleet import FastFleet

GCS = 900
INCLUSION_CIRCLE = 5003  # MAV_CMD_NAV_FENCE_CIRCLE_INCLUSION
EXCLUSION_CIRCLE = 5004  # MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION


def north(m: float) -> tuple[float, float]:
    return SITL_HOME.lat_deg + m / 111_320.0, SITL_HOME.lon_deg


class Operator:
    """Commands as a ground station sends them, one after another, each until its ack."""

    def __init__(self, fleet: FastFleet) -> None:
        self.fleet, self.seq = fleet, 0

    def __call__(self, kind: CommandKind, **args: object) -> Ack:
        self.seq += 1
        seq = self.seq
        self.fleet.broadcast(Command(GCS, seq, kind, args=CommandArgs(**args)))  # type: ignore[arg-type]

        def answered() -> bool:
            return any(a.ref_id == seq for a in self.fleet.messages(Ack))

        assert self.fleet.run_until(answered, 60), f"{kind.name}: no answer"
        return next(a for a in self.fleet.messages(Ack) if a.ref_id == seq)


def test_a_zone_becomes_the_autopilots_fence_and_turns_the_vehicle_back(
    fleet_profiles: dict,
) -> None:
    fleet = FastFleet.build([7], fleet_profiles)  # a seed quadcopter
    v = fleet.vehicles[7]
    sim = v.endpoint.autopilot
    assert fleet.run_until(lambda: v.link.state.ekf_has_position and v.link.state.home, 60)
    assert sim.fence_items == [] and sim.params["FENCE_ENABLE"][0] == 0.0

    zlat, zlon = north(150.0)
    zone = NoFlyZone(3, Geometry.circle(zlat, zlon, 40.0), name="backstop test")
    fleet.broadcast(zone)
    fleet.run_for(3.0)
    assert [(it.command, it.param1) for it in sim.fence_items] == [(EXCLUSION_CIRCLE, 40.0)]
    assert sim.fence_items[0].lat_deg == pytest.approx(zlat, abs=1e-7)
    assert sim.params["FENCE_ENABLE"][0] == 1.0
    assert sim.params["FENCE_TYPE"][0] == 4.0  # polygon/circle fences only, not ALT/CIRCLE
    # enabled at the first try (real SITL refused the enable sent at
    # once after the upload, ArduPilot not having loaded the fence yet; the simulator now
    # does the same): no "fence upload failed" warning, one DO_FENCE_ENABLE
    assert not [a for a in fleet.messages(Alert, sender=7) if a.code == AlertCode.NO_FLY_ZONE]
    assert v.node.fences.keeper.failures == 0 and sim.fence_present()

    # flown straight at the zone (a GOTO through it, no planner involved): the
    # autopilot's own fence breach turns it home before it gets far in
    op = Operator(fleet)
    assert op(CommandKind.SET_MODE, text="GUIDED").accepted
    assert op(CommandKind.ARM).accepted
    assert op(CommandKind.TAKEOFF, value=30.0).accepted
    assert fleet.run_until(lambda: (v.link.state.alt_rel_m or 0.0) > 25.0, 60)
    lat, lon = north(400.0)
    assert op(CommandKind.GOTO, point=GeoPoint(lat, lon, SITL_HOME.alt_m + 30.0)).accepted
    furthest = -math.inf  # north of the zone's centre, m

    def turned_back() -> bool:
        nonlocal furthest
        if sim.fence_breach_count == 0 and v.link.state.lat_deg is not None:
            furthest = max(furthest, (v.link.state.lat_deg - zlat) * 111_320.0)
        return sim.fence_breach_count > 0 and sim.mode_name == "RTL"

    assert fleet.run_until(turned_back, 120)
    assert -45.0 < furthest < -35.0, furthest  # breached at its southern edge (40 m radius)
    fleet.run_for(30.0)
    here = v.link.state.lat_deg
    assert here is not None and (here - zlat) * 111_320.0 < -60.0  # on its way home

    # withdrawn: the autopilot's fence is emptied and disabled
    fleet.broadcast(NoFlyZone(3, zone.geometry, active=False))
    fleet.run_for(3.0)
    assert sim.fence_items == [] and sim.params["FENCE_ENABLE"][0] == 0.0


def test_an_operating_area_becomes_an_inclusion_fence(fleet_profiles: dict) -> None:
    fleet = FastFleet.build([10], fleet_profiles)  # a seed rover
    v = fleet.vehicles[10]
    sim = v.endpoint.autopilot
    assert fleet.run_until(lambda: v.link.state.ekf_has_position and v.link.state.home, 60)
    area = NoFlyZone(
        1, Geometry.circle(SITL_HOME.lat_deg, SITL_HOME.lon_deg, 500.0), operating_area=True
    )
    zlat, zlon = north(150.0)
    fleet.broadcast(area)
    fleet.broadcast(NoFlyZone(3, Geometry.circle(zlat, zlon, 40.0)))
    fleet.run_for(3.0)
    assert [(it.command, it.param1) for it in sim.fence_items] == [
        (INCLUSION_CIRCLE, 500.0),
        (EXCLUSION_CIRCLE, 40.0),
    ]
    assert sim.params["FENCE_ENABLE"][0] == 1.0 and sim.params["FENCE_TYPE"][0] == 4.0
