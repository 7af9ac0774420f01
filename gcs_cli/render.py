"""Rich rendering of what the ground station sees."""

from __future__ import annotations

import time
from typing import Any

from rich import box
from rich.console import Group
from rich.table import Table
from rich.text import Text

from swarm_proto import Ack, AlertFlag, Selector, VehicleStatus, VehicleType
from swarm_proto.ardupilot import autopilot_mismatch, mode_name

from .core.lost import lost_fields
from .core.reasons import ack_text
from .ground import FleetView


def flag_names(flags: AlertFlag) -> str:
    return ",".join(f.name.lower() for f in AlertFlag if f and f in flags and f.name) or "-"


def data_age_s(status: VehicleStatus, now_unix_s: float) -> float:
    """How old the autopilot data in a status is: its `time_unix_s` is the time of the
    autopilot's sample (GPS time), and after an autopilot link loss the node keeps
    sending the last one: `age s` says when the ground station last heard the
    node, `data s` how old what it says is. Clamped at 0 (a vehicle clock ahead). A radio
    peer's status predicted by its gateway is `predicted_s` older than its
    time says."""
    return round(max(0.0, now_unix_s - status.time_unix_s) + status.predicted_s, 1)


def fleet_rows(
    view: FleetView, lost: dict[int, dict[str, Any]] | None = None
) -> list[dict[str, Any]]:
    """One plain dict per vehicle (also the --json output); a vehicle not heard for
    5 s that was flying is LOST (its last position and age, its predicted position:
    core/lost.py), and so is each of `lost` (the kept list's, unheard in this run)."""
    now = time.monotonic()
    now_unix = time.time()
    rows = []
    for vid in sorted(set(view.vehicle_ids()) | set(lost or ())):
        if vid not in view.status and vid not in view.info and vid not in view.alive:
            kept = (lost or {})[vid]
            last = kept["last"]
            rows.append(
                {"id": vid, "type": "OTHER", "alive": False, "fsm": "LOST", **kept}
                | {"lat": last["lat"], "lon": last["lon"], "alt_rel_m": last["alt_rel_m"]}
                | {"age_s": last["age_s"]}
            )
            continue
        st, info = view.status.get(vid), view.info.get(vid)
        vt = info.vehicle_type if info else VehicleType.OTHER
        row: dict[str, Any] = {
            "id": vid,
            "model": info.model if info else "",
            "user_id": info.user_id if info else "",
            "type": vt.name,
            "alive": vid in view.alive,
            "age_s": round(now - view.heard_at[vid], 1) if vid in view.heard_at else None,
            "fsm": view.fsm_state(vid).name,
            "mission_id": info.mission_id if info else 0,
            "fleet": info.fleet_id if info else None,  # the status's, once heard
        }
        mismatch = autopilot_mismatch(vt, info.mav_type) if info is not None else None
        if mismatch:
            row["autopilot_mismatch"] = mismatch
        if vid in view.untrusted:  # heard from two sources: why (what the map can show)
            row["untrusted"] = view.untrusted[vid] or "identity in doubt"
        if st is not None:
            row.update(
                mode=mode_name(vt, st.ap_mode) if vt != VehicleType.OTHER else str(st.ap_mode),
                armed=st.armed,
                mission=st.mission_state.name,
                progress_pct=st.mission_progress_pct,
                fleet=st.fleet_id,
                battery_pct=st.battery_pct,
                battery_v=round(st.battery_v, 2),
                gps=f"{st.gps_fix.name}/{st.gps_sats}",
                gps_short=f"{GPS_SHORT.get(st.gps_fix.name, '?')}/{st.gps_sats}",
                lat=round(st.lat_deg, 7),
                lon=round(st.lon_deg, 7),
                alt_rel_m=round(st.alt_rel_m, 1),
                groundspeed_m_s=round(st.groundspeed_m_s, 1),
                heading_deg=round(st.heading_deg),
                alerts=flag_names(st.alerts),
                alert_bits=int(st.alerts),
                data_age_s=data_age_s(st, now_unix),
            )
            gone = lost_fields(st, info, row["age_s"])
            if gone:
                row.update(gone, fsm="LOST")
        rows.append(row)
    return rows


