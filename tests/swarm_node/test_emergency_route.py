"""An emergency return does not cross a no-fly zone: ArduPilot's
RTL flies straight to the rally point; against SITL a copter sent to RTL in EMERGENCY
flew straight through the zone. In fast time (FastFleet: node core, the real autopilot
link, a simulated ArduCopter, real MAVLink bytes): a quadcopter beyond a zone, with
home on the other side, raises an emergency that asks for RTL; the track it flies home
keeps clear of the zone and it lands at home."""

from __future__ import annotations

import math

from swarm_node.core.autopilot.items import ItemKind
from swarm_node.core.autopilot.requests import ReturnToLaunch, StartMission, UploadMission
from swarm_node.core.autopilot.state import AutopilotState
from swarm_node.core.emergency_route import zone_safe_emergency
from swarm_proto import (
    Ack,
    Alert,
    AlertCode,
    Command,
    CommandArgs,
    CommandKind,
    FsmState,
    Geometry,
    GeoPoint,
    NoFlyZone,
)
from swarm_sim.core import SITL_HOME
from swarm_sim.demo import offset
from swarm_sim.fast_fleet import FastFleet

GCS = 900


def test_rtl_across_a_zone_becomes_a_zone_safe_way_home(fleet_profiles: dict) -> None:
    """Pure: RTL is replaced only when its straight line crosses a zone in force."""
    quad = fleet_profiles[7]
    home = GeoPoint(SITL_HOME.lat_deg, SITL_HOME.lon_deg, SITL_HOME.alt_m)
    zone = NoFlyZone(1, Geometry.circle(*offset(home.lat_deg, home.lon_deg, 150.0, 0.0), 40.0))
    beyond = AutopilotState(
        armed=True,
        lat_deg=offset(home.lat_deg, home.lon_deg, 300.0, 0.0)[0],
        lon_deg=home.lon_deg,
        alt_rel_m=20.0,
        home=home,
    )
    reqs, why = zone_safe_emergency((ReturnToLaunch(),), beyond, home, [zone], quad, 0.0)
    assert why.startswith("RTL would cross a no-fly zone")
    assert isinstance(reqs[0], UploadMission) and isinstance(reqs[1], StartMission)
    assert reqs[0].items[-1].kind == ItemKind.RTL and len(reqs[0].items) >= 3
    # beside the zone: the straight line is clear, plain RTL
    lat, lon = offset(home.lat_deg, home.lon_deg, 300.0, 200.0)
    aside = AutopilotState(armed=True, lat_deg=lat, lon_deg=lon, alt_rel_m=20.0, home=home)
    assert zone_safe_emergency((ReturnToLaunch(),), aside, home, [zone], quad, 0.0) == (
        (ReturnToLaunch(),),
        "",
    )
    # a zone not in force, or no zone: plain RTL
    assert zone_safe_emergency((ReturnToLaunch(),), beyond, home, [], quad, 0.0)[1] == ""


class Operator:
    def __init__(self, fleet: FastFleet) -> None:
        self.fleet, self.seq = fleet, 0

    def __call__(self, kind: CommandKind, **args: object) -> Ack:
        self.seq += 1
        seq = self.seq
        self.fleet.broadcast(Command(GCS, seq, kind, args=CommandArgs(**args)))  # type: ignore[arg-type]
        assert self.fleet.run_until(
            lambda: any(a.ref_id == seq for a in self.fleet.messages(Ack)), 60
        )
        return next(a for a in self.fleet.messages(Ack) if a.ref_id == seq)


def test_emergency_return_flies_around_the_zone(fleet_profiles: dict) -> None:
    fleet = FastFleet.build([7], fleet_profiles)
    v = fleet.vehicles[7]
    sim = v.endpoint.autopilot
    assert fleet.run_until(lambda: v.link.state.ekf_has_position and v.link.state.home, 60)
    home = v.link.state.home
    assert home is not None
    h = (home.lat_deg, home.lon_deg)
    # zone B between the vehicle and home, at every height (also the autopilot's fence);
    # zone A, further out, only below 25 m above home: a companion-computer zone the
    # copter is flown into at 20 m, which raises the emergency (GEOFENCE_BREACH -> RTL)
    zb = NoFlyZone(1, Geometry.circle(*offset(*h, 150.0, 0.0), 40.0), name="B")
    za = NoFlyZone(
        2,
        Geometry.circle(*offset(*h, 300.0, 0.0), 30.0),
        floor_alt_msl_m=-100.0,
        ceiling_alt_msl_m=home.alt_msl_m + 25.0,
        name="A",
    )
    op = Operator(fleet)
    assert op(CommandKind.SET_BASE, point=home).accepted
    fleet.broadcast(zb)
    fleet.broadcast(za)
    fleet.run_for(3.0)
    assert op(CommandKind.SET_MODE, text="GUIDED").accepted
    assert op(CommandKind.ARM).accepted
    assert op(CommandKind.TAKEOFF, value=20.0).accepted
    assert fleet.run_until(lambda: (v.link.state.alt_rel_m or 0.0) > 19.0, 60)
    # round zone B on the east, then on to zone A
    for n, e in ((150.0, 120.0), (300.0, 0.0)):
        lat, lon = offset(*h, n, e)
        assert op(CommandKind.GOTO, point=GeoPoint(lat, lon, home.alt_msl_m + 20.0)).accepted
        assert fleet.run_until(
            lambda lat=lat, lon=lon: (
                v.node.fsm.state == FsmState.EMERGENCY or math.hypot(*_ne(sim, lat, lon)) < 3.0
            ),
            300,
        )
    assert v.node.fsm.state == FsmState.EMERGENCY
    assert any(a.code == AlertCode.GEOFENCE_BREACH for a in fleet.messages(Alert))
    bc = _zone_ne(sim, zb)
    clearance = math.inf

    def landed() -> bool:
        nonlocal clearance
        b = sim.body
        clearance = min(clearance, math.hypot(b.n - bc[0], b.e - bc[1]) - 40.0)
        return not sim.armed and b.on_ground

    assert fleet.run_until(landed, 600)
    assert clearance > 0.0, clearance
    b = sim.body
    assert math.hypot(b.n - sim.home_ne[0], b.e - sim.home_ne[1]) < 5.0
    assert any("zone-safe legs home" in t for _, _, t in fleet.notes)


def _ne(sim: object, lat: float, lon: float) -> tuple[float, float]:
    n, e = sim.frame.to_ne(lat, lon)  # type: ignore[attr-defined]
    b = sim.body  # type: ignore[attr-defined]
    return n - b.n, e - b.e


def _zone_ne(sim: object, zone: NoFlyZone) -> tuple[float, float]:
    c = zone.geometry.points[0]
    return sim.frame.to_ne(c.lat_deg, c.lon_deg)  # type: ignore[attr-defined, no-any-return]
