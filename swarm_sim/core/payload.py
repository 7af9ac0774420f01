"""The camera mount (MAV_CMD_DO_MOUNT_CONTROL / DO_MOUNT_CONTROL_QUATERNION's angles):
where it points, within the camera's limits."""

from __future__ import annotations

import math
from dataclasses import dataclass

from .airframes import CameraParams


@dataclass
class Mount:
    camera: CameraParams
    pitch_deg: float = 0.0
    yaw_deg: float = 0.0

    def point(self, pitch_deg: float, yaw_deg: float) -> None:
        """Point the mount; a value that is not finite leaves its angle as it was."""
        if math.isfinite(pitch_deg):
            self.pitch_deg = max(
                self.camera.pitch_min_deg, min(self.camera.pitch_max_deg, pitch_deg)
            )
        if math.isfinite(yaw_deg):
            self.yaw_deg = yaw_deg
