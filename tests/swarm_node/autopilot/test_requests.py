"""Requests -> MAVLink per vehicle type, and the COMMAND_ACK state machine: retries,
TEMPORARILY_REJECTED, IN_PROGRESS, refusals with ArduPilot's explanation, NO_POSITION,
timeouts, urgent requests, link down. Pure: LinkCore against the scripted autopilot,
time jumping to deadlines."""

from __future__ import annotations

import math
from typing import Any

import pytest

from swarm_node.core.autopilot import requests as rq
from swarm_node.core.autopilot.items import ItemKind, Waypoint
from swarm_node.core.autopilot.link import LinkCore, LinkSettings
from swarm_node.core.autopilot.mission_item import MavCmd
from swarm_node.core.autopilot.plans import InvalidRequest, check_request
from swarm_node.core.autopilot.requests import ApError
from swarm_proto import VehicleType

from .fake_autopilot import FakeAutopilot, Harness

MAV_CMD_REQUEST_MESSAGE = 512

KIND = {
    VehicleType.COPTER: "copter",
    VehicleType.PLANE: "plane",
    VehicleType.VTOL: "vtol",
    VehicleType.ROVER: "rover",
    VehicleType.BOAT: "boat",
}


def harness(vt: VehicleType, **fake_kw: Any) -> Harness:
    core = LinkCore(LinkSettings(vehicle_type=vt), 1000.0)
    h = Harness(core, FakeAutopilot(KIND[vt], **fake_kw))
    assert h.run_until(lambda: core.state.link_ok and core.state.has_position, 10)
    return h


def commands_sent(h: Harness, since: int) -> list[tuple[str, int, tuple[float, ...]]]:
    out = []
    for m in h.sent[since:]:
        if m.get_type() == "COMMAND_LONG" and m.command not in (
            MavCmd.SET_MESSAGE_INTERVAL,
            MAV_CMD_REQUEST_MESSAGE,  # a HEARTBEAT to confirm a mode change
        ):
            out.append(
                (
                    "long",
                    m.command,
                    (m.param1, m.param2, m.param3, m.param4, m.param5, m.param6, m.param7),
                )
            )
        elif m.get_type() == "COMMAND_INT":
            out.append(("int", m.command, (m.param1, m.param2, m.param3, m.param4, m.x, m.y, m.z)))
        elif m.get_type() == "PARAM_SET":
            out.append(("param", 0, (m.param_value,)))
    return out


def run(h: Harness, request: rq.ApRequest, max_s: float = 60) -> tuple[rq.ApResult, list]:
    since = len(h.sent)
    token = len(h.results()) + 100
    result = h.run_request(token, request, max_s=max_s)
    assert result is not None
    return result, commands_sent(h, since)


