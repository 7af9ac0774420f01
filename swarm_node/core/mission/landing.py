"""AUTOLAND as the mission manager flies it ("swarm airport operations"): every member
flies to the holding fix at its own stack level and holds there (a LOITER_UNLIMITED,
`plan_autoland(hold_until_released=True)`) until its turn, then flies the final
approach and lands on its own pad.

Turns without a leader: the landing order is the plan's (`AutolandPlan.slots`), the
same on every node. The first leaves the hold as soon as it is in it. Each of the
others leaves `separation_s` after the one before it has landed, less its own final
approach (`final_approach_s`), so touchdowns are `separation_s` apart whatever the
transits took (the planned hold times assume every vehicle starts from its home: in
the air they do not). Whether the one before has landed every node sees in its
VehicleInfo: it left the mission with its share flown (`Roster.finished`); one lost
(`Roster.lost`) no longer holds the others up.

Pure: no I/O, no clock.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from ..autopilot.items import ItemKind, Waypoint
from ..planning import AutolandPlan, PlanVehicle
from ..planning.autoland import DEFAULT_SEPARATION_S, final_approach_s
from ..planning.fleet_plan import FleetPlan
from ..swarm.roster import Roster


@dataclass
class LandingTurn:
    vehicle_id: int
    hold_seq: int  # the uploaded item (seq, 0 = home) of our hold over the fix
    before: int | None  # who lands before us (None: we land first)
    wait_s: float  # after the one before landed (>= 0)
    ready_at: float | None = None  # when we saw the one before land (or lost)
    released_at: float | None = None

    @classmethod
    def of(
        cls, plan: FleetPlan, vehicle_id: int, uploaded: Sequence[Waypoint]
    ) -> LandingTurn | None:
        """Our turn in an AUTOLAND plan, for the items we uploaded; None for any other
        plan or without a hold."""
        detail = plan.detail
        if not isinstance(detail, AutolandPlan):
            return None
        hold = next(
            (k for k, w in enumerate(uploaded) if w.kind == ItemKind.LOITER_UNLIMITED), None
        )
        order = [s.vehicle_id for s in sorted(detail.slots, key=lambda s: s.sequence)]
        if hold is None or vehicle_id not in order:
            return None
        i = order.index(vehicle_id)
        v = next((v for v in plan.vehicles if v.vehicle_id == vehicle_id), None)
        sep = plan.mission.params.separation_s or DEFAULT_SEPARATION_S
        alt = uploaded[hold].alt_rel_m
        final = (
            final_approach_s(v, v.speed(plan.mission.params), alt)
            if isinstance(v, PlanVehicle)
            else 0.0
        )
        return cls(vehicle_id, hold + 1, order[i - 1] if i else None, max(sep - final, 0.0))

    def release(self, current_seq: int, fleet: Roster | None, now: float) -> bool:
        """True once: we are in our hold and it is our turn."""
        if self.released_at is not None:
            return False
        if self.ready_at is None:
            if self.before is None:
                self.ready_at = now - self.wait_s
            elif fleet is not None and (self.before in fleet.finished or self.before in fleet.lost):
                self.ready_at = now
        if current_seq < self.hold_seq or self.ready_at is None:
            return False
        if now - self.ready_at < self.wait_s - 1e-9:
            return False
        self.released_at = now
        return True
