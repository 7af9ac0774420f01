"""The vehicle node process: the I/O shell around `swarm_node.core.node.NodeCore`.

One thread runs the loop: it waits on an inbox (fed by Zenoh callbacks and the
autopilot link) until the core's next deadline, hands inputs and timers to the core
and carries out its outputs: publish on Zenoh, submit to the autopilot, run plan jobs,
log. Every few hundred milliseconds the autopilot state snapshot is handed to the core
(the link tracks MAVLink at full rate in its own thread; the core decides at 5 Hz).

Planning never runs on that loop: a `PlanJob` goes to `PlanWorker`, a spawn-context
process pool of one (the planners are CPU-bound Python holding the GIL; in a thread
they would slow the loop), whose outcome comes back through the inbox as `PlanDone`.
`planner="thread"` runs them in a thread instead (no process start-up; measured in
`python -m bench planning`). Plan jobs are handed to the worker after the loop's step
(starting the worker process takes a while on a loaded host).

Only the loop thread touches the core. The queryables (peers, zones, declared state)
answer from a snapshot the loop refreshes at 5 Hz, so a Zenoh callback never waits for
the loop (a node starting its first plan job left `gcs peers` unanswered).

Declared state: restored from the node's database at start (`Learned` from
"database"), asked of every peer that comes alive (its DECLARED queryable), stored on
every change by `StateWriter` off the loop.

The input boundary (docs/security.md): every sample was size-checked, decoded and its
key checked against its payload by the bus (swarm_proto.intake); what the bus dropped
comes here as `Dropped` and goes to the `InputAlarm` (counts for the peers queryable, a
MALFORMED_INPUT alert at most once a minute per topic). Peers' statuses and infos come
with their source and pass the `IdentityBook` (core/identity.py) first; so do the
holder tokens (`id/<id>/<session>`) and anything in this vehicle's own name published
by another session (`Own`): its news goes to the core as `IdentityNews` and
`PeerAlive`. Nodes do not read `alive/<id>` tokens (a foreign one cannot be told from
ours).
"""

from __future__ import annotations

import dataclasses
import logging
import multiprocessing
import os
import queue
import threading
import time
from collections.abc import Callable
from concurrent.futures import Executor, Future, ProcessPoolExecutor, ThreadPoolExecutor
from dataclasses import dataclass
from typing import Protocol, TypeGuard

import msgspec
import zenoh

from swarm_proto import (
    Ack,
    Alert,
    AlertCode,
    AlertFlag,
    Clock,
    DeclaredState,
    DroppedInput,
    FsmState,
    Mission,
    MissionType,
    NoFlyZone,
    PeerEntry,
    Severity,
    SwarmView,
    VehicleInfo,
    VehicleStatus,
    VehicleType,
    intake,
    lan,
)
from swarm_proto.clock import SteadyClock
from swarm_proto.errors import DecodeError
from swarm_proto.intake import InputAlarm, Source
from swarm_proto.session import SwarmBus
from swarm_proto.text import short_text
from swarm_proto.topics import (
    ACK,
    COMMAND,
    DECLARED,
    FLEET,
    INFO,
    INTENT,
    LINEAGE,
    MAVLINK_COMMAND,
    MISSION,
    MISSIONS,
    PEERS,
    STATUS,
    TARGET,
    VOTE,
    ZONE,
    ZONES,
)

from ..core.autopilot.requests import ApRequest, ApResult, RelayCommand
from ..core.autopilot.state import AutopilotState
from ..core.identity import HolderAlive, IdentityBook
from ..core.identity import Output as IdentityOutput
from ..core.mission.share import PlanOutcome, PlanRequest, run_plan, warm
from ..core.mission.tasking import RETASK_MODULE, VOTING_MODULE, TaskingSettings
from ..core.node import (
    AutopilotResult,
    AutopilotUpdate,
    Input,
    Learned,
    NodeCore,
    NodeSettings,
    Note,
    Output,
    PeerAlive,
    Persist,
    PlanDone,
    PlanJob,
    Publish,
    Received,
    Submit,
)
from ..core.outputs import Sessions, StreamWish, ToAutopilot, ToClient
from ..core.profile import VehicleProfile
from ..database import ProfileError, SwarmDatabase
from ..database.queryable import DatabaseQueryable
from ..database.resolve import mav_sysid_of
from ..database.state import NodeStateStore
from .config import NodeConfig
from .parent_watch import exit_with_parent
from .passthrough import PassthroughRelay, RelayPort
from .persistence import StateWriter

