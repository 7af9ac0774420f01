"""the autopilot backstop restored: after an autopilot reboot (empty stores,
the simulator's `reboot`) the node puts the fence and the rally point back and verifies
them by download; an autopilot that does not keep what it is given is a CRITICAL alert.
In fast time (FastFleet: node core, link core and simulated ArduPilot on MAVLink)."""

from __future__ import annotations

import dataclasses
from typing import Any

import pytest

from swarm_proto import Alert, AlertCode, CommandKind, Geometry, GeoPoint, NoFlyZone, Severity
from swarm_sim.core import SITL_HOME
from swarm_sim.fast_fleet import FastFleet
from tests.swarm_node.test_node_fences_sim import EXCLUSION_CIRCLE, Operator, north

NAV_RALLY_POINT = 5100
BASE = GeoPoint(SITL_HOME.lat_deg + 0.0005, SITL_HOME.lon_deg, SITL_HOME.alt_m + 20.0)


def backstopped(fleet_profiles: dict, vid: int = 7) -> FastFleet:
    fleet = FastFleet.build([vid], fleet_profiles)
    v = fleet.vehicles[vid]
    assert fleet.run_until(lambda: v.link.state.ekf_has_position and v.link.state.home, 60)
    assert Operator(fleet)(CommandKind.SET_BASE, point=BASE).accepted
    zlat, zlon = north(150.0)
    fleet.broadcast(NoFlyZone(3, Geometry.circle(zlat, zlon, 40.0), time_unix_s=fleet.now))
    fleet.run_for(5.0)
    sim = v.endpoint.autopilot
    assert [it.command for it in sim.fence_items] == [EXCLUSION_CIRCLE]
    assert [it.command for it in sim.rally_items] == [NAV_RALLY_POINT]
    return fleet


def alerts_since(fleet: FastFleet, t0: float, vid: int = 7) -> list[tuple[Severity, str]]:
    return [
        (a.severity, a.text)
        for a in fleet.messages(Alert, sender=vid)
        if a.time_unix_s >= t0 and a.code in (AlertCode.NO_FLY_ZONE, AlertCode.GENERIC)
    ]


@pytest.mark.parametrize("vid", [7, 1])  # a quadcopter, an Albatross VTOL
def test_after_an_autopilot_reboot_the_fence_and_rally_point_are_back(
    fleet_profiles: dict, vid: int
) -> None:
    """Before the autopilot stayed with 0 fence items and 0 rally points."""
    fleet = backstopped(fleet_profiles, vid)
    v = fleet.vehicles[vid]
    fence_before = list(v.endpoint.autopilot.fence_items)
    rally_before = list(v.endpoint.autopilot.rally_items)
    t0 = fleet.now
    fleet.reboot_autopilot(vid)
    sim = v.endpoint.autopilot
    assert sim.fence_items == [] and sim.rally_items == [] and sim.params["FENCE_ENABLE"][0] == 0
    fleet.run_for(20.0)
    assert v.link.state.reboots == 1
    sim = v.endpoint.autopilot
    assert [(i.command, i.lat_deg, i.lon_deg, i.param1) for i in sim.fence_items] == [
        (i.command, i.lat_deg, i.lon_deg, i.param1) for i in fence_before
    ]
    assert [(i.x, i.y, i.z) for i in sim.rally_items] == [(i.x, i.y, i.z) for i in rally_before]
    assert sim.params["FENCE_ENABLE"][0] == 1.0 and sim.fence_present()
    seen = alerts_since(fleet, t0, vid)
    assert (Severity.WARNING, "fence restored and verified (autopilot rebooted)") in seen
    assert (Severity.WARNING, "rally point restored and verified (autopilot rebooted)") in seen
    assert not [s for s, _ in seen if s >= Severity.CRITICAL]
    assert v.node.backstop.restored == 2 and v.node.backstop.mismatches == 0


def test_a_store_left_as_it_was_is_only_verified(fleet_profiles: dict) -> None:
    fleet = backstopped(fleet_profiles)
    v = fleet.vehicles[7]
    t0, verified = fleet.now, v.node.backstop.verified
    fleet.reboot_autopilot(7, keep_stores=True)  # ArduPilot keeps them in its storage
    fleet.run_for(20.0)
    assert not alerts_since(fleet, t0)
    assert v.node.backstop.restored == 0 and v.node.backstop.verified == verified + 2


class Drifting(list):  # type: ignore[type-arg]
    """A rally store that keeps every point 100 m north of where it was put."""

    def __setitem__(self, key: Any, value: Any) -> None:
        items = value if isinstance(key, slice) else [value]
        moved = [dataclasses.replace(i, x=i.x + 9000) for i in items]
        super().__setitem__(key, moved if isinstance(key, slice) else moved[0])

    def append(self, value: Any) -> None:
        super().append(dataclasses.replace(value, x=value.x + 9000))


def test_an_autopilot_that_does_not_keep_the_rally_point_is_a_critical_alert(
    fleet_profiles: dict,
) -> None:
    fleet = backstopped(fleet_profiles)
    v = fleet.vehicles[7]
    t0 = fleet.now
    fleet.reboot_autopilot(7)
    sim = v.endpoint.autopilot
    broken = Drifting()
    sim.rally_items = broken
    sim.transfers[2].items = broken  # MAV_MISSION_TYPE_RALLY
    fleet.run_for(30.0)
    critical = [t for s, t in alerts_since(fleet, t0) if s == Severity.CRITICAL]
    assert critical == ["autopilot rally point differs after restore: 1 items, 1 wanted"]
    assert v.node.backstop.mismatches >= 2  # retried, alerted once
    # the fence, kept right, was restored and verified
    assert [i.command for i in sim.fence_items] == [EXCLUSION_CIRCLE]
