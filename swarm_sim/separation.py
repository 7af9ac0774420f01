"""The paper's separation experiments (section 4, tables 2 and 3) and the stress case,
flown in fast time by FastFleet (simulated ArduPilot vehicles, the real autopilot link
and node cores, real MAVLink bytes), with collision avoidance on or off, measured as
the paper does (`gcs analyze separation` on the flight recorder's trajectory).

    exp1_six_vtol            six Albatross 250 VTOLs on pads 30 m apart: an area survey
                             by all six, re-tasked while it flies: a target orbit (1),
                             a perimeter patrol (2, 3), a route (4); 5 and 6 finish the
                             area (replanned among them); then home to the pads
    exp2_takeoff_three_vtol  three VTOLs on pads 8 m apart in a line, one route mission
                             released to all three in the same instant
    stress_eight_headon      eight fixed-wing aircraft on a 1 km circle, each sent on a
                             route through its centre to the opposite side at one
                             altitude, all in the same instant: head-on at one point

Voting is not wired into the node yet: experiment 1's re-tasking is a
sequence of missions addressed to listed vehicles (`Selector.ids`), not QUANTITY
missions voted on.

Counts are over the whole record (from the first mission to the last vehicle down, as
the paper counts) and "once airborne" (samples of pairs where both are armed and above
1 m: pads 8 m apart are a danger-band pair on the ground).
"""

from __future__ import annotations

import math
import tempfile
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import msgspec

from gcs_cli.separation import SeparationReport, analyze
from swarm_node.core.node import NodeSettings
from swarm_node.core.profile import VehicleProfile
from swarm_proto import (
    Alert,
    AlertCode,
    Command,
    CommandArgs,
    CommandKind,
    FsmState,
    Geometry,
    GeometryKind,
    GeoPoint,
    LatLon,
    Mission,
    MissionParams,
    MissionType,
    Selector,
    VehicleIntent,
    VehicleType,
    geodesy,
)
from swarm_proto.trajectory import read_trajectory

from .core import SITL_HOME, Home
from .fast_fleet import FastFleet
from .recording import Row, status_rows, write_trajectory

GCS = 900
SCENARIOS = ("exp1_six_vtol", "exp2_takeoff_three_vtol", "stress_eight_headon")


@dataclass
class SeparationRun:
    name: str
    avoid: bool
    whole: SeparationReport  # from the first mission until every vehicle is down
    airborne: SeparationReport  # pairs counted only while both are airborne
    landed: frozenset[int]  # vehicles back on the ground, disarmed, state machine done
    completed: frozenset[int]  # vehicles that reported MISSION_COMPLETE
    duration_s: float  # simulated
    wall_s: float
    manoeuvres: int  # avoidance climbs/levels/stops alerted
    takeoff_waits: int  # launches held for a neighbour (pads.py)
    intent: bool = True  # members published their next legs, avoidance predicted along them
    intents: int = 0  # VehicleIntent messages published
    notes: list[tuple[float, int, str]] = field(default_factory=list)

    def figures(self) -> dict[str, Any]:
        tot, air = self.whole.totals(), self.airborne.totals()
        return {
            "min_sep_m": _r(self.whole.min_sep_m),
            "risk": tot["risk"],
            "danger": tot["danger"],
            "near": tot["near"],
            "airborne": {
                "min_sep_m": _r(self.airborne.min_sep_m),
                "risk": air["risk"],
                "danger": air["danger"],
                "near": air["near"],
            },
            "pair_samples": tot["samples"],
            "flight_s": round(self.duration_s, 1),
            "landed": len(self.landed),
            "manoeuvres": self.manoeuvres,
            "takeoff_waits": self.takeoff_waits,
            "intents": self.intents,
        }


def _r(x: float) -> float | None:
    return None if math.isnan(x) else round(x, 2)


