"""The boot sequence as the recorded SITL sorties show it, on the autopilot's timeline:
the boot texts, ArduPilot Ready (the initial mode), GPS detected, a 3-D fix, the EKF
origin (home) and the EKF using GPS (a position: modes that need one, and arming)."""

from __future__ import annotations

from .arming import Arming
from .firmware import (
    BOOT_TEXTS,
    EKF_GPS_TEXTS,
    EKF_ORIGIN_TEXTS,
    GPS_DETECTED_TEXTS,
    SEV_INFO,
    Firmware,
)
from .home import HomeState
from .kinematics import Body
from .modes import Modes
from .options import StartupTimes
from .outbox import Outbox
from .sensors import Sensors
from .timeline import Timeline


class Boot:
    def __init__(
        self,
        firmware: Firmware,
        startup: StartupTimes,
        *,
        texts: bool,
        body: Body,
        sensors: Sensors,
        home: HomeState,
        modes: Modes,
        arming: Arming,
        timeline: Timeline,
        out: Outbox,
    ) -> None:
        self.firmware = firmware
        self.texts = texts
        self.body = body
        self.sensors = sensors
        self.home = home
        self.modes = modes
        self.arming = arming
        self.timeline = timeline
        self.out = out
        t0 = timeline.boot_time
        if texts:
            for dt, sev, text in BOOT_TEXTS[firmware]:
                timeline.schedule(t0 + dt, lambda s=sev, x=text: out.text(s, x))  # type: ignore[misc]
        ready_at = 1.2 if firmware == Firmware.PLANE else 1.3
        events = [
            (t0 + ready_at, self._ready),
            (t0 + startup.gps_detect_s, self._gps_detected),
            (t0 + startup.gps_fix_s, self._gps_fixed),
            (t0 + startup.ekf_origin_s, self._ekf_origin),
            (t0 + startup.ekf_gps_s, self._ekf_using_gps),
        ]
        for at, action in events:
            timeline.schedule(at, action)

    def _ready(self) -> None:
        self.sensors.ready = True
        self.modes.boot_ready(self.timeline.boot_time)

    def _gps_detected(self) -> None:
        self.sensors.gps_detected = True
        if self.texts:
            for text in GPS_DETECTED_TEXTS:
                self.out.text(SEV_INFO, text)

    def _gps_fixed(self) -> None:
        self.sensors.gps_detected = True
        self.sensors.gps_fix = True

    def _ekf_origin(self) -> None:
        self.home.set(self.body.n, self.body.e, self.body.ground_alt)
        if self.texts:
            for text in EKF_ORIGIN_TEXTS:
                self.out.text(SEV_INFO, text.format(alt=self.home.alt))
        t = self.timeline.t
        self.out.send(self.home.origin_message(t))
        self.out.send(self.home.position_message(t))

    def _ekf_using_gps(self) -> None:
        self.sensors.ekf_position = True
        self.arming.position_ready()
        if self.texts:
            for text in EKF_GPS_TEXTS:
                self.out.text(SEV_INFO, text)
            if self.firmware == Firmware.PLANE:
                self.out.text(SEV_INFO, "AHRS: EKF3 active")  # the plane switched AHRS here
