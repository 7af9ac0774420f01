"""Fast-time harness: simulated vehicles and in-process MAVLink clients joined without
sockets. Time jumps to the earliest deadline, so a 20-minute sortie runs in seconds and
every run is repeatable (loss is drawn from a seeded generator).

    h = FastTimeHarness()
    link = h.add_vehicle("copter", instance=0)
    c = link.client
    h.run_until(lambda: link.autopilot.ekf_position, timeout_s=30)
    c.mav.command_long_send(c.target_system, c.target_component, 176, 0, 1, 4, 0, 0, 0, 0, 0)
    ack = h.wait_for(c, "COMMAND_ACK", timeout_s=5)

The client's `mav` is a pymavlink MAVLink encoder, so test code reads like a pymavlink
program; every message goes through real MAVLink bytes both ways.
"""

from __future__ import annotations

import random
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from .airframes import AirframeParams, VehicleModel
from .autopilot import SITL_HOME, Home, SimAutopilot, SimOptions
from .endpoint import VehicleEndpoint


class _FrameSink:
    def __init__(self) -> None:
        self.frames: list[bytes] = []

    def write(self, data: bytes) -> None:
        self.frames.append(bytes(data))


def _split(data: bytes) -> list[Any]:
    """The messages in `data` (a fresh parser: whole frames only)."""
    parser = mavlink.MAVLink(_FrameSink(), srcSystem=0, srcComponent=0)
    parser.robust_parsing = True
    return [
        m for m in parser.parse_buffer(data) or [] if m.get_type() not in ("BAD_DATA", "UNKNOWN")
    ]


class SimClient:
    """The ground end of a harness link: `mav.<message>_send(...)` sends, received
    messages queue up in `inbox` (and all of them in `history`)."""

    def __init__(self, sysid: int = 255, compid: int = 190, target_system: int = 1) -> None:
        self._sink = _FrameSink()
        self.mav = mavlink.MAVLink(self._sink, srcSystem=sysid, srcComponent=compid)
        self._parser = mavlink.MAVLink(_FrameSink(), srcSystem=0, srcComponent=0)
        self._parser.robust_parsing = True
        self.target_system = target_system
        self.target_component = 1
        self.inbox: list[Any] = []
        self.history: list[tuple[float, Any]] = []
        self.raw_out: list[bytes] = []  # extra bytes to send as-is (garbage tests)

    def send_raw(self, data: bytes) -> None:
        self.raw_out.append(bytes(data))

    def take_outgoing(self) -> list[bytes]:
        frames, self._sink.frames = self._sink.frames, []
        raw, self.raw_out = self.raw_out, []
        return frames + raw

    def feed(self, data: bytes, now: float) -> None:
        if not data:
            return
        for msg in self._parser.parse_buffer(data) or []:
            if msg.get_type() in ("BAD_DATA", "UNKNOWN"):
                continue
            self.inbox.append(msg)
            self.history.append((now, msg))

    def pop(
        self, mtype: str | tuple[str, ...] | None = None, cond: Callable[[Any], bool] | None = None
    ) -> Any | None:
        """The oldest unread message of `mtype` (matching `cond`), removed from the inbox."""
        types = (mtype,) if isinstance(mtype, str) else mtype
        for i, msg in enumerate(self.inbox):
            if (types is None or msg.get_type() in types) and (cond is None or cond(msg)):
                return self.inbox.pop(i)
        return None

    def clear(self) -> None:
        self.inbox.clear()

    def seen(self, mtype: str) -> list[Any]:
        return [m for _, m in self.history if m.get_type() == mtype]

    def texts(self) -> list[str]:
        return [m.text for m in self.seen("STATUSTEXT")]


@dataclass
class HarnessLink:
    endpoint: VehicleEndpoint
    client: SimClient
    extra_clients: list[SimClient] = field(default_factory=list)
    loss_to_vehicle: float = 0.0
    loss_to_client: float = 0.0
    drop_to_vehicle: Callable[[Any], bool] | None = None  # per message, True drops it
    latency_s: float = 0.0  # one-way delay, both directions
    rng: random.Random = field(default_factory=lambda: random.Random(0))
    dropped: int = 0
    _up: list[tuple[float, int, bytes]] = field(default_factory=list)  # due, channel, bytes
    _down: list[tuple[float, bytes]] = field(default_factory=list)

    def next_delivery(self) -> float | None:
        times = [t for t, _, _ in self._up[:1]] + [t for t, _ in self._down[:1]]
        return min(times) if times else None

    @property
    def autopilot(self) -> SimAutopilot:
        return self.endpoint.autopilot

    @property
    def clients(self) -> list[SimClient]:
        return [self.client, *self.extra_clients]

    def add_client(self, sysid: int, compid: int = 190) -> SimClient:
        """Another ground station on the same vehicle (it gets everything the vehicle
        sends, like a second TCP client of the runtime)."""
        client = SimClient(sysid=sysid, compid=compid, target_system=self.autopilot.sysid)
        self.extra_clients.append(client)
        return client