@pytest.mark.parametrize(
    ("vt", "req", "expected"),
    [
        (VehicleType.COPTER, rq.SetMode(mode="guided"), [("long", 176, (1, 4))]),
        (VehicleType.VTOL, rq.SetMode(mode="QLOITER"), [("long", 176, (1, 19))]),
        (VehicleType.PLANE, rq.SetMode(mode="FBWA"), [("long", 176, (1, 5))]),
        (VehicleType.BOAT, rq.SetMode(mode="HOLD"), [("long", 176, (1, 4))]),
        (VehicleType.COPTER, rq.Arm(), [("long", 400, (1, 0))]),
        (VehicleType.COPTER, rq.Arm(force=True), [("long", 400, (1, 21196))]),
        (VehicleType.ROVER, rq.Disarm(), [("long", 400, (0, 0))]),
        (VehicleType.COPTER, rq.ReturnToLaunch(), [("long", 176, (1, 6))]),
        (VehicleType.VTOL, rq.ReturnToLaunch(), [("long", 176, (1, 11))]),
        (VehicleType.ROVER, rq.ReturnToLaunch(), [("long", 176, (1, 11))]),
        (VehicleType.COPTER, rq.Land(), [("long", 176, (1, 9))]),
        (VehicleType.VTOL, rq.Land(), [("long", 176, (1, 20))]),
        (VehicleType.PLANE, rq.Land(), [("long", 189, ())]),
        (VehicleType.BOAT, rq.Land(), [("long", 176, (1, 4))]),
        (VehicleType.COPTER, rq.Parachute(), [("long", 208, (2,))]),
        (VehicleType.COPTER, rq.ChangeSpeed(speed_m_s=7.5), [("long", 178, (1, 7.5, -1))]),
        (VehicleType.VTOL, rq.ChangeSpeed(speed_m_s=22), [("long", 178, (0, 22, -1))]),
        (
            VehicleType.PLANE,
            rq.ChangeSpeed(speed_m_s=15, airspeed=False),
            [("long", 178, (1, 15, -1))],
        ),
        (VehicleType.PLANE, rq.ChangeAltitude(alt_rel_m=120), [("int", 186, (120, 3))]),
        (
            VehicleType.COPTER,
            rq.Goto(lat_deg=37.5, lon_deg=-5.9, alt_rel_m=40),
            [("int", 192, (-1, 1, 0, math.nan, 375000000, -59000000, 40))],
        ),
        (
            VehicleType.COPTER,
            rq.StartMission(),  # DO_SET_MISSION_CURRENT 1 first, as ArduPilot needs
            [("long", 224, (1,)), ("long", 176, (1, 3)), ("long", 300, (0,))],
        ),
        (
            VehicleType.PLANE,
            rq.StartMission(first_item=3),
            [("long", 224, (3,)), ("long", 176, (1, 10)), ("long", 300, (0,))],
        ),
        (VehicleType.COPTER, rq.Calibrate(what="baro"), [("long", 241, (0, 0, 1))]),
        (VehicleType.PLANE, rq.Calibrate(what="airspeed"), [("long", 241, (0, 0, 0, 0, 0, 2))]),
        (VehicleType.COPTER, rq.Calibrate(what="compass"), [("long", 42424, (0, 0, 1))]),
        (VehicleType.COPTER, rq.SetParam(name="WPNAV_SPEED", value=750), [("param", 0, (750,))]),
    ],
    ids=lambda x: type(x).__name__ if isinstance(x, rq.ApRequest) else None,
)
def test_what_each_request_sends(vt: VehicleType, req: rq.ApRequest, expected: list) -> None:
    h = harness(vt)
    result, sent = run(h, req)
    assert result.ok, result
    assert [(k, c) for k, c, _ in sent] == [(k, c) for k, c, _ in expected]
    for (_, _, got), (_, _, want) in zip(sent, expected, strict=True):
        for g, w in zip(got, want, strict=False):
            assert (math.isnan(g) and math.isnan(w)) or g == pytest.approx(w)


@pytest.mark.parametrize("vt", [VehicleType.COPTER, VehicleType.VTOL])
def test_takeoff_guided_then_nav_takeoff(vt: VehicleType) -> None:
    h = harness(vt)
    assert run(h, rq.Arm())[0].ok
    result, sent = run(h, rq.Takeoff(alt_rel_m=35))
    assert result.ok
    assert (sent[0][1], sent[0][2][1]) == (176, 4 if vt == VehicleType.COPTER else 15)
    assert sent[1][1] == 22 and sent[1][2][6] == 35
    # already GUIDED: the mode step is skipped
    h.step()
    h.run_until(lambda: h.core.state.mode_name == "GUIDED", 5)
    assert [c for _, c, _ in run(h, rq.Takeoff(alt_rel_m=35))[1]] == [22]


def test_plane_takeoff_sets_tkoff_alt_then_takeoff_mode() -> None:
    h = harness(VehicleType.PLANE)
    run(h, rq.Arm())
    result, sent = run(h, rq.Takeoff(alt_rel_m=80))
    assert result.ok and sent == [("param", 0, (80.0,)), ("long", 176, (1, 13, 0, 0, 0, 0, 0))]
    assert h.fake.params["TKOFF_ALT"] == 80


def test_plane_takeoff_carries_on_when_the_param_is_not_confirmed() -> None:
    h = harness(VehicleType.PLANE)
    h.fake._on_param_set = lambda msg, now: []  # type: ignore[method-assign]
    run(h, rq.Arm())
    result, sent = run(h, rq.Takeoff(alt_rel_m=80))
    assert result.ok and "autopilot's own value" in result.reason
    assert sent[-1][1] == 176