def plane_profile(vid: int, like: VehicleProfile) -> VehicleProfile:
    """A fixed-wing aircraft flown by the simulator's generic plane (22 m/s cruise)."""
    return msgspec.structs.replace(
        like,
        vehicle_id=vid,
        user_id=f"FW-{vid:02d}",
        model="generic fixed-wing",
        vehicle_type=VehicleType.PLANE,
        cruise_speed_m_s=22.0,
        min_speed_m_s=12.0,
        max_speed_m_s=30.0,
        loiter_radius_m=60.0,
        hover_current_a=0.0,
    )


def _polyline(*pts: tuple[float, float]) -> Geometry:
    return Geometry(GeometryKind.POLYLINE, tuple(LatLon(a, b) for a, b in pts))


def _square(lat: float, lon: float, half_m: float) -> Geometry:
    corners = [(-half_m, -half_m), (-half_m, half_m), (half_m, half_m), (half_m, -half_m)]
    return Geometry.polygon([geodesy.offset(lat, lon, n, e) for n, e in corners])


def _at(north_m: float, east_m: float) -> tuple[float, float]:
    return geodesy.offset(SITL_HOME.lat_deg, SITL_HOME.lon_deg, north_m, east_m)


Step = tuple[Callable[[FastFleet], bool], Callable[[FastFleet], None]]  # when, then


def _fly(
    name: str,
    fleet: FastFleet,
    steps: Sequence[Step],
    *,
    avoid: bool,
    timeout_s: float,
    record: Path | None = None,
    intent: bool = True,
    done: Callable[[FastFleet, float], bool] | None = None,
) -> SeparationRun:
    """Set the base, then carry out `steps` in order (each when its condition holds)
    until every vehicle is down and its state machine done, or `timeout_s`."""
    wall = time.perf_counter()
    fleet.run_until(lambda: all(v.link.state.ekf_has_position for v in fleet.vehicles.values()), 60)
    base = GeoPoint(SITL_HOME.lat_deg, SITL_HOME.lon_deg, SITL_HOME.alt_m)
    fleet.broadcast(Command(GCS, 1, CommandKind.SET_BASE, args=CommandArgs(point=base)))
    fleet.run_until(
        lambda: all(v.node.fsm.state == FsmState.GO_MISSION for v in fleet.vehicles.values()), 30
    )
    t0 = fleet.now
    end = t0 + timeout_s
    todo = list(steps)

    def down() -> bool:
        if done is not None:
            return done(fleet, t0)
        return all(
            v.node.fsm.state == FsmState.INACTIVE and not v.link.state.armed
            for v in fleet.vehicles.values()
        )

    def next_or_done() -> bool:
        return todo[0][0](fleet) if todo else down()

    while fleet.now < end:
        while todo and todo[0][0](fleet):
            todo.pop(0)[1](fleet)
        if not todo and down():
            break
        fleet.run_until(next_or_done, min(30.0, end - fleet.now))
    whole = _analysed(
        status_rows(fleet.published, t0=t0),
        record,
        f"{name}-{'on' if avoid else 'off'}{'' if intent else '-no-intent'}",
    )
    airborne = _analysed(status_rows(fleet.published, t0=t0, airborne_only=True), None, "")
    alerts = [a for a in fleet.messages(Alert) if a.time_unix_s >= t0]
    landed = frozenset(
        vid
        for vid, v in fleet.vehicles.items()
        if v.node.fsm.state == FsmState.INACTIVE and not v.link.state.armed
    )
    return SeparationRun(
        name=name,
        avoid=avoid,
        whole=whole,
        airborne=airborne,
        landed=landed,
        completed=frozenset(a.vehicle_id for a in alerts if a.code == AlertCode.MISSION_COMPLETE),
        duration_s=fleet.now - t0,
        wall_s=time.perf_counter() - wall,
        manoeuvres=sum(
            1
            for a in alerts
            if a.code == AlertCode.COLLISION_RISK
            and a.text.startswith("avoid: ")
            and ("climb" in a.text or "level" in a.text or "stop" in a.text)
        ),
        takeoff_waits=sum(1 for _t, _v, n in fleet.notes if n.startswith("take-off: waiting")),
        intent=intent,
        intents=sum(1 for t, _v, m in fleet.published if t >= t0 and isinstance(m, VehicleIntent)),
        notes=[(t - t0, v, n) for t, v, n in fleet.notes if t >= t0],
    )


