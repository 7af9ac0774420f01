"""MAVLink passthrough on the node (swarm_node/core/passthrough.py): a ground station's
frames classified, relayed, ruled on as the operator's or refused, and the swarm told.
Pure (the module on its own) and in fast time (FastFleet: node cores, real autopilot
links and simulated ArduPilot exchanging real MAVLink bytes)."""

from __future__ import annotations

import msgspec
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from swarm_node.core.arbiter import AutopilotArbiter, Owner, flies
from swarm_node.core.autopilot.framing import MavFramer
from swarm_node.core.autopilot.link import LinkCore, LinkSettings, Transmit, for_passthrough
from swarm_node.core.autopilot.requests import (
    ApError,
    ApResult,
    Arm,
    ChangeSpeed,
    Disarm,
    Land,
    RelayCommand,
    RelaySetting,
    ReturnToLaunch,
    SetMode,
    Takeoff,
)
from swarm_node.core.autopilot.state import AutopilotState
from swarm_node.core.autopilot.streams import StreamRequester
from swarm_node.core.commands import NodeView
from swarm_node.core.inputs import MavlinkUp, Received
from swarm_node.core.mission.phases import Phase
from swarm_node.core.outputs import (
    Delegate,
    Note,
    Publish,
    Recheck,
    Sessions,
    StreamWish,
    Submit,
    TakeOver,
    ToAutopilot,
    ToClient,
)
from swarm_node.core.passthrough import Kind, Passthrough, classify, radio_request
from swarm_proto import (
    Alert,
    AlertCode,
    Command,
    CommandArgs,
    CommandKind,
    FsmState,
    Geometry,
    GeoPoint,
    Mission,
    MissionParams,
    MissionType,
    Selector,
    VehicleType,
)
from swarm_proto.messages import MavlinkAnswer, MavlinkCommand, MavlinkSession, MavlinkSummary
from swarm_sim.core import SITL_HOME
from swarm_sim.fast_fleet import FastFleet

GCS, SID = 900, 11
CLIENT = mavlink.MAVLink(None, srcSystem=255, srcComponent=190)  # QGroundControl's ids
AP = AutopilotState(
    sysid=7, compid=1, link_ok=True, vehicle_type=VehicleType.COPTER, mode_number=3
)  # AUTO


def frame(msg: object, mav: mavlink.MAVLink = CLIENT) -> bytes:
    return bytes(msg.pack(mav))  # type: ignore[attr-defined]


def view(fleet_profiles: dict, *, on_mission: bool = False, ap: AutopilotState = AP) -> NodeView:
    return NodeView(
        7,
        1,
        fleet_profiles[7],
        ap,
        FsmState.GO_MISSION if on_mission else FsmState.PLAN,
        41 if on_mission else None,
        None,
        True,
    )


def opened(read_only: bool = False) -> Passthrough:
    pt = Passthrough(7)
    assert pt.on_session(MavlinkSession(7, SID, GCS, read_only), 0.0)[-1] == Sessions((SID,))
    return pt


def decoded(outs: list) -> list:
    data = b"".join(o.data for o in outs if isinstance(o, ToClient))
    return MavFramer().feed(data)


def command(cmd: int, *params: float) -> object:
    p = [*params, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0][:7]
    return mavlink.MAVLink_command_long_message(7, 1, cmd, 0, *p)


