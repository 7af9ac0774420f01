"""Inbound MAVLink messages other than commands, for `SimAutopilot`: the table
`HANDLERS` maps each handled message type to its handler, `IGNORED` lists what is
received and deliberately ignored. Mission-protocol messages go to the per-type
`ItemTransfer`s; guided targets, parameters, streams, TIMESYNC and FTP are here."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from . import commands, telemetry
from .firmware import SEV_INFO, SEV_WARNING, Behaviour, Firmware
from .mission import (
    GLOBAL_FRAMES,
    MISSION,
    NO_SPACE,
    ItemTransfer,
    MissionItem,
    Peer,
    validate_item,
)
from .navigation import FlyTo, Hold, Loiter, Purpose
from .vehicle import Vehicle

MSG_ID_SET_MODE = 11
GUIDED_VELOCITY_TIMEOUT_S = 3.0  # GUID_TIMEOUT


def param_id(raw: Any) -> str:
    if isinstance(raw, bytes):
        raw = raw.decode("ascii", "replace")
    return str(raw).split("\x00", 1)[0].strip()


def on_set_mode(v: Vehicle, msg: Any, src: Peer, now: float) -> None:
    result = commands.set_mode_common(v, int(msg.base_mode), int(msg.custom_mode))
    # ArduPilot acks SET_MODE with a COMMAND_ACK for "command" 11 (the message id)
    v.out.send(
        mavlink.MAVLink_command_ack_message(MSG_ID_SET_MODE, result, 0, 0, src.sysid, src.compid)
    )


def on_heartbeat(v: Vehicle, msg: Any, src: Peer, now: float) -> None:
    """Any HEARTBEAT of system SYSID_MYGCS keeps the GCS failsafe off (ArduPilot's
    GCS_MAVLINK::handle_heartbeat)."""
    if "SYSID_MYGCS" in v.params and src.sysid == int(v.params.value("SYSID_MYGCS")):
        v.failsafes.gcs_heartbeat(now)


def on_position_target_global(v: Vehicle, msg: Any, src: Peer, now: float) -> None:
    if v.modes.behaviour != Behaviour.GUIDED:
        v.counters["position_target_not_guided"] += 1
        return
    nav = v.navigator
    mask = int(msg.type_mask)
    pos_ignore = mask & 0b111 == 0b111
    alt_ignore = bool(mask & 0b100)
    vel_ignore = mask & 0b111000 == 0b111000
    alt = v.home.alt_from_frame(int(msg.coordinate_frame), float(msg.alt))
    if v.firmware == Firmware.PLANE:
        if alt is None:
            v.out.text(SEV_WARNING, "Invalid coord frame in SET_POSTION_TARGET_GLOBAL_INT")
            return
        if not alt_ignore:
            nav.change_alt(alt, guided=True)
        return
    if not pos_ignore:
        lat, lon = msg.lat_int * 1e-7, msg.lon_int * 1e-7
        if alt is None or not (-90 <= lat <= 90 and -180 <= lon <= 180):
            nav.set(nav.hold_here())
            return
        nav.goto(lat, lon, alt)
    elif not vel_ignore:
        vn, ve, vd = float(msg.vx), float(msg.vy), float(msg.vz)
        if not all(math.isfinite(x) and abs(x) < 1000 for x in (vn, ve, vd)):
            nav.set(nav.hold_here())
            return
        b = v.body
        speed = math.hypot(vn, ve)
        t = GUIDED_VELOCITY_TIMEOUT_S
        task = FlyTo(
            b.n + vn * t, b.e + ve * t, b.alt - vd * t, accept_m=0.5, speed=speed, stop=True
        )
        nav.set(task, Purpose.GUIDED_VELOCITY)


def on_position_target_local(v: Vehicle, msg: Any, src: Peer, now: float) -> None:
    if v.modes.behaviour != Behaviour.GUIDED:
        return
    nav = v.navigator
    if v.firmware == Firmware.PLANE:
        if int(msg.coordinate_frame) == 7:  # LOCAL_OFFSET_NED: altitude only
            task = nav.leaf()
            if isinstance(task, (FlyTo, Hold, Loiter)) and math.isfinite(float(msg.z)):
                task.alt += -float(msg.z)
                v.out.text(SEV_INFO, f"Change alt to {task.alt - v.home.alt:.1f}")
        return
    mask = int(msg.type_mask)
    if mask & 0b111 == 0b111:
        return
    frame = int(msg.coordinate_frame)
    x, y, z = float(msg.x), float(msg.y), float(msg.z)
    if not all(math.isfinite(c) for c in (x, y, z)):
        nav.set(nav.hold_here())
        return
    b = v.body
    if frame == 1:  # LOCAL_NED, from the EKF origin
        n, e, alt = x, y, v.home.origin_alt - z
    elif frame in (7, 9):  # LOCAL_OFFSET_NED, BODY_OFFSET_NED
        if frame == 9:
            h = math.radians(b.heading_deg)
            x, y = x * math.cos(h) - y * math.sin(h), x * math.sin(h) + y * math.cos(h)
        n, e, alt = b.n + x, b.e + y, b.alt - z
    else:
        nav.set(nav.hold_here())
        return
    lat, lon = v.frame.to_latlon(n, e)
    nav.goto(lat, lon, alt)


def on_mission_count(v: Vehicle, msg: Any, src: Peer, now: float) -> None:
    transfer = transfer_for(v, msg)
    if transfer is None:
        return
    if not v.sensors.ready and int(msg.count) > 0:
        # recorded: before "ArduPilot Ready" the storage holds 0 items: MISSION_ACK
        # NO_SPACE at once and "Only 0 items are supported"
        v.out.send(mission_ack(src, NO_SPACE, transfer.mission_type))
        v.out.text(SEV_WARNING, "Only 0 items are supported")
        return
    v.out.extend(transfer.handle_count(src, int(msg.count), now))


def on_mission_item(v: Vehicle, msg: Any, src: Peer, now: float) -> None:
    mtype = int(getattr(msg, "mission_type", 0))
    if mtype == MISSION and int(msg.current) in (2, 3):
        guided_mission_item(v, msg)
        return
    transfer = transfer_for(v, msg)
    if transfer is None:
        return
    item = MissionItem.from_message(msg)
    v.out.extend(transfer.handle_item(src, item, now, as_float=msg.get_type() == "MISSION_ITEM"))


def guided_mission_item(v: Vehicle, msg: Any) -> None:
    """MISSION_ITEM(_INT) with current=2 (guided goto) or 3 (change altitude)."""
    item = MissionItem.from_message(msg)
    if validate_item(item) != 0 or item.frame not in GLOBAL_FRAMES:
        v.out.send(
            mavlink.MAVLink_mission_ack_message(
                msg.get_srcSystem(), msg.get_srcComponent(), 1, MISSION
            )
        )
        return
    guided = v.modes.behaviour == Behaviour.GUIDED
    if int(msg.current) == 3:
        v.navigator.change_alt(v.home.item_alt(item), guided=guided)
        result = 0
    elif not guided:
        result = 1  # ERROR: only in GUIDED
    else:
        v.navigator.goto(item.lat_deg, item.lon_deg, v.home.item_alt(item))
        result = 0
    v.out.send(
        mavlink.MAVLink_mission_ack_message(
            msg.get_srcSystem(), msg.get_srcComponent(), result, MISSION
        )
    )


def on_mission_request(v: Vehicle, msg: Any, src: Peer, now: float) -> None:
    transfer = transfer_for(v, msg)
    if transfer is not None:
        as_int = msg.get_type() == "MISSION_REQUEST_INT"
        v.out.extend(transfer.handle_request(src, int(msg.seq), as_int=as_int))


def on_mission_request_list(v: Vehicle, msg: Any, src: Peer, now: float) -> None:
    transfer = transfer_for(v, msg)
    if transfer is not None:
        v.out.extend(transfer.handle_request_list(src))


def on_mission_clear_all(v: Vehicle, msg: Any, src: Peer, now: float) -> None:
    mtype = int(getattr(msg, "mission_type", 0))
    if mtype == 255:
        for each in v.stores.transfers.values():
            each.handle_clear_all(src)
        v.out.send(mavlink.MAVLink_mission_ack_message(src.sysid, src.compid, 0, 255))
        return
    transfer = transfer_for(v, msg)
    if transfer is not None:
        v.out.extend(transfer.handle_clear_all(src))


def on_mission_set_current(v: Vehicle, msg: Any, src: Peer, now: float) -> None:
    if v.mission.set_current(int(msg.seq)):
        v.out.send(telemetry.mission_current(v))


def on_mission_write_partial_list(v: Vehicle, msg: Any, src: Peer, now: float) -> None:
    transfer = transfer_for(v, msg)
    if transfer is not None:
        v.out.extend(
            transfer.handle_partial_list(src, int(msg.start_index), int(msg.end_index), now)
        )


def mission_ack(peer: Peer, result: int, mission_type: int) -> Any:
    return mavlink.MAVLink_mission_ack_message(peer.sysid, peer.compid, result, mission_type)


def transfer_for(v: Vehicle, msg: Any) -> ItemTransfer | None:
    mtype = int(getattr(msg, "mission_type", 0))
    transfer = v.stores.transfers.get(mtype)
    if transfer is None:
        v.counters["bad_mission_type"] += 1
        src = Peer(msg.get_srcSystem(), msg.get_srcComponent())
        v.out.send(mission_ack(src, 3, mtype & 0xFF))
    return transfer


def on_request_data_stream(v: Vehicle, msg: Any, src: Peer, now: float) -> None:
    v.streams.request_data_stream(
        int(msg.req_stream_id), int(msg.req_message_rate), bool(msg.start_stop), now
    )


def on_param_request_list(v: Vehicle, msg: Any, src: Peer, now: float) -> None:
    names = sorted(v.params)
    for index in range(len(names)):
        v.out.send(v.params.value_message_at(index, names))


def on_param_request_read(v: Vehicle, msg: Any, src: Peer, now: float) -> None:
    names = sorted(v.params)
    name = param_id(msg.param_id)
    if name in v.params:
        v.out.send(v.params.value_message(name))
    elif 0 <= int(msg.param_index) < len(names) and name == "":
        v.out.send(v.params.value_message_at(int(msg.param_index), names))
    else:
        v.counters["param_unknown"] += 1


def on_param_set(v: Vehicle, msg: Any, src: Peer, now: float) -> None:
    name = param_id(msg.param_id)
    value = float(msg.param_value)
    if not v.params.set_from_gcs(name, value):
        v.counters["param_unknown"] += 1
        return
    if name == "BATT_CAPACITY" and value > 0:  # a bigger battery, as charged as before
        v.battery.resize(value)
    v.out.send(v.params.value_message(name))


def on_timesync(v: Vehicle, msg: Any, src: Peer, now: float) -> None:
    if int(msg.tc1) == 0:
        v.out.send(mavlink.MAVLink_timesync_message(int(now * 1e9), int(msg.ts1)))


def on_ftp(v: Vehicle, msg: Any, src: Peer, now: float) -> None:
    """MAVLink FTP is not simulated: NAK every request at once (TerminateSession and
    ResetSessions are ACKed), so that MAVProxy and QGC fall back to PARAM_REQUEST_LIST
    and MISSION_REQUEST_* instead of timing out."""
    payload = bytes(msg.payload)
    if len(payload) < 12:
        v.counters["bad_ftp"] += 1
        return
    seq, session, opcode = int.from_bytes(payload[0:2], "little"), payload[2], payload[3]
    ack = opcode in (1, 2)
    error = 10 if opcode in (3, 4, 14) else 1  # FileNotFound for list/open/crc, else Fail
    reply = bytearray(251)
    reply[0:2] = ((seq + 1) & 0xFFFF).to_bytes(2, "little")
    reply[2], reply[3], reply[5] = session, 128 if ack else 129, opcode
    if not ack:
        reply[4], reply[12] = 1, error
    v.out.send(
        mavlink.MAVLink_file_transfer_protocol_message(0, src.sysid, src.compid, list(reply))
    )


# ------------------------------------------------------------------ helpers


HANDLERS: dict[str, Callable[[Vehicle, Any, Peer, float], None]] = {
    "COMMAND_LONG": commands.on_command_long,
    "COMMAND_INT": commands.on_command_int,
    "SET_MODE": on_set_mode,
    "SET_POSITION_TARGET_GLOBAL_INT": on_position_target_global,
    "SET_POSITION_TARGET_LOCAL_NED": on_position_target_local,
    "MISSION_COUNT": on_mission_count,
    "MISSION_ITEM": on_mission_item,
    "MISSION_ITEM_INT": on_mission_item,
    "MISSION_REQUEST": on_mission_request,
    "MISSION_REQUEST_INT": on_mission_request,
    "MISSION_REQUEST_LIST": on_mission_request_list,
    "MISSION_CLEAR_ALL": on_mission_clear_all,
    "MISSION_SET_CURRENT": on_mission_set_current,
    "MISSION_WRITE_PARTIAL_LIST": on_mission_write_partial_list,
    "REQUEST_DATA_STREAM": on_request_data_stream,
    "PARAM_REQUEST_LIST": on_param_request_list,
    "PARAM_REQUEST_READ": on_param_request_read,
    "PARAM_SET": on_param_set,
    "HEARTBEAT": on_heartbeat,
    "TIMESYNC": on_timesync,
    "FILE_TRANSFER_PROTOCOL": on_ftp,
}

# Received and deliberately ignored (acks of our own messages, ...)
IGNORED = frozenset(
    {
        "MISSION_ACK",
        "COMMAND_ACK",
        "SYSTEM_TIME",
        "RC_CHANNELS_OVERRIDE",
        "MANUAL_CONTROL",
        "RADIO_STATUS",
        "RADIO",
        "GPS_RTCM_DATA",
        "GPS_INJECT_DATA",
        "STATUSTEXT",
        "PING",
        "SET_ATTITUDE_TARGET",
        "LOG_REQUEST_LIST",
        "TERRAIN_DATA",
        "TERRAIN_CHECK",
        "REQUEST_AUTOPILOT_CAPABILITIES",
        "SETUP_SIGNING",
    }
)
# messages whose target_component may be anything (they are for the whole system)
ANY_COMPONENT = frozenset({"REQUEST_DATA_STREAM", "MISSION_REQUEST_LIST", "PARAM_REQUEST_LIST"})
