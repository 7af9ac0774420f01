"""Identity and input on the LAN over real node processes on loopback Zenoh, each linked
over MAVLink to a simulated quadcopter: an impostor in a running vehicle's name, two
nodes started with one id, a garbage run (docs/security.md). The logic is tested with
injected time in test_identity.py and tests/swarm_proto/test_intake.py."""

from __future__ import annotations

import math
import queue
import subprocess
import time
from collections import Counter
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import msgspec
import pytest
import zenoh

from gcs_cli.ground import GroundStation
from swarm_proto import (
    Ack,
    AckReason,
    Alert,
    AlertCode,
    Command,
    CommandKind,
    FsmState,
    Mission,
    MissionParams,
    MissionState,
    MissionType,
    SwarmView,
    VehicleStatus,
    lan,
)
from swarm_proto.intake import parse_source
from swarm_proto.session import ZenohSettings
from swarm_sim.core import SITL_HOME
from swarm_sim.runtime import VehicleSpec, spread_homes
from tests.swarm_node.processes import nodes, plain_session, served, start_node, stop, wait_until
from tests.swarm_node.test_mission_processes import Watch, activate, send, swarm, wavy_area

pytestmark = pytest.mark.network
__all__ = ["swarm"]  # fixture


@pytest.fixture
def vehicles(request: pytest.FixtureRequest) -> Iterator[dict[int, str]]:
    """Simulated quadcopters by MAVLink system id (= the node id the database gives)."""
    ids: list[int] = request.param
    homes = spread_homes(SITL_HOME, len(ids), 30.0)
    specs = {
        vid: VehicleSpec("copter", instance=i, port=0, home=homes[i], sysid=vid)
        for i, vid in enumerate(ids)
    }
    with served(specs) as ports:
        yield {vid: f"tcp:127.0.0.1:{port}" for vid, port in ports.items()}


class Alerts:
    """Every alert of the swarm with the session that published it."""

    def __init__(self, session: Any, swarm: str) -> None:
        self.got: queue.Queue[tuple[float, str, Alert]] = queue.Queue()
        self.seen: list[tuple[float, str, Alert]] = []

        def on(s: Any) -> None:
            att = s.attachment.to_bytes() if s.attachment is not None else None
            alert = msgspec.msgpack.decode(s.payload.to_bytes(), type=Alert)
            self.got.put((time.monotonic(), parse_source(att).zid, alert))

        self.sub = session.declare_subscriber(f"bandada/{swarm}/vehicle/*/alert", on)

    def drain(self) -> list[tuple[float, str, Alert]]:
        while True:
            try:
                self.seen.append(self.got.get_nowait())
            except queue.Empty:
                return self.seen

    def of(self, code: AlertCode) -> list[tuple[float, str, Alert]]:
        return [x for x in self.drain() if x[2].code == code]


def views(session: Any, swarm: str, node: int) -> list[SwarmView]:
    """Every answer on a node's peers key (two nodes with one id both answer)."""
    out = []
    key = f"bandada/{swarm}/vehicle/{node}/peers"
    for reply in session.get(key, timeout=1.0, consolidation=zenoh.ConsolidationMode.NONE):
        if reply.ok is not None:
            out.append(msgspec.msgpack.decode(reply.ok.payload.to_bytes(), type=SwarmView))
    return out


def listed(session: Any, swarm: str, ids: list[int]) -> bool:
    for vid in ids:
        v = views(session, swarm, vid)
        if not v or sorted(p.node_id for p in v[0].peers) != [i for i in ids if i != vid]:
            return False
    return True


