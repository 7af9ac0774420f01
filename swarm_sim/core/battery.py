"""Battery drain: coulomb counting with a current drawn by flight phase, and a voltage
from the state of charge and the internal resistance."""

from __future__ import annotations

import msgspec

from .airframes import AirframeParams, BatteryParams, VehicleModel
from .kinematics import Body, VtolState

CELL_FULL_V = 4.2
CELL_EMPTY_V = 3.3


class Battery:
    def __init__(self, params: BatteryParams, *, remaining_pct: float = 100.0) -> None:
        if params.capacity_mah <= 0 or params.cells <= 0:
            raise ValueError("battery needs a positive capacity and cell count")
        self.params = params
        self.consumed_mah = params.capacity_mah * (1.0 - remaining_pct / 100.0)
        self.energy_wh = 0.0
        self.current_a = 0.0

    @property
    def remaining_frac(self) -> float:
        return max(0.0, 1.0 - self.consumed_mah / self.params.capacity_mah)

    @property
    def remaining_pct(self) -> int:
        return round(100.0 * self.remaining_frac)

    @property
    def resting_voltage(self) -> float:
        # a linear-ish discharge curve with a knee near empty
        soc = self.remaining_frac
        cell = CELL_EMPTY_V + (CELL_FULL_V - CELL_EMPTY_V) * (0.15 * soc + 0.85 * soc**0.5)
        return self.params.cells * cell

    @property
    def voltage(self) -> float:
        return max(0.0, self.resting_voltage - self.current_a * self.params.internal_resistance_ohm)

    def step(self, current_a: float, dt: float) -> None:
        self.current_a = max(0.0, current_a)
        self.consumed_mah += self.current_a * dt / 3.6
        self.energy_wh += self.voltage * self.current_a * dt / 3600.0

    def set_remaining_pct(self, pct: float) -> None:
        pct = min(100.0, max(0.0, pct))
        self.consumed_mah = self.params.capacity_mah * (1.0 - pct / 100.0)

    def resize(self, capacity_mah: float) -> None:
        """A battery of another capacity (BATT_CAPACITY), as charged as this one."""
        left = self.remaining_frac
        self.params = msgspec.structs.replace(self.params, capacity_mah=capacity_mah)
        self.consumed_mah = capacity_mah * (1.0 - left)


def current_draw(af: AirframeParams, b: Body, armed: bool) -> float:
    """The current (A) the airframe draws in its flight phase: idle, hovering (more when
    climbing and moving), cruising on its wings, or driving."""
    bp = af.battery
    current = bp.idle_current_a
    if armed and not (b.on_ground and b.groundspeed < 0.1 and not af.is_ground):
        if af.model == VehicleModel.COPTER or (
            af.model == VehicleModel.VTOL and b.vtol_state != VtolState.FW
        ):
            current = bp.hover_current_a * (1.0 + 0.15 * max(0.0, -b.vd) + 0.002 * b.groundspeed**2)
        elif af.is_fixed_wing:
            ratio = b.airspeed / max(af.cruise_speed_m_s, 1.0)
            current = bp.cruise_current_a * (0.4 + 0.6 * ratio**3) * (1.0 + 0.1 * max(0.0, -b.vd))
        else:
            current = bp.idle_current_a + bp.cruise_current_a * b.groundspeed / max(
                af.cruise_speed_m_s, 0.1
            )
    elif armed:
        current = bp.idle_current_a * 2.0
    return current
