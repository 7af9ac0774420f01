"""Failsafes: what the autopilot does on its own when a limit is crossed. The geofence
(AC_Fence with FENCE_ACTION: a breach outside RTL/LAND/QRTL switches to RTL, or QRTL on a
hovering QuadPlane). A failsafe is one more check in `check`, run after every physics
step while armed."""

from __future__ import annotations

from .fence import Fence
from .firmware import SEV_NOTICE, Behaviour, Firmware, mode_number
from .kinematics import Body
from .modes import Modes
from .navigator import Navigator
from .outbox import Outbox
from .params import Parameters


class Failsafes:
    def __init__(
        self,
        firmware: Firmware,
        *,
        body: Body,
        params: Parameters,
        fence: Fence,
        navigator: Navigator,
        modes: Modes,
        out: Outbox,
    ) -> None:
        self.firmware = firmware
        self.body = body
        self.params = params
        self.fence = fence
        self.navigator = navigator
        self.modes = modes
        self.out = out

    def check(self) -> None:
        """After every physics step while armed."""
        self._fence()

    def _fence(self) -> None:
        b = self.body
        if not self.fence.check(b.n, b.e, b.on_ground):
            return
        self.out.text(SEV_NOTICE, "Fence Breached")
        action = int(self.params.value("FENCE_ACTION"))
        if action != 0 and self.modes.behaviour not in (
            Behaviour.RTL,
            Behaviour.LAND,
            Behaviour.QRTL,
        ):
            rtl = "QRTL" if self.navigator.vtol_hovering() else "RTL"
            self.modes.set_mode(mode_number(self.firmware, rtl))
