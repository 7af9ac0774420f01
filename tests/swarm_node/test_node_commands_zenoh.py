"""A command from a plain zenoh-python client, answered with the right reason codes;
malformed payloads on every subscribed key are logged and ignored."""

from __future__ import annotations

import os
import queue
import time
from collections.abc import Callable
from pathlib import Path

import msgspec
import pytest

from swarm_proto import (
    Ack,
    AckReason,
    Alert,
    AlertCode,
    Command,
    CommandArgs,
    CommandKind,
    Geometry,
    GeoPoint,
    Mission,
    MissionType,
    Selector,
    SelectorKind,
    SystemClock,
    VehicleInfo,
)
from swarm_sim.runtime import VehicleServer, VehicleSpec
from tests.conftest import free_tcp_port
from tests.swarm_node.processes import peers_of, plain_session, start_node, stop, wait_until

pytestmark = pytest.mark.network
GCS = 900


def test_commands_and_malformed_input(zenoh_router: str, tmp_path: Path, swarm_db: Path) -> None:
    swarm = f"c{os.getpid()}"
    log = tmp_path / "node.log"
    proc = start_node(4, zenoh_router, swarm, log=log)
    client = plain_session(zenoh_router)
    acks: queue.Queue[Ack] = queue.Queue()
    sub = client.declare_subscriber(
        f"bandada/{swarm}/vehicle/4/ack",
        lambda s: acks.put(msgspec.msgpack.decode(s.payload.to_bytes(), type=Ack)),
    )
    try:
        assert wait_until(lambda: peers_of(client, swarm, 4) is not None, timeout=30) is not None

        # garbage on every key the node subscribes to
        for key in (
            "vehicle/77/status",
            "vehicle/77/info",
            "cmd/900",
            "mission/5",
            "zone/3",
            "fleet/2",
        ):
            client.put(f"bandada/{swarm}/{key}", b"\xc1\xc1 garbage")
            client.put(f"bandada/{swarm}/{key}", msgspec.msgpack.encode({"lat_deg": float("nan")}))

        def send(
            seq: int, kind: CommandKind, target: Selector | None = None, **args: object
        ) -> Ack:
            cmd = Command(GCS, seq, kind, target or Selector(), CommandArgs(**args))  # type: ignore[arg-type]
            client.put(f"bandada/{swarm}/cmd/{GCS}", msgspec.msgpack.encode(cmd))
            while True:
                ack = acks.get(timeout=20)
                if ack.ref_id == seq:
                    return ack

        ok = send(1, CommandKind.SET_BASE, point=GeoPoint(37.41, -5.99, 10.0))
        assert ok.accepted and ok.reason == AckReason.OK and ok.issuer_id == GCS
        assert send(2, CommandKind.RTL).reason == AckReason.NOT_READY  # no autopilot link
        assert send(3, CommandKind.SET_BASE).reason == AckReason.INVALID  # no point
        assert send(4, CommandKind.CANCEL_MISSION, mission_id=8).reason == AckReason.NOT_FOUND
        assert send(5, CommandKind.ACTIVATE, Selector.ids(4, 5)).accepted
        mission = Mission(
            21, GCS, MissionType.OBJECTIVE, Geometry.point(37.42, -5.98), selection=Selector.ids(4)
        )
        client.put(f"bandada/{swarm}/mission/21", msgspec.msgpack.encode(mission))
        ack = acks.get(timeout=20)
        assert (ack.ref_id, ack.accepted, ack.reason) == (21, False, AckReason.HOME_NOT_SET)
        # every node answers every mission: one not for vehicle 4 is NOT_ADDRESSED
        other = msgspec.structs.replace(mission, mission_id=22, selection=Selector.ids(5))
        client.put(f"bandada/{swarm}/mission/22", msgspec.msgpack.encode(other))
        ack = acks.get(timeout=20)
        assert (ack.ref_id, ack.accepted, ack.reason) == (22, False, AckReason.NOT_ADDRESSED)
        # vehicles chosen by voting (QUANTITY): not implemented, said so
        voted = Selector(SelectorKind.QUANTITY, quantity=1)
        assert send(6, CommandKind.RTL, voted).reason == AckReason.UNSUPPORTED
        assert proc.poll() is None
    finally:
        sub.undeclare()
        client.close()
        assert stop(proc) == 0
    text = log.read_text()
    for key in (
        "vehicle/77/status",
        "vehicle/77/info",
        "cmd/900",
        "mission/5",
        "zone/3",
        "fleet/2",
    ):
        # one line per topic (its MALFORMED_INPUT alert), not one per payload
        assert text.count(f"MALFORMED_INPUT: 1 dropped, first {key}: ") == 1, key
    assert text.count("MALFORMED_INPUT") == 6, text