COLUMNS = [  # (row key, header) of the 100-column table
    ("id", "id"),
    ("type", "type"),
    ("fsm", "state"),
    ("mission", "mission"),
    ("mode", "mode"),
    ("armed", "A"),
    ("fleet", "fl"),
    ("battery_pct", "bat"),
    ("gps", "gps"),
    ("position", "position"),
    ("alt_rel_m", "alt"),
    ("groundspeed_m_s", "gs"),
    ("heading_deg", "hdg"),
    ("age_s", "age"),
    ("data_age_s", "data"),
    # the active conditions: a line under the table per vehicle (the row in red)
]
TYPE_SHORT = {
    "VTOL": "VTOL",
    "PLANE": "PLN",
    "COPTER": "COPT",
    "ROVER": "ROVR",
    "BOAT": "BOAT",
    "OTHER": "?",
    "GCS": "GCS",
    "MANNED": "MAN",
}
FSM_SHORT = {"INACTIVE": "INACT", "PLAN": "PLAN", "GO_MISSION": "GO", "EMERGENCY": "EMERG"}
MISSION_SHORT = {
    "IDLE": "-",
    "PLANNING": "plan",
    "VOTING": "vote",
    "PREMISSION": "pre",
    "MISSION": "msn",
    "PARACHUTE": "chute",
    "SENDING_MISSION": "send",
    "WAITING_MISSION": "wait",
    "REPLAN": "replan",
}
GPS_SHORT = {
    "NO_GPS": "none",
    "NO_FIX": "nofix",
    "FIX_2D": "2D",
    "FIX_3D": "3D",
    "DGPS": "DGPS",
    "RTK_FLOAT": "RTKf",
    "RTK_FIXED": "RTK",
    "STATIC": "stat",
}
#: the alert flags as the table shows them (docs/ground-station.md has the legend)
FLAG_SHORT = {
    AlertFlag.BATTERY_LOW: "batt",
    AlertFlag.BATTERY_CRITICAL: "BATT!",
    AlertFlag.GPS_LOSS: "gps",
    AlertFlag.EKF_FAILURE: "ekf",
    AlertFlag.AUTOPILOT_LINK_LOSS: "aplink",
    AlertFlag.GEOFENCE_BREACH: "fence",
    AlertFlag.ATTITUDE_ABNORMAL: "att",
    AlertFlag.COLLISION_RISK: "coll",
    AlertFlag.SWARM_LINK_LOSS: "swarm",
    AlertFlag.NO_FLY_ZONE: "nfz",
    AlertFlag.AUTOPILOT_MISMATCH: "AP≠db",
    AlertFlag.IDENTITY_CONFLICT: "ID!",
}


def _short_flags(flags: AlertFlag) -> str:
    return ",".join(v for f, v in FLAG_SHORT.items() if f in flags)


