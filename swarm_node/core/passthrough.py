"""MAVLink passthrough: a ground station (QGroundControl, MAVProxy, pymavlink) talks to
this vehicle's autopilot through the swarm (`gcs mavlink`), and the swarm stays in
charge and knows (docs/autopilot-link.md, "Passthrough").

The node is its autopilot's only MAVLink client. A session's frames reach the autopilot
through this module, the autopilot's frames reach the session through the shell (the
link keeps them while a session is open: `Sessions`). Each frame from a client is
classified (`classify`; the tables below say what is what):

    READ     relayed at once: parameter and mission reads, downloads, the log list, FTP
             reads, time sync
    LOCAL    answered by the node: the client's HEARTBEAT (the session is alive) and its
             stream rates (REQUEST_DATA_STREAM, SET_MESSAGE_INTERVAL would set the rates
             of the node's own link; a wish raises a rate, never lowers the node's:
             `StreamWish`)
    ITEM     an item of an upload the arbiter granted (MISSION_ITEM_INT): relayed within
             the upload
    FLIGHT   changes what the vehicle does (a mode, arming, a command that moves it, a
             mission upload, guided targets, sticks): a `RelayCommand` of owner OPERATOR,
             ruled on by the arbiter; granted while the vehicle is on a mission it takes
             the vehicle out of its fleet (`TakeOver`: the fleet replans without it, the
             state machine raises the alert), refused it is answered as the autopilot
             would (COMMAND_ACK TEMPORARILY_REJECTED, STATUSTEXT saying who holds it)
    SETTING  changes the vehicle without flying it (a parameter, a fence or rally upload,
             a calibration, RTK corrections, FTP writes): a `RelaySetting`, never refused
             for precedence; bandada's own (`BANDADA_PARAMS`, fence and rally uploads,
             DO_FENCE_ENABLE) are reported in an alert and the backstop checks the fence
             and rally point as after a reboot (`Recheck`)

Over the 900 MHz radio (`gcs mavlink --radio`) a session is budgeted: the node
publishes a HIGH_LATENCY2 summary (`high_latency2`) every `SUMMARY_PERIOD_S` while a
radio session was heard within `RADIO_SESSION_S`, and takes commands only (COMMAND_LONG,
COMMAND_INT, SET_MODE), one frame each, turned into the node's own requests
(`radio_request`: a mode, arming, RTL, land, take-off, speed, mission start, parachute)
and ruled on by the arbiter as above; the answer (COMMAND_ACK from the request's result,
a STATUSTEXT for a refusal) goes back as a `MavlinkAnswer`.

A read-only session's FLIGHT and SETTING frames are refused: COMMAND_ACK DENIED (a
MISSION_ACK DENIED for an upload) and a STATUSTEXT to the client, from the autopilot's
ids. A frame that does not decode, one addressed to another system, one that claims the
node's own MAVLink ids, or one of a session never announced is dropped and counted
(`counts`); a session unheard for `timeout_s` ends, and nothing is sent to the vehicle.

    inputs                                  outputs
    on_session(MavlinkSession)              Sessions (the shell relays to them), Note
    on_frames(session, data, view)          ToAutopilot (READ, ITEM), Submit(Relay*,
                                            OPERATOR), ToClient (answers), StreamWish
    on_radio(MavlinkCommand, view)          Submit(own request, OPERATOR), Publish(answer)
    on_result(result) (owns(request_id))    TakeOver (+ Delegate), Publish(Alert),
                                            Recheck, ToClient / Publish(MavlinkAnswer)
    on_timer(now, view)                     Sessions (timed out), Recheck (an upload over),
                                            Publish(MavlinkSummary)

Pure: no I/O; `now` is passed in.
"""

from __future__ import annotations

import itertools
import logging
from collections import Counter
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from enum import Enum

import msgspec
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from swarm_proto import Alert, AlertCode, GpsFix, Severity
from swarm_proto.ardupilot import mode_name
from swarm_proto.messages import MavlinkAnswer, MavlinkCommand, MavlinkSession, MavlinkSummary
from swarm_proto.text import short_text

from .autopilot.framing import BadFrame, MavEncoder, MavFramer, MAVLinkMessage
from .autopilot.requests import (
    ApError,
    ApRequest,
    ApResult,
    Arm,
    ChangeSpeed,
    Disarm,
    Land,
    Parachute,
    RelayCommand,
    RelaySetting,
    ReturnToLaunch,
    SetMode,
    StartMission,
    Takeoff,
)
from .autopilot.state import AutopilotState
from .commands import NodeView
from .mission.phases import Phase
from .outputs import (
    Delegate,
    ModuleOutput,
    Note,
    Owner,
    Publish,
    Recheck,
    Sessions,
    StreamWish,
    Submit,
    TakeOver,
    ToAutopilot,
    ToClient,
)