def test_a_vehicle_with_a_base_but_not_ready_rejects_a_mission(
    zenoh_router: str, tmp_path: Path, swarm_db: Path
) -> None:
    """A node whose autopilot has a home, then falls silent: with a base set it answers a
    mission NOT_READY (a plain zenoh-python client on 127.0.0.1)."""
    swarm = f"r{os.getpid()}"
    log = tmp_path / "node7.log"
    spec = VehicleSpec("copter", port=free_tcp_port(), sysid=7)
    server = VehicleServer([spec], SystemClock())
    server.start_thread()
    proc = start_node(
        7, zenoh_router, swarm, "--autopilot", f"tcp:127.0.0.1:{spec.tcp_port}", log=log
    )
    client = plain_session(zenoh_router)
    heard: queue.Queue[object] = queue.Queue()
    subs = [
        client.declare_subscriber(
            f"bandada/{swarm}/vehicle/7/{what}",
            lambda s, cls=cls: heard.put(msgspec.msgpack.decode(s.payload.to_bytes(), type=cls)),
        )
        for what, cls in (("ack", Ack), ("info", VehicleInfo), ("alert", Alert))
    ]

    def wait_for(pred: Callable[[object], bool], timeout: float, what: str) -> object:
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            try:
                msg = heard.get(timeout=0.5)
            except queue.Empty:
                continue
            if pred(msg):
                return msg
        pytest.fail(f"never saw {what}")

    try:
        assert wait_until(lambda: peers_of(client, swarm, 7) is not None, timeout=30) is not None
        wait_for(lambda m: isinstance(m, VehicleInfo) and m.home is not None, 60, "a home")
        server.close()  # the autopilot falls silent: the vehicle is no longer ready
        wait_for(
            lambda m: isinstance(m, Alert) and m.code == AlertCode.AUTOPILOT_LINK_LOSS,
            20,
            "the link loss alert",
        )
        base = Command(
            GCS, 1, CommandKind.SET_BASE, args=CommandArgs(point=GeoPoint(37.41, -5.99, 10.0))
        )
        client.put(f"bandada/{swarm}/cmd/{GCS}", msgspec.msgpack.encode(base))
        ok = wait_for(lambda m: isinstance(m, Ack) and m.ref_id == 1, 20, "SET_BASE's ack")
        assert isinstance(ok, Ack) and ok.accepted
        mission = Mission(
            31, GCS, MissionType.OBJECTIVE, Geometry.point(37.42, -5.98), selection=Selector.ids(7)
        )
        client.put(f"bandada/{swarm}/mission/31", msgspec.msgpack.encode(mission))
        ack = wait_for(lambda m: isinstance(m, Ack) and m.ref_id == 31, 20, "the mission's ack")
        assert isinstance(ack, Ack)
        assert (ack.accepted, ack.reason) == (False, AckReason.NOT_READY), log.read_text()
    finally:
        for sub in subs:
            sub.undeclare()
        client.close()
        server.close()
        assert stop(proc) == 0
