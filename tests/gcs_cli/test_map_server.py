"""The map's server (gcs_cli/map/server.py) in-process over HTTP, with a real ground
station session on a Zenoh router on 127.0.0.1: no command without the token, nothing
sent for bad input, the page and its WebSocket need the token off loopback, no
WebSocket from another site's page; Leaflet served from the package; `gcs map`'s own
options refused in one line; the replay's clock."""

from __future__ import annotations

import asyncio
import json
import time
from collections.abc import Awaitable, Callable, Iterator
from pathlib import Path

import pytest
from aiohttp import WSServerHandshakeError
from aiohttp.test_utils import TestClient, TestServer

from gcs_cli.app import run
from gcs_cli.ground import GroundStation
from gcs_cli.map.replay import Player, read_flight
from gcs_cli.map.server import Config, Hub, make_app
from swarm_proto import VehicleStatus
from swarm_proto.session import SwarmBus, ZenohSettings
from swarm_proto.topics import COMMAND, ZONE
from swarm_proto.trajectory import TrajectoryError

pytestmark = pytest.mark.network
TOKEN = "test-token-0123456789abcdef"


@pytest.fixture
def station(zenoh_router: str) -> Iterator[tuple[GroundStation, list[object]]]:
    """A ground station, and what a listener on the router hears of commands and zones
    (the map must send nothing it refuses)."""
    gs = GroundStation(ZenohSettings(connect=(zenoh_router,)), "maptest")
    heard: list[object] = []
    bus = SwarmBus.open(ZenohSettings(connect=(zenoh_router,)), "maptest")
    for topic in (COMMAND, ZONE):
        bus.subscribe(topic, lambda m, k: heard.append(m))
    try:
        yield gs, heard
    finally:
        bus.close()
        gs.close()


def serving(
    hub: Hub, test: Callable[[TestClient], Awaitable[None]]
) -> None:  # one event loop per test
    async def main() -> None:
        async with TestClient(TestServer(make_app(hub))) as client:
            await test(client)

    try:
        asyncio.run(main())
    finally:
        hub.close()


def test_no_command_without_the_token_and_nothing_sent_for_bad_input(
    station: tuple[GroundStation, list[object]],
) -> None:
    gs, heard = station
    hub = Hub(Config("127.0.0.1", 0, TOKEN, swarm="maptest"), gs)
    hub.attach()
    rtl = {"type": "command", "kind": "set-base", "point": [37.4, -5.9]}

    async def test(client: TestClient) -> None:
        r = await client.post("/api/send", json={"req": rtl})
        assert r.status == 403 and "token" in (await r.json())["error"]
        r = await client.post("/api/send", json={"req": rtl, "token": "wrong" * 5})
        assert r.status == 403
        r = await client.post("/api/send", data=json.dumps({"req": rtl, "token": TOKEN}))
        assert r.status == 415  # not sent as JSON: a form posted from another page
        bad = {**rtl, "point": [float("nan"), 0.0]}
        r = await client.post(
            "/api/check",
            data=json.dumps({"req": bad, "token": TOKEN}).replace("NaN", '"nan"'),
            headers={"Content-Type": "application/json"},
        )
        body = await r.json()
        assert r.status == 400 and body["error"] == "Invalid value for --point: latitude is nan"
        r = await client.post(
            "/api/send",
            json={"req": {"type": "zone", "polygon": [[0, 0], [1, 1], [0, 1], [1, 0]]}},
            headers={"X-Bandada-Token": TOKEN},
        )
        assert r.status == 400 and "Self-intersection" in (await r.json())["error"]
        # with the token, a good one is checked (its confirmation names the vehicles)
        r = await client.post("/api/check", json={"req": rtl, "token": TOKEN})
        body = await r.json()
        assert body["ok"] and body["question"].startswith("set-base to every vehicle alive")
        zone = {"type": "zone", "circle": [37.4, -5.9, 30]}
        body = await (await client.post("/api/check", json={"req": zone, "token": TOKEN})).json()
        assert body["fixed"] == {"zone_id": 1}  # the id the confirmation names is the one sent
        assert body["question"] == "zone 1 to every vehicle alive (none known alive)?"
        assert body["geometry"] == {"kind": "circle", "points": [[37.4, -5.9]], "radius_m": 30.0}
        # the page and the frames need no token on loopback; the WebSocket sends frames
        assert (await client.get("/")).status == 200
        ws = await client.ws_connect("/ws")
        frame = json.loads((await ws.receive_bytes(timeout=5)).decode())
        assert frame["full"] and frame["mode"] == "live" and frame["epoch"] == 1
        await ws.send_str(json.dumps({"op": "send", "rid": 7, "req": rtl}))
        answer = await ws.receive_json(timeout=5)
        assert answer["rid"] == 7 and not answer["ok"] and "token" in answer["error"]
        await ws.close()

    serving(hub, test)
    time.sleep(1.0)  # anything sent would have reached the listener by now
    assert heard == []