TIMEOUT_S = 5.0  # a session unheard this long (no announcement, no frame) ends
UPLOAD_IDLE_S = 5.0  # an upload with no item for this long is over
MAX_WISH_HZ = 10.0  # a session's stream wish: at most the node's own fastest rate
#: the node's own MAVLink ids on the link (LinkSettings): a client must not claim them
NODE_IDS = (255, 191)
RADIO_SESSION_S = 60.0  # a radio session not heard of this long ends (kept every 20 s)
SUMMARY_PERIOD_S = 5.0  # HIGH_LATENCY2's rate on a high-latency link (as ArduPilot sends it)
MAV_AUTOPILOT_ARDUPILOTMEGA = 3
TELL_AGAIN_S = 2.0  # one refusal's STATUSTEXT at most this often per session


class Kind(Enum):
    READ = "read"
    LOCAL = "local"
    ITEM = "item"
    FLIGHT = "flight"
    SETTING = "setting"


#: Messages by what they do (anything not listed flies the vehicle: FLIGHT).
READ_MESSAGES = frozenset(
    {
        "PARAM_REQUEST_READ",
        "PARAM_REQUEST_LIST",
        "PARAM_EXT_REQUEST_READ",
        "PARAM_EXT_REQUEST_LIST",
        "MISSION_REQUEST_LIST",
        "MISSION_REQUEST",
        "MISSION_REQUEST_INT",
        "MISSION_REQUEST_PARTIAL_LIST",
        "MISSION_ACK",  # the client ends its download
        "FENCE_FETCH_POINT",
        "RALLY_FETCH_POINT",
        "LOG_REQUEST_LIST",
        "LOG_REQUEST_DATA",
        "LOG_REQUEST_END",
        "REMOTE_LOG_BLOCK_STATUS",
        "LOGGING_ACK",
        "AUTOPILOT_VERSION_REQUEST",
        "TIMESYNC",
        "PING",
        "SYSTEM_TIME",
    }
)
LOCAL_MESSAGES = frozenset({"HEARTBEAT", "REQUEST_DATA_STREAM", "RADIO_STATUS"})
ITEM_MESSAGES = frozenset({"MISSION_ITEM", "MISSION_ITEM_INT"})
SETTING_MESSAGES = frozenset(
    {
        "PARAM_SET",
        "PARAM_EXT_SET",
        "GPS_RTCM_DATA",
        "GPS_INJECT_DATA",
        "SETUP_SIGNING",
        "TERRAIN_DATA",
        "LOG_ERASE",
        "FENCE_POINT",
        "RALLY_POINT",
        "SET_GPS_GLOBAL_ORIGIN",
        "SET_HOME_POSITION",
    }
)
#: uploads and clears: FLIGHT for the mission, SETTING for the fence and the rally points
TRANSFER_STARTS = frozenset({"MISSION_COUNT", "MISSION_CLEAR_ALL", "MISSION_WRITE_PARTIAL_LIST"})
MISSION, FENCE, RALLY, ALL_TYPES = 0, 1, 2, 255

#: COMMAND_LONG / COMMAND_INT ids that only read
READ_COMMANDS = frozenset({410, 510, 512, 519, 520, 521, 522, 525, 527, 528, 2504, 2505})
SET_MESSAGE_INTERVAL = 511
#: commands that change the vehicle without flying it (calibrations, storage, servos and
#: relays, camera and gimbal, compass calibration)
SETTING_COMMANDS = frozenset(
    {
        181,  # DO_SET_RELAY
        182,  # DO_REPEAT_RELAY
        183,  # DO_SET_SERVO
        184,  # DO_REPEAT_SERVO
        202,  # DO_DIGICAM_CONFIGURE
        203,  # DO_DIGICAM_CONTROL
        204,  # DO_MOUNT_CONFIGURE
        205,  # DO_MOUNT_CONTROL
        206,  # DO_SET_CAM_TRIGG_DIST
        241,  # PREFLIGHT_CALIBRATION
        245,  # PREFLIGHT_STORAGE
        530,  # SET_CAMERA_MODE
        531,  # SET_CAMERA_ZOOM
        532,  # SET_CAMERA_FOCUS
        1000,  # DO_GIMBAL_MANAGER_PITCHYAW
        1001,  # DO_GIMBAL_MANAGER_CONFIGURE
        2000,  # IMAGE_START_CAPTURE
        2001,  # IMAGE_STOP_CAPTURE
        2500,  # VIDEO_START_CAPTURE
        2501,  # VIDEO_STOP_CAPTURE
        42424,  # DO_START_MAG_CAL
        42425,  # DO_ACCEPT_MAG_CAL
        42426,  # DO_CANCEL_MAG_CAL
    }
)
DO_SET_MODE, DO_FENCE_ENABLE, DO_SET_HOME = 176, 207, 179
#: settings bandada relies on, reported when a session changes them: the backstop checks
#: the fence and rally point (`restore`: their settings may differ where a download
#: cannot tell, so the fence is uploaded again)
REPORTED_COMMANDS = {DO_FENCE_ENABLE: True, DO_SET_HOME: False}
#: parameters bandada relies on (prefixes): its fence, its rally point, the failsafes
BANDADA_PARAMS = ("FENCE_", "RALLY_", "FS_", "BATT_FS_", "SYSID_MYGCS", "MAV_GCS_SYSID")
#: FTP opcodes that only read (MAVLink FTP: payload[3])
FTP_READS = frozenset({0, 1, 2, 3, 4, 5, 14, 15})

