"""`gcs mavlink`: QGroundControl, MAVProxy or pymavlink on any vehicle, through the
swarm, with the swarm still in charge (docs/ground-station.md, "MAVLink passthrough").

One local MAVLink endpoint per vehicle speaks for that vehicle's autopilot: the
client attaches to it as to the autopilot itself. The frames travel raw over Zenoh to
the vehicle's node, which relays them, answers some itself and rules on those that
would change what the vehicle does (swarm_node/core/passthrough.py). The sessions are
`gcs_cli.core.mavlink_session`'s (pure); this moves the bytes, on one thread.
"""

from __future__ import annotations

import contextlib
import os
import queue
import random
import select
import signal
import threading
import time
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Annotated, Any

import typer

from swarm_node.runtime.mavlink_transport import Endpoint, Transport, make_transport, parse_url
from swarm_proto.clock import clock_from_env
from swarm_proto.messages import MavlinkAnswer, MavlinkSummary
from swarm_proto.session import put_options
from swarm_proto.topics import MAVLINK_ANSWER, MAVLINK_DOWN, MAVLINK_SUMMARY, MAVLINK_UP

from .common import console
from .core.mavlink_session import (
    ANNOUNCE_S,
    CLIENT_TIMEOUT_S,
    Action,
    Announce,
    Command,
    Down,
    Listen,
    RadioAction,
    RadioSessionCore,
    SessionCore,
    Up,
)
from .ground import GroundStation
from .options import AllOption, IdsOption

SUMMARY, ANSWER = -1, -2  # radio frames in the down queue (not session ids)

ServeOption = Annotated[
    str,
    typer.Option(
        "--serve",
        help="the endpoint for the client, as MAVProxy writes it: udp:HOST:PORT (listen), "
        "udpout:HOST:PORT (send to a listening QGroundControl), tcpin:HOST:PORT; with "
        "several vehicles, PORT is the first and each next vehicle gets the next port",
    ),
]


@dataclass
class _Vehicle:
    """One vehicle's endpoint: its transport, its session and its Zenoh ends."""

    vehicle_id: int
    endpoint: Endpoint
    transport: Transport
    core: SessionCore | RadioSessionCore
    sub: Any = None  # the current session's down subscriber
    pub: Any = None  # ... and up publisher