def _cells(row: dict[str, Any]) -> list[str]:
    """A JSON row as the table's cells."""

    def g(key: str) -> Any:
        return row.get(key)

    mission = g("mission")
    if mission is not None:
        short = MISSION_SHORT.get(mission, mission[:6])
        mission = short if mission == "IDLE" else f"{short} {g('progress_pct')}%"
    lat, lon = g("lat"), g("lon")
    alerts = _short_flags(AlertFlag(g("alert_bits") or 0))
    if g("autopilot_mismatch") and "AP≠db" not in alerts:
        alerts = ",".join(x for x in (alerts, "AP≠db") if x)
    data = g("data_age_s")
    cells = {
        "id": str(g("id")),
        "type": TYPE_SHORT.get(g("type"), g("type")),
        "fsm": FSM_SHORT.get(g("fsm"), g("fsm")),
        "mission": mission or "",
        "mode": (g("mode") or "")[:9],
        "armed": "" if g("armed") is None else ("A" if g("armed") else "-"),
        "fleet": "" if g("fleet") is None else str(g("fleet")),
        "battery_pct": ""
        if g("battery_pct") is None
        else ("?" if g("battery_pct") < 0 else str(g("battery_pct"))),
        "gps": "" if g("gps") is None else g("gps_short"),
        "position": "" if lat is None else f"{lat:.5f},{lon:.5f}",
        "alt_rel_m": "" if g("alt_rel_m") is None else f"{g('alt_rel_m'):.0f}",
        "groundspeed_m_s": "" if g("groundspeed_m_s") is None else f"{g('groundspeed_m_s'):.0f}",
        "heading_deg": "" if g("heading_deg") is None else str(g("heading_deg")),
        "alert_names": alerts,
        "age_s": ""
        if g("age_s") is None
        else (f"{g('age_s'):.1f}" if g("age_s") < 10 else f"{g('age_s'):.0f}"),
        "data_age_s": "" if data is None else (f"{data:.0f}" if data >= 10 else f"{data:.1f}"),
    }
    return [cells[k] for k, _ in COLUMNS] + [cells["alert_names"]]


def fleet_table(
    view: FleetView,
    title: str = "fleet",
    shown: Selector | None = None,
    *,
    rates: bool = False,
    lost: dict[int, dict[str, Any]] | None = None,
) -> Group:
    """The fleet, one line per vehicle, in 100 columns (with `rates`, the packets per
    second heard from each vehicle too: `gcs watch`), and under it one line per vehicle
    with active conditions (flags: FLAG_SHORT)."""
    table = Table(
        title=title, box=box.SIMPLE_HEAD, pad_edge=False, padding=(0, 0), title_justify="left"
    )
    for key, header in COLUMNS:
        right = key in (
            "id",
            "battery_pct",
            "alt_rel_m",
            "groundspeed_m_s",
            "heading_deg",
            "age_s",
            "data_age_s",
            "fleet",
        )
        table.add_column(header, justify="right" if right else "left", no_wrap=True)
    if rates:
        table.add_column("pkt/s", justify="right", no_wrap=True)
    now = time.monotonic()
    notes: list[Text] = []
    for row in fleet_rows(view, lost):
        if shown is not None and not shown.addresses(row["id"], row.get("fleet") or 0):
            continue
        *cells, names = _cells(row)
        if rates:
            cells.append(f"{view.packets_per_s(row['id'], now):.1f}")
        bad = row.get("alert_bits") or row.get("autopilot_mismatch") or row.get("untrusted")
        style = "red" if bad else ("dim" if not row["alive"] else None)
        table.add_row(*cells, style=style)
        if names:
            notes.append(Text(f"{row['id']:>5} ! {names}", style="red"))
        if row.get("untrusted"):
            notes.append(Text(f"{row['id']:>5} ! untrusted: {row['untrusted']}", style="red"))
        if row.get("lost"):
            notes.append(Text(f"{row['id']:>5} ! {lost_note(row)}", style="red"))
    return Group(table, *notes)


def lost_note(row: dict[str, Any]) -> str:
    """A lost vehicle's line: its last position, how long ago, where it is predicted."""
    last, p = row["last"], row.get("predicted")
    text = (
        f"LOST {last['age_s']:.0f} s: last {last['lat']:.5f},{last['lon']:.5f} "
        f"{last['alt_rel_m']:.0f} m"
    )
    if p:
        text += (
            f"; predicted {p['lat']:.5f},{p['lon']:.5f} {p['alt_rel_m']:.0f} m "
            f"±{p['error_m']:.0f} m ({p['phase']})"
        )
    return text


def ack_table(acks: list[Ack], title: str) -> Table:
    table = Table(title=title)
    for col in ("vehicle", "accepted", "reason", "why"):
        table.add_column(col)
    for a in sorted(acks, key=lambda a: a.vehicle_id):
        table.add_row(
            str(a.vehicle_id),
            "yes" if a.accepted else "NO",
            a.reason.name,
            ack_text(a),
            style=None if a.accepted else "red",
        )
    return table
