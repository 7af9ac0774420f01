"""Turns the MAVLink an ArduPilot autopilot sends into an `AutopilotState` snapshot and
`ApEvent`s, and detects link loss by deadline. Pure: messages and `now` in.

Which autopilot: the first HEARTBEAT from a real autopilot (autopilot != INVALID) that
matches the configured `target_sysid` / `target_compid` (either may be None = any) locks
the tracker to that (sysid, compid); everything else valid is counted as foreign and
dropped. Every accepted message is validated field by field (ranges, NaN, unknown
enums): a message that fails is dropped whole and counted in `bad_packets`, never
half-applied.

`HANDLERS` (telemetry -> handler), `PROTOCOL` (handed on to the command and mission
cores) and `IGNORED` (sent by ArduPilot, deliberately not used) together say what
happens to every message type; anything else is counted in `unhandled`.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from enum import Enum
from typing import Any

import msgspec

from swarm_proto import GeoPoint, GpsFix, VehicleType
from swarm_proto.ardupilot import mode_name, vehicle_type_from_mav_type

from .events import (
    ApEvent,
    ArmedChanged,
    AutopilotFound,
    AutopilotRebooted,
    EkfChanged,
    HomeChanged,
    HostStalled,
    LandedChanged,
    LinkLost,
    LinkRestored,
    MissionCurrentChanged,
    MissionItemReached,
    ModeChanged,
    StatusText,
)
from .framing import BadFrame, MAVLinkMessage
from .state import (
    EKF_ATTITUDE,
    EKF_CONST_POS_MODE,
    EKF_POS_HORIZ_ABS,
    EKF_UNINITIALIZED,
    EKF_VELOCITY_HORIZ,
    AdsbReport,
    AutopilotState,
)

MAV_AUTOPILOT_INVALID = 8
ADSB_VALID_POSITION = 1 | 2  # ADSB_FLAGS_VALID_COORDS | VALID_ALTITUDE
ADSB_VALID_VELOCITY = 4 | 8  # ADSB_FLAGS_VALID_HEADING | VALID_VELOCITY
TRAFFIC_KEEP_S = 20.0  # an aircraft not heard on ADS-B for this long leaves `traffic`
TRAFFIC_MAX = 32  # the nearest in time are kept beyond this many
MAV_MODE_FLAG_SAFETY_ARMED = 128
UINT16_MAX = 65535
_EARLIEST_GPS_UNIX_S = 1.42e9  # 2015: an older SYSTEM_TIME.time_unix_usec is not GPS time
_LATEST_UNIX_S = 4.0e9
_REBOOT_BACKSTEP_MS = 5000
MAV_STATE_STANDBY = 3  # HEARTBEAT system_status: BOOT (1) / CALIBRATING (2) until "ArduPilot Ready"
GPS_FIX_2D = 2
READY_TEXT = "ArduPilot Ready"
#: A link timer served this late (or a message read this much later than the autopilot's
#: own time since boot says it was sent) means the node stalled, not the link.
LATE_TOLERANCE_S = 0.25
#: After a late timer, bytes may be waiting to be read: the loss is decided this later.
DRAIN_S = 0.2


class Verdict(Enum):
    ACCEPTED = "accepted"  # from our autopilot, valid, applied (or handed on)
    FOREIGN = "foreign"  # another system or component: dropped
    INVALID = "invalid"  # from our autopilot but out of range / NaN / garbage: dropped
    UNHANDLED = "unhandled"  # from our autopilot, a type nobody here uses
    WAITING = "waiting"  # before the autopilot's first HEARTBEAT


class _Invalid(Exception):
    pass


Changes = dict[str, Any]


class StateTracker:
    def __init__(
        self,
        *,
        vehicle_type: VehicleType | None = None,
        target_sysid: int | None = None,
        target_compid: int | None = None,
        link_timeout_s: float = 0.9,
        heartbeat_timeout_s: float = 2.5,
    ) -> None:
        if not (link_timeout_s > 0 and heartbeat_timeout_s > 0):
            raise ValueError("link timeouts must be positive")
        self.heartbeat_timeout_s = heartbeat_timeout_s
        self._last_telemetry_s: float | None = None
        self.configured_type = vehicle_type
        self.target_sysid = target_sysid
        self.target_compid = target_compid
        self.link_timeout_s = link_timeout_s
        self._state = AutopilotState(
            vehicle_type=vehicle_type if vehicle_type is not None else VehicleType.OTHER
        )
        self._locked = False
        self._gps_offset_s: float | None = None  # GPS UNIX time minus time since boot
        self._text_chunks: dict[int, tuple[int, list[str]]] = {}
        # link loss judged from the autopilot's own time, apart from our stalls
        self._recheck_at: float | None = None  # a late timer: decide the loss then
        self._ap_boot_ms: int | None = None  # the latest time since boot received ...
        self._ap_rx_s = 0.0  # ... and when (our clock)
        self._boot_at_loss: int | None = None  # time since boot when the link was lost
        self._gap_pending = False  # restored by an untimed message: measure on the next
        self.unhandled = 0
        self.last_bad_reason = ""
        self.handlers: dict[str, Callable[[MAVLinkMessage, float], tuple[Changes, list[ApEvent]]]]
        self.handlers = {
            "HEARTBEAT": self._on_heartbeat,
            "GLOBAL_POSITION_INT": self._on_global_position_int,
            "ATTITUDE": self._on_attitude,
            "VFR_HUD": self._on_vfr_hud,
            "SYS_STATUS": self._on_sys_status,
            "BATTERY_STATUS": self._on_battery_status,
            "GPS_RAW_INT": self._on_gps_raw_int,
            "SYSTEM_TIME": self._on_system_time,
            "HOME_POSITION": self._on_home_position,
            "MISSION_CURRENT": self._on_mission_current,
            "MISSION_ITEM_REACHED": self._on_mission_item_reached,
            "STATUSTEXT": self._on_statustext,
            "EKF_STATUS_REPORT": self._on_ekf_status_report,
            "EXTENDED_SYS_STATE": self._on_extended_sys_state,
            "ADSB_VEHICLE": self._on_adsb_vehicle,
        }

    # ------------------------------------------------------------------ public

    @property
    def state(self) -> AutopilotState:
        return self._state

    @property
    def locked(self) -> bool:
        """Whether the autopilot's first HEARTBEAT has been seen."""
        return self._locked

    def vehicle_type(self) -> VehicleType:
        return self._state.vehicle_type

    def handle(self, msg: MAVLinkMessage | BadFrame, now: float) -> tuple[Verdict, list[ApEvent]]:
        if isinstance(msg, BadFrame):
            self._count_bad(f"{msg.n_bytes} bad bytes: {msg.reason}")
            return Verdict.INVALID, []
        mtype = msg.get_type()
        src = (msg.get_srcSystem(), msg.get_srcComponent())
        was_locked = self._locked
        if not was_locked:
            if mtype != "HEARTBEAT" or not self._is_target_heartbeat(msg, src):
                return (
                    Verdict.FOREIGN if self._is_foreign_before_lock(src) else Verdict.WAITING
                ), []
        elif src != (self._state.sysid, self._state.compid) and not (
            mtype == "ADSB_VEHICLE" and src[0] == self._state.sysid  # its ADS-B receiver
        ):
            self._state = msgspec.structs.replace(
                self._state, foreign_packets=self._state.foreign_packets + 1
            )
            return Verdict.FOREIGN, []
        handler = self.handlers.get(mtype)
        events: list[ApEvent] = []
        if handler is not None:
            try:
                changes, events = handler(msg, now)
            except _Invalid as exc:
                self._count_bad(f"{mtype}: {exc}")
                return Verdict.INVALID, []
            except (TypeError, ValueError, AttributeError, OverflowError) as exc:
                self._count_bad(f"{mtype}: {type(exc).__name__}")
                return Verdict.INVALID, []
            verdict = Verdict.ACCEPTED
        elif mtype in PROTOCOL:
            changes, verdict = {}, Verdict.ACCEPTED
        else:
            changes = {}
            verdict = Verdict.ACCEPTED if mtype in IGNORED else Verdict.UNHANDLED
            if verdict is Verdict.UNHANDLED:
                self.unhandled += 1
        changes["last_message_s"] = now
        self._recheck_at = None
        if mtype != "HEARTBEAT":
            self._last_telemetry_s = now
        if was_locked and not self._state.link_ok:
            changes["link_ok"] = True
            last = self._state.last_message_s
            gap = self._autopilot_gap()
            self._gap_pending = gap < 0.0
            if gap >= 0.0:
                changes["link_gap_s"] = gap
            events.insert(
                0,
                LinkRestored(time_s=now, down_s=now - last if last else 0.0, autopilot_gap_s=gap),
            )
        elif self._gap_pending and "boot_time_ms" in changes:
            gap = self._autopilot_gap()
            if gap >= 0.0:
                self._gap_pending = False
                changes["link_gap_s"] = gap
        self._state = msgspec.structs.replace(self._state, **changes)
        return verdict, events

    def _autopilot_gap(self) -> float:
        """The last link loss in the autopilot's own time: from its time since boot when
        the link was lost to the latest one received (-1: not known yet)."""
        if self._boot_at_loss is None or self._ap_boot_ms is None:
            return -1.0
        if self._ap_boot_ms == self._boot_at_loss:
            return -1.0  # no timed message since the loss yet
        return max(0.0, (self._ap_boot_ms - self._boot_at_loss) / 1000.0)

    def count_invalid(self, reason: str) -> None:
        """Another core rejected a message from our autopilot (e.g. a bad MISSION_ACK)."""
        self._count_bad(reason)

    def set_figures(self, **figures: float | None) -> None:
        """The autopilot's own figures, read from its parameters (the link's FIGURES)."""
        self._state = msgspec.structs.replace(self._state, **figures)

    def set_mission_count(self, count: int) -> None:
        """After a successful mission upload or download."""
        self._state = msgspec.structs.replace(self._state, mission_count=count)

    def link_timeout(self) -> float:
        """`link_timeout_s` while telemetry flows; while only HEARTBEATs come (1 Hz,
        e.g. before the requested streams start), `heartbeat_timeout_s`, so the link
        does not flap between HEARTBEATs."""
        last, fast = self._state.last_message_s, self._last_telemetry_s
        if last is not None and fast is not None and last - fast <= self.link_timeout_s:
            return self.link_timeout_s
        return max(self.link_timeout_s, self.heartbeat_timeout_s)

    def next_deadline(self) -> float | None:
        if not self._state.link_ok or self._state.last_message_s is None:
            return None
        due = self._state.last_message_s + self.link_timeout()
        return due if self._recheck_at is None else max(due, self._recheck_at)

    def on_timer(self, now: float) -> list[ApEvent]:
        """Link loss: no valid message for the link timeout. A timer served late (the
        node stalled: its loop did not run, a loaded host) does not decide it: what the
        autopilot sent meanwhile may still be waiting to be read, so the loss is decided
        `DRAIN_S` later, if nothing came (the stall is counted apart, `HostStalled`)."""
        deadline = self.next_deadline()
        if deadline is None or now < deadline:
            return []
        if self._recheck_at is None and now - deadline > LATE_TOLERANCE_S:
            stall = now - deadline
            self._recheck_at = now + DRAIN_S
            self._state = msgspec.structs.replace(
                self._state, host_stalls=self._state.host_stalls + 1, host_stall_s=stall
            )
            return [HostStalled(time_s=now, stall_s=stall)]
        self._recheck_at = None
        last = self._state.last_message_s or now
        self._boot_at_loss = self._ap_boot_ms
        self._state = msgspec.structs.replace(
            self._state, link_ok=False, link_losses=self._state.link_losses + 1
        )
        return [LinkLost(time_s=now, silent_s=now - last)]

    # ------------------------------------------------------------------ helpers

    def _count_bad(self, reason: str) -> None:
        self.last_bad_reason = reason
        self._state = msgspec.structs.replace(self._state, bad_packets=self._state.bad_packets + 1)

    def _is_target_heartbeat(self, msg: MAVLinkMessage, src: tuple[int, int]) -> bool:
        if msg.autopilot == MAV_AUTOPILOT_INVALID or src[0] == 0:
            return False
        if self.target_sysid is not None and src[0] != self.target_sysid:
            return False
        return self.target_compid is None or src[1] == self.target_compid

    def _is_foreign_before_lock(self, src: tuple[int, int]) -> bool:
        return self.target_sysid is not None and src[0] != self.target_sysid

    def _note_boot_time(self, boot_ms: int, now: float, changes: Changes) -> list[ApEvent]:
        if boot_ms < 0 or boot_ms > 2**32 - 1:
            raise _Invalid(f"time_boot_ms {boot_ms}")
        events: list[ApEvent] = []
        if boot_ms + _REBOOT_BACKSTEP_MS < self._state.boot_time_ms:
            self._gps_offset_s = None
            changes["position_time_unix_s"] = None
            # a rebooted autopilot boots again and has no fix yet
            changes.update(
                autopilot_ready=False, position_trusted=False, reboots=self._state.reboots + 1
            )
            events.append(AutopilotRebooted(time_s=now, boot_time_ms=boot_ms))
            self._ap_boot_ms = None
            self._boot_at_loss = None
        prev = self._ap_boot_ms
        if prev is not None and boot_ms > prev and self._state.link_ok:
            # read later than the autopilot's own clock says it was sent: a burst of what
            # waited in the socket while this node was stalled (its stall, not the link's;
            # a link already judged lost on time was silent: an autopilot that paused,
            # SITL stopped, has a paused clock too)
            late = (now - self._ap_rx_s) - (boot_ms - prev) / 1000.0
            if late > LATE_TOLERANCE_S:
                changes.update(host_stalls=self._state.host_stalls + 1, host_stall_s=late)
                events.append(HostStalled(time_s=now, stall_s=late))
        if prev is None or boot_ms > prev:
            self._ap_boot_ms, self._ap_rx_s = boot_ms, now
        changes["boot_time_ms"] = boot_ms
        return events

    # ------------------------------------------------------------------ handlers

    def _on_heartbeat(self, msg: MAVLinkMessage, now: float) -> tuple[Changes, list[ApEvent]]:
        custom_mode = int(msg.custom_mode)
        if not 0 <= custom_mode <= 255:
            raise _Invalid(f"custom_mode {custom_mode} is no ArduPilot mode")
        if not 0 <= int(msg.system_status) <= 8:
            raise _Invalid(f"system_status {msg.system_status}")
        if msg.autopilot == MAV_AUTOPILOT_INVALID:
            raise _Invalid("autopilot INVALID from the autopilot's own id")
        s = self._state
        events: list[ApEvent] = []
        changes: Changes = {}
        vtype = self.configured_type
        if vtype is None:
            vtype = vehicle_type_from_mav_type(int(msg.type))
        if not self._locked:
            self._locked = True
            changes.update(sysid=msg.get_srcSystem(), compid=msg.get_srcComponent(), link_ok=True)
            events.append(
                AutopilotFound(
                    time_s=now,
                    sysid=msg.get_srcSystem(),
                    compid=msg.get_srcComponent(),
                    mav_type=int(msg.type),
                    vehicle_type=vtype,
                )
            )
        name = mode_name(vtype, custom_mode)
        armed = bool(msg.base_mode & MAV_MODE_FLAG_SAFETY_ARMED)
        if name != s.mode_name or custom_mode != s.mode_number:
            events.append(
                ModeChanged(time_s=now, old_mode=s.mode_name, mode=name, mode_number=custom_mode)
            )
        if armed != s.armed:
            events.append(ArmedChanged(time_s=now, armed=armed))
        changes.update(
            vehicle_type=vtype,
            mav_type=int(msg.type),
            mode_number=custom_mode,
            mode_name=name,
            armed=armed,
            system_status=int(msg.system_status),
            last_heartbeat_s=now,
            # real ArduPilot refuses uploads until booted: BOOT / CALIBRATING before
            # "ArduPilot Ready", STANDBY or later after it
            autopilot_ready=int(msg.system_status) >= MAV_STATE_STANDBY,
        )
        return changes, events

    def _on_global_position_int(
        self, msg: MAVLinkMessage, now: float
    ) -> tuple[Changes, list[ApEvent]]:
        lat, lon = int(msg.lat), int(msg.lon)
        if not (-900_000_000 <= lat <= 900_000_000 and -1_800_000_000 <= lon <= 1_800_000_000):
            raise _Invalid(f"position {lat}, {lon} out of range")
        alt_m, rel_m = msg.alt / 1000.0, msg.relative_alt / 1000.0
        if not (-2000.0 <= alt_m <= 50_000.0 and -50_000.0 <= rel_m <= 50_000.0):
            raise _Invalid(f"altitude {alt_m} / {rel_m} m out of range")
        changes: Changes = {
            "vel_north_m_s": msg.vx / 100.0,
            "vel_east_m_s": msg.vy / 100.0,
            "vel_down_m_s": msg.vz / 100.0,
        }
        if msg.hdg != UINT16_MAX:
            if not 0 <= msg.hdg <= 36000:
                raise _Invalid(f"hdg {msg.hdg}")
            changes["heading_deg"] = (msg.hdg / 100.0) % 360.0
        events = self._note_boot_time(int(msg.time_boot_ms), now, changes)
        trusted = changes.get("position_trusted", self._state.position_trusted)
        if (lat == 0 and lon == 0) or not trusted:
            # ArduPilot sends zeros, or a drifting estimate near (0, 0) (0.0003, 0.00002:
            # recorded, fix NO_GPS, EKF uninitialised), until it has a position: "no
            # position" until a 2-D fix or an EKF absolute position was seen
            changes.update(lat_deg=None, lon_deg=None, alt_msl_m=None, alt_rel_m=None)
        else:
            changes.update(lat_deg=lat / 1e7, lon_deg=lon / 1e7, alt_msl_m=alt_m, alt_rel_m=rel_m)
            if self._gps_offset_s is not None:
                changes["position_time_unix_s"] = self._gps_offset_s + msg.time_boot_ms / 1000.0
        return changes, events

    def _on_adsb_vehicle(self, msg: MAVLinkMessage, now: float) -> tuple[Changes, list[ApEvent]]:
        """Traffic for collision avoidance: the latest report per ICAO address, those
        not heard for TRAFFIC_KEEP_S dropped (a report without a valid position is
        invalid input)."""
        try:
            report = parse_adsb(msg.to_dict(), received_s=now)
        except ValueError as exc:
            raise _Invalid(str(exc)) from exc
        keep = {
            t.icao_address: t
            for t in self._state.traffic
            if now - t.time_s <= TRAFFIC_KEEP_S and t.icao_address != report.icao_address
        }
        keep[report.icao_address] = report
        newest = sorted(keep.values(), key=lambda t: -t.time_s)[:TRAFFIC_MAX]
        return {"traffic": tuple(sorted(newest, key=lambda t: t.icao_address))}, []

    def _on_attitude(self, msg: MAVLinkMessage, now: float) -> tuple[Changes, list[ApEvent]]:
        roll, pitch, yaw = float(msg.roll), float(msg.pitch), float(msg.yaw)
        for name, v in (("roll", roll), ("pitch", pitch), ("yaw", yaw)):
            if not math.isfinite(v) or abs(v) > 2 * math.pi + 1e-3:
                raise _Invalid(f"{name} {v}")
        changes: Changes = {
            "roll_deg": math.degrees(roll),
            "pitch_deg": math.degrees(pitch),
        }
        events = self._note_boot_time(int(msg.time_boot_ms), now, changes)
        return changes, events

    def _on_vfr_hud(self, msg: MAVLinkMessage, now: float) -> tuple[Changes, list[ApEvent]]:
        air, ground, climb = float(msg.airspeed), float(msg.groundspeed), float(msg.climb)
        for name, v, lo, hi in (
            ("airspeed", air, -5.0, 400.0),
            ("groundspeed", ground, -5.0, 400.0),
            ("climb", climb, -400.0, 400.0),
        ):
            if not (math.isfinite(v) and lo <= v <= hi):
                raise _Invalid(f"{name} {v}")
        if not 0 <= int(msg.throttle) <= 200:
            raise _Invalid(f"throttle {msg.throttle}")
        return {
            "airspeed_m_s": max(0.0, air),
            "groundspeed_m_s": max(0.0, ground),
            "climb_m_s": climb,
            "throttle_pct": int(msg.throttle),
        }, []

    def _on_sys_status(self, msg: MAVLinkMessage, now: float) -> tuple[Changes, list[ApEvent]]:
        remaining = int(msg.battery_remaining)
        if not -1 <= remaining <= 100:
            raise _Invalid(f"battery_remaining {remaining}")
        changes: Changes = {
            "battery_pct": remaining,
            "sensors_present": int(msg.onboard_control_sensors_present),
            "sensors_enabled": int(msg.onboard_control_sensors_enabled),
            "sensors_health": int(msg.onboard_control_sensors_health),
        }
        if msg.voltage_battery != UINT16_MAX:
            changes["battery_v"] = msg.voltage_battery / 1000.0
        return changes, []

    def _on_battery_status(self, msg: MAVLinkMessage, now: float) -> tuple[Changes, list[ApEvent]]:
        if msg.id != 0:  # only the primary battery
            return {}, []
        remaining = int(msg.battery_remaining)
        if not -1 <= remaining <= 100:
            raise _Invalid(f"battery_remaining {remaining}")
        cells = [v for v in msg.voltages if v != UINT16_MAX]
        cells += [v for v in getattr(msg, "voltages_ext", ()) or () if v not in (0, UINT16_MAX)]
        changes: Changes = {"battery_pct": remaining}
        if cells:
            changes["battery_v"] = sum(cells) / 1000.0
        return changes, []

    def _on_gps_raw_int(self, msg: MAVLinkMessage, now: float) -> tuple[Changes, list[ApEvent]]:
        fix = int(msg.fix_type)
        if not 0 <= fix <= 8:
            raise _Invalid(f"fix_type {fix}")
        sats = int(msg.satellites_visible)
        changes: Changes = {
            "gps_fix": GpsFix(fix) if fix <= 7 else GpsFix.FIX_3D,  # 8 = PPP
            "gps_sats": 0 if sats == 255 else sats,
        }
        if fix >= GPS_FIX_2D:
            changes["position_trusted"] = True
        return changes, []

    def _on_system_time(self, msg: MAVLinkMessage, now: float) -> tuple[Changes, list[ApEvent]]:
        changes: Changes = {}
        events = self._note_boot_time(int(msg.time_boot_ms), now, changes)
        unix_s = msg.time_unix_usec / 1e6
        if msg.time_unix_usec == 0:
            return changes, events
        if not _EARLIEST_GPS_UNIX_S <= unix_s <= _LATEST_UNIX_S:
            raise _Invalid(f"time_unix_usec {msg.time_unix_usec}")
        self._gps_offset_s = unix_s - msg.time_boot_ms / 1000.0
        changes["gps_time_unix_s"] = unix_s
        return changes, events

    def _on_home_position(self, msg: MAVLinkMessage, now: float) -> tuple[Changes, list[ApEvent]]:
        lat, lon, alt = int(msg.latitude), int(msg.longitude), msg.altitude / 1000.0
        if not (-900_000_000 <= lat <= 900_000_000 and -1_800_000_000 <= lon <= 1_800_000_000):
            raise _Invalid(f"home {lat}, {lon} out of range")
        if not -1000.0 <= alt <= 8000.0:
            raise _Invalid(f"home altitude {alt}")
        if lat == 0 and lon == 0:
            return {}, []
        home = GeoPoint(lat / 1e7, lon / 1e7, alt)
        if home == self._state.home:
            return {}, []
        return {"home": home}, [HomeChanged(time_s=now, home=home)]

    def _on_mission_current(self, msg: MAVLinkMessage, now: float) -> tuple[Changes, list[ApEvent]]:
        seq = int(msg.seq)
        total = int(getattr(msg, "total", 0))
        changes: Changes = {"mission_current": seq}
        if total == UINT16_MAX:
            changes["mission_count"] = 0
        elif total > 0:
            # seq may exceed total: a mission uploaded in AUTO with fewer items keeps the
            # old current item (recorded: mission-start-in-auto, seq 5 of total 3)
            changes["mission_count"] = total + 1  # ArduPilot's total excludes home (item 0)
        mission_state = int(getattr(msg, "mission_state", 0))
        if not 0 <= mission_state <= 5:  # MISSION_STATE
            raise _Invalid(f"mission_state {mission_state}")
        changes["mission_state"] = mission_state
        events: list[ApEvent] = []
        if seq != self._state.mission_current:
            events.append(MissionCurrentChanged(time_s=now, seq=seq))
        return changes, events

    def _on_mission_item_reached(
        self, msg: MAVLinkMessage, now: float
    ) -> tuple[Changes, list[ApEvent]]:
        seq = int(msg.seq)
        return {"mission_reached": seq}, [MissionItemReached(time_s=now, seq=seq)]

    def _on_statustext(self, msg: MAVLinkMessage, now: float) -> tuple[Changes, list[ApEvent]]:
        severity = int(msg.severity)
        if not 0 <= severity <= 7:
            raise _Invalid(f"severity {severity}")
        text = msg.text
        if isinstance(text, bytes | bytearray):
            text = text.decode("utf-8", "replace")
        text = "".join(ch if ch.isprintable() else "?" for ch in str(text).rstrip("\x00"))
        chunk_id = int(getattr(msg, "id", 0))
        if chunk_id == 0:
            ready: Changes = {"autopilot_ready": True} if text == READY_TEXT else {}
            return ready, [StatusText(time_s=now, severity=severity, text=text)]
        _, parts = self._text_chunks.setdefault(chunk_id, (severity, []))
        parts.append(text)
        if len(text) >= 50 and len(parts) < 8:  # more chunks follow
            return {}, []
        del self._text_chunks[chunk_id]
        return {}, [StatusText(time_s=now, severity=severity, text="".join(parts))]

    def _on_ekf_status_report(
        self, msg: MAVLinkMessage, now: float
    ) -> tuple[Changes, list[ApEvent]]:
        flags = int(msg.flags)
        for name in ("velocity_variance", "pos_horiz_variance", "pos_vert_variance"):
            v = float(getattr(msg, name))
            if not math.isfinite(v) or v < 0:
                raise _Invalid(f"{name} {v}")
        need = EKF_ATTITUDE | EKF_VELOCITY_HORIZ | EKF_POS_HORIZ_ABS
        bad = flags & (EKF_CONST_POS_MODE | EKF_UNINITIALIZED)
        ok = (flags & need) == need and not bad
        events: list[ApEvent] = []
        if ok != self._state.ekf_ok:
            events.append(EkfChanged(time_s=now, ok=ok, flags=flags))
        changes: Changes = {"ekf_ok": ok, "ekf_flags": flags}
        if flags & EKF_POS_HORIZ_ABS and not bad:
            changes["position_trusted"] = True
        return changes, events

    def _on_extended_sys_state(
        self, msg: MAVLinkMessage, now: float
    ) -> tuple[Changes, list[ApEvent]]:
        landed_state = int(msg.landed_state)
        if not 0 <= landed_state <= 4:
            raise _Invalid(f"landed_state {landed_state}")
        landed = None if landed_state == 0 else landed_state == 1
        events: list[ApEvent] = []
        if landed is not None and landed != self._state.landed:
            events.append(LandedChanged(time_s=now, landed=landed))
        return {"landed": landed}, events


