"""`radio-gateway run`: a serial radio and a Zenoh session, bridged.

Zenoh side: one subscriber on `bandada/<swarm>/**` that ignores this session's own
publications; samples of on-air topics originated locally are queued for the air
(`core.bridge`). Radio side: `RadioLink`. What is heard is published under the key
rebuilt from the message, with the radio attachment, unless the LAN already had it.
Statistics go to `bandada/<swarm>/radio/<node_id>/stats` (RadioStats) every
`stats_period_s`.
"""

from __future__ import annotations

import logging
import threading
from dataclasses import dataclass, field
from pathlib import Path

import msgspec
import serial
import zenoh

from swarm_proto import intake
from swarm_proto.clock import Clock, clock_from_env
from swarm_proto.radio import STATUS_BYTES
from swarm_proto.session import SwarmBus, ZenohSettings, open_session, put_options, zenoh_reason
from swarm_proto.topics import check_swarm_name, match, prefix

from ..core.airtime import LinkTiming
from ..core.auth import parse_key
from ..core.bridge import RADIO_ATTACHMENT, Bridge, OwnStatus, Publication
from ..core.node import Deliver, NodeConfig, RadioNode
from ..core.slots import TdmConfig
from ..core.stats import StatsReporter
from ..core.telemetry import TURN_TRAILER, PeerPredictor, PredictConfig, SendOnErrorConfig
from ..core.xtend import RadioSettings
from .link import RadioLink
from .timesource import TimeSource, time_source_from_spec
from .xtend_config import configure, verify

log = logging.getLogger(__name__)

EXIT_RADIO = 3  # run_gateway: the radio is not set up for bandada
EXIT_ZENOH = 4  # run_gateway: its Zenoh session cannot open


class GatewayConfig(msgspec.Struct, frozen=True, forbid_unknown_fields=True):
    """Everything `radio-gateway run` needs (a TOML file and/or command-line options)."""

    node_id: int
    port: str
    key_file: str
    swarm: str = "default"
    zenoh: ZenohSettings = ZenohSettings()
    radio: RadioSettings = RadioSettings()
    cycle_s: float = 0.2
    guard_s: float = 0.005
    sync_s: float = 0.006  # the module's per-packet preamble
    min_payload: int = 42  # with send on error at least 88: a status (+ turn rate) and room
    latest_keep: int = 1  # 2 with cycle_s 0.4, min_payload 84: 5 Hz statuses, two a frame
    # "on_error" (send on error, peers predicted on the LAN) or "every" (each
    # status queued, latest only, at most 5 Hz)
    status_mode: str = "on_error"
    threshold_m: float = 5.0  # send when the peers' prediction would be this far off
    heartbeat_s: float = 1.0  # and at least this often
    republish_hz: float = 5.0  # radio peers' predicted statuses on the LAN
    max_accel_mps2: float = 6.0  # error bound of a prediction: this * age^2
    predict_max_s: float = 5.0  # stop predicting a peer this long after its last status
    adaptive: bool = True  # slot shares follow need levels
    min_level: int = 0  # a ground station's gateway: 2
    silent_periods: int = 5
    initial_members: tuple[int, ...] = ()
    local_ids: tuple[int, ...] = ()  # whose messages go on air; default: node_id
    forward_unattributed: bool = True  # zones (no originator field)
    time_source: str = "clock"  # clock, clock-free, mavlink:URL, nmea:PORT[:BAUD]
    configure_radio: bool = False  # apply `radio` settings before verifying them
    verify_radio: bool = True  # refuse to run unless the module matches `radio`
    at_guard_s: float = 1.1
    stats_period_s: float = 1.0

    def __post_init__(self) -> None:
        if self.status_mode not in ("on_error", "every"):
            raise ValueError(f"status_mode is 'on_error' or 'every', not {self.status_mode!r}")
        if not 0 <= self.min_level <= 3:
            raise ValueError("min_level is 0..3")
        # the other numbers are checked where they are used (SendOnErrorConfig, ...)
        self.send_on_error()
        self.predict_config()

    @property
    def on_error(self) -> bool:
        return self.status_mode == "on_error"

    def send_on_error(self) -> SendOnErrorConfig | None:
        if not self.on_error:
            return None
        return SendOnErrorConfig(threshold_m=self.threshold_m, heartbeat_s=self.heartbeat_s)

    def predict_config(self) -> PredictConfig:
        return PredictConfig(
            republish_hz=self.republish_hz,
            max_accel_mps2=self.max_accel_mps2,
            predict_max_s=self.predict_max_s,
        )

    def node_config(self) -> NodeConfig:
        radio = msgspec.structs.replace(self.radio, address=self.node_id)
        timing: LinkTiming = radio.timing(sync_s=self.sync_s)
        min_payload = self.min_payload
        if self.on_error:  # a status with its turn rate, and as much again for the rest
            min_payload = max(min_payload, 2 * (STATUS_BYTES + TURN_TRAILER.size + 2))
        tdm = TdmConfig(
            cycle_s=self.cycle_s,
            guard_s=self.guard_s,
            min_payload=min_payload,
            silent_periods=self.silent_periods,
        )
        return NodeConfig(
            self.node_id,
            timing=timing,
            tdm=tdm,
            initial_members=self.initial_members,
            latest_keep=self.latest_keep,
            send_on_error=self.send_on_error(),
            adaptive=self.adaptive,
            min_level=self.min_level,
        )

    def bridge(self) -> Bridge:
        return Bridge(
            self.swarm,
            self.node_id,
            frozenset(self.local_ids or (self.node_id,)),
            self.forward_unattributed,
            predictor=PeerPredictor(self.predict_config()) if self.on_error else None,
        )


