"""The node's own stalls, measured apart from the autopilot link.

A core declares when it next needs to run (`next_deadline`); a shell that serves it late
(the process stopped, a loaded host, a long garbage collection) shows up as lateness:
the core is called at `now` past the deadline it declared. That time was the node's,
not the autopilot's: vehicle monitoring does not count it toward a link loss's
escalation (`VehicleMonitor.note_stall`), and a stall long enough for an operator to
care (`report_s`) is reported as what it is (a WARNING "node stalled", `delay_s` after
it, the worst since the last report, at most one per `every_s`), never as a link loss.

Pure: `observe(now, due)` with both times passed in.
"""

from __future__ import annotations

from dataclasses import dataclass

STALL_TOLERANCE_S = 0.25  # lateness below this is scheduling jitter
STALL_REPORT_S = 1.0  # a stall this long is reported to the operator
STALL_REPORT_EVERY_S = 10.0
STALL_REPORT_DELAY_S = 1.0


@dataclass
class StallMeter:
    tolerance_s: float = STALL_TOLERANCE_S
    report_s: float = STALL_REPORT_S
    every_s: float = STALL_REPORT_EVERY_S
    delay_s: float = STALL_REPORT_DELAY_S
    count: int = 0  # stalls longer than the tolerance
    total_s: float = 0.0
    max_s: float = 0.0
    last_s: float = 0.0
    _reported_at: float | None = None
    _report_at: float | None = None
    _pending_s: float = 0.0

    def observe(self, now: float, due: float | None) -> float:
        """The stall (seconds) if the core is served at `now` later than `due` by more
        than the tolerance; 0.0 otherwise."""
        if due is None:
            return 0.0
        late = now - due
        if not late > self.tolerance_s:  # NaN-safe
            return 0.0
        self.count += 1
        self.total_s += late
        self.max_s = max(self.max_s, late)
        self.last_s = late
        return late

    def note(self, now: float, stall_s: float) -> None:
        """A stall to report, `delay_s` from now: a node stopped longer than the Zenoh
        lease has lost its session, and what it publishes the moment it resumes is lost
        while the session comes back (measured: reconnected within milliseconds)."""
        if stall_s < self.report_s:
            return
        self._pending_s = max(self._pending_s, stall_s)
        if self._report_at is None:
            self._report_at = now + self.delay_s
        if self._reported_at is not None:
            self._report_at = max(self._report_at, self._reported_at + self.every_s)

    def due_report(self, now: float) -> float:
        """The worst stall not reported yet, if its report is due now (else 0.0)."""
        if self._report_at is None or now < self._report_at:
            return 0.0
        stall, self._pending_s, self._report_at = self._pending_s, 0.0, None
        self._reported_at = now
        return stall

    def next_deadline(self) -> float | None:
        return self._report_at

    def idle(self, now: float, due: float | None) -> bool:
        """Nothing to observe nor report at `now` (the check on every input)."""
        return self._report_at is None and (due is None or not now - due > self.tolerance_s)
