"""`gcs map` in a real browser: headless Chromium (selenium) against `gcs map` processes
serving live nodes on 127.0.0.1 (simulated vehicles, one `swarm-node run` each, in
fast time) and a flight CSV replayed. The vehicles appear (icons in their fleet's
colour where they are: the screenshot's pixels) and move; clicking icons selects; an
RTL to the selection is confirmed naming the vehicles and every vehicle's answer is
shown; the base is set by a click; a zone drawn on the map is acknowledged by every
vehicle and drawn; a mission drawn flies; bad input is the command line's one-line
error on the page, and nothing is sent; a replay plays, seeks and changes speed.

Chromium and chromedriver come from Debian's packages (`make browser`, which `make
test` runs, installs them as root). Where they are missing these tests fail under CI
(CI set) and are skipped elsewhere, saying why.

One browser for the module and few vehicles: the whole suite runs on two cores."""

from __future__ import annotations

import io
import math
import os
import shutil
import signal
import subprocess
import sys
import time
import warnings
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pytest

from swarm_node.database import SwarmDatabase
from swarm_proto import ScaledClock
from swarm_proto.session import SwarmBus, ZenohSettings, open_session
from swarm_proto.topics import COMMAND, MISSION, ZONE
from swarm_sim.core import SITL_HOME
from swarm_sim.runtime import VehicleServer, VehicleSpec
from swarm_sim.runtime.server import spread_homes
from tests.conftest import free_tcp_port
from tests.swarm_node.processes import peers_of, plain_session, start_node, stop, wait_until

pytestmark = [pytest.mark.network, pytest.mark.xdist_group("map-browser")]

TOKEN = "browser-test-token-0123456789"
SPEEDUP = 4.0  # simulated seconds per wall second: a take-off in a few seconds
IDS = (1, 2, 7)  # two VTOLs and a quadcopter (the seed database's types)
MODEL = {1: "vtol", 2: "vtol", 7: "copter"}
GREY = (158, 158, 158)  # fleet 0 (map.js FLEET_COLORS)
GREEN = (67, 160, 71)  # fleet 2


def browser_binaries() -> tuple[str, str]:
    chromium = shutil.which("chromium") or shutil.which("chromium-browser")
    driver = shutil.which("chromedriver")
    if chromium and driver:
        return chromium, driver
    why = (
        "chromium and chromedriver are not installed: `make browser` installs them "
        "(apt-get, as root, on Debian/Ubuntu)"
    )
    if os.environ.get("CI"):
        pytest.fail(why)  # never skipped where CI runs
    warnings.warn(why, stacklevel=1)
    pytest.skip(why)


@pytest.fixture(scope="module")
def driver() -> Iterator[Any]:
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    chromium, chromedriver = browser_binaries()
    options = webdriver.ChromeOptions()
    options.binary_location = chromium
    for arg in (
        "--headless=new",
        "--no-sandbox",  # CI runs as root
        "--disable-gpu",
        "--disable-dev-shm-usage",
        "--window-size=1400,900",
        "--force-device-scale-factor=1",
    ):
        options.add_argument(arg)
    d = webdriver.Chrome(options=options, service=Service(chromedriver))
    try:
        yield d
    finally:
        d.quit()


def start_map(log: Path, *args: str) -> tuple[subprocess.Popen[bytes], str]:
    """`gcs ... map` as an operator runs it; returns it and the URL it printed."""
    out = open(log, "wb")  # noqa: SIM115
    proc = subprocess.Popen(
        [sys.executable, "-m", "gcs_cli.app", *args],
        stdout=out,
        stderr=subprocess.STDOUT,
        env={**os.environ, "PYTHONUNBUFFERED": "1"},
    )
    out.close()
    found = wait_until(lambda: "http://" in log.read_text(errors="replace"), 60.0)
    text = log.read_text(errors="replace")
    assert found is not None and proc.poll() is None, text
    url = next(w for w in text.split() if w.startswith("http://"))
    return proc, url


@dataclass
class Live:
    router: str
    swarm: str
    url: str
    tmp: Path
    heard: list[object] = field(default_factory=list)  # commands, missions, zones on the router


