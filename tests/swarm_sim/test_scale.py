"""Scale: many vehicles in one process (`make scale`)."""

from __future__ import annotations

import selectors
import socket
import time

import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from swarm_proto.clock import ScaledClock
from swarm_sim.core import SITL_HOME
from swarm_sim.runtime import VehicleServer, VehicleSpec, spread_homes

MODELS = ("vtol", "copter", "plane", "rover", "boat")


@pytest.mark.scale
def test_sixty_vehicles_in_one_process_at_10x() -> None:
    n = 60
    homes = spread_homes(SITL_HOME, n, 20.0)
    # port 0: the kernel's free ports (sixty picked one after another came out equal)
    specs = [VehicleSpec(MODELS[k % 5], instance=k, home=homes[k], port=0) for k in range(n)]
    server = VehicleServer(specs, ScaledClock(10.0))
    server.start_thread()
    ports = server.ports
    sel = selectors.DefaultSelector()
    parsers = {}
    seen: dict[int, set[str]] = {}
    try:
        for k, port in enumerate(ports):
            s = socket.create_connection(("127.0.0.1", port), timeout=5)
            s.setblocking(False)
            sel.register(s, selectors.EVENT_READ, k)
            parser = mavlink.MAVLink(None, srcSystem=0, srcComponent=0)
            parser.robust_parsing = True
            parsers[k] = parser
        deadline = time.monotonic() + 30
        while (
            time.monotonic() < deadline
            and len([k for k, v in seen.items() if "GLOBAL_POSITION_INT" in v]) < n
        ):
            for key, _ in sel.select(0.2):
                k = key.data
                for msg in parsers[k].parse_buffer(key.fileobj.recv(65536)) or []:
                    if msg.get_type() == "BAD_DATA":
                        continue
                    assert msg.get_srcSystem() == k + 1
                    if msg.get_type() != "GLOBAL_POSITION_INT" or msg.lat != 0:
                        seen.setdefault(k, set()).add(msg.get_type())
        assert len(seen) == n
        assert all({"HEARTBEAT", "GLOBAL_POSITION_INT"} <= types for types in seen.values())
        assert server.max_lag_s < 5.0  # simulated seconds; the loop keeps up
    finally:
        for key in list(sel.get_map().values()):
            key.fileobj.close()  # type: ignore[union-attr]
        server.close()
