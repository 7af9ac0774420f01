"""Zenoh at the edge: session settings a field deployment needs, and `SwarmBus`, a
typed publish/subscribe layer over one session that uses the topic registry for keys
and QoS and the LAN encoding for payloads.

Callbacks run on Zenoh's threads: keep them short (hand the message to a queue).
Every sample goes through `swarm_proto.intake` first: a payload larger than its topic's
cap is dropped before it is copied out of Zenoh, then it is decoded and its key checked
against its payload; what is dropped is counted per topic and reported to
`on_bad_input` (logged at DEBUG only: the node alerts, rate-limited), never raised.
Everything published carries the source attachment (intake.source_tag: this session's
id and the autopilot's MAVLink system id); `subscribe_sourced` hands it to the callback.
`SwarmBus.close()` undeclares everything it declared (a process that exits with a
callback subscriber still declared hangs).
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

from . import intake, lan
from .errors import DecodeError, EncodeError
from .intake import Source
from .topics import ALIVE, HOLDER, Congestion, Reliability, Topic, prefix, topic_of
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
    # Nothing larger than the registry's largest cap is reassembled, and no shared
    # memory: on one host Zenoh 1.10 passes payloads over 3 KiB through a 16 MiB shared
    # pool by default (transport_optimization), which neither limit applies to and which
    # stays mapped in the receiver (docs/security.md, "Input size caps")
    conf.insert_json5("transport/link/rx/max_message_size", str(intake.max_message_bytes()))
    conf.insert_json5("transport/shared_memory/enabled", "false")
    if json.loads(conf.get_json("mode")) == "router":
        # a router enforces the registry's size caps itself (intake.size_filters): what
        # exceeds them never reaches the nodes behind it (a node still drops, counts and
        # reports what a peer sends it directly); a config file's own rules are kept
        own = json.loads(conf.get_json("low_pass_filter"))
        ours = intake.size_filters()
        names = {r["id"] for r in ours}
        kept = [r for r in own if isinstance(r, dict) and r.get("id") not in names]
        conf.insert_json5("low_pass_filter", json.dumps(kept + ours))
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
SourcedCallback = Callable[[Any, str, Source], None]  # (message, key, who says it sent it)
BadInputCallback = Callable[[str, DecodeError], None]  # (key, error)
AliveCallback = Callable[[int, bool], None]  # (node_id, alive)
HolderCallback = Callable[[int, str, bool], None]  # (node_id, Zenoh session id, alive)


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
        zid = getattr(session, "zid", None)  # (a test's stand-in session may have none)
        self.zid = str(zid()) if zid is not None else ""
        self._tag = intake.source_tag(self.zid)
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
    def set_sysid(self, sysid: int) -> None:
        """The MAVLink system id of this node's autopilot, from now on in the source
        attachment of everything published (0: none)."""
        self._tag = intake.source_tag(self.zid, sysid)

    def publish(self, msg: msgspec.Struct) -> str:
        """Encode and publish a message on its key; returns the key. EncodeError for a
        message larger than its topic takes (the receivers would drop it)."""
        topic = topic_of(msg)
        key = topic.key_of(self.swarm, msg)
        payload = lan.encode(msg)
        problem = intake.too_large(topic, len(payload))
        if problem:
            raise EncodeError(f"{type(msg).__name__} not sent: {problem}")
        with self._lock:
            if self._closed:
                raise RuntimeError("SwarmBus is closed")
            pub = self._publishers.get(key)
            if pub is None:
                pub = self.session.declare_publisher(key, **_qos(topic))
                self._publishers[key] = pub
        pub.put(payload, attachment=self._tag)
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
        return self._subscribe(topic, lambda msg, k, _att: callback(msg, k), key, sourced=False)

    def subscribe_sourced(
        self,
        topic: Topic,
        callback: SourcedCallback,
        key: str | None = None,
        *,
        remote_only: bool = False,
        quiet: bool = False,
    ) -> zenoh.Subscriber:
        """As `subscribe`, and `callback(message, key, source)` gets who the sample says
        published it (intake.parse_source). `remote_only`: not what this session
        publishes itself. `quiet`: what it drops is not counted nor reported (another
        subscription of this bus hears the same samples and does)."""
        return self._subscribe(
            topic,
            lambda msg, k, att: callback(msg, k, intake.parse_source(att)),
            key,
            sourced=True,
            remote_only=remote_only,
            quiet=quiet,
        )

    def _subscribe(
        self,
        topic: Topic,
        deliver: Callable[[Any, str, bytes | None], None],
        key: str | None,
        *,
        sourced: bool,
        remote_only: bool = False,
        quiet: bool = False,
    ) -> zenoh.Subscriber:
        if topic.msg_type is None:
            raise ValueError(f"topic {topic.name} carries no messages")
        expr = key or topic.wildcard(self.swarm)
        swarm = self.swarm

        def handler(sample: zenoh.Sample) -> None:
            k = str(sample.key_expr)
            payload = sample.payload
            # the size before the bytes: an oversized payload is never copied out of Zenoh
            problem = intake.too_large(topic, len(payload))
            if problem:
                if not quiet:
                    self._bad(topic.name, k, DecodeError(problem, reason=intake.TOO_LARGE))
                return
            try:
                msg: Any = intake.decode(topic, swarm, k, payload.to_bytes())
            except DecodeError as exc:
                if not quiet:
                    self._bad(topic.name, k, exc)
                return
            att = None
            if sourced:
                a = sample.attachment
                if a is not None and len(a) <= intake.MAX_ATTACHMENT_BYTES:
                    att = a.to_bytes()
            try:
                deliver(msg, k, att)
            except Exception:  # a bug in our handler must not kill Zenoh's thread
                log.exception("handler for %s failed", k)

        if remote_only:
            sub = self.session.declare_subscriber(
                expr, handler, allowed_origin=zenoh.Locality.REMOTE
            )
        else:
            sub = self.session.declare_subscriber(expr, handler)
        with self._lock:
            self._declared.append(sub)
        return sub

    def _bad(self, topic_name: str, key: str, exc: DecodeError) -> None:
        self.bad_input[topic_name] += 1
        # one line per drop would be a log flood: the node alerts (rate-limited) instead
        log.debug("dropped %s payload on %s: %s", exc.reason, key[:200], exc)
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
                self._bad(
                    ALIVE.name,
                    str(sample.key_expr),
                    DecodeError("bad liveliness key", reason=intake.BAD_KEY),
                )
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

    def declare_holder(self, node_id: int) -> zenoh.LivelinessToken:
        """The token that says this session holds `node_id` (HOLDER: a vehicle node's;
        two sessions holding one id are an identity conflict)."""
        key = HOLDER.key(self.swarm, node_id=node_id, zid=self.zid)
        token = self.session.liveliness().declare_token(key)
        with self._lock:
            self._declared.append(token)
        return token

    def watch_holders(self, callback: HolderCallback) -> zenoh.Subscriber:
        """callback(node_id, zid, alive) for every holder token there and every change."""

        def handler(sample: zenoh.Sample) -> None:
            k = str(sample.key_expr)
            params = HOLDER.parse(self.swarm, k)
            if (
                params is None
                or not params["node_id"].isdigit()
                or not 0 < int(params["node_id"]) < 65535
                or len(params["zid"]) > 32
            ):
                self._bad(HOLDER.name, k, DecodeError("bad holder key", reason=intake.BAD_KEY))
                return
            try:
                callback(
                    int(params["node_id"]),
                    params["zid"].lower(),
                    sample.kind == zenoh.SampleKind.PUT,
                )
            except Exception:
                log.exception("holder handler failed")

        sub = self.session.liveliness().declare_subscriber(
            HOLDER.wildcard(self.swarm), handler, history=True
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
