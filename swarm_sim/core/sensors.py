"""What the simulated sensors and estimator report while the autopilot boots: booted
(ArduPilot Ready), GPS detected, 3-D fix, and the EKF using GPS (a position estimate).
`boot.Boot` sets them on its timeline."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass
class Sensors:
    ready: bool = False  # boot finished (STANDBY)
    gps_detected: bool = False
    gps_fix: bool = False
    ekf_position: bool = False
