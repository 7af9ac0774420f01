"""Failsafes: what the autopilot does on its own when a limit is crossed. The geofence
(AC_Fence with FENCE_ACTION: a breach outside RTL/LAND/QRTL switches to RTL, or QRTL on a
hovering QuadPlane), and the GCS failsafe: HEARTBEATs from system SYSID_MYGCS stop
for the timeout (ArduCopter FS_GCS_ENABLE / FS_GCS_TIMEOUT, ArduPlane FS_GCS_ENABL /
FS_LONG_TIMEOUT) -> RTL, unless the vehicle flies AUTO and the parameters say continue
(ArduCopter FS_OPTIONS bit 1, ArduPlane FS_LONG_ACTN 0) or it is already coming home;
never before the first such HEARTBEAT. A failsafe is one more check in `check`, run
after every physics step while armed."""

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
        self.gcs_seen_at: float | None = None  # the last HEARTBEAT of SYSID_MYGCS
        self.gcs_lost = False  # the GCS failsafe is on (until a HEARTBEAT again)

    def gcs_heartbeat(self, now: float) -> None:
        self.gcs_seen_at = now
        if self.gcs_lost:
            self.gcs_lost = False
            self.out.text(SEV_NOTICE, "GCS Failsafe Cleared")

    def check(self, now: float) -> None:
        """After every physics step while armed."""
        self._fence()
        self._gcs(now)

    def _gcs(self, now: float) -> None:
        p, fw = self.params, self.firmware
        if fw == Firmware.COPTER:
            enabled, timeout_s = p.get("FS_GCS_ENABLE"), p.get("FS_GCS_TIMEOUT")
            go_on = int(p.value("FS_OPTIONS")) & 2 if "FS_OPTIONS" in p else 0
        elif fw == Firmware.PLANE:
            enabled, timeout_s = p.get("FS_GCS_ENABL"), p.get("FS_LONG_TIMEOUT")
            go_on = "FS_LONG_ACTN" in p and int(p.value("FS_LONG_ACTN")) == 0
        else:
            return
        if enabled is None or timeout_s is None or enabled[0] == 0 or self.gcs_seen_at is None:
            return
        if self.gcs_lost or now - self.gcs_seen_at < timeout_s[0]:
            return
        self.gcs_lost = True
        self.out.text(SEV_NOTICE, "GCS Failsafe")
        behaviour = self.modes.behaviour
        if go_on and behaviour == Behaviour.AUTO:
            return
        if behaviour in (Behaviour.RTL, Behaviour.LAND, Behaviour.QRTL):
            return
        rtl = "QRTL" if self.navigator.vtol_hovering() else "RTL"
        self.modes.set_mode(mode_number(self.firmware, rtl))

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
