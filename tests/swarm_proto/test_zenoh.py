"""Real Zenoh sessions on 127.0.0.1: what bandada publishes, plain zenoh-python and
msgspec can read; malformed payloads are dropped and counted; liveliness tracks nodes."""

from __future__ import annotations

import json
import queue
import threading

import msgspec
import pytest
import zenoh

from swarm_proto import Command, CommandKind, VehicleStatus
from swarm_proto.session import SwarmBus, ZenohSettings
from swarm_proto.topics import COMMAND, STATUS

pytestmark = pytest.mark.network


def plain_session(endpoint: str) -> zenoh.Session:
    """A session configured with nothing but zenoh-python, as a third party would."""
    conf = zenoh.Config()
    conf.insert_json5("mode", '"peer"')
    conf.insert_json5("scouting/multicast/enabled", "false")
    conf.insert_json5("connect/endpoints", json.dumps([endpoint]))
    return zenoh.open(conf)


def test_plain_zenoh_subscriber_decodes_status(zenoh_router: str) -> None:
    got: queue.Queue[tuple[str, dict]] = queue.Queue()
    plain = plain_session(zenoh_router)
    sub = plain.declare_subscriber(
        "bandada/default/vehicle/*/status",
        lambda s: got.put((str(s.key_expr), msgspec.msgpack.decode(s.payload.to_bytes()))),
    )
    bus = SwarmBus.open(ZenohSettings(connect=(zenoh_router,)))
    try:
        status = VehicleStatus(
            vehicle_id=42,
            time_unix_s=1.75e9,
            lat_deg=37.4112,
            lon_deg=-5.9889,
            alt_msl_m=110.0,
            alt_rel_m=100.0,
            battery_pct=87,
        )
        deadline = threading.Event()
        key, payload = None, None
        for _ in range(50):  # discovery takes a moment: publish until heard
            bus.publish(status)
            try:
                key, payload = got.get(timeout=0.1)
                break
            except queue.Empty:
                continue
        deadline.set()
        assert key == "bandada/default/vehicle/42/status"
        assert payload is not None
        assert payload["lat_deg"] == 37.4112 and payload["battery_pct"] == 87
        assert msgspec.convert(payload, VehicleStatus) == status
    finally:
        sub.undeclare()
        bus.close()
        plain.close()


def test_malformed_payloads_are_counted_and_dropped(zenoh_router: str) -> None:
    received: queue.Queue[Command] = queue.Queue()
    bad: queue.Queue[str] = queue.Queue()
    listener = SwarmBus.open(
        ZenohSettings(connect=(zenoh_router,)), on_bad_input=lambda k, e: bad.put(k)
    )
    sender = plain_session(zenoh_router)
    try:
        listener.subscribe(COMMAND, lambda m, k: received.put(m))
        good = Command(issuer_id=900, seq=1, kind=CommandKind.RTL)
        got = None
        for _ in range(200):  # until the subscription has reached the sender
            sender.put("bandada/default/cmd/900", b"\xc1 not msgpack")
            sender.put("bandada/default/cmd/900", msgspec.msgpack.encode({"issuer_id": 0}))
            sender.put("bandada/default/cmd/900", msgspec.msgpack.encode(good))
            try:
                got = received.get(timeout=0.1)
                break
            except queue.Empty:
                continue
        assert got == good
        # the subscription may have reached the sender between the puts of a round:
        # one more round, all three heard in order once its good command is
        after = Command(issuer_id=900, seq=2, kind=CommandKind.RTL)
        before = listener.bad_input["command"]
        sender.put("bandada/default/cmd/900", b"\xc1 not msgpack")
        sender.put("bandada/default/cmd/900", msgspec.msgpack.encode({"issuer_id": 0}))
        sender.put("bandada/default/cmd/900", msgspec.msgpack.encode(after))
        while got != after:
            got = received.get(timeout=30)  # a loaded host may hold Zenoh's thread a while
        assert bad.get(timeout=2) == "bandada/default/cmd/900"
        assert listener.bad_input["command"] >= before + 2
    finally:
        listener.close()
        sender.close()


