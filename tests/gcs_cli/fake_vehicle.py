"""A vehicle as the ground station sees one, without a node: alive, publishing its
VehicleInfo (its home and battery), answering its zones queryable, and acknowledging
every zone, command and mission it is sent (tests of the ground station on a Zenoh
router on 127.0.0.1)."""

from __future__ import annotations

import threading

from swarm_proto import (
    Ack,
    AckReason,
    AckRef,
    Command,
    GeoPoint,
    Mission,
    NoFlyZone,
    VehicleInfo,
    VehicleType,
    lan,
)
from swarm_proto.session import SwarmBus, ZenohSettings
from swarm_proto.topics import COMMAND, MISSION, ZONE, ZONES


class Vehicle:
    """A vehicle as the ground station sees one: alive, its VehicleInfo, its zones
    queryable, and an Ack for every zone and command it is sent."""

    def __init__(
        self,
        router: str,
        swarm: str,
        vid: int,
        zones: list[NoFlyZone],
        *,
        home: GeoPoint | None = None,
        battery_pct: int = -1,
        mission_id: int = 0,
    ) -> None:
        self.vid, self.swarm, self.home, self.battery_pct = vid, swarm, home, battery_pct
        self.mission_id = mission_id
        self.zones = {z.zone_id: z for z in zones}
        self.got: list[object] = []
        self.lock = threading.Lock()
        self.bus = SwarmBus.open(ZenohSettings(mode="client", connect=(router,)), swarm)
        self.queryable = self.bus.session.declare_queryable(
            ZONES.key(swarm, vehicle_id=vid), self._answer
        )
        self.bus.subscribe(ZONE, self._on_zone)
        self.bus.subscribe(COMMAND, self._on_command)
        self.bus.subscribe(MISSION, self._on_mission)
        self.bus.declare_alive(vid)
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self._info, daemon=True)
        self.thread.start()

    def _info(self) -> None:
        info = VehicleInfo(
            self.vid,
            VehicleType.COPTER,
            "Generic Quadcopter",
            f"Q{self.vid}",
            home=self.home,
            battery_pct=self.battery_pct,
            mission_id=self.mission_id,
        )
        while not self.stop.wait(0.2):
            self.bus.publish(info)

    def _answer(self, query: object) -> None:
        with self.lock:
            zones = list(self.zones.values())
        for z in zones:
            key = ZONES.key(self.swarm, vehicle_id=self.vid, zone_id=z.zone_id)
            query.reply(key, lan.encode(z))  # type: ignore[attr-defined]

    def _on_zone(self, z: NoFlyZone, key: str) -> None:
        with self.lock:
            self.got.append(z)
            self.zones[z.zone_id] = z
        self.bus.publish(Ack(self.vid, z.issuer_id, AckRef.ZONE, z.zone_id, True, text="held"))

    def _on_command(self, c: Command, key: str) -> None:
        with self.lock:
            self.got.append(c)
        self.bus.publish(Ack(self.vid, c.issuer_id, AckRef.COMMAND, c.seq, True, AckReason.OK))

    def _on_mission(self, m: Mission, key: str) -> None:
        with self.lock:
            self.got.append(m)
        self.bus.publish(Ack(self.vid, m.issuer_id, AckRef.MISSION, m.mission_id, True))

    def close(self) -> None:
        self.stop.set()
        self.thread.join(2.0)
        self.queryable.undeclare()
        self.bus.close()
