"""Which leg of its sortie the mission manager flies (`Phase`)."""

from __future__ import annotations

from enum import Enum


class Phase(Enum):
    IDLE = "idle"
    STARTING = "starting"  # upload, arm, take off
    CLIMBING = "climbing"  # waiting for the take-off altitude
    MEETING = "meeting"  # PREMISSION: climbed, waiting for the fleet's meet time
    FOLLOWING = "following"  # MUM-T: holding our slot around the lead
    FLYING = "flying"  # the mission is running on the autopilot
    RETURNING = "returning"  # RTL
    LANDING = "landing"
    PARACHUTE = "parachute"  # released: coming down under the canopy