@pytest.fixture(scope="module")
def live(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Live]:
    tmp = tmp_path_factory.mktemp("map-live")
    db = tmp / "swarm.db"
    SwarmDatabase.open(db).close()
    clock = ScaledClock(SPEEDUP)
    router = f"tcp/127.0.0.1:{free_tcp_port()}"
    swarm = f"m{os.getpid()}"
    homes = spread_homes(SITL_HOME, len(IDS), 30.0)
    specs = [VehicleSpec(MODEL[v], port=0, sysid=v, home=homes[i]) for i, v in enumerate(IDS)]
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("BANDADA_DB", str(db))
        mp.setenv("BANDADA_CLOCK", clock.spec())  # the nodes' clock, as the simulator's
        session = open_session(ZenohSettings(mode="router", listen=(router,)))
        procs: dict[int, subprocess.Popen[bytes]] = {}
        gcs_map = None
        listener = None
        try:
            with VehicleServer(specs, clock) as server:
                for vid, port in zip(IDS, server.ports, strict=True):
                    procs[vid] = start_node(
                        vid,
                        router,
                        swarm,
                        "--autopilot",
                        f"tcp:127.0.0.1:{port}",
                        "--link-timeout",
                        str(2.0 * SPEEDUP),  # 2 s of wall time on a busy host
                        log=tmp / f"node{vid}.log",
                    )
                watcher = plain_session(router)
                try:
                    for vid in IDS:
                        up = wait_until(lambda v=vid: peers_of(watcher, swarm, v) is not None, 60)
                        assert up is not None, (tmp / f"node{vid}.log").read_text()
                finally:
                    watcher.close()
                gcs_map, url = start_map(
                    tmp / "map.log",
                    *("--connect", router, "--swarm", swarm, "map"),
                    *("--listen", "127.0.0.1:0", "--token", TOKEN),
                )
                state = Live(router, swarm, url, tmp)
                listener = SwarmBus.open(ZenohSettings(connect=(router,)), swarm)
                for topic in (COMMAND, MISSION, ZONE):
                    listener.subscribe(topic, lambda m, k: state.heard.append(m))
                yield state
        finally:
            if listener is not None:
                listener.close()
            codes = {}
            if gcs_map is not None:
                codes["map"] = stop(gcs_map)
            for vid, p in procs.items():
                codes[vid] = stop(p)
            session.close()
            for name in ["map", *IDS]:
                log = tmp / (f"node{name}.log" if name != "map" else "map.log")
                if log.exists():
                    print(f"--- {log.name}\n" + log.read_text(errors="replace")[-3000:])
            assert all(c == 0 for c in codes.values()), codes


# ----------------------------------------------------------------------------- helpers


def until(
    d: Any, script: str, check: Callable[[Any], bool], timeout: float, what: str, *args: Any
) -> Any:
    """Run `script` in the page until `check(result)`; fail naming `what` otherwise."""
    end = time.monotonic() + timeout
    result = None
    while time.monotonic() < end:
        result = d.execute_script(script, *args)
        if check(result):
            return result
        time.sleep(0.2)
    d.save_screenshot(str(Path(os.environ.get("TMPDIR", "/tmp")) / "map-test-failure.png"))
    raise AssertionError(f"{what}: last {result!r}")


VEHICLES = """return [...mapState.vehicles.values()].map(v => ({id: v.id, lat: v.data.lat,
  lon: v.data.lon, fleet: v.data.fleet, has: !!v.data.has_position, trail: v.trail.length,
  lost: !!(v.link && v.link.lost), sel: mapState.sel.has(v.id)}))"""


def vehicles(d: Any) -> dict[int, dict[str, Any]]:
    return {v["id"]: v for v in d.execute_script(VEHICLES)}


def pixel_of(d: Any, lat: float, lon: float) -> tuple[int, int]:
    x, y = d.execute_script(
        "const p = leafletMap.latLngToContainerPoint([arguments[0], arguments[1]]);"
        "return [p.x, p.y];",
        lat,
        lon,
    )
    return round(x), round(y)


def screenshot(d: Any) -> Any:
    from PIL import Image

    return Image.open(io.BytesIO(d.get_screenshot_as_png())).convert("RGB")


def near(c: tuple[int, ...], want: tuple[int, int, int], tol: int = 40) -> bool:
    return all(abs(a - b) <= tol for a, b in zip(c, want, strict=False))


