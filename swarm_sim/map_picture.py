"""The README's picture of the live map, from a real run: `python -m swarm_sim.map_picture
[--out docs/img/map.png]` starts `swarm-sim demo`, attaches `gcs map` to the demo's
Zenoh network with the command the demo prints, opens the page in headless Chromium and
saves a screenshot once the page shows what the demo's story is about: the six VTOLs
flying, the survey's shares, the zones, the vote and the vehicle that was lost. Then it
stops the demo. Needs chromium and chromedriver (`make browser`). About five minutes."""

from __future__ import annotations

import argparse
import os
import shlex
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

READY = """
const vs = [...mapState.vehicles.values()];
const ms = mapState.missions || [];
return {
  vehicles: vs.length,
  flying: vs.filter(v => (v.data.alt_rel_m || 0) > 5).length,
  lost: vs.filter(v => v.link && v.link.lost).length,
  zones: (mapState.zones || []).length,
  shares: ms.reduce((n, m) => n + Object.keys(m.shares).length, 0),
  vote: document.getElementById('vote-body').textContent,
};"""


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=Path("docs/img/map.png"))
    ap.add_argument("--timeout", type=float, default=900.0, help="wall seconds to wait")
    args = ap.parse_args(argv)
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    chromium = shutil.which("chromium") or shutil.which("chromium-browser")
    chromedriver = shutil.which("chromedriver")
    if not (chromium and chromedriver):
        print("map_picture: chromium and chromedriver are needed (`make browser`)")
        return 2
    tmp = Path(tempfile.mkdtemp(prefix="map-picture-"))
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    demo_log = open(tmp / "demo.log", "wb")  # noqa: SIM115
    demo = subprocess.Popen(
        [str(Path(sys.executable).parent / "swarm-sim"), "demo", "--out", str(tmp / "demo-out")],
        stdout=demo_log,
        stderr=subprocess.STDOUT,
        env=env,
    )
    gcs_map = None
    driver = None
    end = time.monotonic() + args.timeout
    try:
        line = ""
        while not line and time.monotonic() < end and demo.poll() is None:
            time.sleep(0.5)
            line = next(
                (x for x in (tmp / "demo.log").read_text().splitlines() if "map: BANDADA_DB=" in x),
                "",
            )
        if not line:
            print(f"map_picture: the demo printed no map command (log: {tmp / 'demo.log'})")
            return 1
        words = shlex.split(line.split("map: ", 1)[1].split("(then")[0])
        db = words[0].split("=", 1)[1]
        cmd = [sys.executable, "-m", "gcs_cli.app", *words[2:], "--listen", "127.0.0.1:0"]
        map_log = tmp / "map.log"
        with open(map_log, "wb") as out:
            gcs_map = subprocess.Popen(
                cmd, stdout=out, stderr=subprocess.STDOUT, env={**env, "BANDADA_DB": db}
            )
        while "http://" not in map_log.read_text() and time.monotonic() < end:
            time.sleep(0.5)
        url = next(w for w in map_log.read_text().split() if w.startswith("http://"))
        options = webdriver.ChromeOptions()
        options.binary_location = chromium
        for a in ("--headless=new", "--no-sandbox", "--disable-gpu", "--window-size=1600,1000"):
            options.add_argument(a)
        driver = webdriver.Chrome(options=options, service=Service(chromedriver))
        driver.get(url)
        seen: dict[str, Any] = {}
        while time.monotonic() < end and demo.poll() is None:
            time.sleep(2.0)
            seen = driver.execute_script(READY)
            print(f"map_picture: {seen}", flush=True)
            if (
                seen["vehicles"] == 6
                and seen["lost"] >= 1
                and seen["zones"]
                and seen["shares"]
                and "winners" in str(seen["vote"])
                and seen["flying"] >= 3
            ):
                driver.execute_script("document.getElementById('btn-fit').click()")
                time.sleep(3.0)
                args.out.parent.mkdir(parents=True, exist_ok=True)
                driver.save_screenshot(str(args.out))
                print(f"map_picture: {args.out} written")
                return 0
        print(f"map_picture: the page never showed it all: {seen}")
        return 1
    finally:
        if driver is not None:
            driver.quit()
        for p in (gcs_map, demo):
            if p is not None and p.poll() is None:
                p.send_signal(signal.SIGINT)
                try:
                    p.wait(60)
                except subprocess.TimeoutExpired:
                    p.kill()
        demo_log.close()


if __name__ == "__main__":
    sys.exit(main())
