"""`SimAutopilot`: ArduPilot's MAVLink behaviour for one simulated vehicle, as a sans-I/O
object. Decoded MAVLink messages and `now` go in, MAVLink messages to send come out:

    ap = SimAutopilot(default_airframe("copter"), Home(37.4112, -5.9889, 10.0, 90.0), now)
    out = ap.handle(msg, now)        # a decoded pymavlink message from a client
    out += ap.on_timer(now)          # telemetry, protocol timeouts, boot events
    wake_at = ap.next_deadline()     # when on_timer wants to run next

It emulates the subset of ArduPlane (incl. QuadPlane), ArduCopter and ArduRover that a
companion computer uses: modes with ArduPilot's numbers, arming checks, guided control,
take-off, RTL, landing, parachute, the mission/fence/rally protocol, AUTO missions,
telemetry streams with SET_MESSAGE_INTERVAL / REQUEST_DATA_STREAM, parameters, and the
STATUSTEXT wording of the recorded SITL sorties. See docs/simulator.md.

Errors by blame: a peer's bad message is counted in `counters` and dropped; misuse of
this API (e.g. time going backwards) raises.
"""

from __future__ import annotations

import bisect
import math
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field
from enum import IntEnum
from typing import Any

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from . import streams as S
from . import telemetry
from .airframes import AirframeParams, VehicleModel
from .battery import Battery
from .firmware import (
    ARM_TEXT,
    BOOT_MODE,
    BOOT_TEXTS,
    DISARM_TEXT,
    EKF_GPS_TEXTS,
    EKF_ORIGIN_TEXTS,
    FIRMWARE_OF,
    GPS_DETECTED_TEXTS,
    INITIAL_MODE,
    MAV_TYPE_OF,
    MISSION_CMD_NAMES,
    MODES,
    SEV_CRITICAL,
    SEV_INFO,
    SEV_NOTICE,
    SEV_WARNING,
    Behaviour,
    Firmware,
    ModeSpec,
    base_mode,
    mode_number,
)
from .geo import LocalFrame, point_in_polygon, wrap_360
from .kinematics import Body, EventKind, Guide, ModelEvent, Target, VtolState, make_model
from .mission import (
    FENCE,
    FRAME_ABSOLUTE,
    GLOBAL_FRAMES,
    MISSION,
    RALLY,
    ItemTransfer,
    MissionItem,
    Peer,
    validate_item,
)
from .navigation import (
    FlyTo,
    Hold,
    Idle,
    Land,
    Loiter,
    NavTask,
    Parachute,
    Sequence,
    Takeoff,
)

# MAV_RESULT
ACCEPTED, TEMPORARILY_REJECTED, DENIED, UNSUPPORTED, FAILED = 0, 1, 2, 3, 4

ARM_FORCE_MAGIC = 2989.0
DISARM_FORCE_MAGIC = 21196.0
MAV_MODE_FLAG_CUSTOM_MODE_ENABLED = 1
MAV_MODE_FLAG_DECODE_POSITION_SAFETY = 128
MAV_DO_REPOSITION_FLAGS_CHANGE_MODE = 1
MSG_ID_SET_MODE = 11
PREARM_DISPLAY_PERIOD_S = 30.0  # AP_Arming: failing pre-arm checks are repeated this often
COPTER_LAND_SETTLE_S = 1.0  # touchdown -> land complete (copter land detector)
PLANE_LAND_SETTLE_S = 5.0  # touchdown -> "Land complete" (recorded QuadPlane ~6 s)
RTL_LOITER_TIME_S = 5.0  # RTL_LOIT_TIME
GUIDED_VELOCITY_TIMEOUT_S = 3.0  # GUID_TIMEOUT
CRASH_IMPACT_M_S = 4.0
MAX_ALT_M = 50_000.0  # altitudes beyond this in a command are refused as bad input

# commands and messages ArduPilot handles without doing anything the simulator models
_ACCEPTED_NOOP_COMMANDS = {115, 183, 184, 181, 182, 201, 195, 197, 203, 206, 2000, 2001, 2500, 2501}


class Purpose(IntEnum):
    """Why the current navigation task runs (decides what happens when it completes)."""

    MODE = 0
    MISSION = 1
    GUIDED_GOTO = 2
    GUIDED_TAKEOFF = 3
    GUIDED_VELOCITY = 4


@dataclass(frozen=True)
class Home:
    """Boot position: latitude, longitude (deg), altitude above sea level (m), heading."""

    lat_deg: float
    lon_deg: float
    alt_m: float
    heading_deg: float = 0.0

    @classmethod
    def parse(cls, text: str) -> Home:
        """ "LAT,LON,ALT,HDG" (as SITL's --home); ALT and HDG optional."""
        parts = [p.strip() for p in text.split(",")]
        if not 2 <= len(parts) <= 4:
            raise ValueError(f"home must be LAT,LON[,ALT[,HDG]], got {text!r}")
        vals = [float(p) for p in parts] + [0.0] * (4 - len(parts))
        home = cls(vals[0], vals[1], vals[2], vals[3])
        home.check()
        return home

    def check(self) -> None:
        if not (-90 <= self.lat_deg <= 90 and -180 <= self.lon_deg <= 180):
            raise ValueError(f"home out of range: {self}")
        if not all(
            math.isfinite(v) for v in (self.lat_deg, self.lon_deg, self.alt_m, self.heading_deg)
        ):
            raise ValueError(f"home not finite: {self}")


# The reference SITL home of the recordings
SITL_HOME = Home(37.4112, -5.9889, 10.0, 90.0)


@dataclass(frozen=True)
class StartupTimes:
    """Seconds after boot (sim time) at which the simulated sensors come up. ArduPilot SITL
    took 20-40 s to use GPS in the recordings; the defaults are shorter."""

    ekf_init_s: float = 3.3  # EKF3 initialised: attitude only
    gps_detect_s: float = 3.0  # GPS 1: detected
    gps_fix_s: float = 4.0  # 3-D fix; SYSTEM_TIME carries UNIX time from here
    ekf_origin_s: float = 5.0  # origin and home set
    ekf_gps_s: float = 6.0  # EKF uses GPS: position estimate, modes and arming allowed


@dataclass(frozen=True)
class SimOptions:
    sysid: int = 1
    compid: int = 1
    startup: StartupTimes = field(default_factory=StartupTimes)
    physics_dt_s: float = 0.1
    wind_speed_m_s: float = 0.0
    wind_from_deg: float = 0.0  # direction the wind blows from
    battery_pct: float = 100.0
    gps_fix_type: int = 6  # SITL reports RTK fixed (6); a real GPS would report 3
    satellites: int = 10
    stream_defaults: dict[int, float] | None = None  # msg id -> interval s; None: defaults
    boot_texts: bool = True


def _param_table(
    fw: Firmware, model: VehicleModel, af: AirframeParams, opts: SimOptions
) -> dict[str, tuple[float, int]]:
    """Parameter name -> (value, MAV_PARAM_TYPE). Only what the simulator uses."""
    p: dict[str, tuple[float, int]] = {
        "SYSID_THISMAV": (float(opts.sysid), 2),
        "ARMING_CHECK": (1.0, 6),
        "FENCE_ENABLE": (0.0, 2),
        "FENCE_ACTION": (1.0, 2),
        "CHUTE_ENABLED": (1.0 if af.has_parachute else 0.0, 2),
        "BATT_CAPACITY": (af.battery.capacity_mah, 6),
        "SIM_WIND_SPD": (opts.wind_speed_m_s, 9),
        "SIM_WIND_DIR": (opts.wind_from_deg, 9),
        "MIS_TOTAL": (0.0, 4),
    }
    if fw == Firmware.COPTER:
        p |= {
            "WPNAV_SPEED": (af.cruise_speed_m_s * 100, 9),
            "WPNAV_SPEED_UP": (af.climb_rate_m_s * 100, 9),
            "WPNAV_SPEED_DN": (af.sink_rate_m_s * 100, 9),
            "WPNAV_RADIUS": (af.wp_radius_m * 100, 9),
            "RTL_ALT": (af.rtl_alt_m * 100, 9),
            "LAND_SPEED": (af.land_speed_m_s * 100, 4),
            "DISARM_DELAY": (10.0, 2),
        }
    elif fw == Firmware.PLANE:
        p |= {
            "AIRSPEED_CRUISE": (af.cruise_speed_m_s, 9),
            "AIRSPEED_MIN": (af.min_airspeed_m_s, 4),
            "AIRSPEED_MAX": (af.max_speed_m_s, 4),
            "WP_RADIUS": (af.wp_radius_m, 4),
            "WP_LOITER_RAD": (af.loiter_radius_m, 4),
            "RTL_ALTITUDE": (af.rtl_alt_m, 9),
            "TKOFF_ALT": (af.takeoff_alt_m, 9),
            "Q_ENABLE": (1.0 if model == VehicleModel.VTOL else 0.0, 2),
        }
        if model == VehicleModel.VTOL:
            p |= {
                "Q_WP_SPEED": (af.vtol_speed_m_s * 100, 9),
                "Q_WP_SPEED_UP": (af.vtol_climb_rate_m_s * 100, 9),
                "Q_WP_SPEED_DN": (af.vtol_sink_rate_m_s * 100, 9),
                "Q_LAND_SPEED": (af.land_speed_m_s * 100, 4),
                "Q_LAND_FINAL_ALT": (af.land_final_alt_m, 9),
                "Q_TRANSITION_MS": (af.transition_time_s * 1000, 4),
            }
    else:
        p |= {
            "WP_SPEED": (af.cruise_speed_m_s, 9),
            "CRUISE_SPEED": (af.cruise_speed_m_s, 9),
            "WP_RADIUS": (af.wp_radius_m, 9),
            "FRAME_CLASS": (2.0 if model == VehicleModel.BOAT else 1.0, 2),
        }
    return p


