"""Reasons in full, for people.

An Ack or an Alert carries a code (AckReason, AlertCode) and at most 64 characters of
text (`swarm_proto.text`): on a 900 MHz radio every byte is air time. The code is the
meaning and is rendered here, in full, at the ground station; the text is what is
particular to that vehicle at that time ("EKF estimate not good yet", "autopilot is
PLANE (MAV_TYPE 1), identity COPTER"), written by the node to fit, and cut visibly
with "…" when it does not. The numbers behind a reason (an endurance budget, a
collision's distance) travel as numbers, a `ReasonDetail`, and are worded here too
("needs about 410 s per vehicle ..., has 148 s"). A new code is one entry here;
`tests/gcs_cli/test_exchange.py` checks every code has one.
"""

from __future__ import annotations

from swarm_proto import Ack, AckReason, AckRef, Alert, AlertCode, DetailCode, ReasonDetail

ACK_REASONS: dict[AckReason, str] = {
    AckReason.OK: "accepted",
    AckReason.HOME_NOT_SET: "the autopilot has no home position yet (it sets one at its "
    "first 3-D GPS fix)",
    AckReason.NOT_READY: "the vehicle is not ready (link, GPS, EKF, home, a critical "
    "alert, or its state machine not started)",
    AckReason.NOT_ADDRESSED: "not for this vehicle",
    AckReason.NO_BASE: "no swarm base set: send `gcs cmd set-base --point LAT,LON --all`",
    AckReason.BUSY: "busy with something that must finish first",
    AckReason.INVALID: "the request is invalid for this vehicle",
    AckReason.UNSUPPORTED: "this vehicle or this version does not do that",
    AckReason.AUTOPILOT_REJECTED: "the autopilot refused it",
    AckReason.TIMEOUT: "the autopilot did not answer in time",
    AckReason.EMERGENCY: "the vehicle is in STATE_EMERGENCY",
    AckReason.NOT_FOUND: "no such thing on this vehicle",
    AckReason.DUPLICATE: "already received",
    AckReason.IN_NO_FLY_ZONE: "it would enter a no-fly zone",
    AckReason.PREEMPTED: "the node refused it: a module of higher priority holds the "
    "autopilot (collision avoidance, an emergency or a landing)",
    AckReason.PLAN_FAILED: "the fleet's plan cannot be flown (every addressed vehicle "
    "refuses the mission for the same reason)",
}

ALERT_CODES: dict[AlertCode, str] = {
    AlertCode.GENERIC: "alert",
    AlertCode.BATTERY_LOW: "battery low",
    AlertCode.BATTERY_CRITICAL: "battery critical: the vehicle returns or lands",
    AlertCode.GPS_LOSS: "GPS lost or degraded",
    AlertCode.EKF_FAILURE: "the autopilot's position estimate (EKF) failed",
    AlertCode.AUTOPILOT_LINK_LOSS: "the node lost its autopilot link",
    AlertCode.GEOFENCE_BREACH: "outside the operating area or inside a no-fly zone",
    AlertCode.ATTITUDE_ABNORMAL: "abnormal attitude (roll or pitch past the limit)",
    AlertCode.COLLISION_RISK: "collision risk",
    AlertCode.SWARM_LINK_LOSS: "the swarm link is lost",
    AlertCode.NO_FLY_ZONE: "no-fly zone or fence problem",
    AlertCode.PLAN_FAILED: "planning failed",
    AlertCode.PLAN_TIMEOUT: "the fleet did not agree on a plan in time",
    AlertCode.MISSION_FAILED: "the mission failed",
    AlertCode.MISSION_COMPLETE: "mission complete",
    AlertCode.AUTOPILOT_TEXT: "autopilot message",
    AlertCode.MALFORMED_INPUT: "the node dropped input it could not take (too large, "
    "undecodable, or its key and payload disagree); counted in `gcs peers`",
    AlertCode.CONDITION_CLEARED: "condition cleared",
    AlertCode.MISSION_CANCELLED: "the operator cancelled the mission",
    AlertCode.AUTOPILOT_MISMATCH: "the autopilot is not the vehicle the swarm database "
    "says (type or MAVLink system id): missions are refused until they match",
    AlertCode.ROSTER_MISMATCH: "a fleet member flies the mission with another roster "
    "(members hash): the fleet re-synchronises before it flies a replan",
    AlertCode.IDENTITY_CONFLICT: "another node or publisher speaks in this vehicle's name: "
    "missions are refused until it has been silent 10 s (stop it, or give it its own id)",
    AlertCode.DATABASE_MISMATCH: "the swarm database disagrees with the autopilot's own "
    "figures: the autopilot's are used",
    AlertCode.CLOCK_SKEW: "the autopilot's GPS time and the node's clock differ (ages are "
    "measured on each receiver's own clock)",
    AlertCode.AUTOPILOT_REFUSED: "the autopilot refused a step of the mission",
}

WHAT: dict[AckRef, str] = {
    AckRef.COMMAND: "command",
    AckRef.MISSION: "mission",
    AckRef.ZONE: "zone",
    AckRef.FLEET: "fleet assignment",
}


#: every DetailCode's words (`detail_text`); a test checks each has them
DETAIL_CODES: dict[DetailCode, str] = {
    DetailCode.NONE: "",
    DetailCode.ENDURANCE: "needs {needed} at cruise (its share and the way home), has {available}",
    DetailCode.COLLISION: "{who} predicted {distance} away in {when}{then}",
}


def _s(seconds: float) -> str:
    return f"{seconds:.0f} s"


def detail_text(detail: ReasonDetail | None) -> str:
    """A ReasonDetail in words: "needs 410 s per vehicle at cruise (its share and the
    way home), has 148 s"; "" for none."""
    if detail is None or detail.code == DetailCode.NONE:
        return ""
    d = detail
    if d.code == DetailCode.ENDURANCE:
        needed = _s(d.needed_s) + (" per vehicle" if not d.vehicle_id else "")
        words = DETAIL_CODES[d.code].format(needed=needed, available=_s(d.available_s))
        return f"vehicle {d.vehicle_id} {words}" if d.vehicle_id else words
    if d.code == DetailCode.COLLISION:
        return DETAIL_CODES[d.code].format(
            who=f"vehicle {d.vehicle_id}" if d.vehicle_id else "traffic",
            distance=f"{d.distance_m:.0f} m",
            when=_s(d.in_s),
            then=f"; going to {d.altitude_m:.0f} m above home" if d.altitude_m else "",
        )
    return d.code.name.lower()  # a code newer than this ground station: its name


def _joined(*parts: str) -> str:
    return ": ".join(p for p in parts if p)


def reason_text(
    reason: AckReason | None, text: str = "", detail: ReasonDetail | None = None
) -> str:
    """A reason in full with its numbers and the vehicle's own text: "the autopilot
    refused it: COMMAND_ACK DENIED". An accepted answer shows only its numbers and
    text."""
    if reason is None or reason == AckReason.OK:
        return _joined(detail_text(detail), text)
    return _joined(ACK_REASONS.get(reason, reason.name), detail_text(detail), text)


def ack_text(ack: Ack) -> str:
    return reason_text(ack.reason, ack.text, ack.detail)


def alert_text(code: AlertCode, text: str = "", detail: ReasonDetail | None = None) -> str:
    full = ALERT_CODES.get(code, code.name)
    return _joined(full, detail_text(detail), text if text != code.name else "")


def alert_words(alert: Alert) -> str:
    """An Alert in full: its code's meaning, its numbers, its text."""
    return alert_text(alert.code, alert.text, alert.detail)