# ----------------------------------------------------------------------- classification
CASES = [
    (mavlink.MAVLink_param_request_read_message(7, 1, b"WPNAV_SPEED", -1), Kind.READ),
    (mavlink.MAVLink_param_request_list_message(7, 1), Kind.READ),
    (mavlink.MAVLink_mission_request_list_message(7, 1, 1), Kind.READ),
    (mavlink.MAVLink_mission_request_int_message(7, 1, 3, 0), Kind.READ),
    (mavlink.MAVLink_log_request_list_message(7, 1, 0, 0xFFFF), Kind.READ),
    (command(512, 148), Kind.READ),  # REQUEST_MESSAGE AUTOPILOT_VERSION
    (mavlink.MAVLink_heartbeat_message(6, 8, 0, 0, 4, 3), Kind.LOCAL),
    (mavlink.MAVLink_request_data_stream_message(7, 1, 0, 4, 1), Kind.LOCAL),
    (command(511, 30, 100_000), Kind.LOCAL),
    (
        mavlink.MAVLink_mission_item_int_message(7, 1, 0, 3, 16, 0, 1, 0, 0, 0, 0, 1, 2, 30),
        Kind.ITEM,
    ),
    (mavlink.MAVLink_set_mode_message(7, 1, 5), Kind.FLIGHT),
    (command(400, 1), Kind.FLIGHT),  # arm
    (command(20), Kind.FLIGHT),  # RTL
    (mavlink.MAVLink_mission_count_message(7, 1, 5, 0), Kind.FLIGHT),
    (mavlink.MAVLink_mission_count_message(7, 1, 5, 1), Kind.SETTING),  # fence
    (mavlink.MAVLink_mission_clear_all_message(7, 1, 2), Kind.SETTING),  # rally
    (mavlink.MAVLink_param_set_message(7, 1, b"WPNAV_SPEED", 500, 9), Kind.SETTING),
    (command(241, 1), Kind.SETTING),  # gyro calibration
    (mavlink.MAVLink_file_transfer_protocol_message(0, 7, 1, [0, 0, 0, 4] + [0] * 247), Kind.READ),
    (
        mavlink.MAVLink_file_transfer_protocol_message(0, 7, 1, [0, 0, 0, 7] + [0] * 247),
        Kind.SETTING,
    ),
    (mavlink.MAVLink_manual_control_message(7, 0, 0, 500, 0, 0), Kind.FLIGHT),
]


@pytest.mark.parametrize("msg, kind", CASES, ids=lambda c: getattr(c, "name", str(c)))
def test_what_each_frame_does(msg: object, kind: Kind, fleet_profiles: dict) -> None:
    decoded_msg = MavFramer().feed(frame(msg))[0]
    assert classify(decoded_msg, view(fleet_profiles)).kind == kind


def test_bandadas_own_settings_are_reported_and_a_mode_names_what_is_watched(
    fleet_profiles: dict,
) -> None:
    v = view(fleet_profiles)

    def verdict(msg: object):  # type: ignore[no-untyped-def]
        return classify(MavFramer().feed(frame(msg))[0], v)

    fence = verdict(mavlink.MAVLink_param_set_message(7, 1, b"FENCE_ENABLE", 0, 2))
    assert fence.report and fence.restore
    fs = verdict(mavlink.MAVLink_param_set_message(7, 1, b"FS_GCS_ENABLE", 0, 2))
    assert fs.report and not fs.restore
    assert not verdict(mavlink.MAVLink_param_set_message(7, 1, b"ATC_RAT_RLL_P", 0.1, 9)).report
    assert verdict(command(207, 0)).restore  # DO_FENCE_ENABLE
    assert verdict(mavlink.MAVLink_set_mode_message(7, 1, 6)).phase == Phase.RETURNING  # RTL
    assert verdict(mavlink.MAVLink_set_mode_message(7, 1, 9)).phase == Phase.LANDING  # LAND
    loiter = verdict(mavlink.MAVLink_set_mode_message(7, 1, 5))
    assert loiter.phase == Phase.OPERATOR and loiter.what == "SET_MODE LOITER"
    assert verdict(command(176, 1, 4)).what == "DO_SET_MODE GUIDED"


def test_relayed_frames_never_fly_for_the_arbiter_unless_they_may() -> None:
    assert flies(RelayCommand(data=b"x")) and not flies(RelaySetting(data=b"x"))
    arb = AutopilotArbiter()
    arb.take(Owner.EMERGENCY)
    (refused,) = arb.submit(Owner.OPERATOR, RelayCommand(request_id=3, data=b"x"))
    assert refused.result.reason == "preempted by EMERGENCY"  # type: ignore[union-attr]
    (sent,) = arb.submit(Owner.OPERATOR, RelaySetting(request_id=4, data=b"x"))
    assert sent.request.data == b"x"  # type: ignore[union-attr]


