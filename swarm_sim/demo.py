"""The demo scenario: simulated vehicles publish telemetry over real Zenoh sessions on
127.0.0.1 and a ground-station session shows the fleet as it sees it."""

from __future__ import annotations

import math
import socket
import threading

from rich.console import Console
from rich.table import Table

from swarm_proto import FsmState, GpsFix, ScaledClock, VehicleStatus, validate
from swarm_proto.session import SwarmBus, ZenohSettings
from swarm_proto.topics import STATUS

HOME = (37.4112, -5.9889, 10.0)  # the reference SITL home


def free_tcp_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _status(vid: int, t: float, t0: float, n: int) -> VehicleStatus:
    radius_m, speed = 300.0, 20.0
    phase = 2 * math.pi * (vid - 1) / n + speed * (t - t0) / radius_m
    north, east = radius_m * math.cos(phase), radius_m * math.sin(phase)
    lat = HOME[0] + north / 111_320.0
    lon = HOME[1] + east / (111_320.0 * math.cos(math.radians(HOME[0])))
    vn, ve = -speed * math.sin(phase), speed * math.cos(phase)
    return VehicleStatus(
        vehicle_id=vid,
        time_unix_s=t,
        lat_deg=lat,
        lon_deg=lon,
        alt_msl_m=HOME[2] + 100.0 + 10.0 * vid,
        alt_rel_m=100.0 + 10.0 * vid,
        vel_north_m_s=vn,
        vel_east_m_s=ve,
        heading_deg=math.degrees(math.atan2(ve, vn)) % 360.0,
        airspeed_m_s=speed,
        battery_pct=max(0, 100 - int((t - t0) / 30)),
        battery_v=25.2,
        gps_fix=GpsFix.FIX_3D,
        gps_sats=14,
        armed=True,
        fsm_state=FsmState.GO_MISSION,
    )


def run_demo(vehicles: int = 4, speedup: float = 10.0, duration_s: float = 60.0) -> int:
    console = Console()
    port = free_tcp_port()
    clock = ScaledClock(speedup)
    seen: dict[int, VehicleStatus] = {}
    lock = threading.Lock()

    def on_status(msg: VehicleStatus, key: str) -> None:
        with lock:
            seen[msg.vehicle_id] = msg

    gcs = SwarmBus.open(ZenohSettings(mode="router", listen=(f"tcp/127.0.0.1:{port}",)))
    fleet = SwarmBus.open(ZenohSettings(connect=(f"tcp/127.0.0.1:{port}",)))
    try:
        gcs.subscribe(STATUS, on_status)
        t0 = clock.now()
        console.print(
            f"[bold]bandada demo[/]: {vehicles} vehicles, {speedup:g}x, Zenoh on 127.0.0.1:{port}"
        )
        while clock.now() - t0 < duration_s:
            now = clock.now()
            for vid in range(1, vehicles + 1):
                msg = _status(vid, now, t0, vehicles)
                validate(msg)
                fleet.publish(msg)
            clock.sleep(0.2)
        clock.sleep(0.5)
    finally:
        fleet.close()
        gcs.close()
    table = Table(title="fleet as seen by the ground station")
    for col in ("id", "lat", "lon", "alt rel m", "gs m/s", "hdg", "batt %", "state"):
        table.add_column(col)
    with lock:
        for vid, s in sorted(seen.items()):
            table.add_row(
                str(vid),
                f"{s.lat_deg:.6f}",
                f"{s.lon_deg:.6f}",
                f"{s.alt_rel_m:.1f}",
                f"{s.groundspeed_m_s:.1f}",
                f"{s.heading_deg:.0f}",
                str(s.battery_pct),
                s.fsm_state.name,
            )
    console.print(table)
    ok = len(seen) == vehicles
    console.print(
        "[green]all vehicles seen[/]" if ok else f"[red]only {len(seen)}/{vehicles} seen[/]"
    )
    return 0 if ok else 1
