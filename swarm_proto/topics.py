"""The key-expression layout and the topic registry: one place that names every key,
its message type, its Zenoh QoS and its radio policy (like PX4's dds_topics.yaml).

Keys live under `bandada/<swarm>/`. A message's key is computed from the message
itself (`Topic.key_of`), so the radio never carries key strings: a receiver rebuilds
the key from the decoded message.

`python -m swarm_proto.keyspace_doc` prints docs/keyspace.md from it (kept in sync by a test).
"""

from __future__ import annotations

import re
import string
from enum import Enum, IntEnum
from typing import Any

import msgspec

from .messages import (
    Ack,
    Alert,
    Command,
    DeclaredState,
    FleetAssignment,
    Mission,
    NoFlyZone,
    PlanLineage,
    RadioStats,
    SwarmView,
    TargetReport,
    VehicleInfo,
    VehicleStatus,
    Vote,
)

ROOT = "bandada"
_SWARM_RE = re.compile(r"^[A-Za-z0-9_-]{1,32}$")


def check_swarm_name(swarm: str) -> str:
    if not _SWARM_RE.match(swarm):
        raise ValueError(f"swarm name {swarm!r}: use 1-32 letters, digits, '_' or '-'")
    return swarm


def prefix(swarm: str) -> str:
    return f"{ROOT}/{check_swarm_name(swarm)}"


class Reliability(Enum):
    RELIABLE = "reliable"
    BEST_EFFORT = "best_effort"


class Congestion(Enum):
    DROP = "drop"  # latest-value data: drop rather than delay
    BLOCK = "block"  # commands: never drop


class Priority(IntEnum):
    """Zenoh priorities (same numbering as zenoh.Priority)."""

    REAL_TIME = 1
    INTERACTIVE_HIGH = 2
    INTERACTIVE_LOW = 3
    DATA_HIGH = 4
    DATA = 5
    DATA_LOW = 6
    BACKGROUND = 7


class RadioClass(IntEnum):
    """Radio scheduling class: a lower value goes on air first."""

    CONTROL = 0  # commands, acks, votes, missions, zones, fleets
    ALERT = 1
    STATUS = 2
    INFO = 3


class RadioPolicy(msgspec.Struct, frozen=True):
    on_air: bool
    klass: RadioClass = RadioClass.INFO
    max_rate_hz: float | None = None  # per source; None: as produced
    latest_only: bool = False  # keep only the newest value per key (telemetry)
    acked: bool = False  # fragmented, acknowledged and retransmitted


class Topic(msgspec.Struct, frozen=True):
    name: str
    pattern: str  # relative to bandada/<swarm>/, {field} placeholders
    msg_type: type | None  # None: not a message (liveliness, queryable)
    doc: str
    reliability: Reliability = Reliability.RELIABLE
    congestion: Congestion = Congestion.BLOCK
    priority: Priority = Priority.DATA
    express: bool = False
    radio: RadioPolicy = RadioPolicy(on_air=False)

    @property
    def params(self) -> tuple[str, ...]:
        return tuple(f for _, f, _, _ in string.Formatter().parse(self.pattern) if f)

    def key(self, swarm: str, **params: Any) -> str:
        """The concrete key. Missing parameters become `*` (a one-chunk wildcard)."""
        values = {p: params.get(p, "*") for p in self.params}
        return f"{prefix(swarm)}/{self.pattern.format(**values)}"

    def wildcard(self, swarm: str) -> str:
        return self.key(swarm)

    def key_of(self, swarm: str, msg: msgspec.Struct) -> str:
        """The key a message is published on, computed from its own fields."""
        return self.key(swarm, **{p: int(getattr(msg, p)) for p in self.params})

    def parse(self, swarm: str, key: str) -> dict[str, str] | None:
        """The placeholder values of a concrete key, or None if it is not this topic's."""
        rx = "^" + re.escape(prefix(swarm) + "/")
        for literal, field, _, _ in string.Formatter().parse(self.pattern):
            rx += re.escape(literal)
            if field:
                rx += f"(?P<{field}>[^/]+)"
        m = re.match(rx + "$", key)
        return m.groupdict() if m else None


_TELEMETRY = dict(reliability=Reliability.BEST_EFFORT, congestion=Congestion.DROP)

