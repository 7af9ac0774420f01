"""What a node tells the operator: it acknowledges every zone to whoever
declared it (AckRef.ZONE was never sent), says why it is not ready when it refuses a
mission (the text was empty), flags an autopilot of another type than the swarm
database says (a quadcopter's node on a QuadPlane), and fits long reasons into the
64-character text visibly."""

from __future__ import annotations

import msgspec

from swarm_node.core.node import NodeCore, Received
from swarm_proto import (
    Ack,
    AckReason,
    AckRef,
    Alert,
    AlertCode,
    AlertFlag,
    Geometry,
    Mission,
    MissionType,
    NoFlyZone,
    Selector,
    VehicleInfo,
    VehicleType,
)
from swarm_proto.ardupilot import autopilot_mismatch
from swarm_proto.text import TEXT_LIMIT, short_text
from swarm_sim.core import SITL_HOME, VehicleEndpoint
from swarm_sim.fast_fleet import FastFleet
from tests.swarm_node.test_node_core import flying, profile

GCS = 900


def acks_of(outputs: list) -> list[Ack]:
    return [o.msg for o in outputs if isinstance(getattr(o, "msg", None), Ack)]


def test_a_zone_is_acknowledged_to_its_issuer() -> None:
    node = NodeCore(profile(7))
    zone = NoFlyZone(3, Geometry.circle(37.42, -5.98, 50.0), issuer_id=GCS)
    (ack,) = acks_of(node.handle(Received(zone), 1.0))
    assert (ack.vehicle_id, ack.issuer_id, ack.ref, ack.ref_id) == (7, GCS, AckRef.ZONE, 3)
    assert ack.accepted and ack.reason == AckReason.OK and ack.text == "held"
    # a repeat is answered again (the ground station repeats until every vehicle answers)
    assert acks_of(node.handle(Received(zone), 2.0))[0].accepted

    gone = NoFlyZone(3, Geometry.circle(0.0, 0.0, 1.0), active=False, issuer_id=GCS)
    (ack,) = acks_of(node.handle(Received(gone), 3.0))
    assert ack.accepted and ack.text == "withdrawn"


def test_withdrawing_a_zone_never_held_is_not_found() -> None:
    """`gcs zone remove 99` said "withdrawn" for a zone nobody held."""
    node = NodeCore(profile(7))
    gone = NoFlyZone(99, Geometry.circle(0.0, 0.0, 1.0), active=False, issuer_id=GCS)
    (ack,) = acks_of(node.handle(Received(gone), 1.0))
    assert not ack.accepted and ack.reason == AckReason.NOT_FOUND
    assert ack.text == "zone 99 was not held"


def test_a_zone_from_an_older_sender_is_not_acknowledged() -> None:
    node = NodeCore(profile(7))
    zone = NoFlyZone(3, Geometry.circle(37.42, -5.98, 50.0))  # issuer_id 0: nobody to answer
    assert acks_of(node.handle(Received(zone), 1.0)) == []
    assert 3 in node.monitor.zones


def test_a_refused_mission_says_why_it_is_not_ready() -> None:
    """NOT_READY came with an empty text."""
    node = NodeCore(profile(7))
    node.handle(Received(_base_cmd()), 0.5)
    node.handle(_update(flying(armed=False, ekf_ok=False)), 1.0)
    mission = Mission(
        5, GCS, MissionType.TARGET, Geometry.point(37.41, -5.98), selection=Selector.ids(7)
    )
    (ack,) = acks_of(node.handle(Received(mission), 2.0))
    assert ack.reason == AckReason.NOT_READY and ack.text == "EKF estimate not good yet"


def test_the_mismatch_table() -> None:
    assert autopilot_mismatch(VehicleType.COPTER, 1) == (
        "autopilot is PLANE (MAV_TYPE 1), identity COPTER"
    )
    assert autopilot_mismatch(VehicleType.VTOL, 1) is None  # a QuadPlane says FIXED_WING
    assert autopilot_mismatch(VehicleType.VTOL, 2) is not None
    assert autopilot_mismatch(VehicleType.COPTER, 13) is None  # a hexarotor is a copter
    assert autopilot_mismatch(VehicleType.COPTER, 0) is None  # no HEARTBEAT yet
    assert autopilot_mismatch(VehicleType.ROVER, 11) is not None  # a boat is no rover


def test_a_quadcopter_node_on_a_quadplane_is_flagged() -> None:
    """A node whose identity says quadcopter, paired with an autopilot whose
    HEARTBEAT says fixed wing (a QuadPlane), was flagged nowhere. Real MAVLink bytes
    from a simulated QuadPlane: an alert with both types, the status flag, the error
    in VehicleInfo, the HEARTBEAT type in VehicleInfo, and every mission refused with
    the reason."""
    fleet = FastFleet.build([7], {7: profile(7)})
    v = fleet.vehicles[7]
    v.endpoint = VehicleEndpoint.create("vtol", home=SITL_HOME, now=fleet.now, sysid=7)
    got = fleet.run_until(lambda: v.node.monitor.flags & AlertFlag.AUTOPILOT_MISMATCH, 30.0)
    assert got
    (alert,) = [
        m
        for _, _, m in fleet.published
        if isinstance(m, Alert) and m.code == AlertCode.AUTOPILOT_MISMATCH
    ]
    assert alert.text == "autopilot is PLANE (MAV_TYPE 1), identity COPTER"
    info = v.node.info()
    assert AlertCode.AUTOPILOT_MISMATCH in info.errors and info.mav_type == 1
    fleet.run_for(20.0)  # GPS, EKF and home come: still not ready
    fleet.broadcast(_base_cmd())
    mission = Mission(
        5, GCS, MissionType.TARGET, Geometry.point(37.41, -5.98), selection=Selector.ids(7)
    )
    fleet.broadcast(mission)
    fleet.run_for(1.0)
    (ack,) = [m for _, _, m in fleet.published if isinstance(m, Ack) and m.ref == AckRef.MISSION]
    assert ack.reason == AckReason.NOT_READY and "autopilot is PLANE" in ack.text


def test_the_right_autopilot_is_not_flagged() -> None:
    fleet = FastFleet.build([7], {7: profile(7)})
    v = fleet.vehicles[7]
    fleet.run_for(20.0)
    assert v.node.autopilot.mav_type == 2 and not v.node.monitor.flags
    info = v.node.info()
    assert info.mav_type == 2 and AlertCode.AUTOPILOT_MISMATCH not in info.errors
    # the flight display's fields travel (roll, pitch, the autopilot's sensor bits)
    assert info.sensors_present and info.sensors_health
    back = msgspec.msgpack.decode(msgspec.msgpack.encode(info), type=VehicleInfo)
    assert back == info


def test_long_texts_are_cut_visibly() -> None:
    long = "no landing route: " + "the straight leg crosses no-fly zone 12 " * 3
    cut = short_text(long)
    assert len(cut) <= TEXT_LIMIT and cut.endswith("…") and cut.startswith("no landing route")
    assert short_text("held") == "held"
    assert len(short_text("x" * 200)) == TEXT_LIMIT


def _update(state: object) -> object:
    from swarm_node.core.node import AutopilotUpdate

    return AutopilotUpdate(state)  # type: ignore[arg-type]


def _base_cmd() -> object:
    from swarm_proto import Command, CommandArgs, CommandKind, GeoPoint

    return Command(
        GCS,
        1,
        CommandKind.SET_BASE,
        Selector(),
        CommandArgs(point=GeoPoint(37.4112, -5.9889, 10.0)),
    )