log = logging.getLogger("swarm_node")


def node_settings(config: NodeConfig) -> NodeSettings:
    """The core's settings from the node's configuration (file and command line)."""
    return NodeSettings(
        status_period_s=1.0 / config.status_hz,
        info_period_s=1.0 / config.info_hz,
        plan_timeout_s=config.plan_timeout_s,
        stale_after_s=config.stale_after_s,
        avoidance=config.avoidance,
        intent=config.intent,
    )


def mission_defaults_of(database: SwarmDatabase) -> dict[MissionType, dict[str, float]]:
    """Every kind of mission's default parameters, from the swarm database."""
    return {t: database.mission_defaults(t) for t in MissionType}


def tasking_settings_of(database: SwarmDatabase) -> TaskingSettings:
    """The voting weights, re-tasking rules and payload hierarchy from the swarm
    database (a database without a module's row: that module's defaults; invalid
    values: ScoreError / RetaskError, refused at start)."""

    def params(module: str) -> dict[str, float]:
        try:
            return database.module_params(module)
        except ProfileError:
            return {}

    return TaskingSettings(params(VOTING_MODULE), params(RETASK_MODULE), database.payload_classes())


class AutopilotPort(Protocol):
    """What the node needs of an autopilot link."""

    @property
    def state(self) -> AutopilotState: ...

    def submit(self, request: ApRequest) -> Future[ApResult]: ...

    def close(self) -> None: ...


class NoAutopilot:
    """A node without an autopilot (it watches the swarm): every request fails."""

    state = AutopilotState()

    def submit(self, request: ApRequest) -> Future[ApResult]:
        f: Future[ApResult] = Future()
        f.set_result(ApResult(request.request_id, False, "no autopilot configured"))
        return f

    def close(self) -> None:
        pass


def _relays(autopilot: object) -> TypeGuard[RelayPort]:
    """Whether an autopilot port can carry passthrough sessions (an AutopilotLink)."""
    return all(hasattr(autopilot, n) for n in ("relay", "set_tap", "want_rates", "on_frames"))


class _Snapshot(msgspec.Struct, frozen=True):
    """What the queryables answer, refreshed by the loop (no lock in Zenoh callbacks)."""

    # id, type, fleet, fsm, heard, untrusted
    peers: tuple[tuple[int, int, int, int, float, bool], ...] = ()
    zones: tuple[NoFlyZone, ...] = ()
    declared: DeclaredState | None = None
    missions: tuple[Mission, ...] = ()
    dropped: tuple[DroppedInput, ...] = ()
    conflict: str = ""


# What the bus and Zenoh hand the loop besides the core's inputs (the input boundary)
@dataclass(frozen=True)
class Heard:
    """A peer's VehicleStatus or VehicleInfo, with its source (for the identity book)."""

    msg: VehicleStatus | VehicleInfo
    source: Source


@dataclass(frozen=True)
class Own:
    """A VehicleStatus or VehicleInfo in this vehicle's name from another session."""

    msg: VehicleStatus | VehicleInfo
    source: Source


@dataclass(frozen=True)
class Holder:
    """A holder token `id/<node_id>/<zid>` appeared or went."""

    node_id: int
    zid: str
    alive: bool


@dataclass(frozen=True)
class Dropped:
    """A sample the bus dropped (swarm_proto.intake reasons)."""

    key: str
    reason: str
    text: str


Boundary = Heard | Own | Holder | Dropped


