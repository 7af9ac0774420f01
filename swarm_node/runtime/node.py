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
`python -m bench planning`).
"""

from __future__ import annotations

import logging
import multiprocessing
import queue
import threading
from collections.abc import Callable
from concurrent.futures import Executor, Future, ProcessPoolExecutor, ThreadPoolExecutor
from typing import Protocol

import msgspec
import zenoh

from swarm_proto import Alert, Clock, MissionType, NoFlyZone, PeerEntry, SwarmView, lan
from swarm_proto.errors import DecodeError
from swarm_proto.session import SwarmBus
from swarm_proto.topics import (
    ACK,
    COMMAND,
    FLEET,
    INFO,
    LINEAGE,
    MISSION,
    MISSIONS,
    PEERS,
    STATUS,
    TARGET,
    VOTE,
    ZONE,
    ZONES,
)

from ..core.autopilot.requests import ApRequest, ApResult
from ..core.autopilot.state import AutopilotState
from ..core.mission.share import PlanOutcome, PlanRequest, run_plan
from ..core.mission.tasking import RETASK_MODULE, VOTING_MODULE, TaskingSettings
from ..core.node import (
    AutopilotResult,
    AutopilotUpdate,
    BadInput,
    Input,
    NodeCore,
    NodeSettings,
    Note,
    Output,
    PeerAlive,
    PlanDone,
    PlanJob,
    Publish,
    Received,
    Submit,
)
from ..core.profile import VehicleProfile
from ..database import ProfileError, SwarmDatabase
from ..database.queryable import DatabaseQueryable
from .config import NodeConfig

log = logging.getLogger("swarm_node")


def node_settings(config: NodeConfig) -> NodeSettings:
    """The core's settings from the node's configuration (file and command line)."""
    return NodeSettings(
        status_period_s=1.0 / config.status_hz,
        info_period_s=1.0 / config.info_hz,
        plan_timeout_s=config.plan_timeout_s,
        stale_after_s=config.stale_after_s,
        avoidance=config.avoidance,
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

    return TaskingSettings(
        params(VOTING_MODULE), params(RETASK_MODULE), database.payload_classes()
    )


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


class _Learned(msgspec.Struct, frozen=True):
    """A zone read from a peer's zones queryable: taken only if the node holds no zone
    of that id yet (what is published live always wins over what is read back)."""

    zone: NoFlyZone


class PlanWorker:
    """Runs plan jobs off the control loop; outcomes go to `deliver`."""

    def __init__(self, deliver: Callable[[Input], None], kind: str = "process") -> None:
        if kind not in ("process", "thread"):
            raise ValueError(f"planner must be process or thread, not {kind!r}")
        self.kind = kind
        self._deliver = deliver
        self._pool: Executor | None = None

    def start(self) -> None:
        if self.kind == "process":
            ctx = multiprocessing.get_context("spawn")
            self._pool = ProcessPoolExecutor(max_workers=1, mp_context=ctx)
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
        self.core = NodeCore(
            profile,
            node_settings(config),
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
        self.inbox: queue.SimpleQueue[Input | _Learned] = queue.SimpleQueue()
        self.planner = PlanWorker(self.inbox.put, planner)
        self.bus = bus or SwarmBus.open(config.zenoh, config.swarm, on_bad_input=self._bad_input)
        if bus is not None:
            bus.on_bad_input = self._bad_input
        self._queryable: zenoh.Queryable | None = None
        self._zones_queryable: zenoh.Queryable | None = None
        self._missions_queryable: zenoh.Queryable | None = None
        self._ask_zones: queue.SimpleQueue[int | None] = queue.SimpleQueue()
        self._zone_asker: threading.Thread | None = None
        self.database = database
        self._db_server: DatabaseQueryable | None = None
        self._lock = threading.Lock()  # guards the core against the peers queryable
        self._ap_period_s = 0.2

    # ------------------------------------------------------------------ wiring
    def _bad_input(self, key: str, exc: Exception) -> None:
        self.inbox.put(BadInput(key, str(exc)))

    def _received(self, msg: msgspec.Struct, key: str) -> None:
        self.inbox.put(Received(msg))

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

    def _alive(self, node_id: int, alive: bool) -> None:
        self.inbox.put(PeerAlive(node_id, alive))
        if alive and node_id != self.core.self_id:
            self._ask_zones.put(node_id)  # learn the zones it holds (off Zenoh's thread)

    # ------------------------------------------------------------------ durable zones
    def _answer_zones(self, query: zenoh.Query) -> None:
        """Every zone this node holds (withdrawn ones too), one reply per zone key."""
        with self._lock:
            zones = list(self.core.monitor.zones.values())
        for z in zones:
            key = ZONES.key(self.config.swarm, vehicle_id=self.core.self_id, zone_id=z.zone_id)
            if zenoh.KeyExpr(key).intersects(query.key_expr):
                query.reply(key, lan.encode(z))

    def _answer_missions(self, query: zenoh.Query) -> None:
        """Every mission this node accepted, one reply per mission key (gcs save)."""
        with self._lock:
            missions = list(self.core.missions.values())
        for m in missions:
            key = MISSIONS.key(self.config.swarm, vehicle_id=self.core.self_id,
                               mission_id=m.mission_id)  # fmt: skip
            if zenoh.KeyExpr(key).intersects(query.key_expr):
                query.reply(key, lan.encode(m))

    def _zone_asking(self) -> None:
        """Ask each peer that comes alive which zones it holds: a node started after a
        zone was declared (or restarted) learns it from any peer that holds it."""
        while True:
            node_id = self._ask_zones.get()
            if node_id is None:
                return
            try:
                replies = list(
                    self.bus.session.get(
                        ZONES.key(self.config.swarm, vehicle_id=node_id), timeout=2.0
                    )
                )
            except Exception:  # the session is closing
                log.debug("zones query failed", exc_info=True)
                continue
            for reply in replies:
                if reply.ok is None:
                    continue
                try:
                    zone = lan.decode(reply.ok.payload.to_bytes(), NoFlyZone)
                except DecodeError as exc:
                    self._bad_input(str(reply.ok.key_expr), exc)
                    continue
                self.inbox.put(_Learned(zone))

    def _handle(self, event: Input | _Learned, now: float) -> list[Output]:
        if isinstance(event, _Learned):
            if event.zone.zone_id in self.core.monitor.zones:
                return []
            log.info("node %d: zone %d learned from a peer", self.core.self_id, event.zone.zone_id)
            return self.core.handle(Received(event.zone), now)
        return self.core.handle(event, now)

    def _answer_peers(self, query: zenoh.Query) -> None:
        with self._lock:
            now = self.clock.now()
            view = SwarmView(
                vehicle_id=self.core.self_id,
                time_unix_s=max(0.0, now),
                peers=tuple(
                    PeerEntry(
                        node_id=p.node_id,
                        vehicle_type=p.vehicle_type,
                        fleet_id=p.fleet_id,
                        fsm_state=p.fsm_state,
                        heard_age_s=min(max(0.0, now - p.last_heard_s), 1e7),
                    )
                    for p in self.core.members.live()
                ),
            )
        query.reply(query.key_expr, lan.encode(view))

    def start(self) -> None:
        # ACK: the peers' answers to missions make the roster (core/swarm/roster.py)
        for topic in (STATUS, INFO, COMMAND, MISSION, ZONE, FLEET, ACK, VOTE, TARGET, LINEAGE):
            self.bus.subscribe(topic, self._received)
        self._zone_asker = threading.Thread(
            target=self._zone_asking, name=f"zones-{self.core.self_id}", daemon=True
        )
        self._zone_asker.start()
        self._zones_queryable = self.bus.session.declare_queryable(
            ZONES.key(self.config.swarm, vehicle_id=self.core.self_id), self._answer_zones
        )
        self._missions_queryable = self.bus.session.declare_queryable(
            MISSIONS.key(self.config.swarm, vehicle_id=self.core.self_id), self._answer_missions
        )
        self.bus.watch_alive(self._alive)
        self.bus.declare_alive(self.core.self_id)
        # the planner's worker process starts with the first plan job (~1 s, off the
        # loop): a node that never plans, or is starting up, does not pay for it
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
                deadline = min(self.core.next_deadline(), next_ap)
                wait = min(self.clock.to_wall(deadline - now), 0.25)
                try:
                    event: Input | _Learned | None = self.inbox.get(timeout=max(0.0, wait))
                except queue.Empty:
                    event = None
                now = self.clock.now()
                with self._lock:
                    if event is not None:
                        self._execute(self._handle(event, now))
                        while True:  # drain what arrived meanwhile
                            try:
                                self._execute(self._handle(self.inbox.get_nowait(), now))
                            except queue.Empty:
                                break
                    if now >= next_ap:
                        next_ap = max(next_ap + self._ap_period_s, now)
                        self._execute(self.core.handle(AutopilotUpdate(self.autopilot.state), now))
                    if now >= self.core.next_deadline():
                        self._execute(self.core.on_timer(now))
        finally:
            self.close()

    def _execute(self, outputs: list[Output]) -> None:
        for o in outputs:
            if isinstance(o, Publish):
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
                self.planner.submit(o.request)

    def _submit(self, request: ApRequest) -> None:
        log.info("node %d: autopilot <- %s", self.core.self_id, type(request).__name__)
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
        if self._zone_asker is not None:
            self._ask_zones.put(None)
            self._zone_asker.join(3.0)
            self._zone_asker = None
        for q in (self._queryable, self._zones_queryable, self._missions_queryable):
            if q is not None:
                try:
                    q.undeclare()
                except Exception:
                    log.debug("queryable undeclare failed", exc_info=True)
        self._queryable = self._zones_queryable = self._missions_queryable = None
        self.bus.close()
        self.autopilot.close()
        if self.database is not None:
            self.database.close()
