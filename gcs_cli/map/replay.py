"""Replay: a flight recorder CSV (`gcs record`, the demo's flight.csv, `swarm-node run
--record`) played on the map with a time slider and a speed.

`read_flight` turns the file's rows into VehicleStatus messages (the columns the
recorder writes beyond the first five are used when present: alt_rel_m,
groundspeed_m_s, heading_deg, battery_pct, fsm, mission, progress_pct, armed); a file
that cannot be used is one line (`TrajectoryError`). `Player` is the replay's clock,
with wall time passed in: `advance(wall_now)` returns the samples whose time has come,
`seek(t)` says the map must be rebuilt from the samples of the trail window before `t`.
"""

from __future__ import annotations

import bisect
import csv
import io
import math
from dataclasses import dataclass, field
from enum import Enum
from pathlib import Path
from typing import TypeVar

from swarm_proto import FsmState, MissionState, VehicleStatus
from swarm_proto.trajectory import TrajectoryError, parse_trajectory

E = TypeVar("E", bound=Enum)
SPEEDS = (0.25, 0.5, 1.0, 2.0, 5.0, 10.0, 30.0, 60.0)


def _cell(row: dict[str, str], col: str, where: str) -> float | None:
    text = (row.get(col) or "").strip()
    if text == "":
        return None
    try:
        x = float(text)
    except ValueError:
        raise TrajectoryError(f"{where}: {col} {text!r} is not a number") from None
    if not math.isfinite(x):
        raise TrajectoryError(f"{where}: {col} is {text}")
    return x


def _int_cell(row: dict[str, str], col: str, where: str) -> int | None:
    x = _cell(row, col, where)
    return None if x is None else int(x)


def _enum(row: dict[str, str], col: str, enum: type[E], where: str) -> E | None:
    text = (row.get(col) or "").strip()
    if text == "":
        return None
    try:
        return enum[text]
    except KeyError:
        names = ", ".join(e.name for e in enum)
        raise TrajectoryError(f"{where}: {col} {text!r} is not one of {names}") from None


def read_flight(path: Path) -> list[VehicleStatus]:
    """Every sample of a flight CSV as a VehicleStatus, in time order."""
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise TrajectoryError(
            f"{path}: cannot read: {getattr(exc, 'strerror', None) or exc}"
        ) from None
    parse_trajectory(text, str(path))  # the five columns checked, one line per problem
    out = []
    for n, row in enumerate(csv.DictReader(io.StringIO(text)), start=2):
        if not any((v or "").strip() for v in row.values()):
            continue
        row = {(k or "").strip(): v for k, v in row.items()}
        where = f"{path}:{n}"
        heading = _cell(row, "heading_deg", where) or 0.0
        speed = _cell(row, "groundspeed_m_s", where) or 0.0
        battery = _int_cell(row, "battery_pct", where)
        progress = _int_cell(row, "progress_pct", where)
        armed = _int_cell(row, "armed", where)
        fsm = _enum(row, "fsm", FsmState, where)
        mission = _enum(row, "mission", MissionState, where)
        alt = float(row["alt_m"])
        out.append(
            VehicleStatus(
                vehicle_id=int(float(row["vehicle"])),
                time_unix_s=max(0.0, float(row["time_s"])),
                lat_deg=float(row["lat"]),
                lon_deg=float(row["lon"]),
                alt_msl_m=alt,
                alt_rel_m=_cell(row, "alt_rel_m", where) or 0.0,
                vel_north_m_s=speed * math.cos(math.radians(heading)),
                vel_east_m_s=speed * math.sin(math.radians(heading)),
                heading_deg=heading % 360.0,
                battery_pct=max(-1, min(100, battery)) if battery is not None else -1,
                armed=bool(armed) if armed is not None else speed > 0.5,
                fsm_state=fsm if fsm is not None else FsmState.INACTIVE,
                mission_state=mission if mission is not None else MissionState.IDLE,
                mission_progress_pct=max(0, min(100, progress or 0)),
            )
        )
    out.sort(key=lambda s: s.time_unix_s)
    return out


@dataclass
class Player:
    """The replay's position in the flight, its speed and whether it plays; wall time
    passed in."""

    samples: list[VehicleStatus]
    speed: float = 1.0
    playing: bool = True
    t: float = 0.0
    _wall: float | None = None
    _next: int = 0
    _times: list[float] = field(default_factory=list)

    def __post_init__(self) -> None:
        if not self.samples:
            raise ValueError("nothing to replay")
        self._times = [s.time_unix_s for s in self.samples]
        self.t = self.t0

    @property
    def t0(self) -> float:
        return self._times[0]

    @property
    def t1(self) -> float:
        return self._times[-1]

    def advance(self, wall_now: float) -> list[VehicleStatus]:
        """The samples from the last position to where the wall clock has taken it."""
        if self._wall is not None and self.playing:
            self.t = min(self.t1, self.t + (wall_now - self._wall) * self.speed)
            if self.t >= self.t1:
                self.playing = False
        self._wall = wall_now
        end = bisect.bisect_right(self._times, self.t)
        due = self.samples[self._next : end]
        self._next = max(self._next, end)
        return due

    def seek(self, t: float, window_s: float) -> list[VehicleStatus]:
        """Jump to `t`: the samples of the `window_s` before it (a new map is built from
        them)."""
        self.t = min(self.t1, max(self.t0, t))
        start = bisect.bisect_left(self._times, self.t - window_s)
        self._next = bisect.bisect_right(self._times, self.t)
        return self.samples[start : self._next]

    def set_speed(self, speed: float) -> None:
        if speed not in SPEEDS:
            raise ValueError(f"speed {speed:g}: one of {', '.join(f'{s:g}' for s in SPEEDS)}")
        self.speed = speed

    def state(self) -> dict[str, object]:
        return {
            "t0": self.t0,
            "t1": self.t1,
            "t": round(self.t, 3),
            "speed": self.speed,
            "playing": self.playing,
            "speeds": list(SPEEDS),
        }
