"""What crosses between the local Zenoh and the air (pure): which samples go on air, how
what is heard becomes a local publication, and the rules that keep it loop- and
duplicate-free.

- Keys never travel: a message goes on air in the radio encoding and the receiving
  gateway rebuilds its key with `swarm_proto.topics.key_of`.
- Only topics whose radio policy is on air cross, with that policy's class, rate,
  latest-only and acknowledgement settings.
- Only messages originated locally go on air: their originator field (vehicle_id,
  issuer_id, voter_id, source_id) is one of `local_ids`; a message without one (a
  NoFlyZone from a sender older than its issuer_id: 0) goes on air if
  `forward_unattributed`.
- A gateway marks what it republishes with an attachment (`RADIO_ATTACHMENT`); no gateway
  forwards a marked sample, so nothing loops between radio and LAN.
- Every message seen on the LAN or heard on air is remembered by the hash of its radio
  encoding (for `seen_ttl_s`, or `telemetry_ttl_s` for latest-only telemetry): a radio copy
  of something already on the local Zenoh (heard over the LAN first, or from another
  gateway, or twice on air) is not republished, so a node that hears the same data via the
  LAN and the radio sees it once; a message already sent is not sent again unchanged
  within the TTL; anything that came from the air is never sent back to it.
- Several gateways on one Zenoh network hear the same frame at the same moment. They
  know each other from their RadioStats; the one with the lowest node id republishes at
  once, the others hold what they heard for `holdoff_s` and republish only what the first
  did not (it may have missed the frame).
- Send on error (`predictor` set): the local vehicle's own VehicleStatus does
  not go to the outbox; `from_lan` hands it back as `OwnStatus` for the radio node, which
  puts it on air when its peers' dead reckoning of it would be off (`telemetry.py`).
  Every status heard on air is published as heard and then, every 1 / republish_hz,
  predicted to `now` (`due`), with its error bound in `position_error_m`: the nodes
  above see radio peers at 5 Hz, as LAN peers. Only the designated gateway predicts; a
  vehicle also heard on the LAN itself is not predicted. A status that is a prediction
  never goes on air, and a status of our own heard back on air is dropped.
"""

from __future__ import annotations

import hashlib
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import msgspec

from swarm_proto import Ack, VehicleStatus, lan, radio
from swarm_proto.errors import DecodeError, EncodeError
from swarm_proto.messages import MavlinkAnswer, RadioStats
from swarm_proto.topics import RADIO_STATS, STATUS, Topic, key_of, match, topic_of

from .outbox import OutMessage
from .telemetry import PeerPredictor, decode_turn

RADIO_ATTACHMENT = b"bandada-radio"
ORIGINATOR_FIELDS = ("vehicle_id", "issuer_id", "voter_id", "source_id")


def originator(msg: msgspec.Struct) -> int | None:
    """Who sent it; None when it does not say (0 is no node: a NoFlyZone from a sender
    older than its `issuer_id`)."""
    for name in ORIGINATOR_FIELDS:
        value = getattr(msg, name, None)
        if isinstance(value, int) and value:
            return value
    return None


_STATUS_HEADER = bytes((radio.RADIO_SCHEMA_VERSION, radio.TAG_OF[VehicleStatus]))


def _digest(data: bytes) -> bytes:
    """A message's identity: its radio encoding (a status without what its sender may
    have appended after the 40 bytes, e.g. the turn rate, so LAN and air copies match)."""
    if data[:2] == _STATUS_HEADER:
        data = data[: radio.STATUS_BYTES]
    return hashlib.blake2s(data, digest_size=12).digest()


@dataclass(frozen=True)
class OwnStatus:
    """The local vehicle's status, for the radio node's send-on-error (not the outbox)."""

    status: VehicleStatus


@dataclass(frozen=True)
class Publication:
    key: str
    payload: bytes  # LAN encoding
    topic: Topic
    message: Any