def _analysed(rows: list[Row], record: Path | None, stem: str) -> SeparationReport:
    """Through the flight recorder's CSV (kept in `record` when given) and the
    separation analysis, as `gcs analyze separation` does it."""
    with tempfile.TemporaryDirectory() as tmp:
        path = (record or Path(tmp)) / f"{stem or 'airborne'}.csv"
        write_trajectory(rows, path)
        return analyze(read_trajectory(path))


def _settings(avoid: bool, intent: bool = True) -> NodeSettings:
    # the take-off sequence of close pads is part of the launch, which the state machine
    # bounds with the plan timeout: 120 s covers a few neighbours (docs/avoidance.md)
    return NodeSettings(avoidance=avoid, plan_timeout_s=180.0, intent=intent)


def _all_flying(ids: Sequence[int]) -> Callable[[FastFleet], bool]:
    return lambda f: all(
        f.vehicles[i].node.manager.phase.value == "flying" for i in ids if i in f.vehicles
    )


def _send(m: Mission) -> Callable[[FastFleet], None]:
    return lambda f: f.broadcast(m)


def _after(seconds: float, since: dict[str, float], key: str) -> Callable[[FastFleet], bool]:
    def when(f: FastFleet) -> bool:
        since.setdefault(key, f.now)
        return f.now - since[key] >= seconds

    return when


def exp2_takeoff_three_vtol(
    profiles: Mapping[int, VehicleProfile],
    *,
    avoid: bool = True,
    intent: bool = True,
    timeout_s: float = 900.0,
    record: Path | None = None,
) -> SeparationRun:
    """Three Albatross VTOLs on pads 8 m apart in a line (east), one route mission
    released to all three in the same instant: they take off together."""
    members = [1, 2, 3]
    fleet = FastFleet.build(members, profiles, spacing_m=8.0, settings=_settings(avoid, intent))
    route = Mission(
        201,
        GCS,
        MissionType.ROUTE,
        _polyline(_at(400.0, -300.0), _at(900.0, 300.0)),
        MissionParams(altitude_rel_m=60.0),
    )
    return _fly(
        "exp2_takeoff_three_vtol",
        fleet,
        [(lambda f: True, _send(route))],
        avoid=avoid,
        timeout_s=timeout_s,
        record=record,
        intent=intent,
    )


def exp1_six_vtol(
    profiles: Mapping[int, VehicleProfile],
    *,
    avoid: bool = True,
    intent: bool = True,
    timeout_s: float = 2400.0,
    record: Path | None = None,
) -> SeparationRun:
    """Six Albatross VTOLs on pads 30 m apart: an area survey by all six, then, while
    it flies, a target orbit (1), a perimeter patrol (2, 3) and a route (4); 5 and 6
    inherit the rest of the area. Missions addressed to listed vehicles (no voting)."""
    members = [1, 2, 3, 4, 5, 6]
    fleet = FastFleet.build(members, profiles, spacing_m=30.0, settings=_settings(avoid, intent))
    alt = 60.0
    area = Mission(
        101,
        GCS,
        MissionType.AREA,
        _square(*_at(800.0, 75.0), 200.0),
        MissionParams(altitude_rel_m=alt),
    )
    target = Mission(
        102,
        GCS,
        MissionType.TARGET,
        Geometry.point(*_at(1000.0, 500.0)),
        MissionParams(altitude_rel_m=alt, duration_s=90.0),
        Selector.ids(1),
    )
    perimeter = Mission(
        103,
        GCS,
        MissionType.PERIMETER,
        _square(*_at(700.0, -700.0), 200.0),
        MissionParams(altitude_rel_m=alt, loops=1),
        Selector.ids(2, 3),
    )
    route = Mission(
        104,
        GCS,
        MissionType.ROUTE,
        _polyline(_at(300.0, 600.0), _at(1400.0, 900.0)),
        MissionParams(altitude_rel_m=alt),
        Selector.ids(4),
    )
    since: dict[str, float] = {}
    steps: list[Step] = [
        (lambda f: True, _send(area)),
        (_all_flying(members), lambda f: None),
        (_after(40.0, since, "retask"), _send(target)),
        (_after(60.0, since, "retask"), _send(perimeter)),
        (_after(80.0, since, "retask"), _send(route)),
    ]
    return _fly(
        "exp1_six_vtol",
        fleet,
        steps,
        avoid=avoid,
        timeout_s=timeout_s,
        record=record,
        intent=intent,
    )


