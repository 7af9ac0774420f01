"""The live map (`gcs map`) at 6 and 50 vehicles: how long from a vehicle's status to
its icon moving on the page, how much of a core the server takes, how long the page
takes to draw a frame.

The vehicles are simulated in one helper process (spawned): each with its liveliness
token, a VehicleStatus at 5 Hz stamped with the wall clock when it is published, and a
VehicleInfo at 1 Hz, moving on circles; so 50 vehicles are 250 statuses a second on a
Zenoh router on 127.0.0.1 (no node processes: the figure is the map's path, Zenoh to
the page). The server is `gcs map` as an operator runs it, in its own process; the
page is headless Chromium (selenium), as in the browser tests.

- `lag_ms_p50/p99`: from a status's publication (its time_unix_s) to the page applying
  the frame that carries it (the icon is moved there; it is painted at the next display
  frame). The server folds and sends at most every 0.2 s, so about 100 ms of it is
  the wait for the next frame.
- `server_cpu_pct`: the `gcs map` process's CPU time (all threads, /proc) over the
  measured window, in % of one core.
- `frame_ms_p99`: from a frame's arrival on the page to the paint after it is applied;
  `apply_ms_p99`: the page's own work in it (the script that moves the icons, trails,
  list and panels), without the wait for the browser's next paint, which on a loaded
  host is most of it.
"""

from __future__ import annotations

import math
import multiprocessing as mp
import os
import shutil
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

SWARM = "benchmap"
SIZES = (6, 50)
WARM_S = 8.0  # every icon on the page, the server steady
WINDOW_S = 20.0
TOKEN = "bench-map-token-0123456789"


def _free_port() -> int:
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _vehicles_main(endpoint: str, n: int, stop: Any, ready: Any) -> None:
    """n vehicles circling, 5 Hz statuses and 1 Hz infos, on one session."""
    from swarm_proto import FsmState, GeoPoint, VehicleInfo, VehicleStatus, VehicleType
    from swarm_proto.session import SwarmBus, ZenohSettings

    bus = SwarmBus.open(ZenohSettings(connect=(endpoint,)), SWARM)
    lat0, lon0 = 37.4112, -5.9889
    types = (VehicleType.VTOL, VehicleType.COPTER, VehicleType.PLANE)
    for i in range(1, n + 1):
        bus.declare_alive(i)
    ready.set()
    t0 = time.time()
    tick = 0
    try:
        while not stop.is_set():
            tick += 1
            for i in range(1, n + 1):
                now = time.time()
                a = (now - t0) * 0.08 + i * 0.4
                r = 150.0 + 12.0 * i
                north, east = r * math.cos(a), r * math.sin(a)
                lat = lat0 + north / 111_320.0
                lon = lon0 + east / (111_320.0 * math.cos(math.radians(lat0)))
                hdg = (math.degrees(a) + 90.0) % 360.0
                v = 0.08 * r
                bus.publish(
                    VehicleStatus(
                        i,
                        now,
                        lat,
                        lon,
                        110.0,
                        100.0,
                        v * math.cos(math.radians(hdg)),
                        v * math.sin(math.radians(hdg)),
                        heading_deg=hdg,
                        battery_pct=80,
                        armed=True,
                        fsm_state=FsmState.GO_MISSION,
                        fleet_id=1 + i % 4,
                    )
                )
                if tick % 5 == i % 5:
                    bus.publish(
                        VehicleInfo(
                            i,
                            types[i % 3],
                            "Bench",
                            f"B{i:02d}",
                            home=GeoPoint(lat0, lon0 + i * 1e-4, 10.0),
                            fleet_id=1 + i % 4,
                            fsm_state=FsmState.GO_MISSION,
                        )
                    )
            time.sleep(max(0.0, 0.2 - (time.time() - now)))
    finally:
        bus.close()


def _cpu_s(pid: int) -> float:
    with open(f"/proc/{pid}/stat") as f:
        fields = f.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def _browser() -> Any:
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    chromium = shutil.which("chromium") or shutil.which("chromium-browser")
    driver = shutil.which("chromedriver")
    if not (chromium and driver):
        raise SystemExit("bench map: chromium and chromedriver are needed (`make browser`)")
    o = webdriver.ChromeOptions()
    o.binary_location = chromium
    for a in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage"):
        o.add_argument(a)
    o.add_argument("--window-size=1400,900")
    return webdriver.Chrome(options=o, service=Service(driver))