@dataclass
class _Memory:
    expiry: dict[bytes, float] = field(default_factory=dict)

    def add(self, h: bytes, until: float) -> None:
        self.expiry[h] = max(self.expiry.get(h, until), until)

    def has(self, h: bytes, now: float) -> bool:
        t = self.expiry.get(h)
        return t is not None and t > now

    def sweep(self, now: float) -> None:
        if len(self.expiry) > 256:
            self.expiry = {h: t for h, t in self.expiry.items() if t > now}


@dataclass
class Bridge:
    swarm: str
    node_id: int
    local_ids: frozenset[int]
    forward_unattributed: bool = True
    seen_ttl_s: float = 30.0
    telemetry_ttl_s: float = 2.0
    holdoff_s: float = 0.3
    peer_gateway_ttl_s: float = 3.5
    predictor: PeerPredictor | None = None  # send on error: statuses to OwnStatus, predictions
    lan_peer_ttl_s: float = 2.0  # a vehicle heard on the LAN itself is not predicted
    counts: Counter[str] = field(default_factory=Counter)
    gateways: dict[int, float] = field(default_factory=dict)  # other gateways -> last seen
    _lan: _Memory = field(default_factory=_Memory)  # seen on the local Zenoh
    _air: _Memory = field(default_factory=_Memory)  # came from the air (here or elsewhere)
    _sent: _Memory = field(default_factory=_Memory)
    _held: list[tuple[float, bytes, Publication]] = field(default_factory=list)
    _lan_peers: dict[int, float] = field(default_factory=dict)  # vehicle -> last heard on LAN

    def _ttl(self, topic: Topic) -> float:
        return self.telemetry_ttl_s if topic.radio.latest_only else self.seen_ttl_s

    def from_lan(
        self, key: str, payload: bytes, now: float, *, from_gateway: bool = False
    ) -> OutMessage | OwnStatus | None:
        """A sample on the local Zenoh; the message to put on air, if any (with send on
        error, the local vehicle's own status for the radio node instead)."""
        found = match(self.swarm, key)
        if found is None:
            return None
        topic, _ = found
        if topic is RADIO_STATS:
            self._note_gateway(payload, now)
            return None
        if topic.msg_type is None or not topic.radio.on_air:
            return None
        try:
            msg: msgspec.Struct = lan.decode(payload, topic.msg_type)
            data = radio.encode(msg)
        except DecodeError:
            self.counts["lan_undecodable"] += 1
            return None
        except EncodeError:
            self.counts["lan_not_radio_encodable"] += 1
            return None
        if key_of(self.swarm, msg) != key:
            self.counts["lan_wrong_key"] += 1
            return None
        status = msg if isinstance(msg, VehicleStatus) else None
        if status is not None and (status.predicted_s > 0 or status.position_error_m > 0):
            self.counts["lan_predicted"] += 1  # a gateway's prediction: never on air
            return None
        if status is not None and not from_gateway and status.vehicle_id not in self.local_ids:
            self._lan_peers[status.vehicle_id] = now  # on our LAN itself: not predicted
            if self.predictor is not None:
                self.predictor.forget(status.vehicle_id)
        h = _digest(data)
        ttl = self._ttl(topic)
        self._lan.add(h, now + ttl)
        self._lan.sweep(now)
        if from_gateway:
            self._air.add(h, now + ttl)
            return None
        if self._air.has(h, now):
            self.counts["lan_echo_of_air"] += 1
            return None
        who = originator(msg)
        if who is None:
            if not self.forward_unattributed:
                return None
        elif who not in self.local_ids:
            return None
        if status is not None and self.predictor is not None:
            self.counts["own_status"] += 1
            return OwnStatus(status)
        if self._sent.has(h, now):
            self.counts["lan_already_sent"] += 1
            return None
        self._sent.add(h, now + ttl)
        self._sent.sweep(now)
        p = topic.radio
        self.counts["to_air"] += 1
        return OutMessage(
            key=key,
            data=data,
            klass=int(p.klass),
            latest_only=p.latest_only,
            acked=p.acked,
            max_rate_hz=p.max_rate_hz,
            # an answer is for its issuer: only the issuer acknowledges it on air (with
            # every member acknowledging every vehicle's Ack, n vehicles answering a
            # command cost n^2 acknowledgements; a passthrough answer likewise)
            ack_by=msg.issuer_id if isinstance(msg, Ack | MavlinkAnswer) else 0,
        )

    def _note_gateway(self, payload: bytes, now: float) -> None:
        try:
            stats = lan.decode(payload, RadioStats)
        except DecodeError:
            self.counts["lan_undecodable"] += 1
            return
        if stats.node_id != self.node_id:
            self.gateways[stats.node_id] = now

    def designated(self, now: float) -> bool:
        """Whether we republish at once: no lower-id gateway is alive on our Zenoh."""
        return not any(
            gid < self.node_id and now - seen <= self.peer_gateway_ttl_s
            for gid, seen in self.gateways.items()
        )

    def from_air(self, data: bytes, now: float) -> Publication | None:
        """A radio message heard; what to publish on the local Zenoh now, if anything
        (held messages come out of `due`)."""
        h = _digest(data)
        if self._lan.has(h, now) or self._air.has(h, now):
            self.counts["air_duplicate"] += 1
            return None
        try:
            msg = radio.decode(data, now_unix_s=now)
        except DecodeError:
            self.counts["air_undecodable"] += 1
            return None
        try:
            topic = topic_of(msg)
        except KeyError:
            self.counts["air_unknown_topic"] += 1
            return None
        if not topic.radio.on_air:
            self.counts["air_not_on_air_topic"] += 1
            return None
        if isinstance(msg, VehicleStatus):
            if msg.vehicle_id in self.local_ids:
                self.counts["air_own_status"] += 1  # ours, relayed back
                return None
            if self.predictor is not None and not self._on_lan(msg.vehicle_id, now):
                self.predictor.on_status(msg, decode_turn(data, radio.STATUS_BYTES), now)
        ttl = self._ttl(topic)
        self._air.add(h, now + ttl)
        self._air.sweep(now)
        pub = Publication(key_of(self.swarm, msg), lan.encode(msg), topic, msg)
        if not self.designated(now):
            self._held.append((now + self.holdoff_s, h, pub))
            return None
        self.counts["from_air"] += 1
        return pub

    def _on_lan(self, vehicle_id: int, now: float) -> bool:
        t = self._lan_peers.get(vehicle_id)
        return t is not None and now - t <= self.lan_peer_ttl_s

    def predictions(
        self, now: float, alive: Callable[[int], bool] | None = None
    ) -> list[Publication]:
        """Send on error: radio peers' statuses predicted to `now` that are due (only the
        designated gateway publishes them; a peer now heard on the LAN is dropped)."""
        p = self.predictor
        if p is None:
            return []
        statuses = p.due(now, alive)
        if not statuses or not self.designated(now):
            return []
        self.counts["predicted"] += len(statuses)
        return [Publication(key_of(self.swarm, s), lan.encode(s), STATUS, s) for s in statuses]

    def next_deadline(self) -> float | None:
        """When `due` or `predictions` next has something (None: nothing waiting)."""
        times = [t for t, _, _ in self._held]
        if self.predictor is not None:
            d = self.predictor.next_deadline()
            if d is not None:
                times.append(d)
        return min(times, default=None)

    def due(self, now: float) -> list[Publication]:
        """Held messages whose hold-off is over and that no other gateway published."""
        out: list[Publication] = []
        keep = []
        for item in self._held:
            t, h, pub = item
            if t > now:
                keep.append(item)
            elif self._lan.has(h, now):
                self.counts["air_published_elsewhere"] += 1
            else:
                self.counts["from_air"] += 1
                out.append(pub)
        self._held = keep
        return out
