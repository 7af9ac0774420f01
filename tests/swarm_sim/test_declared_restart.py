"""declared state that survives restarts, in fast time (FastFleet: the node
cores, their autopilot links and simulated ArduPilots; each node's database is the last
state it stored): a node restarted on its database, or on a new one, holds the base,
zones, operating area and fleet the operator declared; a zone withdrawn while it was
down stays withdrawn everywhere; a full disk is alerted and loses nothing."""

from __future__ import annotations

import msgspec

from swarm_proto import (
    Alert,
    AlertCode,
    Command,
    CommandArgs,
    CommandKind,
    Geometry,
    GeoPoint,
    NoFlyZone,
    Selector,
    SelectorKind,
    Severity,
)
from swarm_sim.core import SITL_HOME
from swarm_sim.fast_fleet import FastFleet
from tests.swarm_node.test_node_fences_sim import EXCLUSION_CIRCLE, GCS, north

MEMBERS = [1, 7, 8]  # an Albatross VTOL and two quadcopters of the seed database


class Declarer:
    """A ground station: every declaration stamped with its clock, as `gcs` does."""

    def __init__(self, fleet: FastFleet) -> None:
        self.fleet, self.seq = fleet, 0

    def __call__(self, msg: msgspec.Struct, to: list[int] | None = None) -> msgspec.Struct:
        msg = msgspec.structs.replace(msg, time_unix_s=self.fleet.now)
        self.fleet.broadcast(
            msg, to=[v for v in (to or self.fleet.vehicles) if not self.fleet.vehicles[v].down]
        )
        self.fleet.run_for(1.0)
        return msg

    def command(self, kind: CommandKind, target: Selector | None = None, **args: object) -> Command:
        self.seq += 1
        cmd = Command(GCS, self.seq, kind, target or Selector(), CommandArgs(**args))  # type: ignore[arg-type]
        out = self(cmd)
        assert isinstance(out, Command)
        return out


BASE = GeoPoint(SITL_HOME.lat_deg + 0.0005, SITL_HOME.lon_deg, SITL_HOME.alt_m)


def declared_fleet(fleet_profiles: dict) -> tuple[FastFleet, Declarer, NoFlyZone, NoFlyZone]:
    fleet = FastFleet.build(MEMBERS, fleet_profiles)
    assert fleet.run_until(
        lambda: all(
            v.link.state.ekf_has_position and v.link.state.home for v in fleet.vehicles.values()
        ),
        60,
    )
    gs = Declarer(fleet)
    gs.command(CommandKind.SET_BASE, point=BASE)
    gs.command(CommandKind.SET_FLEET, Selector(SelectorKind.IDS, (7, 8)), fleet_id=2)
    zlat, zlon = north(200.0)
    zone = gs(NoFlyZone(3, Geometry.circle(zlat, zlon, 30.0), name="tower"))
    area = gs(
        NoFlyZone(
            4,
            Geometry.circle(SITL_HOME.lat_deg, SITL_HOME.lon_deg, 2000.0),
            name="field",
            operating_area=True,
        )
    )
    fleet.run_for(3.0)
    assert isinstance(zone, NoFlyZone) and isinstance(area, NoFlyZone)
    return fleet, gs, zone, area


def holds(fleet: FastFleet, vid: int, zones: dict[int, NoFlyZone], fleet_id: int) -> bool:
    n = fleet.vehicles[vid].node
    return n.base == BASE and n.monitor.zones == zones and n.fleet_id == fleet_id


def test_a_restarted_node_holds_what_was_declared(fleet_profiles: dict) -> None:
    """Before a restarted node forgot the base, zones and fleet: it stayed
    INACTIVE, nothing re-sent them and its peers did not tell it."""
    fleet, _, zone, area = declared_fleet(fleet_profiles)
    zones = {3: zone, 4: area}
    assert all(holds(fleet, v, zones, 0 if v == 1 else 2) for v in MEMBERS)
    assert fleet.vehicles[7].store.writes >= 1
    fleet.kill_node(7)
    fleet.run_for(5.0)
    node = fleet.restart_node(7)
    fleet.run_for(3.0)
    assert node is fleet.vehicles[7].node
    assert holds(fleet, 7, zones, 2)
    # its autopilot's fence is the zones in force again (the backstop)
    fleet.run_for(5.0)
    sim = fleet.vehicles[7].endpoint.autopilot
    assert EXCLUSION_CIRCLE in [it.command for it in sim.fence_items]


def test_a_node_on_a_new_database_learns_it_all_from_its_peers(fleet_profiles: dict) -> None:
    fleet, _, zone, area = declared_fleet(fleet_profiles)
    fleet.kill_node(8)
    fleet.run_for(2.0)
    fleet.restart_node(8, keep_database=False)  # the file was lost or replaced
    fleet.run_for(3.0)
    assert holds(fleet, 8, {3: zone, 4: area}, 2)
    assert fleet.vehicles[8].store.state is not None  # and stored what it learned
    assert {z.zone_id for z in fleet.vehicles[8].store.state.zones} == {3, 4}


def test_a_zone_withdrawn_while_a_node_was_down_stays_withdrawn(fleet_profiles: dict) -> None:
    fleet, gs, zone, _area = declared_fleet(fleet_profiles)
    fleet.kill_node(7)
    fleet.run_for(2.0)
    withdrawn = gs(msgspec.structs.replace(zone, active=False))  # 7 does not hear it
    assert fleet.vehicles[7].store.state is not None
    assert next(z for z in fleet.vehicles[7].store.state.zones if z.zone_id == 3).active
    fleet.restart_node(7)  # its database still holds the zone in force
    fleet.run_for(8.0)
    for vid in MEMBERS:  # everyone, the restarted node too, holds the withdrawal
        assert fleet.vehicles[vid].node.monitor.zones[3] == withdrawn, vid
    sim = fleet.vehicles[7].endpoint.autopilot
    assert EXCLUSION_CIRCLE not in [it.command for it in sim.fence_items]


def test_a_full_disk_is_alerted_once_and_loses_nothing(fleet_profiles: dict) -> None:
    fleet, gs, _zone, _area = declared_fleet(fleet_profiles)
    v = fleet.vehicles[7]
    v.store.full = True
    zlat, zlon = north(-300.0)
    z5 = gs(NoFlyZone(5, Geometry.circle(zlat, zlon, 25.0), name="mast"))
    gs(NoFlyZone(6, Geometry.circle(zlat, zlon + 0.001, 25.0), name="mast 2"))
    warned = [a for a in fleet.messages(Alert, sender=7) if "not stored" in a.text]
    assert len(warned) == 1 and warned[0].severity == Severity.WARNING
    assert warned[0].code == AlertCode.GENERIC and "disk" in warned[0].text
    assert v.node.monitor.zones[5] == z5  # held in memory
    fleet.kill_node(7)
    fleet.run_for(1.0)
    fleet.restart_node(7)  # its database missed zones 5 and 6: the peers have them
    fleet.run_for(3.0)
    assert {3, 4, 5, 6} <= set(v.node.monitor.zones)
    v.store.full = False
    gs.command(CommandKind.SET_BASE, point=BASE)  # any change is stored again
    assert v.store.state is not None and {3, 4, 5, 6} <= {z.zone_id for z in v.store.state.zones}
