"""What a receiver does with a sample before any logic sees it (pure): the size cap of
its topic, checked before the payload is copied or decoded; the decode; the check that
the key names what the payload says; who the sample says it comes from; and a
rate-limited alarm for what was dropped.

    problem = too_large(topic, size)              # before copying the payload
    msg = decode(topic, swarm, key, data)         # or DecodeError(reason=...)
    source = parse_source(attachment)             # who says it published this
    alarm.dropped(key, reason, text, now)         # at most one Alarm a minute per topic

Drop reasons (`DecodeError.reason`, the counts in a node's SwarmView):

| reason | what |
|---|---|
| `too_large` | bigger than its topic's `max_bytes` (never copied nor decoded) |
| `malformed` | not MessagePack |
| `invalid` | MessagePack, but not the message: a field of the wrong type or missing, out of its range (NaN too), a message rule broken |
| `key_mismatch` | the key names another id than the payload (`vehicle/7/status` carrying vehicle 8; `cmd/555` whose `issuer_id` is 901) |
| `bad_key` | a key of no topic, or a liveliness key without a number |
| `identity` | a vehicle's telemetry from a source other than the one trusted (swarm_node core/identity.py) |

Zenoh itself refuses larger messages first (`max_message_bytes`: no session reassembles
one larger than the largest cap) and a router drops what exceeds a topic's cap
(`size_filters`); those never reach the application and are not counted.

Fields a receiver does not know are not a reason: senders append fields (the evolution
rule in messages.py), and the size cap bounds what they can add.

**Sources.** Every bandada publisher attaches `bandada-src:<zid>:<sysid>`: its Zenoh
session id and its autopilot's MAVLink system id (0: none). A radio gateway attaches
`bandada-radio:<gateway id>` to what it relays from the air. A sample without either is
from a foreign publisher. An attachment is what the publisher says: anyone can copy
one (docs/security.md says what it tells and what it does not).
"""

from __future__ import annotations

import string
from collections import Counter
from dataclasses import dataclass, field
from typing import Any

import msgspec

from .errors import DecodeError
from .lan import decoder
from .text import short_text
from .topics import ROOT, TOPICS, Topic, prefix

TOO_LARGE = "too_large"
MALFORMED = "malformed"
INVALID = "invalid"
KEY_MISMATCH = "key_mismatch"
BAD_KEY = "bad_key"
IDENTITY = "identity"
REASONS = (TOO_LARGE, MALFORMED, INVALID, KEY_MISMATCH, BAD_KEY, IDENTITY)

ALARM_PERIOD_S = 60.0  # at most one alarm per topic in this long

# --------------------------------------------------------------------------- payloads


def too_large(topic: Topic, size: int) -> str | None:
    """Why a payload of `size` bytes is refused on `topic` (None: within its cap)."""
    cap = topic.max_bytes
    if cap is not None and size > cap:
        return f"{size} bytes, more than the {cap} {topic.name} takes"
    return None


def decode(topic: Topic, swarm: str, key: str, data: bytes | bytearray | memoryview) -> Any:
    """The message a sample on `key` carries, or DecodeError with its `reason`. Checks
    the size cap too (for callers that hold the bytes already)."""
    cls = topic.msg_type
    if cls is None:
        raise DecodeError(f"{topic.name} carries no message", reason=BAD_KEY)
    problem = too_large(topic, len(data))
    if problem:
        raise DecodeError(problem, reason=TOO_LARGE)
    try:
        msg: Any = decoder(cls).decode(data)
    except msgspec.ValidationError as exc:
        raise DecodeError(f"invalid {cls.__name__}: {exc}", reason=INVALID) from exc
    except (msgspec.MsgspecError, ValueError, TypeError, OverflowError, RecursionError) as exc:
        raise DecodeError(f"malformed {cls.__name__}: {exc}", reason=MALFORMED) from exc
    problem = key_problem(topic, swarm, key, msg)
    if problem:
        raise DecodeError(problem, reason=KEY_MISMATCH)
    return msg


