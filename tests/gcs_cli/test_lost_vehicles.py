"""A lost vehicle stays on the ground station's list (LOST, its last position, its
age, its predicted position) until it is heard again, seen landed or dismissed: the
map's model (injected time), the kept list between `gcs` runs (SQLite), `gcs status`'s
rows and `gcs dismiss` at the command line."""

from __future__ import annotations

import json
import math
import re
import time
from pathlib import Path

import pytest
from msgspec.structs import replace
from typer.testing import CliRunner

from gcs_cli import lost_store
from gcs_cli.app import app
from gcs_cli.core.lost import LostBook, NotLostError
from gcs_cli.ground import FleetView
from gcs_cli.map.commands import PageError, dismissal
from gcs_cli.map.model import MapModel
from gcs_cli.render import fleet_rows, fleet_table
from swarm_proto import GeoPoint, VehicleInfo, VehicleStatus, VehicleType

LAT, LON = 37.4112, -5.9889
T0 = 1.7e9


def flying(vid: int, t: float, **kw: object) -> VehicleStatus:
    kw.setdefault("armed", True)
    kw.setdefault("vel_north_m_s", 10.0)
    return VehicleStatus(vid, T0 + t, LAT, LON, 50.0, 40.0, **kw)  # type: ignore[arg-type]


def info(vid: int) -> VehicleInfo:
    base = GeoPoint(LAT - 0.002, LON, 40.0)
    pad = GeoPoint(LAT - 0.002, LON + 0.0003, 10.0)  # its pad by the base: its RTL's end
    return VehicleInfo(vid, VehicleType.COPTER, "quad", f"Q-{vid}", home=pad, base=base)


def test_the_map_keeps_a_lost_vehicle_predicted_until_dismissed() -> None:
    m = MapModel(0.0)
    m.handle(info(8), 0.0)
    m.handle(flying(8, 0.0), 0.0)
    link = m.frame(0, 3.0)[0]["links"]["8"]
    assert not link["lost"] and "predicted" not in link
    frame, cursor = m.frame(0, 60.0)  # a minute unheard
    link = frame["links"]["8"]
    assert link["lost"] and not link["landed"]
    assert link["last"] == {"lat": LAT, "lon": LON, "alt_rel_m": 40.0, "age_s": 60.0}
    p = link["predicted"]
    # 10 s straight on north (its failsafe), then home to its base 222 m south
    assert p["phase"] in ("rtl", "landing", "landed") and p["lat"] < LAT
    assert 5.0 < p["error_m"] <= 50.0
    assert frame["summary"]["by_state"]["LOST"] == [8]
    with pytest.raises(NotLostError, match="vehicle 9 is not lost"):
        m.dismiss(9, 60.0)
    with pytest.raises(NotLostError, match="not a vehicle id: nan"):
        m.dismiss(math.nan, 60.0)
    assert m.dismiss("8", 60.0) == 8
    frame, cursor = m.frame(cursor, 61.0)
    assert frame["dismissed"] == [8] and "8" not in frame["links"]
    m.handle(flying(8, 70.0), 70.0)  # heard again: back on the map
    frame, _ = m.frame(cursor, 70.0)
    assert [v["id"] for v in frame["vehicles"]] == [8] and frame["dismissed"] == []


def test_the_map_does_not_predict_a_vehicle_seen_landed() -> None:
    m = MapModel(0.0)
    m.handle(replace(flying(8, 0.0, armed=False, vel_north_m_s=0.0), alt_rel_m=0.2), 0.0)
    link = m.frame(0, 60.0)[0]["links"]["8"]
    assert link["lost"] and link["landed"] and link["predicted"] is None
    with pytest.raises(NotLostError, match="vehicle 8 is not lost"):
        m.dismiss(8, 1.0)  # heard a second ago


def test_the_pages_dismissal_is_checked() -> None:
    assert dismissal({"id": 8}) == 8
    for bad in ({"id": float("nan")}, {"id": "eight"}, {"id": 1.5}, {"id": 0}, [8], {}):
        with pytest.raises(PageError):
            dismissal(bad)


