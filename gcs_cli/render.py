"""Rich rendering of what the ground station sees."""

from __future__ import annotations

import time
from typing import Any

from rich.table import Table

from swarm_proto import Ack, AlertFlag, VehicleStatus, VehicleType
from swarm_proto.ardupilot import mode_name

from .ground import FleetView


def flag_names(flags: AlertFlag) -> str:
    return ",".join(f.name.lower() for f in AlertFlag if f and f in flags and f.name) or "-"


def data_age_s(status: VehicleStatus, now_unix_s: float) -> float:
    """How old the autopilot data in a status is: its `time_unix_s` is the time of the
    autopilot's sample (GPS time), and after an autopilot link loss the node keeps
    sending the last one (issue 11): `age s` says when the ground station last heard the
    node, `data s` how old what it says is. Clamped at 0 (a vehicle clock ahead). A radio
    peer's status predicted by its gateway (issue 19) is `predicted_s` older than its
    time says."""
    return round(max(0.0, now_unix_s - status.time_unix_s) + status.predicted_s, 1)


def fleet_rows(view: FleetView) -> list[dict[str, Any]]:
    """One plain dict per vehicle (also the --json output)."""
    now = time.monotonic()
    now_unix = time.time()
    rows = []
    for vid in view.vehicle_ids():
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
        }
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
                lat=round(st.lat_deg, 7),
                lon=round(st.lon_deg, 7),
                alt_rel_m=round(st.alt_rel_m, 1),
                groundspeed_m_s=round(st.groundspeed_m_s, 1),
                heading_deg=round(st.heading_deg),
                alerts=flag_names(st.alerts),
                data_age_s=data_age_s(st, now_unix),
            )
        rows.append(row)
    return rows


COLUMNS = [
    ("id", "id"),
    ("model", "model"),
    ("fsm", "state"),
    ("mode", "mode"),
    ("armed", "armed"),
    ("mission", "mission"),
    ("progress_pct", "%"),
    ("fleet", "fleet"),
    ("battery_pct", "batt %"),
    ("gps", "gps"),
    ("alt_rel_m", "alt m"),
    ("groundspeed_m_s", "gs m/s"),
    ("heading_deg", "hdg"),
    ("alerts", "alerts"),
    ("age_s", "age s"),
    ("data_age_s", "data s"),
]


def fleet_table(view: FleetView, title: str = "fleet") -> Table:
    table = Table(title=title)
    for _, header in COLUMNS:
        table.add_column(header)
    for row in fleet_rows(view):
        cells = []
        for key, _ in COLUMNS:
            v = row.get(key)
            if key == "armed":
                v = "yes" if v else ("no" if v is not None else "")
            cells.append("" if v is None else str(v))
        style = (
            "red" if row.get("alerts") not in (None, "-") else ("dim" if not row["alive"] else None)
        )
        table.add_row(*cells, style=style)
    return table


def ack_table(acks: list[Ack], title: str) -> Table:
    table = Table(title=title)
    for col in ("vehicle", "accepted", "reason", "text"):
        table.add_column(col)
    for a in sorted(acks, key=lambda a: a.vehicle_id):
        table.add_row(
            str(a.vehicle_id),
            "yes" if a.accepted else "NO",
            a.reason.name,
            a.text,
            style=None if a.accepted else "red",
        )
    return table