# ----------------------------------------------------------------------- the module
def test_reads_go_to_the_autopilot_in_one_write_and_commands_to_the_arbiter(
    fleet_profiles: dict,
) -> None:
    pt = opened()
    read = frame(mavlink.MAVLink_param_request_read_message(7, 1, b"WPNAV_SPEED", -1))
    listing = frame(mavlink.MAVLink_mission_request_list_message(7, 1, 0))
    mode = frame(mavlink.MAVLink_set_mode_message(7, 1, 5))
    after = frame(mavlink.MAVLink_param_request_list_message(7, 1))
    outs = pt.on_frames(SID, read + listing + mode + after, view(fleet_profiles), 1.0)
    assert outs[0] == ToAutopilot(read + listing)  # in order: before the command
    submit = outs[1]
    assert isinstance(submit, Submit) and submit.owner == Owner.OPERATOR
    assert isinstance(submit.request, RelayCommand) and submit.request.data == mode
    assert submit.request.what == "ground station 900: SET_MODE LOITER"
    assert outs[2] == ToAutopilot(after)
    # granted on a mission: out of the fleet, the mission manager left to watch the landing
    pt2 = opened()
    (sub,) = pt2.on_frames(SID, mode, view(fleet_profiles, on_mission=True), 1.0)
    assert isinstance(sub, Submit) and pt2.owns(sub.request.request_id)
    outs = pt2.on_result(
        ApResult(sub.request.request_id, True, "relayed"), view(fleet_profiles), 2.0
    )
    assert TakeOver("ground station 900: SET_MODE LOITER", Phase.OPERATOR) in outs
    assert not any(isinstance(o, Delegate) for o in outs)
    rtl = frame(command(20))
    (sub,) = pt2.on_frames(SID, rtl, view(fleet_profiles, on_mission=True), 3.0)
    outs = pt2.on_result(ApResult(sub.request.request_id, True), view(fleet_profiles), 3.0)
    assert TakeOver("ground station 900: NAV_RETURN_TO_LAUNCH", Phase.RETURNING) in outs
    assert Delegate(Owner.MISSION, Owner.OPERATOR) in outs  # it lands it once home


def test_a_refusal_is_answered_as_the_autopilot_would_and_says_who_holds_it(
    fleet_profiles: dict,
) -> None:
    pt = opened()
    (sub,) = pt.on_frames(SID, frame(command(400, 1)), view(fleet_profiles), 1.0)
    outs = pt.on_result(
        ApResult(sub.request.request_id, False, "preempted by EMERGENCY", error=ApError.PREEMPTED),
        view(fleet_profiles),
        1.0,
    )
    ack, text = decoded(outs)
    assert ack.get_type() == "COMMAND_ACK" and ack.command == 400
    assert ack.result == mavlink.MAV_RESULT_TEMPORARILY_REJECTED
    assert (ack.target_system, ack.target_component) == (255, 190)
    assert (ack.get_srcSystem(), ack.get_srcComponent()) == (7, 1)  # the autopilot's ids
    assert text.text == "bandada: preempted by EMERGENCY: COMPONENT_ARM_DIS"  # 50 characters
    assert not any(isinstance(o, TakeOver) for o in outs)


