"""The serial side of a gateway: a pyserial port and a `RadioNode` driven in real time.

One thread reads the port and timestamps what arrives; one loop thread owns the node:
it feeds it received bytes and queued messages, sleeps until the node's next deadline
and writes each frame in one serial write at the time the node asked for. Callbacks run
on the loop thread.
"""

from __future__ import annotations

import contextlib
import logging
import queue
import threading
from collections.abc import Callable
from typing import Any

import serial

from swarm_proto.clock import Clock, SystemClock

from ..core.node import Deliver, Notice, RadioNode, Transmit
from ..core.outbox import OutMessage
from .timesource import TimeSource

log = logging.getLogger(__name__)

DeliverCallback = Callable[[Deliver, float], None]
TickCallback = Callable[[RadioNode, float], None]


class RadioLink:
    def __init__(
        self,
        port: serial.Serial,
        node: RadioNode,
        time_source: TimeSource,
        *,
        clock: Clock | None = None,
        on_deliver: DeliverCallback | None = None,
        on_tick: TickCallback | None = None,
        name: str = "radio",
    ) -> None:
        """`clock` converts time-source seconds to wall seconds for sleeping (a
        ScaledClock in a simulation)."""
        self.port = port
        self.node = node
        self.time = time_source
        self.clock = clock or SystemClock()
        self.on_deliver = on_deliver
        self.on_tick = on_tick
        self.name = name
        self.inbox: queue.Queue[tuple[str, Any, float]] = queue.Queue()
        self.late_writes = 0
        self.write_errors = 0
        self._stop = threading.Event()
        self._threads: list[threading.Thread] = []

    def start(self) -> RadioLink:
        for target, suffix in ((self._read, "rx"), (self._loop, "loop")):
            t = threading.Thread(target=target, name=f"{self.name}-{suffix}", daemon=True)
            t.start()
            self._threads.append(t)
        return self

    def submit(self, msg: OutMessage) -> None:
        """Queue a message for the air (any thread)."""
        self.inbox.put(("tx", msg, self.time.now()))

    def call(self, fn: Callable[[RadioNode], None]) -> None:
        """Run `fn(node)` on the loop thread (any thread)."""
        self.inbox.put(("call", fn, 0.0))

    def close(self) -> None:
        self._stop.set()
        for t in self._threads:
            t.join(timeout=5)
        self._threads = []
        with contextlib.suppress(Exception):
            self.port.close()

    def __enter__(self) -> RadioLink:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.close()

    # ------------------------------------------------------------------ threads
    def _read(self) -> None:
        while not self._stop.is_set():
            try:
                data = self.port.read(max(1, self.port.in_waiting))
            except (serial.SerialException, OSError, TypeError, AttributeError):
                if self._stop.is_set():
                    return
                log.warning("%s: serial read failed", self.name, exc_info=True)
                self._stop.wait(0.2)
                continue
            if data:
                self.inbox.put(("rx", data, self.time.now()))

    def _loop(self) -> None:
        node = self.node
        while not self._stop.is_set():
            now = self.time.now()
            node.timesync.source_stratum = self.time.stratum
            deadline = node.next_deadline()
            wait = min(max(self.clock.to_wall(deadline - now), 0.0), 0.05)
            try:
                item = self.inbox.get(timeout=wait)
            except queue.Empty:
                item = None
            while item is not None:
                self._handle(item)
                try:
                    item = self.inbox.get_nowait()
                except queue.Empty:
                    item = None
            now = self.time.now()
            if now >= node.next_deadline():
                self._act(node.on_timer(now))
            if self.on_tick is not None:
                try:
                    self.on_tick(node, now)
                except Exception:
                    log.exception("%s: tick handler failed", self.name)

    def _handle(self, item: tuple[str, Any, float]) -> None:
        kind, payload, t = item
        if kind == "rx":
            self._act(self.node.handle_bytes(payload, t))
        elif kind == "tx":
            self.node.submit(payload, t)
        elif kind == "call":
            payload(self.node)

    def _act(self, actions: list[Transmit | Deliver | Notice]) -> None:
        for a in actions:
            if isinstance(a, Transmit):
                self._write(a)
            elif isinstance(a, Deliver):
                if self.on_deliver is not None:
                    try:
                        self.on_deliver(a, self.time.now())
                    except Exception:
                        log.exception("%s: deliver handler failed", self.name)
            else:
                (log.warning if a.level == "warning" else log.info)("%s: %s", self.name, a.text)

    def _write(self, a: Transmit) -> None:
        delay = a.at - self.time.now()
        if delay > 0:
            self.clock.sleep(delay)
        if self.time.now() > a.latest:
            self.late_writes += 1  # the slot is gone: sending now would hit the next one
            self.node.counts["tx_late"] += 1
            return
        try:
            self.port.write(a.data)
        except (serial.SerialException, OSError):
            self.write_errors += 1
            log.warning("%s: serial write failed", self.name, exc_info=True)
