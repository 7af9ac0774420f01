"""The ground station against six simulated vehicles and their node processes on
127.0.0.1: every command reaches the vehicles it names (--all,
--fleet, --id) and reports each one's answer, vehicles that start after `gcs` too;
zones are acknowledged, listed, exported and withdrawn; save / load; the monitoring
commands' JSON. Each `gcs` here is the command line as an operator runs it
(`gcs_cli.app.run`, a fresh ground station session per command)."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import threading
from collections.abc import Iterator
from pathlib import Path

import pytest

from gcs_cli.app import run
from swarm_proto import Ack, AckReason, AckRef, Command, VehicleInfo, VehicleType
from swarm_proto.session import SwarmBus, ZenohSettings
from swarm_proto.topics import ACK, COMMAND
from swarm_sim.core import SITL_HOME
from swarm_sim.runtime import VehicleSpec
from swarm_sim.runtime.server import spread_homes
from tests.swarm_node.processes import peers_of, plain_session, served, start_node, stop, wait_until

pytestmark = pytest.mark.network

FIRST = (1, 2, 3, 7)  # three VTOLs and a quadcopter (the seed database's types)
LATE = (8, 9)  # quadcopters started while the ground station is at work
MODEL = {1: "vtol", 2: "vtol", 3: "vtol", 7: "copter", 8: "copter", 9: "copter"}


class Swarm:
    def __init__(self, router: str, swarm: str, tmp: Path, ports: dict[int, int]) -> None:
        self.router, self.swarm, self.tmp, self.ports = router, swarm, tmp, ports
        self.procs: dict[int, subprocess.Popen[bytes]] = {}

    def start(self, vid: int) -> subprocess.Popen[bytes]:
        p = start_node(
            vid,
            self.router,
            self.swarm,
            "--autopilot",
            f"tcp:127.0.0.1:{self.ports[vid]}",
            log=self.tmp / f"node{vid}.log",
        )
        self.procs[vid] = p
        return p

    def alive(self, vid: int, timeout: float = 40.0) -> bool:
        watcher = plain_session(self.router)
        try:
            return (
                wait_until(lambda: peers_of(watcher, self.swarm, vid) is not None, timeout)
                is not None
            )
        finally:
            watcher.close()

    def gcs(self, capsys: pytest.CaptureFixture[str], *args: str) -> tuple[int, str, str]:
        code = run(["--connect", self.router, "--swarm", self.swarm, *args])
        out, err = capsys.readouterr()
        return code, out, err


@pytest.fixture
def swarm(zenoh_router: str, swarm_db: Path, tmp_path: Path) -> Iterator[Swarm]:
    ids = [*FIRST, *LATE]
    homes = spread_homes(SITL_HOME, len(ids), 40.0)
    specs = {
        vid: VehicleSpec(MODEL[vid], port=0, sysid=vid, home=homes[i]) for i, vid in enumerate(ids)
    }
    with served(specs) as ports:
        s = Swarm(zenoh_router, f"s{os.getpid()}", tmp_path, ports)
        try:
            for vid in FIRST:
                s.start(vid)
            for vid in FIRST:
                assert s.alive(vid), (tmp_path / f"node{vid}.log").read_text(errors="replace")
            yield s
        finally:
            codes = {}
            for vid, p in s.procs.items():
                os.kill(p.pid, signal.SIGCONT)
                codes[vid] = stop(p)
            for vid in s.procs:
                print(
                    f"--- node {vid}\n"
                    + (tmp_path / f"node{vid}.log").read_text(errors="replace")[-3000:]
                )
            assert all(c == 0 for c in codes.values()), codes


def rows(out: str) -> dict[int, dict]:
    return {r["id"]: r for r in json.loads(out)["vehicles"]}


# addressing and late joiners: test_exchange.py; gcs against a node: test_gcs_commands.py
@pytest.mark.soak
def test_six_vehicles_every_command_and_answer(
    swarm: Swarm, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    s = swarm
    # positions arrive (the simulated EKF takes a few seconds)
    for _ in range(40):
        code, out, _ = s.gcs(capsys, "status", "--json", "--wait", "1.2")
        got = {r["id"]: r for r in json.loads(out)}
        if set(FIRST) <= set(got) and all(
            got[v].get("lat") and got[v]["type"] != "OTHER" for v in FIRST
        ):
            break
    assert set(FIRST) <= set(got) and got[1]["type"] == "VTOL" and got[7]["type"] == "COPTER"

    # a vehicle named with --id that starts after the command was sent is waited for
    bus = SwarmBus.open(ZenohSettings(mode="client", connect=(s.router,)), s.swarm)
    sent = threading.Event()
    bus.subscribe(COMMAND, lambda c, k: sent.set() if isinstance(c, Command) else None)
    try:
        result: dict[str, object] = {}
        t = threading.Thread(
            target=lambda: result.update(
                r=run(
                    [
                        "--connect",
                        s.router,
                        "--swarm",
                        s.swarm,
                        "cmd",
                        "activate",
                        "--id",
                        "8",
                        "--timeout",
                        "30",
                        "--json",
                    ]
                )
            )
        )
        t.start()
        assert sent.wait(20)
        s.start(8)  # only now
        t.join(60)
        out = capsys.readouterr().out
        assert result["r"] == 0, out
        assert rows(out)[8]["answer"] == "accepted"

        # --all with a vehicle that starts while the command waits: a vehicle 60 is alive
        # (its liveliness token and VehicleInfo) but never answers, so the command is
        # still waiting when node 9 comes alive; 9 is reached, 60 reported silent
        sent.clear()
        mute = SwarmBus.open(ZenohSettings(mode="client", connect=(s.router,)), s.swarm)
        mute.declare_alive(60)
        mute.publish(VehicleInfo(60, VehicleType.COPTER, "Generic Quadcopter", "MUTE"))
        seqs: list[int] = []
        bus.subscribe(COMMAND, lambda c, k: seqs.append(c.seq))

        def late_no(a: Ack, key: str) -> None:  # 60 refuses once 9 has answered
            if a.vehicle_id == 9 and a.ref == AckRef.COMMAND and a.ref_id in seqs:
                mute.publish(
                    Ack(
                        60,
                        a.issuer_id,
                        AckRef.COMMAND,
                        a.ref_id,
                        False,
                        AckReason.BUSY,
                        "busy with a test",
                    )
                )

        mute.subscribe(ACK, late_no)
        try:
            t = threading.Thread(
                target=lambda: result.update(
                    r=run(
                        [
                            "--connect",
                            s.router,
                            "--swarm",
                            s.swarm,
                            "cmd",
                            "set-base",
                            "--all",
                            "--point",
                            f"{SITL_HOME.lat_deg},{SITL_HOME.lon_deg},{SITL_HOME.alt_m}",
                            "--timeout",
                            "25",
                            "--json",
                        ]
                    )
                )
            )
            t.start()
            assert sent.wait(20)
            s.start(9)
            t.join(60)
        finally:
            mute.close()
        out = capsys.readouterr().out
    finally:
        bus.close()
    answers = rows(out)
    assert result["r"] == 1, out  # 60 refused
    assert set(answers) == {1, 2, 3, 7, 8, 9, 60}, out
    assert all(answers[v]["answer"] == "accepted" for v in (1, 2, 3, 7, 8, 9)), out
    assert answers[9]["notes"] == ["joined while waiting"], out
    assert answers[60]["answer"] == "rejected" and answers[60]["reason"] == "BUSY"
    assert answers[60]["why"] == "busy with something that must finish first: busy with a test"
    assert answers[60]["notes"] == ["not in the swarm database"], out

    # --fleet: exactly its members answer
    code, out, _ = s.gcs(capsys, "cmd", "set-fleet", "--fleet-id", "2", "--id", "1", "--id", "7")
    assert code == 0, out
    assert wait_until(lambda: _fleet_known(s, capsys), 20) is not None
    code, out, _ = s.gcs(capsys, "cmd", "rtl", "--fleet", "2", "--yes", "--json")
    answers = rows(out)
    assert set(answers) == {1, 7}, out
    for r in answers.values():  # accepted, or refused with the full reason
        assert r["answer"] == "accepted" or (r["reason"] and r["why"]), out

    # the monitoring commands' JSON
    code, out, _ = s.gcs(capsys, "fleets", "--json", "--wait", "1")
    fleets = {f["fleet"]: f for f in json.loads(out)}
    assert fleets[2]["vehicles"] == [1, 7] and fleets[0]["vehicles"] == [2, 3, 8, 9]
    code, out, _ = s.gcs(capsys, "vehicle", "1", "--json")
    pfd = json.loads(out)
    assert code == 0 and pfd["type"] == "VTOL" and pfd["base"] and pfd["sensors"]["gyro"] == "ok"
    assert pfd["autopilot_mav_type"] == 1 and pfd["autopilot_mismatch"] is None

    # zones: every vehicle acknowledges; listed with who holds it; exported; an unknown
    # id withdrawn is NOT_FOUND from each
    code, out, _ = s.gcs(capsys, "zone", "add", "5", "--circle", "37.4,-5.95,60", "--json")
    assert code == 0 and set(rows(out)) == {1, 2, 3, 7, 8, 9}, out
    code, out, _ = s.gcs(capsys, "zone", "list", "--json")
    (zone,) = json.loads(out)
    assert zone["zone_id"] == 5 and zone["held_by"] == [1, 2, 3, 7, 8, 9]
    code, out, _ = s.gcs(capsys, "zone", "export", str(tmp_path / "zones.geojson"))
    assert code == 0 and json.loads((tmp_path / "zones.geojson").read_text())["features"]
    # the exported file imported again: zone 5 is held as the file has it, left alone;
    # with a file id changed it is a clash, refused with the id named (nothing sent)
    code, out, _ = s.gcs(capsys, "zone", "import", str(tmp_path / "zones.geojson"), "--json")
    assert code == 0 and json.loads(out)["zones"] == [{"zone_id": 5, "action": "unchanged"}], out
    moved = json.loads((tmp_path / "zones.geojson").read_text())
    moved["features"][0]["properties"]["radius_m"] = 70.0
    (tmp_path / "moved.geojson").write_text(json.dumps(moved))
    code, _, err = s.gcs(capsys, "zone", "import", str(tmp_path / "moved.geojson"))
    assert code == 2 and "zone 5 is in force" in err and "--replace" in err, err
    # an id no vehicle holds is not withdrawn (each would keep the withdrawal); --force
    # sends it all the same, and each vehicle answers NOT_FOUND
    code, out, _ = s.gcs(capsys, "zone", "remove", "77")
    assert code == 1 and "zone 77 is held by no vehicle" in out, out
    code, out, _ = s.gcs(capsys, "zone", "remove", "77", "--force", "--json")
    answers = rows(out)
    assert code == 1 and {r["reason"] for r in answers.values()} == {"NOT_FOUND"}, out
    assert len(answers) == 6

    # a mission to the fleet: its members answer, the others are listed apart
    code, out, _ = s.gcs(
        capsys, "mission", "target", "--point", "37.41,-5.98", "--fleet", "2", "--yes", "--json"
    )
    data = json.loads(out)
    assert {r["id"] for r in data["vehicles"]} == {1, 7}, out
    assert set(data["not_addressed"]) <= {2, 3, 8, 9}, out  # those heard before it was over

    # save and load: the base and the zone come back from the vehicles
    state = tmp_path / "state.json"
    code, out, _ = s.gcs(capsys, "save", str(state))
    saved = json.loads(state.read_text())
    assert code == 0 and saved["base"] and [z["zone_id"] for z in saved["zones"]] == [5], out
    assert {v["vehicle_id"] for v in saved["vehicles"]} == {1, 2, 3, 7, 8, 9}
    code, out, _ = s.gcs(capsys, "load", str(state), "--yes")
    assert "set-base: 6 accepted of 6 addressed" in out and "zone 5: 6 accepted" in out, out


def _fleet_known(s: Swarm, capsys: pytest.CaptureFixture[str]) -> bool:
    _code, out, _ = s.gcs(capsys, "status", "--json", "--wait", "0.3", "--fleet", "2")
    return {r["id"] for r in json.loads(out)} == {1, 7}
