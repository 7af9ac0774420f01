"""Reasons in full, for people.

An Ack or an Alert carries a code (AckReason, AlertCode) and at most 64 characters of
text (`swarm_proto.text`): on a 900 MHz radio every byte is air time. The code is the
meaning and is rendered here, in full, at the ground station; the text is what is
particular to that vehicle at that time ("EKF estimate not good yet", "autopilot is
PLANE (MAV_TYPE 1), identity COPTER"), written by the node to fit, and cut visibly
with "…" when it does not. A new code is one entry here;
`tests/gcs_cli/test_exchange.py` checks every code has one.
"""

from __future__ import annotations

from swarm_proto import Ack, AckReason, AckRef, AlertCode

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
}

WHAT: dict[AckRef, str] = {
    AckRef.COMMAND: "command",
    AckRef.MISSION: "mission",
    AckRef.ZONE: "zone",
    AckRef.FLEET: "fleet assignment",
}


def reason_text(reason: AckReason | None, text: str = "") -> str:
    """A reason in full with the vehicle's own text: "the autopilot refused it:
    COMMAND_ACK DENIED". An accepted answer shows only its text."""
    if reason is None:
        return text
    if reason == AckReason.OK:
        return text
    full = ACK_REASONS.get(reason, reason.name)
    return f"{full}: {text}" if text else full


def ack_text(ack: Ack) -> str:
    return reason_text(ack.reason, ack.text)


def alert_text(code: AlertCode, text: str = "") -> str:
    full = ALERT_CODES.get(code, code.name)
    return f"{full}: {text}" if text and text != code.name else full