def key_problem(topic: Topic, swarm: str, key: str, msg: msgspec.Struct) -> str | None:
    """Why `key` is not the key `msg` is published on (None: it is). Every id a key
    names (the sender's, the mission's, the zone's ...) is the payload's field of the
    same name, as `Topic.key_of` builds it."""
    params = topic.parse(swarm, key)
    if params is None:
        return f"not a {topic.name} key"
    for name, value in params.items():
        field_value = getattr(msg, name, None)
        if field_value is None:
            continue
        if value != str(int(field_value)):
            return f"key {name} {value[:12]}, payload {int(field_value)}"
    return None


def max_message_bytes() -> int:
    """The largest message a bandada session takes from Zenoh at all (its
    `transport/link/rx/max_message_size`): the largest cap of the registry and room for
    a key and an attachment. A larger one is dropped as its fragments arrive, before it
    is reassembled."""
    return max(t.max_bytes or 0 for t in TOPICS) + 64 * 1024


def size_filters() -> list[dict[str, Any]]:
    """The topic registry's size caps as Zenoh `low_pass_filter` rules (ingress, every
    swarm): Zenoh itself drops a larger put or reply before it reaches the application.
    On a router they keep an oversized sample from reaching the nodes at all (a node
    that receives one spends memory reassembling it even when it is dropped); the
    attachment is allowed for. Keys of no topic under the root take the largest cap."""
    rules: list[dict[str, Any]] = []
    largest = 0
    for topic in TOPICS:
        if topic.max_bytes is None:
            continue
        largest = max(largest, topic.max_bytes)
        rules.append(
            {
                "id": f"bandada-{topic.name}",
                "flows": ["ingress"],
                "messages": ["put", "reply"],
                "key_exprs": [f"{ROOT}/*/{_pattern_expr(topic)}"],
                "size_limit": topic.max_bytes + MAX_ATTACHMENT_BYTES,
            }
        )
    rules.append(
        {
            "id": "bandada-other",
            "flows": ["ingress"],
            "messages": ["put"],
            "key_exprs": [f"{ROOT}/**"],
            "size_limit": largest + MAX_ATTACHMENT_BYTES,
        }
    )
    return rules


def key_expr_of(swarm: str, key: str) -> str:
    """The topic key expression a concrete key belongs to, relative to the swarm
    (`vehicle/*/status`), or "other": the bounded set alarms and counts are kept by."""
    for topic in TOPICS:
        if topic.parse(swarm, key) is not None:
            return _pattern_expr(topic)
    return "other"


def _pattern_expr(topic: Topic) -> str:
    return "".join(
        lit + ("*" if f else "") for lit, f, _, _ in string.Formatter().parse(topic.pattern)
    )


def relative(swarm: str, key: str) -> str:
    """`key` without the swarm's prefix (for a person; short)."""
    p = prefix(swarm) + "/"
    return key[len(p) :] if key.startswith(p) else key


# --------------------------------------------------------------------------- sources

SOURCE_ATTACHMENT = b"bandada-src:"
RADIO_ATTACHMENT = b"bandada-radio"
MAX_ATTACHMENT_BYTES = 96  # larger attachments are not read (the sample is foreign)
_HEX = frozenset("0123456789abcdef")


@dataclass(frozen=True, slots=True)
class Source:
    """Who a sample says it comes from (its attachment)."""

    zid: str = ""  # the publishing Zenoh session's id, hex ("": not named)
    sysid: int = 0  # the MAVLink system id of the publisher's autopilot (0: none)
    relay: int = 0  # relayed from the air by this radio gateway (0: not relayed)

    @property
    def key(self) -> str:
        """What tells two sources apart: a session, the radio, or "foreign"."""
        if self.relay:
            return "radio"
        return self.zid or "foreign"

    @property
    def foreign(self) -> bool:
        return not self.zid and not self.relay

    def describe(self) -> str:
        if self.relay:
            return f"radio gateway {self.relay}"
        if not self.zid:
            return "a foreign publisher"
        text = f"session {self.zid[:8]}"
        return f"{text} sysid {self.sysid}" if self.sysid else text


