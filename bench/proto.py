"""Message encoding: size and speed of every message on the LAN and the radio, beside
pymavlink's HIGH_LATENCY2 and GLOBAL_POSITION_INT measured in the same run."""

from __future__ import annotations

import statistics
from typing import Any

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from bench.common import time_us
from swarm_proto import (
    MESSAGE_TYPES,
    Ack,
    AckReason,
    AckRef,
    Alert,
    AlertCode,
    AlertFlag,
    Command,
    CommandArgs,
    CommandKind,
    FleetAssignment,
    FsmState,
    Geometry,
    GeoPoint,
    GpsFix,
    LineageHome,
    LineageProgress,
    LineageStep,
    Mission,
    MissionParams,
    MissionState,
    MissionType,
    NoFlyZone,
    PeerRadioStats,
    PlanLineage,
    RadioStats,
    Selector,
    SelectorKind,
    Severity,
    TargetReport,
    TargetSource,
    VehicleInfo,
    VehicleStatus,
    VehicleType,
    Vote,
    VoteScore,
    lan,
    radio,
)
from swarm_proto.messages import (
    IntentPoint,
    MavlinkAnswer,
    MavlinkCommand,
    MavlinkSummary,
    VehicleIntent,
)

NOW = 1.75e9


def sample_status() -> VehicleStatus:
    return VehicleStatus(
        vehicle_id=12,
        time_unix_s=NOW,
        lat_deg=37.4112345,
        lon_deg=-5.9889123,
        alt_msl_m=412.25,
        alt_rel_m=402.0,
        vel_north_m_s=18.21,
        vel_east_m_s=-12.5,
        vel_down_m_s=0.4,
        heading_deg=325.5,
        airspeed_m_s=26.1,
        battery_pct=71,
        battery_v=47.31,
        gps_fix=GpsFix.FIX_3D,
        gps_sats=17,
        ap_mode=10,
        armed=True,
        fsm_state=FsmState.GO_MISSION,
        mission_state=MissionState.MISSION,
        mission_progress_pct=38,
        fleet_id=2,
        alerts=AlertFlag.NONE,
    )


HOME = GeoPoint(37.4112, -5.9889, 10.0)
FIELD = [(37.4120, -5.9900), (37.4120, -5.9800), (37.4180, -5.9800), (37.4180, -5.9900)]

SAMPLES: dict[type, Any] = {
    VehicleStatus: sample_status(),
    VehicleInfo: VehicleInfo(
        12,
        VehicleType.VTOL,
        "Albatross 250 VTOL",
        "ALB-03",
        3,
        "Camera 2-axis 1.5 Mpx",
        "EO gimbal",
        "Camera",
        26.0,
        HOME,
        HOME,
        2,
        7,
    ),
    Command: Command(900, 41, CommandKind.GOTO, Selector.ids(3, 4), CommandArgs(point=HOME), NOW),
    Ack: Ack(12, 900, AckRef.COMMAND, 41, False, AckReason.HOME_NOT_SET),
    Alert: Alert(12, NOW, Severity.CRITICAL, AlertCode.BATTERY_CRITICAL, "battery 9%"),
    Mission: Mission(
        7,
        900,
        MissionType.AREA,
        Geometry.polygon(FIELD),
        MissionParams(altitude_rel_m=100.0),
        Selector(SelectorKind.QUANTITY, quantity=3, payload_model="Camera 2-axis 1.5 Mpx"),
        "field A",
        NOW,
    ),
    Vote: Vote(7, 12, tuple(VoteScore(v, 0.1 * v) for v in range(1, 7))),
    FleetAssignment: FleetAssignment(2, 7, (3, 4, 12), 12, NOW),
    NoFlyZone: NoFlyZone(5, Geometry.circle(37.415, -5.985, 250.0), 0.0, 300.0),
    TargetReport: TargetReport(88, 12, TargetSource.PAYLOAD, NOW, HOME, "vehicle", 0.82),
    PlanLineage: PlanLineage(
        Mission(
            7, 900, MissionType.AREA, Geometry.polygon(FIELD), MissionParams(altitude_rel_m=60.0)
        ),
        12,
        tuple(LineageHome(v, HOME) for v in (3, 4, 12)),
        (LineageStep((3, 4, 5), tuple(LineageProgress(v, 812.5) for v in (3, 4, 12))),),
        0xBEEF,
    ),
    RadioStats: RadioStats(
        12,
        NOW,
        "member",
        (3, 4, 7, 12),
        0xBEEF,
        1,
        0.05,
        204,
        0.42,
        0.8,
        0,
        1200,
        3590,
        peers=tuple(PeerRadioStats(v, 5.0, 0.01, 0.4, 0.35, 0.2, 0) for v in (3, 4, 7)),
    ),
}