def test_ground_vehicles_need_no_takeoff_or_altitude_and_have_no_parachute() -> None:
    h = harness(VehicleType.ROVER)
    for req in (rq.Takeoff(alt_rel_m=10), rq.ChangeAltitude(alt_rel_m=10)):
        result, sent = run(h, req)
        assert result.ok and sent == [] and "nothing to do" in result.reason
    result, sent = run(h, rq.Parachute())
    assert not result.ok and result.error == ApError.NOT_APPLICABLE and sent == []


def test_copter_change_altitude_repositions_to_the_last_target() -> None:
    h = harness(VehicleType.COPTER)
    result, _ = run(h, rq.ChangeAltitude(alt_rel_m=50))
    assert not result.ok and "GUIDED only" in result.reason
    run(h, rq.Goto(lat_deg=37.42, lon_deg=-5.97, alt_rel_m=30))
    h.run_until(lambda: h.core.state.mode_name == "GUIDED", 5)
    result, sent = run(h, rq.ChangeAltitude(alt_rel_m=50))
    assert result.ok and sent[0][1] == 192
    assert sent[0][2][4:] == (374200000, -59700000, 50)
    assert sent[0][2][1] == 0  # no mode change flag: only in GUIDED


def test_takeoff_refused_while_disarmed_says_so() -> None:
    h = harness(VehicleType.COPTER)
    h.fake.ack_script[22] = [4]
    result, _ = run(h, rq.Takeoff(alt_rel_m=20))
    assert not result.ok and result.error == ApError.FAILED and "not armed" in result.reason


def test_mode_refused_without_ekf_position_is_no_position() -> None:
    h = harness(VehicleType.COPTER, ekf_ok=False)
    h.fake.ack_script[176] = [4]
    h.fake.statustexts.append((4, "Mode change to GUIDED failed: requires position"))
    result, _ = run(h, rq.SetMode(mode="GUIDED"))
    assert not result.ok and result.error == ApError.NO_POSITION and result.mav_result == 4
    assert "EKF has no position yet" in result.reason and "requires position" in result.reason


def test_arming_refusal_quotes_the_prearm_text() -> None:
    h = harness(VehicleType.COPTER)
    h.fake.ack_script[400] = [4]
    h.fake.statustexts.append((3, "Arm: LAND mode not armable"))
    result, _ = run(h, rq.Arm())
    assert result.error == ApError.FAILED and "Arm: LAND mode not armable" in result.reason


def test_a_quadplane_leaves_a_landing_sequence_before_it_arms() -> None:
    """After a landing its mission flew ArduPlane refuses to arm ("Arm: In landing
    sequence") until the mission's current item is set again: DO_SET_MISSION_CURRENT 1
    first, and a refusal of it (no mission) does not stop the arm."""
    h = harness(VehicleType.VTOL)
    h.fake.ack_script[224] = [4]  # no mission: FAILED (ArduPilot cleared the flag anyway)
    result, sent = run(h, rq.Arm())
    assert result.ok and [c for _, c, _ in sent] == [224, 400]
    assert "out of the landing sequence" in result.reason and "carried on" in result.reason
    run(h, rq.Disarm(force=True))
    again, sent = run(h, rq.Arm(force=True))
    assert again.ok and [c for _, c, _ in sent] == [400]  # forced: no checks to pass


def test_a_refusal_waits_for_the_text_ardupilot_sends_after_its_ack() -> None:
    """ArduPilot sends COMMAND_ACK at once and its STATUSTEXT from a queue after it: the
    refusal carries the text, under its true name (an arm refusal, FAILED)."""
    h = harness(VehicleType.VTOL)
    h.fake.ack_script[400] = [4]
    h.fake.texts_after_ack.append((2, "PreArm: QLAND mode not armable"))
    result, _ = run(h, rq.Arm())
    assert not result.ok and result.error == ApError.FAILED and result.mav_result == 4
    assert result.reason == "Arm: COMMAND_ACK FAILED (PreArm: QLAND mode not armable)"


def test_a_refusal_without_a_text_is_reported_after_the_wait() -> None:
    h = harness(VehicleType.COPTER)
    h.fake.ack_script[400] = [4]
    start = h.now
    result, _ = run(h, rq.Arm())
    assert result.error == ApError.FAILED and result.reason == "Arm: COMMAND_ACK FAILED"
    assert h.now - start == pytest.approx(0.5, abs=0.15)  # RunnerSettings.explain_wait_s