STATUS = Topic(
    "status",
    "vehicle/{vehicle_id}/status",
    VehicleStatus,
    "Fast telemetry, 5 Hz.",
    priority=Priority.DATA_HIGH,
    express=True,
    radio=RadioPolicy(True, RadioClass.STATUS, max_rate_hz=5.0, latest_only=True),
    **_TELEMETRY,  # type: ignore[arg-type]
)
INFO = Topic(
    "info",
    "vehicle/{vehicle_id}/info",
    VehicleInfo,
    "Identity and slower state, 1 Hz.",
    priority=Priority.DATA,
    radio=RadioPolicy(True, RadioClass.INFO, max_rate_hz=1.0, latest_only=True),
    **_TELEMETRY,  # type: ignore[arg-type]
)
ACK = Topic(
    "ack",
    "vehicle/{vehicle_id}/ack",
    Ack,
    "Answers to commands, missions, zones and fleet assignments.",
    priority=Priority.INTERACTIVE_HIGH,
    radio=RadioPolicy(True, RadioClass.CONTROL, acked=True),
)
ALERT = Topic(
    "alert",
    "vehicle/{vehicle_id}/alert",
    Alert,
    "Alerts raised by vehicle monitoring and the swarm logic.",
    priority=Priority.DATA_HIGH,
    radio=RadioPolicy(True, RadioClass.ALERT, acked=True),
)
COMMAND = Topic(
    "command",
    "cmd/{issuer_id}",
    Command,
    "Operator or peer commands; the Selector inside says who is addressed.",
    priority=Priority.INTERACTIVE_HIGH,
    radio=RadioPolicy(True, RadioClass.CONTROL, acked=True),
)
MISSION = Topic(
    "mission",
    "mission/{mission_id}",
    Mission,
    "Missions for the swarm.",
    priority=Priority.INTERACTIVE_LOW,
    radio=RadioPolicy(True, RadioClass.CONTROL, acked=True),
)
VOTE = Topic(
    "vote",
    "vote/{mission_id}/{voter_id}",
    Vote,
    "Voting for QUANTITY missions.",
    priority=Priority.INTERACTIVE_LOW,
    radio=RadioPolicy(True, RadioClass.CONTROL, acked=True),
)
FLEET = Topic(
    "fleet",
    "fleet/{fleet_id}",
    FleetAssignment,
    "Which vehicles fly a mission together.",
    priority=Priority.INTERACTIVE_LOW,
    radio=RadioPolicy(True, RadioClass.CONTROL, acked=True),
)
ZONE = Topic(
    "zone",
    "zone/{zone_id}",
    NoFlyZone,
    "No-fly zones.",
    priority=Priority.INTERACTIVE_LOW,
    radio=RadioPolicy(True, RadioClass.CONTROL, acked=True),
)
TARGET = Topic(
    "target",
    "target/{source_id}/{target_id}",
    TargetReport,
    "Targets detected by payloads or marked by the operator.",
    priority=Priority.DATA_HIGH,
    radio=RadioPolicy(True, RadioClass.ALERT, acked=True),
)
LINEAGE = Topic(
    "lineage",
    "lineage/{mission_id}/{sender_id}",
    PlanLineage,
    "How a fleet's plan came to be, for a vehicle joining it (add, swap) or a fleet "
    "taking over an emptied fleet's mission; published by the fleet's members.",
    priority=Priority.INTERACTIVE_LOW,
    radio=RadioPolicy(True, RadioClass.CONTROL, acked=True),
)
ALIVE = Topic(
    "alive",
    "alive/{node_id}",
    None,
    "Liveliness token of every running node (vehicle, ground station, gateway).",
)

PEERS = Topic(
    "peers",
    "vehicle/{vehicle_id}/peers",
    SwarmView,
    "Queryable: the node's view of the swarm (its live peers); LAN only.",
)
ZONES = Topic(
    "zones",
    "vehicle/{vehicle_id}/zones/{zone_id}",
    None,
    "Queryable: the no-fly zones and operating areas the node holds (withdrawn ones "
    "too), one NoFlyZone reply per zone on its own key; a (re)started node and the "
    "ground station ask it (`vehicle/*/zones/*`). LAN only.",
)
MISSIONS = Topic(
    "missions",
    "vehicle/{vehicle_id}/missions/{mission_id}",
    None,
    "Queryable: the missions the node accepted (the one in force is VehicleInfo's "
    "`mission_id`), one Mission reply per mission on its own key; the ground station's "
    "`gcs save` asks it (`vehicle/*/missions/*`). LAN only.",
)
DECLARED = Topic(
    "declared",
    "vehicle/{vehicle_id}/declared",
    DeclaredState,
    "Queryable: what the operator declared, as the node holds it (zones, bases, fleets, "
    "missions, each with its stamp; the newest wins). A (re)started node asks each peer "
    "that comes alive and merges; `gcs declared` asks any node. LAN only.",
)
DATABASE = Topic(
    "database",
    "db/{node_id}",
    None,
    "Swarm database of a node (queryable): `db/<node_id>` answers its info; beneath it "
    "`profile`, `profiles`, `table/<group>/<table>[?field=value]`, `export`. "
    "MessagePack replies, errors as `{error}` (docs/database.md).",
)
RADIO_STATS = Topic(
    "radio_stats",
    "radio/{node_id}/stats",
    RadioStats,
    "Radio gateway statistics per peer (LAN only).",
)

TOPICS: tuple[Topic, ...] = (
    STATUS,
    INFO,
    ACK,
    ALERT,
    COMMAND,
    MISSION,
    VOTE,
    FLEET,
    ZONE,
    TARGET,
    LINEAGE,
    ALIVE,
    PEERS,
    ZONES,
    MISSIONS,
    DECLARED,
    DATABASE,
    RADIO_STATS,
)
TOPIC_OF_TYPE: dict[type, Topic] = {t.msg_type: t for t in TOPICS if t.msg_type is not None}


def topic_of(msg_or_type: msgspec.Struct | type) -> Topic:
    cls = msg_or_type if isinstance(msg_or_type, type) else type(msg_or_type)
    try:
        return TOPIC_OF_TYPE[cls]
    except KeyError:
        raise KeyError(f"no topic carries {cls.__name__}") from None


def key_of(swarm: str, msg: msgspec.Struct) -> str:
    return topic_of(msg).key_of(swarm, msg)


def match(swarm: str, key: str) -> tuple[Topic, dict[str, str]] | None:
    """Which topic a concrete key belongs to, and its placeholder values."""
    for topic in TOPICS:
        params = topic.parse(swarm, key)
        if params is not None:
            return topic, params
    return None
