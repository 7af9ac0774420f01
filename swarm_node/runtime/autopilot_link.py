"""The autopilot link of a vehicle node: one thread that moves MAVLink bytes between a
connection (serial, UDP, TCP) and the pure `LinkCore`, on an injected clock.

    link = AutopilotLink("tcp:127.0.0.1:5760", clock, vehicle_type=VehicleType.VTOL,
                         on_event=print)
    link.start()
    link.state                                   # AutopilotState snapshot, any thread
    result = link.submit(Arm()).result(timeout=10)   # concurrent.futures.Future[ApResult]
    link.close()

Reconnection: a connection that fails to open is retried every `reopen_interval_s`
(wall seconds); one that breaks (TCP closed, serial device gone) is closed and
reopened the same way; a TCP or serial connection that stays silent for
`reopen_after_silence_s` (clock seconds) after a LinkLost is reopened too. Link loss
and restoration are reported as events (LinkLost within `link_timeout_s`, 0.9 s).
"""

from __future__ import annotations

import contextlib
import dataclasses
import logging
import os
import queue
import select
import threading
import time
from collections.abc import Callable, Mapping
from concurrent.futures import Future
from typing import Any

import msgspec

from swarm_node.core.autopilot.events import ApEvent, HostStalled, LinkLost, LinkRestored
from swarm_node.core.autopilot.framing import MAVLinkMessage
from swarm_node.core.autopilot.link import Complete, Emit, LinkCore, LinkSettings, Output, Transmit
from swarm_node.core.autopilot.plans import InvalidRequest
from swarm_node.core.autopilot.requests import ApError, ApRequest, ApResult
from swarm_node.core.autopilot.state import AutopilotState
from swarm_node.core.autopilot.status import to_vehicle_status
from swarm_proto import AlertFlag, Clock, FsmState, MissionState, VehicleStatus, VehicleType

from .mavlink_transport import Transport, make_transport, parse_url

log = logging.getLogger("swarm_node.autopilot")

__all__ = ["AutopilotLink", "InvalidRequest", "LinkSettings"]


