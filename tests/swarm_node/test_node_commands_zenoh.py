"""A command from a plain zenoh-python client, answered with the right reason codes;
malformed payloads on every subscribed key are logged and ignored."""

from __future__ import annotations

import os
import queue
from pathlib import Path

import msgspec
import pytest

from swarm_proto import (
    Ack,
    AckReason,
    Command,
    CommandArgs,
    CommandKind,
    Geometry,
    GeoPoint,
    Mission,
    MissionType,
    Selector,
)
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
        assert f"dropped malformed input on bandada/{swarm}/{key}" in text, key