@pytest.mark.parametrize("vehicles", [[7, 8]], indirect=True)
def test_an_impostor_is_noticed_and_bad_input_is_alerted(
    zenoh_router: str, swarm: str, vehicles: dict[int, str], swarm_db: Path
) -> None:
    client = plain_session(zenoh_router)
    alerts = Alerts(client, swarm)
    watch = Watch(client, swarm)
    gs: GroundStation | None = None
    tokens: list[Any] = []
    try:
        with nodes([7, 8], zenoh_router, swarm, autopilots=vehicles):
            assert wait_until(lambda: listed(client, swarm, [7, 8]), timeout=90) is not None
            gs = GroundStation(ZenohSettings(connect=(zenoh_router,)), swarm, announce=False)
            assert gs.wait_for(lambda v: 7 in v.status and 8 in v.status, 30)
            honest = gs.snapshot().status[7]

            # a plain zenoh-python process speaks as vehicle 7 (a status and a token) and
            # declares a token for 55, which does not exist
            fake = VehicleStatus(7, time.time(), 37.5, -5.9, 110.0, 100.0)
            fake = msgspec.structs.replace(fake, fsm_state=FsmState.EMERGENCY)
            tokens = [
                client.liveliness().declare_token(f"bandada/{swarm}/alive/{i}") for i in (7, 55)
            ]
            t0 = time.monotonic()
            while time.monotonic() - t0 < 5.0 and not alerts.of(AlertCode.IDENTITY_CONFLICT):
                client.put(f"bandada/{swarm}/vehicle/7/status", lan.encode(fake))
                time.sleep(0.2)
            (t_alert, _, alert), *_ = alerts.of(AlertCode.IDENTITY_CONFLICT)
            # the requirement is 2 s; the path is one Zenoh hop and the node's
            # inbox, which a loaded 2-core host serves within a few hundred ms
            assert t_alert - t0 <= 2.0, t_alert - t0
            assert alert.vehicle_id == 7 and alert.text == "id 7 also used by a foreign publisher"

            def untrusted_at_8() -> bool:
                v = views(client, swarm, 8)
                return bool(v) and any(p.node_id == 7 and p.untrusted for p in v[0].peers)

            assert wait_until(untrusted_at_8, timeout=5) is not None
            (view8,) = views(client, swarm, 8)
            assert [p.node_id for p in view8.peers] == [7]  # no 55: a token alone is nobody
            assert 7 in gs.snapshot().untrusted
            assert gs.snapshot().status[7].fsm_state == honest.fsm_state  # not the fake's

            # a command whose key names another issuer than its payload, and garbage
            base = time.monotonic()
            n_alerts = len(alerts.of(AlertCode.MALFORMED_INPUT))
            wrong = Command(901, 77, CommandKind.ACTIVATE)
            for data, key in (
                (lan.encode(wrong), "cmd/555"),
                (b"\xc1 not msgpack", "vehicle/8/status"),
                (bytes(10_000_000), "vehicle/8/status"),
                (msgspec.msgpack.encode({"mission_id": math.nan}), "mission/5"),
                (b"\xc1", "cmd/555"),
            ):
                for _ in range(3):
                    client.put(f"bandada/{swarm}/{key}", data)
            time.sleep(3.0)
            new = alerts.of(AlertCode.MALFORMED_INPUT)[n_alerts:]
            per = Counter(
                (a.vehicle_id, a.text.split("first ")[1].split(":")[0]) for _, _, a in new
            )
            assert per == {
                (vid, key): 1
                for vid in (7, 8)
                for key in ("cmd/555", "vehicle/8/status", "mission/5")
            }, per  # one per topic and node (the second cmd/555 payload waits a minute)
            statuses = Counter(
                s.vehicle_id for t, s in list(watch.statuses.queue) if base < t < base + 3.0
            )
            assert min(statuses[7], statuses[8]) >= 10, statuses  # 5 Hz kept (a loaded host)
            assert not [a for a in watch.acks.queue if a.ref_id == 77]  # never answered
            (view7,) = views(client, swarm, 7)
            reasons = {d.reason for d in view7.dropped}
            assert {"key_mismatch", "malformed", "invalid"} <= reasons, view7.dropped
            assert view7.identity_conflict.startswith("id 7 also used by a foreign publisher")
    finally:
        for t in tokens:
            t.undeclare()
        if gs is not None:
            gs.close()
        alerts.sub.undeclare()
        watch.close()
        client.close()


