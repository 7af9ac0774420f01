"""The ground station's request/answer core without Zenoh: whom a request addresses
(membership and the database), repeats, the timeout, every answer accounted for."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from gcs_cli.core.exchange import (
    Exchange,
    Finished,
    Heard,
    Known,
    Outcome,
    Request,
    Seen,
    Send,
    Verdict,
    known_from,
)
from gcs_cli.core.reasons import ACK_REASONS, ALERT_CODES, ack_text
from swarm_proto import Ack, AckReason, AckRef, AlertCode, Selector

GCS = 900


def req(selector: Selector | None = None, ref: AckRef = AckRef.COMMAND, **kw: object) -> Request:
    return Request(ref, 42, GCS, selector or Selector(), **kw)  # type: ignore[arg-type]


def ack(
    vid: int,
    ok: bool = True,
    reason: AckReason = AckReason.OK,
    text: str = "",
    ref: AckRef = AckRef.COMMAND,
    ref_id: int = 42,
) -> Ack:
    return Ack(vid, GCS, ref, ref_id, ok, reason, text)


def run(ex: Exchange, events: list[tuple[float, object]], until: float = 100.0) -> Outcome:
    """Drive the core as the shell does: timers and events in time order."""
    t = 0.0
    sends = []
    for at, ev in [*events, (until, None)]:
        while (d := ex.next_deadline()) is not None and d <= at:
            t = d
            for o in ex.on_timer(t):
                if isinstance(o, Send):
                    sends.append(t)
                if isinstance(o, Finished):
                    return o.outcome
        if ev is None:
            break
        t = at
        for o in ex.handle(ev, t):  # type: ignore[arg-type]
            if isinstance(o, Finished):
                return o.outcome
    raise AssertionError("never finished")


def test_listed_ids_are_waited_for_even_if_never_heard() -> None:
    """`mission --id 8` said "addresses none" because 8 was not heard yet."""
    ex = Exchange(
        req(Selector.ids(8), AckRef.MISSION, everyone_answers=True),
        [Known(7, alive=True, fleet_id=0)],
        0.0,
        timeout_s=5.0,
    )
    out = run(
        ex,
        [
            (0.1, Heard(ack(7, False, AckReason.NOT_ADDRESSED, ref=AckRef.MISSION))),
            (2.5, Heard(ack(8, ref=AckRef.MISSION))),
        ],
    )
    assert [(r.vehicle_id, r.verdict) for r in out.rows] == [(8, Verdict.ACCEPTED)]
    assert out.not_addressed == (7,) and out.exit_code == 0
    assert out.rows[0].notes == ()  # it answered: "not alive when sent" is not said


def test_a_silent_vehicle_fails_the_request_with_why() -> None:
    ex = Exchange(
        req(Selector.ids(3, 8)), [Known(3, alive=True)], 0.0, timeout_s=5.0, database_known=True
    )
    out = run(ex, [(0.2, Heard(ack(3)))])
    assert [(r.vehicle_id, r.verdict) for r in out.rows] == [
        (3, Verdict.ACCEPTED),
        (8, Verdict.SILENT),
    ]
    assert out.rows[1].notes == ("not alive when sent", "not in the swarm database")
    assert out.exit_code == 1 and out.elapsed_s == 5.0


def test_all_means_every_vehicle_alive_not_only_those_heard() -> None:
    """`set-base` listed 2 of 4 acks. The four are alive (liveliness) though
    only two were heard: it waits for all four."""
    known = known_from(alive=[1, 2, 3, 4], fleets={1: 0, 2: 0}, database_ids=range(1, 10))
    ex = Exchange(req(), known, 0.0, timeout_s=10.0, database_known=True)
    out = run(
        ex, [(0.1, Heard(ack(1))), (0.2, Heard(ack(2))), (1.5, Heard(ack(3))), (2.5, Heard(ack(4)))]
    )
    assert [r.vehicle_id for r in out.rows] == [1, 2, 3, 4] and out.ok
    assert out.elapsed_s == 2.5  # done when the last answered, not at the timeout
    assert out.absent == (5, 6, 7, 8, 9)  # in the database, not alive: said, not failed


def test_a_vehicle_that_starts_while_waiting_is_reached() -> None:
    ex = Exchange(req(), [Known(1, alive=True)], 0.0, timeout_s=10.0)
    out = run(
        ex,
        [
            (0.5, Seen(Known(5, alive=True))),
            (0.6, Heard(ack(1))),
            (2.1, Heard(ack(5, False, AckReason.NOT_READY, "EKF estimate not good yet"))),
        ],
    )
    assert [(r.vehicle_id, r.verdict) for r in out.rows] == [
        (1, Verdict.ACCEPTED),
        (5, Verdict.REJECTED),
    ]
    assert out.rows[1].notes == ("joined while waiting",)
    assert ack_text(out.rows[1].ack) == (  # type: ignore[arg-type]
        f"{ACK_REASONS[AckReason.NOT_READY]}: EKF estimate not good yet"
    )
    assert out.exit_code == 1


def test_a_fleet_waits_until_its_members_are_known() -> None:
    """Vehicle 2 is alive but its fleet is not known yet: the exchange is not complete
    when vehicle 1 (fleet 3) answers; it becomes known as fleet 4 (not addressed)."""
    ex = Exchange(
        req(Selector.fleet(3)), [Known(1, True, 3), Known(2, True, None)], 0.0, timeout_s=10.0
    )
    out = run(ex, [(0.1, Heard(ack(1))), (1.7, Seen(Known(2, True, 4)))])
    assert [r.vehicle_id for r in out.rows] == [1] and out.ok and out.elapsed_s == 1.7


def test_a_vehicle_lost_while_waiting_is_said() -> None:
    ex = Exchange(req(), [Known(1, True), Known(2, True)], 0.0, timeout_s=3.0)
    out = run(ex, [(0.1, Heard(ack(1))), (0.5, Seen(Known(2, alive=False)))])
    assert out.rows[1].verdict == Verdict.SILENT and out.rows[1].notes == ("lost while waiting",)


def test_nobody_alive_waits_the_timeout_and_fails() -> None:
    out = run(Exchange(req(), [], 0.0, timeout_s=2.0), [])
    assert out.rows == () and not out.ok and out.exit_code == 1 and out.elapsed_s == 2.0


def test_repeats_on_the_grid_and_first_answer_counts() -> None:
    ex = Exchange(req(Selector.ids(1)), [], 0.0, timeout_s=10.0, repeat_s=1.0)
    assert ex.on_timer(0.0) == [Send(1)]
    assert ex.on_timer(0.5) == [] and ex.next_deadline() == 1.0
    assert ex.on_timer(3.7) == [Send(2)] and ex.next_deadline() == 4.0  # no burst
    assert ex.handle(Heard(ack(1, False, AckReason.BUSY)), 3.8) != []
    assert ex.finished is not None and ex.finished.rows[0].verdict == Verdict.REJECTED
    assert ex.handle(Heard(ack(1)), 3.9) == []  # over: a later answer changes nothing


def test_answers_to_something_else_are_ignored() -> None:
    ex = Exchange(req(Selector.ids(1)), [], 0.0, timeout_s=2.0)
    ex.on_timer(0.0)
    for other in (
        ack(1, ref_id=41),
        ack(1, ref=AckRef.MISSION),
        Ack(1, 901, AckRef.COMMAND, 42, True),
    ):
        assert ex.handle(Heard(other), 0.1) == []
    assert ex.waiting_for() == [1]


def test_a_zone_to_listed_ids_counts_the_others_apart() -> None:
    """Every vehicle holds a zone: with --id the others' acks are listed apart."""
    ex = Exchange(
        req(Selector.ids(2), AckRef.ZONE, everyone_answers=True),
        [Known(1, True), Known(2, True)],
        0.0,
        timeout_s=5.0,
    )
    out = run(ex, [(0.1, Heard(ack(1, ref=AckRef.ZONE))), (0.2, Heard(ack(2, ref=AckRef.ZONE)))])
    assert [r.vehicle_id for r in out.rows] == [2] and out.not_addressed == (1,) and out.ok