def test_off_loopback_the_page_needs_the_token_and_other_sites_are_refused(
    station: tuple[GroundStation, list[object]],
) -> None:
    gs, _ = station
    hub = Hub(Config("0.0.0.0", 0, TOKEN, swarm="maptest"), gs)

    async def test(client: TestClient) -> None:
        assert (await client.get("/")).status == 403
        assert (await client.get("/config")).status == 403
        with pytest.raises(WSServerHandshakeError):
            await client.ws_connect("/ws")
        assert (await client.get(f"/?token={TOKEN}")).status == 200
        config = await (await client.get(f"/config?token={TOKEN}")).json()
        assert config["commands"] and config["mode"] == "live" and config["tiles"] is None
        with pytest.raises(WSServerHandshakeError) as exc:
            await client.ws_connect(f"/ws?token={TOKEN}", headers={"Origin": "http://evil.test"})
        assert exc.value.status == 403
        ws = await client.ws_connect(f"/ws?token={TOKEN}")
        assert json.loads((await ws.receive_bytes(timeout=5)).decode())["full"]
        await ws.close()
        # Leaflet from the xstatic-leaflet package: served here, no network needed
        r = await client.get("/leaflet/leaflet.js")
        assert r.status == 200 and "Leaflet" in (await r.text())[:400]
        assert (await client.get("/static/map.js")).status == 200

    serving(hub, test)


@pytest.mark.parametrize(
    ("argv", "words"),
    [
        (("map", "--listen", "localhost"), "expected HOST:PORT"),
        (("map", "--listen", "127.0.0.1:99999"), "out of range"),
        (("map", "--tiles", "file:///etc/passwd"), "a tile URL is http(s)"),
        (("map", "--tiles", "http://tiles.local/{z}/{x}.png"), "a tile URL is"),
        (("map", "--trail", "nan"), "nan is not a number"),
        (("map", "--replay", "/nonexistent/flight.csv"), "cannot read"),
    ],
)
def test_bad_options_are_one_line_and_exit_2(
    argv: tuple[str, ...], words: str, capsys: pytest.CaptureFixture[str]
) -> None:
    assert run(["--connect", "tcp/127.0.0.1:1", *argv]) == 2
    err = capsys.readouterr().err.strip()
    assert words in err and "\n" not in err, err


