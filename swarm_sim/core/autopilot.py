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
from dataclasses import dataclass, field, replace
from typing import Any

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from . import inbound, mission_runner, telemetry
from . import streams as S
from .airframes import AirframeParams, VehicleModel
from .battery import Battery
from .commands import MAX_ALT_M
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
)
from .navigation import (
    FlyTo,
    Hold,
    Idle,
    Land,
    Loiter,
    NavTask,
    Parachute,
    Purpose,
    Sequence,
    Takeoff,
)

PREARM_DISPLAY_PERIOD_S = 30.0  # AP_Arming: failing pre-arm checks are repeated this often
COPTER_LAND_SETTLE_S = 1.0  # touchdown -> land complete (copter land detector)
PLANE_LAND_SETTLE_S = 5.0  # touchdown -> "Land complete" (recorded QuadPlane ~6 s)
RTL_LOITER_TIME_S = 5.0  # RTL_LOIT_TIME
FENCE_LOAD_DELAY_S = 0.1  # AC_PolyFence_loader loads an uploaded fence in the fence task
FENCE_LOAD_RETRY_S = 0.5  # ... and retries while the EKF has no origin
CRASH_IMPACT_M_S = 4.0


@dataclass(frozen=True)
class Home:
    """Boot position: latitude, longitude (deg), altitude above sea level (m), heading."""

    lat_deg: float
    lon_deg: float
    alt_m: float
    heading_deg: float = 0.0

    @classmethod
    def parse(cls, text: str) -> Home:
        """From SITL's --home text, LAT,LON,ALT,HDG (ALT and HDG optional)."""
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
        # AP_Rally: ArduPlane 0 (the recorded QuadPlane), ArduCopter and Rover 1
        "RALLY_INCL_HOME": (0.0 if fw == Firmware.PLANE else 1.0, 2),
        "FENCE_ACTION": (1.0, 2),
        # ArduPilot's defaults: Copter ALT_MAX|CIRCLE|POLYGON, Plane POLYGON, Rover
        # CIRCLE|POLYGON; the simulator enforces the POLYGON bit (polygon/circle items)
        "FENCE_TYPE": ({Firmware.COPTER: 7.0, Firmware.PLANE: 4.0}.get(fw, 6.0), 2),
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
            "WPNAV_ACCEL": (af.accel_m_s2 * 100, 9),
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
            "RTL_AUTOLAND": (0.0, 2),
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
        self._evt_t = now  # the time of the timeline event being run
        self._now = now  # time of the message or timer being handled
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
        self.fence_breach_count = 0
        self.fence_breach_ms = 0
        self.mount_pitch_deg = 0.0
        self.mount_yaw_deg = 0.0
        self._guided_radius = 0.0

        self.mission_items: list[MissionItem] = []
        self.fence_items: list[MissionItem] = []
        # what AC_PolyFence_loader has loaded: ArduPilot loads an uploaded fence in its
        # fence task a moment after the upload, and only once the EKF has an origin
        self.fence_loaded: list[MissionItem] = []
        self.rally_items: list[MissionItem] = []
        self.mission_seq = 0  # current NAV command index, 0: none
        self.mission_running = False
        self.mission_complete = False
        self._jumps: dict[int, int] = {}
        changed = self._items_changed
        self.transfers: dict[int, ItemTransfer] = {
            MISSION: ItemTransfer(
                MISSION,
                self.mission_items,
                home_item=self._home_item,
                current_seq=lambda: self.mission_seq,
                on_change=changed,
                statustext=self._statustext,
            ),
            FENCE: ItemTransfer(
                FENCE, self.fence_items, on_change=changed, statustext=self._statustext
            ),
            RALLY: ItemTransfer(
                RALLY, self.rally_items, on_change=changed, statustext=self._statustext
            ),
        }

        self.streams = S.StreamScheduler(now, self.options.stream_defaults)
        self._out: list[Any] = []
        self._timeline: list[tuple[float, Callable[[], None]]] = []
        self._build_timeline()

    # ------------------------------------------------------------------ public API

    def handle(self, msg: Any, now: float) -> list[Any]:
        """Process one decoded MAVLink message from a client; returns messages to send."""
        self._advance(now)
        self._now = now
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
        self._now = now
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

    def rebooted(self, now: float, *, keep_stores: bool = False) -> SimAutopilot:
        """The same vehicle after a power cycle at `now`: it boots again where
        it stands (on the ground: a reboot in flight is not modelled), with its time since
        boot from 0, no fix yet, disarmed, its parameters kept (ArduPilot's EEPROM) but
        the runtime fence enable lost, and by default empty mission, fence and rally
        stores (what a wiped or replaced board comes back with)."""
        lat, lon = self.latlon
        home = Home(lat, lon, self.body.ground_alt, self.body.heading_deg)
        options = replace(self.options, battery_pct=100.0 * self.battery.remaining_frac)
        new = SimAutopilot(self.airframe, home, now, options)
        new.params.update({k: v for k, v in self.params.items() if k != "FENCE_ENABLE"})
        new.counters["reboots"] = self.counters["reboots"] + 1
        if keep_stores:
            new.mission_items[:] = self.mission_items
            new.fence_items[:] = self.fence_items
            new.rally_items[:] = self.rally_items
        return new

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
    def wp_accel(self) -> float:
        """Horizontal acceleration in AUTO (copter: WPNAV_ACCEL)."""
        if self.firmware == Firmware.COPTER:
            return self._param("WPNAV_ACCEL") / 100.0
        return self.airframe.accel_m_s2

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
                self._evt_t = t_evt  # an action that reschedules itself counts from here
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
        if (
            self._param("FENCE_ENABLE") == 0
            or not int(self._param("FENCE_TYPE")) & 4
            or not self.fence_loaded
            or self.body.on_ground
        ):
            self.fence_breached = False
            return
        breached = self._outside_fence()
        if breached and not self.fence_breached:
            self.fence_breach_count += 1
            self.fence_breach_ms = self.boot_ms(self._t)
            self._text(SEV_NOTICE, "Fence Breached")
            action = int(self._param("FENCE_ACTION"))
            behaviour = self.mode_spec.behaviour
            if action != 0 and behaviour not in (Behaviour.RTL, Behaviour.LAND, Behaviour.QRTL):
                rtl = mode_number(self.firmware, "QRTL" if self._vtol_hovering() else "RTL")
                self._set_mode(rtl)
        self.fence_breached = breached

    def fence_present(self) -> bool:
        """AC_Fence::present(): FENCE_TYPE has the circle or an altitude fence, or the
        polygon/circle bit and a loaded fence. DO_FENCE_ENABLE(1) is FAILED without it."""
        types = int(self._param("FENCE_TYPE"))
        return bool(types & (1 | 2 | 8)) or bool(types & 4 and self.fence_loaded)

    def _fence_uploaded(self) -> None:
        self.fence_loaded = []  # re-indexed: unloaded until the fence task loads it
        bisect.insort(
            self._timeline, (self._now + FENCE_LOAD_DELAY_S, self._load_fence), key=lambda ev: ev[0]
        )

    def _load_fence(self) -> None:
        if not self.home_set:  # "fence load requires origin": try again later
            at = max(self._t, self._evt_t) + FENCE_LOAD_RETRY_S
            bisect.insort(self._timeline, (at, self._load_fence), key=lambda ev: ev[0])
            return
        self.fence_loaded = list(self.fence_items)

    def _outside_fence(self) -> bool:
        b = self.body
        items = self.fence_loaded
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
        n, e = self._stopping_point()  # brake, then hold where it stops
        return Hold(n, e, alt, vtol=self._vtol_hovering())

    def _rtl_point(self) -> tuple[float, float]:
        n, e, _ = self._rtl_target()
        return n, e

    def _rtl_target(self) -> tuple[float, float, float | None]:
        """The nearest rally point, or home if it is nearer and RALLY_INCL_HOME is 1 (as
        ArduPilot's AP_Rally, RALLY_LIMIT_KM not modelled), with the rally point's altitude
        (MSL; None for home)."""
        best: tuple[float, float, float | None] = (*self.home_ne, None)
        b = self.body
        best_d = math.hypot(best[0] - b.n, best[1] - b.e)
        if self._param("RALLY_INCL_HOME") == 0 and self.rally_items:
            best_d = math.inf
        for item in self.rally_items:
            n, e = self.frame.to_ne(item.lat_deg, item.lon_deg)
            d = math.hypot(n - b.n, e - b.e)
            if d < best_d:
                alt = self._alt_from_frame(item.frame, item.z)
                best, best_d = (n, e, alt), d
        return best

    def _rtl_task(self) -> NavTask:
        b = self.body
        hn, he, rally_alt = self._rtl_target()
        if self.firmware == Firmware.COPTER:
            # ArduCopter climbs to max(rally altitude, RTL_ALT) (and keeps a higher one)
            rtl_alt = max(b.alt, self.home_alt + self._param("RTL_ALT") / 100.0)
            if rally_alt is not None:
                rtl_alt = max(rtl_alt, rally_alt)
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
            # fly home, then (in _nav_done) loiter there or land via DO_LAND_START
            rtl = self._param("RTL_ALTITUDE")
            alt = b.alt if rtl < 0 else self.home_alt + rtl
            if rally_alt is not None:
                # ArduPlane flies to a rally point at the rally point's own altitude
                # (recorded: plane-rtl-rally-alt-zero descends into the ground; RTL_ALTITUDE
                # is no floor)
                alt = rally_alt
            return FlyTo(hn, he, alt, accept_m=self.loiter_radius, stop=False)
        return FlyTo(hn, he, b.alt, accept_m=self._param("WP_RADIUS"), stop=True)

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
            mission_runner.start_or_resume(self)
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
            sn, se = self._stopping_point()
            self._set_nav(Hold(sn, se, alt, vtol=spec.vtol or not self.fixed_wing))
        elif beh == Behaviour.GUIDED:
            self._set_nav(self._hold_here())
        elif beh == Behaviour.RTL:
            if (
                self.firmware == Firmware.PLANE
                and self._param("RTL_AUTOLAND") == 2
                and mission_runner.jump_to_landing_sequence(self)
            ):
                return
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
            mission_runner.item_done(self)
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
        elif (
            beh == Behaviour.RTL and self.firmware == Firmware.PLANE and isinstance(self.nav, FlyTo)
        ):
            # RTL_AUTOLAND=1: home reached, land via the mission's DO_LAND_START
            if self._param("RTL_AUTOLAND") == 1 and mission_runner.jump_to_landing_sequence(self):
                return
            self._set_nav(Loiter(self.nav.n, self.nav.e, self.nav.alt))
        elif beh == Behaviour.TAKEOFF:
            self._set_nav(Loiter(*self._here()))
        elif isinstance(self.nav, Parachute):
            self._set_nav(Idle())
        else:
            self._set_nav(self._hold_here())

    def _items_changed(self, mission_type: int) -> list[Any]:
        if mission_type == FENCE:
            self._fence_uploaded()
        return mission_runner.items_changed(self, mission_type)

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

    def _wp_radius(self) -> float:
        if self.firmware == Firmware.COPTER:
            return self._param("WPNAV_RADIUS") / 100.0
        return self._param("WP_RADIUS")

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
            and not mission_runner.starts_with_takeoff(self)
        ):
            self._text(SEV_CRITICAL, "Auto: Missing Takeoff Cmd")
            return False
        self.mode = number
        self._speed = None
        self._out.append(telemetry.heartbeat(self))
        self._enter_mode(spec)
        return True

    def prearm_failure(self) -> str | None:
        """The first failing arming check, worded as ArduPilot's PreArm messages; None when
        the vehicle may arm."""
        if not self.ready:
            return "Initialising"  # booting (arming is refused without a text until ready)
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
        if self._param("FENCE_ENABLE") != 0 and self.fence_loaded and self._outside_fence():
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
            and mtype not in inbound.ANY_COMPONENT
        ):
            self.counters["foreign_component"] += 1
            return
        handler = inbound.HANDLERS.get(mtype)
        if handler is None:
            self.counters["ignored" if mtype in inbound.IGNORED else "unhandled"] += 1
            return
        self.counters[f"rx:{mtype}"] += 1
        handler(self, msg, src, now)

    # commands --------------------------------------------------------------------

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

    def _change_alt(self, alt: float) -> None:
        task = self._leaf_task()
        if isinstance(task, (FlyTo, Hold, Loiter)):
            task.alt = alt
        elif self.mode_spec.behaviour == Behaviour.GUIDED:
            hold = self._hold_here()
            if isinstance(hold, (Hold, Loiter)):
                hold.alt = alt
            self._set_nav(hold)

    def _set_mission_current(self, seq: int) -> bool:
        if not 0 < seq < len(self.mission_items):
            return False
        self.mission_seq = seq
        self.mission_complete = False
        if self.mode_spec.behaviour == Behaviour.AUTO:
            self.mission_running = True
            mission_runner.run_from(self, seq)
        self._out.append(telemetry.mission_current(self))
        return True

    def _param_value(self, name: str, index: int, count: int) -> Any:
        value, ptype = self.params[name]
        return mavlink.MAVLink_param_value_message(name.encode(), value, ptype, count, index)

    def _param(self, name: str) -> float:
        return self.params[name][0]

    def _text(self, severity: int, text: str) -> None:
        self._out.append(self._statustext(severity, text))

    @staticmethod
    def _statustext(severity: int, text: str) -> Any:
        return mavlink.MAVLink_statustext_message(severity, text.encode()[:50], 0, 0)