SNAPSHOT_PERIOD_S = 0.2  # wall seconds
CLOCK_STEP_REPORT_S = 1.0  # a system clock step larger than this is reported


class PlanWorker:
    """Runs plan jobs off the control loop; outcomes go to `deliver`."""

    def __init__(self, deliver: Callable[[Input], None], kind: str = "process") -> None:
        if kind not in ("process", "thread"):
            raise ValueError(f"planner must be process or thread, not {kind!r}")
        self.kind = kind
        self._deliver = deliver
        self._pool: Executor | None = None

    @property
    def started(self) -> bool:
        return self._pool is not None

    def start(self) -> None:
        """Start the worker; a process worker is spawned and imports the planners now
        (`share.warm`: about 0.5 s of CPU), not in the first plan job's time."""
        if self.kind == "process":
            ctx = multiprocessing.get_context("spawn")
            self._pool = ProcessPoolExecutor(
                max_workers=1, mp_context=ctx, initializer=exit_with_parent, initargs=(os.getpid(),)
            )
            try:
                self._pool.submit(warm)
            except Exception:  # a broken pool: the first plan job says so
                log.exception("could not start the planner worker")
        else:
            self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="planner")

    def submit(self, request: PlanRequest) -> None:
        if self._pool is None:
            self.start()
        assert self._pool is not None
        deliver = self._deliver

        def done(f: Future[PlanOutcome]) -> None:
            try:
                outcome = f.result()
            except Exception as exc:  # a crashed worker is a failed plan, not a hung node
                log.exception("plan job %d failed", request.job_id)
                outcome = PlanOutcome(request.job_id, None, f"planner crashed: {exc}"[:60])
            deliver(PlanDone(outcome))

        try:
            self._pool.submit(run_plan, request).add_done_callback(done)
        except Exception as exc:  # a broken pool: say so, and start a new one next time
            log.exception("could not start plan job %d", request.job_id)
            self._pool = None
            deliver(PlanDone(PlanOutcome(request.job_id, None, f"planner: {exc}"[:60])))

    def close(self) -> None:
        if self._pool is not None:
            self._pool.shutdown(wait=False, cancel_futures=True)
            self._pool = None