#: modes and commands that bring the vehicle home or down: what the mission manager then
#: watches for (as after `gcs cmd rtl` / `land`); any other mode leaves it to the operator
RETURN_MODES = frozenset({"RTL", "QRTL", "SMART_RTL", "AUTO_RTL"})
LAND_MODES = frozenset({"LAND", "QLAND"})
COMMAND_PHASE = {20: Phase.RETURNING, 21: Phase.LANDING, 85: Phase.LANDING}

#: ArduPilot's REQUEST_DATA_STREAM groups, by the messages a client uses most
STREAM_GROUPS: Mapping[int, tuple[str, ...]] = {
    1: ("RAW_IMU", "SCALED_PRESSURE"),
    2: ("SYS_STATUS", "MISSION_CURRENT", "GPS_RAW_INT", "NAV_CONTROLLER_OUTPUT", "MEMINFO"),
    3: ("SERVO_OUTPUT_RAW", "RC_CHANNELS"),
    6: ("GLOBAL_POSITION_INT", "LOCAL_POSITION_NED"),
    10: ("ATTITUDE", "AHRS2"),
    11: ("VFR_HUD",),
    12: ("SYSTEM_TIME", "WIND", "BATTERY_STATUS", "EKF_STATUS_REPORT", "VIBRATION"),
}


@dataclass(frozen=True)
class Verdict:
    kind: Kind
    what: str  # for people: "SET_MODE LOITER", "PARAM_SET FENCE_ENABLE"
    phase: Phase = Phase.OPERATOR  # FLIGHT: what the mission manager watches after a take-over
    mission_type: int | None = None  # an upload or clear: which store
    report: bool = False  # SETTING bandada relies on: alert and backstop check
    restore: bool = False  # ... and the fence uploaded again


def _text(raw: object) -> str:
    if isinstance(raw, bytes):
        raw = raw.decode("ascii", "replace")
    return str(raw).split("\x00", 1)[0].strip()


def classify(msg: MAVLinkMessage, view: NodeView) -> Verdict:
    """What a client's frame does (the tables above)."""
    name = msg.get_type()
    if name in READ_MESSAGES:
        return Verdict(Kind.READ, name)
    if name in LOCAL_MESSAGES:
        return Verdict(Kind.LOCAL, name)
    if name in ITEM_MESSAGES:
        return Verdict(Kind.ITEM, name, mission_type=int(getattr(msg, "mission_type", 0)))
    if name in ("COMMAND_LONG", "COMMAND_INT"):
        return _command(msg, view)
    if name == "SET_MODE":
        return _mode(name, int(msg.custom_mode), view)
    if name in ("PARAM_SET", "PARAM_EXT_SET"):
        param = _text(msg.param_id)
        mine = param.upper().startswith(BANDADA_PARAMS)
        return Verdict(
            Kind.SETTING,
            f"{name} {param}",
            report=mine,
            restore=mine and param.upper().startswith("FENCE_"),
        )
    if name in TRANSFER_STARTS:
        mt = int(getattr(msg, "mission_type", 0))
        store = {MISSION: "mission", FENCE: "fence", RALLY: "rally points"}.get(mt, "every store")
        what = f"{'upload' if name != 'MISSION_CLEAR_ALL' else 'clear'} of the {store}"
        if mt in (FENCE, RALLY):
            return Verdict(Kind.SETTING, what, mission_type=mt, report=True)
        return Verdict(Kind.FLIGHT, what, mission_type=mt, report=mt == ALL_TYPES)
    if name == "FILE_TRANSFER_PROTOCOL":
        payload = list(msg.payload)
        if len(payload) > 3 and payload[3] in FTP_READS:
            return Verdict(Kind.READ, name)
        return Verdict(Kind.SETTING, "FTP write", report=True, restore=True)
    if name in SETTING_MESSAGES:
        return Verdict(Kind.SETTING, name, report=name == "SET_HOME_POSITION")
    return Verdict(Kind.FLIGHT, name)


def _command(msg: MAVLinkMessage, view: NodeView) -> Verdict:
    cmd = int(msg.command)
    label = _command_name(cmd)
    if cmd in READ_COMMANDS:
        return Verdict(Kind.READ, label)
    if cmd == SET_MESSAGE_INTERVAL:
        return Verdict(Kind.LOCAL, label)
    if cmd == DO_SET_MODE:
        return _mode(label, int(msg.param2), view)
    if cmd in REPORTED_COMMANDS:
        return Verdict(Kind.SETTING, label, report=True, restore=REPORTED_COMMANDS[cmd])
    if cmd in SETTING_COMMANDS:
        return Verdict(Kind.SETTING, label)
    phase = COMMAND_PHASE.get(cmd, Phase.OPERATOR)
    if cmd == 208 and round(float(msg.param1)) == 2:  # DO_PARACHUTE release
        phase = Phase.PARACHUTE
    return Verdict(Kind.FLIGHT, label, phase=phase)


def _mode(label: str, number: int, view: NodeView) -> Verdict:
    name = mode_name(view.autopilot.vehicle_type, number)
    phase = (
        Phase.RETURNING if name in RETURN_MODES else Phase.LANDING if name in LAND_MODES else None
    )
    return Verdict(Kind.FLIGHT, f"{label} {name}", phase=phase or Phase.OPERATOR)


