"""Monitoring commands: `gcs watch` (the live fleet table, packets per second and link
age per vehicle, alerts as they arrive), `gcs vehicle ID` (the paper's PFD: attitude,
speeds, altitude, battery, GPS, sensor calibration, base) and `gcs fleets`."""

from __future__ import annotations

import json
import time
from typing import Any

import typer
from rich import box
from rich.console import Console, Group
from rich.live import Live
from rich.table import Table
from rich.text import Text

from swarm_proto import Selector, VehicleInfo, VehicleType
from swarm_proto.ardupilot import autopilot_mismatch, mode_name

from . import lost_store
from .common import console, quit_on_signal, read_filter, wait_option
from .core.reasons import alert_text
from .ground import FleetView, GroundStation
from .options import AllOption, FleetOption, IdsOption, JsonOption, finite
from .render import fleet_rows, fleet_table

app = typer.Typer()  # watch, vehicle, fleets: app.py puts them at the top level

ALERT_LINES = 8  # the latest alerts under the live table


def watch_screen(
    view: FleetView,
    swarm: str,
    shown: Selector | None,
    lost: dict[int, dict[str, Any]] | None = None,
) -> Group:
    """The live table (with `lost`: the kept lost list's vehicles not heard) and,
    below it, the latest alerts with their full meaning."""
    now = time.time()
    lines = [
        Text(
            f"{time.strftime('%H:%M:%S', time.gmtime(a.time_unix_s))} {a.vehicle_id:>5} "
            f"{a.severity.name:<9} {alert_text(a.code, a.text, a.detail)}",
            style="red" if a.severity >= 2 else ("yellow" if a.severity == 1 else ""),
        )
        for a in list(view.alerts)[-ALERT_LINES:]
        if shown is None or shown.addresses(a.vehicle_id, _fleet(view, a.vehicle_id))
    ]
    title = f"swarm {swarm}  {time.strftime('%H:%M:%S', time.gmtime(now))} UTC  (Ctrl-C quits)"
    alerts = lines or [Text("no alert yet", style="dim")]
    table = fleet_table(view, title=title, shown=shown, rates=True, lost=lost)
    return Group(table, Text("alerts:"), *alerts)


def _fleet(view: FleetView, vid: int) -> int:
    st = view.status.get(vid)
    return st.fleet_id if st else 0


def live_watch(
    gs: GroundStation,
    out: Console,
    shown: Selector | None,
    *,
    period_s: float = 0.5,
    duration_s: float | None = None,
) -> None:
    end = None if duration_s is None else time.monotonic() + duration_s
    # the vehicles lost before this watch began (lost_store.py), shown until heard
    kept = lost_store.load(gs.swarm)

    def screen() -> Group:
        view = gs.snapshot()
        lost = {v: f for v, f in kept.lost(time.time()).items() if v not in view.status}
        return watch_screen(view, gs.swarm, shown, lost)

    with (
        quit_on_signal() as quit_,
        Live(
            screen(),
            console=out,
            refresh_per_second=4,
            screen=False,
        ) as live,
    ):
        try:
            while end is None or time.monotonic() < end:
                if quit_.wait(period_s):
                    break
                live.update(screen())
        except KeyboardInterrupt:
            pass
    lost_store.update(gs.swarm, gs.snapshot())  # what this watch heard, kept


@app.command()
def watch(
    ctx: typer.Context,
    ids: IdsOption = [],  # noqa: B006
    fleet: FleetOption = None,
    all_: AllOption = False,
    period: float = typer.Option(0.5, help="seconds between refreshes"),
    duration: float | None = typer.Option(None, help="stop after this many seconds"),
    as_json: JsonOption = False,
) -> None:
    """The fleet, live: the status table with packets per second and link age (`age s`)
    per vehicle, and the alerts as they arrive. Ctrl-C quits. With --json, one JSON
    line per refresh (the rows of `gcs status --json`, with `packets_per_s`).

    Example: gcs watch --fleet 1
    """
    finite(period, "--period", 0.0, 3600.0)
    finite(duration, "--duration", 0.0, 1.0e7)
    if period <= 0:
        raise typer.BadParameter("must be > 0", param_hint="--period")
    shown = read_filter(ids, fleet, all_)
    with ctx.obj.open() as gs:
        if not as_json:
            live_watch(gs, console, shown, period_s=period, duration_s=duration)
            return
        end = None if duration is None else time.monotonic() + duration
        with quit_on_signal() as quit_:
            while end is None or time.monotonic() < end:
                if quit_.wait(period):
                    break
                view = gs.snapshot()
                now = time.monotonic()
                rows = [
                    {**r, "packets_per_s": round(view.packets_per_s(r["id"], now), 1)}
                    for r in fleet_rows(view)
                    if shown.addresses(r["id"], r.get("fleet") or 0)
                ]
                typer.echo(json.dumps({"time_unix_s": round(time.time(), 3), "vehicles": rows}))