class Bridge:
    """Moves bytes between the endpoints and Zenoh, on the calling thread (`run`)."""

    def __init__(
        self,
        gs: GroundStation,
        read_only: bool,
        client_timeout_s: float = CLIENT_TIMEOUT_S,
        *,
        radio: bool = False,
    ) -> None:
        self.gs = gs
        self.read_only = read_only
        self.radio = radio
        self.client_timeout_s = client_timeout_s
        self.vehicles: dict[int, _Vehicle] = {}
        # from Zenoh's threads: (vehicle, session id or SUMMARY / ANSWER, frames)
        self._down: queue.SimpleQueue[tuple[int, int, bytes]] = queue.SimpleQueue()
        self._wake_r, self._wake_w = os.pipe()
        os.set_blocking(self._wake_r, False)
        os.set_blocking(self._wake_w, False)
        self._rng = random.SystemRandom()
        self.stop = threading.Event()
        # the client is a person's program (wall time); the node times a session out on
        # the swarm's clock, which a simulation runs faster (BANDADA_CLOCK): announced
        # every second of that clock
        wall = clock_from_env().to_wall(ANNOUNCE_S)
        self.announce_s = wall if wall > 0 else ANNOUNCE_S

    def add(self, vehicle_id: int, endpoint: Endpoint) -> None:
        """An endpoint for `vehicle_id` (opened now: OSError when the port is taken)."""
        transport = make_transport(endpoint)
        transport.open()
        if self.radio:
            radio = RadioSessionCore(vehicle_id, self.gs.gcs_id)
            v = self.vehicles[vehicle_id] = _Vehicle(vehicle_id, endpoint, transport, radio)
            bus, swarm = self.gs.bus, self.gs.swarm
            summary = MAVLINK_SUMMARY.key(swarm, vehicle_id=vehicle_id)
            bus.subscribe(MAVLINK_SUMMARY, self._queue(vehicle_id, SUMMARY), key=summary)
            answer = MAVLINK_ANSWER.key(swarm, vehicle_id=vehicle_id, issuer_id=self.gs.gcs_id)
            bus.subscribe(MAVLINK_ANSWER, self._queue(vehicle_id, ANSWER), key=answer)
            self._carry(v, radio.start(time.monotonic()))
            return
        core = SessionCore(
            vehicle_id,
            self.gs.gcs_id,
            lambda: self._rng.randint(1, 2**32 - 1),
            read_only=self.read_only,
            listens=endpoint.kind != "udpout",
            client_timeout_s=self.client_timeout_s,
            announce_s=self.announce_s,
        )
        v = self.vehicles[vehicle_id] = _Vehicle(vehicle_id, endpoint, transport, core)
        self._carry(v, core.start(time.monotonic()))

    def run(self, duration_s: float | None = None) -> None:
        end = None if duration_s is None else time.monotonic() + duration_s
        try:
            while not self.stop.is_set() and (end is None or time.monotonic() < end):
                self.step(0.2)
        finally:
            self.close()

    def step(self, max_wait_s: float) -> None:
        now = time.monotonic()
        dues = [d for v in self.vehicles.values() if (d := v.core.next_deadline()) is not None]
        wait = max(0.0, min([max_wait_s, *(d - now for d in dues)]))
        fds: dict[int, _Vehicle] = {}
        for v in self.vehicles.values():
            for fd in v.transport.filenos():
                fds[fd] = v
        try:
            readable, _, _ = select.select([self._wake_r, *fds], [], [], wait)
        except (OSError, ValueError):
            readable = []
        if self._wake_r in readable:
            with contextlib.suppress(OSError):
                os.read(self._wake_r, 4096)
        now = time.monotonic()
        for fd in readable:
            if fd not in fds:
                continue
            v = fds[fd]
            for _ in range(64):
                try:
                    data = v.transport.read()
                except OSError:
                    v.transport.close()
                    with contextlib.suppress(OSError):
                        v.transport.open()
                    break
                if not data:
                    break
                self._carry(v, v.core.on_client(data, now))
        while True:
            try:
                vid, sid, data = self._down.get_nowait()
            except queue.Empty:
                break
            v2 = self.vehicles.get(vid)
            if v2 is None:
                continue
            c = v2.core
            if isinstance(c, RadioSessionCore):
                got = c.on_summary(data, now) if sid == SUMMARY else c.on_answer(data)
                self._carry(v2, got)
            else:
                self._carry(v2, c.on_vehicle(sid, data))
        for v in self.vehicles.values():
            self._carry(v, v.core.on_timer(now))

    def _carry(self, v: _Vehicle, actions: Sequence[Action | RadioAction]) -> None:
        session = self.gs.bus.session
        for a in actions:
            if isinstance(a, Command):
                self.gs.bus.publish(a.msg)  # the radio gateway carries it
            elif isinstance(a, Up):
                if v.pub is not None:
                    v.pub.put(a.data)
            elif isinstance(a, Down):
                with contextlib.suppress(OSError):
                    v.transport.write(a.data)
            elif isinstance(a, Announce):
                self.gs.bus.publish(a.msg)
                if a.msg.closing:
                    console.print(f"vehicle {v.vehicle_id}: session {a.msg.session_id} ended")
            elif isinstance(a, Listen):
                for old in (v.sub, v.pub):
                    if old is not None:
                        with contextlib.suppress(Exception):
                            old.undeclare()
                v.sub = v.pub = None
                sid = a.session_id
                if sid is None:
                    continue
                swarm, vid = self.gs.swarm, v.vehicle_id
                down = MAVLINK_DOWN.key(swarm, vehicle_id=vid, session_id=sid)
                up = MAVLINK_UP.key(swarm, vehicle_id=vid, session_id=sid)
                v.sub = session.declare_subscriber(down, self._on_down(vid, sid))
                v.pub = session.declare_publisher(up, **put_options(MAVLINK_UP))
                mode = " (read-only)" if self.read_only else ""
                console.print(f"vehicle {vid}: session {sid} open{mode}")

    def _queue(self, vid: int, kind: int) -> Any:
        """A typed subscriber's callback: a radio summary's or answer's frames."""

        def handler(msg: MavlinkSummary | MavlinkAnswer, _key: str) -> None:
            self._down.put((vid, kind, msg.frame))
            with contextlib.suppress(OSError):
                os.write(self._wake_w, b"x")

        return handler

    def _on_down(self, vid: int, sid: int) -> Any:
        def handler(sample: Any) -> None:
            self._down.put((vid, sid, sample.payload.to_bytes()))
            with contextlib.suppress(OSError):
                os.write(self._wake_w, b"x")

        return handler

    def close(self) -> None:
        for v in self.vehicles.values():
            self._carry(v, v.core.close())
            self._carry(v, [Listen(None)])
            v.transport.close()
        for fd in (self._wake_r, self._wake_w):
            with contextlib.suppress(OSError):
                os.close(fd)
        self._wake_r = self._wake_w = -1


