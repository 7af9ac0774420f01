"""The ground station repeats a command until it is answered: a real Zenoh responder on
127.0.0.1 that ignores the first copy (a frame lost on the radio) still gets the command
through, and its answer to each copy shows once."""

from __future__ import annotations

import threading
import time

import pytest

from gcs_cli.ground import GroundStation
from swarm_proto import (
    Ack,
    AckReason,
    AckRef,
    Command,
    CommandKind,
    Geometry,
    Mission,
    MissionType,
    Selector,
    VehicleInfo,
    VehicleType,
)
from swarm_proto.session import SwarmBus, ZenohSettings
from swarm_proto.topics import COMMAND, MISSION

pytestmark = pytest.mark.network


def test_a_lost_command_is_sent_again_until_answered(zenoh_router: str) -> None:
    settings = ZenohSettings(mode="client", connect=(zenoh_router,))
    copies: list[Command] = []
    heard = threading.Event()
    with SwarmBus.open(settings, "rep") as vehicle:

        def on_command(cmd: Command, key: str) -> None:
            copies.append(cmd)
            if len(copies) >= 2:  # the first copy is "lost"; every later one is answered
                vehicle.publish(Ack(5, cmd.issuer_id, AckRef.COMMAND, cmd.seq, True))
            heard.set()

        vehicle.subscribe(COMMAND, on_command)
        gs = GroundStation(settings, "rep", announce=False)
        gs.repeat_s = 0.2
        try:
            vehicle.publish(VehicleInfo(5, VehicleType.COPTER, "Generic Quad", "U5"))
            assert gs.wait_for(lambda v: 5 in v.vehicle_ids(), 10.0)
            acks = gs.command(CommandKind.RTL, Selector.ids(5), timeout_s=10.0)
            sent = len(copies)
            time.sleep(5 * gs.repeat_s)
            assert len(copies) == sent  # answered: no more repeats
        finally:
            gs.close()
    assert heard.is_set() and len(copies) >= 2
    assert len({(c.seq, c.kind) for c in copies}) == 1  # repeats are the same command
    assert [(a.vehicle_id, a.accepted) for a in acks] == [(5, True)]


def test_a_mission_waits_for_the_addressed_vehicles_not_the_others(zenoh_router: str) -> None:
    """Every vehicle answers a mission; one it does not address answers NOT_ADDRESSED at
    once, and the ground station still waits for the addressed one (here it answers the
    second copy only) and returns both answers."""
    settings = ZenohSettings(mode="client", connect=(zenoh_router,))
    copies: list[Mission] = []
    with SwarmBus.open(settings, "mis") as vehicles:

        def on_mission(m: Mission, key: str) -> None:
            copies.append(m)
            vehicles.publish(
                Ack(6, m.issuer_id, AckRef.MISSION, m.mission_id, False, AckReason.NOT_ADDRESSED)
            )
            if len(copies) >= 2:
                vehicles.publish(Ack(5, m.issuer_id, AckRef.MISSION, m.mission_id, True))

        vehicles.subscribe(MISSION, on_mission)
        gs = GroundStation(settings, "mis", announce=False)
        gs.repeat_s = 0.2
        try:
            # as vehicles do, said again until heard: the station's subscription may not
            # have reached the router when the first one goes out
            end = time.monotonic() + 30.0  # a loaded host may take seconds; heard in ms
            while not gs.wait_for(lambda v: {5, 6} <= set(v.vehicle_ids()), 0.2):
                assert time.monotonic() < end, "the ground station never heard 5 and 6"
                for vid in (5, 6):
                    vehicles.publish(
                        VehicleInfo(vid, VehicleType.COPTER, "Generic Quad", f"U{vid}")
                    )
            mission = Mission(
                77,
                gs.gcs_id,
                MissionType.OBJECTIVE,
                Geometry.point(37.4, -6.0),
                selection=Selector.ids(5),
            )
            acks = gs.mission(mission, timeout_s=10.0)
        finally:
            gs.close()
    assert len(copies) >= 2
    assert sorted((a.vehicle_id, a.reason) for a in acks) == [
        (5, AckReason.OK),
        (6, AckReason.NOT_ADDRESSED),
    ]


def test_the_ground_station_does_not_wait_for_itself(zenoh_router: str) -> None:
    """Its own liveliness token is not a vehicle: a command to ALL returns once the
    vehicles answered, not at the timeout."""
    settings = ZenohSettings(mode="client", connect=(zenoh_router,))
    with SwarmBus.open(settings, "self") as vehicle:
        vehicle.subscribe(
            COMMAND,
            lambda cmd, key: vehicle.publish(Ack(5, cmd.issuer_id, AckRef.COMMAND, cmd.seq, True)),
        )
        gs = GroundStation(settings, "self")  # announces itself: token and VehicleInfo
        try:
            # at once, before its own VehicleInfo (1 s) could say it is a ground station;
            # sent again every 0.2 s as a vehicle does (one sent before the ground
            # station's subscription reached the router, on a loaded host, was lost)
            deadline = time.monotonic() + 10.0
            seen = False
            while not seen and time.monotonic() < deadline:
                vehicle.publish(VehicleInfo(5, VehicleType.COPTER, "Generic Quad", "U5"))
                seen = gs.wait_for(lambda v: 5 in v.vehicle_ids(), 0.2)
            assert seen
            assert gs.snapshot().vehicle_ids() == [5]
            t0 = time.monotonic()
            acks = gs.command(CommandKind.ACTIVATE, timeout_s=20.0)
            took = time.monotonic() - t0
        finally:
            gs.close()
    assert [(a.vehicle_id, a.accepted) for a in acks] == [(5, True)]
    assert took < 10.0  # generous: it returns in milliseconds; the timeout is 20 s


def test_discovery_asks_again_while_nobody_answers(zenoh_router: str) -> None:
    """A liveliness query that finds nobody is asked again within the discovery window
    (a fresh client session under load got an empty answer at once right after a node
    restart: `gcs declared` said "no vehicle alive to ask"). Here the vehicle comes
    alive 0.6 s into the window."""
    settings = ZenohSettings(mode="client", connect=(zenoh_router,))
    with SwarmBus.open(settings, "disc") as vehicle:
        gs = GroundStation(settings, "disc", announce=False)
        timer = threading.Timer(0.6, lambda: vehicle.declare_alive(6))
        try:
            timer.start()
            t0 = time.monotonic()
            found = gs.discover(window_s=3.0)
            took = time.monotonic() - t0
        finally:
            timer.cancel()
            gs.close()
    assert found == {6}, (found, took)