#: Telemetry the tracker turns into state (the keys of StateTracker.handlers).
HANDLED: tuple[str, ...] = (
    "HEARTBEAT",
    "GLOBAL_POSITION_INT",
    "ATTITUDE",
    "VFR_HUD",
    "SYS_STATUS",
    "BATTERY_STATUS",
    "GPS_RAW_INT",
    "SYSTEM_TIME",
    "HOME_POSITION",
    "MISSION_CURRENT",
    "MISSION_ITEM_REACHED",
    "STATUSTEXT",
    "EKF_STATUS_REPORT",
    "EXTENDED_SYS_STATE",
    "ADSB_VEHICLE",
)

#: Handed on to the command and mission cores (after the source check).
PROTOCOL: frozenset[str] = frozenset(
    {
        "COMMAND_ACK",
        "MISSION_REQUEST",
        "MISSION_REQUEST_INT",
        "MISSION_ACK",
        "MISSION_COUNT",
        "MISSION_ITEM",
        "MISSION_ITEM_INT",
        "PARAM_VALUE",
    }
)


#: Sent by ArduPilot (default streams of SITL and real boards) and deliberately unused.
def parse_adsb(report: Mapping[str, Any], *, received_s: float) -> AdsbReport:
    """An ADSB_VEHICLE's fields (pymavlink `to_dict()`): `lat`/`lon` degE7, `altitude`
    mm MSL, `heading` cdeg, `hor_velocity` and `ver_velocity` cm/s (up positive),
    `flags`, `ICAO_address`, `tslc` s, `callsign`. Position and altitude must be
    flagged valid; a velocity not flagged valid counts as zero (avoidance widens a
    report's protection volume by its age anyway). Raises ValueError naming what is
    wrong."""

    def num(name: str, lo: float, hi: float) -> float:
        v = report.get(name)
        if isinstance(v, bool) or not isinstance(v, int | float):
            raise ValueError(f"ADS-B {name} must be a number, got {v!r}")
        if not (math.isfinite(v) and lo <= v <= hi):
            raise ValueError(f"ADS-B {name} = {v!r} is not in [{lo}, {hi}]")
        return float(v)

    flags = int(num("flags", 0, 0xFFFF))
    if flags & ADSB_VALID_POSITION != ADSB_VALID_POSITION:
        raise ValueError(f"ADS-B report without a valid position and altitude ({flags:#06x})")
    lat = num("lat", -90e7, 90e7) / 1e7
    lon = num("lon", -180e7, 180e7) / 1e7
    alt = num("altitude", -1_000_000, 50_000_000) / 1000.0
    vn = ve = vd = 0.0
    if flags & ADSB_VALID_VELOCITY == ADSB_VALID_VELOCITY:  # heading and velocity
        course = math.radians(num("heading", 0, 35_999) / 100.0)
        speed = num("hor_velocity", 0, 65_534) / 100.0
        vn, ve = speed * math.cos(course), speed * math.sin(course)
        vd = -num("ver_velocity", -32_767, 32_767) / 100.0
    icao = int(num("ICAO_address", 0, 0xFFFFFF))
    age = num("tslc", 0, 255)
    if not math.isfinite(received_s):
        raise ValueError("received_s must be finite")
    callsign = report.get("callsign", "")
    if isinstance(callsign, bytes):
        callsign = callsign.decode("ascii", "replace")
    callsign = str(callsign).strip("\x00 ")[:9]
    return AdsbReport(icao, lat, lon, alt, vn, ve, vd, received_s - age, callsign)


