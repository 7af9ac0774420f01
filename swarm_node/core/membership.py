"""Swarm manager, membership half (paper section 2.3.3): who is in the swarm.

A peer joins when its liveliness token appears or when its first telemetry arrives
(peers behind the radio have no liveliness, only telemetry relayed by the gateway).
It leaves when its liveliness token is withdrawn, or when nothing has been heard from
it for `stale_after_s` (a frozen process loses its token only after the Zenoh lease;
a radio peer only goes silent). A peer that sends no VehicleStatus, only its 1 Hz
VehicleInfo (a ground station), is given `info_stale_after_s` instead: over the radio
info is the lowest class, so two seconds would be two missed updates. Pure: events and
`now` in, PeerJoined/PeerLeft out.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from swarm_proto import FsmState, VehicleInfo, VehicleStatus, VehicleType


@dataclass(frozen=True)
class PeerJoined:
    node_id: int
    how: str  # "liveliness" | "telemetry"


@dataclass(frozen=True)
class PeerLeft:
    node_id: int
    why: str  # "liveliness" | "stale"


PeerEvent = PeerJoined | PeerLeft


@dataclass
class Peer:
    node_id: int
    present: bool = False
    alive_token: bool = False
    last_heard_s: float = float("-inf")
    status: VehicleStatus | None = None
    info: VehicleInfo | None = None

    @property
    def vehicle_type(self) -> VehicleType:
        return self.info.vehicle_type if self.info else VehicleType.OTHER

    @property
    def is_ground_station(self) -> bool:
        return self.vehicle_type == VehicleType.GCS

    @property
    def fleet_id(self) -> int:
        if self.status is not None:
            return self.status.fleet_id
        return self.info.fleet_id if self.info else 0

    @property
    def fsm_state(self) -> FsmState:
        if self.status is not None:
            return self.status.fsm_state
        return self.info.fsm_state if self.info else FsmState.INACTIVE

    @property
    def mission_id(self) -> int:
        return self.info.mission_id if self.info else 0


@dataclass
class SwarmMembership:
    self_id: int
    stale_after_s: float = 2.0  # a peer that sends VehicleStatus (5 Hz)
    info_stale_after_s: float = 5.0  # a peer that sends only VehicleInfo (1 Hz)
    peers: dict[int, Peer] = field(default_factory=dict)

    def _stale_after(self, peer: Peer) -> float:
        if peer.status is None:
            return max(self.stale_after_s, self.info_stale_after_s)
        return self.stale_after_s

    # ------------------------------------------------------------------ inputs
    def on_alive(self, node_id: int, alive: bool, now: float) -> list[PeerEvent]:
        if node_id == self.self_id:
            return []
        peer = self.peers.setdefault(node_id, Peer(node_id))
        peer.alive_token = alive
        if alive:
            peer.last_heard_s = now
            return self._join(peer, "liveliness")
        return self._leave(peer, "liveliness")

    def on_status(self, msg: VehicleStatus, now: float) -> list[PeerEvent]:
        return self._heard(msg.vehicle_id, now, status=msg)

    def on_info(self, msg: VehicleInfo, now: float) -> list[PeerEvent]:
        return self._heard(msg.vehicle_id, now, info=msg)

    def on_timer(self, now: float) -> list[PeerEvent]:
        out: list[PeerEvent] = []
        for peer in self.peers.values():
            if (
                peer.present
                and not peer.alive_token
                and now - peer.last_heard_s >= self._stale_after(peer)
            ):
                out += self._leave(peer, "stale")
        return out

    def next_deadline(self) -> float | None:
        times = [
            p.last_heard_s + self._stale_after(p)
            for p in self.peers.values()
            if p.present and not p.alive_token
        ]
        return min(times) if times else None

    # ------------------------------------------------------------------ views
    def live(self) -> list[Peer]:
        return sorted((p for p in self.peers.values() if p.present), key=lambda p: p.node_id)

    def live_ids(self) -> list[int]:
        return [p.node_id for p in self.live()]

    def vehicles(self) -> list[Peer]:
        return [p for p in self.live() if not p.is_ground_station]

    def fleet(self, fleet_id: int) -> list[Peer]:
        return [p for p in self.vehicles() if fleet_id and p.fleet_id == fleet_id]

    # ------------------------------------------------------------------ internals
    def _heard(
        self,
        node_id: int,
        now: float,
        *,
        status: VehicleStatus | None = None,
        info: VehicleInfo | None = None,
    ) -> list[PeerEvent]:
        if node_id == self.self_id:
            return []
        peer = self.peers.setdefault(node_id, Peer(node_id))
        peer.last_heard_s = max(peer.last_heard_s, now)
        if status is not None:
            peer.status = status
        if info is not None:
            peer.info = info
        return self._join(peer, "telemetry")

    def _join(self, peer: Peer, how: str) -> list[PeerEvent]:
        if peer.present:
            return []
        peer.present = True
        return [PeerJoined(peer.node_id, how)]

    def _leave(self, peer: Peer, why: str) -> list[PeerEvent]:
        if not peer.present:
            return []
        peer.present = False
        peer.alive_token = False
        return [PeerLeft(peer.node_id, why)]