# MAV_SYS_STATUS_SENSOR bits the flight display shows (what calibration makes healthy)
SENSORS = {
    "gyro": 1 << 0,
    "accel": 1 << 1,
    "compass": 1 << 2,
    "baro": 1 << 3,
    "airspeed": 1 << 4,
    "gps": 1 << 5,
}


def pfd(view: FleetView, vid: int) -> dict[str, Any]:
    """What the paper's primary flight display shows of one vehicle, as plain data."""
    st, info = view.status.get(vid), view.info.get(vid)
    vt = info.vehicle_type if info else VehicleType.OTHER
    out: dict[str, Any] = {"id": vid}
    if info is not None:
        out.update(
            model=info.model,
            user_id=info.user_id,
            type=vt.name,
            fleet=info.fleet_id,
            mission_id=info.mission_id,
            fsm=info.fsm_state.name,
            roll_deg=round(info.roll_deg, 1),
            pitch_deg=round(info.pitch_deg, 1),
            payload=info.payload_model,
            cruise_speed_m_s=info.cruise_speed_m_s,
            home=_point(info.home),
            base=_point(info.base),
            errors=[c.name for c in info.errors],
            autopilot_mav_type=info.mav_type,
            autopilot_mismatch=autopilot_mismatch(vt, info.mav_type),
            sensors={
                name: (
                    "absent"
                    if not info.sensors_present & bit
                    else "ok"
                    if info.sensors_health & bit
                    else "NOT HEALTHY"
                )
                for name, bit in SENSORS.items()
            }
            if info.sensors_present
            else {},
        )
    if st is not None:
        out.update(
            heading_deg=round(st.heading_deg, 1),
            groundspeed_m_s=round(st.groundspeed_m_s, 1),
            airspeed_m_s=round(st.airspeed_m_s, 1),
            climb_m_s=round(-st.vel_down_m_s, 1),
            alt_rel_m=round(st.alt_rel_m, 1),
            alt_msl_m=round(st.alt_msl_m, 1),
            lat=round(st.lat_deg, 7),
            lon=round(st.lon_deg, 7),
            battery_pct=st.battery_pct,
            battery_v=round(st.battery_v, 2),
            gps_fix=st.gps_fix.name,
            gps_sats=st.gps_sats,
            armed=st.armed,
            mode=mode_name(vt, st.ap_mode),
            mission_state=st.mission_state.name,
            mission_progress_pct=st.mission_progress_pct,
            alerts=[f.name for f in type(st.alerts) if f and f in st.alerts],
        )
    return out


def _point(p: Any) -> dict[str, float] | None:
    if p is None:
        return None
    return {
        "lat": round(p.lat_deg, 7),
        "lon": round(p.lon_deg, 7),
        "alt_msl_m": round(p.alt_msl_m, 1),
    }


def pfd_table(d: dict[str, Any]) -> Table:
    t = Table(
        title=f"vehicle {d['id']}  {d.get('model', '')}  {d.get('user_id', '')}",
        box=box.SIMPLE_HEAD,
        show_header=False,
        title_justify="left",
    )
    t.add_column(style="bold")
    t.add_column()
    t.add_column(style="bold")
    t.add_column()

    def v(key: str, fmt: str = "{}") -> str:
        return fmt.format(d[key]) if d.get(key) is not None else "-"

    base = d.get("base")
    sensors = d.get("sensors") or {}
    rows = [
        (
            "attitude",
            f"roll {v('roll_deg')}°  pitch {v('pitch_deg')}°  hdg {v('heading_deg')}°",
            "state",
            f"{v('fsm')} / {v('mission_state')} {v('mission_progress_pct')}%",
        ),
        (
            "ground speed",
            v("groundspeed_m_s", "{} m/s"),
            "altitude",
            f"{v('alt_rel_m')} m above home ({v('alt_msl_m')} m MSL)",
        ),
        ("airspeed", v("airspeed_m_s", "{} m/s"), "climb", v("climb_m_s", "{} m/s")),
        (
            "mode",
            f"{v('mode')} {'ARMED' if d.get('armed') else 'disarmed'}",
            "battery",
            f"{v('battery_pct')} %  {v('battery_v')} V",
        ),
        ("position", f"{v('lat')}, {v('lon')}", "GPS", f"{v('gps_fix')} {v('gps_sats')} sats"),
        (
            "base",
            f"{base['lat']}, {base['lon']} ({base['alt_msl_m']} m)" if base else "not set",
            "fleet",
            f"{v('fleet')}  mission {v('mission_id')}",
        ),
        (
            "sensors",
            "  ".join(f"{k} {s}" for k, s in sensors.items()) or "-",
            "alerts",
            ", ".join(d.get("alerts") or []) or "-",
        ),
    ]
    for r in rows:
        t.add_row(*r)
    if d.get("autopilot_mismatch"):
        t.add_row("AUTOPILOT", d["autopilot_mismatch"], "", "", style="red")
    return t