def test_a_mode_change_is_done_when_a_heartbeat_shows_it() -> None:
    """SetMode then Arm: the Arm is not sent before a HEARTBEAT shows the mode (the node
    sent them 1 ms apart, and ArduPlane refused the Arm in the old mode)."""
    h = harness(VehicleType.VTOL)
    h.fake.answer_heartbeat = False  # only the 1 Hz HEARTBEAT
    order: list[tuple[str, int]] = []
    h.fake.on_command = lambda m: order.append(("cmd", int(m.command)))
    result, _ = run(h, rq.SetMode(mode="QLOITER"))
    assert result.ok and h.core.state.mode_name == "QLOITER"
    run(h, rq.Arm())
    # 224: ArduPlane's DO_SET_MISSION_CURRENT before an arm, out of a landing sequence
    assert [c for _, c in order if c != 511] == [176, 512, 224, 400]


def test_a_mode_change_the_heartbeat_never_shows_fails_and_says_so() -> None:
    h = harness(VehicleType.VTOL)
    assert h.core.state.mode_number == 0
    h.fake.modes_not_taken.add(15)  # GUIDED accepted, but the autopilot stays where it was
    start = h.now
    result, _ = run(h, rq.SetMode(mode="GUIDED"))
    assert not result.ok and result.error == ApError.MODE_NOT_CONFIRMED
    assert "HEARTBEAT still shows MANUAL" in result.reason and "not GUIDED" in result.reason
    assert h.now - start == pytest.approx(3.0, abs=0.2)  # RunnerSettings.mode_confirm_s


def test_a_mode_the_autopilot_moves_on_from_at_once_is_confirmed() -> None:
    """A QuadPlane's RTL becomes QRTL at once: a HEARTBEAT out of the old mode confirms."""
    h = harness(VehicleType.VTOL)
    h.fake.modes_not_taken.add(11)  # RTL ...
    h.fake.on_command = lambda m: setattr(h.fake, "custom_mode", 21) if m.command == 176 else None
    result, _ = run(h, rq.ReturnToLaunch())  # ... shown as QRTL
    assert result.ok


def test_read_param_answers_the_value_and_does_not_wait_behind_commands() -> None:
    h = harness(VehicleType.COPTER)
    assert h.run_until(lambda: h.core.pending_requests() == 0, 30)  # the link's own reads
    h.fake.params["WPNAV_SPEED"] = 1000.0
    h.fake.silent_commands.add(178)
    h.submit(1, rq.ChangeSpeed(speed_m_s=5))
    result = h.run_request(2, rq.ReadParam(name="WPNAV_SPEED"), max_s=10)
    assert result is not None and result.ok and result.value == 1000.0
    assert 1 not in h.results()  # the command still waits for its COMMAND_ACK
    missing = h.run_request(3, rq.ReadParam(name="NO_SUCH_PARAM"), max_s=10)
    assert missing is not None and missing.error == ApError.TIMEOUT and missing.value is None


@pytest.mark.parametrize(
    ("vt", "params", "capacity", "bank"),
    [
        (
            VehicleType.COPTER,
            {"BATT_MONITOR": 4, "BATT_CAPACITY": 20000, "ANGLE_MAX": 3000},
            20000,
            30,
        ),
        (
            VehicleType.VTOL,
            {"BATT_MONITOR": 0, "BATT_CAPACITY": 3300, "ROLL_LIMIT_DEG": 65},
            None,
            65,
        ),
        (
            VehicleType.PLANE,
            {"BATT_MONITOR": 4, "BATT_CAPACITY": 5000, "LIM_ROLL_CD": 4500},
            5000,
            45,
        ),
        (VehicleType.ROVER, {"BATT_CAPACITY": 10000}, 10000, None),
    ],
)
def test_the_autopilots_own_figures_are_read_when_it_is_found(
    vt: VehicleType, params: dict[str, float], capacity: float | None, bank: float | None
) -> None:
    """BATT_CAPACITY (None without a battery monitor: BATT_MONITOR 0) and the attitude
    limit (ArduCopter ANGLE_MAX cdeg, ArduPlane ROLL_LIMIT_DEG, or LIM_ROLL_CD before it)."""
    core = LinkCore(LinkSettings(vehicle_type=vt), 1000.0)
    fake = FakeAutopilot(KIND[vt])
    fake.params.update({k: float(v) for k, v in params.items()})
    h = Harness(core, fake)
    assert h.run_until(
        lambda: (
            core.state.battery_capacity_mah == capacity
            and core.state.max_bank_deg == bank
            and core.pending_requests() == 0
        ),
        30,
    )
    assert h.results() == {}  # the link's own reads are not results of anyone's request


