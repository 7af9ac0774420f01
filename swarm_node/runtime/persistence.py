"""Stores the node's declared state in its database off the control loop.

The node core emits `Persist(state, sortie)` whenever what the operator declared (or
the share it flies) changes; `StateWriter` keeps only the newest one and writes it in
its own thread (an SQLite commit on an SD card may take tens of milliseconds: not on
the 5 Hz loop). Each write is reported back (`StoreResult` in the node's inbox): a
failure (a full disk, a read-only file) is alerted by the core once, and the newest
state is written again every `retry_s` until it succeeds (the state is held in memory
and by the peers meanwhile).
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable

from swarm_proto import DeclaredState

from ..core.declared import SortieRecord
from ..core.node import Input, StoreResult
from ..database.state import NodeStateStore

log = logging.getLogger("swarm_node.persistence")

RETRY_S = 5.0


class StateWriter:
    def __init__(
        self,
        store: NodeStateStore,
        report: Callable[[Input], None],
        *,
        retry_s: float = RETRY_S,
        name: str = "state-writer",
    ) -> None:
        self.store = store
        self._report = report
        self.retry_s = retry_s
        self._cond = threading.Condition()
        self._pending: tuple[DeclaredState, SortieRecord | None] | None = None
        self._closed = False
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)
        self.written = 0
        self.failed = 0

    def start(self) -> None:
        self._thread.start()

    def submit(self, state: DeclaredState, sortie: SortieRecord | None) -> None:
        with self._cond:
            self._pending = (state, sortie)
            self._cond.notify()

    def close(self, timeout_s: float = 3.0) -> None:
        """Write what is pending (once), then stop."""
        with self._cond:
            self._closed = True
            self._cond.notify()
        if self._thread.is_alive():
            self._thread.join(timeout_s)

    def _run(self) -> None:
        while True:
            with self._cond:
                while self._pending is None and not self._closed:
                    self._cond.wait()
                job, self._pending = self._pending, None
                closed = self._closed
            if job is not None:
                ok = self._write(*job)
                if not ok and not closed:
                    with self._cond:  # retry the newest state a little later
                        if self._pending is None:
                            self._pending = job
                        self._cond.wait(self.retry_s)
            if closed:
                return

    def _write(self, state: DeclaredState, sortie: SortieRecord | None) -> bool:
        try:
            self.store.save(state, sortie)
        except Exception as exc:
            self.failed += 1
            if self.failed == 1 or self.failed % 20 == 0:
                log.warning("declared state not stored (%d failures): %s", self.failed, exc)
            self._report(StoreResult(False, _short(exc)))
            return False
        self.written += 1
        self._report(StoreResult(True))
        return True


def _short(exc: Exception) -> str:
    text = str(exc)
    for hint in ("disk is full", "disk full", "read-only", "readonly", "locked", "I/O"):
        if hint.lower() in text.lower():
            return hint
    return text[:40]