IGNORED: frozenset[str] = frozenset(
    {
        "AHRS",
        "AHRS2",
        "AHRS3",
        "AIRSPEED",
        "AOA_SSA",
        "ATTITUDE_QUATERNION",
        "AUTOPILOT_VERSION",
        "BATTERY2",
        "CAMERA_FEEDBACK",
        "DISTANCE_SENSOR",
        "ESC_TELEMETRY_1_TO_4",
        "ESC_TELEMETRY_5_TO_8",
        "FENCE_STATUS",
        "GIMBAL_DEVICE_ATTITUDE_STATUS",
        "GPS2_RAW",
        "GPS_GLOBAL_ORIGIN",
        "GPS_RTK",
        "HWSTATUS",
        "LOCAL_POSITION_NED",
        "MAG_CAL_PROGRESS",
        "MAG_CAL_REPORT",
        "MCU_STATUS",
        "MEMINFO",
        "MOUNT_STATUS",
        "NAV_CONTROLLER_OUTPUT",
        "PID_TUNING",
        "POSITION_TARGET_GLOBAL_INT",
        "POSITION_TARGET_LOCAL_NED",
        "POWER_STATUS",
        "RANGEFINDER",
        "RAW_IMU",
        "RC_CHANNELS",
        "RC_CHANNELS_RAW",
        "RPM",
        "SCALED_IMU",
        "SCALED_IMU2",
        "SCALED_IMU3",
        "SCALED_PRESSURE",
        "SCALED_PRESSURE2",
        "SCALED_PRESSURE3",
        "SENSOR_OFFSETS",
        "SERVO_OUTPUT_RAW",
        "SIMSTATE",
        "SIM_STATE",
        "TERRAIN_REPORT",
        "TERRAIN_REQUEST",
        "TIMESYNC",
        "VIBRATION",
        "WIND",
    }
)