class SimAutopilot:
    """One simulated ArduPilot vehicle (see the module docstring)."""

    def __init__(
        self,
        airframe: AirframeParams,
        home: Home,
        now: float,
        options: SimOptions | None = None,
    ) -> None:
        home.check()
        self.options = options or SimOptions()
        if not 1 <= self.options.sysid <= 255:
            raise ValueError("sysid must be 1..255")
        self.airframe = airframe
        self.model = airframe.model
        self.firmware = FIRMWARE_OF[self.model]
        self.mav_type = MAV_TYPE_OF[self.model]
        self.sysid = self.options.sysid
        self.compid = self.options.compid
        self.kinematics = make_model(airframe)
        self.frame = LocalFrame(home.lat_deg, home.lon_deg)
        self.origin_alt = home.alt_m
        self.body = Body(
            alt=home.alt_m, ground_alt=home.alt_m, heading_deg=wrap_360(home.heading_deg)
        )
        if self.model == VehicleModel.VTOL:
            self.body.vtol_state = VtolState.MC
        self.battery = Battery(airframe.battery, remaining_pct=self.options.battery_pct)
        self.params = _param_table(self.firmware, self.model, airframe, self.options)
        self.counters: Counter[str] = Counter()

        self.boot_time = now
        self._t = now
        self._next_phys = now
        self.mode = BOOT_MODE[self.firmware]
        self.armed = False
        self.gps_detected = False
        self.gps_fix = False
        self.ekf_position = False
        self.home_set = False
        self.home_ne = (0.0, 0.0)
        self.home_alt = home.alt_m
        self.ready = False  # boot finished (STANDBY)
        self.nav: NavTask = Idle()
        self.purpose = Purpose.MODE
        self._speed: float | None = None  # DO_CHANGE_SPEED override
        self._ground_since: float | None = now
        self._prearm_next = now
        self.parachute_released = False
        self.crashed = False
        self.fence_breached = False
        self.mount_pitch_deg = 0.0
        self.mount_yaw_deg = 0.0
        self._guided_radius = 0.0

        self.mission_items: list[MissionItem] = []
        self.fence_items: list[MissionItem] = []
        self.rally_items: list[MissionItem] = []
        self.mission_seq = 0  # current NAV command index, 0: none
        self.mission_running = False
        self.mission_complete = False
        self._jumps: dict[int, int] = {}
        self.transfers: dict[int, ItemTransfer] = {
            MISSION: ItemTransfer(
                MISSION, self.mission_items, home_item=self._home_item,
                current_seq=lambda: self.mission_seq, on_change=self._items_changed,
                statustext=self._statustext,
            ),
            FENCE: ItemTransfer(FENCE, self.fence_items, on_change=self._items_changed,
                                statustext=self._statustext),
            RALLY: ItemTransfer(RALLY, self.rally_items, on_change=self._items_changed,
                                statustext=self._statustext),
        }  # fmt: skip

        self.streams = S.StreamScheduler(now, self.options.stream_defaults)
        self._out: list[Any] = []
        self._timeline: list[tuple[float, Callable[[], None]]] = []
        self._build_timeline()

    # ------------------------------------------------------------------ public API

    def handle(self, msg: Any, now: float) -> list[Any]:
        """Process one decoded MAVLink message from a client; returns messages to send."""
        self._advance(now)
        try:
            self._dispatch(msg, now)
        except (ValueError, TypeError, OverflowError) as exc:
            # a malformed field from a peer: count and drop, never crash
            self.counters["bad_field"] += 1
            self.counters[f"bad_field:{type(exc).__name__}"] += 1
        self._emit_due(now)
        return self._flush()

    def on_timer(self, now: float) -> list[Any]:
        """Run physics, boot events, protocol timeouts and due telemetry up to `now`."""
        self._advance(now)
        for transfer in self.transfers.values():
            self._out.extend(transfer.update(now))
        self._emit_due(now)
        return self._flush()

    def next_deadline(self) -> float | None:
        t = self._next_phys
        if self._timeline and self._timeline[0][0] < t:
            t = self._timeline[0][0]
        due = self.streams.next_deadline()
        if due is not None and due < t:
            t = due
        for transfer in self.transfers.values():
            if transfer.receiving:
                d = transfer.next_deadline()
                if d is not None and d < t:
                    t = d
        if self.ready and not self.armed and self._prearm_next < t:
            t = self._prearm_next
        return t

    # state views used by telemetry, tests and the runtime
    @property
    def mode_spec(self) -> ModeSpec:
        return MODES[self.firmware][self.mode]

    @property
    def mode_name(self) -> str:
        return self.mode_spec.name

    @property
    def latlon(self) -> tuple[float, float]:
        return self.frame.to_latlon(self.body.n, self.body.e)

    @property
    def rel_alt_m(self) -> float:
        return self.body.alt - self.home_alt

    @property
    def home_latlon_alt(self) -> tuple[float, float, float]:
        lat, lon = self.frame.to_latlon(*self.home_ne)
        return lat, lon, self.home_alt

    @property
    def hdg_cdeg(self) -> int:
        return round(self.body.heading_deg * 100) % 36000

    @property
    def base_mode(self) -> int:
        return base_mode(self.firmware, self.mode_spec, self.armed)

    @property
    def ekf_init_s(self) -> float:
        return self.options.startup.ekf_init_s

    @property
    def system_status(self) -> int:
        if not self.ready:
            return 2 if self.firmware == Firmware.PLANE else 1  # CALIBRATING / BOOT
        if self.crashed or (self.parachute_released and not self.body.on_ground):
            return 6  # EMERGENCY
        if self.armed:
            if self.firmware == Firmware.PLANE:
                landed = self._ground_since is not None and self._t - self._ground_since > 1.0
                return 3 if landed and self._landing_context() else 4
            return 3 if self.body.on_ground else 4
        return 3  # STANDBY

    @property
    def taking_off(self) -> bool:
        return isinstance(self._leaf_task(), Takeoff)

    @property
    def landing(self) -> bool:
        return isinstance(self._leaf_task(), (Land, Parachute))

    @property
    def hover_capable(self) -> bool:
        return self.airframe.can_hover

    @property
    def fixed_wing(self) -> bool:
        return self.airframe.is_fixed_wing

    @property
    def wp_speed(self) -> float:
        if self._speed is not None:
            return self._speed
        if self.firmware == Firmware.COPTER:
            return self._param("WPNAV_SPEED") / 100.0
        if self.firmware == Firmware.PLANE:
            return self._param("AIRSPEED_CRUISE")
        return self._param("WP_SPEED")

    @property
    def loiter_radius(self) -> float:
        if self.firmware == Firmware.PLANE:
            return max(10.0, self._param("WP_LOITER_RAD"))
        return 0.0

    def boot_ms(self, now: float) -> int:
        return max(0, int((now - self.boot_time) * 1000)) & 0xFFFFFFFF

    def mission_current_fields(self) -> tuple[int, int, int, int]:
        total = max(0, len(self.mission_items) - 1)
        in_auto = self.mode_spec.behaviour == Behaviour.AUTO
        if total == 0:
            state = 1  # NO_MISSION
        elif self.mission_complete:
            state = 5
        elif self.mission_running and in_auto:
            state = 3
        else:
            state = 2
        seq = 0 if self.mission_complete else self.mission_seq
        return seq, total, state, 1 if in_auto else 0

    # ------------------------------------------------------------------ time

    def _advance(self, now: float) -> None:
        if now < self._t - 1e-6:
            raise ValueError(f"time went backwards: {now} < {self._t}")
        while True:
            t_evt = self._timeline[0][0] if self._timeline else math.inf
            t_phys = self._next_phys
            if min(t_evt, t_phys) > now:
                break
            if t_evt <= t_phys:
                _, action = self._timeline.pop(0)
                action()
            else:
                dt = self._phys_dt()
                self._physics_step(t_phys - self._t if t_phys > self._t else 0.0, t_phys)
                self._t = t_phys
                self._next_phys = t_phys + dt
        if self.ready and not self.armed and now >= self._prearm_next:
            self._prearm_next = now + PREARM_DISPLAY_PERIOD_S
            if self.ekf_position and self.params["ARMING_CHECK"][0] != 0:
                reason = self.prearm_failure()
                if reason is not None:
                    self._text(SEV_CRITICAL, f"PreArm: {reason}")

    def _phys_dt(self) -> float:
        idle = not self.armed and self.body.on_ground and self.body.groundspeed < 0.01
        return 1.0 if idle else self.options.physics_dt_s

    def _emit_due(self, now: float) -> None:
        for mid in self.streams.due(now):
            msg = telemetry.build(self, mid, now)
            if msg is not None:
                self._out.append(msg)

    def _flush(self) -> list[Any]:
        out, self._out = self._out, []
        return out

    # ------------------------------------------------------------------ boot

    def _build_timeline(self) -> None:
        st = self.options.startup
        t0 = self.boot_time
        events: list[tuple[float, Callable[[], None]]] = []
        if self.options.boot_texts:
            for dt, sev, text in BOOT_TEXTS[self.firmware]:
                events.append((t0 + dt, lambda s=sev, x=text: self._text(s, x)))  # type: ignore[misc]
        ready_at = 1.2 if self.firmware == Firmware.PLANE else 1.3
        events.append((t0 + ready_at, self._boot_ready))
        events.append((t0 + st.gps_detect_s, self._gps_detected))
        events.append((t0 + st.gps_fix_s, self._gps_fixed))
        events.append((t0 + st.ekf_origin_s, self._ekf_origin))
        events.append((t0 + st.ekf_gps_s, self._ekf_using_gps))
        events.sort(key=lambda ev: ev[0])
        self._timeline = events

    def _boot_ready(self) -> None:
        self.ready = True
        if self.mode != BOOT_MODE[self.firmware]:
            return
        if self.firmware == Firmware.PLANE:
            # recorded: INITIALISING -> MANUAL -> the RC mode switch's mode (FBWA)
            self.mode = 0
            self._out.append(telemetry.heartbeat(self))
            bisect.insort(
                self._timeline, (self.boot_time + 1.4, self._initial_mode), key=lambda ev: ev[0]
            )
        else:
            self._initial_mode()

    def _initial_mode(self) -> None:
        if self.mode in (0, BOOT_MODE[self.firmware]) and not self.armed:
            changed = self.mode != INITIAL_MODE[self.firmware]
            self.mode = INITIAL_MODE[self.firmware]
            self.nav = Idle()
            if changed:
                self._out.append(
                    telemetry.heartbeat(self)
                )  # ArduPilot sends one on every mode change

    def _gps_detected(self) -> None:
        self.gps_detected = True
        if self.options.boot_texts:
            for text in GPS_DETECTED_TEXTS:
                self._text(SEV_INFO, text)

    def _gps_fixed(self) -> None:
        self.gps_detected = True
        self.gps_fix = True

    def _ekf_origin(self) -> None:
        self.home_set = True
        self.home_ne = (self.body.n, self.body.e)
        self.home_alt = self.body.ground_alt
        if self.options.boot_texts:
            for text in EKF_ORIGIN_TEXTS:
                self._text(SEV_INFO, text.format(alt=self.home_alt))
        self._out.append(telemetry.gps_global_origin(self, self._t))
        self._out.append(telemetry.home_position(self, self._t))

    def _ekf_using_gps(self) -> None:
        self.ekf_position = True
        self._prearm_next = self._t + PREARM_DISPLAY_PERIOD_S
        if self.options.boot_texts:
            for text in EKF_GPS_TEXTS:
                self._text(SEV_INFO, text)
            if self.firmware == Firmware.PLANE:
                self._text(SEV_INFO, "AHRS: EKF3 active")  # the plane switched AHRS here

    # ------------------------------------------------------------------ physics

    def _physics_step(self, dt: float, t: float) -> None:
        b = self.body
        spd, frm = self._param("SIM_WIND_SPD"), math.radians(self._param("SIM_WIND_DIR"))
        b.wind_n, b.wind_e = -spd * math.cos(frm), -spd * math.sin(frm)
        if dt <= 0.0:
            return
        target = self._target()
        events = self.kinematics.step(b, target, dt)
        for ev in events:
            self._model_event(ev)
        if b.on_ground:
            if self._ground_since is None:
                self._ground_since = t
        else:
            self._ground_since = None
        if (self.armed or isinstance(self.nav, Parachute)) and self.nav.update(self, dt):
            self._nav_done()
        self._battery_step(dt)
        if self.armed:
            self._auto_disarm_check(t)
            self._fence_check()

    def _target(self) -> Target:
        if isinstance(self.nav, Parachute):
            return self.nav.target(self)
        if not self.armed:
            return Target(Guide.IDLE)
        target = self.nav.target(self)
        if self.airframe.is_ground:
            if target.kind in (Guide.TAKEOFF, Guide.LAND, Guide.IDLE):
                return Target(Guide.HOLD, self.body.n, self.body.e, self.body.alt)
            return target
        if self.body.on_ground and target.kind != Guide.TAKEOFF:
            return Target(Guide.IDLE)
        return target

    def _model_event(self, ev: ModelEvent) -> None:
        if ev.kind == EventKind.TOUCHDOWN:
            self._text(SEV_INFO, f"SIM Hit ground at {ev.value:f} m/s")
            if ev.value > CRASH_IMPACT_M_S and not self.parachute_released:
                self.crashed = True
                if self.armed:
                    self._text(SEV_CRITICAL, "Crash: Disarming")
                    self._disarm()
        elif ev.kind == EventKind.TRANSITION_STARTED:
            self._text(SEV_INFO, f"Transition started airspeed {ev.value:.1f}")
        elif ev.kind == EventKind.TRANSITION_AIRSPEED:
            self._text(SEV_INFO, f"Transition airspeed reached {ev.value:.1f}")
        elif ev.kind == EventKind.TRANSITION_DONE:
            self._text(SEV_INFO, "Transition done")

    def _battery_step(self, dt: float) -> None:
        af, b = self.airframe, self.body
        bp = af.battery
        current = bp.idle_current_a
        if self.armed and not (b.on_ground and b.groundspeed < 0.1 and not self.airframe.is_ground):
            if af.model == VehicleModel.COPTER or (
                af.model == VehicleModel.VTOL and b.vtol_state != VtolState.FW
            ):
                current = bp.hover_current_a * (
                    1.0 + 0.15 * max(0.0, -b.vd) + 0.002 * b.groundspeed**2
                )
            elif af.is_fixed_wing:
                ratio = b.airspeed / max(af.cruise_speed_m_s, 1.0)
                current = (
                    bp.cruise_current_a * (0.4 + 0.6 * ratio**3) * (1.0 + 0.1 * max(0.0, -b.vd))
                )
            else:
                current = bp.idle_current_a + bp.cruise_current_a * b.groundspeed / max(
                    af.cruise_speed_m_s, 0.1
                )
        elif self.armed:
            current = bp.idle_current_a * 2.0
        self.battery.step(current, dt)

    def _auto_disarm_check(self, t: float) -> None:
        if self.firmware != Firmware.COPTER or self._ground_since is None:
            return
        if isinstance(self._leaf_task(), Takeoff):
            return
        if t - self._ground_since >= self._param("DISARM_DELAY") > 0:
            self._disarm()

    def _fence_check(self) -> None:
        if self._param("FENCE_ENABLE") == 0 or not self.fence_items or self.body.on_ground:
            self.fence_breached = False
            return
        breached = self._outside_fence()
        if breached and not self.fence_breached:
            self._text(SEV_CRITICAL, "Fence Breached")
            action = int(self._param("FENCE_ACTION"))
            behaviour = self.mode_spec.behaviour
            if action != 0 and behaviour not in (Behaviour.RTL, Behaviour.LAND, Behaviour.QRTL):
                rtl = mode_number(self.firmware, "QRTL" if self._vtol_hovering() else "RTL")
                self._set_mode(rtl)
        self.fence_breached = breached

    def _outside_fence(self) -> bool:
        b = self.body
        items = self.fence_items
        inclusion_seen, inside_any_inclusion = False, False
        i = 0
        while i < len(items):
            item = items[i]
            if item.command in (5001, 5002):
                count = max(1, int(item.param1))
                poly = [self.frame.to_ne(it.lat_deg, it.lon_deg) for it in items[i : i + count]]
                inside = point_in_polygon(b.n, b.e, poly)
                if item.command == 5002 and inside:
                    return True
                if item.command == 5001:
                    inclusion_seen = True
                    inside_any_inclusion |= inside
                i += count
                continue
            if item.command in (5003, 5004):
                cn, ce = self.frame.to_ne(item.lat_deg, item.lon_deg)
                inside = math.hypot(b.n - cn, b.e - ce) <= item.param1
                if item.command == 5004 and inside:
                    return True
                if item.command == 5003:
                    inclusion_seen = True
                    inside_any_inclusion |= inside
            i += 1
        return inclusion_seen and not inside_any_inclusion

    # ------------------------------------------------------------------ navigation

    def _leaf_task(self) -> NavTask:
        task = self.nav
        while isinstance(task, Sequence):
            current = task.current
            if current is None:
                break
            task = current
        return task

    def _set_nav(self, task: NavTask, purpose: Purpose = Purpose.MODE) -> None:
        self.nav = task
        self.purpose = purpose

    def _here(self) -> tuple[float, float, float]:
        return self.body.n, self.body.e, self.body.alt

    def _vtol_hovering(self) -> bool:
        return self.model == VehicleModel.VTOL and self.body.vtol_state in (
            VtolState.MC,
            VtolState.TRANSITION_TO_MC,
        )

    def _hold_here(self) -> NavTask:
        n, e, alt = self._here()
        if self.firmware == Firmware.PLANE and not self._vtol_hovering():
            return Loiter(n, e, alt)
        return Hold(n, e, alt, vtol=self._vtol_hovering())

    def _rtl_point(self) -> tuple[float, float]:
        """Home, or the nearest rally point if it is closer (RALLY_INCL_HOME=1)."""
        best = self.home_ne
        b = self.body
        best_d = math.hypot(best[0] - b.n, best[1] - b.e)
        for item in self.rally_items:
            n, e = self.frame.to_ne(item.lat_deg, item.lon_deg)
            d = math.hypot(n - b.n, e - b.e)
            if d < best_d:
                best, best_d = (n, e), d
        return best

    def _rtl_task(self) -> NavTask:
        b = self.body
        hn, he = self._rtl_point()
        if self.firmware == Firmware.COPTER:
            rtl_alt = max(b.alt, self.home_alt + self._param("RTL_ALT") / 100.0)
            tasks: list[NavTask] = []
            if b.alt < rtl_alt - 0.5:
                tasks.append(FlyTo(b.n, b.e, rtl_alt, accept_m=2.0, stop=True))
            tasks += [
                FlyTo(hn, he, rtl_alt, accept_m=2.0, stop=True),
                Hold(hn, he, rtl_alt, time_s=RTL_LOITER_TIME_S),
                self._land_task(hn, he, vtol=True),
            ]
            return Sequence(tasks)
        if self.firmware == Firmware.PLANE:
            rtl = self._param("RTL_ALTITUDE")
            alt = b.alt if rtl < 0 else self.home_alt + rtl
            return Sequence([FlyTo(hn, he, alt, accept_m=self.loiter_radius, stop=False),
                             Loiter(hn, he, alt)])  # fmt: skip
        return Sequence([FlyTo(hn, he, b.alt, accept_m=self._param("WP_RADIUS"), stop=True),
                         Hold(hn, he, b.alt)])  # fmt: skip

    def _qrtl_task(self) -> NavTask:
        b = self.body
        hn, he = self._rtl_point()
        tasks: list[NavTask] = []
        far = math.hypot(hn - b.n, he - b.e) > 2.0 * self.loiter_radius
        if far:
            alt = max(b.alt, self.home_alt + 15.0)
            tasks.append(FlyTo(hn, he, alt, accept_m=self.loiter_radius, stop=False))
        tasks.append(FlyTo(hn, he, max(b.alt, self.home_alt + 5.0), accept_m=3.0, vtol=True))
        tasks.append(self._land_task(hn, he, vtol=True))
        return Sequence(tasks)

    def _enter_mode(self, spec: ModeSpec) -> None:
        beh = spec.behaviour
        b = self.body
        n, e, alt = self._here()
        if beh == Behaviour.AUTO:
            self._mission_start_or_resume()
            return
        self.mission_running = False
        if beh in (Behaviour.MANUAL, Behaviour.INITIALISING):
            if self.firmware == Firmware.PLANE and not b.on_ground and not self._vtol_hovering():
                h = math.radians(b.heading_deg)
                self._set_nav(
                    FlyTo(
                        n + 1e5 * math.cos(h), e + 1e5 * math.sin(h), alt, accept_m=0.0, stop=False
                    )
                )
            else:
                self._set_nav(Hold(n, e, alt, vtol=self._vtol_hovering()))
        elif beh == Behaviour.HOLD:
            self._set_nav(Hold(n, e, alt, vtol=spec.vtol or not self.fixed_wing))
        elif beh == Behaviour.GUIDED:
            self._set_nav(self._hold_here())
        elif beh == Behaviour.RTL:
            self._set_nav(self._rtl_task())
        elif beh == Behaviour.QRTL:
            self._set_nav(self._qrtl_task())
        elif beh == Behaviour.LAND:
            ln, le = self._stopping_point()
            self._set_nav(self._land_task(ln, le, vtol=True))
        elif beh == Behaviour.CIRCLE:
            if self.firmware == Firmware.COPTER:
                h = math.radians(b.heading_deg)
                self._set_nav(Loiter(n + 10 * math.cos(h), e + 10 * math.sin(h), alt, radius=10.0))
            else:
                self._set_nav(Loiter(n, e, alt, radius=self.loiter_radius or 20.0))
        elif beh == Behaviour.LOITER:
            self._set_nav(Loiter(n, e, alt))
        elif beh == Behaviour.TAKEOFF:
            if b.on_ground:
                climb = self.home_alt + self._param("TKOFF_ALT")
                self._set_nav(Sequence([Takeoff(climb, vtol=False), Loiter(n, e, climb)]))
            else:
                self._set_nav(Loiter(n, e, alt))

    def _nav_done(self) -> None:
        leaf = self._leaf_task()
        if self.purpose == Purpose.MISSION:
            self._mission_item_done()
            return
        if self.purpose == Purpose.GUIDED_GOTO:
            dest = self.nav.destination or self._here()
            if self.firmware == Firmware.PLANE:
                self._out.append(mavlink.MAVLink_mission_item_reached_message(0))
                if self._vtol_hovering() and isinstance(self.nav, FlyTo) and self.nav.vtol:
                    self._set_nav(Hold(*dest, vtol=True))
                else:
                    self._set_nav(Loiter(*dest, radius=self._guided_radius))
            else:
                self._set_nav(Hold(*dest))
            return
        if self.purpose in (Purpose.GUIDED_TAKEOFF, Purpose.GUIDED_VELOCITY):
            n, e, alt = self._here()
            if self.purpose == Purpose.GUIDED_TAKEOFF and isinstance(self.nav, Takeoff):
                alt = self.nav.alt
            self._set_nav(Hold(n, e, alt, vtol=self.model == VehicleModel.VTOL))
            return
        # mode tasks
        if isinstance(leaf, Land) or (
            isinstance(self.nav, Sequence) and isinstance(self.nav.tasks[-1], Land)
        ):
            self._land_complete()
            self._set_nav(Idle())
            return
        beh = self.mode_spec.behaviour
        if beh == Behaviour.RTL and self.firmware == Firmware.ROVER:
            self._text(SEV_INFO, "Reached destination")
            self._set_nav(Hold(*self._here()))
        elif beh == Behaviour.TAKEOFF:
            self._set_nav(Loiter(*self._here()))
        elif isinstance(self.nav, Parachute):
            self._set_nav(Idle())
        else:
            self._set_nav(self._hold_here())

    def _land_task(self, n: float, e: float, vtol: bool) -> Land:
        settle = PLANE_LAND_SETTLE_S if self.firmware == Firmware.PLANE else COPTER_LAND_SETTLE_S
        return Land(n, e, vtol=vtol, settle_s=settle)

    def _stopping_point(self) -> tuple[float, float]:
        """Where the vehicle comes to a stop if it brakes now (QLAND/LAND land there)."""
        b = self.body
        v = b.groundspeed
        if v < 1.0:
            return b.n, b.e
        d = v * v / (2.0 * max(self.airframe.accel_m_s2, 0.5))
        return b.n + b.vn / v * d, b.e + b.ve / v * d

    def _land_complete(self) -> None:
        if not self.armed:
            return
        if self.firmware == Firmware.PLANE:
            self._text(SEV_INFO, "Land complete")
        self._disarm()

    def _landing_context(self) -> bool:
        return isinstance(self._leaf_task(), (Land, Parachute, Idle))

    # ------------------------------------------------------------------ mission

    def _home_item(self) -> MissionItem:
        lat, lon, alt = self.home_latlon_alt
        return MissionItem(
            seq=0, frame=0, command=16, x=round(lat * 1e7), y=round(lon * 1e7), z=alt
        )

    def _items_changed(self, mission_type: int) -> list[Any]:
        out: list[Any] = []
        if mission_type == MISSION:
            self.params["MIS_TOTAL"] = (float(max(0, len(self.mission_items) - 1)), 4)
            names = sorted(self.params)
            out.append(self._param_value("MIS_TOTAL", names.index("MIS_TOTAL"), len(names)))
            self.mission_seq = 0
            self.mission_complete = False
            self._jumps.clear()
            if self.mode_spec.behaviour == Behaviour.AUTO:
                self._mission_start_or_resume()
        return out

    @staticmethod
    def _is_nav(command: int) -> bool:
        return command <= 95 or command in (213, 42702, 42703)

    def _mission_start_or_resume(self) -> None:
        if len(self.mission_items) <= 1:
            self.mission_running = False
            self._set_nav(self._hold_here() if not self.body.on_ground else Idle())
            return
        if self.mission_complete or self.mission_seq <= 0:
            self.mission_complete = False
            self._jumps.clear()
            start = 1
        else:
            start = self.mission_seq
        self.mission_running = True
        self._mission_run_from(start)

    def _mission_run_from(self, seq: int) -> None:
        items = self.mission_items
        guard = 0
        while seq < len(items) and guard < 4 * len(items) + 10:
            guard += 1
            item = items[seq]
            if item.command == 177:  # DO_JUMP
                seq = self._jump(seq, item)
                continue
            self._text(SEV_INFO, f"Mission: {seq} {MISSION_CMD_NAMES.get(item.command, '?')}")
            if not self._is_nav(item.command):
                self._do_command(item)
                seq += 1
                continue
            self.mission_seq = seq
            started = self._start_nav_item(item)
            k = seq + 1
            while k < len(items) and not self._is_nav(items[k].command) and items[k].command != 177:
                self._text(SEV_INFO, f"Mission: {k} {MISSION_CMD_NAMES.get(items[k].command, '?')}")
                self._do_command(items[k])
                k += 1
            if started == "done":
                self._mission_item_done()
            return
        self._mission_finished()

    def _jump(self, seq: int, item: MissionItem) -> int:
        target, repeat = int(item.param1), int(item.param2)
        taken = self._jumps.get(seq, 0)
        if 0 < target < len(self.mission_items) and (repeat < 0 or taken < repeat):
            self._jumps[seq] = taken + 1
            return target
        return seq + 1

    def _start_nav_item(self, item: MissionItem) -> str:
        """Start the task for a NAV item: "started", "done" (complete at once) or "mode"
        (the item switched modes)."""
        fw, b = self.firmware, self.body
        cmd = item.command
        n, e, alt = self._item_location(item)
        vtol_model = self.model == VehicleModel.VTOL
        if cmd in (16, 82):  # WAYPOINT, SPLINE_WAYPOINT
            accept = item.param2 if item.param2 > 0 else self._wp_radius()
            hold = 0.0 if fw == Firmware.PLANE else max(0.0, item.param1)
            prev = self.nav.destination if isinstance(self._leaf_task(), FlyTo) else None
            origin = (prev[0], prev[1]) if prev is not None and self.fixed_wing else None
            task = FlyTo(
                n, e, alt, accept_m=accept, hold_s=hold, stop=not self.fixed_wing, origin=origin
            )
            self._set_nav(task, Purpose.MISSION)
        elif cmd in (17, 18, 19, 31):  # LOITER_UNLIM, _TURNS, _TIME, _TO_ALT
            radius = abs(item.param3) if cmd != 31 else abs(item.param2)
            turns = item.param1 if cmd == 18 else None
            time_s = item.param1 if cmd == 19 else (0.0 if cmd == 31 else None)
            self._set_nav(Loiter(n, e, alt, radius=radius, ccw=item.param3 < 0, turns=turns, time_s=time_s),
                          Purpose.MISSION)  # fmt: skip
        elif cmd == 20:  # RETURN_TO_LAUNCH
            if fw == Firmware.PLANE:
                self._set_mode(mode_number(fw, "RTL"))
                return "mode"
            if fw == Firmware.ROVER:  # done on arrival; the mission then completes
                hn, he = self._rtl_point()
                self._set_nav(FlyTo(hn, he, b.alt, accept_m=self._wp_radius()), Purpose.MISSION)
            else:
                self._set_nav(self._rtl_task(), Purpose.MISSION)
        elif cmd == 22 or (cmd == 84 and not vtol_model):  # TAKEOFF (VTOL_TAKEOFF on a copter)
            if fw == Firmware.ROVER or (cmd == 84 and fw == Firmware.PLANE):
                return "done"
            target_alt = self._item_alt(item)
            if not b.on_ground and b.alt >= target_alt - 0.5:
                return "done"
            self._set_nav(Takeoff(target_alt, vtol=fw == Firmware.COPTER), Purpose.MISSION)
        elif cmd == 84:  # VTOL_TAKEOFF on a QuadPlane
            target_alt = self._item_alt(item)
            if not b.on_ground and b.alt >= target_alt - 0.5:
                return "done"
            self._set_nav(Takeoff(target_alt, vtol=True), Purpose.MISSION)
        elif cmd in (21, 85):  # LAND, VTOL_LAND
            if fw == Firmware.ROVER or (cmd == 85 and not self.hover_capable):
                return "done"
            vertical = fw == Firmware.COPTER or cmd == 85
            tasks: list[NavTask] = []
            if item.has_location:
                if vertical and vtol_model:
                    if math.hypot(n - b.n, e - b.e) > 2.0 * self.loiter_radius:
                        tasks.append(FlyTo(n, e, b.alt, accept_m=self.loiter_radius, stop=False))
                    tasks.append(FlyTo(n, e, b.alt, accept_m=3.0, vtol=True))
                elif vertical:
                    tasks.append(FlyTo(n, e, b.alt, accept_m=2.0))
            else:
                n, e = b.n, b.e
            tasks.append(self._land_task(n, e, vtol=vertical))
            self._set_nav(Sequence(tasks), Purpose.MISSION)
        elif cmd == 93:  # NAV_DELAY
            self._set_nav(Hold(*self._here(), time_s=max(0.0, item.param1)), Purpose.MISSION)
        else:
            return "done"
        return "started"

    def _item_alt(self, item: MissionItem) -> float:
        if item.frame in FRAME_ABSOLUTE:
            return item.z
        return self.home_alt + item.z

    def _item_location(self, item: MissionItem) -> tuple[float, float, float]:
        b = self.body
        if item.frame in GLOBAL_FRAMES and not (item.x == 0 and item.y == 0):
            n, e = self.frame.to_ne(item.lat_deg, item.lon_deg)
        else:
            n, e = b.n, b.e
        if self.airframe.is_ground:
            return n, e, b.ground_alt
        if item.frame in GLOBAL_FRAMES and not (
            item.z == 0 and item.frame not in FRAME_ABSOLUTE and item.command != 16
        ):
            alt = self._item_alt(item)
        else:
            alt = b.alt
        return n, e, alt

    def _wp_radius(self) -> float:
        if self.firmware == Firmware.COPTER:
            return self._param("WPNAV_RADIUS") / 100.0
        return self._param("WP_RADIUS")

    def _do_command(self, item: MissionItem) -> None:
        cmd = item.command
        if cmd == 178:  # DO_CHANGE_SPEED
            self._change_speed(int(item.param1), item.param2)
        elif cmd == 179:  # DO_SET_HOME
            if item.param1 == 1 or not item.has_location:
                self._set_home(self.body.n, self.body.e, self.body.alt)
            else:
                n, e = self.frame.to_ne(item.lat_deg, item.lon_deg)
                self._set_home(n, e, self._item_alt(item))
        elif cmd == 208:  # DO_PARACHUTE
            if int(item.param1) == 2:
                self._parachute_release()
        elif cmd == 207:  # DO_FENCE_ENABLE
            self.params["FENCE_ENABLE"] = (1.0 if int(item.param1) == 1 else 0.0, 2)

    def _mission_item_done(self) -> None:
        seq = self.mission_seq
        item = self.mission_items[seq] if 0 < seq < len(self.mission_items) else None
        self._out.append(mavlink.MAVLink_mission_item_reached_message(seq))
        if item is not None and item.command in (16, 82):
            leaf = self.nav if isinstance(self.nav, FlyTo) else None
            if self.firmware == Firmware.COPTER:
                self._text(SEV_INFO, f"Reached command #{seq}")
            else:
                dist = int(leaf.reached_dist_m) if leaf is not None else 0
                self._text(SEV_INFO, f"Reached waypoint #{seq} dist {dist}m")
        landed_item = item is not None and (
            item.command in (21, 85) or (item.command == 20 and self.firmware == Firmware.COPTER)
        )
        if landed_item and self.body.on_ground:
            self._land_complete()
        k = seq + 1
        while (
            k < len(self.mission_items)
            and not self._is_nav(self.mission_items[k].command)
            and self.mission_items[k].command != 177
        ):
            k += 1  # DO commands after the item already ran with it
        if k >= len(self.mission_items):
            self._mission_finished()
        else:
            self._mission_run_from(k)

    def _mission_finished(self) -> None:
        self.mission_running = False
        self.mission_complete = True
        if self.firmware == Firmware.PLANE:
            if self.armed and not self.body.on_ground:
                self._set_mode(mode_number(self.firmware, "RTL"))
                self._text(SEV_INFO, "Mission complete, changing mode to RTL")
            else:
                self._set_nav(Idle())
        elif self.firmware == Firmware.ROVER:
            self._text(SEV_NOTICE, "Mission Complete")
            self._set_mode(mode_number(self.firmware, "HOLD"))
        else:
            self._set_nav(self._hold_here() if not self.body.on_ground else Idle())

    # ------------------------------------------------------------------ modes, arming

    def _set_mode(self, number: int) -> bool:
        """Plane/Copter/Rover::set_mode. On failure the reason is sent as STATUSTEXT."""
        spec = MODES[self.firmware].get(number)
        if spec is None or not spec.selectable:
            self._text(SEV_WARNING, f"No such mode {number}")
            return False
        if spec.vtol and self.model != VehicleModel.VTOL:
            self._text(SEV_INFO, "Q_ENABLE 0")
            return False
        if number == self.mode:
            return True
        if spec.requires_position and not self.ekf_position:
            self._text(SEV_WARNING, f"Mode change to {spec.name} failed: requires position")
            return False
        if (
            self.firmware == Firmware.COPTER
            and spec.behaviour == Behaviour.AUTO
            and self.armed
            and self.body.on_ground
            and not self._mission_starts_with_takeoff()
        ):
            self._text(SEV_CRITICAL, "Auto: Missing Takeoff Cmd")
            return False
        self.mode = number
        self._speed = None
        self._out.append(telemetry.heartbeat(self))
        self._enter_mode(spec)
        return True

    def _mission_starts_with_takeoff(self) -> bool:
        for item in self.mission_items[1:]:
            if self._is_nav(item.command):
                return item.command in (22, 84)
        return False

    def prearm_failure(self) -> str | None:
        """The first failing arming check, worded as ArduPilot's PreArm messages; None when
        the vehicle may arm."""
        if not self.ready:
            return "Waiting for RC"  # not reached in practice: arming waits for boot
        if self.crashed:
            return "Crashed"
        if not self.gps_fix:
            return "GPS 1: Bad fix"
        if not self.ekf_position:
            return (
                "AHRS: waiting for home"
                if self.firmware == Firmware.PLANE
                else "Need Position Estimate"
            )
        if not self.mode_spec.armable:
            return f"{self.mode_name} mode not armable"
        if self._param("FENCE_ENABLE") != 0 and self.fence_items and self._outside_fence():
            return "Fence: vehicle outside fence"
        if self.battery.remaining_pct < 5:
            return "Battery 1 below minimum arming capacity"
        return None

    def _arm(self, force: bool) -> bool:
        if self.armed:
            return True
        if not self.ready:
            return False
        if not force and self._param("ARMING_CHECK") != 0:
            reason = self.prearm_failure()
            if reason is not None:
                self._text(SEV_CRITICAL, f"PreArm: {reason}")
                return False
        self.armed = True
        self.crashed = False
        self._ground_since = self._t if self.body.on_ground else None
        if self.home_set or self.ekf_position:
            self._set_home(
                self.body.n,
                self.body.e,
                self.body.ground_alt if self.body.on_ground else self.home_alt,
            )
        if self.firmware == Firmware.COPTER:
            self._out.append(telemetry.gps_global_origin(self, self._t))
        self._text(SEV_INFO, ARM_TEXT[self.firmware])
        if self.mode_spec.behaviour == Behaviour.AUTO and self.mission_running:
            pass  # the current item (e.g. a take-off) proceeds now that the motors run
        return True

    def _disarm(self) -> None:
        if not self.armed:
            return
        self.armed = False
        self._prearm_next = self._t + PREARM_DISPLAY_PERIOD_S
        self._text(SEV_INFO, DISARM_TEXT[self.firmware])
        if self.firmware == Firmware.PLANE:
            self.mission_seq = 0
            self.mission_running = False
        if self.body.on_ground and not isinstance(self.nav, Parachute):
            self._set_nav(Idle())

    def _flying(self) -> bool:
        return not self.body.on_ground and not self.airframe.is_ground

    def _set_home(self, n: float, e: float, alt: float) -> None:
        self.home_set = True
        self.home_ne = (n, e)
        self.home_alt = alt
        self._out.append(telemetry.home_position(self, self._t))

    def _parachute_release(self) -> bool:
        if self._param("CHUTE_ENABLED") == 0 or self.parachute_released:
            return False
        if self.body.on_ground:
            self._text(SEV_INFO, "Parachute: Landed")
            return False
        if self.body.height < self.airframe.parachute_min_alt_m:
            self._text(SEV_INFO, "Parachute: Too low")
            return False
        self._text(SEV_CRITICAL, "Parachute: Released")
        self.parachute_released = True
        self.mission_running = False
        self._set_nav(Parachute())
        if self.armed:
            self.armed = False
            self._text(SEV_INFO, DISARM_TEXT[self.firmware])
        return True

    def _change_speed(self, speed_type: int, speed: float) -> bool:
        if not math.isfinite(speed) or speed <= 0:
            return False
        if self.firmware == Firmware.PLANE:
            if speed_type == 0:
                if not self._param("AIRSPEED_MIN") <= speed <= self._param("AIRSPEED_MAX"):
                    return False
                self._speed = speed
                self._text(SEV_INFO, f"Set airspeed {int(speed)} m/s")
                return True
            if speed_type == 1:
                self._text(SEV_INFO, f"Set groundspeed {int(speed)}")
                return True
            return False
        if speed_type in (0, 1):
            self._speed = min(speed, self.airframe.max_speed_m_s)
            return True
        return speed_type in (2, 3)

    # ------------------------------------------------------------------ dispatch

    def _dispatch(self, msg: Any, now: float) -> None:
        mtype = msg.get_type()
        if mtype in ("BAD_DATA", "UNKNOWN"):
            self.counters["bad_data"] += 1
            return
        src = Peer(msg.get_srcSystem(), msg.get_srcComponent())
        if src.sysid == self.sysid and src.compid == self.compid:
            self.counters["own_echo"] += 1
            return
        target = getattr(msg, "target_system", None)
        if target is not None and target not in (0, self.sysid):
            self.counters["foreign_target"] += 1
            return
        tcomp = getattr(msg, "target_component", None)
        if (
            target is not None
            and tcomp not in (None, 0, self.compid)
            and mtype not in _ANY_COMPONENT
        ):
            self.counters["foreign_component"] += 1
            return
        handler = _HANDLERS.get(mtype)
        if handler is None:
            self.counters["ignored" if mtype in _IGNORED else "unhandled"] += 1
            return
        self.counters[f"rx:{mtype}"] += 1
        handler(self, msg, src, now)

    # commands --------------------------------------------------------------------

    def _on_command_long(self, msg: Any, src: Peer, now: float) -> None:
        cmd = Cmd(
            command=int(msg.command), p1=msg.param1, p2=msg.param2, p3=msg.param3, p4=msg.param4,
            x=msg.param5, y=msg.param6, z=msg.param7, frame=_COMMAND_LONG_FRAME.get(int(msg.command), 3),
            is_int=False, src=src,
        )  # fmt: skip
        self._run_command(cmd)

    def _on_command_int(self, msg: Any, src: Peer, now: float) -> None:
        cmd = Cmd(
            command=int(msg.command), p1=msg.param1, p2=msg.param2, p3=msg.param3, p4=msg.param4,
            x=msg.x * 1e-7 if msg.frame in GLOBAL_FRAMES else float(msg.x),
            y=msg.y * 1e-7 if msg.frame in GLOBAL_FRAMES else float(msg.y),
            z=msg.z, frame=int(msg.frame), is_int=True, src=src,
        )  # fmt: skip
        self._run_command(cmd)

    def _run_command(self, cmd: Cmd) -> None:
        mark = len(self._out)
        handler = _COMMANDS.get(cmd.command)
        if handler is None:
            result = ACCEPTED if cmd.command in _ACCEPTED_NOOP_COMMANDS else UNSUPPORTED
        else:
            result = handler(self, cmd)
        ack = mavlink.MAVLink_command_ack_message(
            cmd.command, result, 0, 0, cmd.src.sysid, cmd.src.compid
        )
        if result == ACCEPTED:
            self._out.insert(mark, ack)  # ACK first, then what the command caused
        else:
            self._out.append(ack)  # the reason (STATUSTEXT) first, then the NAK
        self.counters[f"cmd:{cmd.command}:{result}"] += 1

    def _cmd_set_mode(self, cmd: Cmd) -> int:
        return self._set_mode_common(int(cmd.p1), int(cmd.p2))

    def _set_mode_common(self, base: int, custom: int) -> int:
        if base & MAV_MODE_FLAG_CUSTOM_MODE_ENABLED:
            return ACCEPTED if self._set_mode(custom) else FAILED
        if base == MAV_MODE_FLAG_DECODE_POSITION_SAFETY:
            return ACCEPTED if custom in (0, 1) else DENIED
        return DENIED

    def _cmd_arm_disarm(self, cmd: Cmd) -> int:
        if cmd.p1 == 1.0:
            return ACCEPTED if self._arm(force=cmd.p2 == ARM_FORCE_MAGIC) else FAILED
        if cmd.p1 == 0.0:
            if not self.armed:
                return ACCEPTED
            if self._flying() and cmd.p2 != DISARM_FORCE_MAGIC:
                return FAILED
            self._disarm()
            if self._flying():
                self._set_nav(Idle())
            return ACCEPTED
        return DENIED

    def _cmd_takeoff(self, cmd: Cmd) -> int:
        fw = self.firmware
        if fw == Firmware.ROVER or (cmd.command == 84 and fw == Firmware.PLANE):
            return UNSUPPORTED
        if not math.isfinite(cmd.z) or abs(cmd.z) > MAX_ALT_M:
            return DENIED
        if fw == Firmware.COPTER:
            if cmd.frame not in (3, 6):
                return DENIED
            alt = self.home_alt + cmd.z
            spec = self.mode_spec
            supports = spec.name in (
                "GUIDED",
                "LOITER",
                "ALT_HOLD",
                "POSHOLD",
                "SPORT",
                "FLOWHOLD",
                "ZIGZAG",
                "GUIDED_NOGPS",
            )
            if not self.armed or not self.body.on_ground or not supports or alt <= self.body.alt:
                return FAILED
            if spec.behaviour == Behaviour.GUIDED:
                self._set_nav(Takeoff(alt, vtol=True), Purpose.GUIDED_TAKEOFF)
            else:
                self._set_nav(
                    Sequence([Takeoff(alt, vtol=True), Hold(self.body.n, self.body.e, alt)])
                )
            return ACCEPTED
        # ArduPlane: QuadPlane only, COMMAND_INT in MAV_FRAME_LOCAL_OFFSET_NED (z down)
        if cmd.is_int:
            if cmd.frame != 7:
                return DENIED
            height = -cmd.z
        else:
            height = cmd.z
        if self.model != VehicleModel.VTOL:
            return FAILED
        if self.mode_spec.behaviour != Behaviour.GUIDED:
            self._text(SEV_INFO, "User Takeoff only in GUIDED mode")
            return FAILED
        if not self.armed:
            self._text(SEV_INFO, "Must be armed for takeoff")
            return FAILED
        if self._flying():
            self._text(SEV_INFO, "Already flying - no takeoff")
            return FAILED
        self._set_nav(Takeoff(self.home_alt + height, vtol=True), Purpose.GUIDED_TAKEOFF)
        return ACCEPTED

    def _cmd_reposition(self, cmd: Cmd) -> int:
        if not cmd.is_int:
            return UNSUPPORTED  # ArduPilot takes DO_REPOSITION as COMMAND_INT only
        if not (-90 <= cmd.x <= 90 and -180 <= cmd.y <= 180) or (cmd.x == 0 and cmd.y == 0):
            return DENIED
        alt = self._alt_from_frame(cmd.frame, cmd.z)
        if alt is None:
            return DENIED
        change_mode = (
            int(cmd.p2) & MAV_DO_REPOSITION_FLAGS_CHANGE_MODE if math.isfinite(cmd.p2) else 0
        )
        in_guided = self.mode_spec.behaviour == Behaviour.GUIDED
        if self.firmware == Firmware.PLANE:
            if not (change_mode or in_guided):
                return FAILED
            if not in_guided and not self._set_mode(mode_number(self.firmware, "GUIDED")):
                return FAILED
            radius = cmd.p3 if math.isfinite(cmd.p3) and cmd.p3 > 0 else 0.0
            self._guided_radius = radius
            self._guided_goto(cmd.x, cmd.y, alt, ccw=math.isfinite(cmd.p4) and cmd.p4 != 0)
            return ACCEPTED
        if not in_guided and not change_mode:
            return DENIED
        if not in_guided and not self._set_mode(mode_number(self.firmware, "GUIDED")):
            return FAILED
        self._guided_goto(cmd.x, cmd.y, alt)
        return ACCEPTED

    def _alt_from_frame(self, frame: int, z: float) -> float | None:
        if not math.isfinite(z) or abs(z) > MAX_ALT_M:
            return None
        if frame in FRAME_ABSOLUTE:
            return z
        if frame in GLOBAL_FRAMES:
            return self.home_alt + z
        return None

    def _guided_goto(self, lat: float, lon: float, alt: float, ccw: bool = False) -> None:
        n, e = self.frame.to_ne(lat, lon)
        if self.airframe.is_ground:
            alt = self.body.ground_alt
        if self.firmware == Firmware.PLANE:
            if (
                self._vtol_hovering()
                and math.hypot(n - self.body.n, e - self.body.e) < 2.0 * self.loiter_radius
                and self._flying()
            ):
                self._set_nav(FlyTo(n, e, alt, accept_m=2.0, vtol=True), Purpose.GUIDED_GOTO)
            else:
                self._set_nav(
                    FlyTo(n, e, alt, accept_m=self.loiter_radius + 10.0, stop=False),
                    Purpose.GUIDED_GOTO,
                )
            return
        accept = self._wp_radius()
        self._set_nav(FlyTo(n, e, alt, accept_m=accept, stop=True), Purpose.GUIDED_GOTO)

    def _cmd_change_speed(self, cmd: Cmd) -> int:
        if self.firmware == Firmware.COPTER:
            if not (math.isfinite(cmd.p2) and cmd.p2 > 0):
                return DENIED
            if int(cmd.p1) not in (0, 1, 2, 3):
                return DENIED
            return ACCEPTED if self._change_speed(int(cmd.p1), cmd.p2) else FAILED
        if self.firmware == Firmware.PLANE:
            beh = self.mode_spec.behaviour
            if beh not in (Behaviour.GUIDED, Behaviour.AUTO):
                return FAILED
        return ACCEPTED if self._change_speed(int(cmd.p1), cmd.p2) else FAILED

    def _cmd_change_altitude(self, cmd: Cmd) -> int:
        if self.firmware != Firmware.PLANE:
            return UNSUPPORTED
        alt = self._alt_from_frame(int(cmd.p2), cmd.p1)
        if alt is None:
            return DENIED
        self._change_alt(alt)
        return ACCEPTED

    def _change_alt(self, alt: float) -> None:
        task = self._leaf_task()
        if isinstance(task, (FlyTo, Hold, Loiter)):
            task.alt = alt
        elif self.mode_spec.behaviour == Behaviour.GUIDED:
            hold = self._hold_here()
            if isinstance(hold, (Hold, Loiter)):
                hold.alt = alt
            self._set_nav(hold)

    def _cmd_rtl(self, cmd: Cmd) -> int:
        ok = self._set_mode(mode_number(self.firmware, "RTL"))
        if self.firmware == Firmware.PLANE:
            return ACCEPTED
        return ACCEPTED if ok else FAILED

    def _cmd_land(self, cmd: Cmd) -> int:
        if self.firmware != Firmware.COPTER:
            return UNSUPPORTED
        return ACCEPTED if self._set_mode(mode_number(self.firmware, "LAND")) else FAILED

    def _cmd_loiter_unlim(self, cmd: Cmd) -> int:
        ok = self._set_mode(mode_number(self.firmware, "LOITER"))
        if self.firmware == Firmware.PLANE:
            return ACCEPTED
        return ACCEPTED if ok else FAILED

    def _cmd_mission_start(self, cmd: Cmd) -> int:
        if (math.isfinite(cmd.p1) and cmd.p1 != 0) or (math.isfinite(cmd.p2) and cmd.p2 != 0):
            return DENIED
        auto = mode_number(self.firmware, "AUTO")
        if self.firmware == Firmware.PLANE:
            self._set_mode(auto)
            return ACCEPTED
        if self.mode == auto:
            if not self.mission_running:
                self._mission_start_or_resume()
            return ACCEPTED
        return ACCEPTED if self._set_mode(auto) else FAILED

    def _cmd_parachute(self, cmd: Cmd) -> int:
        if self.firmware == Firmware.ROVER:
            return UNSUPPORTED
        action = int(cmd.p1) if math.isfinite(cmd.p1) else -1
        if action == 0:
            self.params["CHUTE_ENABLED"] = (0.0, 2)
            return ACCEPTED
        if action == 1:
            self.params["CHUTE_ENABLED"] = (1.0, 2)
            return ACCEPTED
        if action != 2:
            return FAILED
        if self.firmware == Firmware.PLANE:
            if self.parachute_released:
                self._text(SEV_NOTICE, "Parachute already released")
                return FAILED
            if self._param("CHUTE_ENABLED") == 0:
                self._text(SEV_NOTICE, "Parachute not enabled")
                return FAILED
            return ACCEPTED if self._parachute_release() else FAILED
        self._parachute_release()  # ArduCopter accepts and checks inside
        return ACCEPTED

    def _cmd_set_home(self, cmd: Cmd) -> int:
        if cmd.p1 == 1:
            if not self.ekf_position:
                return FAILED
            self._set_home(self.body.n, self.body.e, self.body.alt)
            return ACCEPTED
        if not (-90 <= cmd.x <= 90 and -180 <= cmd.y <= 180) or (cmd.x == 0 and cmd.y == 0):
            return FAILED
        frame = cmd.frame if cmd.is_int else 0
        alt = self._alt_from_frame(frame, cmd.z)
        if alt is None:
            return FAILED
        n, e = self.frame.to_ne(cmd.x, cmd.y)
        self._set_home(n, e, alt)
        return ACCEPTED

    def _cmd_set_mission_current(self, cmd: Cmd) -> int:
        seq = int(cmd.p1) if math.isfinite(cmd.p1) else -1
        if not self._set_mission_current(seq):
            return FAILED
        return ACCEPTED

    def _set_mission_current(self, seq: int) -> bool:
        if not 0 < seq < len(self.mission_items):
            return False
        self.mission_seq = seq
        self.mission_complete = False
        if self.mode_spec.behaviour == Behaviour.AUTO:
            self.mission_running = True
            self._mission_run_from(seq)
        self._out.append(telemetry.mission_current(self))
        return True

    def _cmd_fence_enable(self, cmd: Cmd) -> int:
        action = int(cmd.p1) if math.isfinite(cmd.p1) else -1
        if action not in (0, 1, 2):
            return FAILED
        self.params["FENCE_ENABLE"] = (1.0 if action == 1 else 0.0, 2)
        return ACCEPTED

    def _cmd_vtol_transition(self, cmd: Cmd) -> int:
        if self.model != VehicleModel.VTOL:
            self._text(SEV_NOTICE, "VTOL not available")
            return FAILED
        if self.mode_spec.behaviour != Behaviour.AUTO:
            self._text(SEV_NOTICE, "VTOL Transition only in AUTO")
            return FAILED
        return ACCEPTED

    def _cmd_set_message_interval(self, cmd: Cmd) -> int:
        if not (math.isfinite(cmd.p1) and math.isfinite(cmd.p2)):
            return DENIED
        msg_id, interval_us = int(cmd.p1), cmd.p2
        if interval_us == 0:
            interval: float | None = None
        elif interval_us < 0:
            interval = 0.0
        else:
            interval = interval_us / 1e6
        return ACCEPTED if self.streams.set_interval(msg_id, interval, self._t) else FAILED

    def _cmd_get_message_interval(self, cmd: Cmd) -> int:
        msg_id = int(cmd.p1) if math.isfinite(cmd.p1) else -1
        if msg_id not in S.STREAMABLE:
            self._out.append(
                mavlink.MAVLink_message_interval_message(max(0, min(65535, msg_id)), 0)
            )
            return ACCEPTED
        iv = self.streams.interval(msg_id)
        self._out.append(
            mavlink.MAVLink_message_interval_message(msg_id, int(iv * 1e6) if iv > 0 else -1)
        )
        return ACCEPTED

    def _cmd_request_message(self, cmd: Cmd) -> int:
        msg_id = int(cmd.p1) if math.isfinite(cmd.p1) else -1
        if msg_id not in telemetry.ONE_SHOT:
            return UNSUPPORTED
        msg = telemetry.build(self, msg_id, self._t)
        if msg is None:
            return FAILED
        self._out.append(msg)
        return ACCEPTED

    def _cmd_autopilot_capabilities(self, cmd: Cmd) -> int:
        self._out.append(telemetry.autopilot_version(self))
        return ACCEPTED

    def _cmd_get_home(self, cmd: Cmd) -> int:
        if not self.home_set:
            return FAILED
        self._out.append(telemetry.home_position(self, self._t))
        return ACCEPTED

    def _cmd_mount(self, cmd: Cmd) -> int:
        if self.airframe.camera is None:
            return UNSUPPORTED
        cam = self.airframe.camera
        pitch = cmd.p1
        yaw = cmd.p3 if cmd.command == 205 else cmd.p2
        if math.isfinite(pitch):
            self.mount_pitch_deg = max(cam.pitch_min_deg, min(cam.pitch_max_deg, pitch))
        if math.isfinite(yaw):
            self.mount_yaw_deg = yaw
        return ACCEPTED

    def _cmd_calibration(self, cmd: Cmd) -> int:
        if self.armed:
            return DENIED
        if cmd.p3 == 1:
            self._text(SEV_INFO, "Updating barometer calibration")
            self._text(SEV_INFO, "Barometer calibration complete")
        if cmd.p6 == 2 and self.airframe.is_fixed_wing:
            self._text(SEV_INFO, "Airspeed 1 calibration started")
        return ACCEPTED

    # other messages ---------------------------------------------------------------

    def _on_set_mode(self, msg: Any, src: Peer, now: float) -> None:
        result = self._set_mode_common(int(msg.base_mode), int(msg.custom_mode))
        # ArduPilot acks SET_MODE with a COMMAND_ACK for "command" 11 (the message id)
        self._out.append(
            mavlink.MAVLink_command_ack_message(
                MSG_ID_SET_MODE, result, 0, 0, src.sysid, src.compid
            )
        )

    def _on_position_target_global(self, msg: Any, src: Peer, now: float) -> None:
        if self.mode_spec.behaviour != Behaviour.GUIDED:
            self.counters["position_target_not_guided"] += 1
            return
        mask = int(msg.type_mask)
        pos_ignore = mask & 0b111 == 0b111
        alt_ignore = bool(mask & 0b100)
        vel_ignore = mask & 0b111000 == 0b111000
        alt = self._alt_from_frame(int(msg.coordinate_frame), float(msg.alt))
        if self.firmware == Firmware.PLANE:
            if alt is None:
                self._text(SEV_WARNING, "Invalid coord frame in SET_POSTION_TARGET_GLOBAL_INT")
                return
            if not alt_ignore:
                self._change_alt(alt)
            return
        if not pos_ignore:
            lat, lon = msg.lat_int * 1e-7, msg.lon_int * 1e-7
            if alt is None or not (-90 <= lat <= 90 and -180 <= lon <= 180):
                self._set_nav(self._hold_here())
                return
            self._guided_goto(lat, lon, alt)
        elif not vel_ignore:
            vn, ve, vd = float(msg.vx), float(msg.vy), float(msg.vz)
            if not all(math.isfinite(v) and abs(v) < 1000 for v in (vn, ve, vd)):
                self._set_nav(self._hold_here())
                return
            b = self.body
            speed = math.hypot(vn, ve)
            t = GUIDED_VELOCITY_TIMEOUT_S
            task = FlyTo(
                b.n + vn * t, b.e + ve * t, b.alt - vd * t, accept_m=0.5, speed=speed, stop=True
            )
            self._set_nav(task, Purpose.GUIDED_VELOCITY)

    def _on_position_target_local(self, msg: Any, src: Peer, now: float) -> None:
        if self.mode_spec.behaviour != Behaviour.GUIDED:
            return
        if self.firmware == Firmware.PLANE:
            if int(msg.coordinate_frame) == 7:  # LOCAL_OFFSET_NED: altitude only
                task = self._leaf_task()
                if isinstance(task, (FlyTo, Hold, Loiter)) and math.isfinite(float(msg.z)):
                    task.alt += -float(msg.z)
                    self._text(SEV_INFO, f"Change alt to {task.alt - self.home_alt:.1f}")
            return
        mask = int(msg.type_mask)
        if mask & 0b111 == 0b111:
            return
        frame = int(msg.coordinate_frame)
        x, y, z = float(msg.x), float(msg.y), float(msg.z)
        if not all(math.isfinite(v) for v in (x, y, z)):
            self._set_nav(self._hold_here())
            return
        b = self.body
        if frame == 1:  # LOCAL_NED, from the EKF origin
            n, e, alt = x, y, self.origin_alt - z
        elif frame in (7, 9):  # LOCAL_OFFSET_NED, BODY_OFFSET_NED
            if frame == 9:
                h = math.radians(b.heading_deg)
                x, y = x * math.cos(h) - y * math.sin(h), x * math.sin(h) + y * math.cos(h)
            n, e, alt = b.n + x, b.e + y, b.alt - z
        else:
            self._set_nav(self._hold_here())
            return
        lat, lon = self.frame.to_latlon(n, e)
        self._guided_goto(lat, lon, alt)

    def _on_mission_count(self, msg: Any, src: Peer, now: float) -> None:
        transfer = self._transfer(msg)
        if transfer is not None:
            self._out.extend(transfer.handle_count(src, int(msg.count), now))

    def _on_mission_item(self, msg: Any, src: Peer, now: float) -> None:
        mtype = int(getattr(msg, "mission_type", 0))
        if mtype == MISSION and int(msg.current) in (2, 3):
            self._guided_mission_item(msg)
            return
        transfer = self._transfer(msg)
        if transfer is None:
            return
        item = MissionItem.from_message(msg)
        self._out.extend(
            transfer.handle_item(src, item, now, as_float=msg.get_type() == "MISSION_ITEM")
        )

    def _guided_mission_item(self, msg: Any) -> None:
        """MISSION_ITEM(_INT) with current=2 (guided goto) or 3 (change altitude)."""
        item = MissionItem.from_message(msg)
        if validate_item(item) != 0 or item.frame not in GLOBAL_FRAMES:
            self._out.append(mavlink.MAVLink_mission_ack_message(
                msg.get_srcSystem(), msg.get_srcComponent(), 1, MISSION))  # fmt: skip
            return
        if int(msg.current) == 3:
            self._change_alt(self._item_alt(item))
            result = 0
        elif self.mode_spec.behaviour != Behaviour.GUIDED:
            result = 1  # ERROR: only in GUIDED
        else:
            self._guided_goto(item.lat_deg, item.lon_deg, self._item_alt(item))
            result = 0
        self._out.append(mavlink.MAVLink_mission_ack_message(
            msg.get_srcSystem(), msg.get_srcComponent(), result, MISSION))  # fmt: skip

    def _on_mission_request(self, msg: Any, src: Peer, now: float) -> None:
        transfer = self._transfer(msg)
        if transfer is not None:
            as_int = msg.get_type() == "MISSION_REQUEST_INT"
            self._out.extend(transfer.handle_request(src, int(msg.seq), as_int=as_int))

    def _on_mission_request_list(self, msg: Any, src: Peer, now: float) -> None:
        transfer = self._transfer(msg)
        if transfer is not None:
            self._out.extend(transfer.handle_request_list(src))

    def _on_mission_clear_all(self, msg: Any, src: Peer, now: float) -> None:
        mtype = int(getattr(msg, "mission_type", 0))
        if mtype == 255:
            for each in self.transfers.values():
                each.handle_clear_all(src)
            self._out.append(mavlink.MAVLink_mission_ack_message(src.sysid, src.compid, 0, 255))
            return
        transfer = self._transfer(msg)
        if transfer is not None:
            self._out.extend(transfer.handle_clear_all(src))

    def _on_mission_set_current(self, msg: Any, src: Peer, now: float) -> None:
        self._set_mission_current(int(msg.seq))

    def _on_mission_write_partial_list(self, msg: Any, src: Peer, now: float) -> None:
        transfer = self._transfer(msg)
        if transfer is not None:
            self._out.extend(
                transfer.handle_partial_list(src, int(msg.start_index), int(msg.end_index), now)
            )

    def _transfer(self, msg: Any) -> ItemTransfer | None:
        mtype = int(getattr(msg, "mission_type", 0))
        transfer = self.transfers.get(mtype)
        if transfer is None:
            self.counters["bad_mission_type"] += 1
            src = Peer(msg.get_srcSystem(), msg.get_srcComponent())
            self._out.append(
                mavlink.MAVLink_mission_ack_message(src.sysid, src.compid, 3, mtype & 0xFF)
            )
        return transfer

    def _on_request_data_stream(self, msg: Any, src: Peer, now: float) -> None:
        self.streams.request_data_stream(
            int(msg.req_stream_id), int(msg.req_message_rate), bool(msg.start_stop), now
        )

    def _on_param_request_list(self, msg: Any, src: Peer, now: float) -> None:
        names = sorted(self.params)
        for index, name in enumerate(names):
            self._out.append(self._param_value(name, index, len(names)))

    def _on_param_request_read(self, msg: Any, src: Peer, now: float) -> None:
        names = sorted(self.params)
        name = _param_id(msg.param_id)
        if name in self.params:
            self._out.append(self._param_value(name, names.index(name), len(names)))
        elif 0 <= int(msg.param_index) < len(names) and name == "":
            idx = int(msg.param_index)
            self._out.append(self._param_value(names[idx], idx, len(names)))
        else:
            self.counters["param_unknown"] += 1

    def _on_param_set(self, msg: Any, src: Peer, now: float) -> None:
        name = _param_id(msg.param_id)
        value = float(msg.param_value)
        if name not in self.params or not math.isfinite(value):
            self.counters["param_unknown"] += 1
            return
        if name not in ("MIS_TOTAL", "SYSID_THISMAV", "Q_ENABLE", "FRAME_CLASS"):
            self.params[name] = (value, self.params[name][1])
        names = sorted(self.params)
        self._out.append(self._param_value(name, names.index(name), len(names)))

    def _param_value(self, name: str, index: int, count: int) -> Any:
        value, ptype = self.params[name]
        return mavlink.MAVLink_param_value_message(name.encode(), value, ptype, count, index)

    def _param(self, name: str) -> float:
        return self.params[name][0]

    def _on_timesync(self, msg: Any, src: Peer, now: float) -> None:
        if int(msg.tc1) == 0:
            self._out.append(mavlink.MAVLink_timesync_message(int(now * 1e9), int(msg.ts1)))

    def _on_ftp(self, msg: Any, src: Peer, now: float) -> None:
        """MAVLink FTP is not simulated: NAK every request at once (TerminateSession and
        ResetSessions are ACKed), so that MAVProxy and QGC fall back to PARAM_REQUEST_LIST
        and MISSION_REQUEST_* instead of timing out."""
        payload = bytes(msg.payload)
        if len(payload) < 12:
            self.counters["bad_ftp"] += 1
            return
        seq, session, opcode = int.from_bytes(payload[0:2], "little"), payload[2], payload[3]
        ack = opcode in (1, 2)
        error = 10 if opcode in (3, 4, 14) else 1  # FileNotFound for list/open/crc, else Fail
        reply = bytearray(251)
        reply[0:2] = ((seq + 1) & 0xFFFF).to_bytes(2, "little")
        reply[2], reply[3], reply[5] = session, 128 if ack else 129, opcode
        if not ack:
            reply[4], reply[12] = 1, error
        self._out.append(
            mavlink.MAVLink_file_transfer_protocol_message(0, src.sysid, src.compid, list(reply))
        )

    # ------------------------------------------------------------------ helpers

    def _text(self, severity: int, text: str) -> None:
        self._out.append(self._statustext(severity, text))

    @staticmethod
    def _statustext(severity: int, text: str) -> Any:
        return mavlink.MAVLink_statustext_message(severity, text.encode()[:50], 0, 0)