def _command_name(cmd: int) -> str:
    entry = mavlink.enums["MAV_CMD"].get(cmd)
    return entry.name.removeprefix("MAV_CMD_") if entry is not None else f"command {cmd}"


# ----------------------------------------------------------------------- sessions


@dataclass
class Session:
    session_id: int
    issuer_id: int
    read_only: bool
    heard: float  # its last announcement or frame
    framer: MavFramer = field(default_factory=MavFramer)
    client: tuple[int, int] | None = None  # the client's (sysid, compid), from its frames
    uploads: dict[int, float] = field(default_factory=dict)  # granted store -> until
    wishes: dict[str, float] = field(default_factory=dict)  # message -> Hz
    encoder: MavEncoder | None = None  # answers on the autopilot's behalf
    counts: Counter[str] = field(default_factory=Counter)  # frames dropped, by why
    noted: set[str] = field(default_factory=set)  # causes already logged
    told: dict[str, float] = field(default_factory=dict)  # refusal text -> when last said


@dataclass(frozen=True)
class _Pending:
    session_id: int  # 0: a radio session's
    verdict: Verdict
    msg_name: str
    command: int  # COMMAND_ACK's command for the answer (the message id for SET_MODE)
    on_mission: bool
    client: tuple[int, int]
    radio_issuer: int = 0  # a radio session's ground station


@dataclass
class RadioSession:
    issuer_id: int
    heard: float