def _pct(values: list[float], q: float) -> float:
    if not values:
        return float("nan")
    s = sorted(values)
    return s[min(len(s) - 1, max(0, math.ceil(q * len(s)) - 1))]


def _one(n: int, endpoint: str, browser: Any, tmp: Path) -> dict[str, Any]:
    ctx = mp.get_context("spawn")
    stop, ready = ctx.Event(), ctx.Event()
    sim = ctx.Process(target=_vehicles_main, args=(endpoint, n, stop, ready), daemon=True)
    sim.start()
    log = tmp / f"map-{n}.log"
    out = open(log, "wb")  # noqa: SIM115
    server = subprocess.Popen(
        [
            *(sys.executable, "-m", "gcs_cli.app", "--connect", endpoint, "--swarm", SWARM),
            *("map", "--listen", "127.0.0.1:0", "--token", TOKEN),
        ],
        stdout=out,
        stderr=subprocess.STDOUT,
        env={**os.environ, "PYTHONUNBUFFERED": "1"},
    )
    out.close()
    try:
        ready.wait(60)
        end = time.monotonic() + 60
        while "http://" not in log.read_text() and time.monotonic() < end:
            time.sleep(0.2)
        url = next(w for w in log.read_text().split() if w.startswith("http://"))
        browser.get(url)
        time.sleep(WARM_S)
        shown = browser.execute_script("return mapState.vehicles.size")
        browser.execute_script(
            "mapStats.lagMs.length = 0; mapStats.frameMs.length = 0; mapStats.applyMs.length = 0;"
            "mapStats.frames = 0; mapStats.bytes = 0;"
        )
        cpu0, t0 = _cpu_s(server.pid), time.monotonic()
        time.sleep(WINDOW_S)
        cpu1, t1 = _cpu_s(server.pid), time.monotonic()
        stats = browser.execute_script(
            "return {lag: mapStats.lagMs.slice(), frame: mapStats.frameMs.slice(),"
            " apply: mapStats.applyMs.slice(),"
            " frames: mapStats.frames, bytes: mapStats.bytes}"
        )
    finally:
        server.send_signal(signal.SIGINT)
        try:
            server.wait(30)
        except subprocess.TimeoutExpired:
            server.kill()
        stop.set()
        sim.join(15)
    lag, frame, apply = stats["lag"], stats["frame"], stats["apply"]
    return {
        "vehicles": n,
        "vehicles_on_page": shown,
        "statuses_per_s": 5 * n,
        "lag_ms_p50": round(statistics.median(lag), 1) if lag else None,
        "lag_ms_p99": round(_pct(lag, 0.99), 1) if lag else None,
        "lag_samples": len(lag),
        "server_cpu_pct": round(100.0 * (cpu1 - cpu0) / (t1 - t0), 1),
        "frame_ms_p50": round(statistics.median(frame), 1) if frame else None,
        "frame_ms_p99": round(_pct(frame, 0.99), 1) if frame else None,
        "apply_ms_p50": round(statistics.median(apply), 1) if apply else None,
        "apply_ms_p99": round(_pct(apply, 0.99), 1) if apply else None,
        "load_avg_1min": round(os.getloadavg()[0], 2),
        "frames_per_s": round(stats["frames"] / (t1 - t0), 1),
        "kbytes_per_s_to_the_page": round(stats["bytes"] / (t1 - t0) / 1000.0, 1),
    }


def run() -> dict[str, Any]:
    from swarm_proto.session import ZenohSettings, open_session

    endpoint = f"tcp/127.0.0.1:{_free_port()}"
    router = open_session(ZenohSettings(mode="router", listen=(endpoint,)))
    browser = _browser()
    tmp = Path(tempfile.mkdtemp(prefix="bench-map-"))
    try:
        rows = [_one(n, endpoint, browser, tmp) for n in SIZES]
    finally:
        browser.quit()
        router.close()
        shutil.rmtree(tmp, ignore_errors=True)
    return {
        "description": (
            "gcs map: status -> icon lag, server CPU and page frame time; vehicles "
            "simulated in one process (5 Hz statuses, 1 Hz infos, liveliness), "
            "gcs map in its own process, headless Chromium; "
            f"{WINDOW_S:g} s measured after {WARM_S:g} s"
        ),
        "targets": {"lag_ms_max": 1000, "server_cpu_pct_max": 10, "frame_ms_max": 50},
        "sizes": {str(r["vehicles"]): r for r in rows},
    }