FOREIGN = Source()


def source_tag(zid: str, sysid: int = 0) -> bytes:
    """The attachment a bandada publisher puts on what it publishes."""
    return SOURCE_ATTACHMENT + zid.encode() + b":" + str(sysid & 0xFF).encode()


def parse_source(data: bytes | None) -> Source:
    """The source an attachment names; FOREIGN for none or anything else."""
    if not data or len(data) > MAX_ATTACHMENT_BYTES:
        return FOREIGN
    if data.startswith(SOURCE_ATTACHMENT):
        zid, sep, sysid = data[len(SOURCE_ATTACHMENT) :].partition(b":")
        text = zid.decode("ascii", "replace").lower()
        if (
            sep
            and 1 <= len(text) <= 32
            and set(text) <= _HEX
            and sysid.isdigit()
            and int(sysid) <= 255
        ):
            return Source(text, int(sysid))
        return FOREIGN
    if data.startswith(RADIO_ATTACHMENT):
        _, _, gw = data[len(RADIO_ATTACHMENT) :].partition(b":")
        return Source(relay=int(gw) if gw.isdigit() and 0 < int(gw) < 65535 else 65535)
    return FOREIGN


# --------------------------------------------------------------------------- the alarm


@dataclass(frozen=True)
class Alarm:
    """Drops on one topic to report: how many since the last alarm, and the first."""

    key_expr: str  # relative to the swarm, e.g. "vehicle/*/status"
    count: int
    first: str  # the first drop's concrete key and reason

    @property
    def text(self) -> str:
        return short_text(f"{self.count} dropped, first {self.first}")


@dataclass
class _Window:
    end: float
    count: int = 0
    first: str = ""


@dataclass
class InputAlarm:
    """Counts what was dropped (by topic and reason) and says so at most once per
    `period_s` per topic key expression: the first drop at once, then, at the end of
    each period with drops, how many and the first of them.

        alarm.dropped(swarm, key, reason, text, now) -> Alarm | None
        alarm.on_timer(now) -> list[Alarm]
        alarm.next_deadline() -> float | None

    Memory is bounded: one window per topic (and "other"), one count per topic and
    reason."""

    swarm: str
    period_s: float = ALARM_PERIOD_S
    counts: Counter[tuple[str, str]] = field(default_factory=Counter)  # (key expr, reason)
    _windows: dict[str, _Window] = field(default_factory=dict)

    def dropped(self, key: str, reason: str, text: str, now: float) -> Alarm | None:
        expr = key_expr_of(self.swarm, key)
        self.counts[(expr, reason if reason in REASONS else MALFORMED)] += 1
        first = f"{relative(self.swarm, key)[:40]}: {reason} {text}"
        window = self._windows.get(expr)
        if window is None or (now >= window.end and not window.count):
            # the last alarm on this topic is a period old or more: this one now
            self._windows[expr] = _Window(now + self.period_s)
            return Alarm(expr, 1, first)
        window.count += 1
        if not window.first:
            window.first = first
        return None

    def on_timer(self, now: float) -> list[Alarm]:
        out = []
        for expr, window in list(self._windows.items()):
            if window.count and now >= window.end:
                out.append(Alarm(expr, window.count, window.first))
                self._windows[expr] = _Window(now + self.period_s)
        return out

    def next_deadline(self) -> float | None:
        due = [w.end for w in self._windows.values() if w.count]
        return min(due) if due else None

    def by_reason(self) -> dict[str, int]:
        out: Counter[str] = Counter()
        for (_, reason), n in self.counts.items():
            out[reason] += n
        return dict(out)