def test_a_taken_port_is_one_line(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    import socket

    flight = tmp_path / "flight.csv"
    flight.write_text("time_s,vehicle,lat,lon,alt_m\n0,1,37.4,-5.9,100\n1,1,37.41,-5.9,100\n")
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen()
        port = s.getsockname()[1]
        assert run(["map", "--replay", str(flight), "--listen", f"127.0.0.1:{port}"]) == 2
    err = capsys.readouterr().err.strip()
    assert f"cannot listen on 127.0.0.1:{port}" in err and "\n" not in err


def flight_csv(path: Path) -> Path:
    rows = ["time_s,vehicle,lat,lon,alt_m,alt_rel_m,groundspeed_m_s,heading_deg,battery_pct,fsm"]
    for k in range(11):
        rows.append(f"{100 + k},1,{37.4 + k * 1e-4},-5.9,110,100,11.1,0,{90 - k},GO_MISSION")
        rows.append(f"{100 + k},2,37.4,{-5.9 + k * 1e-4},110,100,8.8,90,80,PLAN")
    path.write_text("\n".join(rows) + "\n")
    return path


def test_a_flight_is_read_as_statuses_and_bad_rows_are_one_line(tmp_path: Path) -> None:
    samples = read_flight(flight_csv(tmp_path / "f.csv"))
    assert len(samples) == 22 and all(isinstance(s, VehicleStatus) for s in samples)
    s = samples[-1]
    assert s.vehicle_id == 2 and s.heading_deg == 90.0 and abs(s.vel_east_m_s - 8.8) < 1e-9
    assert samples[0].battery_pct == 90 and samples[0].fsm_state.name == "GO_MISSION"
    bad = tmp_path / "bad.csv"
    bad.write_text("time_s,vehicle,lat,lon,alt_m,fsm\n0,1,37.4,-5.9,100,FLYING\n")
    with pytest.raises(TrajectoryError, match=r"bad.csv:2: fsm 'FLYING' is not one of"):
        read_flight(bad)
    bad.write_text("time_s,vehicle,lat,lon,alt_m,battery_pct\n0,1,37.4,-5.9,100,lots\n")
    with pytest.raises(TrajectoryError, match="battery_pct 'lots' is not a number"):
        read_flight(bad)


def test_the_replay_clock_plays_at_its_speed_and_seeks(tmp_path: Path) -> None:
    p = Player(read_flight(flight_csv(tmp_path / "f.csv")))
    assert (p.t0, p.t1, p.t) == (100.0, 110.0, 100.0)
    assert [s.time_unix_s for s in p.advance(0.0)] == [100.0, 100.0]
    assert [s.time_unix_s for s in p.advance(2.0)] == [101.0] * 2 + [102.0] * 2
    p.set_speed(5.0)
    assert len(p.advance(3.0)) == 10  # 5 s of flight in 1 s of wall time
    with pytest.raises(ValueError, match="one of"):
        p.set_speed(3.3)
    window = p.seek(104.0, 2.0)
    assert {s.time_unix_s for s in window} == {102.0, 103.0, 104.0} and p.t == 104.0
    assert p.advance(10.0) == [] or p.t == 110.0
    assert not p.playing and p.t == 110.0  # stops at the end


def test_replay_controls_carry_the_token_and_a_seek_rebuilds_the_map(tmp_path: Path) -> None:
    player = Player(read_flight(flight_csv(tmp_path / "f.csv")))
    hub = Hub(Config("127.0.0.1", 0, TOKEN), player=player)

    async def test(client: TestClient) -> None:
        ws = await client.ws_connect("/ws")
        first = json.loads((await ws.receive_bytes(timeout=5)).decode())
        assert first["mode"] == "replay" and first["replay"]["t0"] == 100.0
        await ws.send_str(json.dumps({"op": "replay", "rid": 1, "req": {"action": "pause"}}))
        assert not (await ws.receive_json(timeout=5))["ok"]  # no token
        seek = {"op": "replay", "rid": 2, "token": TOKEN, "req": {"action": "seek", "t": 105}}
        await ws.send_str(json.dumps(seek))
        while True:
            msg = await ws.receive(timeout=5)
            if msg.type.name == "TEXT":
                assert json.loads(msg.data)["replay"]["t"] == 105.0
                break
        while True:  # the next full frame is a new map (epoch 2) at t = 105
            frame = json.loads((await ws.receive_bytes(timeout=5)).decode())
            if frame["epoch"] == 2:
                break
        assert frame["full"] and {v["id"] for v in frame["vehicles"]} == {1, 2}
        north = {v["id"]: v["lat"] for v in frame["vehicles"]}
        assert 37.4004 <= north[1] <= 37.4007  # where vehicle 1 was at 104-105 s
        r = await client.post("/api/send", json={"req": {"type": "command"}, "token": TOKEN})
        assert r.status == 400 and "replay sends no commands" in (await r.json())["error"]
        await ws.close()

    serving(hub, test)


def test_the_map_server_process_stops_on_sigint(tmp_path: Path) -> None:
    """`gcs map --replay` as an operator runs it: prints its URL, serves, and exits 0
    at Ctrl-C (no thread left hanging)."""
    import os
    import signal
    import subprocess
    import sys

    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "gcs_cli.app",
            "map",
            "--replay",
            str(flight_csv(tmp_path / "f.csv")),
            "--listen",
            "127.0.0.1:0",
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        env={**os.environ, "PYTHONUNBUFFERED": "1"},
    )
    try:
        assert proc.stdout is not None
        line = proc.stdout.readline().decode()
        assert line.startswith("gcs map (replay): http://127.0.0.1:") and "?token=" in line, line
        proc.send_signal(signal.SIGINT)
        # a bound that holds on a loaded 2-core host: the process only closes its server
        assert proc.wait(30) == 0
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()


def test_hub_is_live_or_a_replay() -> None:
    with pytest.raises(ValueError):
        Hub(Config("127.0.0.1", 0, TOKEN))