class NodeRuntime:
    def __init__(
        self,
        config: NodeConfig,
        profile: VehicleProfile,
        clock: Clock,
        autopilot: AutopilotPort | None = None,
        *,
        bus: SwarmBus | None = None,
        database: SwarmDatabase | None = None,
        planner: str = "process",
    ) -> None:
        self.config = config
        self.clock = clock
        self.autopilot: AutopilotPort = autopilot or NoAutopilot()
        settings = node_settings(config)
        if database is not None:  # the autopilot must be the system the database says
            try:
                sysid = mav_sysid_of(database.system_params(profile.vehicle_id), profile.vehicle_id)
            except ProfileError as exc:  # refused at start, in one line (exit 2)
                raise ValueError(str(exc)) from exc
            settings = dataclasses.replace(settings, mav_sysid=sysid)
        self.core = NodeCore(
            profile,
            settings,
            now=clock.now(),
            # the planners need every fleet member's airframe: the database knows them all
            fleet_profiles=(
                {p.vehicle_id: p for p in database.profiles()}
                if database is not None
                else {profile.vehicle_id: profile}
            ),
            mission_defaults=mission_defaults_of(database) if database is not None else {},
            tasking_settings=(
                tasking_settings_of(database) if database is not None else TaskingSettings()
            ),
        )
        self.inbox: queue.SimpleQueue[Input | Boundary] = queue.SimpleQueue()
        self.planner = PlanWorker(self.inbox.put, planner)
        self._plan_jobs: list[PlanRequest] = []  # handed to the worker after the loop step
        self.bus = bus or SwarmBus.open(config.zenoh, config.swarm, on_bad_input=self._bad_input)
        if bus is not None:
            bus.on_bad_input = self._bad_input
        self.alarm = InputAlarm(config.swarm)  # what the bus dropped: counts, alerts
        self.identity = IdentityBook(profile.vehicle_id, self.bus.zid)
        self._sysid = 0  # the autopilot's MAVLink system id, as last told to the bus
        self._untrusted: frozenset[int] = frozenset()  # as last logged
        # MAVLink passthrough sessions (ground stations' QGroundControl, MAVProxy), when the
        # autopilot is a link that relays (core/passthrough.py decides): made at start,
        # the link may be given after the node is built (launch.py)
        self.passthrough: PassthroughRelay | None = None
        self._queryable: zenoh.Queryable | None = None
        self._zones_queryable: zenoh.Queryable | None = None
        self._missions_queryable: zenoh.Queryable | None = None
        self._declared_queryable: zenoh.Queryable | None = None
        self._ask_peers: queue.SimpleQueue[int | None] = queue.SimpleQueue()
        self._asker: threading.Thread | None = None
        self.database = database
        self._db_server: DatabaseQueryable | None = None
        self.store = NodeStateStore(database, profile.vehicle_id) if database is not None else None
        self.writer = (
            StateWriter(self.store, self.inbox.put, name=f"state-{profile.vehicle_id}")
            if self.store is not None
            else None
        )
        self._snap = _Snapshot()
        self._snap_at = 0.0
        self._clock_step_s = 0.0  # the system clock's step last reported (SteadyClock)
        self._clock_checked = 0.0
        self._ap_period_s = 0.2

    # ------------------------------------------------------------------ wiring
    def _bad_input(self, key: str, exc: Exception) -> None:
        reason = exc.reason if isinstance(exc, DecodeError) else intake.MALFORMED
        self.inbox.put(Dropped(key[:200], reason, str(exc)[:200]))

    def _received(self, msg: msgspec.Struct, key: str) -> None:
        self.inbox.put(Received(msg))

    def _heard(self, msg: VehicleStatus | VehicleInfo, key: str, source: Source) -> None:
        self.inbox.put(Heard(msg, source))

    def _own(self, msg: VehicleStatus | VehicleInfo, key: str, source: Source) -> None:
        self.inbox.put(Own(msg, source))

    def _holder(self, node_id: int, zid: str, alive: bool) -> None:
        self.inbox.put(Holder(node_id, zid, alive))

    def on_autopilot_event(self, event: object) -> None:
        """Link events (on the link's thread): state changes that matter now (link lost
        or restored, armed, mode, landed) reach the core at once instead of at the next
        200 ms poll."""
        from ..core.autopilot.events import (
            ArmedChanged,
            LandedChanged,
            LinkLost,
            LinkRestored,
            ModeChanged,
        )

        if isinstance(event, LinkLost | LinkRestored | ArmedChanged | ModeChanged | LandedChanged):
            self.inbox.put(AutopilotUpdate(self.autopilot.state))

    # ------------------------------------------------------------------ the input boundary
    def _handle(self, event: Input | Boundary, now: float) -> list[Output]:
        """One input: the boundary's own (identity, drops), or the core's."""
        if isinstance(event, Heard):
            return self._on_heard(event, now)
        if isinstance(event, Own):
            msg = event.msg
            sysid = msg.mav_sysid if isinstance(msg, VehicleInfo) else 0
            return self._identity_news(self.identity.heard_own(event.source, now, sysid=sysid), now)
        if isinstance(event, Holder):
            news = self.identity.holder(event.node_id, event.zid, event.alive, now)
            return self._identity_news(news, now)
        if isinstance(event, Dropped):
            return self._dropped(event, now)
        return self.core.handle(event, now)

    def _on_heard(self, event: Heard, now: float) -> list[Output]:
        msg = event.msg
        if isinstance(msg, VehicleInfo):
            keep, news = self.identity.heard(
                msg.vehicle_id,
                event.source,
                now,
                sysid=msg.mav_sysid,
                reports_conflict=AlertCode.IDENTITY_CONFLICT in msg.errors,
                ground=msg.vehicle_type == VehicleType.GCS,
            )
        else:
            keep, news = self.identity.heard(
                msg.vehicle_id,
                event.source,
                now,
                reports_conflict=bool(msg.alerts & AlertFlag.IDENTITY_CONFLICT),
            )
        out = self._identity_news(news, now)
        if keep:
            return out + self.core.handle(Received(msg), now)
        kind = "status" if isinstance(msg, VehicleStatus) else "info"
        self.alarm.counts[(f"vehicle/*/{kind}", intake.IDENTITY)] += 1
        return out

    def _identity_news(self, news: list[IdentityOutput], now: float) -> list[Output]:
        out: list[Output] = []
        for n in news:
            if isinstance(n, HolderAlive):
                out += self.core.handle(PeerAlive(n.node_id, n.alive), now)
                if n.alive:
                    self._ask_peers.put(n.node_id)  # learn what it holds (off the loop)
                continue
            before, self._untrusted = self._untrusted, n.untrusted
            for vid in sorted(n.untrusted - before):
                log.warning(
                    "node %d: vehicle %d untrusted: %s",
                    self.core.self_id,
                    vid,
                    self.identity.why(vid),
                )
            for vid in sorted(before - n.untrusted):
                log.info("node %d: vehicle %d trusted again", self.core.self_id, vid)
            out += self.core.handle(n, now)
        return out

    def _dropped(self, event: Dropped, now: float) -> list[Output]:
        alarm = self.alarm.dropped(event.key, event.reason, event.text, now)
        if alarm is None:
            return []
        return [self._malformed(alarm, now)]

    def _malformed(self, alarm: intake.Alarm, now: float) -> Publish:
        return Publish(
            Alert(
                self.core.self_id,
                max(0.0, now),
                Severity.WARNING,
                AlertCode.MALFORMED_INPUT,
                alarm.text,
            )
        )

    def _boundary_timer(self, now: float) -> list[Output]:
        out: list[Output] = [self._malformed(a, now) for a in self.alarm.on_timer(now)]
        due = self.identity.next_deadline()
        if due is not None and now >= due:
            out += self._identity_news(self.identity.on_timer(now), now)
        return out

    def _boundary_deadline(self) -> float:
        due = [d for d in (self.alarm.next_deadline(), self.identity.next_deadline()) if d]
        return min(due) if due else float("inf")

    def _note_sysid(self, state: AutopilotState) -> None:
        """The autopilot's MAVLink system id goes into what we publish (and is what our
        own name must not be heard with from another airframe)."""
        if state.sysid and state.sysid != self._sysid:
            self._sysid = state.sysid
            self.bus.set_sysid(state.sysid)
            self.identity.set_own_sysid(state.sysid)

    # ------------------------------------------------------------------ declared state
    def _refresh_snapshot(self, now: float, *, force: bool = False) -> None:
        """What the queryables answer (the loop thread; cheap, at most 5 Hz)."""
        wall = time.monotonic()
        if not force and wall - self._snap_at < SNAPSHOT_PERIOD_S:
            return
        self._snap_at = wall
        core = self.core
        untrusted = self.identity.untrusted
        self._snap = _Snapshot(
            peers=tuple(
                (
                    p.node_id,
                    int(p.vehicle_type),
                    p.fleet_id,
                    int(p.fsm_state),
                    p.last_heard_s,
                    p.node_id in untrusted,
                )
                for p in core.members.live()
            ),
            zones=tuple(core.monitor.zones.values()),
            declared=core.declared_state(now),
            missions=tuple(core.missions.values()),
            dropped=tuple(
                DroppedInput(expr, reason, min(n, 2**32 - 1))
                for (expr, reason), n in sorted(self.alarm.counts.items())
            ),
            conflict=self.identity.conflict,
        )

    def _answer_zones(self, query: zenoh.Query) -> None:
        """Every zone this node holds (withdrawn ones too), one reply per zone key."""
        for z in self._snap.zones:
            key = ZONES.key(self.config.swarm, vehicle_id=self.core.self_id, zone_id=z.zone_id)
            if zenoh.KeyExpr(key).intersects(query.key_expr):
                query.reply(key, lan.encode(z))

    def _answer_missions(self, query: zenoh.Query) -> None:
        """Every mission this node accepted, one reply per mission key (gcs save)."""
        for m in self._snap.missions:
            key = MISSIONS.key(
                self.config.swarm, vehicle_id=self.core.self_id, mission_id=m.mission_id
            )
            if zenoh.KeyExpr(key).intersects(query.key_expr):
                query.reply(key, lan.encode(m))

    def _answer_declared(self, query: zenoh.Query) -> None:
        state = self._snap.declared
        if state is not None:
            query.reply(query.key_expr, lan.encode(state))

    def _asking(self) -> None:
        """Ask each peer that comes alive what it holds (its DECLARED queryable): a node
        started after a declaration (or restarted, or with a new database) learns it from
        any peer that holds it; the newest stamp wins (core/declared.py)."""
        while True:
            node_id = self._ask_peers.get()
            if node_id is None:
                return
            try:
                replies = list(
                    self.bus.session.get(
                        DECLARED.key(self.config.swarm, vehicle_id=node_id), timeout=2.0
                    )
                )
            except Exception:  # the session is closing
                log.debug("declared state query failed", exc_info=True)
                continue
            for reply in replies:
                if reply.ok is None:
                    continue
                key, payload = str(reply.ok.key_expr), reply.ok.payload
                problem = intake.too_large(DECLARED, len(payload))  # before the copy
                try:
                    if problem:
                        raise DecodeError(problem, reason=intake.TOO_LARGE)
                    state = intake.decode(DECLARED, self.config.swarm, key, payload.to_bytes())
                except DecodeError as exc:
                    self._bad_input(key, exc)
                    continue
                self.inbox.put(Learned(state, None, f"peer {state.vehicle_id}"))

    def _restore(self) -> None:
        """The declared state stored in the node's database, first thing in the inbox."""
        if self.store is None:
            return
        try:
            state, sortie, bad = self.store.load(self.clock.now())
        except Exception as exc:  # an unreadable table: start empty, learn from peers
            log.error(
                "node %d: stored declared state unreadable (%s): starting from the peers'",
                self.core.self_id,
                exc,
            )
            return
        if bad:
            log.warning(
                "node %d: %d stored declarations did not decode (skipped)", self.core.self_id, bad
            )
        log.info(
            "node %d: restored %d zones, %d commands, %d fleet assignments, %d missions%s",
            self.core.self_id,
            len(state.zones),
            len(state.commands),
            len(state.assignments),
            len(state.missions),
            " and the share it was flying" if sortie else "",
        )
        self.inbox.put(Learned(state, sortie, "database"))

    def _check_clock(self, now: float) -> None:
        """A step of the system clock (the node runs on a SteadyClock: it does not follow
        it) is reported once per step."""
        clock = self.clock
        wall = time.monotonic()
        if not isinstance(clock, SteadyClock) or wall - self._clock_checked < 1.0:
            return
        self._clock_checked = wall
        step = clock.step_s()
        if abs(step - self._clock_step_s) <= CLOCK_STEP_REPORT_S:
            return
        self._clock_step_s = step
        text = f"system clock stepped {step:+.0f} s; node time kept steady"
        log.warning("node %d: %s", self.core.self_id, text)
        self._execute(
            [
                Publish(
                    Alert(
                        self.core.self_id,
                        max(0.0, now),
                        Severity.WARNING,
                        AlertCode.GENERIC,
                        short_text(text),
                    )
                )
            ]
        )

    def _answer_peers(self, query: zenoh.Query) -> None:
        now = self.clock.now()
        snap = self._snap
        view = SwarmView(
            vehicle_id=self.core.self_id,
            time_unix_s=max(0.0, now),
            peers=tuple(
                PeerEntry(
                    node_id=nid,
                    vehicle_type=VehicleType(vt),
                    fleet_id=fleet,
                    fsm_state=FsmState(fsm),
                    heard_age_s=min(max(0.0, now - heard), 1e7),
                    untrusted=untrusted,
                )
                for nid, vt, fleet, fsm, heard, untrusted in snap.peers
            ),
            dropped=snap.dropped,
            identity_conflict=short_text(snap.conflict),
        )
        query.reply(query.key_expr, lan.encode(view))

    def start(self) -> None:
        self._restore()
        self._refresh_snapshot(self.clock.now(), force=True)
        if self.writer is not None:
            self.writer.start()
        # ACK: the peers' answers to missions make the roster (core/swarm/roster.py)
        for topic in (COMMAND, MISSION, ZONE, FLEET, ACK, VOTE, TARGET, LINEAGE, INTENT):
            self.bus.subscribe(topic, self._received)
        swarm, me = self.config.swarm, self.core.self_id
        for topic in (STATUS, INFO):  # telemetry passes the identity book first
            self.bus.subscribe_sourced(topic, self._heard)
            # our own name from another session (never our own publications)
            own = topic.key(swarm, vehicle_id=me)
            self.bus.subscribe_sourced(topic, self._own, own, remote_only=True, quiet=True)
        # radio passthrough sessions' commands to this vehicle (core/passthrough.py)
        key = MAVLINK_COMMAND.key(swarm, target_id=me)
        self.bus.subscribe(MAVLINK_COMMAND, self._received, key=key)
        self._asker = threading.Thread(
            target=self._asking, name=f"declared-{self.core.self_id}", daemon=True
        )
        self._asker.start()
        self._zones_queryable = self.bus.session.declare_queryable(
            ZONES.key(self.config.swarm, vehicle_id=self.core.self_id), self._answer_zones
        )
        self._missions_queryable = self.bus.session.declare_queryable(
            MISSIONS.key(self.config.swarm, vehicle_id=self.core.self_id), self._answer_missions
        )
        self._declared_queryable = self.bus.session.declare_queryable(
            DECLARED.key(self.config.swarm, vehicle_id=self.core.self_id), self._answer_declared
        )
        if _relays(self.autopilot):
            self.passthrough = PassthroughRelay(
                self.bus, self.core.self_id, self.autopilot, self.inbox.put
            )
            self.passthrough.start()
        self.bus.watch_holders(self._holder)
        self.bus.declare_holder(self.core.self_id)
        self.bus.declare_alive(self.core.self_id)  # for ground stations (discovery)
        # the planner's worker process starts once the node is active (the run loop),
        # or with the first plan job: a node that never plans does not pay for it
        key = PEERS.key(self.config.swarm, vehicle_id=self.core.self_id)
        self._queryable = self.bus.session.declare_queryable(key, self._answer_peers)
        if self.database is not None:  # peers and the ground station read our database
            self._db_server = DatabaseQueryable(
                self.bus.session, self.database, self.core.self_id, self.config.swarm
            )

    # ------------------------------------------------------------------ loop
    def run(self, stop: threading.Event) -> None:
        """Run until `stop` is set; then close everything (no hang at exit)."""
        self.start()
        next_ap = self.clock.now()
        try:
            while not stop.is_set():
                now = self.clock.now()
                deadline = min(self.core.next_deadline(), next_ap, self._boundary_deadline())
                wait = min(self.clock.to_wall(deadline - now), 0.25)
                try:
                    event: Input | Boundary | None = self.inbox.get(timeout=max(0.0, wait))
                except queue.Empty:
                    event = None
                now = self.clock.now()
                if event is not None:
                    self._execute(self._handle(event, now))
                    while True:  # drain what arrived meanwhile
                        try:
                            self._execute(self._handle(self.inbox.get_nowait(), now))
                        except queue.Empty:
                            break
                if now >= next_ap:
                    next_ap = max(next_ap + self._ap_period_s, now)
                    state = self.autopilot.state
                    self._note_sysid(state)
                    self._execute(self.core.handle(AutopilotUpdate(state), now))
                if now >= self.core.next_deadline():
                    self._execute(self.core.on_timer(now))
                if now >= self._boundary_deadline():
                    self._execute(self._boundary_timer(now))
                self._refresh_snapshot(now)
                self._check_clock(now)
                jobs, self._plan_jobs = self._plan_jobs, []
                for job in jobs:  # after the step: starting the worker takes a while
                    self.planner.submit(job)
                if not self.planner.started and self.core.fsm.state != FsmState.INACTIVE:
                    # active (base set): missions come next. Eleven nodes of a demo on
                    # two cores plan at once; the worker's start-up is not in that time
                    self.planner.start()
        finally:
            self.close()

    def _execute(self, outputs: list[Output]) -> None:
        for o in outputs:
            if isinstance(o, Publish):
                if isinstance(o.msg, Ack):
                    # what we acknowledge (a zone, a mission, a declaration) is what our
                    # queryables answer from now on: a ground station that asks right
                    # after the ack must not read the snapshot from before it
                    self._refresh_snapshot(self.clock.now(), force=True)
                if isinstance(o.msg, Alert):
                    log.warning(
                        "node %d: alert %s %s: %s",
                        self.core.self_id,
                        o.msg.severity.name,
                        o.msg.code.name,
                        o.msg.text,
                    )
                try:
                    self.bus.publish(o.msg)
                except Exception:  # an invalid message of ours must not stop the node
                    log.exception("could not publish %s", type(o.msg).__name__)
            elif isinstance(o, Submit):
                self._submit(o.request)
            elif isinstance(o, Note):
                log.log(o.level, "node %d: %s", self.core.self_id, o.text)
            elif isinstance(o, PlanJob):
                self._plan_jobs.append(o.request)
            elif isinstance(o, Persist) and self.writer is not None:
                self.writer.submit(o.state, o.sortie)
            elif self.passthrough is not None:
                if isinstance(o, ToAutopilot):
                    self.passthrough.to_autopilot(o.data)
                elif isinstance(o, ToClient):
                    self.passthrough.to_client(o.session_id, o.data)
                elif isinstance(o, Sessions):
                    self.passthrough.sessions(o.ids)
                elif isinstance(o, StreamWish):
                    self.passthrough.wish(o.rates)

    def _submit(self, request: ApRequest) -> None:
        # a passthrough session's frames (sticks at 50 Hz) are logged by the core instead
        level = logging.DEBUG if isinstance(request, RelayCommand) else logging.INFO
        log.log(level, "node %d: autopilot <- %s", self.core.self_id, type(request).__name__)
        try:
            future = self.autopilot.submit(request)
        except Exception as exc:  # a request the link refuses outright
            self.inbox.put(AutopilotResult(ApResult(request.request_id, False, str(exc)[:60])))
            return
        put: Callable[[Input], None] = self.inbox.put

        def done(f: Future[ApResult]) -> None:
            try:
                result = f.result()
            except Exception as exc:
                result = ApResult(request.request_id, False, str(exc)[:60])
            put(AutopilotResult(result))

        future.add_done_callback(done)

    def close(self) -> None:
        self.planner.close()
        if self._db_server is not None:
            self._db_server.close()
            self._db_server = None
        if self._asker is not None:
            self._ask_peers.put(None)
            self._asker.join(3.0)
            self._asker = None
        for q in (
            self._queryable,
            self._zones_queryable,
            self._declared_queryable,
            self._missions_queryable,
        ):
            if q is not None:
                try:
                    q.undeclare()
                except Exception:
                    log.debug("queryable undeclare failed", exc_info=True)
        self._queryable = self._zones_queryable = self._declared_queryable = None
        self._missions_queryable = None
        if self.writer is not None:
            self.writer.close()
        if self.passthrough is not None:
            self.passthrough.close()
        self.bus.close()
        self.autopilot.close()
        if self.database is not None:
            self.database.close()
