"""The geofence as AC_Fence and AC_PolyFence_loader run it: the polygons and circles
loaded from the fence store, whether the vehicle is outside, and the breach state that
FENCE_STATUS and SYS_STATUS report. What a breach makes the vehicle do is
`failsafes.Failsafes`'."""

from __future__ import annotations

import math

from .geo import LocalFrame, point_in_polygon
from .home import HomeState
from .mission import MissionItem
from .params import Parameters
from .stores import ItemStores
from .timeline import Timeline

FENCE_LOAD_DELAY_S = 0.1  # AC_PolyFence_loader loads an uploaded fence in the fence task
FENCE_LOAD_RETRY_S = 0.5  # ... and retries while the EKF has no origin


class Fence:
    def __init__(
        self,
        params: Parameters,
        stores: ItemStores,
        frame: LocalFrame,
        home: HomeState,
        timeline: Timeline,
    ) -> None:
        self.params = params
        self.stores = stores
        self.frame = frame
        self.home = home
        self.timeline = timeline
        # what AC_PolyFence_loader has loaded: ArduPilot loads an uploaded fence in its
        # fence task a moment after the upload, and only once the EKF has an origin
        self.loaded: list[MissionItem] = []
        self.breached = False
        self.breach_count = 0
        self.breach_ms = 0

    @property
    def enabled(self) -> bool:
        return self.params.value("FENCE_ENABLE") != 0

    def present(self) -> bool:
        """AC_Fence::present(): FENCE_TYPE has the circle or an altitude fence, or the
        polygon/circle bit and a loaded fence. DO_FENCE_ENABLE(1) is FAILED without it."""
        types = int(self.params.value("FENCE_TYPE"))
        return bool(types & (1 | 2 | 8)) or bool(types & 4 and self.loaded)

    def uploaded(self) -> None:
        """The fence store changed: re-indexed, unloaded until the fence task loads it."""
        self.loaded = []
        self.timeline.schedule(self.timeline.now + FENCE_LOAD_DELAY_S, self._load)

    def _load(self) -> None:
        if not self.home.is_set:  # "fence load requires origin": try again later
            at = max(self.timeline.t, self.timeline.event_t) + FENCE_LOAD_RETRY_S
            self.timeline.schedule(at, self._load)
            return
        self.loaded = list(self.stores.fence)

    def outside(self, n: float, e: float) -> bool:
        """Inside an exclusion zone, or outside every inclusion zone (when there is one)."""
        items = self.loaded
        inclusion_seen, inside_any_inclusion = False, False
        i = 0
        while i < len(items):
            item = items[i]
            if item.command in (5001, 5002):
                count = max(1, int(item.param1))
                poly = [self.frame.to_ne(it.lat_deg, it.lon_deg) for it in items[i : i + count]]
                inside = point_in_polygon(n, e, poly)
                if item.command == 5002 and inside:
                    return True
                if item.command == 5001:
                    inclusion_seen = True
                    inside_any_inclusion |= inside
                i += count
                continue
            if item.command in (5003, 5004):
                cn, ce = self.frame.to_ne(item.lat_deg, item.lon_deg)
                inside = math.hypot(n - cn, e - ce) <= item.param1
                if item.command == 5004 and inside:
                    return True
                if item.command == 5003:
                    inclusion_seen = True
                    inside_any_inclusion |= inside
            i += 1
        return inclusion_seen and not inside_any_inclusion

    def check(self, n: float, e: float, on_ground: bool) -> bool:
        """Update the breach state after a physics step (the timeline still at its
        start); True on a new breach (the failsafe acts on it)."""
        if (
            not self.enabled
            or not int(self.params.value("FENCE_TYPE")) & 4
            or not self.loaded
            or on_ground
        ):
            self.breached = False
            return False
        breached = self.outside(n, e)
        new = breached and not self.breached
        if new:
            self.breach_count += 1
            self.breach_ms = self.timeline.boot_ms(self.timeline.t)
        self.breached = breached
        return new