@dataclass
class Passthrough:
    """The node's passthrough sessions (the module docstring)."""

    vehicle_id: int
    ids: itertools.count[int] = field(default_factory=lambda: itertools.count(1))
    timeout_s: float = TIMEOUT_S
    sessions: dict[int, Session] = field(default_factory=dict)
    counts: Counter[str] = field(default_factory=Counter)  # dropped and refused, by why
    _pending: dict[int, _Pending] = field(default_factory=dict)  # request id -> frame
    _wish: dict[str, float] = field(default_factory=dict)  # the last StreamWish
    radio: dict[int, RadioSession] = field(default_factory=dict)  # by ground station
    radio_timeout_s: float = RADIO_SESSION_S
    summary_period_s: float = SUMMARY_PERIOD_S
    _summary_at: float = float("-inf")
    _encoder: MavEncoder | None = None  # summaries and radio answers, the autopilot's ids

    # ------------------------------------------------------------------ sessions
    def on_session(self, msg: MavlinkSession, now: float) -> list[ModuleOutput]:
        """A session announced (opened, kept, or `closing`)."""
        if msg.vehicle_id != self.vehicle_id:
            return []
        s = self.sessions.get(msg.session_id)
        if msg.closing:
            return self._end(msg.session_id, "closed by the ground station", now) if s else []
        if s is not None:
            s.heard, s.read_only = now, msg.read_only
            return []
        self.sessions[msg.session_id] = Session(msg.session_id, msg.issuer_id, msg.read_only, now)
        mode = "read-only " if msg.read_only else ""
        text = f"{mode}passthrough session {msg.session_id} of ground station {msg.issuer_id}"
        return [Note(logging.INFO, f"{text} open"), self._sessions()]

    def on_timer(self, now: float, view: Callable[[], NodeView]) -> list[ModuleOutput]:
        """Sessions timed out, uploads over, the radio's summary (`view` asked then)."""
        out: list[ModuleOutput] = self._radio_timer(now, view) if self.radio else []
        for sid, s in list(self.sessions.items()):
            if now - s.heard >= self.timeout_s:
                out += self._end(sid, f"client silent for {self.timeout_s:g} s", now)
                continue
            for mt, until in list(s.uploads.items()):
                if now >= until:
                    out += self._upload_over(s, mt, now)
        return out

    def next_deadline(self) -> float | None:
        if not self.sessions and not self.radio:
            return None
        due = [s.heard + self.timeout_s for s in self.sessions.values()]
        due += [t for s in self.sessions.values() for t in s.uploads.values()]
        due += [r.heard + self.radio_timeout_s for r in self.radio.values()]
        if self.radio:
            due.append(self._summary_at)
        return min(due)

    def _end(self, sid: int, why: str, now: float) -> list[ModuleOutput]:
        s = self.sessions.pop(sid)
        out: list[ModuleOutput] = [Note(logging.INFO, f"passthrough session {sid} ended: {why}")]
        for mt in list(s.uploads):
            out += self._upload_over(s, mt, now)
        return [*out, self._sessions(), *self._wishes()]

    def _sessions(self) -> Sessions:
        return Sessions(tuple(sorted(self.sessions)))

    # ------------------------------------------------------------------ frames
    def on_frames(
        self, session_id: int, data: bytes, view: NodeView, now: float
    ) -> list[ModuleOutput]:
        """Frames from a session's client: relayed, ruled on, answered or dropped."""
        s = self.sessions.get(session_id)
        if s is None:
            self.counts["no_session"] += 1
            return []
        s.heard = now
        out: list[ModuleOutput] = []
        reads: list[bytes] = []
        for item in s.framer.feed(data):
            if isinstance(item, BadFrame):
                self._drop(s, "malformed")
                continue
            v = self._accepted(s, item, view)
            if v is None:
                continue
            raw = bytes(item.get_msgbuf())
            if v.kind == Kind.READ:
                reads.append(raw)
            elif v.kind == Kind.ITEM:
                if v.mission_type in s.uploads:
                    s.uploads[v.mission_type] = now + UPLOAD_IDLE_S
                    reads.append(raw)
                else:
                    self._drop(s, "item_outside_upload")
            elif v.kind == Kind.LOCAL:
                out += self._local(s, item, view)
            else:
                if reads:  # in order: what came before it goes first
                    out.append(ToAutopilot(b"".join(reads)))
                    reads = []
                out += self._rule(s, item, raw, v, view, now)
        if reads:
            out.append(ToAutopilot(b"".join(reads)))
        for why in sorted(set(s.counts) - s.noted):  # said once per session and cause
            s.noted.add(why)
            text = f"passthrough session {session_id}: dropping frames from its client ({why})"
            out.append(Note(logging.WARNING, text))
        return out

    def _accepted(self, s: Session, msg: MAVLinkMessage, view: NodeView) -> Verdict | None:
        """The frame's verdict, or None: dropped (counted)."""
        src = (int(msg.get_srcSystem()), int(msg.get_srcComponent()))
        if src == NODE_IDS:
            self._drop(s, "node_ids")  # the autopilot would answer the node, not the client
            return None
        target = getattr(msg, "target_system", None)
        sysid = view.autopilot.sysid
        if target is not None and int(target) != 0 and int(target) != sysid:
            self._drop(s, "foreign_system" if sysid else "no_autopilot_yet")
            return None
        s.client = src
        return classify(msg, view)

    def _drop(self, s: Session, why: str) -> None:
        s.counts[why] += 1
        self.counts[why] += 1

    # ------------------------------------------------------------------ ruling
    def _rule(
        self, s: Session, msg: MAVLinkMessage, raw: bytes, v: Verdict, view: NodeView, now: float
    ) -> list[ModuleOutput]:
        """A FLIGHT or SETTING frame: refused (read-only), answered (a mode it is in
        already), or to the arbiter as the operator's."""
        name = msg.get_type()
        command = int(getattr(msg, "command", 0)) if name.startswith("COMMAND_") else 0
        if name == "SET_MODE":
            command = mavlink.MAVLINK_MSG_ID_SET_MODE  # ArduPilot acks it with its id
        if s.read_only:
            self._drop(s, "refused_read_only")
            text = f"bandada read-only: {v.what} refused"
            return self._refuse(s, name, command, v, mavlink.MAV_RESULT_DENIED, text, view, now)
        ap = view.autopilot
        if command in (DO_SET_MODE, mavlink.MAVLINK_MSG_ID_SET_MODE) and ap.link_ok:
            number = int(msg.custom_mode) if name == "SET_MODE" else int(msg.param2)
            if number == ap.mode_number:  # nothing to change: no take-over for it
                return self._answer(s, view, self._ack(s, command, mavlink.MAV_RESULT_ACCEPTED))
        rid = next(self.ids)
        assert s.client is not None
        self._pending[rid] = _Pending(s.session_id, v, name, command, view.on_mission, s.client)
        if v.mission_type is not None and name != "MISSION_CLEAR_ALL":
            for mt in (FENCE, RALLY, MISSION) if v.mission_type == ALL_TYPES else (v.mission_type,):
                s.uploads[mt] = now + UPLOAD_IDLE_S  # its items follow (closed if refused)
        req_type = RelayCommand if v.kind == Kind.FLIGHT else RelaySetting
        who = f"ground station {s.issuer_id}: {v.what}"
        return [Submit(req_type(request_id=rid, data=raw, what=short_text(who)), Owner.OPERATOR)]

    def owns(self, request_id: int) -> bool:
        return request_id in self._pending

    def on_result(self, result: ApResult, view: NodeView, now: float) -> list[ModuleOutput]:
        """The arbiter's ruling on a session's frame (the link's answer when granted)."""
        p = self._pending.pop(result.request_id, None)
        if p is None:
            return []
        if p.radio_issuer:
            return self._radio_result(p, result, view, now)
        s = self.sessions.get(p.session_id)
        v, who = p.verdict, f"ground station {s.issuer_id}" if s else "a ground station"
        if not result.ok:
            self.counts["refused"] += 1
            if s is None:
                return []
            for mt in list(s.uploads):
                if v.mission_type in (mt, ALL_TYPES):
                    del s.uploads[mt]
            code = (
                mavlink.MAV_RESULT_TEMPORARILY_REJECTED
                if result.error == ApError.PREEMPTED
                else mavlink.MAV_RESULT_FAILED
            )
            text = f"bandada: {result.reason}: {v.what} refused"  # the why first: 50 characters
            out: list[ModuleOutput] = [Note(logging.INFO, f"passthrough {who}: {text}")]
            return out + self._refuse(s, p.msg_name, p.command, v, code, text, view, now)
        self.counts["granted"] += 1
        takes_over = v.kind == Kind.FLIGHT and p.on_mission
        level = logging.INFO if takes_over or v.report else logging.DEBUG  # sticks: 50 Hz
        out = [Note(level, f"passthrough {who}: {v.what} relayed")]
        if takes_over:
            # the operator flies the vehicle now: out of its fleet, as on `gcs cmd rtl`
            out.append(TakeOver(short_text(f"{who}: {v.what}"), v.phase))
            if v.phase != Phase.OPERATOR:  # the mission manager lands it for the operator
                out.append(Delegate(Owner.MISSION, Owner.OPERATOR))
        if v.report and (v.mission_type in (None, ALL_TYPES) or p.msg_name == "MISSION_CLEAR_ALL"):
            out += self._report(who, v, now)  # (an upload: once its items are in)
        return out

    def _report(self, who: str, v: Verdict, now: float) -> list[ModuleOutput]:
        """A setting bandada relies on, changed from outside: said, and checked."""
        then = "fence reloaded" if v.restore else "backstop checks it"
        text = short_text(f"{v.what} from {who}; {then}")
        alert = Alert(self.vehicle_id, max(0.0, now), Severity.WARNING, AlertCode.GENERIC, text)
        return [Publish(alert), Recheck(f"set by {who}", v.restore)]

    def _upload_over(self, s: Session, mt: int, now: float) -> list[ModuleOutput]:
        """A granted upload is over (no item for UPLOAD_IDLE_S): a fence or rally
        upload is reported and checked once it is done, not while its items come."""
        s.uploads.pop(mt, None)
        if mt in (FENCE, RALLY):
            store = "fence" if mt == FENCE else "rally points"
            v = Verdict(Kind.SETTING, f"{store} uploaded", report=True)
            return self._report(f"ground station {s.issuer_id}", v, now)
        return []

    # ------------------------------------------------------------------ the radio
    def on_radio(self, msg: MavlinkCommand, view: NodeView, now: float) -> list[ModuleOutput]:
        """A radio session's keep-alive (no frame) or command: ruled on as the node's
        own request of owner OPERATOR; anything but a command is refused."""
        if msg.target_id != self.vehicle_id:
            return []
        out: list[ModuleOutput] = []
        r = self.radio.get(msg.issuer_id)
        if r is None:
            r = self.radio[msg.issuer_id] = RadioSession(msg.issuer_id, now)
            self._summary_at = now  # the first summary at once
            text = f"radio passthrough session of ground station {msg.issuer_id} open"
            out.append(Note(logging.INFO, text))
        r.heard = now
        if not msg.frame:
            return out
        items = MavFramer().feed(msg.frame)
        if len(items) != 1 or isinstance(items[0], BadFrame):
            self.counts["malformed"] += 1
            return out
        m = items[0]
        target = getattr(m, "target_system", None)
        if target is not None and int(target) not in (0, view.autopilot.sysid):
            self.counts["foreign_system"] += 1
            return out
        name = m.get_type()
        client = (int(m.get_srcSystem()), int(m.get_srcComponent()))
        command = int(m.command) if name.startswith("COMMAND_") else mavlink.MAVLINK_MSG_ID_SET_MODE
        request = radio_request(m, view.autopilot) if name in RADIO_MESSAGES else None
        if request is None:
            self.counts["not_over_the_radio"] += 1
            text = f"bandada: not on the radio: {_label(m)}"
            code = mavlink.MAV_RESULT_UNSUPPORTED
            return out + self._radio_answer(msg.issuer_id, client, command, code, text, view)
        v = classify(m, view)
        ap = view.autopilot
        if isinstance(request, SetMode) and ap.link_ok and request.mode == ap.mode_name:
            ok = mavlink.MAV_RESULT_ACCEPTED
            return out + self._radio_answer(msg.issuer_id, client, command, ok, "", view)
        rid = next(self.ids)
        self._pending[rid] = _Pending(
            0, v, name, command, view.on_mission, client, radio_issuer=msg.issuer_id
        )
        req = msgspec.structs.replace(request, request_id=rid)
        return [*out, Submit(req, Owner.OPERATOR)]

    def _radio_result(
        self, p: _Pending, result: ApResult, view: NodeView, now: float
    ) -> list[ModuleOutput]:
        who, v = f"ground station {p.radio_issuer} (radio)", p.verdict
        if result.ok:
            code, text = mavlink.MAV_RESULT_ACCEPTED, ""
        elif result.error == ApError.PREEMPTED:
            code, text = mavlink.MAV_RESULT_TEMPORARILY_REJECTED, f"bandada: {result.reason}"
        else:
            code = result.mav_result if result.mav_result is not None else mavlink.MAV_RESULT_FAILED
            text = f"bandada: {result.reason}" if result.reason else ""
        out = self._radio_answer(p.radio_issuer, p.client, p.command, code, text, view)
        self.counts["granted" if result.ok else "refused"] += 1
        out.append(Note(logging.INFO, f"passthrough {who}: {v.what}: {result.reason or 'done'}"))
        if result.ok and v.kind == Kind.FLIGHT and p.on_mission:
            out.append(TakeOver(short_text(f"{who}: {v.what}"), v.phase))
            if v.phase != Phase.OPERATOR:
                out.append(Delegate(Owner.MISSION, Owner.OPERATOR))
        return out

    def _radio_answer(
        self,
        issuer: int,
        client: tuple[int, int],
        command: int,
        code: int,
        text: str,
        view: NodeView,
    ) -> list[ModuleOutput]:
        msgs = [mavlink.MAVLink_command_ack_message(command, code, 0, 0, client[0], client[1])]
        if text:
            msgs.append(
                mavlink.MAVLink_statustext_message(
                    mavlink.MAV_SEVERITY_WARNING, text[:50].encode("ascii", "replace")
                )
            )
        enc = self._encoder_for(view.autopilot)
        frames = b"".join(enc.encode(m) for m in msgs)
        return [Publish(MavlinkAnswer(self.vehicle_id, issuer, frames))]

    def _radio_timer(self, now: float, view: Callable[[], NodeView]) -> list[ModuleOutput]:
        out: list[ModuleOutput] = []
        for issuer, r in list(self.radio.items()):
            if now - r.heard >= self.radio_timeout_s:
                del self.radio[issuer]
                text = f"radio passthrough session of ground station {issuer} ended (silent)"
                out.append(Note(logging.INFO, text))
        if self.radio and now >= self._summary_at:
            self._summary_at = now + self.summary_period_s
            v = view()
            ap = v.autopilot
            if ap.sysid:  # an autopilot heard: there is something to sum up
                frame = self._encoder_for(ap).encode(high_latency2(ap, int(v.fsm_state)))
                out.append(Publish(MavlinkSummary(self.vehicle_id, frame)))
        return out

    def _encoder_for(self, ap: AutopilotState) -> MavEncoder:
        ids = (ap.sysid or self.vehicle_id % 256 or 1, ap.compid or 1)
        enc = self._encoder
        if enc is None or (enc.sysid, enc.compid) != ids:
            enc = self._encoder = MavEncoder(*ids)
        return enc

    # ------------------------------------------------------------------ local answers
    def _local(self, s: Session, msg: MAVLinkMessage, view: NodeView) -> list[ModuleOutput]:
        name = msg.get_type()
        if name == "REQUEST_DATA_STREAM":
            names = [n for g in _groups(int(msg.req_stream_id)) for n in STREAM_GROUPS[g]]
            rate = float(msg.req_message_rate) if int(msg.start_stop) else 0.0
            for n in names:
                _wish(s.wishes, n, rate)
            return self._wishes()
        if name.startswith("COMMAND_"):  # SET_MESSAGE_INTERVAL
            entry = mavlink.mavlink_map.get(int(msg.param1))
            interval_us = float(msg.param2)
            if entry is None:
                ack = self._ack(s, SET_MESSAGE_INTERVAL, mavlink.MAV_RESULT_DENIED)
                return self._answer(s, view, ack)
            rate = 1e6 / interval_us if interval_us > 0 else 0.0
            _wish(s.wishes, entry.msgname, rate)
            ack = self._ack(s, SET_MESSAGE_INTERVAL, mavlink.MAV_RESULT_ACCEPTED)
            return [*self._answer(s, view, ack), *self._wishes()]
        return []  # HEARTBEAT: the session is alive (the node's own keeps ArduPilot's failsafe)

    def _wishes(self) -> list[ModuleOutput]:
        """The sessions' stream wishes together, when they changed."""
        want: dict[str, float] = {}
        for s in self.sessions.values():
            for n, hz in s.wishes.items():
                want[n] = max(want.get(n, 0.0), hz)
        if want == self._wish:
            return []
        self._wish = want
        return [StreamWish(tuple(sorted(want.items())))]

    # ------------------------------------------------------------------ answers
    def _refuse(
        self,
        s: Session,
        name: str,
        command: int,
        v: Verdict,
        code: int,
        text: str,
        view: NodeView,
        now: float,
    ) -> list[ModuleOutput]:
        """Answered as the autopilot answers a refusal, and said in a STATUSTEXT (each
        text once in `TELL_AGAIN_S`)."""
        msgs: list[MAVLinkMessage] = []
        client = s.client or (0, 0)
        if command:
            msgs.append(self._ack(s, command, code))
        elif name in TRANSFER_STARTS:
            mt = v.mission_type if v.mission_type is not None else 0
            msgs.append(
                mavlink.MAVLink_mission_ack_message(
                    client[0], client[1], mavlink.MAV_MISSION_DENIED, mt
                )
            )
        last = s.told.get(text)
        if last is None or now - last >= TELL_AGAIN_S:  # sticks at 50 Hz: said once a while
            s.told[text] = now
            msgs.append(
                mavlink.MAVLink_statustext_message(
                    mavlink.MAV_SEVERITY_WARNING, text[:50].encode("ascii", "replace")
                )
            )
        return self._answer(s, view, *msgs) if msgs else []

    def _ack(self, s: Session, command: int, result: int) -> MAVLinkMessage:
        c = s.client or (0, 0)
        return mavlink.MAVLink_command_ack_message(command, result, 0, 0, c[0], c[1])

    def _answer(self, s: Session, view: NodeView, *msgs: MAVLinkMessage) -> list[ModuleOutput]:
        """Frames to the client from the autopilot's ids (the node speaks for it)."""
        ap = view.autopilot
        ids = (ap.sysid or self.vehicle_id % 256 or 1, ap.compid or 1)
        enc = s.encoder
        if enc is None or (enc.sysid, enc.compid) != ids:
            enc = s.encoder = MavEncoder(*ids)
        return [ToClient(s.session_id, b"".join(enc.encode(m) for m in msgs))]


