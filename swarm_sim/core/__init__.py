"""Pure simulator cores: kinematic models, the ArduPilot behaviour emulation
(`SimAutopilot`, messages in and out), its MAVLink framing (`VehicleEndpoint`, bytes in
and out) and a fast-time harness. No sockets, threads or clocks here (see
tests/test_architecture.py); `swarm_sim.runtime` puts them on TCP ports."""

from .airframes import (
    ALBATROSS_250_VTOL,
    DEFAULT_AIRFRAMES,
    GENERIC_BOAT,
    GENERIC_PLANE,
    GENERIC_QUADCOPTER,
    GENERIC_ROVER,
    AirframeParams,
    BatteryParams,
    CameraParams,
    VehicleModel,
    default_airframe,
)
from .autopilot import SITL_HOME, Home, SimAutopilot, SimOptions, StartupTimes
from .endpoint import VehicleEndpoint, sitl_port
from .harness import FastTimeHarness, HarnessLink, SimClient

__all__ = [
    "ALBATROSS_250_VTOL",
    "DEFAULT_AIRFRAMES",
    "GENERIC_BOAT",
    "GENERIC_PLANE",
    "GENERIC_QUADCOPTER",
    "GENERIC_ROVER",
    "SITL_HOME",
    "AirframeParams",
    "BatteryParams",
    "CameraParams",
    "FastTimeHarness",
    "HarnessLink",
    "Home",
    "SimAutopilot",
    "SimClient",
    "SimOptions",
    "StartupTimes",
    "VehicleEndpoint",
    "VehicleModel",
    "default_airframe",
    "sitl_port",
]