def test_a_read_only_session_gets_downloads_and_refusals(fleet_profiles: dict) -> None:
    pt = opened(read_only=True)
    v = view(fleet_profiles, on_mission=True)
    read = frame(mavlink.MAVLink_mission_request_list_message(7, 1, 1))
    assert pt.on_frames(SID, read, v, 1.0) == [ToAutopilot(read)]
    for msg, name, command_id in [
        (mavlink.MAVLink_set_mode_message(7, 1, 5), "COMMAND_ACK", 11),
        (command(176, 1, 5), "COMMAND_ACK", 176),
        (mavlink.MAVLink_mission_count_message(7, 1, 4, 0), "MISSION_ACK", None),
        (mavlink.MAVLink_param_set_message(7, 1, b"FENCE_ENABLE", 0, 2), "STATUSTEXT", None),
    ]:
        outs = pt.on_frames(SID, frame(msg), v, 1.0)
        # nothing goes anywhere but to the client (and the node's log, once)
        assert all(isinstance(o, ToClient | Note) for o in outs), outs
        answers = decoded(outs)
        assert answers[0].get_type() == name
        if command_id is not None:
            assert answers[0].command == command_id
            assert answers[0].result == mavlink.MAV_RESULT_DENIED
        if name == "MISSION_ACK":
            assert answers[0].type == mavlink.MAV_MISSION_DENIED
        assert answers[-1].get_type() == "STATUSTEXT"
        assert answers[-1].text.startswith("bandada read-only: ")
    assert pt.counts["refused_read_only"] == 4


def test_sticks_refused_at_50_hz_are_told_once_in_2_s(fleet_profiles: dict) -> None:
    pt = opened(read_only=True)
    sticks = frame(mavlink.MAVLink_manual_control_message(7, 0, 0, 500, 0, 0))
    told = [decoded(pt.on_frames(SID, sticks, view(fleet_profiles), i * 0.02)) for i in range(150)]
    assert [i for i, t in enumerate(told) if t] == [0, 100]  # at 0 s and 2 s, not 150 times


def test_a_fence_cleared_by_a_ground_station_is_reported_at_once(fleet_profiles: dict) -> None:
    pt = opened()
    v = view(fleet_profiles)
    clear = frame(mavlink.MAVLink_mission_clear_all_message(7, 1, 1))
    (sub,) = pt.on_frames(SID, clear, v, 1.0)
    outs = pt.on_result(ApResult(sub.request.request_id, True), v, 1.0)
    assert Recheck("set by ground station 900", False) in outs


def test_a_mode_it_is_in_already_is_answered_and_takes_nothing_over(fleet_profiles: dict) -> None:
    pt = opened()
    outs = pt.on_frames(
        SID,
        frame(mavlink.MAVLink_set_mode_message(7, 1, 3)),
        view(fleet_profiles, on_mission=True),
        1.0,
    )
    (ack,) = decoded(outs)
    assert ack.result == mavlink.MAV_RESULT_ACCEPTED and not any(
        isinstance(o, Submit) for o in outs
    )


def test_bandadas_settings_changed_by_a_ground_station_are_alerted_and_checked(
    fleet_profiles: dict,
) -> None:
    pt = opened()
    v = view(fleet_profiles)
    (sub,) = pt.on_frames(
        SID, frame(mavlink.MAVLink_param_set_message(7, 1, b"FENCE_ENABLE", 0, 2)), v, 1.0
    )
    assert isinstance(sub.request, RelaySetting)
    outs = pt.on_result(ApResult(sub.request.request_id, True), v, 1.0)
    alert = next(o.msg for o in outs if isinstance(o, Publish))
    assert isinstance(alert, Alert) and alert.code == AlertCode.GENERIC
    assert alert.text == "PARAM_SET FENCE_ENABLE from ground station 900; fence reloaded"
    assert Recheck("set by ground station 900", True) in outs
    # a fence upload: its items go within the upload, checked once it is over
    (sub,) = pt.on_frames(SID, frame(mavlink.MAVLink_mission_count_message(7, 1, 1, 1)), v, 2.0)
    assert pt.on_result(ApResult(sub.request.request_id, True), v, 2.0)[-1].text.endswith("relayed")  # type: ignore[union-attr]
    item = frame(
        mavlink.MAVLink_mission_item_int_message(7, 1, 0, 0, 5003, 0, 0, 4, 0, 0, 0, 1, 2, 0, 1)
    )
    assert pt.on_frames(SID, item, v, 3.0) == [ToAutopilot(item)]
    assert pt.on_session(MavlinkSession(7, SID, GCS), 7.0) == []  # announced every second
    assert pt.on_timer(7.9, lambda: v) == []
    outs = pt.on_timer(8.0, lambda: v)  # 5 s without an item
    assert Recheck("set by ground station 900", False) in outs
    outs = pt.on_frames(SID, item, v, 9.0)  # no upload: dropped, and said once
    assert [type(o) for o in outs] == [Note] and "item_outside_upload" in outs[0].text
    assert pt.counts["item_outside_upload"] == 1


