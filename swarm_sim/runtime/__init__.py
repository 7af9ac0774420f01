"""I/O shells for the simulator: TCP servers for simulated vehicles."""

from .server import VehicleServer, VehicleSpec, spread_homes

__all__ = ["VehicleServer", "VehicleSpec", "spread_homes"]
