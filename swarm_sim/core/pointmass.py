"""A point-mass kinematic simulation for avoidance scenarios, in fast time.

Each vehicle flies a straight path at constant ground velocity (its mission) and moves
vertically towards its commanded altitude at a bounded climb / sink rate. With
avoidance on, every vehicle runs its own `CollisionAvoider`, fed with its own fresh
state every tick and the peers' VehicleStatus every `telemetry_period_s` (so peers'
data are up to one period old, as on the swarm network at 5 Hz); the manoeuvres it
returns are applied as the autopilot would: ChangeAltitude / Goto change the target
altitude (a multirotor's Goto also stops it), SetMode HOLD stops a ground vehicle,
RESUME restores the path.

    result = run(stress_eight_headon(), duration_s=60, avoid=True)
    result.samples  # (time_s, vehicle, lat, lon, alt_msl_m) every record period

Pure (no clock, no I/O): the same inputs give the same trajectories.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from swarm_node.core.autopilot.requests import ChangeAltitude, Goto, SetMode
from swarm_node.core.safety.avoidance import (
    AvoidanceConfig,
    CollisionAvoider,
    Manoeuvre,
    ManoeuvreKind,
    Traffic,
)
from swarm_proto import VehicleInfo, VehicleStatus, VehicleType, geodesy

T0_UNIX_S = 1_700_000_000.0
ORIGIN = (40.4168, -3.7038, 650.0)  # lat, lon, home altitude MSL (Madrid)


@dataclass(frozen=True, slots=True)
class Start:
    vehicle_id: int
    vehicle_type: VehicleType
    east_m: float
    north_m: float
    alt_rel_m: float
    vel_east_m_s: float
    vel_north_m_s: float
    climb_rate_m_s: float = 5.0
    sink_rate_m_s: float = 3.0
    cooperative: bool = True  # False: no avoider, others see it as ADS-B traffic


@dataclass(slots=True)
class _Body:
    start: Start
    e: float
    n: float
    up: float
    ve: float
    vn: float
    vu: float = 0.0
    target_up: float = 0.0
    stopped: bool = False


@dataclass
class Result:
    samples: list[tuple[float, int, float, float, float]] = field(default_factory=list)
    manoeuvres: dict[int, list[Manoeuvre]] = field(default_factory=dict)
    ticks: int = 0


def stress_eight_headon(
    radius_m: float = 500.0, speed_m_s: float = 20.0, alt_rel_m: float = 100.0
) -> list[Start]:
    """Eight fixed-wing aircraft on a circle flying at its centre, all at one altitude."""
    out = []
    for i in range(8):
        ang = 2.0 * math.pi * i / 8
        e, n = radius_m * math.cos(ang), radius_m * math.sin(ang)
        out.append(
            Start(
                i + 1,
                VehicleType.PLANE,
                e,
                n,
                alt_rel_m,
                -speed_m_s * math.cos(ang),
                -speed_m_s * math.sin(ang),
            )
        )
    return out


def run(
    starts: Sequence[Start],
    *,
    duration_s: float,
    avoid: bool = True,
    dt_s: float = 0.1,
    telemetry_period_s: float = 0.2,
    adsb_period_s: float = 1.0,
    record_period_s: float = 0.2,
    origin: tuple[float, float, float] = ORIGIN,
    config: dict[str, Any] | None = None,
) -> Result:
    lat0, lon0, h0 = origin
    bodies = [
        _Body(
            s, s.east_m, s.north_m, s.alt_rel_m, s.vel_east_m_s, s.vel_north_m_s, 0.0, s.alt_rel_m
        )
        for s in starts
    ]
    avoiders = {
        b.start.vehicle_id: CollisionAvoider(
            AvoidanceConfig(b.start.vehicle_id, b.start.vehicle_type, **(config or {}))
        )
        for b in bodies
        if b.start.cooperative
    }
    result = Result(manoeuvres={b.start.vehicle_id: [] for b in bodies})
    infos = [
        VehicleInfo(
            vehicle_id=b.start.vehicle_id, vehicle_type=b.start.vehicle_type, model="", user_id=""
        )
        for b in bodies
    ]
    for av in avoiders.values():
        for info in infos:
            av.handle(info, T0_UNIX_S)
    steps = round(duration_s / dt_s)
    tel_every = max(1, round(telemetry_period_s / dt_s))
    adsb_every = max(1, round(adsb_period_s / dt_s))
    rec_every = max(1, round(record_period_s / dt_s))
    for step in range(steps + 1):
        t = step * dt_s
        now = T0_UNIX_S + t
        e = np.array([b.e for b in bodies])
        n = np.array([b.n for b in bodies])
        u = np.array([b.up for b in bodies])
        lat, lon, h = geodesy.geodetic(e, n, u, lat0, lon0, h0).T
        if step % rec_every == 0:
            for i, b in enumerate(bodies):
                result.samples.append(
                    (round(t, 6), b.start.vehicle_id, float(lat[i]), float(lon[i]), float(h[i]))
                )
        if avoid:
            statuses = [
                _status(b, float(lat[i]), float(lon[i]), float(h[i]), now)
                for i, b in enumerate(bodies)
            ]
            for i, b in enumerate(bodies):
                mine = avoiders.get(b.start.vehicle_id)
                if mine is None:
                    continue  # non-cooperative: flies on, whatever happens
                mine.handle(statuses[i], now)
                for j, s in enumerate(statuses):
                    if j == i:
                        continue
                    if bodies[j].start.cooperative and step % tel_every == 0:
                        mine.handle(s, now)
                    elif not bodies[j].start.cooperative and step % adsb_every == 0:
                        mine.handle(_traffic(s), now)
                for out in mine.on_timer(now):
                    if isinstance(out, Manoeuvre):
                        result.manoeuvres[b.start.vehicle_id].append(out)
                        _apply(b, out)
            result.ticks += 1
        for b in bodies:
            _step(b, dt_s)
    return result


def _status(b: _Body, lat: float, lon: float, h: float, now: float) -> VehicleStatus:
    ve, vn = (0.0, 0.0) if b.stopped else (b.ve, b.vn)
    return VehicleStatus(
        vehicle_id=b.start.vehicle_id,
        time_unix_s=now,
        lat_deg=lat,
        lon_deg=lon,
        alt_msl_m=h,
        alt_rel_m=b.up,
        vel_north_m_s=vn,
        vel_east_m_s=ve,
        vel_down_m_s=-b.vu,
        armed=True,
    )


def _traffic(s: VehicleStatus) -> Traffic:
    """What an ADS-B receiver would report of a vehicle (ICAO address = its id)."""
    return Traffic(
        s.vehicle_id,
        s.lat_deg,
        s.lon_deg,
        s.alt_msl_m,
        s.vel_north_m_s,
        s.vel_east_m_s,
        s.vel_down_m_s,
        s.time_unix_s,
    )


def _apply(b: _Body, m: Manoeuvre) -> None:
    for r in m.requests:
        if isinstance(r, ChangeAltitude):
            b.target_up = r.alt_rel_m
        elif isinstance(r, Goto):
            b.target_up = r.alt_rel_m
            b.stopped = True  # a multirotor holds over the point
        elif isinstance(r, SetMode) and r.mode == "HOLD":
            b.stopped = True
    if m.kind is ManoeuvreKind.RESUME:
        b.stopped = False
        if m.target_alt_rel_m is not None:
            b.target_up = m.target_alt_rel_m


def _step(b: _Body, dt: float) -> None:
    if not b.stopped:
        b.e += b.ve * dt
        b.n += b.vn * dt
    dz = b.target_up - b.up
    rate = b.start.climb_rate_m_s if dz > 0 else b.start.sink_rate_m_s
    move = max(-rate * dt, min(rate * dt, dz))
    b.vu = move / dt
    b.up += move