def test_stream_rates_are_the_nodes_wishes_not_the_clients_settings(fleet_profiles: dict) -> None:
    pt = opened()
    v = view(fleet_profiles)
    outs = pt.on_frames(
        SID, frame(mavlink.MAVLink_request_data_stream_message(7, 1, 3, 4, 1)), v, 1.0
    )
    assert outs == [StreamWish((("RC_CHANNELS", 4.0), ("SERVO_OUTPUT_RAW", 4.0)))]
    outs = pt.on_frames(SID, frame(command(511, 30, 20_000)), v, 1.0)  # ATTITUDE at 50 Hz
    (ack,) = decoded(outs)
    assert ack.command == 511 and ack.result == mavlink.MAV_RESULT_ACCEPTED
    assert StreamWish((("ATTITUDE", 10.0), ("RC_CHANNELS", 4.0), ("SERVO_OUTPUT_RAW", 4.0))) in outs
    ended = pt.on_session(MavlinkSession(7, SID, GCS, closing=True), 2.0)
    assert Sessions(()) in ended and StreamWish(()) in ended


def test_the_stream_requester_asks_for_wishes_when_its_own_requests_are_answered() -> None:
    s = StreamRequester()
    own = s.on_link_up((7, 1), 0.0)  # its own requests await their COMMAND_ACKs
    assert s.want({"ATTITUDE": 25.0, "RC_CHANNELS": 4.0, "NO_SUCH_THING": 1.0}, 0.0) == []
    accepted = mavlink.MAVLink_command_ack_message(511, mavlink.MAV_RESULT_ACCEPTED)
    for _ in own[1:]:
        assert s.handle_ack(accepted, 0.1) == []
    out = s.handle_ack(accepted, 0.1)  # the last answer: now the wishes
    rates = {int(m.param1): 1e6 / m.param2 for m in out if m.param2 > 0}
    assert rates[mavlink.MAVLINK_MSG_ID_ATTITUDE] == 25.0  # faster than its own 10 Hz
    assert rates[mavlink.MAVLINK_MSG_ID_RC_CHANNELS] == 4.0
    out = s.want({"ATTITUDE": 2.0}, 3.0)  # slower than its own: its own; RC back to default
    back = {int(m.param1): m.param2 for m in out}
    assert back == {
        mavlink.MAVLINK_MSG_ID_ATTITUDE: 100_000.0,
        mavlink.MAVLINK_MSG_ID_RC_CHANNELS: 0.0,
    }


# ----------------------------------------------------------------------- bad input
def test_bad_frames_are_dropped_and_counted_and_a_silent_session_ends(
    fleet_profiles: dict,
) -> None:
    pt = opened()
    v = view(fleet_profiles)
    foreign = frame(mavlink.MAVLink_param_request_read_message(9, 1, b"WPNAV_SPEED", -1))
    impostor = frame(
        mavlink.MAVLink_param_request_list_message(7, 1),
        mavlink.MAVLink(None, srcSystem=255, srcComponent=191),
    )
    good = frame(mavlink.MAVLink_param_request_list_message(7, 1))
    outs = pt.on_frames(SID, b"\x00garbage\xfd\x09" + foreign + impostor + good, v, 1.0)
    assert outs[0] == ToAutopilot(good)
    logged = [o.text.rsplit("(", 1)[1] for o in outs[1:] if isinstance(o, Note)]
    assert logged == ["foreign_system)", "malformed)", "node_ids)"]  # once each, per session
    again = pt.on_frames(SID, foreign + good, v, 1.0)
    assert again == [ToAutopilot(good)]
    assert pt.counts["malformed"] == 1 and pt.counts["foreign_system"] == 2
    assert pt.counts["node_ids"] == 1
    assert pt.on_frames(99, good, v, 1.0) == [] and pt.counts["no_session"] == 1
    assert pt.next_deadline() == 6.0
    outs = pt.on_timer(6.0, lambda: v)
    assert Sessions(()) in outs and not any(isinstance(o, ToAutopilot | Submit) for o in outs)


