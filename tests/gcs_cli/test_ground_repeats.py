"""The ground station repeats a command until it is answered: a real Zenoh responder on
127.0.0.1 that ignores the first copy (a frame lost on the radio) still gets the command
through, and its answer to each copy shows once."""

from __future__ import annotations

import threading
import time

import pytest

from gcs_cli.ground import GroundStation
from swarm_proto import Ack, AckRef, Command, CommandKind, Selector, VehicleInfo, VehicleType
from swarm_proto.session import SwarmBus, ZenohSettings
from swarm_proto.topics import COMMAND

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
