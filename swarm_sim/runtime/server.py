"""TCP shell around simulated vehicles: each vehicle listens on its own port (ArduPilot
SITL's tcp:5760 + 10*instance), any number of vehicles in one process and one thread.
One `selectors` loop reads clients, feeds the pure `VehicleEndpoint`s with the shared
clock's time, and sleeps until the earliest vehicle deadline.

Unlike SITL, a port accepts several clients at once (a node and MAVProxy, say) and
sends every client everything the vehicle sends; the simulation runs whether or not
anyone is connected.
"""

from __future__ import annotations

import contextlib
import logging
import selectors
import socket
import threading
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field

from swarm_proto.clock import Clock

from ..core.airframes import AirframeParams, VehicleModel
from ..core.autopilot import SITL_HOME, Home, SimOptions
from ..core.endpoint import VehicleEndpoint, sitl_port

log = logging.getLogger(__name__)

MAX_CLIENT_BACKLOG_BYTES = 4 * 1024 * 1024  # a client this far behind loses its telemetry
READ_CHUNK = 65536
MAX_SLEEP_WALL_S = 0.2  # wake up at least this often to notice `stop`
MIN_SLEEP_WALL_S = 0.0005
MANUAL_CLOCK_POLL_S = 0.01


@dataclass(frozen=True)
class VehicleSpec:
    """One simulated vehicle to serve."""

    model: VehicleModel | str
    instance: int = 0
    home: Home = SITL_HOME
    sysid: int | None = None  # default instance + 1 (like sim_vehicle.py --auto-sysid)
    airframe: AirframeParams | None = None
    options: SimOptions | None = None
    port: int | None = None  # default 5760 + 10 * instance

    @property
    def tcp_port(self) -> int:
        return self.port if self.port is not None else sitl_port(self.instance)

    @property
    def system_id(self) -> int:
        return self.sysid if self.sysid is not None else self.instance + 1


@dataclass
class _Client:
    sock: socket.socket
    vehicle: _Vehicle
    outbuf: bytearray = field(default_factory=bytearray)


@dataclass
class _Vehicle:
    spec: VehicleSpec
    endpoint: VehicleEndpoint
    listener: socket.socket
    clients: list[_Client] = field(default_factory=list)


