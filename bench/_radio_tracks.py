"""Tracks for the radio-scale benchmark: the demo's mission flown in fast time.

`demo_flight()` flies the demo's survey (its field and no-fly zone, the default fleet of
three Albatross VTOLs and two quadcopters) in FastFleet, the real node cores on
simulated ArduPilot vehicles, from take-off to landing, and keeps every VehicleStatus
each node published (5 Hz): the vehicles' own view of where they were, the truth the
radio's belief is measured against. `Swarm` makes n vehicles of it: vehicle i flies
demo vehicle i mod 5's track from a different moment of its flight (spread over the
whole flight) and a different place, so that at any instant a swarm of 14, 25 or 50
has vehicles climbing out, in transit, on survey lanes, turning, returning and landing.

A track is sampled between its statuses by interpolating position and velocity
linearly (the chord of an 18 m/s turn of 60 m radius between 200 ms samples is 3 cm off
the arc).
"""

from __future__ import annotations

import bisect
import math
from dataclasses import dataclass

import msgspec

from swarm_proto import VehicleStatus


@dataclass(frozen=True)
class Track:
    vehicle_id: int  # in the demo
    times: tuple[float, ...]  # seconds from the start of the flight
    statuses: tuple[VehicleStatus, ...]

    @property
    def duration_s(self) -> float:
        return self.times[-1] - self.times[0]

    def at(self, t: float) -> VehicleStatus:
        """The status at `t` seconds into the flight (clamped to the flight)."""
        ts = self.times
        t = min(max(t, ts[0]), ts[-1])
        i = max(1, bisect.bisect_left(ts, t))
        a, b = self.statuses[i - 1], self.statuses[i]
        span = ts[i] - ts[i - 1]
        u = 0.0 if span <= 0 else (t - ts[i - 1]) / span

        def mix(x: float, y: float) -> float:
            return x + (y - x) * u

        return msgspec.structs.replace(
            b if u > 0.5 else a,
            lat_deg=mix(a.lat_deg, b.lat_deg),
            lon_deg=mix(a.lon_deg, b.lon_deg),
            alt_msl_m=mix(a.alt_msl_m, b.alt_msl_m),
            alt_rel_m=mix(a.alt_rel_m, b.alt_rel_m),
            vel_north_m_s=mix(a.vel_north_m_s, b.vel_north_m_s),
            vel_east_m_s=mix(a.vel_east_m_s, b.vel_east_m_s),
            vel_down_m_s=mix(a.vel_down_m_s, b.vel_down_m_s),
        )


def demo_flight() -> dict[int, Track]:
    """Fly the demo's survey in FastFleet; every vehicle's published statuses, take-off
    (first armed) to landing (last armed, plus 5 s)."""
    from swarm_node.database import seed_fleet
    from swarm_proto import (
        Command,
        CommandArgs,
        CommandKind,
        FsmState,
        GeoPoint,
        Mission,
        MissionParams,
        MissionType,
        Selector,
    )
    from swarm_sim.demo import DEFAULT_FLEET, demo_area
    from swarm_sim.fast_fleet import SITL_HOME, FastFleet

    profiles = {p.vehicle_id: p for p in seed_fleet()}
    members = list(DEFAULT_FLEET)
    fleet = FastFleet.build(members, profiles)
    fleet.run_until(lambda: all(v.link.state.ekf_has_position for v in fleet.vehicles.values()), 60)
    base = GeoPoint(SITL_HOME.lat_deg, SITL_HOME.lon_deg, SITL_HOME.alt_m)
    gcs = 900
    fleet.broadcast(Command(gcs, 1, CommandKind.SET_BASE, args=CommandArgs(point=base)))
    fleet.run_for(2.0)
    area, zone = demo_area()
    fleet.broadcast(zone)
    params = MissionParams(altitude_rel_m=60.0, side_overlap=0.6)
    fleet.broadcast(Mission(7, gcs, MissionType.AREA, area, params, Selector.ids(*members)))
    t0 = fleet.now
    fleet.run_until(
        lambda: (
            fleet.now > t0 + 60
            and all(v.node.fsm.state == FsmState.INACTIVE for v in fleet.vehicles.values())
        ),
        900,
    )
    tracks: dict[int, Track] = {}
    for vid in members:
        sts = [(t, m) for t, v, m in fleet.published if v == vid and isinstance(m, VehicleStatus)]
        armed = [t for t, m in sts if m.armed]
        if not armed:
            continue
        lo, hi = armed[0] - 2.0, armed[-1] + 5.0
        kept = [(t, m) for t, m in sts if lo <= t <= hi]
        dedup: list[tuple[float, VehicleStatus]] = []
        for t, m in kept:
            if not dedup or t > dedup[-1][0]:
                dedup.append((t, m))
        start = dedup[0][0]
        tracks[vid] = Track(vid, tuple(t - start for t, _ in dedup), tuple(m for _, m in dedup))
    return tracks


