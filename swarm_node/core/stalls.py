"""The node's own stalls, measured apart from the autopilot link.

A core declares when it next needs to run (`next_deadline`); a shell that serves it late
(the process stopped, a loaded host, a long garbage collection) shows up as lateness:
the core is called at `now` past the deadline it declared. That time was the node's,
not the autopilot's: vehicle monitoring does not count it toward a link loss's
escalation (`VehicleMonitor.note_stall`), and a stall long enough for an operator to
care (`report_s`) is reported as what it is (a WARNING "node stalled", `delay_s` after
it, the worst since the last report, at most one per `every_s`), never as a link loss.

`StallGuard` is the node's module for it: it reports stalls, and holds peers that left
just after one of the node's own long stalls (its Zenoh session dropped by the lease,
its peers' news late) as suspects until `stale_after_s` has passed: lost then if they
did not come back (a node stopped 3 s otherwise took every member for lost and
replanned their shares alone).

Pure: `observe(now, due)` with both times passed in.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field

from swarm_proto import Alert, AlertCode, Severity
from swarm_proto.text import short_text

from .membership import PeerEvent, PeerJoined, PeerLeft
from .outputs import ModuleOutput, Note, PeerLost, Publish, Stalled

STALL_TOLERANCE_S = 0.25  # lateness below this is scheduling jitter
STALL_REPORT_S = 1.0  # a stall this long is reported to the operator
STALL_REPORT_EVERY_S = 10.0
STALL_REPORT_DELAY_S = 1.0
#: A stall of this node this long may have let its Zenoh session lapse (the 2 s lease)
#: and its peers' news go stale: peers leaving right after it are suspects first.
OWN_STALL_SUSPECT_S = 1.0


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


@dataclass
class StallGuard:
    vehicle_id: int
    stale_after_s: float = 2.0  # the grace after our own stall (a peer's staleness)
    meter: StallMeter = field(default_factory=StallMeter)
    _own_stall_until: float = float("-inf")  # peers leaving before then are suspects
    _suspects: dict[int, str] = field(default_factory=dict)

    def idle(self, now: float, due: float | None) -> bool:
        return self.meter.idle(now, due)

    def check(self, now: float, due: float | None) -> list[ModuleOutput]:
        """The node's own stall (served later than its declared deadline): for vehicle
        monitoring (`Stalled`: not counted as autopilot link loss; routed before the
        step's input), and its report."""
        meter = self.meter
        if meter.idle(now, due):
            return []
        stall = meter.observe(now, due)
        out: list[ModuleOutput] = []
        if stall:
            out.append(Stalled(stall))
            meter.note(now, stall)
            if stall >= OWN_STALL_SUSPECT_S:  # our session and our news of the peers lapsed
                self._own_stall_until = now + self.stale_after_s
        worst = meter.due_report(now)
        if not worst:
            return out
        text = f"node stalled {worst:.1f} s (host busy), not a link loss"
        alert = Alert(
            self.vehicle_id, max(0.0, now), Severity.WARNING, AlertCode.GENERIC, short_text(text)
        )
        return [*out, Note(logging.WARNING, text), Publish(alert)]

    def peer_events(self, events: list[PeerEvent], now: float) -> list[ModuleOutput]:
        """Peers joined and left; one that leaves just after our own long stall is only
        a suspect until the grace has passed."""
        out: list[ModuleOutput] = []
        for ev in events:
            if isinstance(ev, PeerJoined):
                if self._suspects.pop(ev.node_id, None) is None:
                    out.append(Note(logging.INFO, f"peer {ev.node_id} joined ({ev.how})"))
            elif isinstance(ev, PeerLeft):
                if now < self._own_stall_until:
                    self._suspects[ev.node_id] = ev.why
                    continue
                out += self._lost(ev.node_id, ev.why)
        return out

    def on_timer(self, now: float) -> list[ModuleOutput]:
        """Suspects that did not come back within the grace after our own stall."""
        if not self._suspects or now < self._own_stall_until:
            return []
        gone, self._suspects = self._suspects, {}
        out: list[ModuleOutput] = []
        for vid, why in gone.items():
            out += self._lost(vid, why)
        return out

    def next_deadline(self) -> float | None:
        report = self.meter.next_deadline()
        if not self._suspects:
            return report
        return self._own_stall_until if report is None else min(report, self._own_stall_until)

    def _lost(self, vid: int, why: str) -> list[ModuleOutput]:
        return [Note(logging.WARNING, f"peer {vid} lost ({why})"), PeerLost(vid, why)]
