"""Lost vehicles: an aircraft the ground station heard flying and hears no more is
still flying somewhere. It stays on the ground station's list (`gcs status`, the map)
as LOST with its last position, how long ago that was, and where it is predicted now
(what its autopilot does without its node: straight on until the GCS failsafe, then
RTL to its base, else its home; swarm_node/core/safety/silent.py, the nodes' own
prediction), until it is heard again, its last report says it landed (disarmed on the
ground), or the operator dismisses it (`gcs dismiss ID`, the map's Dismiss).

Pure: `LostBook` is fed what was heard and when (UNIX seconds, the caller's clock);
`store.py`'s SQLite file keeps it between `gcs` runs.
"""

from __future__ import annotations

import contextlib
import math
from dataclasses import dataclass, field
from typing import Any

from swarm_node.core.safety.avoidance import MAX_SPEED_M_S
from swarm_node.core.safety.silent import SilentAircraft
from swarm_node.core.safety.ttc import BadTrackError, Track
from swarm_proto import VehicleInfo, VehicleStatus, VehicleType

LOST_AFTER_S = 5.0  # not heard for longer: lost (as the ground station counts alive)
PARKED_ALT_M = 2.0  # disarmed and lower than this above home: on the ground


class NotLostError(ValueError):
    """A dismissal of a vehicle that is not on the lost list (one line)."""


def landed(status: VehicleStatus) -> bool:
    """Its report says it is on the ground, motors off."""
    return not status.armed and status.alt_rel_m < PARKED_ALT_M


def predicted(status: VehicleStatus, info: VehicleInfo | None, age_s: float) -> dict[str, Any]:
    """Where a vehicle last heard `age_s` seconds ago (saying `status`) is predicted now:
    lat, lon, alt_msl_m, alt_rel_m, error_m (the bound of the prediction) and phase."""
    vtype = info.vehicle_type if info is not None else None
    speed = MAX_SPEED_M_S.get(vtype or VehicleType.OTHER, 35.0)
    t = status.time_unix_s
    track = Track.from_status(status, time_s=t, max_speed_m_s=speed)
    a = SilentAircraft.of(track, vtype, info, status.alt_msl_m - status.alt_rel_m)
    home_msl = a.home_msl_m
    p = a.predict(t + max(0.0, age_s))
    return {
        "lat": round(p.track.lat_deg, 7),
        "lon": round(p.track.lon_deg, 7),
        "alt_msl_m": round(p.track.alt_msl_m, 1),
        "alt_rel_m": round(p.track.alt_msl_m - home_msl, 1),
        "error_m": round(p.track.error_m, 1),
        "phase": p.phase,
    }


def lost_fields(
    status: VehicleStatus | None, info: VehicleInfo | None, age_s: float | None
) -> dict[str, Any]:
    """What a row of a vehicle not heard for `age_s` adds: {} while it is heard (or
    was never heard flying, or its last report says it landed); else lost, its last
    position and its age, and its predicted position (None if it cannot be predicted:
    no position)."""
    if status is None or age_s is None or age_s <= LOST_AFTER_S or landed(status):
        return {}
    out: dict[str, Any] = {
        "lost": True,
        "last": {
            "lat": round(status.lat_deg, 7),
            "lon": round(status.lon_deg, 7),
            "alt_rel_m": round(status.alt_rel_m, 1),
            "age_s": round(age_s, 1),
        },
        "predicted": None,
    }
    if not (status.lat_deg == 0.0 and status.lon_deg == 0.0):
        with contextlib.suppress(BadTrackError):  # a position out of range: none
            out["predicted"] = predicted(status, info, age_s)
    return out


@dataclass
class Seen:
    """A vehicle's last report, its info, and when it was heard (UNIX seconds)."""

    status: VehicleStatus
    info: VehicleInfo | None
    heard_unix_s: float


@dataclass
class LostBook:
    """The vehicles last heard flying (their last report), kept until heard landed or
    dismissed: the lost ones are those not heard for LOST_AFTER_S."""

    seen: dict[int, Seen] = field(default_factory=dict)

    def heard(self, status: VehicleStatus, info: VehicleInfo | None, at_unix_s: float) -> None:
        if info is not None and info.vehicle_type == VehicleType.GCS:
            return
        old = self.seen.get(status.vehicle_id)
        if old is not None and old.heard_unix_s > at_unix_s:
            return  # an older run's report: the newer one stays
        if landed(status):
            self.seen.pop(status.vehicle_id, None)  # seen landed: not lost
            return
        self.seen[status.vehicle_id] = Seen(status, info or (old.info if old else None), at_unix_s)

    def lost(self, now_unix_s: float) -> dict[int, dict[str, Any]]:
        """Each lost vehicle's fields (`lost_fields`), by id."""
        out: dict[int, dict[str, Any]] = {}
        for vid, s in sorted(self.seen.items()):
            f = lost_fields(s.status, s.info, now_unix_s - s.heard_unix_s)
            if f:
                out[vid] = f | {"type": s.info.vehicle_type.name} if s.info else f
        return out

    def dismiss(self, vehicle_id: int, now_unix_s: float) -> None:
        """The operator knows where it is: off the list. Raises NotLostError (one
        line) for a vehicle that is not lost."""
        if isinstance(vehicle_id, bool) or not isinstance(vehicle_id, int):
            raise NotLostError(f"not a vehicle id: {vehicle_id!r}")
        if vehicle_id not in self.lost(now_unix_s):
            known = ", ".join(str(v) for v in self.lost(now_unix_s)) or "none"
            raise NotLostError(f"vehicle {vehicle_id} is not lost (lost: {known})")
        del self.seen[vehicle_id]


def finite_id(value: Any) -> int:
    """A vehicle id from the page or the command line (an int, or a string of one).
    Raises NotLostError (one line) for anything else: NaN, a fraction, a name."""
    if isinstance(value, bool):
        raise NotLostError(f"not a vehicle id: {value!r}")
    if isinstance(value, float):
        if not math.isfinite(value) or value != int(value):
            raise NotLostError(f"not a vehicle id: {value!r}")
        value = int(value)
    if isinstance(value, str):
        try:
            value = int(value.strip())
        except ValueError:
            raise NotLostError(f"not a vehicle id: {value!r}") from None
    if not isinstance(value, int) or not (1 <= value <= 65534):
        raise NotLostError(f"not a vehicle id: {value!r}")
    return value