def _mav() -> mavlink.MAVLink:
    class Sink:
        def write(self, b: bytes) -> None:
            pass

    m = mavlink.MAVLink(Sink(), srcSystem=1, srcComponent=1)
    return m


def _hl2() -> Any:
    # every field set (MAVLink 2 trims trailing zero bytes; a real HIGH_LATENCY2 carrying
    # swarm data in custom0..2 uses the full 42-byte payload)
    return mavlink.MAVLink_high_latency2_message(
        123456,
        1,
        3,
        10,
        374112345,
        -59889123,
        412,
        500,
        325 // 2,
        150,
        100,
        200,
        130,
        26,
        3,
        7,
        2,
        4,
        71,
        5,
        9,
        1,
        0,
        0x10,
        2,
        38,
        4,
    )


# MAVLink passthrough on the radio (swarm_node/core/passthrough.py): a HIGH_LATENCY2
# summary, a radio session's command and the vehicle's answer
SAMPLES[MavlinkSummary] = MavlinkSummary(12, bytes(_hl2().pack(_mav())))
SAMPLES[MavlinkCommand] = MavlinkCommand(
    900,
    12,
    bytes(mavlink.MAVLink_command_long_message(12, 1, 176, 0, 1, 5, 0, 0, 0, 0, 0).pack(_mav())),
)
SAMPLES[MavlinkAnswer] = MavlinkAnswer(
    12, 900, bytes(mavlink.MAVLink_command_ack_message(176, 0, 0, 0, 255, 190).pack(_mav()))
)
# three legs ahead: a lane's end, the next lane's start and end
SAMPLES[VehicleIntent] = VehicleIntent(
    12,
    NOW,
    22.0,
    68.9,
    False,
    (
        IntentPoint(37.4123456, -5.9912345, 112.25),
        IntentPoint(37.4123456, -5.9905678, 112.25),
        IntentPoint(37.4023456, -5.9905678, 112.25),
    ),
)


def _signed_mav() -> mavlink.MAVLink:
    mav = _mav()
    mav.signing.secret_key = bytes(range(32))
    mav.signing.link_id = 1
    mav.signing.sign_outgoing = True
    return mav


# the radio frame a status travels in: one MSG record, a 10-member swarm's heard bitmap
FRAME_MEMBERS = 10
FRAME_KEY = bytes(range(32))


def status_frame(blob: bytes) -> bytes:
    """`blob` (a radio-encoded status) as the radio gateway puts it on air: a frame with
    one MSG record (header, heard bitmap, record header, BLAKE2s tag, CRC, COBS, 0x00)."""
    from radio_gateway.core import frame

    f = frame.Frame(
        src=12,
        cycle=123456,
        table_hash=0xBEEF,
        n_members=FRAME_MEMBERS,
        heard=b"\xff" * frame.heard_bytes(FRAME_MEMBERS),
        records=(frame.Msg(blob),),
    )
    return frame.encode(f, FRAME_KEY)