def _param_id(raw: Any) -> str:
    if isinstance(raw, bytes):
        raw = raw.decode("ascii", "replace")
    return str(raw).split("\x00", 1)[0].strip()


@dataclass(frozen=True, slots=True)
class Cmd:
    """COMMAND_LONG and COMMAND_INT, normalised (x/y in degrees for global frames)."""

    command: int
    p1: float
    p2: float
    p3: float
    p4: float
    x: float
    y: float
    z: float
    frame: int
    is_int: bool
    src: Peer

    @property
    def p6(self) -> float:
        return self.y


# COMMAND_LONG has no frame: ArduPilot converts it with these (GCS_MAVLINK and the
# vehicle's mav_frame_for_command_long): take-offs relative to home on a copter, local
# offset (z = height) on a plane, DO_SET_HOME absolute.
_COMMAND_LONG_FRAME = {22: 3, 84: 3, 179: 0}

_COMMANDS: dict[int, Callable[[SimAutopilot, Cmd], int]] = {
    176: SimAutopilot._cmd_set_mode,
    400: SimAutopilot._cmd_arm_disarm,
    22: SimAutopilot._cmd_takeoff,
    84: SimAutopilot._cmd_takeoff,
    192: SimAutopilot._cmd_reposition,
    178: SimAutopilot._cmd_change_speed,
    186: SimAutopilot._cmd_change_altitude,
    20: SimAutopilot._cmd_rtl,
    21: SimAutopilot._cmd_land,
    85: SimAutopilot._cmd_land,
    17: SimAutopilot._cmd_loiter_unlim,
    300: SimAutopilot._cmd_mission_start,
    208: SimAutopilot._cmd_parachute,
    179: SimAutopilot._cmd_set_home,
    224: SimAutopilot._cmd_set_mission_current,
    207: SimAutopilot._cmd_fence_enable,
    3000: SimAutopilot._cmd_vtol_transition,
    511: SimAutopilot._cmd_set_message_interval,
    510: SimAutopilot._cmd_get_message_interval,
    512: SimAutopilot._cmd_request_message,
    520: SimAutopilot._cmd_autopilot_capabilities,
    410: SimAutopilot._cmd_get_home,
    205: SimAutopilot._cmd_mount,
    1000: SimAutopilot._cmd_mount,
    241: SimAutopilot._cmd_calibration,
}

