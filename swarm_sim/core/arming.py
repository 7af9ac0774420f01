"""Arming as ArduPilot does it (AP_Arming and the vehicles' motors state): the pre-arm
checks worded as its PreArm messages, arm and disarm, the copter's auto-disarm on the
ground, landing complete, a crash, the parachute, and the SYS_STATUS system state that
follows from them. Add an arming check to `prearm_failure`."""

from __future__ import annotations

from .airframes import AirframeParams
from .battery import Battery
from .fence import Fence
from .firmware import (
    ARM_TEXT,
    DISARM_TEXT,
    SEV_CRITICAL,
    SEV_INFO,
    Firmware,
    ModeSpec,
)
from .home import HomeState
from .kinematics import Body
from .navigation import Idle, Parachute, Takeoff
from .navigator import Navigator
from .outbox import Outbox
from .params import Parameters
from .sensors import Sensors
from .stores import MissionProgress
from .timeline import Timeline

PREARM_DISPLAY_PERIOD_S = 30.0  # AP_Arming: failing pre-arm checks are repeated this often
CRASH_IMPACT_M_S = 4.0


class Arming:
    def __init__(
        self,
        airframe: AirframeParams,
        firmware: Firmware,
        *,
        body: Body,
        battery: Battery,
        sensors: Sensors,
        params: Parameters,
        fence: Fence,
        home: HomeState,
        progress: MissionProgress,
        navigator: Navigator,
        timeline: Timeline,
        out: Outbox,
    ) -> None:
        self.airframe = airframe
        self.firmware = firmware
        self.body = body
        self.battery = battery
        self.sensors = sensors
        self.params = params
        self.fence = fence
        self.home = home
        self.progress = progress
        self.navigator = navigator
        self.timeline = timeline
        self.out = out
        self.armed = False
        self.crashed = False
        self.parachute_released = False
        self.ground_since: float | None = timeline.t  # on the ground since (None: flying)
        self.prearm_next = timeline.t  # when failing pre-arm checks are sent again

    def prearm_failure(self, mode: ModeSpec, arming: bool = False) -> str | None:
        """The first failing arming check in `mode`, worded as ArduPilot's PreArm
        messages; None when the vehicle may arm. ArduCopter checks the mode only when
        asked to arm (`arming`: "Arm: LAND mode not armable"), ArduPlane in its pre-arm
        checks too."""
        s = self.sensors
        if not s.ready:
            return "Initialising"  # booting (arming is refused without a text until ready)
        if self.crashed:
            return "Crashed"
        if not s.gps_fix:
            return "GPS 1: Bad fix"
        if not s.ekf_position:
            return (
                "AHRS: waiting for home"
                if self.firmware == Firmware.PLANE
                else "Need Position Estimate"
            )
        if not mode.armable and (arming or self.firmware != Firmware.COPTER):
            return f"{mode.name} mode not armable"
        if (
            self.fence.enabled
            and self.fence.loaded
            and self.fence.outside(self.body.n, self.body.e)
        ):
            return "Fence: vehicle outside fence"
        if self.battery.remaining_pct < 5:
            return "Battery 1 below minimum arming capacity"
        return None

    def prearm_due(self, now: float) -> bool:
        """Time to send the failing pre-arm check again (booted, disarmed)."""
        return self.sensors.ready and not self.armed and now >= self.prearm_next

    def show_prearm_failure(self, now: float, mode: ModeSpec) -> None:
        """When due, every PREARM_DISPLAY_PERIOD_S: the failing check, as ArduPilot
        repeats it (once the EKF has a position)."""
        self.prearm_next = now + PREARM_DISPLAY_PERIOD_S
        if self.sensors.ekf_position and self.params.value("ARMING_CHECK") != 0:
            reason = self.prearm_failure(mode)
            if reason is not None:
                self.out.text(SEV_CRITICAL, f"PreArm: {reason}")

    def position_ready(self) -> None:
        """The EKF has a position: pre-arm failures are shown a period from now."""
        self.prearm_next = self.timeline.t + PREARM_DISPLAY_PERIOD_S

    def arm(self, mode: ModeSpec, *, force: bool) -> bool:
        if self.armed:
            return True
        if not self.sensors.ready:
            return False
        if not force and self.params.value("ARMING_CHECK") != 0:
            reason = self.prearm_failure(mode, arming=True)
            if reason is not None:
                mode_check = self.firmware == Firmware.COPTER and not mode.armable
                self.out.text(SEV_CRITICAL, f"{'Arm' if mode_check else 'PreArm'}: {reason}")
                return False
            if self.firmware == Firmware.PLANE and self.progress.in_landing_sequence:
                # AP_Arming_Plane::arm_checks: the mission's flag, until its current
                # item is set again (DO_SET_MISSION_CURRENT)
                self.out.text(SEV_CRITICAL, "Arm: In landing sequence")
                return False
        b, t = self.body, self.timeline.t
        self.armed = True
        self.crashed = False
        self.ground_since = t if b.on_ground else None
        if self.home.is_set or self.sensors.ekf_position:
            self.home.set(b.n, b.e, b.ground_alt if b.on_ground else self.home.alt)
            self.out.send(self.home.position_message(t))
        if self.firmware == Firmware.COPTER:
            self.out.send(self.home.origin_message(t))
        self.out.text(SEV_INFO, ARM_TEXT[self.firmware])
        return True

    def disarm(self) -> None:
        if not self.armed:
            return
        self.armed = False
        self.prearm_next = self.timeline.t + PREARM_DISPLAY_PERIOD_S
        self.out.text(SEV_INFO, DISARM_TEXT[self.firmware])
        if self.firmware == Firmware.PLANE:
            self.progress.seq = 0
            self.progress.running = False
        if self.body.on_ground and not isinstance(self.navigator.task, Parachute):
            self.navigator.set(Idle())

    def land_complete(self) -> None:
        if not self.armed:
            return
        if self.firmware == Firmware.PLANE:
            self.out.text(SEV_INFO, "Land complete")
        self.disarm()

    def parachute_release(self) -> bool:
        if self.params.value("CHUTE_ENABLED") == 0 or self.parachute_released:
            return False
        if self.body.on_ground:
            self.out.text(SEV_INFO, "Parachute: Landed")
            return False
        if self.body.height < self.airframe.parachute_min_alt_m:
            self.out.text(SEV_INFO, "Parachute: Too low")
            return False
        self.out.text(SEV_CRITICAL, "Parachute: Released")
        self.parachute_released = True
        self.progress.running = False
        self.navigator.set(Parachute())
        if self.armed:
            self.armed = False
            self.out.text(SEV_INFO, DISARM_TEXT[self.firmware])
        return True

    def touched_down(self, impact_m_s: float) -> None:
        """The airframe hit the ground at `impact_m_s`: a crash above CRASH_IMPACT_M_S
        (unless under a parachute) disarms."""
        self.out.text(SEV_INFO, f"SIM Hit ground at {impact_m_s:f} m/s")
        if impact_m_s > CRASH_IMPACT_M_S and not self.parachute_released:
            self.crashed = True
            if self.armed:
                self.out.text(SEV_CRITICAL, "Crash: Disarming")
                self.disarm()

    def track_ground(self, t: float) -> None:
        """After a physics step at `t`: since when the vehicle is on the ground."""
        if self.body.on_ground:
            if self.ground_since is None:
                self.ground_since = t
        else:
            self.ground_since = None

    def auto_disarm_check(self, t: float) -> None:
        """The copter disarms DISARM_DELAY after landing (not while taking off)."""
        if self.firmware != Firmware.COPTER or self.ground_since is None:
            return
        if isinstance(self.navigator.leaf(), Takeoff):
            return
        if t - self.ground_since >= self.params.value("DISARM_DELAY") > 0:
            self.disarm()

    def system_status(self) -> int:
        """HEARTBEAT.system_status (MAV_STATE)."""
        if not self.sensors.ready:
            return 2 if self.firmware == Firmware.PLANE else 1  # CALIBRATING / BOOT
        if self.crashed or (self.parachute_released and not self.body.on_ground):
            return 6  # EMERGENCY
        if self.armed:
            if self.firmware == Firmware.PLANE:
                landed = self.ground_since is not None and self.timeline.t - self.ground_since > 1.0
                return 3 if landed and self.navigator.landing_context() else 4
            return 3 if self.body.on_ground else 4
        return 3  # STANDBY