class AutopilotLink:
    """See the module docstring and docs/autopilot-link.md."""

    def __init__(
        self,
        url: str,
        clock: Clock,
        *,
        vehicle_type: VehicleType | None = None,
        target_sysid: int | None = None,
        target_compid: int | None = None,
        baud: int = 57600,
        on_event: Callable[[ApEvent], None] | None = None,
        on_send: Callable[[MAVLinkMessage], None] | None = None,
        settings: LinkSettings | None = None,
        reopen_interval_s: float = 1.0,
        reopen_after_silence_s: float = 3.0,
        name: str = "autopilot-link",
    ) -> None:
        self.url = url
        self.endpoint = parse_url(url, baud)  # ValueError now, not in the thread
        self.clock = clock
        base = settings or LinkSettings()
        self.settings = dataclasses.replace(
            base,
            vehicle_type=vehicle_type if vehicle_type is not None else base.vehicle_type,
            target_sysid=target_sysid if target_sysid is not None else base.target_sysid,
            target_compid=target_compid if target_compid is not None else base.target_compid,
        )
        self.on_event = on_event
        self.on_send = on_send
        self.reopen_interval_s = reopen_interval_s
        self.reopen_after_silence_s = reopen_after_silence_s
        self.name = name
        #: events when no `on_event` callback is given (bounded; see `dropped_events`)
        self.events: queue.Queue[ApEvent] = queue.Queue(maxsize=10_000)
        self.dropped_events = 0
        self.reconnects = 0
        self.io_errors = 0
        self._core = LinkCore(self.settings, clock.now())
        self._state: AutopilotState = self._core.state
        self._transport: Transport = make_transport(self.endpoint)
        self._inbox: queue.SimpleQueue[tuple[int, ApRequest, Future[ApResult]]] = (
            queue.SimpleQueue()
        )
        self._futures: dict[int, Future[ApResult]] = {}
        self._next_token = 1
        self._token_lock = threading.Lock()
        self._wake_r, self._wake_w = os.pipe()
        os.set_blocking(self._wake_r, False)
        os.set_blocking(self._wake_w, False)
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._closed = False
        self._reopen_at = 0.0  # monotonic wall time
        self._lost_since: float | None = None
        self._problem = ""  # why nothing is heard yet (AutopilotState.link_problem)
        # passthrough (core/passthrough.py): sessions' frames to write, the autopilot's
        # frames for them (`on_frames`, on this link's thread, while tapped)
        self._relay_out: queue.SimpleQueue[bytes] = queue.SimpleQueue()
        self._wishes: queue.SimpleQueue[dict[str, float]] = queue.SimpleQueue()  # stream rates
        self._tap = False
        self.on_frames: Callable[[bytes], None] | None = None

    # ------------------------------------------------------------------ public API

    @property
    def state(self) -> AutopilotState:
        """The latest AutopilotState (an immutable snapshot; safe from any thread)."""
        return self._state

    def start(self) -> None:
        if self._thread is not None:
            raise RuntimeError("AutopilotLink already started")
        if self._closed:
            raise RuntimeError("AutopilotLink is closed")
        self._thread = threading.Thread(target=self._run, name=self.name, daemon=True)
        self._thread.start()

    def submit(self, request: ApRequest) -> Future[ApResult]:
        """Queue a request; the Future resolves with its ApResult (never an exception).
        Raises InvalidRequest at once for a malformed request (NaN, unknown mode...)."""
        if self._closed:
            raise RuntimeError("AutopilotLink is closed")
        from swarm_node.core.autopilot.plans import check_request

        vt = self._state.vehicle_type
        check_request(request, vt if vt != VehicleType.OTHER else None)
        future: Future[ApResult] = Future()
        with self._token_lock:
            token = self._next_token
            self._next_token += 1
        self._inbox.put((token, request, future))
        self._wake()
        return future

    def relay(self, data: bytes) -> None:
        """A passthrough session's frames, written to the autopilot as they are (any
        thread; the node's core decided they may go: core/passthrough.py)."""
        if data and not self._closed:
            self._relay_out.put(bytes(data))
            self._wake()

    def want_rates(self, rates: Mapping[str, float]) -> None:
        """Message rates passthrough sessions want (name -> Hz; any thread)."""
        self._wishes.put(dict(rates))
        self._wake()

    def set_tap(self, on: bool) -> None:
        """Hand the autopilot's frames to `on_frames` (passthrough sessions open)."""
        self._tap = on

    def request(self, request: ApRequest, timeout_s: float | None = None) -> ApResult:
        """Blocking submit (wall-clock `timeout_s`; None waits for the result, which
        always comes: every request ends after its attempts)."""
        return self.submit(request).result(timeout=timeout_s)

    def vehicle_status(
        self,
        vehicle_id: int,
        *,
        fsm_state: FsmState = FsmState.INACTIVE,
        mission_state: MissionState = MissionState.IDLE,
        mission_progress: int | None = None,
        fleet_id: int = 0,
        alerts: AlertFlag = AlertFlag.NONE,
    ) -> VehicleStatus | None:
        """`to_vehicle_status(self.state, ...)` at the clock's now (None: no position)."""
        return to_vehicle_status(
            self._state,
            vehicle_id=vehicle_id,
            now_unix_s=self.clock.now(),
            fsm_state=fsm_state,
            mission_state=mission_state,
            mission_progress=mission_progress,
            fleet_id=fleet_id,
            alerts=alerts,
        )

    def stats(self) -> dict[str, Any]:
        c = self._core.counters
        return {
            "connection": self._transport.description,
            "bytes_in": c.bytes_in,
            "bytes_out": c.bytes_out,
            "messages_in": c.messages_in,
            "messages_out": c.messages_out,
            "garbage_bytes": self._core.framer.garbage_bytes,
            "bad_packets": self._state.bad_packets,
            "foreign_packets": self._state.foreign_packets,
            "unhandled": self._core.tracker.unhandled,
            "not_for_us": c.not_for_us,
            "relayed_out": c.relayed_out,
            "tapped": c.tapped,
            "last_bad_reason": self._core.tracker.last_bad_reason,
            "reconnects": self.reconnects,
            "io_errors": self.io_errors,
            "link_losses": self._state.link_losses,
            "dropped_events": self.dropped_events,
            "pending_requests": self._core.pending_requests(),
        }

    def close(self, timeout_s: float = 5.0) -> None:
        """Stop the thread, resolve pending requests as CANCELLED, close the connection."""
        if self._closed:
            return
        self._closed = True
        self._stop.set()
        self._wake()
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(timeout_s)
            if self._thread.is_alive():
                log.error("%s: I/O thread did not stop within %.1f s", self.name, timeout_s)
        self._execute(self._core.close("link closed"))
        self._drain_inbox("link closed")
        self._transport.close()
        for fd in (self._wake_r, self._wake_w):
            with contextlib.suppress(OSError):
                os.close(fd)

    def __enter__(self) -> AutopilotLink:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # ------------------------------------------------------------------ the I/O thread

    def _wake(self) -> None:
        with contextlib.suppress(OSError):
            os.write(self._wake_w, b"x")

    def _run(self) -> None:
        try:
            while not self._stop.is_set():
                self._step()
        except Exception:  # a bug here must not die silently
            log.exception("%s: I/O thread crashed", self.name)
            raise

    def _step(self) -> None:
        t = self._transport
        if not t.is_open and time.monotonic() >= self._reopen_at:
            try:
                t.open()
                log.info("%s: opened %s", self.name, t.description)
                self._problem = f"{t.description} open, nothing heard"
            except OSError as exc:
                self._reopen_at = time.monotonic() + self.reopen_interval_s
                log.debug("%s: cannot open %s: %s", self.name, t.description, exc)
                self._problem = f"{t.description}: {exc.strerror or exc}"
        now = self.clock.now()
        wait = self._wait_s(now)
        link_fds = t.filenos()
        try:
            readable, _, _ = select.select([self._wake_r, *link_fds], [], [], wait)
        except (OSError, ValueError):  # an fd was closed under us
            readable = []
            self._broken("select failed")
        if self._wake_r in readable:
            with contextlib.suppress(OSError):
                os.read(self._wake_r, 4096)
        out: list[Output] = []
        self._core.tap = self._tap and self.on_frames is not None
        if any(fd in readable for fd in link_fds):
            for _ in range(64):  # drain, but let timers run under a flood
                try:
                    data = t.read()
                except OSError as exc:
                    self._broken(str(exc))
                    break
                if not data:
                    break
                out += self._core.receive(data, self.clock.now())
        while True:
            try:
                out += self._core.relay(self._relay_out.get_nowait())
            except queue.Empty:
                break
        now = self.clock.now()
        wishes: dict[str, float] | None = None
        while True:  # the newest wishes only
            try:
                wishes = self._wishes.get_nowait()
            except queue.Empty:
                break
        if wishes is not None:
            out += self._core.want_rates(wishes, now)
        while True:
            try:
                token, request, future = self._inbox.get_nowait()
            except queue.Empty:
                break
            self._futures[token] = future
            try:
                out += self._core.submit(token, request, now)
            except InvalidRequest as exc:  # the vehicle type became known meanwhile
                self._resolve(
                    token, ApResult(request.request_id, False, str(exc), error=ApError.DENIED)
                )
        if now >= self._core.next_deadline():
            out += self._core.on_timer(now)
        self._execute(out)
        state = self._core.state
        if self._problem and state.last_message_s is None:
            # nothing heard yet: the state carries why, for the node's alert
            state = msgspec.structs.replace(state, link_problem=self._problem)
        self._state = state
        tapped = self._core.take_tapped()
        if tapped and self.on_frames is not None:
            self._call(self.on_frames, tapped)
        self._maybe_reopen_silent(now)

    def _wait_s(self, now: float) -> float:
        dt = self._core.next_deadline() - now
        if dt <= 0:
            return 0.0
        wall = self.clock.to_wall(dt)
        if wall <= 0:  # a manual clock: time moves only when a test moves it
            return 0.005
        return min(wall, 0.1)

    def _broken(self, why: str) -> None:
        self.io_errors += 1
        log.info("%s: connection %s broke: %s", self.name, self._transport.description, why)
        self._transport.close()
        self.reconnects += 1
        self._reopen_at = time.monotonic() + min(self.reopen_interval_s, 0.2)

    def _maybe_reopen_silent(self, now: float) -> None:
        if self.endpoint.kind not in ("tcp", "serial"):
            return
        if self._state.link_ok or self._state.last_message_s is None:
            self._lost_since = None
            return
        if self._lost_since is None:
            self._lost_since = now
        elif now - self._lost_since >= self.reopen_after_silence_s and self._transport.is_open:
            self._lost_since = now
            self._broken("silent since the link was lost")

    def _execute(self, outputs: list[Output]) -> None:
        for o in outputs:
            if isinstance(o, Transmit):
                try:
                    self._transport.write(o.data)
                except OSError as exc:
                    self._broken(str(exc))
                if self.on_send is not None and o.message is not None:
                    self._call(self.on_send, o.message)
            elif isinstance(o, Emit):
                ev = o.event
                if isinstance(ev, LinkLost):
                    log.warning("%s: link lost (%.2f s silent)", self.name, ev.silent_s)
                elif isinstance(ev, LinkRestored):
                    log.info(
                        "%s: link restored after %.2f s (the autopilot's own clock: %.2f s)",
                        self.name,
                        ev.down_s,
                        ev.autopilot_gap_s,
                    )
                elif isinstance(ev, HostStalled):  # a second or more is worth a warning
                    log.log(
                        logging.WARNING if ev.stall_s >= 1.0 else logging.DEBUG,
                        "%s: read %.2f s late (this host stalled, not the link)",
                        self.name,
                        ev.stall_s,
                    )
                self._deliver(ev)
            elif isinstance(o, Complete):
                self._resolve(o.token, o.result)

    def _deliver(self, event: ApEvent) -> None:
        if self.on_event is not None:
            self._call(self.on_event, event)
            return
        try:
            self.events.put_nowait(event)
        except queue.Full:
            self.dropped_events += 1

    def _call(self, fn: Callable[[Any], None], arg: Any) -> None:
        try:
            fn(arg)
        except Exception:
            log.exception("%s: callback %r failed", self.name, fn)

    def _resolve(self, token: int, result: ApResult) -> None:
        future = self._futures.pop(token, None)
        if future is not None and not future.done():
            future.set_result(result)

    def _drain_inbox(self, reason: str) -> None:
        while True:
            try:
                token, request, future = self._inbox.get_nowait()
            except queue.Empty:
                break
            if not future.done():
                future.set_result(
                    ApResult(request.request_id, False, reason, error=ApError.CANCELLED)
                )
        for token in list(self._futures):
            self._resolve(token, ApResult(0, False, reason, error=ApError.CANCELLED))