# another session with our id, named by its session and airframe: test_identity.py
# (pure); identity over real processes and Zenoh: the impostor test above
@pytest.mark.soak
@pytest.mark.parametrize("vehicles", [[7, 8, 10]], indirect=True)
def test_two_nodes_with_one_id_both_alert_and_neither_flies(
    zenoh_router: str, swarm: str, vehicles: dict[int, str], swarm_db: Path, tmp_path: Path
) -> None:
    """A second node 7 on vehicle 7's own autopilot (another database), and a second node
    8 on another airframe (MAVLink system id 10)."""
    client = plain_session(zenoh_router)
    alerts = Alerts(client, swarm)
    watch = Watch(client, swarm)
    twins: list[subprocess.Popen[bytes]] = []
    try:
        with nodes([7, 8], zenoh_router, swarm, autopilots={i: vehicles[i] for i in (7, 8)}):
            assert wait_until(lambda: listed(client, swarm, [7, 8]), timeout=90) is not None
            activate(client, swarm, watch, [7, 8])
            other_db = str(tmp_path / "other.db")
            twins = [
                start_node(7, zenoh_router, swarm, "--autopilot", vehicles[7], "--db", other_db),
                start_node(8, zenoh_router, swarm, "--autopilot", vehicles[10]),
            ]

            def both_alerted() -> bool:
                by = {(a.vehicle_id, zid) for _, zid, a in alerts.of(AlertCode.IDENTITY_CONFLICT)}
                return all(len({z for v, z in by if v == vid}) == 2 for vid in (7, 8))

            assert wait_until(both_alerted, timeout=60) is not None

            def mismatch() -> bool:  # once the twin of 8 hears its autopilot
                found = alerts.of(AlertCode.AUTOPILOT_MISMATCH)
                return any("MAVLink system 10" in a.text for _, _, a in found)

            assert wait_until(mismatch, timeout=30) is not None
            # a mission for both: every node in their names refuses it
            area = wavy_area(12, SITL_HOME.lat_deg + 0.002, SITL_HOME.lon_deg, 60.0)
            send(
                client,
                swarm,
                Mission(61, 900, MissionType.AREA, area, MissionParams(altitude_rel_m=20.0)),
            )
            answers: list[Ack] = []
            t_end = time.monotonic() + 20.0
            while len(answers) < 4 and time.monotonic() < t_end:
                try:
                    a = watch.acks.get(timeout=0.5)
                except queue.Empty:
                    continue
                if a.ref_id == 61:
                    answers.append(a)
            assert len(answers) == 4 and not any(a.accepted for a in answers), answers
            # the honest nodes refuse for the conflict (a twin may refuse for an earlier
            # reason of the acceptance order: its autopilot has no home yet)
            for vid in (7, 8):
                assert any(
                    a.vehicle_id == vid
                    and a.reason == AckReason.NOT_READY
                    and a.text.startswith("identity conflict")
                    for a in answers
                ), answers
            time.sleep(3.0)
            flying = [
                s
                for _, s in list(watch.statuses.queue)
                if s.armed or s.mission_state == MissionState.MISSION
            ]
            assert not flying, flying[:3]
            # the honest fleet keeps 7 (untrusted, not lost), as every node 8 sees it
            v8 = views(client, swarm, 8)
            assert len(v8) == 2, v8
            assert all(any(p.node_id == 7 and p.untrusted for p in v.peers) for v in v8), v8
    finally:
        codes = [stop(p) for p in twins]
        alerts.sub.undeclare()
        watch.close()
        client.close()
    assert all(c != -999 for c in codes), codes


@pytest.mark.soak  # the short version above runs by default; this one is the whole run
def test_a_garbage_run_keeps_the_nodes_up_at_5_hz_with_bounded_memory() -> None:
    from bench import identity

    result = identity.run()
    assert result["nodes_up"], result
    assert result["rss_growth_pct"] <= 20.0, result
    assert min(result["status_hz_during"].values()) >= 4.5, result
    # one per topic: the run lasts seconds, under the alarm's minute
    assert max(result["malformed_alerts"].values()) <= len(identity.SUBSCRIBED), result
    assert max(result["log_lines"].values()) <= 20, result
    assert result["conflict_detect_ms"] is not None and result["conflict_detect_ms"] <= 2000
