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

`SimAutopilot` composes the parts listed in `vehicle.py`, each owning its state (modes,
arming, navigator, mission runner, item stores, fence, failsafes, parameters, ...); it
runs time (boot events, physics steps), routes each inbound message to its handler
(`inbound.HANDLERS`, `commands.COMMANDS`) and sends the due telemetry.

Errors by blame: a peer's bad message is counted in `counters` and dropped; misuse of
this API (e.g. time going backwards) raises.
"""

from __future__ import annotations

import math
from collections import Counter
from dataclasses import replace
from typing import Any

from . import inbound, telemetry
from .airframes import AirframeParams, VehicleModel
from .arming import Arming
from .battery import Battery, current_draw
from .boot import Boot
from .failsafes import Failsafes
from .fence import Fence
from .firmware import FIRMWARE_OF, MAV_TYPE_OF, SEV_INFO, ModeSpec
from .geo import LocalFrame, wrap_360
from .home import SITL_HOME, Home, HomeState
from .kinematics import Body, EventKind, ModelEvent, VtolState, make_model
from .mission import FENCE, MISSION, MissionItem, Peer
from .mission_runner import MissionRunner
from .modes import Modes
from .navigation import NavTask, Parachute
from .navigator import Navigator
from .options import SimOptions, StartupTimes
from .outbox import Outbox, statustext
from .params import Parameters, defaults
from .payload import Mount
from .sensors import Sensors
from .stores import ItemStores
from .streams import StreamScheduler
from .timeline import Timeline

__all__ = ["SITL_HOME", "Home", "SimAutopilot", "SimOptions", "StartupTimes"]


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
        self.options = opts = options or SimOptions()
        if not 1 <= opts.sysid <= 255:
            raise ValueError("sysid must be 1..255")
        self.airframe = af = airframe
        self.model = airframe.model
        self.firmware = fw = FIRMWARE_OF[self.model]
        self.mav_type = MAV_TYPE_OF[self.model]
        self.sysid = opts.sysid
        self.compid = opts.compid
        self.kinematics = make_model(airframe)
        self.frame = LocalFrame(home.lat_deg, home.lon_deg)
        self.counters: Counter[str] = Counter()

        self.timeline = timeline = Timeline(now)
        self.out = out = Outbox()
        self.params: Parameters = defaults(
            fw, self.model, af, sysid=opts.sysid, wind=(opts.wind_speed_m_s, opts.wind_from_deg)
        )
        self.body = body = Body(
            alt=home.alt_m, ground_alt=home.alt_m, heading_deg=wrap_360(home.heading_deg)
        )
        if self.model == VehicleModel.VTOL:
            body.vtol_state = VtolState.MC
        self.battery = Battery(af.battery, remaining_pct=opts.battery_pct)
        self.sensors = Sensors()
        self.home = HomeState(self.frame, home.alt_m, now)
        self.stores = stores = ItemStores(
            home_item=self.home.item, on_change=self._items_changed, statustext=statustext
        )
        self.fence = Fence(self.params, stores, self.frame, self.home, timeline)
        self.navigator = Navigator(af, fw, body, self.params, self.frame, self.home, stores, out)
        self.arming = Arming(
            af,
            fw,
            body=body,
            battery=self.battery,
            sensors=self.sensors,
            params=self.params,
            fence=self.fence,
            home=self.home,
            progress=stores.progress,
            navigator=self.navigator,
            timeline=timeline,
            out=out,
        )
        self.mission = MissionRunner(
            af,
            fw,
            body=body,
            frame=self.frame,
            stores=stores,
            params=self.params,
            sensors=self.sensors,
            home=self.home,
            navigator=self.navigator,
            arming=self.arming,
            timeline=timeline,
            out=out,
        )
        self.modes = Modes(
            af,
            fw,
            self.mav_type,
            body=body,
            sensors=self.sensors,
            params=self.params,
            stores=stores,
            navigator=self.navigator,
            arming=self.arming,
            mission=self.mission,
            timeline=timeline,
            out=out,
        )
        self.mission.modes = self.modes  # a mission ends in RTL, a landing sequence in AUTO
        self.failsafes = Failsafes(
            fw,
            body=body,
            params=self.params,
            fence=self.fence,
            navigator=self.navigator,
            modes=self.modes,
            out=out,
        )
        self.boot = Boot(
            fw,
            opts.startup,
            texts=opts.boot_texts,
            body=body,
            sensors=self.sensors,
            home=self.home,
            modes=self.modes,
            arming=self.arming,
            timeline=timeline,
            out=out,
        )
        self.streams = StreamScheduler(now, opts.stream_defaults)
        self.mount = Mount(af.camera) if af.camera is not None else None
        self._next_phys = now

    # ------------------------------------------------------------------ public API

    def handle(self, msg: Any, now: float) -> list[Any]:
        """Process one decoded MAVLink message from a client; returns messages to send."""
        self._advance(now)
        self.timeline.now = now
        try:
            self._dispatch(msg, now)
        except (ValueError, TypeError, OverflowError) as exc:
            # a malformed field from a peer: count and drop, never crash
            self.counters["bad_field"] += 1
            self.counters[f"bad_field:{type(exc).__name__}"] += 1
        self._emit_due(now)
        return self.out.flush()

    def on_timer(self, now: float) -> list[Any]:
        """Run physics, boot events, protocol timeouts and due telemetry up to `now`."""
        self._advance(now)
        self.timeline.now = now
        timeouts = self.stores.update(now)
        if timeouts:
            self.out.extend(timeouts)
        self._emit_due(now)
        return self.out.flush()

    def next_deadline(self) -> float | None:
        t = self._next_phys
        if self.timeline.next_at < t:
            t = self.timeline.next_at
        due = self.streams.next_deadline()
        if due is not None and due < t:
            t = due
        due = self.stores.next_deadline()
        if due is not None and due < t:
            t = due
        if self.sensors.ready and not self.arming.armed and self.arming.prearm_next < t:
            t = self.arming.prearm_next
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
            new.stores.keep(self.stores)
        return new

    # ------------------------------------------------------------------ state views
    # (tests, the runtime, FastFleet and docs/simulator.md read these)

    @property
    def mode(self) -> int:
        return self.modes.mode

    @property
    def mode_spec(self) -> ModeSpec:
        return self.modes.spec

    @property
    def mode_name(self) -> str:
        return self.modes.spec.name

    @property
    def armed(self) -> bool:
        return self.arming.armed

    @property
    def crashed(self) -> bool:
        return self.arming.crashed

    @property
    def ready(self) -> bool:
        return self.sensors.ready

    @property
    def gps_fix(self) -> bool:
        return self.sensors.gps_fix

    @property
    def ekf_position(self) -> bool:
        return self.sensors.ekf_position

    @property
    def latlon(self) -> tuple[float, float]:
        return telemetry.latlon(self)

    @property
    def rel_alt_m(self) -> float:
        return self.body.alt - self.home.alt

    @property
    def home_set(self) -> bool:
        return self.home.is_set

    @property
    def home_ne(self) -> tuple[float, float]:
        return self.home.ne

    @property
    def home_alt(self) -> float:
        return self.home.alt

    @property
    def nav(self) -> NavTask:
        """The navigation task flown now."""
        return self.navigator.task

    @property
    def transfers(self) -> dict[int, Any]:
        return self.stores.transfers

    @property
    def mission_items(self) -> list[MissionItem]:
        return self.stores.mission

    @property
    def fence_items(self) -> list[MissionItem]:
        return self.stores.fence

    @property
    def rally_items(self) -> list[MissionItem]:
        return self.stores.rally

    @rally_items.setter
    def rally_items(self, items: list[MissionItem]) -> None:
        self.stores.rally = items

    @property
    def mission_seq(self) -> int:
        return self.stores.progress.seq

    @property
    def mission_running(self) -> bool:
        return self.stores.progress.running

    @property
    def fence_breach_count(self) -> int:
        return self.fence.breach_count

    def fence_present(self) -> bool:
        return self.fence.present()

    def prearm_failure(self) -> str | None:
        """The first failing arming check in the current mode (None: it may arm)."""
        return self.arming.prearm_failure(self.modes.spec)

    def boot_ms(self, now: float) -> int:
        return self.timeline.boot_ms(now)

    # ------------------------------------------------------------------ time

    def _advance(self, now: float) -> None:
        tl = self.timeline
        if now < tl.t - 1e-6:
            raise ValueError(f"time went backwards: {now} < {tl.t}")
        while True:
            t_evt = tl.next_at
            t_phys = self._next_phys
            if min(t_evt, t_phys) > now:
                break
            if t_evt <= t_phys:
                tl.run_next()
            else:
                dt = self._phys_dt()
                self._physics_step(t_phys - tl.t if t_phys > tl.t else 0.0, t_phys)
                tl.t = t_phys
                self._next_phys = t_phys + dt
        if self.arming.prearm_due(now):
            self.arming.show_prearm_failure(now, self.modes.spec)

    def _phys_dt(self) -> float:
        b = self.body
        idle = not self.arming.armed and b.on_ground and b.groundspeed < 0.01
        return 1.0 if idle else self.options.physics_dt_s

    def _physics_step(self, dt: float, t: float) -> None:
        b, nav, arming = self.body, self.navigator, self.arming
        spd = self.params.value("SIM_WIND_SPD")
        frm = math.radians(self.params.value("SIM_WIND_DIR"))
        b.wind_n, b.wind_e = -spd * math.cos(frm), -spd * math.sin(frm)
        if dt <= 0.0:
            return
        for ev in self.kinematics.step(b, nav.target(arming.armed), dt):
            self._model_event(ev)
        arming.track_ground(t)
        if (arming.armed or isinstance(nav.task, Parachute)) and nav.task.update(nav, dt):
            self.modes.task_done()
        self.battery.step(current_draw(self.airframe, b, arming.armed), dt)
        if arming.armed:
            arming.auto_disarm_check(t)
            self.failsafes.check(t)

    def _model_event(self, ev: ModelEvent) -> None:
        if ev.kind == EventKind.TOUCHDOWN:
            self.arming.touched_down(ev.value)
        elif ev.kind == EventKind.TRANSITION_STARTED:
            self.out.text(SEV_INFO, f"Transition started airspeed {ev.value:.1f}")
        elif ev.kind == EventKind.TRANSITION_AIRSPEED:
            self.out.text(SEV_INFO, f"Transition airspeed reached {ev.value:.1f}")
        elif ev.kind == EventKind.TRANSITION_DONE:
            self.out.text(SEV_INFO, "Transition done")

    def _emit_due(self, now: float) -> None:
        for mid in self.streams.due(now):
            msg = telemetry.build(self, mid, now)
            if msg is not None:
                self.out.send(msg)

    def _items_changed(self, mission_type: int) -> list[Any]:
        """An upload or a clear of a store completed."""
        if mission_type == FENCE:
            self.fence.uploaded()
        if mission_type == MISSION:
            return self.mission.items_changed()
        return []

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