class VehicleServer:
    """Serves `specs` on 127.0.0.1 (or `host`). `start()` binds the ports (OSError if one
    is taken), `serve(stop)` runs until `stop` is set, `close()` releases everything."""

    def __init__(
        self,
        specs: list[VehicleSpec],
        clock: Clock,
        host: str = "127.0.0.1",
        endpoints: list[VehicleEndpoint] | None = None,
    ) -> None:
        """`endpoints`: already built (e.g. flown ahead in fast time) vehicles to serve
        instead of new ones, one per spec; their time must not be ahead of `clock`."""
        if not specs:
            raise ValueError("no vehicles to serve")
        ports = [s.tcp_port for s in specs if s.tcp_port != 0]  # 0: any free port
        if len(set(ports)) != len(ports):
            raise ValueError(f"two vehicles on one port: {ports}")
        if endpoints is not None and len(endpoints) != len(specs):
            raise ValueError("one endpoint per spec")
        self.specs = specs
        self.clock = clock
        self.host = host
        self._given = endpoints
        self.vehicles: list[_Vehicle] = []
        self.counters: Counter[str] = Counter()
        self.max_lag_s = 0.0  # worst lateness of a vehicle deadline, simulated seconds
        self._sel = selectors.DefaultSelector()
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()
        self._actions: list[Callable[[], None]] = []  # run by the serving thread
        self._actions_lock = threading.Lock()
        self._removals: list[int] = []  # system ids to take away (another thread asks)
        self._removals_lock = threading.Lock()

    # lifecycle -------------------------------------------------------------------

    def start(self) -> None:
        now = self.clock.now()
        try:
            for k, spec in enumerate(self.specs):
                listener = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
                listener.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
                listener.bind((self.host, spec.tcp_port))
                listener.listen(8)
                listener.setblocking(False)
                if self._given is not None:
                    endpoint = self._given[k]
                else:
                    endpoint = VehicleEndpoint.create(
                        spec.model,
                        home=spec.home,
                        now=now,
                        sysid=spec.system_id,
                        airframe=spec.airframe,
                        options=spec.options,
                    )
                vehicle = _Vehicle(spec, endpoint, listener)
                self.vehicles.append(vehicle)
                self._sel.register(listener, selectors.EVENT_READ, vehicle)
        except BaseException:
            self.close()
            raise

    @property
    def ports(self) -> list[int]:
        """The TCP port each vehicle listens on, in spec order (after start: a spec's
        port 0 is the free port the kernel gave)."""
        return [int(v.listener.getsockname()[1]) for v in self.vehicles]

    def serve(self, stop: threading.Event | None = None) -> None:
        stop = stop if stop is not None else self._stop
        if not self.vehicles:
            self.start()
        while not stop.is_set():
            if self._removals:
                self._remove_now()
            self._run_timers()
            self._wait_and_read()

    def remove(self, system_id: int) -> None:
        """Take a vehicle away (a crash: it stops, its clients are disconnected, its port
        closes); from any thread, carried out by the serving loop."""
        with self._removals_lock:
            self._removals.append(system_id)

    def _remove_now(self) -> None:
        with self._removals_lock:
            gone, self._removals = set(self._removals), []
        for vehicle in [v for v in self.vehicles if v.spec.system_id in gone]:
            for client in list(vehicle.clients):
                self._drop(client)
            with contextlib.suppress(KeyError, ValueError):
                self._sel.unregister(vehicle.listener)
            vehicle.listener.close()
            self.vehicles.remove(vehicle)
            log.info("vehicle %d: removed", vehicle.spec.system_id)

    def start_thread(self) -> None:
        """start() and serve() in a daemon thread; stop with close()."""
        if not self.vehicles:
            self.start()
        self._thread = threading.Thread(
            target=self.serve, args=(self._stop,), daemon=True, name="swarm-sim"
        )
        self._thread.start()

    def close(self) -> None:
        self._stop.set()
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(timeout=5.0)
            self._thread = None
        for vehicle in self.vehicles:
            for client in list(vehicle.clients):
                self._drop(client)
            with contextlib.suppress(KeyError, ValueError):
                self._sel.unregister(vehicle.listener)
            vehicle.listener.close()
        self.vehicles.clear()
        self._sel.close()

    def __enter__(self) -> VehicleServer:
        self.start_thread()
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    @property
    def endpoints(self) -> list[VehicleEndpoint]:
        return [v.endpoint for v in self.vehicles]

    def reboot(self, sysid: int, *, keep_stores: bool = False) -> None:
        """Power-cycle vehicle `sysid`: its clients are disconnected, as a real
        reboot drops the USB or TCP link, and it boots again where it stands, by default
        with empty mission, fence and rally stores. Safe from any thread."""

        def act() -> None:
            for v in self.vehicles:
                if v.spec.system_id == sysid:
                    for client in list(v.clients):
                        self._drop(client)
                    v.endpoint.reboot(self.clock.now(), keep_stores=keep_stores)
                    self.counters["reboots"] += 1

        with self._actions_lock:
            self._actions.append(act)

    # loop ------------------------------------------------------------------------

    def _run_timers(self) -> None:
        with self._actions_lock:
            actions, self._actions = self._actions, []
        for act in actions:
            act()
        now = self.clock.now()
        for vehicle in self.vehicles:
            deadline = vehicle.endpoint.next_deadline()
            if deadline is not None and deadline <= now:
                self.max_lag_s = max(self.max_lag_s, now - deadline)
                self._broadcast(vehicle, vehicle.endpoint.on_timer(now))

    def _next_deadline(self) -> float | None:
        deadlines = [
            d for d in (v.endpoint.next_deadline() for v in self.vehicles) if d is not None
        ]
        return min(deadlines) if deadlines else None

    def _wait_and_read(self) -> None:
        deadline = self._next_deadline()
        if deadline is None:
            timeout = MAX_SLEEP_WALL_S
        else:
            ahead = deadline - self.clock.now()
            wall = self.clock.to_wall(ahead) if ahead > 0 else 0.0
            if ahead > 0 and wall <= 0.0:
                wall = MANUAL_CLOCK_POLL_S  # a ManualClock: time moves only when told
            timeout = 0.0 if ahead <= 0 else max(MIN_SLEEP_WALL_S, min(MAX_SLEEP_WALL_S, wall))
        for key, events in self._sel.select(timeout):
            obj = key.data
            if isinstance(obj, _Vehicle):
                self._accept(obj)
            elif isinstance(obj, _Client):
                if events & selectors.EVENT_READ:
                    self._read(obj)
                if events & selectors.EVENT_WRITE and obj.sock.fileno() >= 0:
                    self._flush(obj)

    def _accept(self, vehicle: _Vehicle) -> None:
        try:
            sock, addr = vehicle.listener.accept()
        except (BlockingIOError, InterruptedError):
            return
        sock.setblocking(False)
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        client = _Client(sock, vehicle)
        vehicle.clients.append(client)
        self._sel.register(sock, selectors.EVENT_READ, client)
        self.counters["accepted"] += 1
        log.info("vehicle %d: client %s connected", vehicle.spec.system_id, addr)

    def _read(self, client: _Client) -> None:
        try:
            data = client.sock.recv(READ_CHUNK)
        except (BlockingIOError, InterruptedError):
            return
        except OSError:
            data = b""
        if not data:
            self._drop(client)
            return
        vehicle = client.vehicle
        out = vehicle.endpoint.receive(data, self.clock.now(), channel=id(client))
        self._broadcast(vehicle, out)

    def _broadcast(self, vehicle: _Vehicle, data: bytes) -> None:
        if not data:
            return
        for client in list(vehicle.clients):
            if client.outbuf:
                if len(client.outbuf) + len(data) > MAX_CLIENT_BACKLOG_BYTES:
                    self.counters["tx_dropped_bytes"] += len(data)
                    continue
                client.outbuf += data
                continue
            try:
                sent = client.sock.send(data)
            except (BlockingIOError, InterruptedError):
                sent = 0
            except OSError:
                self._drop(client)
                continue
            if sent < len(data):
                client.outbuf += data[sent:]
                self._sel.modify(client.sock, selectors.EVENT_READ | selectors.EVENT_WRITE, client)

    def _flush(self, client: _Client) -> None:
        try:
            sent = client.sock.send(client.outbuf)
        except (BlockingIOError, InterruptedError):
            return
        except OSError:
            self._drop(client)
            return
        del client.outbuf[:sent]
        if not client.outbuf:
            self._sel.modify(client.sock, selectors.EVENT_READ, client)

    def _drop(self, client: _Client) -> None:
        vehicle = client.vehicle
        if client in vehicle.clients:
            vehicle.clients.remove(client)
        vehicle.endpoint.drop_channel(id(client))
        with contextlib.suppress(KeyError, ValueError):
            self._sel.unregister(client.sock)
        client.sock.close()
        self.counters["disconnected"] += 1


def spread_homes(home: Home, count: int, spacing_m: float) -> list[Home]:
    """`count` homes east of `home`, `spacing_m` apart (vehicles of one process must not
    start on top of each other)."""
    from ..core.geo import LocalFrame

    frame = LocalFrame(home.lat_deg, home.lon_deg)
    homes = []
    for k in range(count):
        lat, lon = frame.to_latlon(0.0, k * spacing_m)
        homes.append(Home(lat, lon, home.alt_m, home.heading_deg))
    return homes