def _groups(stream_id: int) -> tuple[int, ...]:
    if stream_id == 0:  # MAV_DATA_STREAM_ALL
        return tuple(STREAM_GROUPS)
    return (stream_id,) if stream_id in STREAM_GROUPS else ()


def _wish(wishes: dict[str, float], name: str, rate_hz: float) -> None:
    if rate_hz > 0:
        wishes[name] = min(rate_hz, MAX_WISH_HZ)
    else:
        wishes.pop(name, None)


# ----------------------------------------------------------------------- the radio's budget
RADIO_MESSAGES = frozenset({"COMMAND_LONG", "COMMAND_INT", "SET_MODE"})
FORCE_MAGIC = 21196  # COMPONENT_ARM_DISARM param2: force


def _label(msg: MAVLinkMessage) -> str:
    name = msg.get_type()
    return _command_name(int(msg.command)) if name.startswith("COMMAND_") else name


def radio_request(msg: MAVLinkMessage, ap: AutopilotState) -> ApRequest | None:
    """A radio session's command as the node's own request (None: not over the radio)."""
    if msg.get_type() == "SET_MODE":
        return _set_mode(int(msg.custom_mode), ap)
    cmd, p1, p2 = int(msg.command), float(msg.param1), float(msg.param2)
    if cmd == DO_SET_MODE:
        return _set_mode(int(p2), ap)
    if cmd == 400:  # COMPONENT_ARM_DISARM
        force = round(p2) == FORCE_MAGIC
        return Arm(force=force) if round(p1) == 1 else Disarm(force=force)
    if cmd == 20:
        return ReturnToLaunch()
    if cmd == 21:
        return Land()
    if cmd == 22:  # NAV_TAKEOFF: the altitude in param7 (COMMAND_INT: z)
        alt = float(msg.param7 if msg.get_type() == "COMMAND_LONG" else msg.z)
        return Takeoff(alt_rel_m=alt) if alt > 0 else None
    if cmd == 178 and p2 > 0:  # DO_CHANGE_SPEED: param1 0 airspeed, param2 m/s
        return ChangeSpeed(speed_m_s=p2, airspeed=round(p1) == 0)
    if cmd == 300:  # MISSION_START
        return StartMission(first_item=max(0, int(p1)))
    if cmd == 208 and round(p1) == 2:  # DO_PARACHUTE release
        return Parachute()
    return None