def test_liveliness_reports_join_and_leave(zenoh_router: str) -> None:
    events: queue.Queue[tuple[int, bool]] = queue.Queue()
    watcher = SwarmBus.open(ZenohSettings(connect=(zenoh_router,)))
    node = SwarmBus.open(ZenohSettings(connect=(zenoh_router,)))
    try:
        watcher.watch_alive(lambda n, alive: events.put((n, alive)))
        node.declare_alive(17)
        assert events.get(timeout=5) == (17, True)
        node.close()
        assert events.get(timeout=5) == (17, False)
    finally:
        node.close()
        watcher.close()


def test_subscribers_survive_a_failing_handler(zenoh_router: str) -> None:
    calls: queue.Queue[int] = queue.Queue()

    def handler(msg: VehicleStatus, key: str) -> None:
        calls.put(msg.vehicle_id)
        raise RuntimeError("bug in a handler")

    bus = SwarmBus.open(ZenohSettings(connect=(zenoh_router,)))
    try:
        bus.subscribe(STATUS, handler)
        for vid in (1, 2):
            st = VehicleStatus(
                vehicle_id=vid, time_unix_s=1.0, lat_deg=0, lon_deg=0, alt_msl_m=0, alt_rel_m=0
            )
            for _ in range(50):
                bus.publish(st)
                try:
                    if calls.get(timeout=0.1) == vid:
                        break
                except queue.Empty:
                    continue
            else:
                pytest.fail(f"status {vid} never delivered")
    finally:
        bus.close()


def test_a_loopback_simulation_listens_on_loopback_only() -> None:
    from swarm_proto.session import zenoh_config

    sim = zenoh_config(ZenohSettings(connect=("tcp/127.0.0.1:7447",)))
    assert "127.0.0.1" in sim.get_json("listen/endpoints")
    field = zenoh_config(ZenohSettings(connect=("tcp/192.168.1.10:7447",)))
    assert "127.0.0.1" not in field.get_json("listen/endpoints")
    explicit = zenoh_config(
        ZenohSettings(connect=("tcp/127.0.0.1:7447",), listen=("tcp/0.0.0.0:7448",))
    )
    assert "0.0.0.0:7448" in explicit.get_json("listen/endpoints")


def test_the_keyspace_doc_example_runs_as_written(zenoh_router: str, tmp_path) -> None:
    """docs/keyspace.md's subscriber, run as a user would (only the endpoint changed)."""
    import re
    import subprocess
    import sys

    from tests.conftest import REPO

    doc = (REPO / "docs" / "keyspace.md").read_text()
    block = re.search(r"```python\n(.*?)```", doc, re.S)
    assert block is not None and "tcp/127.0.0.1:7447" in block.group(1)
    script = tmp_path / "example.py"
    script.write_text(block.group(1).replace("tcp/127.0.0.1:7447", zenoh_router))
    proc = subprocess.Popen(
        [sys.executable, str(script)],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    lines: queue.Queue[str] = queue.Queue()
    reader = threading.Thread(
        target=lambda: [lines.put(x) for x in iter(proc.stdout.readline, "")],  # type: ignore[union-attr]
        daemon=True,
    )
    reader.start()
    bus = SwarmBus.open(ZenohSettings(connect=(zenoh_router,)))
    try:
        status = VehicleStatus(
            vehicle_id=42,
            time_unix_s=1.75e9,
            lat_deg=37.4112,
            lon_deg=-5.9889,
            alt_msl_m=110.0,
            alt_rel_m=100.0,
        )
        line = ""
        for _ in range(150):  # the example's start-up and discovery take a moment
            bus.publish(status)
            try:
                line = lines.get(timeout=0.1)
                break
            except queue.Empty:
                assert proc.poll() is None, proc.stderr.read()  # type: ignore[union-attr]
        printed = line[line.index("bandada/") :]  # after input()'s prompt, if it shares the line
        assert printed.split() == [
            "bandada/default/vehicle/42/status",
            "37.4112",
            "-5.9889",
            "110.0",
        ]
        proc.stdin.write("\n")  # type: ignore[union-attr]
        proc.stdin.flush()  # type: ignore[union-attr]
        assert proc.wait(timeout=30) == 0  # and it exits cleanly: no hang at close
    finally:
        bus.close()
        if proc.poll() is None:
            proc.kill()
        proc.wait()