def circle_homes(n: int, radius_m: float, center: tuple[float, float]) -> list[Home]:
    """`n` homes evenly on a circle, each facing its centre."""
    out = []
    for k in range(n):
        bearing = 360.0 * k / n
        b = math.radians(bearing)
        lat, lon = geodesy.offset(*center, radius_m * math.cos(b), radius_m * math.sin(b))
        out.append(Home(lat, lon, SITL_HOME.alt_m, (bearing + 180.0) % 360.0))
    return out


def stress_eight_headon(
    profiles: Mapping[int, VehicleProfile],
    *,
    avoid: bool = True,
    intent: bool = True,
    timeout_s: float = 900.0,
    radius_m: float = 500.0,
    alt_m: float = 100.0,
    record: Path | None = None,
    count: int = 8,
) -> SeparationRun:
    """Eight fixed-wing aircraft take off from runways 1.5 km out on a circle, each
    facing its centre, and are sent, all in the same instant, on a route from the 1 km
    circle (radius `radius_m`) through its centre to the opposite side, at one altitude:
    they meet head-on at the centre."""
    like = next(p for p in profiles.values() if p.vehicle_type == VehicleType.VTOL)
    members = list(range(21, 21 + count))
    planes = {vid: plane_profile(vid, like) for vid in members}
    center = _at(0.0, 0.0)
    homes = circle_homes(len(members), radius_m + 1000.0, center)
    fleet = FastFleet.build(members, planes, homes=homes, settings=_settings(avoid, intent))
    missions = []
    for k, vid in enumerate(members):
        b = math.radians(360.0 * k / len(members))
        a = geodesy.offset(*center, radius_m * math.cos(b), radius_m * math.sin(b))
        z = geodesy.offset(*center, -radius_m * math.cos(b), -radius_m * math.sin(b))
        missions.append(
            Mission(
                300 + vid,
                GCS,
                MissionType.ROUTE,
                _polyline(a, center, z),
                MissionParams(altitude_rel_m=alt_m),
                Selector.ids(vid),
            )
        )

    def send_all(f: FastFleet) -> None:
        for m in missions:
            f.broadcast(m)

    flown: set[int] = set()
    seen = [0]

    def routes_flown(f: FastFleet, t0: float) -> bool:
        # the stress is the convergence: the record ends when every route is flown (the
        # planes then circle the base, where fixed-wing aircraft wait to be landed)
        for _t, _v, m in f.published[seen[0] :]:
            if isinstance(m, Alert) and m.code == AlertCode.MISSION_COMPLETE:
                flown.add(m.vehicle_id)
        seen[0] = len(f.published)
        return flown >= set(members)

    return _fly(
        "stress_eight_headon",
        fleet,
        [(lambda f: True, send_all)],
        avoid=avoid,
        timeout_s=timeout_s,
        record=record,
        intent=intent,
        done=routes_flown,
    )


RUNS: dict[str, Callable[..., SeparationRun]] = {
    "exp1_six_vtol": exp1_six_vtol,
    "exp2_takeoff_three_vtol": exp2_takeoff_three_vtol,
    "stress_eight_headon": stress_eight_headon,
}
