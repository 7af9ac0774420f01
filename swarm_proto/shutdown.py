"""Clean process shutdown for the shells: SIGINT/SIGTERM set an event the main loop
waits on, so every process can undeclare its Zenoh entities and close before exiting.

The event is set two ways. The Python handler sets it when the main thread runs it;
and the signal's number, which the interpreter's C handler writes to a wakeup pipe the
moment the signal arrives (`signal.set_wakeup_fd`), sets it from a thread of its own.
The second way does not depend on the main thread dispatching the Python handler: a
node stopped with SIGINT under load once ran on with its main loop turning and the
handler never run (its threads' stacks dumped 10 s later), so a supervisor's stop
(a test's, systemd's) would have had to kill it."""

from __future__ import annotations

import os
import signal
import threading
from types import FrameType

STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)


def stop_event() -> threading.Event:
    """An event set by SIGINT or SIGTERM (call from the main thread)."""
    event = threading.Event()

    def handler(signum: int, frame: FrameType | None) -> None:
        event.set()

    for sig in STOP_SIGNALS:
        signal.signal(sig, handler)
    _watch_wakeup_fd(event)
    return event


def _watch_wakeup_fd(event: threading.Event) -> None:
    """Set `event` from a thread reading the signals' wakeup pipe. Left alone where the
    process already has a wakeup fd (an asyncio event loop's: its own)."""
    r, w = os.pipe()
    os.set_blocking(w, False)  # the C handler must never block on a full pipe
    try:
        before = signal.set_wakeup_fd(w, warn_on_full_buffer=False)
    except ValueError:  # not the main thread: the Python handler only
        os.close(r)
        os.close(w)
        return
    if before != -1:
        signal.set_wakeup_fd(before)
        os.close(r)
        os.close(w)
        return
    stops = {int(s) for s in STOP_SIGNALS}

    def watch() -> None:
        while True:
            try:
                data = os.read(r, 64)
            except OSError:
                return
            if not data:
                return
            if stops.intersection(data):
                event.set()

    threading.Thread(target=watch, name="stop-signals", daemon=True).start()