@pytest.mark.parametrize(
    ("code", "error"),
    [(2, ApError.DENIED), (3, ApError.UNSUPPORTED), (6, ApError.CANCELLED), (77, ApError.FAILED)],
)
def test_final_refusals(code: int, error: ApError) -> None:
    h = harness(VehicleType.COPTER)
    h.fake.ack_script[178] = [code]
    result, sent = run(h, rq.ChangeSpeed(speed_m_s=3))
    assert not result.ok and result.error == error and result.mav_result == code and len(sent) == 1


def test_temporarily_rejected_is_retried_then_given_up() -> None:
    h = harness(VehicleType.COPTER)
    h.fake.ack_script[400] = [1, 0]
    result, sent = run(h, rq.Arm())
    assert result.ok and len(sent) == 2 and result.attempts == 2
    h.fake.ack_script[400] = [1, 1, 1]
    result, sent = run(h, rq.Disarm())
    assert result.error == ApError.TEMPORARILY_REJECTED and len(sent) == 3


def test_in_progress_extends_the_wait() -> None:
    h = harness(VehicleType.COPTER)
    h.fake.ack_script[241] = [5]  # IN_PROGRESS, then nothing more
    start = h.now
    result, sent = run(h, rq.Calibrate(what="gyro"), max_s=600)
    assert result.error == ApError.IN_PROGRESS and len(sent) == 1
    assert h.now - start == pytest.approx(120.0, abs=0.5)  # not resent while in progress


def test_silence_resends_with_confirmation_then_times_out() -> None:
    h = harness(VehicleType.COPTER)
    h.fake.silent_commands.add(176)
    start = h.now
    result, _ = run(h, rq.SetMode(mode="LOITER"))
    longs = [m for m in h.sent if m.get_type() == "COMMAND_LONG" and m.command == 176]
    assert [m.confirmation for m in longs] == [0, 1, 2]
    assert result.error == ApError.TIMEOUT and "after 3 tries" in result.reason
    assert h.now - start == pytest.approx(4.5, abs=0.2)


def test_urgent_requests_supersede_a_pending_command() -> None:
    h = harness(VehicleType.COPTER)
    h.fake.silent_commands.add(178)
    h.submit(1, rq.ChangeSpeed(speed_m_s=5))
    h.submit(2, rq.SetMode(mode="LOITER"))
    h.submit(3, rq.ReturnToLaunch())
    h.run_until(lambda: len(h.results()) == 3, 30)
    res = h.results()
    assert res[1].error == ApError.CANCELLED and "superseded by ReturnToLaunch" in res[1].reason
    assert res[3].ok and res[2].ok
    modes = [m.param2 for m in h.sent if m.get_type() == "COMMAND_LONG" and m.command == 176]
    assert modes == [6, 5]  # RTL went first


def test_transfers_do_not_wait_behind_commands() -> None:
    h = harness(VehicleType.COPTER)
    h.fake.silent_commands.add(176)
    h.submit(1, rq.SetMode(mode="AUTO"))
    h.submit(2, rq.UploadRally(points=((37.41, -5.98, 50.0),)))
    h.run_until(lambda: 2 in h.results(), 30)
    assert h.results()[2].ok and 1 not in h.results()


def test_requests_fail_fast_while_the_link_is_down() -> None:
    h = harness(VehicleType.COPTER)
    h.down = True
    h.run_until(lambda: not h.core.state.link_ok, 5)
    result, sent = run(h, rq.Arm())
    assert result.error == ApError.LINK_DOWN and sent == []
    # and a request in flight when the link drops says so
    h.down = False
    h.run_until(lambda: h.core.state.link_ok, 5)
    h.fake.silent_commands.add(176)
    h.submit(7, rq.SetMode(mode="LOITER"))
    h.down = True
    h.run_until(lambda: 7 in h.results(), 30)
    assert h.results()[7].error == ApError.LINK_DOWN