@settings(max_examples=200, derandomize=True, deadline=None)
@given(chunks=st.lists(st.binary(max_size=80), max_size=6), read_only=st.booleans())
def test_any_bytes_from_a_client_never_raise_and_only_whole_frames_go_on(
    chunks: list[bytes], read_only: bool
) -> None:
    from swarm_node.database import seed_fleet

    profiles = {p.vehicle_id: p for p in seed_fleet()}
    pt = opened(read_only)
    good = frame(mavlink.MAVLink_param_request_list_message(7, 1))
    for chunk in [*chunks, good]:
        for o in pt.on_frames(SID, chunk, view(profiles), 1.0):
            if isinstance(o, ToAutopilot):
                assert all(not isinstance(m, type(None)) for m in MavFramer().feed(o.data))
                assert b"".join(bytes(m.get_msgbuf()) for m in MavFramer().feed(o.data)) == o.data


def test_the_link_keeps_the_autopilots_frames_but_not_its_answers_to_the_node() -> None:
    ap = mavlink.MAVLink(None, srcSystem=7, srcComponent=1)
    link = LinkCore(LinkSettings(vehicle_type=VehicleType.COPTER), 0.0)
    link.tap = True
    hb = frame(mavlink.MAVLink_heartbeat_message(2, 3, 89, 3, 4, 3), ap)
    to_node = frame(mavlink.MAVLink_command_ack_message(511, 0, 0, 0, 255, 191), ap)
    to_client = frame(mavlink.MAVLink_command_ack_message(400, 0, 0, 0, 255, 190), ap)
    other = frame(
        mavlink.MAVLink_heartbeat_message(6, 8, 0, 0, 4, 3), mavlink.MAVLink(None, 255, 190)
    )
    link.receive(hb + to_node + to_client + other, 0.1)
    assert link.take_tapped() == hb + to_client
    assert not for_passthrough(MavFramer().feed(to_node)[0], 255, 191)
    out = link.submit(1, RelayCommand(request_id=5, data=b"\xfdraw"), 0.2)
    assert isinstance(out[0], Transmit) and out[0].data == b"\xfdraw" and out[0].message is None
    assert out[1].result.ok  # type: ignore[union-attr]


