"""Flight recorder for a running node (`swarm-node run --record PATH`): every
VehicleStatus heard on the swarm, its own included, appended to a trajectory CSV
(`time_s,vehicle,lat,lon,alt_m,...`, see swarm_proto/trajectory.py) at the sample's GPS
time. Several nodes recording the same swarm write the same rows; one is enough. A
radio peer's status predicted by its gateway (`predicted_s > 0`) is a belief,
not a sample: it is not recorded."""

from __future__ import annotations

import threading
from pathlib import Path

import msgspec

from swarm_proto import VehicleStatus
from swarm_proto.session import SwarmBus
from swarm_proto.topics import STATUS
from swarm_proto.trajectory import TrajectoryWriter

EXTRA = ("alt_rel_m", "vel_north_m_s", "vel_east_m_s", "vel_down_m_s")


class StatusRecorder:
    def __init__(self, path: Path | str) -> None:
        self.writer = TrajectoryWriter(path, extra_columns=EXTRA)
        self._lock = threading.Lock()
        self._closed = False

    def attach(self, bus: SwarmBus) -> None:
        bus.subscribe(STATUS, self.on_message)

    def on_message(self, msg: msgspec.Struct, key: str = "") -> None:
        if isinstance(msg, VehicleStatus) and msg.predicted_s == 0.0:
            with self._lock:
                if not self._closed:  # a late callback after close is dropped
                    self.writer.write_status(msg)

    def close(self) -> None:
        with self._lock:
            self._closed = True
            self.writer.close()