def synthetic_tracks(count: int = 5, duration_s: float = 120.0, seed: int = 0) -> dict[int, Track]:
    """Fixed-wing tracks without a simulator (for quick tests): 18 m/s, straight legs and
    60-120 m orbits of 8-15 s each, some climbing, every acceleration within 5.4 m/s^2;
    statuses at 5 Hz."""
    import random

    from radio_gateway.core.deadreckon import Kinematics, predict

    lat0, lon0 = 37.4112, -5.9889
    mlat = 111_132.0
    mlon = 111_320.0 * math.cos(math.radians(lat0))
    out: dict[int, Track] = {}
    for v in range(1, count + 1):
        rng = random.Random(seed * 1000 + v)
        heading = rng.uniform(0, 2 * math.pi)
        k = Kinematics(
            0.0,
            rng.uniform(-500, 500),
            rng.uniform(-500, 500),
            rng.uniform(60, 150),
            18.0 * math.cos(heading),
            18.0 * math.sin(heading),
            0.0,
            0.0,
        )
        segs: list[Kinematics] = []
        t, orbit = 0.0, rng.random() < 0.5
        while t < duration_s + 1:
            w = rng.choice((-1, 1)) * 18.0 / rng.uniform(60, 120) if orbit else 0.0
            vz = rng.choice((0.0, 0.0, 1.5, -1.5))
            k = Kinematics(k.t, k.x, k.y, k.z, k.vx, k.vy, vz, w)
            segs.append(k)
            t += rng.uniform(8, 15)
            k = predict(k, t)
            orbit = not orbit
        times, statuses = [], []
        for i in range(int(duration_s * 5) + 1):
            ts = i * 0.2
            seg = segs[0]
            for sg in segs:
                if sg.t > ts:
                    break
                seg = sg
            p = predict(seg, ts)
            times.append(ts)
            statuses.append(
                VehicleStatus(
                    vehicle_id=v,
                    time_unix_s=ts,
                    lat_deg=lat0 + p.y / mlat,
                    lon_deg=lon0 + p.x / mlon,
                    alt_msl_m=p.z,
                    alt_rel_m=p.z - 10.0,
                    vel_north_m_s=p.vy,
                    vel_east_m_s=p.vx,
                    vel_down_m_s=-p.vz,
                    heading_deg=math.degrees(math.atan2(p.vx, p.vy)) % 360.0,
                    armed=True,
                    battery_pct=80,
                )
            )
        out[v] = Track(v, tuple(times), tuple(statuses))
    return out


@dataclass
class Swarm:
    """n vehicles flying the demo's tracks, each from its own moment and place."""

    tracks: dict[int, Track]
    n: int
    t0: float  # the swarm's clock when the window starts
    window_s: float

    def __post_init__(self) -> None:
        self._src = sorted(self.tracks)
        self._phase: dict[int, float] = {}
        self._shift: dict[int, tuple[float, float]] = {}
        for i in range(self.n):
            tr = self.tracks[self._src[i % len(self._src)]]
            usable = max(0.0, tr.duration_s - self.window_s)
            # spread the starting moments over the whole flight (golden-ratio steps)
            self._phase[i + 1] = usable * ((i * 0.618_033_988_75) % 1.0)
            ring, k = divmod(i, len(self._src))
            self._shift[i + 1] = (0.004 * k, 0.004 * ring)  # degrees: ~450 m apart

    def vehicle(self, vid: int, t: float) -> VehicleStatus:
        """Vehicle `vid`'s status at swarm time `t`."""
        tr = self.tracks[self._src[(vid - 1) % len(self._src)]]
        s = tr.at(self._phase[vid] + (t - self.t0))
        dlat, dlon = self._shift[vid]
        return msgspec.structs.replace(
            s,
            vehicle_id=vid,
            time_unix_s=t,
            lat_deg=s.lat_deg + dlat,
            lon_deg=s.lon_deg + dlon,
        )


def position_error_m(a: VehicleStatus, b: VehicleStatus) -> float:
    """3-D distance between two statuses' positions (local flat earth: metres)."""
    mlat = 111_132.0
    mlon = 111_320.0 * math.cos(math.radians(a.lat_deg))
    return math.sqrt(
        ((a.lat_deg - b.lat_deg) * mlat) ** 2
        + ((a.lon_deg - b.lon_deg) * mlon) ** 2
        + (a.alt_msl_m - b.alt_msl_m) ** 2
    )