@app.command()
def vehicle(
    ctx: typer.Context,
    vehicle_id: int = typer.Argument(..., min=1, max=65534, metavar="ID", help="vehicle id"),
    wait: float = typer.Option(3.0, help="seconds to wait to hear it"),
    as_json: JsonOption = False,
) -> None:
    """One vehicle's flight display (the paper's PFD): attitude, ground speed and
    airspeed, altitude, battery, GPS, whether its sensors are calibrated (healthy),
    its base, mode and state, and an autopilot of the wrong type. Exit 1 if not heard.

    Example: gcs vehicle 7 --json
    """
    wait_option(wait)
    with ctx.obj.open() as gs:
        heard = gs.wait_for(lambda v: vehicle_id in v.status and vehicle_id in v.info, wait)
        view = gs.snapshot()
    if not heard and vehicle_id not in view.status and vehicle_id not in view.info:
        console.print(f"[red]vehicle {vehicle_id} not heard in {wait:g} s[/]")
        raise typer.Exit(1)
    d = pfd(view, vehicle_id)
    if as_json:
        typer.echo(json.dumps(d, indent=2))
    else:
        console.print(pfd_table(d))


def rosters_of(infos: list[VehicleInfo]) -> list[dict[str, Any]]:
    """What each node believes its mission's fleet is: the vehicles flying or planning
    a mission grouped by the roster hash they publish; a mission flown under more than
    one roster is `split` (its fleet replanned apart, e.g. across a partition)."""
    groups: dict[tuple[int, int], list[int]] = {}
    for i in infos:
        if i.mission_id > 0 and i.members_hash:
            groups.setdefault((i.mission_id, i.members_hash), []).append(i.vehicle_id)
    per_mission: dict[int, int] = {}
    for mid, _ in groups:
        per_mission[mid] = per_mission.get(mid, 0) + 1
    return [
        {
            "mission": mid,
            "roster": f"{h:#06x}",
            "vehicles": sorted(vids),
            "split": per_mission[mid] > 1,
        }
        for (mid, h), vids in sorted(groups.items())
    ]


@app.command()
def fleets(
    ctx: typer.Context,
    wait: float = typer.Option(2.0, help="seconds to listen"),
    as_json: JsonOption = False,
) -> None:
    """The fleets heard: each fleet's vehicles, their types, states and missions
    (fleet 0: vehicles in no fleet).

    Example: gcs fleets --json
    """
    wait_option(wait)
    with ctx.obj.open() as gs:
        alive = gs.discover(min(wait, 2.0))
        gs.wait_for(lambda v: all(i in v.status and i in v.info for i in alive), wait)
        view = gs.snapshot()
        rows = fleet_rows(view)
    by: dict[int, list[dict[str, Any]]] = {}
    for r in rows:
        by.setdefault(int(r.get("fleet") or 0), []).append(r)
    data: list[dict[str, Any]] = [
        {
            "fleet": f,
            "vehicles": [r["id"] for r in members],
            "types": sorted({r["type"] for r in members}),
            "states": sorted({r["fsm"] for r in members}),
            "missions": sorted({r["mission_id"] for r in members if r["mission_id"]}),
            "rosters": rosters_of([view.info[r["id"]] for r in members if r["id"] in view.info]),
        }
        for f, members in sorted(by.items())
    ]
    if as_json:
        typer.echo(json.dumps(data, indent=2))
        return
    t = Table(title="fleets", box=box.SIMPLE_HEAD, title_justify="left")
    for col in ("fleet", "vehicles", "types", "states", "missions", "rosters (per node)"):
        t.add_column(col)
    for d in data:
        t.add_row(
            str(d["fleet"]) if d["fleet"] else "none",
            ", ".join(map(str, d["vehicles"])),
            ", ".join(d["types"]),
            ", ".join(d["states"]),
            ", ".join(map(str, d["missions"])) or "-",
            "; ".join(
                f"{r['mission']}:{r['roster']} {r['vehicles']}" + (" SPLIT" if r["split"] else "")
                for r in d["rosters"]
            )
            or "-",
        )
    console.print(t if data else "no vehicle heard")