def test_bad_times_are_refused() -> None:
    for timeout in (-1.0, float("nan")):
        with pytest.raises(ValueError):
            Exchange(req(), [], 0.0, timeout_s=timeout)


def test_every_code_has_its_words() -> None:
    assert set(ACK_REASONS) == set(AckReason)
    assert set(ALERT_CODES) == set(AlertCode)


answers = st.lists(
    st.tuples(
        st.floats(0.0, 12.0),
        st.integers(1, 8),
        st.sampled_from(
            [AckReason.OK, AckReason.BUSY, AckReason.NOT_READY, AckReason.NOT_ADDRESSED]
        ),
    ),
    max_size=20,
)


@given(
    alive=st.sets(st.integers(1, 8)),
    listed=st.sets(st.integers(1, 8), max_size=4),
    events=answers,
    everyone=st.booleans(),
)
def test_every_addressed_vehicle_is_accounted_for_once(
    alive: set[int], listed: set[int], events: list, everyone: bool
) -> None:
    """Whatever answers arrive and when: one row per addressed vehicle; exit 0 exactly
    when there is a row and every row accepted; an answer that arrived before the end
    is never reported as silence."""
    sel = Selector.ids(*sorted(listed)) if listed else Selector()
    ex = Exchange(
        req(sel, everyone_answers=everyone), [Known(v, True, 0) for v in alive], 0.0, timeout_s=10.0
    )
    evs = sorted(
        ((t, Heard(ack(v, r == AckReason.OK, r))) for t, v, r in events), key=lambda e: e[0]
    )
    out = run(ex, evs)  # type: ignore[arg-type]
    ids = [r.vehicle_id for r in out.rows]
    assert ids == sorted(set(ids))
    assert out.ok == (bool(out.rows) and all(r.verdict == Verdict.ACCEPTED for r in out.rows))
    assert (out.exit_code == 0) == out.ok
    if listed:
        assert set(ids) == listed  # listed ids: exactly those, answered or not
    else:
        assert alive <= set(ids) | set(out.not_addressed)
    first: dict[int, Ack] = {}
    for t, h in evs:
        if t < out.elapsed_s:  # one at the very end comes after the timeout (the shell's order)
            first.setdefault(h.ack.vehicle_id, h.ack)
    for r in out.rows:
        if r.vehicle_id in first and first[r.vehicle_id].reason != AckReason.NOT_ADDRESSED:
            assert r.ack == first[r.vehicle_id]
