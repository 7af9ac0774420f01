"""Zenoh at the edge: session settings a field deployment needs, and `SwarmBus`, a
typed publish/subscribe layer over one session that uses the topic registry for keys
and QoS and the LAN encoding for payloads.

Callbacks run on Zenoh's threads: keep them short (hand the message to a queue).
Payloads that do not decode are counted per topic and reported to `on_bad_input`,
never raised. `SwarmBus.close()` undeclares everything it declared (a process that
exits with a callback subscriber still declared hangs).
"""

from __future__ import annotations

import json
import logging
import re
import threading
from collections import Counter
from collections.abc import Callable
from typing import Any, Literal

import msgspec
import zenoh

from . import lan
from .errors import DecodeError
from .topics import ALIVE, Congestion, Reliability, Topic, prefix, topic_of
from .warm import warm_decoders

log = logging.getLogger(__name__)

Mode = Literal["peer", "router", "client"]


class ZenohSettings(msgspec.Struct, frozen=True, forbid_unknown_fields=True):
    """How a process joins Zenoh. Decoded from config files with msgspec.

    Multicast scouting is off by default: it fails quietly on loopback and is rarely
    what a field network wants. Give `connect` endpoints (the lab router, or peers), or
    turn multicast on with an explicit `scouting_interface`. The lease bounds how long
    a frozen peer stays "alive" (default 2 s; Zenoh's own default is 10 s).

    `config_file` names a Zenoh JSON5 config (deploy/zenoh/*.json5, or one made by
    `swarm-node certs make`). Then the file decides everything it says, and only the
    fields given here with a value other than their default are applied over it (a
    `--connect` on the command line wins over the file's endpoints; the default
    `multicast_scouting = false` does not turn off the scouting the file enables).
    """

    mode: Mode = "peer"
    listen: tuple[str, ...] = ()
    connect: tuple[str, ...] = ()
    multicast_scouting: bool = False
    scouting_interface: str | None = None
    gossip_scouting: bool = True
    lease_ms: int = 2000
    keep_alive: int = 4
    config_file: str | None = None  # a Zenoh JSON5 config; the fields above override it


def load_zenoh_file(path: str) -> zenoh.Config:
    """A Zenoh JSON5 config file, or ValueError with the file and Zenoh's reason."""
    try:
        return zenoh.Config.from_file(path)
    except Exception as exc:  # zenoh raises ZError (and OSError-like messages) here
        raise ValueError(f"cannot load Zenoh config {path}: {exc}") from exc


def zenoh_config(s: ZenohSettings) -> zenoh.Config:
    """The zenoh.Config for these settings (ValueError for an unreadable config file)."""
    if s.config_file:
        conf = load_zenoh_file(s.config_file)
        default = ZenohSettings()

        def given(name: str) -> bool:
            return bool(getattr(s, name) != getattr(default, name))

    else:
        conf = zenoh.Config()

        def given(name: str) -> bool:
            return True

    if given("mode"):
        conf.insert_json5("mode", json.dumps(s.mode))
    if s.listen:
        conf.insert_json5("listen/endpoints", json.dumps(list(s.listen)))
    elif (
        not s.config_file
        and s.mode == "peer"
        and s.connect
        and all(_is_loopback(e) for e in s.connect)
    ):
        # a simulation on one machine: do not listen on every interface (Zenoh's default)
        conf.insert_json5("listen/endpoints", json.dumps(["tcp/127.0.0.1:0"]))
    if s.connect:
        conf.insert_json5("connect/endpoints", json.dumps(list(s.connect)))
    # multicast scouting: off unless asked for, or an interface to scout on is named
    if given("multicast_scouting") or given("scouting_interface"):
        multicast = s.multicast_scouting or bool(s.scouting_interface)
        conf.insert_json5("scouting/multicast/enabled", json.dumps(multicast))
    if s.scouting_interface:
        conf.insert_json5("scouting/multicast/interface", json.dumps(s.scouting_interface))
    if given("gossip_scouting"):
        conf.insert_json5("scouting/gossip/enabled", json.dumps(s.gossip_scouting))
    if given("lease_ms"):
        conf.insert_json5("transport/link/tx/lease", str(int(s.lease_ms)))
    if given("keep_alive"):
        conf.insert_json5("transport/link/tx/keep_alive", str(int(s.keep_alive)))
    return conf


def _is_loopback(endpoint: str) -> bool:
    """tcp/127.0.0.1:7447, udp/[::1]:7447, tcp/localhost:7447 ..."""
    locator = endpoint.split("#")[0].split("/", 1)[-1]
    host = locator.rsplit(":", 1)[0].strip("[]")
    return host in ("localhost", "::1") or host.startswith("127.")


def zenoh_reason(exc: Exception) -> str:
    """Zenoh's error message without its Rust source locations, for a person."""
    text = str(exc)
    found = re.search(r'msg: "(.*?)(?: at /[^"]*)?"', text)
    reason = found.group(1) if found else text.splitlines()[0] if text else type(exc).__name__
    return re.sub(r"\s*at /\S+\.rs:\d+\.?", "", reason)[:300]


def open_session(s: ZenohSettings) -> zenoh.Session:
    """Open a session; first, on this thread, build every message decoder (`warm`:
    msgspec builds a type's decode information lazily, and two Zenoh or serial threads
    meeting a type for the first time at once crashed a gateway)."""
    warm_decoders()
    return zenoh.open(zenoh_config(s))


def _zenoh_priority(p: int) -> zenoh.Priority:
    from .topics import Priority

    return getattr(zenoh.Priority, Priority(p).name)


