"""Clean process shutdown for the shells: SIGINT/SIGTERM set an event the main loop
waits on, so every process can undeclare its Zenoh entities and close before exiting."""

from __future__ import annotations

import signal
import threading
from types import FrameType


def stop_event() -> threading.Event:
    """An event set by SIGINT or SIGTERM (call from the main thread)."""
    event = threading.Event()

    def handler(signum: int, frame: FrameType | None) -> None:
        event.set()

    signal.signal(signal.SIGINT, handler)
    signal.signal(signal.SIGTERM, handler)
    return event