def mavlink_figures() -> dict[str, Any]:
    mav = _mav()
    hl2 = _hl2()
    gpi = mavlink.MAVLink_global_position_int_message(
        123456, 374112345, -59889123, 412250, 402000, 1821, -1250, 40, 32550
    )
    raw_hl2 = hl2.pack(mav)
    signed = _signed_mav()
    raw_signed = _hl2().pack(signed)
    return {
        "high_latency2_bytes": len(raw_hl2),
        "high_latency2_signed_bytes": len(raw_signed),
        "global_position_int_bytes": len(gpi.pack(mav)),
        "global_position_int_encode_us": time_us(lambda: gpi.pack(mav)),
    }


def codec_figures(s: VehicleStatus) -> dict[str, Any]:
    """Status encode and decode beside HIGH_LATENCY2 pack and decode, in alternating
    rounds (medians), so both see the same machine load."""
    mav, hl2 = _mav(), _hl2()
    blob = radio.encode(s)
    raw = hl2.pack(mav)
    parser = mavlink.MAVLink(None)
    rounds: dict[str, list[float]] = {k: [] for k in ("enc", "dec", "hl2_enc", "hl2_dec")}

    def enc() -> object:
        return radio.encode(s)

    def hl2_enc() -> object:
        return hl2.pack(mav)

    def dec() -> object:
        return radio.decode(blob, now_unix_s=NOW)

    def hl2_dec() -> object:
        return parser.decode(bytearray(raw))

    for _ in range(5):
        for key, fn in (("enc", enc), ("hl2_enc", hl2_enc), ("dec", dec), ("hl2_dec", hl2_dec)):
            rounds[key].append(time_us(fn, repeat=3))
    med = {k: round(statistics.median(v), 3) for k, v in rounds.items()}
    return {
        "status_encode_us": med["enc"],
        "status_decode_us": med["dec"],
        "high_latency2_encode_us": med["hl2_enc"],
        "high_latency2_decode_us": med["hl2_dec"],
        "status_encode_vs_high_latency2": round(med["enc"] / med["hl2_enc"], 3),
        "status_decode_vs_high_latency2": round(med["dec"] / med["hl2_dec"], 3),
    }


def run() -> dict[str, Any]:
    s = sample_status()
    radio_blob = radio.encode(s)
    lan_blob = lan.encode(s)
    figures: dict[str, Any] = {
        "status_radio_bytes": len(radio_blob),
        "status_frame_bytes": len(status_frame(radio_blob)),
        "status_lan_bytes": len(lan_blob),
        "status_lan_encode_us": time_us(lambda: lan.encode(s)),
        "status_lan_decode_us": time_us(lambda: lan.decode(lan_blob, VehicleStatus)),
    }
    figures.update(mavlink_figures())
    figures.update(codec_figures(s))
    per_message: dict[str, dict[str, float]] = {}
    for cls in MESSAGE_TYPES:
        msg = SAMPLES[cls]
        rb, lb = radio.encode(msg), lan.encode(msg)
        per_message[cls.__name__] = {
            "radio_bytes": len(rb),
            "lan_bytes": len(lb),
            "radio_encode_us": time_us(lambda m=msg: radio.encode(m), number=300),
            "radio_decode_us": time_us(lambda b=rb: radio.decode(b, now_unix_s=NOW), number=300),
            "lan_encode_us": time_us(lambda m=msg: lan.encode(m), number=300),
            "lan_decode_us": time_us(lambda b=lb, c=cls: lan.decode(b, c), number=300),
        }
    figures["messages"] = per_message
    figures["note"] = (
        "Framed against framed: status_frame_bytes is the 40-byte status as the radio "
        "gateway puts it on air (one MSG record in a frame of a 10-member swarm: header, "
        "heard bitmap, BLAKE2s-48 tag, CRC, COBS, delimiter); high_latency2_bytes is "
        "MAVLink 2 framing unsigned (no trailing-zero trim), high_latency2_signed_bytes "
        "with the 13-byte signature. Codec times: the status payload (status_*) and "
        "pymavlink's HIGH_LATENCY2 pack/decode, in alternating rounds of the same run "
        "(*_vs_high_latency2: our time / theirs). `messages`: every message type."
    )
    return figures
