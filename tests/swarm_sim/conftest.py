"""Helpers for simulator tests: a fast-time harness with a ready (EKF using GPS) vehicle
and small pymavlink-style helpers around its client."""

from __future__ import annotations

from typing import Any

import pytest

from swarm_sim.core import FastTimeHarness, HarnessLink
from swarm_sim.core.firmware import mode_number
from swarm_sim.core.geo import LocalFrame

MODELS = ("plane", "vtol", "copter", "rover", "boat")


class Pilot:
    """Drives one harness link the way a ground-station script would."""

    def __init__(self, harness: FastTimeHarness, link: HarnessLink) -> None:
        self.h = harness
        self.link = link
        self.c = link.client
        self.ap = link.autopilot
        self.frame = LocalFrame(self.ap.frame.lat0, self.ap.frame.lon0)

    def wait_ready(self) -> None:
        assert self.h.run_until(lambda: self.ap.ekf_position, 60), "EKF never used GPS"

    def command(self, command: int, *params: float, timeout: float = 5.0) -> int | None:
        p = [*params, *([0.0] * (7 - len(params)))]
        self.c.mav.command_long_send(self.ap.sysid, 1, command, 0, *p)
        ack = self.h.wait_for(self.c, "COMMAND_ACK", timeout, cond=lambda a: a.command == command)
        return None if ack is None else int(ack.result)

    def command_int(
        self, command: int, frame: int, *params: float, x: int = 0, y: int = 0, z: float = 0.0
    ) -> int | None:
        p = [*params, *([0.0] * (4 - len(params)))]
        self.c.mav.command_int_send(self.ap.sysid, 1, frame, command, 0, 0, *p, x, y, z)
        ack = self.h.wait_for(self.c, "COMMAND_ACK", 5.0, cond=lambda a: a.command == command)
        return None if ack is None else int(ack.result)

    def set_mode(self, name: str) -> int | None:
        return self.command(176, 1, mode_number(self.ap.firmware, name))

    def arm(self) -> int | None:
        return self.command(400, 1)

    def latlon(self, north: float, east: float) -> tuple[int, int]:
        lat, lon = self.frame.to_latlon(north, east)
        return round(lat * 1e7), round(lon * 1e7)

    def upload(
        self, items: list[tuple[int, int, float, float, float]], mission_type: int = 0
    ) -> Any:
        """items: (command, frame, north_m, east_m, z) or with params via upload_raw."""
        raw = []
        for cmd, frame, n, e, z in items:
            x, y = self.latlon(n, e) if (n or e) else (0, 0)
            raw.append((cmd, frame, (0.0, 0.0, 0.0, 0.0), x, y, z))
        return self.upload_raw(raw, mission_type)

    def upload_raw(
        self,
        items: list[tuple[int, int, tuple[float, float, float, float], int, int, float]],
        mission_type: int = 0,
    ) -> Any:
        self.c.mav.mission_count_send(self.ap.sysid, 1, len(items), mission_type)
        while True:
            msg = self.h.wait_for(
                self.c, ("MISSION_REQUEST", "MISSION_REQUEST_INT", "MISSION_ACK"), 10
            )
            if msg is None or msg.get_type() == "MISSION_ACK":
                return msg
            cmd, frame, p, x, y, z = items[msg.seq]
            self.c.mav.mission_item_int_send(
                self.ap.sysid, 1, msg.seq, frame, cmd, 0, 1, *p, x, y, z, mission_type
            )


@pytest.fixture
def harness() -> FastTimeHarness:
    return FastTimeHarness()


def make_pilot(model: str, instance: int = 0, **kw: Any) -> Pilot:
    h = FastTimeHarness()
    return Pilot(h, h.add_vehicle(model, instance=instance, **kw))


__all__ = ["MODELS", "Pilot", "make_pilot", "mode_number"]
