"""Reasons in full at the ground station: an answer's or an alert's numbers (a
ReasonDetail) worded in full, a refusal naming who refused (the node or the autopilot),
a cut text ending in "…" at a word."""

from __future__ import annotations

from rich.console import Console

from gcs_cli.answers import outcome_json, outcome_table
from gcs_cli.core.exchange import Outcome, Request, Row, Verdict
from gcs_cli.core.reasons import ACK_REASONS, DETAIL_CODES, ack_text, alert_words
from swarm_proto import (
    Ack,
    AckReason,
    AckRef,
    Alert,
    AlertCode,
    DetailCode,
    ReasonDetail,
    Selector,
    Severity,
)
from swarm_proto.text import short_text

ENDURANCE = ReasonDetail(DetailCode.ENDURANCE, 0, needed_s=410.0, available_s=148.0)


def test_every_detail_code_has_its_words() -> None:
    assert set(DETAIL_CODES) == set(DetailCode)


def test_the_budgets_are_in_the_words() -> None:
    ack = Ack(7, 900, AckRef.MISSION, 4, False, AckReason.INVALID, "planning", ENDURANCE)
    assert "needs 410 s per vehicle at cruise (its share and the way home), has 148 s" in (
        ack_text(ack)
    )
    one = ReasonDetail(DetailCode.ENDURANCE, 8, needed_s=300.0, available_s=150.0)
    alert = Alert(8, 1.0, Severity.WARNING, AlertCode.PLAN_FAILED, "planning: …", one)
    assert alert_words(alert).startswith(
        "planning failed: vehicle 8 needs 300 s at cruise (its share and the way home), has 150 s"
    )


def test_a_collision_alert_says_who_how_close_and_when() -> None:
    """It read "…for 8 in 0 s at 1" for 19 m, cut with no ellipsis."""
    text = "avoid: climb to 45 m (too slow: 3 s to climb) for 8, 9 and ICAO 4CA123 in 0 s at 19 m"
    cut = short_text(text)
    assert len(cut) <= 64 and cut.endswith("…") and not cut.endswith(" …")
    d = ReasonDetail(DetailCode.COLLISION, 8, distance_m=19.0, in_s=0.4, altitude_m=45.0)
    words = alert_words(Alert(7, 1.0, Severity.CRITICAL, AlertCode.COLLISION_RISK, cut, d))
    assert "vehicle 8 predicted 19 m away in 0 s; going to 45 m above home" in words


def test_the_node_refusing_is_not_the_autopilot_refusing() -> None:
    ack = Ack(7, 900, AckRef.COMMAND, 4, False, AckReason.PREEMPTED, "preempted by AVOIDANCE")
    text = ack_text(ack)
    assert text.startswith("the node refused it") and "autopilot refused" not in text
    assert ACK_REASONS[AckReason.AUTOPILOT_REJECTED] == "the autopilot refused it"


def test_the_answer_table_and_json_carry_the_numbers() -> None:
    ack = Ack(7, 900, AckRef.MISSION, 4, False, AckReason.INVALID, "endurance", ENDURANCE)
    out = Outcome(
        Request(AckRef.MISSION, 4, 900, Selector.ids(7), what="mission 4 (area)"),
        (Row(7, Verdict.REJECTED, ack),),
        (),
        (),
        (),
        1.0,
        1,
    )
    console = Console(width=200, record=True)
    console.print(outcome_table(out))
    assert "has 148 s" in console.export_text()
    data = outcome_json(out)["vehicles"][0]
    assert data["detail"]["needed_s"] == 410.0 and "has 148 s" in data["why"]