def click(d: Any, css: str) -> None:
    from selenium.webdriver.common.by import By

    d.find_element(By.CSS_SELECTOR, css).click()


def click_map(d: Any, x: int, y: int) -> None:
    """A click on the map at container pixel (x, y)."""
    from selenium.webdriver.common.action_chains import ActionChains
    from selenium.webdriver.common.by import By

    body = d.find_element(By.TAG_NAME, "body")
    w, h = d.execute_script("return [window.innerWidth, window.innerHeight]")
    ActionChains(d).move_to_element_with_offset(body, x - w // 2, y - h // 2).click().perform()


def confirm(d: Any, question: str) -> None:
    until(
        d,
        "return document.getElementById('modal').classList.contains('hidden') ? null"
        " : document.getElementById('modal-question').textContent",
        lambda q: q is not None,
        10,
        "the confirmation",
    )
    asked = d.execute_script("return document.getElementById('modal-question').textContent")
    assert asked == question
    click(d, "#modal-ok")


ANSWERS = """const c = document.querySelector('#answers-list .cmd');
  return c ? {state: c.className, q: c.querySelector('.q').textContent,
    rows: [...c.querySelectorAll('.ans')].map(r => [Number(r.dataset.vehicle), r.textContent])} : null"""


def answered(d: Any, question: str, timeout: float = 30.0) -> dict[int, str]:
    """The last command's answers, once its exchange is over."""
    got = until(
        d,
        ANSWERS,
        lambda a: a is not None and a["q"] == question and "waiting" not in a["state"],
        timeout,
        f"the answers to {question!r}",
    )
    return {vid: text for vid, text in got["rows"]}


def menu(d: Any, tab: str) -> None:
    if d.execute_script("return document.getElementById('menu').classList.contains('hidden')"):
        click(d, "#btn-menu")
    click(d, f"#menu .tabs button[data-tab={tab}]")


# ----------------------------------------------------------------------------- tests


def test_the_live_map_shows_selects_commands_and_draws(live: Live, driver: Any) -> None:
    d = driver
    d.get(live.url)
    # the vehicles appear: a row each and an icon where they are, once the simulated
    # autopilots have a position
    found = until(
        d,
        VEHICLES,
        lambda vs: len(vs) == 3 and all(v["has"] for v in vs),
        90,
        "three vehicles with a position",
    )
    assert sorted(v["id"] for v in found) == list(IDS)
    rows = d.execute_script(
        "return [...document.querySelectorAll('#vrows .vrow')].map(r => r.textContent)"
    )
    assert len(rows) == 3 and "ALB-01" in rows[0] and "/s" in rows[0]  # packets per second
    d.execute_script("leafletMap.setZoom(18, {animate: false})")
    d.execute_script("document.getElementById('btn-fit').click()")
    time.sleep(0.5)

    # fleets from the map: vehicle 7 to fleet 2 (an id selection by clicking its icon)
    click(d, '.leaflet-marker-icon[data-vehicle="7"]')
    assert d.execute_script("return document.getElementById('sel-text').textContent") == (
        "vehicles 7"
    )
    d.execute_script(
        "window.mapRequest({type: 'command', kind: 'set-fleet', fleet_id: 2, select: {ids: [7]}})"
    )
    confirm(d, "set-fleet to vehicle 7?")
    assert answered(d, "set-fleet to vehicle 7?")[7].startswith("7: accepted")
    until(d, VEHICLES, lambda vs: {v["id"]: v["fleet"] for v in vs}.get(7) == 2, 20, "fleet 2")
    click(d, "#sel-none")
    time.sleep(0.6)  # a frame or two: the icon redrawn in its new fleet's colour
    img = screenshot(d)
    vs = vehicles(d)
    for vid, want in ((1, GREY), (2, GREY), (7, GREEN)):
        x, y = pixel_of(d, vs[vid]["lat"], vs[vid]["lon"])
        assert near(img.getpixel((x, y)), want), (vid, img.getpixel((x, y)), want)
    x, y = pixel_of(d, vs[1]["lat"], vs[1]["lon"])
    assert near(img.getpixel((x - 150, y - 150)), (238, 241, 244), 12)  # the map's ground

    # the vehicle list: a row opens the flight display; the eye hides the icon
    click(d, '#vrows .vrow[data-id="1"]')
    pfd = until(
        d,
        "return document.getElementById('pfd').textContent",
        lambda t: "ALB-01" in t,
        10,
        "the flight display",
    )
    for words in ("ground speed", "airspeed", "altitude", "battery", "GPS", "base"):
        assert words in pfd, (words, pfd)
    click(d, '#vrows .vrow[data-id="2"] button.eye')
    icons = "return document.querySelectorAll('.leaflet-marker-icon[data-vehicle=\"2\"]').length"
    assert d.execute_script(icons) == 0
    click(d, '#vrows .vrow[data-id="2"] button.eye')
    until(d, icons, lambda n: n == 1, 5, "vehicle 2 shown again")
    # the fleet summary selects by state; By ID lists every vehicle
    click(d, '#summary .state[data-state="INACTIVE"]')
    assert d.execute_script("return document.getElementById('sel-text').textContent") == (
        "vehicles 1, 2, 7"
    )
    click(d, "#sel-none")
    click(d, "#sel-id")
    click(d, '#idlist input[data-id="2"]')
    assert d.execute_script("return document.getElementById('sel-text').textContent") == (
        "vehicles 2"
    )
    click(d, "#sel-id")
    click(d, "#sel-none")

    # clicking icons selects; an RTL to the selection is confirmed and every answer shown
    click(d, '.leaflet-marker-icon[data-vehicle="1"]')
    click(d, '.leaflet-marker-icon[data-vehicle="2"]')
    assert d.execute_script("return document.getElementById('sel-text').textContent") == (
        "vehicles 1, 2"
    )
    assert (
        d.execute_script("return [...document.querySelectorAll('.veh.sel')].length") == 2
    )  # the selection's halo
    menu(d, "actions")
    click(d, "#btn-rtl")
    confirm(d, "rtl to vehicles 1, 2?")
    rtl = answered(d, "rtl to vehicles 1, 2?")
    assert set(rtl) == {1, 2} and all("no answer" not in t for t in rtl.values()), rtl

    # a box dragged with shift held selects what is inside it; Fleet: one click, its fleet
    from selenium.webdriver.common.action_chains import ActionChains
    from selenium.webdriver.common.by import By
    from selenium.webdriver.common.keys import Keys

    vs = vehicles(d)
    xs, ys = zip(*(pixel_of(d, v["lat"], v["lon"]) for v in vs.values()), strict=True)
    body = d.find_element(By.TAG_NAME, "body")
    w, h = d.execute_script("return [window.innerWidth, window.innerHeight]")
    corner = (min(xs) - 40 - w // 2, min(ys) - 40 - h // 2)
    ActionChains(d).key_down(Keys.SHIFT).move_to_element_with_offset(
        body, *corner
    ).click_and_hold().move_by_offset(
        max(xs) - min(xs) + 80, max(ys) - min(ys) + 80
    ).release().key_up(Keys.SHIFT).perform()
    until(
        d,
        "return document.getElementById('sel-text').textContent",
        lambda t: t == "vehicles 1, 2, 7",
        10,
        "the box's selection",
    )
    click(d, "#sel-fleet")
    click(d, '.leaflet-marker-icon[data-vehicle="7"]')
    assert d.execute_script("return document.getElementById('sel-text').textContent") == (
        "fleet 2: 7"
    )
    click(d, "#sel-uav")
    click(d, "#sel-none")

    # the base, set by clicking the map
    vs = vehicles(d)
    bx, by = pixel_of(d, vs[1]["lat"], vs[1]["lon"])
    menu(d, "base")
    click(d, "#btn-set-base")
    click_map(d, bx, by + 60)
    confirm(d, "set-base to every vehicle alive (1, 2, 7)?")
    base = answered(d, "set-base to every vehicle alive (1, 2, 7)?")
    assert set(base) == set(IDS) and all(t.startswith(f"{v}: accepted") for v, t in base.items())
    until(d, "return mapState.base", lambda b: b is not None, 20, "the base on the map")

    # a no-fly zone drawn as a circle, acknowledged by every vehicle, drawn in red
    zx, zy = bx - 260, by - 120
    menu(d, "zones")
    click(d, "#z-draw-circle")
    click_map(d, zx, zy)
    click_map(d, zx + 50, zy)
    confirm(d, "zone 1 to every vehicle alive (1, 2, 7)?")
    zone = answered(d, "zone 1 to every vehicle alive (1, 2, 7)?")
    assert set(zone) == set(IDS) and all(t.startswith(f"{v}: accepted") for v, t in zone.items()), (
        zone
    )  # every vehicle holds it
    until(d, "return mapState.zones.length", lambda n: n == 1, 20, "the zone on the map")
    time.sleep(0.3)
    r, g, b = screenshot(d).getpixel((zx, zy))
    assert r > g + 30 and r > b + 30, (r, g, b)  # the zone's red over the map

    # bad input: the command line's one-line error on the page, nothing sent
    heard = len(live.heard)
    d.execute_script(
        "window.mapRequest({type: 'command', kind: 'takeoff', value: 'nan', select: {ids: [7]}})"
    )
    error = until(
        d,
        "const e = document.getElementById('error');"
        "return e.classList.contains('hidden') ? null : e.textContent",
        lambda t: t,
        10,
        "the error",
    )
    assert error == "Invalid value for --value: nan is not a number"
    click(d, "#z-draw-polygon")
    for px, py in ((zx + 150, zy), (zx + 250, zy + 80), (zx + 250, zy), (zx + 150, zy + 80)):
        click_map(d, px, py)
    click(d, "#draw-finish")
    error = until(
        d,
        "return document.getElementById('error').textContent",
        lambda t: "Self-intersection" in t,
        10,
        "the polygon's error",
    )
    assert error.startswith("Invalid value: invalid POLYGON geometry: polygon is not simple")
    assert d.execute_script("return document.getElementById('modal').classList.contains('hidden')")
    time.sleep(1.0)
    assert len(live.heard) == heard  # nothing went out

    # a mission drawn on the map flies: a target for vehicle 7, north of it
    vs = vehicles(d)
    start = (vs[7]["lat"], vs[7]["lon"])
    x7, y7 = pixel_of(d, *start)
    click(d, "#sel-none")
    click(d, '.leaflet-marker-icon[data-vehicle="7"]')
    menu(d, "missions")
    d.execute_script("document.getElementById('m-type').value = 'target'")
    click(d, "#m-draw-point")
    click_map(d, x7, y7 - 150)
    d.execute_script("document.getElementById('m-alt').value = '30'")
    click(d, "#btn-mission")
    question = until(
        d,
        "return document.getElementById('modal-question').textContent",
        lambda q: q.startswith("mission "),
        10,
        "the mission's confirmation",
    )
    assert question.endswith("(target) to vehicle 7?")
    confirm(d, question)
    assert answered(d, question)[7].startswith("7: accepted")

    def moved(vs: list[dict[str, Any]]) -> bool:
        v = {x["id"]: x for x in vs}[7]
        north = (v["lat"] - start[0]) * 111_320.0
        east = (v["lon"] - start[1]) * 111_320.0 * math.cos(math.radians(start[0]))
        return math.hypot(north, east) > 15.0 and v["trail"] > 1

    # a mission from a file the operator picks (read on the page, checked by the server
    # as `gcs mission --file` reads it): confirmed or, here, cancelled
    field_file = live.tmp / "field.geojson"
    lat0, lon0 = start
    ring = [[lon0, lat0], [lon0 + 0.002, lat0], [lon0 + 0.002, lat0 + 0.002], [lon0, lat0 + 0.002]]
    field_file.write_text(
        '{"type": "Polygon", "coordinates": [' + str([*ring, ring[0]]).replace("'", '"') + "]}"
    )
    d.execute_script("document.getElementById('m-type').value = 'area'")
    d.find_element(By.ID, "m-file").send_keys(str(field_file))
    until(
        d,
        "return document.getElementById('m-geometry').textContent",
        lambda t: t == "file: field.geojson",
        10,
        "the file read",
    )
    click(d, "#sel-all")
    click(d, "#btn-mission")
    question = until(
        d,
        "return document.getElementById('modal-question').textContent",
        lambda q: "(area)" in q,
        10,
        "the file mission's confirmation",
    )
    assert question.endswith("(area) to every vehicle alive (1, 2, 7)?"), question
    heard = len(live.heard)
    click(d, "#modal-cancel")

    until(d, VEHICLES, moved, 120, "vehicle 7 flying its mission")
    time.sleep(0.5)
    assert len(live.heard) == heard  # cancelled: not sent
    until(
        d,
        "return mapState.missions.map(m => [m.plan, Object.keys(m.shares)])",
        lambda ms: ["planned", ["7"]] in ms,
        60,
        "vehicle 7's share of the mission",
    )


def flight_csv(path: Path) -> Path:
    """Two vehicles flying 20 s: 1 north, 2 east, 10 m/s."""
    rows = ["time_s,vehicle,lat,lon,alt_m,alt_rel_m,groundspeed_m_s,heading_deg,battery_pct,fsm"]
    lat0, lon0 = SITL_HOME.lat_deg, SITL_HOME.lon_deg
    for k in range(0, 201):
        t = k / 10
        north = 10.0 * t / 111_320.0
        east = 10.0 * t / (111_320.0 * math.cos(math.radians(lat0)))
        rows.append(f"{1000 + t:.1f},1,{lat0 + north:.8f},{lon0:.8f},120,100,10,0,90,GO_MISSION")
        rows.append(f"{1000 + t:.1f},2,{lat0:.8f},{lon0 + east:.8f},120,100,10,90,80,GO_MISSION")
    path.write_text("\n".join(rows) + "\n")
    return path


def test_a_flight_replayed(tmp_path: Path, driver: Any) -> None:
    d = driver
    proc, url = start_map(
        tmp_path / "map.log",
        *("map", "--replay", str(flight_csv(tmp_path / "flight.csv"))),
        *("--listen", "127.0.0.1:0", "--token", TOKEN),
    )
    try:
        d.get(url)
        until(
            d,
            "return mapState.replay",
            lambda r: r is not None and r["t0"] == 1000.0 and r["t1"] == 1020.0,
            20,
            "the replay bar",
        )
        assert d.execute_script(
            "return document.getElementById('fast').classList.contains('hidden')"
        )  # no commands in a replay
        first = until(
            d, VEHICLES, lambda vs: len(vs) == 2 and all(v["has"] for v in vs), 20, "2 vehicles"
        )
        lat1 = {v["id"]: v["lat"] for v in first}[1]
        # it plays: vehicle 1 goes north, the slider moves
        until(d, VEHICLES, lambda vs: {v["id"]: v["lat"] for v in vs}[1] > lat1, 20, "moving")
        click(d, "#r-play")  # pause
        until(d, "return mapState.replay.playing", lambda p: p is False, 10, "paused")
        # faster, and a seek to the last second rebuilds the map there
        d.execute_script(
            "const s = document.getElementById('r-speed'); s.value = '10';"
            "s.dispatchEvent(new Event('change'))"
        )
        until(d, "return mapState.replay.speed", lambda s: s == 10, 10, "10x")
        d.execute_script(
            "const s = document.getElementById('r-slider'); s.value = '950';"
            "s.dispatchEvent(new Event('change'))"
        )
        r = until(d, "return mapState.replay", lambda r: r["t"] >= 1018.9, 10, "the seek")
        assert not r["playing"]
        late = until(
            d,
            VEHICLES,
            lambda vs: len(vs) == 2 and {v["id"]: v["lat"] for v in vs}[1] > lat1 + 0.0015,
            10,
            "vehicle 1 where it was at 19 s",
        )
        v1 = {v["id"]: v for v in late}[1]
        img = screenshot(d)
        x, y = pixel_of(d, v1["lat"], v1["lon"])
        if 0 < x < img.width and 0 < y < img.height:
            assert near(img.getpixel((x, y)), GREY)  # its icon where it is
        shown = d.execute_script("return document.getElementById('r-time').textContent")
        assert shown == "0:19 / 0:20"
    finally:
        proc.send_signal(signal.SIGINT)
        assert proc.wait(30) == 0, (tmp_path / "map.log").read_text()


def test_without_chromium_ci_fails_and_elsewhere_skips(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(shutil, "which", lambda name: None)
    monkeypatch.setenv("CI", "true")
    with pytest.raises(pytest.fail.Exception, match="make browser"):
        browser_binaries()
    monkeypatch.delenv("CI")
    with pytest.warns(UserWarning, match="not installed"), pytest.raises(pytest.skip.Exception):
        browser_binaries()