def test_unknown_vehicle_type_waits_for_the_heartbeat_or_fails_clearly() -> None:
    core = LinkCore(LinkSettings(), 1000.0)
    h = Harness(core, FakeAutopilot("plane"))
    h.run_until(lambda: core.state.link_ok, 5)
    assert core.state.vehicle_type == VehicleType.PLANE  # from MAV_TYPE_FIXED_WING
    assert run(h, rq.SetMode(mode="QHOVER"))[0].ok  # plane modes include the Q modes
    other = FakeAutopilot("copter")
    other.mav_type = 26  # a gimbal-like type: no ArduPilot vehicle
    h2 = Harness(LinkCore(LinkSettings(), 1000.0), other)
    h2.run_until(lambda: h2.core.state.link_ok, 5)
    result, _ = run(h2, rq.Arm())
    assert result.error == ApError.UNKNOWN_VEHICLE


def test_upload_mission_reports_the_items_and_counts_them() -> None:
    h = harness(VehicleType.VTOL)
    wps = (
        Waypoint(ItemKind.TAKEOFF, alt_rel_m=40),
        Waypoint(lat_deg=37.42, lon_deg=-5.98, alt_rel_m=60, speed_m_s=22),
        Waypoint(ItemKind.LAND, lat_deg=37.41, lon_deg=-5.99),
    )
    result, _ = run(h, rq.UploadMission(items=wps))
    assert result.ok
    assert [i.command for i in result.items] == [16, 84, 178, 16, 85]
    assert h.core.state.mission_count == 5
    assert len(h.fake.servers[0].items) == 5


def test_upload_fence_then_enable() -> None:
    h = harness(VehicleType.COPTER)
    fence = rq.UploadFence(
        inclusion_polygons=(((37.40, -6.00), (37.43, -6.00), (37.43, -5.97), (37.40, -5.97)),),
        exclusion_polygons=(((37.41, -5.99), (37.415, -5.99), (37.415, -5.985)),),
        exclusion_circles=((37.42, -5.98, 50.0),),
        enable=True,
    )
    result, sent = run(h, fence)
    assert result.ok and sent == [("long", 207, (1, 0, 0, 0, 0, 0, 0))]
    stored = h.fake.servers[1].items
    assert [m.command for m in stored] == [5001] * 4 + [5002] * 3 + [5004]
    assert [m.param1 for m in stored] == [4] * 4 + [3] * 3 + [50]


@pytest.mark.parametrize(
    "req",
    [
        rq.Goto(lat_deg=91, lon_deg=0, alt_rel_m=10),
        rq.Goto(lat_deg=0, lon_deg=0, alt_rel_m=math.inf),
        rq.Takeoff(alt_rel_m=0),
        rq.Takeoff(alt_rel_m=math.nan),
        rq.ChangeSpeed(speed_m_s=-1),
        rq.SetMode(mode="QLAND"),  # not a copter mode
        rq.SetParam(name="A" * 17, value=1),
        rq.SetParam(name="X", value=math.nan),
        rq.Calibrate(what="everything"),
        rq.UploadFence(exclusion_polygons=(((0.0, 0.0), (1.0, 1.0), (0.0, 1.0), (1.0, 0.0)),)),
        rq.UploadFence(exclusion_polygons=(((0.0, 0.0), (1.0, 1.0)),)),
        rq.UploadFence(exclusion_circles=((0.0, 0.0, -5.0),)),
        rq.UploadRally(points=((100.0, 0.0, 10.0),)),
        rq.UploadMission(items=(Waypoint(lat_deg=math.nan),)),
        rq.UploadMission(items=(Waypoint(ItemKind.LOITER_TURNS, lat_deg=1, lon_deg=1, turns=0),)),
    ],
    ids=lambda r: type(r).__name__,
)
def test_our_own_misuse_raises(req: rq.ApRequest) -> None:
    with pytest.raises(InvalidRequest):
        check_request(req, VehicleType.COPTER)
    core = LinkCore(LinkSettings(vehicle_type=VehicleType.COPTER), 0.0)
    with pytest.raises(InvalidRequest):
        core.submit(1, req, 0.0)
