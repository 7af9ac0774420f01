"""One request of the ground station and every answer to it, accounted for.

A command, a mission or a zone is sent, sent again every `repeat_s` (a frame lost on
the radio, a vehicle that starts meanwhile) and answered by Acks. `Exchange` decides,
without I/O and with time passed in, whom the request addresses, when to send it
again, when it is over and what each addressed vehicle answered:

    ex = Exchange(request, known, now, timeout_s=5)
    ex.on_timer(now)      -> [Send()]              (the first copy at once)
    ex.handle(event, now) -> [] | [Finished(outcome)]
    ex.on_timer(now)      -> [Send()] | [Finished(outcome)]
    ex.next_deadline()    -> when to call on_timer again (None when finished)

Whom it addresses comes from membership AND the swarm database, not only from what
the ground station has heard (`set-base` listed 2 of 4 acks; `mission --id
8` said "addresses none" because 8 was not heard yet):

- listed ids (`--id`): exactly those, heard or not;
- a fleet or all (`--fleet`, `--all`): every vehicle alive (liveliness, membership)
  that the selector addresses (a fleet's members known from their status), and every
  vehicle that joins or answers while it waits; a vehicle alive whose fleet is not
  known yet holds the exchange open until it is known or the time is up.
- the database names the vehicles that exist: for `--all`, those not alive are listed
  apart (not a failure: a database lists every airframe, not those flying today); an
  id that is not in it is noted.

The outcome has one row per addressed vehicle: ACCEPTED, REJECTED (with the vehicle's
reason and text) or SILENT (no answer before the timeout, with why it may be silent:
not alive when sent, lost while waiting). Exit code 0 only when every addressed
vehicle accepted and there was at least one.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field, replace
from enum import StrEnum

from swarm_proto import Ack, AckReason, AckRef, Selector, SelectorKind

REPEAT_S = 1.0


class Verdict(StrEnum):
    ACCEPTED = "accepted"
    REJECTED = "rejected"
    SILENT = "no answer"


@dataclass(frozen=True)
class Known:
    """What the ground station knows of one vehicle (from membership, its telemetry
    and the swarm database)."""

    vehicle_id: int
    alive: bool = False  # its liveliness token is up
    fleet_id: int | None = None  # from its status or info; None: not heard yet
    in_database: bool = False


@dataclass(frozen=True)
class Request:
    """What was sent: the Ack that answers it carries (ref, ref_id, issuer_id)."""

    ref: AckRef
    ref_id: int
    issuer_id: int
    selector: Selector = field(default_factory=Selector)
    everyone_answers: bool = False  # missions and zones: NOT_ADDRESSED or a copy held
    what: str = ""  # for people: "rtl", "mission 12 (area)", "zone 3"


# ----------------------------------------------------------------------------- I/O


@dataclass(frozen=True)
class Heard:
    """An Ack arrived."""

    ack: Ack


@dataclass(frozen=True)
class Seen:
    """Membership news: a vehicle came alive, was lost, or its fleet became known."""

    vehicle: Known


Event = Heard | Seen


@dataclass(frozen=True)
class Send:
    """Publish the request (again: a repeat is answered with the first answer)."""

    copy: int  # 1 for the first


@dataclass(frozen=True)
class Row:
    vehicle_id: int
    verdict: Verdict
    ack: Ack | None = None
    notes: tuple[str, ...] = ()  # "not alive when sent", "joined while waiting", ...

    @property
    def reason(self) -> AckReason | None:
        return self.ack.reason if self.ack is not None else None


@dataclass(frozen=True)
class Outcome:
    request: Request
    rows: tuple[Row, ...]  # every addressed vehicle, by id
    not_addressed: tuple[int, ...] = ()  # answered NOT_ADDRESSED (every vehicle answers)
    absent: tuple[int, ...] = ()  # in the database, not alive, not listed (--all)
    undetermined: tuple[int, ...] = ()  # alive, fleet never heard, never answered
    elapsed_s: float = 0.0
    copies: int = 0

    def count(self, verdict: Verdict) -> int:
        return sum(r.verdict == verdict for r in self.rows)

    @property
    def ok(self) -> bool:
        return bool(self.rows) and all(r.verdict == Verdict.ACCEPTED for r in self.rows)

    @property
    def exit_code(self) -> int:
        return 0 if self.ok else 1


@dataclass(frozen=True)
class Finished:
    outcome: Outcome


Output = Send | Finished


# ----------------------------------------------------------------------------- core


class Exchange:
    def __init__(
        self,
        request: Request,
        known: Iterable[Known],
        now: float,
        *,
        timeout_s: float,
        repeat_s: float = REPEAT_S,
        database_known: bool = False,
    ) -> None:
        if not timeout_s >= 0.0 or not repeat_s > 0.0:  # also refuses NaN
            raise ValueError(f"timeout {timeout_s} s and repeat {repeat_s} s must be >= 0, > 0")
        self.request = request
        self.started = now
        self.end = now + timeout_s
        self.repeat_s = repeat_s
        self.database_known = database_known  # the ground station could read a database
        self._known: dict[int, Known] = {k.vehicle_id: k for k in known}
        self._at_start = dict(self._known)
        self.expected: set[int] = set()
        self.answers: dict[int, Ack] = {}
        self.not_addressed: set[int] = set()
        self._lost: set[int] = set()
        self._joined: set[int] = set()
        self._next_send = now
        self.copies = 0
        self.finished: Outcome | None = None
        sel = request.selector
        if sel.kind == SelectorKind.IDS:
            self.expected = set(sel.vehicle_ids)
        else:
            self.expected = {v for v, k in self._known.items() if self._addressed(k) is True}

    # ------------------------------------------------------------------ selection
    def _addressed(self, k: Known) -> bool | None:
        """Whether the request addresses this vehicle: None when it cannot be told yet
        (a fleet selector, the vehicle's fleet not heard)."""
        sel = self.request.selector
        if sel.kind == SelectorKind.IDS:
            return k.vehicle_id in sel.vehicle_ids
        if not k.alive:
            return False
        if sel.kind == SelectorKind.ALL or (sel.kind == SelectorKind.QUANTITY and not sel.fleet_id):
            return True
        if k.fleet_id is None:
            return None
        return sel.addresses(k.vehicle_id, k.fleet_id)

    def undetermined(self) -> set[int]:
        """Alive vehicles the request may address (fleet not heard) that have not
        answered: the exchange waits for them too."""
        return {
            v
            for v, k in self._known.items()
            if self._addressed(k) is None and v not in self.answers and v not in self.not_addressed
        }

    def waiting_for(self) -> list[int]:
        return sorted((self.expected - set(self.answers)) | self.undetermined())

    # ------------------------------------------------------------------ inputs
    def handle(self, event: Event, now: float) -> list[Output]:
        if self.finished is not None:
            return []
        match event:
            case Heard(ack):
                self._on_ack(ack)
            case Seen(k):
                self._on_seen(k)
        return self._check(now)

    def _on_ack(self, ack: Ack) -> None:
        r = self.request
        if (ack.ref, ack.ref_id, ack.issuer_id) != (r.ref, r.ref_id, r.issuer_id):
            return
        vid = ack.vehicle_id
        if vid in self.answers or vid in self.not_addressed:
            return  # a repeat is answered again: the first answer counts
        k = self._known.get(vid, Known(vid))
        addressed = self._addressed(replace(k, alive=True))  # it answers: it is alive
        listed = r.selector.kind == SelectorKind.IDS
        if (not listed or addressed is False) and (
            ack.reason == AckReason.NOT_ADDRESSED
            or (addressed is False and (r.everyone_answers or listed))
        ):  # every vehicle answers a mission, holds a zone; an id not listed is apart
            # (a listed id that says NOT_ADDRESSED keeps its row: a rejection, shown)
            self.not_addressed.add(vid)
            self.expected.discard(vid)
            return
        self.answers[vid] = ack  # it answered: it is addressed (a command is answered
        if vid not in self.expected and vid not in self._at_start:  # only if addressed)
            self._joined.add(vid)
        self.expected.add(vid)

    def _on_seen(self, k: Known) -> None:
        vid = k.vehicle_id
        old = self._known.get(vid)
        self._known[vid] = k
        if not k.alive:
            if vid in self.expected and vid not in self.answers:
                self._lost.add(vid)
            return
        self._lost.discard(vid)
        new = vid not in self.expected and vid not in self.not_addressed
        if new and self._addressed(k) is True:
            self.expected.add(vid)
            if old is None or not old.alive:
                self._joined.add(vid)

    def on_timer(self, now: float) -> list[Output]:
        if self.finished is not None:
            return []
        done = self._check(now)
        if done:
            return done
        if now >= self._next_send:
            self.copies += 1
            # the next copy on the repeat grid (a late wake-up does not send a burst)
            while self._next_send <= now:
                self._next_send += self.repeat_s
            return [Send(self.copies)]
        return []

    def next_deadline(self) -> float | None:
        if self.finished is not None:
            return None
        return min(self._next_send, self.end)

    # ------------------------------------------------------------------ outcome
    def _complete(self) -> bool:
        return (
            bool(self.expected) and self.expected <= set(self.answers) and not self.undetermined()
        )

    def _check(self, now: float) -> list[Output]:
        if self.copies == 0:
            return []  # nothing can be complete before the first copy went out
        if self._complete() or now >= self.end:
            self.finished = self.outcome(now)
            return [Finished(self.finished)]
        return []

    def outcome(self, now: float) -> Outcome:
        rows = []
        for vid in sorted(self.expected):
            notes = self._notes(vid)
            ack = self.answers.get(vid)
            if ack is None:
                rows.append(Row(vid, Verdict.SILENT, None, notes))
            else:
                verdict = Verdict.ACCEPTED if ack.accepted else Verdict.REJECTED
                rows.append(Row(vid, verdict, ack, notes))
        absent: tuple[int, ...] = ()
        if self.request.selector.kind == SelectorKind.ALL:
            absent = tuple(
                sorted(
                    v
                    for v, k in self._known.items()
                    if k.in_database
                    and not k.alive
                    and v not in self.expected
                    and v not in self.not_addressed
                )
            )
        return Outcome(
            self.request,
            tuple(rows),
            tuple(sorted(self.not_addressed)),
            absent,
            tuple(sorted(self.undetermined())),
            round(max(0.0, now - self.started), 3),
            self.copies,
        )

    def _notes(self, vid: int) -> tuple[str, ...]:
        notes = []
        start = self._at_start.get(vid)
        if vid in self._joined:
            notes.append("joined while waiting")
        elif vid not in self.answers and (start is None or not start.alive):
            notes.append("not alive when sent")
        if vid in self._lost:
            notes.append("lost while waiting")
        k = self._known.get(vid)
        if self.database_known and (k is None or not k.in_database):
            notes.append("not in the swarm database")
        return tuple(notes)


def known_from(
    alive: Iterable[int],
    fleets: Mapping[int, int],
    database_ids: Iterable[int] = (),
    heard: Iterable[int] = (),
) -> list[Known]:
    """Every vehicle the ground station knows of: alive (membership), heard (its fleet
    from telemetry) or in the swarm database."""
    alive_set, db = set(alive), set(database_ids)
    ids = alive_set | db | set(fleets) | set(heard)
    return [Known(v, v in alive_set, fleets.get(v), v in db) for v in sorted(ids)]
