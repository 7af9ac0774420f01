"""Autopilot link loss drives STATE_EMERGENCY within 1 s (issue 4), link detection
included: the real autopilot link (LinkCore, link_timeout_s 0.6) and the node core in
simulated time (FastFleet) with a simulated ArduPilot that dies mid-flight."""

from __future__ import annotations

import pytest

from swarm_proto import Alert, AlertCode, CommandKind, FsmState, GeoPoint
from swarm_sim.core import SITL_HOME
from swarm_sim.fast_fleet import FastFleet
from tests.swarm_node.test_node_fences_sim import Operator


class DeadAutopilot:
    """A simulated autopilot whose process died: it never sends or answers again."""

    def receive(self, data: bytes, now: float) -> bytes:
        return b""

    def on_timer(self, now: float) -> bytes:
        return b""

    def next_deadline(self) -> float | None:
        return None




@pytest.mark.parametrize("vid", [7, 1])  # a seed quadcopter, a seed Albatross VTOL
def test_link_loss_reaches_emergency_within_one_second(fleet_profiles: dict, vid: int) -> None:
    fleet = FastFleet.build([vid], fleet_profiles)
    v = fleet.vehicles[vid]
    assert fleet.run_until(lambda: v.link.state.ekf_has_position and v.link.state.home, 60)
    op = Operator(fleet)
    base = GeoPoint(SITL_HOME.lat_deg, SITL_HOME.lon_deg, SITL_HOME.alt_m)
    assert op(CommandKind.SET_BASE, point=base).accepted
    assert op(CommandKind.SET_MODE, text="GUIDED").accepted
    assert op(CommandKind.ARM).accepted
    assert op(CommandKind.TAKEOFF, value=30.0).accepted
    assert fleet.run_until(lambda: v.node.fsm.state == FsmState.GO_MISSION, 30)
    fleet.run_for(5.0)
    assert v.link.state.armed and v.node.fsm.state == FsmState.GO_MISSION
    died = fleet.now
    v.endpoint = DeadAutopilot()  # type: ignore[assignment]
    assert fleet.run_until(lambda: v.node.fsm.state == FsmState.EMERGENCY, 10)
    took = fleet.now - died
    lost = [a for a in fleet.messages(Alert, sender=vid) if a.code == AlertCode.AUTOPILOT_LINK_LOSS]
    print(f"link loss -> STATE_EMERGENCY after {took:.2f} s simulated")
    assert 0.0 < took <= 1.0  # the link's 0.6 s, then the node's 5 Hz poll and tick
    assert lost and lost[0].time_unix_s - died < 0.9
