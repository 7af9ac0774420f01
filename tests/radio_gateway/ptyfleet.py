"""Real gateways' serial side (pyserial + RadioLink threads) on the emulated channel's
pseudo-terminals, with a producer publishing each node's 5 Hz status."""

from __future__ import annotations

import sys
import threading
from dataclasses import dataclass, field

import serial

from radio_gateway.core.node import Deliver, NodeConfig, RadioNode
from radio_gateway.core.slots import TdmConfig
from radio_gateway.core.xtend import RadioSettings
from radio_gateway.runtime.link import RadioLink
from radio_gateway.runtime.timesource import ClockTimeSource
from swarm_proto.clock import Clock, ScaledClock
from swarm_sim.radio_channel.model import ChannelParams
from swarm_sim.radio_channel.pty import ChannelProcess

from .helpers import KEY, TDM, status_out

SETTINGS = RadioSettings()


@dataclass
class PtyFleet:
    ports: int
    speed: float = 1.0  # simulated seconds per wall second (< 1: more timing margin)
    params: ChannelParams = field(default_factory=ChannelParams)
    tdm: TdmConfig = TDM
    producer_period_s: float = 0.1  # simulated seconds between a node's statuses
    clock: Clock = field(init=False)
    channel: ChannelProcess = field(init=False)
    links: dict[int, RadioLink] = field(default_factory=dict)
    deliveries: list[tuple[float, int, int, bytes]] = field(default_factory=list)
    _lock: threading.Lock = field(default_factory=threading.Lock)
    _stop: threading.Event = field(default_factory=threading.Event)
    _producer: threading.Thread | None = None
    _free: list[int] = field(init=False)
    _switch: float = 0.005

    def __post_init__(self) -> None:
        self.clock = ScaledClock(self.speed)
        self.channel = ChannelProcess(
            self.ports, self.params, self.clock, registers=SETTINGS.registers()
        )
        self._free = list(range(self.ports))

    def __enter__(self) -> PtyFleet:
        # every gateway shares this interpreter (on a vehicle each has its own process):
        # switch threads every 0.5 ms rather than 5 ms so serial writes stay on time
        self._switch = sys.getswitchinterval()
        sys.setswitchinterval(0.0005)
        self._producer = threading.Thread(target=self._produce, daemon=True)
        self._producer.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        if self._producer is not None:
            self._producer.join(timeout=5)
        for link in self.links.values():
            link.close()
        self.channel.close()
        sys.setswitchinterval(self._switch)

    def start(self, node_id: int, initial_members: tuple[int, ...] = ()) -> RadioLink:
        port = self._free.pop(0)
        cfg = NodeConfig(
            node_id,
            timing=SETTINGS.timing(),
            tdm=self.tdm,
            initial_members=initial_members,
            seed=node_id,
        )
        node = RadioNode(cfg, KEY, self.clock.now())
        ser = serial.Serial(self.channel.ports[port], SETTINGS.serial_baud, timeout=0.05)

        def deliver(d: Deliver, now: float) -> None:
            with self._lock:
                self.deliveries.append((now, node_id, d.src, d.data))

        link = RadioLink(
            ser,
            node,
            ClockTimeSource(self.clock),
            clock=self.clock,
            on_deliver=deliver,
            name=f"node{node_id}",
        )
        self.links[node_id] = link.start()
        return link

    def late_writes(self) -> dict[int, int]:
        """Frames each running link skipped because the host woke it past its slot."""
        return {v: link.late_writes for v, link in self.links.items()}

    def stop(self, node_id: int) -> None:
        self.links.pop(node_id).close()

    def _produce(self) -> None:
        # Each node's status at twice the cycle rate, on a schedule that does not drift:
        # a producer at exactly 5 Hz beats against the 5 Hz slot (a status submitted just
        # after a frame was built waits a whole cycle), which measures the phase of two
        # clocks, not the TDM. At 10 Hz every frame carries a status under 100 ms old.
        period = self.producer_period_s
        due = self.clock.now()
        while not self._stop.is_set():
            t = self.clock.now()
            for vid, link in list(self.links.items()):
                link.submit(status_out(vid, t))
            due = max(due + period, self.clock.now())
            self.clock.sleep(due - self.clock.now())

    def sleep(self, sim_s: float) -> None:
        self.clock.sleep(sim_s)

    def snapshot(self) -> list[tuple[float, int, int, bytes]]:
        with self._lock:
            return list(self.deliveries)

    def node(self, node_id: int) -> RadioNode:
        return self.links[node_id].node