def test_the_list_is_kept_between_runs_until_landed_or_dismissed(tmp_path: Path) -> None:
    path = tmp_path / "lost.db"
    book = LostBook()
    book.heard(flying(8, 0.0), info(8), T0)
    book.heard(flying(7, 0.0), info(7), T0)
    lost_store.save("s", book, path)
    again = lost_store.load("s", path)
    assert set(again.lost(T0 + 30.0)) == {7, 8}
    assert again.lost(T0 + 30.0)[8]["type"] == "COPTER"
    assert lost_store.load("other swarm", path).seen == {}
    landed = replace(flying(7, 40.0, armed=False, vel_north_m_s=0.0), alt_rel_m=0.0)
    again.heard(landed, None, T0 + 40.0)  # seen landed: off the list
    assert set(again.lost(T0 + 50.0)) == {8}
    with pytest.raises(NotLostError, match="vehicle 7 is not lost"):
        again.dismiss(7, T0 + 50.0)


def test_gcs_status_rows_and_table_show_a_lost_vehicle() -> None:
    view = FleetView()
    now = time.monotonic()
    view.status[8] = flying(8, 0.0)
    view.info[8] = info(8)
    view.heard_at[8] = now - 30.0  # unheard 30 s (a long `gcs watch`)
    book = LostBook()
    book.heard(flying(9, 0.0), info(9), time.time() - 90.0)  # kept from an earlier run
    rows = fleet_rows(view, book.lost(time.time()))
    by_id = {r["id"]: r for r in rows}
    assert by_id[8]["fsm"] == "LOST" and by_id[8]["predicted"]["phase"] in ("rtl", "route")
    assert by_id[9]["fsm"] == "LOST" and by_id[9]["last"]["age_s"] == pytest.approx(90.0, abs=2)
    assert by_id[9]["type"] == "COPTER"
    from rich.console import Console

    console = Console(width=100, record=True)
    console.print(fleet_table(view, lost=book.lost(time.time())))
    text = console.export_text()
    assert "LOST 90 s: last 37.41120,-5.98890 40 m; predicted" in text


def test_gcs_dismiss_at_the_command_line() -> None:
    book = LostBook()
    book.heard(flying(8, 0.0), info(8), time.time() - 60.0)
    lost_store.save("default", book)
    runner = CliRunner()
    r = runner.invoke(app, ["dismiss", "9"])
    assert r.exit_code == 2 and "vehicle 9 is not lost (lost: 8)" in r.output
    r = runner.invoke(app, ["dismiss", "nan"])
    assert r.exit_code == 2 and "not a vehicle id: 'nan'" in r.output
    r = runner.invoke(app, ["dismiss", "8"])
    assert r.exit_code == 0, r.output
    assert "vehicle 8 dismissed" in r.output
    assert lost_store.load("default").seen == {}
    assert json.loads(json.dumps(lost_store.load("default").lost(time.time()))) == {}


def test_gcs_status_lists_a_vehicle_lost_before_it_ran(
    zenoh_router: str, capsys: pytest.CaptureFixture[str]
) -> None:
    from gcs_cli.app import run

    book = LostBook()
    book.heard(flying(8, 0.0), info(8), time.time() - 60.0)
    lost_store.save("default", book)
    assert run(["--connect", zenoh_router, "status", "--wait", "0", "--json"]) == 0
    (row,) = json.loads(capsys.readouterr().out)
    assert row["id"] == 8 and row["fsm"] == "LOST" and row["type"] == "COPTER"
    assert row["predicted"]["error_m"] > 5.0
    assert run(["--connect", zenoh_router, "status", "--wait", "0"]) == 0
    out = capsys.readouterr().out
    assert re.search(r"8 ! LOST 6\d s: last 37.41120,-5.98890 40 m; predicted 37.40", out), out


def test_gcs_watch_shows_the_kept_list_and_keeps_what_it_heard() -> None:
    from rich.console import Console

    from gcs_cli.monitor import watch_screen

    book = LostBook()
    book.heard(flying(9, 0.0), info(9), time.time() - 30.0)
    console = Console(width=100, record=True)
    console.print(watch_screen(FleetView(), "s", None, book.lost(time.time())))
    assert re.search(r"9 ! LOST 3\d s: last", console.export_text())
    view = FleetView()
    view.status[7] = flying(7, 0.0)
    view.heard_at[7] = time.monotonic() - 20.0  # flying, unheard 20 s when the watch ends
    assert set(lost_store.update("s", view)) == set()  # 7 is in the view (its row says LOST)
    assert set(lost_store.load("s").lost(time.time())) == {7}
