"""The flight recorder's trajectory CSV: one row per vehicle and sample.

    time_s,vehicle,lat,lon,alt_m[,more columns]
    12.400,3,40.41680123,-3.70380456,712.25

`time_s` seconds (any epoch, the same for every row of a file: the node writes GPS UNIX
time, the simulator seconds since the start), `vehicle` the vehicle id, `lat`/`lon`
WGS84 degrees, `alt_m` metres above mean sea level. More columns may follow the first
five; readers ignore the ones they do not know.

Written by the simulator (`swarm_sim.core.pointmass`, `swarm-sim` scenarios) and by
the node (`swarm-node run --record PATH`); read by `gcs analyze separation`.
"""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from types import TracebackType
from typing import TextIO

import numpy as np
import numpy.typing as npt

from .messages import VehicleStatus

COLUMNS = ("time_s", "vehicle", "lat", "lon", "alt_m")
HEADER = ",".join(COLUMNS)


class TrajectoryError(ValueError):
    """A trajectory file that cannot be read; the message is one line, for people."""


class TrajectoryWriter:
    """Appends rows to a trajectory CSV (header first); flushes every `flush_every` rows
    so a crash loses little. Use as a context manager or call `close()`."""

    def __init__(
        self,
        path: Path | str,
        extra_columns: Sequence[str] = (),
        *,
        flush_every: int = 50,
    ) -> None:
        self.path = Path(path)
        self.extra_columns = tuple(extra_columns)
        self._file: TextIO = self.path.open("w", newline="", encoding="utf-8")
        self._writer = csv.writer(self._file, lineterminator="\n")
        self._writer.writerow((*COLUMNS, *self.extra_columns))
        self._flush_every = max(1, flush_every)
        self._pending = 0
        self.rows = 0

    def write(
        self, time_s: float, vehicle: int, lat: float, lon: float, alt_m: float, *extra: object
    ) -> None:
        if len(extra) != len(self.extra_columns):
            raise ValueError(f"expected {len(self.extra_columns)} extra values, got {len(extra)}")
        self._writer.writerow(
            (f"{time_s:.3f}", int(vehicle), f"{lat:.8f}", f"{lon:.8f}", f"{alt_m:.3f}", *extra)
        )
        self.rows += 1
        self._pending += 1
        if self._pending >= self._flush_every:
            self.flush()

    def write_rows(self, rows: Iterable[tuple[float, int, float, float, float]]) -> None:
        for row in rows:
            self.write(*row)

    def write_status(self, s: VehicleStatus) -> None:
        """A VehicleStatus at its own time (GPS UNIX seconds); extra columns, if any,
        are filled from the status fields of the same name."""
        extra = tuple(getattr(s, c, "") for c in self.extra_columns)
        self.write(s.time_unix_s, s.vehicle_id, s.lat_deg, s.lon_deg, s.alt_msl_m, *extra)

    def flush(self) -> None:
        self._file.flush()
        self._pending = 0

    def close(self) -> None:
        if not self._file.closed:
            self._file.close()

    def __enter__(self) -> TrajectoryWriter:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()


@dataclass(frozen=True)
class Trajectory:
    """Columns of a trajectory file, rows in file order."""

    time_s: npt.NDArray[np.float64]
    vehicle: npt.NDArray[np.int64]
    lat: npt.NDArray[np.float64]
    lon: npt.NDArray[np.float64]
    alt_m: npt.NDArray[np.float64]

    @property
    def vehicles(self) -> list[int]:
        return sorted({int(v) for v in self.vehicle})


def parse_trajectory(text: str, name: str = "trajectory") -> Trajectory:
    """Parse CSV text; raises TrajectoryError (one line, with the row number) on a
    missing column, a non-number, a non-finite or out-of-range value, or no rows."""
    reader = csv.reader(io.StringIO(text))
    try:
        header = next(reader)
    except StopIteration:
        raise TrajectoryError(f"{name}: empty file (want the header {HEADER})") from None
    header = [h.strip() for h in header]
    missing = [c for c in COLUMNS if c not in header]
    if missing:
        raise TrajectoryError(f"{name}: missing column(s) {', '.join(missing)} (header {HEADER})")
    idx = [header.index(c) for c in COLUMNS]
    cols: list[list[float]] = [[] for _ in COLUMNS]
    for line_no, row in enumerate(reader, start=2):
        if not row or all(not cell.strip() for cell in row):
            continue
        if len(row) < len(header):
            raise TrajectoryError(
                f"{name}:{line_no}: {len(row)} fields, the header has {len(header)}"
            )
        for k, (col, i) in enumerate(zip(COLUMNS, idx, strict=True)):
            cell = row[i].strip()
            try:
                value = float(cell)
            except ValueError:
                raise TrajectoryError(f"{name}:{line_no}: {col} {cell!r} is not a number") from None
            if not math.isfinite(value):
                raise TrajectoryError(f"{name}:{line_no}: {col} is {cell}")
            cols[k].append(value)
        vehicle, lat, lon = cols[1][-1], cols[2][-1], cols[3][-1]
        if vehicle != int(vehicle) or vehicle < 0:
            raise TrajectoryError(f"{name}:{line_no}: vehicle {row[idx[1]]!r} is not an id")
        if not (-90.0 <= lat <= 90.0 and -180.0 <= lon <= 180.0):
            raise TrajectoryError(f"{name}:{line_no}: position ({lat}, {lon}) out of range")
    if not cols[0]:
        raise TrajectoryError(f"{name}: no samples after the header")
    return Trajectory(
        np.array(cols[0]),
        np.array(cols[1], dtype=np.int64),
        np.array(cols[2]),
        np.array(cols[3]),
        np.array(cols[4]),
    )


def read_trajectory(path: Path | str) -> Trajectory:
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise TrajectoryError(
            f"{p}: cannot read: {getattr(exc, 'strerror', None) or exc}"
        ) from None
    return parse_trajectory(text, str(p))