def load_config(path: Path | None, overrides: dict[str, object]) -> GatewayConfig:
    raw: dict[str, object] = {}
    if path is not None:
        raw = msgspec.toml.decode(path.read_bytes())
    raw.update({k: v for k, v in overrides.items() if v is not None})
    return msgspec.convert(raw, GatewayConfig)


@dataclass
class Gateway:
    config: GatewayConfig
    session: zenoh.Session
    port: serial.Serial
    time_source: TimeSource
    clock: Clock
    key: bytes
    bridge: Bridge = field(init=False)
    link: RadioLink = field(init=False)
    bus: SwarmBus = field(init=False)
    _reporter: StatsReporter = field(default_factory=StatsReporter)
    _next_stats: float = 0.0
    _subscriber: zenoh.Subscriber | None = None
    _lock: threading.Lock = field(default_factory=threading.Lock)

    def __post_init__(self) -> None:
        c = self.config
        check_swarm_name(c.swarm)
        self.bridge = c.bridge()
        node = RadioNode(c.node_config(), self.key, self.time_source.now())
        self.link = RadioLink(
            self.port,
            node,
            self.time_source,
            clock=self.clock,
            on_deliver=self._on_air,
            on_tick=self._tick,
            name=f"radio-{c.node_id}",
        )
        self.bus = SwarmBus(self.session, c.swarm)
        self._attachment = RADIO_ATTACHMENT + b":" + str(c.node_id).encode()

    def start(self) -> Gateway:
        self._subscriber = self.session.declare_subscriber(
            f"{prefix(self.config.swarm)}/**",
            self._on_lan,
            allowed_origin=zenoh.Locality.REMOTE,
        )
        self.link.start()
        return self

    def close(self) -> None:
        if self._subscriber is not None:
            self._subscriber.undeclare()
            self._subscriber = None
        self.link.close()
        self.bus.close()
        self.time_source.close()

    # ------------------------------------------------------------------ LAN -> air
    def _on_lan(self, sample: zenoh.Sample) -> None:
        key = str(sample.key_expr)
        found = match(self.config.swarm, key)
        if found is not None and intake.too_large(found[0], len(sample.payload)):
            with self._lock:  # never copied out of Zenoh: nothing that large is sent
                self.bridge.counts["lan_too_large"] += 1
            return
        att = sample.attachment
        from_gw = att is not None and att.to_bytes().startswith(RADIO_ATTACHMENT)
        payload = sample.payload.to_bytes()
        now = self.time_source.now()
        with self._lock:  # Zenoh calls back on several threads
            out = self.bridge.from_lan(key, payload, now, from_gateway=from_gw)
        if isinstance(out, OwnStatus):
            status = out.status
            self.link.call(lambda node: node.own_status(status, now))
        elif out is not None:
            self.link.submit(out)

    # ------------------------------------------------------------------ air -> LAN
    def _on_air(self, d: Deliver, now: float) -> None:
        with self._lock:
            pub = self.bridge.from_air(d.data, now)
        if pub is not None:
            self._publish(pub)

    def _publish(self, pub: Publication) -> None:
        try:
            self.session.put(
                pub.key, pub.payload, attachment=self._attachment, **put_options(pub.topic)
            )
        except zenoh.ZError:
            log.warning("publishing %s failed", pub.key, exc_info=True)

    # ------------------------------------------------------------------ stats
    def _tick(self, node: RadioNode, now: float) -> None:
        silent = node.silence_limit_s(self.config.predict_config().silent_s)

        def alive(vid: int) -> bool:  # a vehicle that is not a radio node: by its statuses
            return vid not in node.peers or node.silent_s(vid, now) <= silent

        with self._lock:
            held = self.bridge.due(now) + self.bridge.predictions(now, alive)
            dropped = self.bridge.predictor.dropped if self.bridge.predictor else []
            for vid, why in dropped:  # its node sees it go stale a moment later
                log.info("no longer predicting vehicle %d to our node: %s", vid, why)
            dropped.clear()
        for pub in held:
            self._publish(pub)
        if now < self._next_stats:
            return
        self._next_stats = now + self.config.stats_period_s
        with self._lock:
            extra = self.bridge.counts.copy()
        msg = self._reporter.report(node, now, extra)
        try:
            self.bus.publish(msg)
        except (zenoh.ZError, RuntimeError):
            log.debug("stats publish failed", exc_info=True)