def endpoint_for(base: Endpoint, index: int) -> Endpoint:
    """The `index`-th vehicle's endpoint: the base port plus `index`."""
    if base.kind == "serial":
        raise typer.BadParameter(
            "a serial port cannot serve several vehicles", param_hint="--serve"
        )
    port = base.port + index
    if not 0 < port <= 65535:
        raise typer.BadParameter(f"port {port} out of range", param_hint="--serve")
    return replace(base, port=port)


def mavlink(
    ctx: typer.Context,
    ids: IdsOption = [],  # noqa: B006 (typer reads the default)
    all_: AllOption = False,
    serve: ServeOption = "udp:127.0.0.1:14550",
    read_only: bool = typer.Option(
        False, "--read-only", help="telemetry and downloads only: the vehicle refuses the rest"
    ),
    client_timeout: float = typer.Option(
        CLIENT_TIMEOUT_S, min=1.0, max=3600.0, help="a client silent this long ends its session"
    ),
    duration: float | None = typer.Option(
        None, min=0.1, help="stop after this many seconds (default: until Ctrl-C)"
    ),
    radio: bool = typer.Option(
        False,
        "--radio",
        help="a vehicle behind the 900 MHz radio: its HIGH_LATENCY2 every 5 s and commands only",
    ),
) -> None:
    """A vehicle's autopilot for QGroundControl, MAVProxy or pymavlink, through the swarm:
    one local endpoint per vehicle, speaking with that autopilot's system id. The
    vehicle's node relays reads and downloads, and rules on what would change what the
    vehicle does: a mode change or mission upload during a swarm mission takes the
    vehicle out of its fleet, with an alert.

    Example: gcs mavlink --id 7 --serve udp:127.0.0.1:14550   (then: mavproxy.py --master udpout:127.0.0.1:14550)
    """
    if bool(ids) == all_:
        raise typer.BadParameter("say which vehicles: --id N (repeat for more) or --all")
    try:
        base = parse_url(serve)
    except ValueError as exc:
        raise typer.BadParameter(str(exc), param_hint="--serve") from exc
    if base.kind == "serial":
        raise typer.BadParameter(
            "serve on udp:, udpout: or tcpin: (a serial port is not an endpoint here)",
            param_hint="--serve",
        )
    if radio and read_only:
        raise typer.BadParameter("--radio carries commands only: --read-only is not for it")
    with ctx.obj.open() as gs:
        wanted = sorted(set(ids)) if ids else sorted(gs.discover())
        if not wanted:
            raise typer.BadParameter("no vehicle alive", param_hint="--all")
        bridge = Bridge(gs, read_only, client_timeout, radio=radio)
        for i, vid in enumerate(wanted):
            ep = endpoint_for(base, i)
            try:
                bridge.add(vid, ep)
            except OSError as exc:
                bridge.close()
                raise typer.BadParameter(
                    f"cannot serve {ep.kind}:{ep.host}:{ep.port}: {exc}", param_hint="--serve"
                ) from exc
            mode = (
                " (read-only)" if read_only else " (radio: summary and commands)" if radio else ""
            )
            console.print(f"vehicle {vid}: {ep.kind}:{ep.host}:{ep.port}{mode}")
        previous = signal.getsignal(signal.SIGTERM)
        signal.signal(signal.SIGTERM, lambda *_: bridge.stop.set())
        try:
            bridge.run(duration)
        except KeyboardInterrupt:
            pass
        finally:
            signal.signal(signal.SIGTERM, previous)
        for vid, v in bridge.vehicles.items():
            c = v.core.counts
            if isinstance(v.core, RadioSessionCore):
                console.print(
                    f"vehicle {vid}: {c['summaries']} summaries, {c['commands']} commands, "
                    f"{c['answers']} answers, {c['too_soon'] + c['not_on_the_radio']} refused here"
                )
                continue
            console.print(
                f"vehicle {vid}: {v.core.sessions} session(s), {c['frames_up']} frames up, "
                f"{c['bytes_down']} bytes down, {c['malformed']} malformed runs dropped"
            )