_HANDLERS: dict[str, Callable[[SimAutopilot, Any, Peer, float], None]] = {
    "COMMAND_LONG": SimAutopilot._on_command_long,
    "COMMAND_INT": SimAutopilot._on_command_int,
    "SET_MODE": SimAutopilot._on_set_mode,
    "SET_POSITION_TARGET_GLOBAL_INT": SimAutopilot._on_position_target_global,
    "SET_POSITION_TARGET_LOCAL_NED": SimAutopilot._on_position_target_local,
    "MISSION_COUNT": SimAutopilot._on_mission_count,
    "MISSION_ITEM": SimAutopilot._on_mission_item,
    "MISSION_ITEM_INT": SimAutopilot._on_mission_item,
    "MISSION_REQUEST": SimAutopilot._on_mission_request,
    "MISSION_REQUEST_INT": SimAutopilot._on_mission_request,
    "MISSION_REQUEST_LIST": SimAutopilot._on_mission_request_list,
    "MISSION_CLEAR_ALL": SimAutopilot._on_mission_clear_all,
    "MISSION_SET_CURRENT": SimAutopilot._on_mission_set_current,
    "MISSION_WRITE_PARTIAL_LIST": SimAutopilot._on_mission_write_partial_list,
    "REQUEST_DATA_STREAM": SimAutopilot._on_request_data_stream,
    "PARAM_REQUEST_LIST": SimAutopilot._on_param_request_list,
    "PARAM_REQUEST_READ": SimAutopilot._on_param_request_read,
    "PARAM_SET": SimAutopilot._on_param_set,
    "TIMESYNC": SimAutopilot._on_timesync,
    "FILE_TRANSFER_PROTOCOL": SimAutopilot._on_ftp,
}

# Received and deliberately ignored (a GCS heartbeat, acks of our own messages, ...)
_IGNORED = frozenset(
    {
        "HEARTBEAT", "MISSION_ACK", "COMMAND_ACK", "SYSTEM_TIME", "RC_CHANNELS_OVERRIDE",
        "MANUAL_CONTROL", "RADIO_STATUS", "RADIO", "GPS_RTCM_DATA", "GPS_INJECT_DATA",
        "STATUSTEXT", "PING", "SET_ATTITUDE_TARGET", "LOG_REQUEST_LIST",
        "TERRAIN_DATA", "TERRAIN_CHECK", "REQUEST_AUTOPILOT_CAPABILITIES", "SETUP_SIGNING",
    }
)  # fmt: skip
# messages whose target_component may be anything (they are for the whole system)
_ANY_COMPONENT = frozenset({"REQUEST_DATA_STREAM", "MISSION_REQUEST_LIST", "PARAM_REQUEST_LIST"})
