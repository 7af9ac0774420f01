"""swarm_proto.shutdown: SIGINT and SIGTERM set the stop event, also when the Python
handler is never run (the wakeup pipe's thread sets it), in a process of their own."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import pytest

SCRIPT = """
import signal, sys, time
from swarm_proto.shutdown import stop_event
stop = stop_event()
if sys.argv[1] == "lost":
    # the Python-level handler taken away: only the C handler's wakeup byte is left
    signal.signal(signal.SIGINT, lambda *a: None)
    signal.signal(signal.SIGTERM, lambda *a: None)
print("ready", flush=True)
print("stopped" if stop.wait(20) else "ran on", flush=True)
"""


@pytest.mark.parametrize("how", ["handler", "lost"])
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_a_stop_signal_sets_the_event(how: str, sig: signal.Signals) -> None:
    proc = subprocess.Popen(
        [sys.executable, "-c", SCRIPT, how],
        stdout=subprocess.PIPE,
        text=True,
        env={**os.environ, "PYTHONUNBUFFERED": "1"},
    )
    try:
        assert proc.stdout is not None
        assert proc.stdout.readline().strip() == "ready"
        t0 = time.monotonic()
        proc.send_signal(sig)
        assert proc.stdout.readline().strip() == "stopped"
        assert proc.wait(30) == 0
        assert time.monotonic() - t0 < 20
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()


def test_outside_the_main_thread_it_is_the_handler_alone() -> None:
    """`stop_event` from another thread: no handler can be installed there (ValueError
    from `signal`), as before; the wakeup pipe is not the reason."""
    import threading

    from swarm_proto.shutdown import _watch_wakeup_fd

    event = threading.Event()
    errors: list[BaseException] = []

    def run() -> None:
        try:
            _watch_wakeup_fd(event)
        except BaseException as exc:
            errors.append(exc)

    t = threading.Thread(target=run)
    t.start()
    t.join()
    assert errors == [] and not event.is_set()