# ----------------------------------------------------------------------- in fast time
def test_a_ground_stations_mode_change_takes_a_vehicle_out_of_its_fleet_and_read_only_is_refused(
    fleet_profiles: dict,
) -> None:
    """Two quadcopters fly an area together; a ground station attached to 7 reads a
    parameter and the mission and sets LOITER: 7 is out of the fleet with an alert, 8
    replans the area alone; a read-only session on 8 asking the same is refused."""
    fleet = FastFleet.build([7, 8], fleet_profiles)
    v7, v8 = fleet.vehicles[7], fleet.vehicles[8]
    fleet.run_until(lambda: v7.link.state.ekf_has_position and v8.link.state.ekf_has_position, 60)
    base = GeoPoint(SITL_HOME.lat_deg, SITL_HOME.lon_deg, SITL_HOME.alt_m)
    fleet.broadcast(Command(GCS, 1, CommandKind.SET_BASE, args=CommandArgs(point=base)))
    assert fleet.run_until(lambda: v7.node.fsm.state == FsmState.GO_MISSION, 30)
    lat, lon = SITL_HOME.lat_deg, SITL_HOME.lon_deg
    corners = [
        (lat + 0.001, lon + 0.001),
        (lat + 0.0016, lon + 0.001),
        (lat + 0.0016, lon + 0.0016),
        (lat + 0.001, lon + 0.0016),
    ]
    area = Geometry.polygon(corners)
    fleet.broadcast(
        Mission(
            41, GCS, MissionType.AREA, area, MissionParams(altitude_rel_m=40.0), Selector.ids(7, 8)
        )
    )
    flying = (Phase.FLYING,)
    assert fleet.run_until(
        lambda: v7.node.manager.phase in flying and v8.node.manager.phase in flying, 600
    )
    fleet.deliver(7, Received(MavlinkSession(7, SID, GCS)), fleet.now)
    fleet.deliver(8, Received(MavlinkSession(8, SID + 1, GCS, read_only=True)), fleet.now)
    fleet.run_for(0.5)
    assert v7.link.tap and v8.link.tap
    v7.link.take_tapped()
    reads = frame(mavlink.MAVLink_param_request_read_message(7, 1, b"WPNAV_SPEED", -1))
    reads += frame(mavlink.MAVLink_mission_request_list_message(7, 1, 0))
    fleet.deliver(7, MavlinkUp(SID, reads), fleet.now)
    fleet.run_for(0.5)
    down = {m.get_type(): m for m in MavFramer().feed(v7.link.take_tapped())}
    assert down["PARAM_VALUE"].param_id == "WPNAV_SPEED"
    assert down["MISSION_COUNT"].count == v7.link.state.mission_count > 2
    assert (down["MISSION_COUNT"].target_system, down["MISSION_COUNT"].target_component) == (
        255,
        190,
    )
    assert "GLOBAL_POSITION_INT" in down and "HEARTBEAT" in down
    loiter = frame(mavlink.MAVLink_set_mode_message(7, 1, 5))
    fleet.deliver(7, MavlinkUp(SID, loiter), fleet.now)
    fleet.deliver(
        8, MavlinkUp(SID + 1, frame(mavlink.MAVLink_set_mode_message(8, 1, 5))), fleet.now
    )
    fleet.run_for(2.0)
    assert v7.link.state.mode_name == "LOITER" and v7.node.manager.phase == Phase.OPERATOR
    alerts = [m for _, vid, m in fleet.published if vid == 7 and isinstance(m, Alert)]
    assert any(
        a.code == AlertCode.MISSION_FAILED
        and a.text == "left the mission: ground station 900: SET_MODE LOITER"
        for a in alerts
    ), alerts
    assert v8.link.state.mode_name == "AUTO"  # read-only: refused, flies on
    (answer,) = [d for _, vid, sid, d in fleet.to_clients if vid == 8]
    ack, text = MavFramer().feed(answer)
    assert ack.result == mavlink.MAV_RESULT_DENIED and "read-only" in text.text
    assert fleet.run_until(
        lambda: any("replanned for [8]" in n for _, vid, n in fleet.notes if vid == 8), 30
    )
    # the client goes away: its session ends, nothing more is kept for it
    assert fleet.run_until(lambda: not v7.link.tap, 10)
    assert v7.link.state.mode_name == "LOITER"