def _set_mode(number: int, ap: AutopilotState) -> SetMode | None:
    name = mode_name(ap.vehicle_type, number)
    return None if name.startswith("MODE(") else SetMode(mode=name)


def _clamp(x: float, lo: int, hi: int) -> int:
    return max(lo, min(hi, round(x))) if x == x else 0


def high_latency2(ap: AutopilotState, fsm_state: int = 0) -> MAVLinkMessage:
    """The vehicle in one HIGH_LATENCY2, as ArduPilot sends it on a high-latency link:
    `custom0` is 1 when armed (the message has no armed flag), `custom1` the node's
    state machine state (FsmState)."""
    failures = 0
    if ap.gps_fix < GpsFix.FIX_3D:
        failures |= mavlink.HL_FAILURE_FLAG_GPS
    if not ap.ekf_ok:
        failures |= mavlink.HL_FAILURE_FLAG_ESTIMATOR
    if not ap.link_ok:
        failures |= mavlink.HL_FAILURE_FLAG_OFFBOARD_LINK
    return mavlink.MAVLink_high_latency2_message(
        ap.boot_time_ms & 0xFFFFFFFF,
        ap.mav_type & 0xFF,
        MAV_AUTOPILOT_ARDUPILOTMEGA,
        ap.mode_number & 0xFFFF,
        _clamp((ap.lat_deg or 0.0) * 1e7, -900_000_000, 900_000_000),
        _clamp((ap.lon_deg or 0.0) * 1e7, -1_800_000_000, 1_800_000_000),
        _clamp(ap.alt_msl_m or 0.0, -32768, 32767),
        0,
        _clamp(ap.heading_deg / 2.0, 0, 179),
        0,
        0,
        _clamp(ap.throttle_pct, 0, 100),
        _clamp(ap.airspeed_m_s * 5.0, 0, 255),
        0,
        _clamp(ap.groundspeed_m_s * 5.0, 0, 255),
        0,
        0,
        0,
        0,
        0,
        _clamp(ap.climb_m_s * 10.0, -128, 127),
        _clamp(ap.battery_pct, -1, 100),
        ap.mission_current & 0xFFFF,
        failures,
        1 if ap.armed else 0,
        _clamp(fsm_state, -128, 127),
        0,
    )