def run_gateway(config: GatewayConfig, stop: threading.Event, clock: Clock | None = None) -> int:
    """Join Zenoh, verify the radio, then bridge until `stop` is set. Returns an exit
    code: 0 when stopped, 3 when the radio is not set up for bandada, 4 when the Zenoh
    session cannot open (an endpoint already in use, a bad certificate).

    The session opens first: a listener that cannot bind is told at once, not after the
    seconds of AT guard times, and "zenoh session open" in the log says the gateway's
    endpoints are its own (`swarm-sim demo --radio` starts its nodes after that line)."""
    clock = clock or clock_from_env()
    settings = msgspec.structs.replace(config.radio, address=config.node_id)
    key = parse_key(Path(config.key_file).read_bytes())
    try:
        session = open_session(config.zenoh)
    except (zenoh.ZError, ValueError) as exc:
        log.error(
            "cannot open the Zenoh session (%s): %s", _endpoints(config.zenoh), zenoh_reason(exc)
        )
        return EXIT_ZENOH
    log.info("zenoh session open (%s)", _endpoints(config.zenoh))
    try:
        if config.configure_radio:
            report = configure(config.port, settings, clock=clock, guard_s=config.at_guard_s)
            log.info("radio configured at %d baud, changed %s", report.found_baud, report.changed)
        if config.verify_radio:
            problems = verify(config.port, settings, clock=clock, guard_s=config.at_guard_s)
            if problems:
                for p in problems:
                    log.error("radio %s: %s", config.port, p)
                log.error(
                    "refusing to run: the radio is not set up for bandada "
                    "(run `radio-gateway configure` or pass --configure)"
                )
                return EXIT_RADIO
        source = time_source_from_spec(config.time_source, clock)
        port = serial.Serial(config.port, settings.serial_baud, timeout=0.05)
        gw = Gateway(config, session, port, source, clock, key)
        try:
            gw.start()
            log.info(
                "radio gateway %d on %s, swarm %r: bridging",
                config.node_id,
                config.port,
                config.swarm,
            )
            stop.wait()
        finally:
            gw.close()
    finally:
        session.close()
    return 0


def _endpoints(z: ZenohSettings) -> str:
    said = [f"listen {e}" for e in z.listen] + [f"connect {e}" for e in z.connect]
    return ", ".join(said) or (f"config {z.config_file}" if z.config_file else "no endpoints")


def members_option(text: str | None) -> tuple[int, ...] | None:
    if not text:
        return None
    return tuple(int(x) for x in text.replace(" ", "").split(",") if x)
