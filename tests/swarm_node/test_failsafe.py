"""The autopilot's lost-companion failsafe set and read back (core/failsafe.py): each
parameter in turn at every attachment, a refusal alerted once and retried, and per
vehicle type the parameters ArduPilot reads."""

from __future__ import annotations

import msgspec

from swarm_node.core.autopilot.requests import ApError, ApResult, SetParam
from swarm_node.core.autopilot.state import AutopilotState
from swarm_node.core.failsafe import COMPANION_TIMEOUT_S, FailsafeKeeper, failsafe_params
from swarm_node.core.outputs import Publish, Submit
from swarm_proto import Alert, Severity, VehicleType

READY = AutopilotState(link_ok=True, autopilot_ready=True)


def _asked(out: list) -> list[SetParam]:
    return [o.request for o in out if isinstance(o, Submit) and isinstance(o.request, SetParam)]


def _answer(k: FailsafeKeeper, req: SetParam, ok: bool, now: float) -> list:
    error = ApError.NONE if ok else ApError.FAILED
    reason = "" if ok else f"the autopilot kept {req.name} = 0"
    return k.on_result(ApResult(req.request_id, ok, reason, error=error), READY, now)


def test_each_parameter_is_set_in_turn_and_again_after_a_reboot() -> None:
    k = FailsafeKeeper(8, VehicleType.COPTER)
    assert _asked(k.on_autopilot(AutopilotState(), 0.0)) == []  # no link yet
    out, done = k.on_autopilot(READY, 1.0), []
    while reqs := _asked(out):
        (req,) = reqs
        done.append((req.name, req.value))
        out = _answer(k, req, True, 1.0)
    assert done == list(failsafe_params(VehicleType.COPTER)) and k.done
    assert ("FS_GCS_ENABLE", 1.0) in done and ("FS_GCS_TIMEOUT", COMPANION_TIMEOUT_S) in done
    assert _asked(k.on_autopilot(READY, 2.0)) == []  # the same attachment: nothing more
    rebooted = msgspec.structs.replace(READY, reboots=1)
    (req,) = _asked(k.on_autopilot(rebooted, 3.0))
    assert req.name == "SYSID_MYGCS" and not k.done


def test_a_renamed_parameter_is_set_under_the_name_the_autopilot_has() -> None:
    """ArduPilot after 4.6 calls SYSID_MYGCS MAV_GCS_SYSID and ignores a PARAM_SET of the
    old name: the other name is asked at once, no alert, and first after a reboot."""
    k = FailsafeKeeper(8, VehicleType.COPTER)
    (req,) = _asked(k.on_autopilot(READY, 0.0))
    assert req.name == "SYSID_MYGCS"
    out = _answer(k, req, False, 0.0)
    assert not [o for o in out if isinstance(o, Publish)]
    (req,) = _asked(out)
    assert (req.name, req.value) == ("MAV_GCS_SYSID", 255.0)
    out = _answer(k, req, True, 0.0)
    while reqs := _asked(out):
        out = _answer(k, reqs[0], True, 0.0)
    assert k.done
    (req,) = _asked(k.on_autopilot(msgspec.structs.replace(READY, reboots=1), 1.0))
    assert req.name == "MAV_GCS_SYSID"


def test_a_refusal_is_alerted_once_and_retried() -> None:
    k = FailsafeKeeper(8, VehicleType.PLANE)
    (req,) = _asked(k.on_autopilot(READY, 0.0))
    (req,) = _asked(_answer(k, req, False, 0.0))  # under its other name: refused too
    assert req.name == "MAV_GCS_SYSID"
    out = _answer(k, req, False, 0.0)
    alerts = [o.msg for o in out if isinstance(o, Publish) and isinstance(o.msg, Alert)]
    assert [a.severity for a in alerts] == [Severity.CRITICAL]
    assert k.next_deadline() == 5.0 and _asked(k.on_timer(READY, 4.9)) == []
    (again,) = _asked(k.on_timer(READY, 5.0))
    assert again.name == req.name
    out = _answer(k, again, False, 5.0)
    assert not [o for o in out if isinstance(o, Publish)]  # alerted once per run
    (again,) = _asked(out)  # each retry asks both names
    out = _answer(k, again, False, 5.0)
    assert not [o for o in out if isinstance(o, Publish)]
    (again,) = _asked(k.on_timer(READY, 10.0))
    out = _answer(k, again, True, 10.0)
    assert [o.msg.severity for o in out if isinstance(o, Publish)] == [Severity.INFO]


def test_the_parameters_per_vehicle_type() -> None:
    plane = dict(failsafe_params(VehicleType.VTOL))
    assert plane["FS_LONG_ACTN"] == 1.0 and plane["FS_GCS_ENABL"] == 1.0
    assert plane["FS_SHORT_ACTN"] == 0.0 and plane["FS_LONG_TIMEOUT"] == COMPANION_TIMEOUT_S
    assert plane["Q_RTL_MODE"] == 1.0  # at its rally point it lands, not circles for good
    assert "Q_RTL_MODE" not in dict(failsafe_params(VehicleType.PLANE))
    assert dict(failsafe_params(VehicleType.COPTER))["FS_OPTIONS"] == 0.0
    assert failsafe_params(VehicleType.ROVER) == ()
    assert _asked(FailsafeKeeper(4, VehicleType.ROVER).on_autopilot(READY, 0.0)) == []