def _qos(topic: Topic) -> dict[str, Any]:
    return dict(
        congestion_control=(
            zenoh.CongestionControl.DROP
            if topic.congestion == Congestion.DROP
            else zenoh.CongestionControl.BLOCK
        ),
        priority=_zenoh_priority(topic.priority),
        express=topic.express,
        reliability=(
            zenoh.Reliability.BEST_EFFORT
            if topic.reliability == Reliability.BEST_EFFORT
            else zenoh.Reliability.RELIABLE
        ),
    )


def put_options(topic: Topic) -> dict[str, Any]:
    """Keyword arguments for `zenoh.Session.put` carrying a topic's QoS (a put has no
    reliability setting; that is the publisher's)."""
    opts = _qos(topic)
    opts.pop("reliability", None)
    return opts


MessageCallback = Callable[[Any, str], None]  # (message, key)
BadInputCallback = Callable[[str, DecodeError], None]  # (key, error)
AliveCallback = Callable[[int, bool], None]  # (node_id, alive)


class SwarmBus:
    """Typed pub/sub for one swarm over one Zenoh session."""

    def __init__(
        self,
        session: zenoh.Session,
        swarm: str = "default",
        *,
        on_bad_input: BadInputCallback | None = None,
        owns_session: bool = False,
    ) -> None:
        warm_decoders()  # before the callbacks below can decode on Zenoh's threads
        self.session = session
        self.swarm = swarm
        self.prefix = prefix(swarm)
        self.on_bad_input = on_bad_input
        self.bad_input: Counter[str] = Counter()  # topic name -> payloads dropped
        self._owns_session = owns_session
        self._publishers: dict[str, zenoh.Publisher] = {}
        self._declared: list[Any] = []
        self._lock = threading.Lock()
        self._closed = False

    @classmethod
    def open(
        cls,
        settings: ZenohSettings,
        swarm: str = "default",
        *,
        on_bad_input: BadInputCallback | None = None,
    ) -> SwarmBus:
        return cls(open_session(settings), swarm, on_bad_input=on_bad_input, owns_session=True)

    # ------------------------------------------------------------------ publishing
    def publish(self, msg: msgspec.Struct) -> str:
        """Encode and publish a message on its key; returns the key."""
        topic = topic_of(msg)
        key = topic.key_of(self.swarm, msg)
        payload = lan.encode(msg)
        with self._lock:
            if self._closed:
                raise RuntimeError("SwarmBus is closed")
            pub = self._publishers.get(key)
            if pub is None:
                pub = self.session.declare_publisher(key, **_qos(topic))
                self._publishers[key] = pub
        pub.put(payload)
        return key

    def put_raw(
        self,
        key: str,
        payload: bytes,
        topic: Topic | None = None,
        *,
        attachment: bytes | None = None,
    ) -> None:
        """Publish already-encoded bytes (gateways, tests of malformed input)."""
        kwargs = put_options(topic) if topic else {}
        self.session.put(key, payload, attachment=attachment, **kwargs)

    # ------------------------------------------------------------------ subscribing
    def subscribe(
        self, topic: Topic, callback: MessageCallback, key: str | None = None
    ) -> zenoh.Subscriber:
        """Subscribe to every key of `topic` (or to `key`, a narrower expression);
        `callback(message, key)` gets decoded, validated messages only."""
        if topic.msg_type is None:
            raise ValueError(f"topic {topic.name} carries no messages")
        msg_type = topic.msg_type
        expr = key or topic.wildcard(self.swarm)

        def handler(sample: zenoh.Sample) -> None:
            k = str(sample.key_expr)
            try:
                msg: Any = lan.decode(sample.payload.to_bytes(), msg_type)
            except DecodeError as exc:
                self._bad(topic.name, k, exc)
                return
            try:
                callback(msg, k)
            except Exception:  # a bug in our handler must not kill Zenoh's thread
                log.exception("handler for %s failed", k)

        sub = self.session.declare_subscriber(expr, handler)
        with self._lock:
            self._declared.append(sub)
        return sub

    def _bad(self, topic_name: str, key: str, exc: DecodeError) -> None:
        self.bad_input[topic_name] += 1
        log.warning("dropped malformed payload on %s: %s", key, exc)
        if self.on_bad_input is not None:
            try:
                self.on_bad_input(key, exc)
            except Exception:
                log.exception("on_bad_input failed")

    # ------------------------------------------------------------------ liveliness
    def declare_alive(self, node_id: int) -> zenoh.LivelinessToken:
        token = self.session.liveliness().declare_token(ALIVE.key(self.swarm, node_id=node_id))
        with self._lock:
            self._declared.append(token)
        return token

    def watch_alive(self, callback: AliveCallback) -> zenoh.Subscriber:
        """callback(node_id, alive) for every node already alive and every change."""

        def handler(sample: zenoh.Sample) -> None:
            params = ALIVE.parse(self.swarm, str(sample.key_expr))
            if params is None or not params["node_id"].isdigit():
                self._bad(ALIVE.name, str(sample.key_expr), DecodeError("bad liveliness key"))
                return
            try:
                callback(int(params["node_id"]), sample.kind == zenoh.SampleKind.PUT)
            except Exception:
                log.exception("liveliness handler failed")

        sub = self.session.liveliness().declare_subscriber(
            ALIVE.wildcard(self.swarm), handler, history=True
        )
        with self._lock:
            self._declared.append(sub)
        return sub

    # ------------------------------------------------------------------ teardown
    def close(self) -> None:
        with self._lock:
            if self._closed:
                return
            self._closed = True
            declared, self._declared = self._declared, []
            pubs, self._publishers = list(self._publishers.values()), {}
        for d in declared + pubs:
            try:
                d.undeclare()
            except Exception:  # already gone with its session
                log.debug("undeclare failed", exc_info=True)
        if self._owns_session:
            self.session.close()

    def __enter__(self) -> SwarmBus:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