# ----------------------------------------------------------------------- the radio
def test_a_radio_session_gets_a_summary_every_5_s_and_commands_as_the_nodes_own(
    fleet_profiles: dict,
) -> None:
    pt = Passthrough(7)
    ap = msgspec.structs.replace(
        AP, lat_deg=37.4, lon_deg=-5.9, alt_msl_m=60.0, armed=True, battery_pct=80, mav_type=2
    )
    v = view(fleet_profiles, on_mission=True, ap=ap)
    assert pt.on_radio(MavlinkCommand(GCS, 8), v, 0.0) == []  # not ours
    pt.on_radio(MavlinkCommand(GCS, 7), v, 0.0)  # the keep-alive opens it
    assert pt.next_deadline() == 0.0
    (summary,) = [o.msg for o in pt.on_timer(0.0, lambda: v) if isinstance(o, Publish)]
    assert isinstance(summary, MavlinkSummary) and len(summary.frame) <= 54
    (hl2,) = MavFramer().feed(summary.frame)
    assert hl2.get_type() == "HIGH_LATENCY2" and hl2.custom_mode == 3 and hl2.custom0 == 1
    assert (hl2.latitude, hl2.altitude, hl2.battery) == (374_000_000, 60, 80)
    assert pt.on_timer(4.9, lambda: v) == [] and pt.next_deadline() == 5.0
    # a mode change: the node's own SetMode, answered with its result
    (sub,) = pt.on_radio(
        MavlinkCommand(GCS, 7, frame(mavlink.MAVLink_set_mode_message(7, 1, 5))), v, 6.0
    )
    assert isinstance(sub, Submit) and sub.request == SetMode(
        request_id=sub.request.request_id, mode="LOITER"
    )
    outs = pt.on_result(ApResult(sub.request.request_id, True), v, 6.1)
    (answer,) = [o.msg for o in outs if isinstance(o, Publish)]
    assert isinstance(answer, MavlinkAnswer) and answer.issuer_id == GCS
    (ack,) = MavFramer().feed(answer.frame)
    assert (ack.command, ack.result, ack.target_component) == (11, 0, 190)
    assert TakeOver("ground station 900 (radio): SET_MODE LOITER", Phase.OPERATOR) in outs
    # what is not a command does not go over the radio
    outs = pt.on_radio(MavlinkCommand(GCS, 7, frame(command(241, 1))), v, 7.0)
    ack, text = MavFramer().feed(outs[0].msg.frame)  # type: ignore[union-attr]
    assert (
        ack.result == mavlink.MAV_RESULT_UNSUPPORTED
        and text.text == "bandada: not on the radio: PREFLIGHT_CALIBRATION"
    )
    # silent for 60 s: no more summaries
    outs = pt.on_timer(67.0, lambda: v)  # 60 s after its last command
    assert not pt.radio and not any(isinstance(o, Publish) for o in outs)


def test_radio_commands_become_the_nodes_requests() -> None:
    ap = AP
    cases = [
        (command(400, 1), Arm()),
        (command(400, 0, 21196), Disarm(force=True)),
        (command(20), ReturnToLaunch()),
        (command(21), Land()),
        (command(22, 0, 0, 0, 0, 0, 0, 30), Takeoff(alt_rel_m=30.0)),
        (command(178, 1, 8), ChangeSpeed(speed_m_s=8.0, airspeed=False)),
        (command(176, 1, 4), SetMode(mode="GUIDED")),
        (command(241, 1), None),
        (mavlink.MAVLink_set_mode_message(7, 1, 99), None),  # no such copter mode
    ]
    for msg, want in cases:
        (decoded_msg,) = MavFramer().feed(frame(msg))
        assert radio_request(decoded_msg, ap) == want


def test_a_radio_sessions_mode_change_in_fast_time(fleet_profiles: dict) -> None:
    fleet = FastFleet.build([7], fleet_profiles)
    v7 = fleet.vehicles[7]
    fleet.run_until(lambda: v7.link.state.ekf_has_position, 60)
    fleet.deliver(7, Received(MavlinkCommand(GCS, 7)), fleet.now)
    fleet.run_for(11.0)
    summaries = [m for _, vid, m in fleet.published if isinstance(m, MavlinkSummary)]
    assert len(summaries) == 3  # at once, then every 5 s
    set_mode = frame(mavlink.MAVLink_set_mode_message(7, 1, 4))  # GUIDED
    fleet.deliver(7, Received(MavlinkCommand(GCS, 7, set_mode)), fleet.now)
    fleet.run_for(2.0)
    assert v7.link.state.mode_name == "GUIDED"
    (answer,) = [m for _, vid, m in fleet.published if isinstance(m, MavlinkAnswer)]
    (ack,) = MavFramer().feed(answer.frame)
    assert ack.result == mavlink.MAV_RESULT_ACCEPTED and ack.get_srcSystem() == 7
