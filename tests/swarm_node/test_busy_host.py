"""link loss vs a busy host, in fast time (FastFleet: the real link core, the
node core and a simulated ArduPilot exchanging MAVLink bytes):

- the node's process stops for 2-3 s (SIGSTOP, a loaded host) while ArduPilot flies on:
  on resume its timers run first and only then does it read what waited in its socket.
  Nothing is judged a link loss, the stall is reported apart, the vehicle is not landed;
- the autopilot really falls silent for 3 s: a WARNING, no emergency (ArduPilot's own
  FS_GCS_TIMEOUT / FS_LONG_TIMEOUT is 5 s); for 6 s: the emergency.
"""

from __future__ import annotations

import pytest

from swarm_proto import Alert, AlertCode, FsmState, Severity
from tests.swarm_node.test_link_loss import DeadAutopilot, flying_fleet


@pytest.mark.parametrize("stall_s", [2.0, 3.0])
@pytest.mark.parametrize("vid", [7, 1])
def test_a_stalled_node_does_not_take_its_stall_for_link_loss(
    fleet_profiles: dict, vid: int, stall_s: float
) -> None:
    fleet = flying_fleet(fleet_profiles, vid)
    v = fleet.vehicles[vid]
    mode, t0 = v.endpoint.autopilot.mode_name, fleet.now
    fleet.stall(vid, stall_s)
    fleet.run_for(stall_s + 8.0)
    alerts = [a for a in fleet.messages(Alert, sender=vid) if a.time_unix_s >= t0]
    assert not [a for a in alerts if a.code == AlertCode.AUTOPILOT_LINK_LOSS], alerts
    stalls = [a for a in alerts if a.code == AlertCode.GENERIC and "stalled" in a.text]
    assert len(stalls) == 1 and stalls[0].severity == Severity.WARNING, alerts
    assert v.node.stalls.meter.max_s == pytest.approx(stall_s, abs=0.3)
    assert v.link.state.host_stalls >= 1  # the link saw it too (late timer or late burst)
    assert v.node.fsm.state == FsmState.GO_MISSION
    assert v.endpoint.autopilot.mode_name == mode and v.endpoint.autopilot.armed
    assert v.endpoint.autopilot.rel_alt_m > 20.0  # not landed


@pytest.mark.parametrize("vid", [7, 1])
def test_three_seconds_of_autopilot_silence_is_a_warning_not_an_emergency(
    fleet_profiles: dict, vid: int
) -> None:
    """Before a loss lasting 2 s put the vehicle in STATE_EMERGENCY for good."""
    fleet = flying_fleet(fleet_profiles, vid)
    v = fleet.vehicles[vid]
    alive, t0 = v.endpoint, fleet.now
    v.endpoint = DeadAutopilot()  # type: ignore[assignment]
    fleet.run_for(3.0)
    v.endpoint = alive
    fleet.run_for(5.0)
    assert v.node.fsm.state == FsmState.GO_MISSION
    lost = [
        (a.code, a.severity)
        for a in fleet.messages(Alert, sender=vid)
        if a.time_unix_s >= t0
        and a.code in (AlertCode.AUTOPILOT_LINK_LOSS, AlertCode.CONDITION_CLEARED)
    ]
    assert lost == [
        (AlertCode.AUTOPILOT_LINK_LOSS, Severity.WARNING),
        (AlertCode.CONDITION_CLEARED, Severity.INFO),
    ]
    # the autopilot's own clock measured the gap the link saw (not our scheduling)
    assert v.link.state.link_gap_s == pytest.approx(3.0, abs=0.3)


def test_a_link_loss_emergency_ends_when_the_link_is_back(fleet_profiles: dict) -> None:
    """A loss longer than the escalation put the
    vehicle in STATE_EMERGENCY for good, though ArduPilot flew on and the link came
    back. Now the emergency ends with the link: the vehicle leaves its fleet (the
    others took its share) and flies home by itself."""
    fleet = flying_fleet(fleet_profiles, 7)
    v = fleet.vehicles[7]
    alive = v.endpoint
    v.endpoint = DeadAutopilot()  # type: ignore[assignment]
    assert fleet.run_until(lambda: v.node.fsm.state == FsmState.EMERGENCY, 10)
    fleet.run_for(2.0)
    v.endpoint = alive
    assert fleet.run_until(lambda: v.node.fsm.state != FsmState.EMERGENCY, 10)
    assert fleet.run_until(lambda: not v.endpoint.autopilot.armed, 300)  # home and down
    texts = [a.text for a in fleet.messages(Alert, sender=7)]
    assert "autopilot link back: returning to base" in texts