class FastTimeHarness:
    def __init__(self, start_time: float = 1_700_000_000.0, seed: int = 0) -> None:
        self.now = start_time
        self.links: list[HarnessLink] = []
        self._seed = seed

    def add_vehicle(
        self,
        model: VehicleModel | str,
        *,
        instance: int = 0,
        home: Home = SITL_HOME,
        airframe: AirframeParams | None = None,
        options: SimOptions | None = None,
        client_sysid: int = 255,
    ) -> HarnessLink:
        endpoint = VehicleEndpoint.create(
            model, home=home, now=self.now, sysid=instance + 1, airframe=airframe, options=options
        )
        client = SimClient(sysid=client_sysid, target_system=endpoint.autopilot.sysid)
        link = HarnessLink(endpoint, client, rng=random.Random(self._seed * 1000 + instance))
        self.links.append(link)
        return link

    def _deliver(self, link: HarnessLink) -> None:
        for channel, client in enumerate(link.clients):
            self._deliver_from(link, client, channel)

    def _deliver_from(self, link: HarnessLink, client: SimClient, channel: int) -> None:
        frames = client.take_outgoing()
        if not frames:
            return
        kept = []
        for frame in frames:
            if link.loss_to_vehicle and link.rng.random() < link.loss_to_vehicle:
                link.dropped += 1
                continue
            if link.drop_to_vehicle is not None:
                msgs = _split(frame)
                if msgs and link.drop_to_vehicle(msgs[0]):
                    link.dropped += 1
                    continue
            kept.append(frame)
        if not kept:
            return
        if link.latency_s > 0:
            link._up.append((self.now + link.latency_s, channel, b"".join(kept)))
            return
        out = link.endpoint.receive(b"".join(kept), self.now, channel=channel)
        self._to_client(link, out)

    def _deliver_due(self, link: HarnessLink) -> None:
        while link._up and link._up[0][0] <= self.now:
            _, channel, data = link._up.pop(0)
            self._to_client(link, link.endpoint.receive(data, self.now, channel=channel))
        while link._down and link._down[0][0] <= self.now:
            _, data = link._down.pop(0)
            for client in link.clients:
                client.feed(data, self.now)

    def _to_client(self, link: HarnessLink, data: bytes) -> None:
        if not data:
            return
        if link.loss_to_client:
            # drop whole frames: re-split by parsing in the client after a loss draw
            msgs = _split(data)
            enc = mavlink.MAVLink(
                _FrameSink(), srcSystem=link.autopilot.sysid, srcComponent=link.autopilot.compid
            )
            kept = []
            for msg in msgs:
                if link.rng.random() < link.loss_to_client:
                    link.dropped += 1
                    continue
                kept.append(msg.pack(enc))
            data = b"".join(kept)
        if link.latency_s > 0:
            link._down.append((self.now + link.latency_s, data))
            return
        for client in link.clients:
            client.feed(data, self.now)

    def step(self, until: float) -> None:
        """Deliver what clients queued, then jump to the next deadline (at most `until`)."""
        for link in self.links:
            self._deliver(link)
        deadlines = [
            d
            for link in self.links
            for d in (link.endpoint.next_deadline(), link.next_delivery())
            if d is not None
        ]
        t = min(deadlines) if deadlines else until
        t = max(self.now, min(t, until))
        self.now = t
        for link in self.links:
            self._deliver_due(link)
            d = link.endpoint.next_deadline()
            if d is not None and d <= t:
                self._to_client(link, link.endpoint.on_timer(t))

    def run_for(self, seconds: float) -> None:
        end = self.now + seconds
        while self.now < end:
            self.step(end)
        for link in self.links:
            self._deliver(link)
            self._deliver_due(link)

    def run_until(self, predicate: Callable[[], bool], timeout_s: float) -> bool:
        """Run until `predicate()` holds (checked after every step); False on timeout."""
        end = self.now + timeout_s
        for link in self.links:
            self._deliver(link)
        while not predicate():
            if self.now >= end:
                return False
            self.step(end)
        return True

    def wait_for(
        self,
        client: SimClient,
        mtype: str | tuple[str, ...],
        timeout_s: float = 10.0,
        cond: Callable[[Any], bool] | None = None,
    ) -> Any | None:
        """Run until `client` receives a message of `mtype` (matching `cond`); pops it."""
        found: list[Any] = []

        def got() -> bool:
            msg = client.pop(mtype, cond)
            if msg is not None:
                found.append(msg)
            return bool(found)

        self.run_until(got, timeout_s)
        return found[0] if found else None
