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
    MavlinkAnswer,
    MavlinkCommand,
    MavlinkSession,
    MavlinkSummary,
    Mission,
    NoFlyZone,
    PlanLineage,
    RadioStats,
    SwarmView,
    TargetReport,
    VehicleInfo,
    VehicleIntent,
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
    PASSTHROUGH = 4  # a ground station's MAVLink: room left over only, never moved up


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
    #: the largest payload a receiver takes, checked before it is copied or decoded
    #: (swarm_proto.intake); None: no payload (liveliness) or not capped
    max_bytes: int | None = None

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


KIB = 1024
#: Missions and zones: a polygon of about 13,000 vertices (19 bytes a vertex on the LAN),
#: three times the 4,000-vertex GIS boundary the planners are benchmarked on; over the
#: radio a mission carries far fewer (docs/security.md, "Input size caps").
POLYGON_BYTES = 256 * KIB

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
    max_bytes=1 * KIB,
)
INFO = Topic(
    "info",
    "vehicle/{vehicle_id}/info",
    VehicleInfo,
    "Identity and slower state, 1 Hz.",
    priority=Priority.DATA,
    radio=RadioPolicy(True, RadioClass.INFO, max_rate_hz=1.0, latest_only=True),
    **_TELEMETRY,  # type: ignore[arg-type]
    max_bytes=2 * KIB,
)
INTENT = Topic(
    "intent",
    "vehicle/{vehicle_id}/intent",
    VehicleIntent,
    "Where the vehicle flies next (its next legs), for the peers' collision avoidance; "
    "when they change and every 2 s.",
    priority=Priority.DATA_HIGH,
    radio=RadioPolicy(True, RadioClass.STATUS, max_rate_hz=1.0, latest_only=True),
    **_TELEMETRY,  # type: ignore[arg-type]
    max_bytes=1 * KIB,
)
ACK = Topic(
    "ack",
    "vehicle/{vehicle_id}/ack",
    Ack,
    "Answers to commands, missions, zones and fleet assignments.",
    priority=Priority.INTERACTIVE_HIGH,
    radio=RadioPolicy(True, RadioClass.CONTROL, acked=True),
    max_bytes=1 * KIB,
)
ALERT = Topic(
    "alert",
    "vehicle/{vehicle_id}/alert",
    Alert,
    "Alerts raised by vehicle monitoring and the swarm logic.",
    priority=Priority.DATA_HIGH,
    radio=RadioPolicy(True, RadioClass.ALERT, acked=True),
    max_bytes=1 * KIB,
)
COMMAND = Topic(
    "command",
    "cmd/{issuer_id}",
    Command,
    "Operator or peer commands; the Selector inside says who is addressed.",
    priority=Priority.INTERACTIVE_HIGH,
    radio=RadioPolicy(True, RadioClass.CONTROL, acked=True),
    max_bytes=16 * KIB,  # a selector of about 5,000 ids
)
MISSION = Topic(
    "mission",
    "mission/{mission_id}",
    Mission,
    "Missions for the swarm.",
    priority=Priority.INTERACTIVE_LOW,
    radio=RadioPolicy(True, RadioClass.CONTROL, acked=True),
    max_bytes=POLYGON_BYTES,
)
VOTE = Topic(
    "vote",
    "vote/{mission_id}/{voter_id}",
    Vote,
    "Voting for QUANTITY missions.",
    priority=Priority.INTERACTIVE_LOW,
    radio=RadioPolicy(True, RadioClass.CONTROL, acked=True),
    max_bytes=16 * KIB,
)
FLEET = Topic(
    "fleet",
    "fleet/{fleet_id}",
    FleetAssignment,
    "Which vehicles fly a mission together.",
    priority=Priority.INTERACTIVE_LOW,
    radio=RadioPolicy(True, RadioClass.CONTROL, acked=True),
    max_bytes=16 * KIB,
)
ZONE = Topic(
    "zone",
    "zone/{zone_id}",
    NoFlyZone,
    "No-fly zones.",
    priority=Priority.INTERACTIVE_LOW,
    radio=RadioPolicy(True, RadioClass.CONTROL, acked=True),
    max_bytes=POLYGON_BYTES,
)
TARGET = Topic(
    "target",
    "target/{source_id}/{target_id}",
    TargetReport,
    "Targets detected by payloads or marked by the operator.",
    priority=Priority.DATA_HIGH,
    radio=RadioPolicy(True, RadioClass.ALERT, acked=True),
    max_bytes=1 * KIB,
)
LINEAGE = Topic(
    "lineage",
    "lineage/{mission_id}/{sender_id}",
    PlanLineage,
    "How a fleet's plan came to be, for a vehicle joining it (add, swap) or a fleet "
    "taking over an emptied fleet's mission; published by the fleet's members.",
    priority=Priority.INTERACTIVE_LOW,
    radio=RadioPolicy(True, RadioClass.CONTROL, acked=True),
    max_bytes=2 * POLYGON_BYTES,  # its mission, and a few bytes per member and replan
)
ALIVE = Topic(
    "alive",
    "alive/{node_id}",
    None,
    "Liveliness token of every running node (vehicle, ground station).",
)
HOLDER = Topic(
    "holder",
    "id/{node_id}/{zid}",
    None,
    "Liveliness token of every vehicle node: its id and its Zenoh session id. Two "
    "sessions holding one id are an identity conflict (docs/security.md).",
)

PEERS = Topic(
    "peers",
    "vehicle/{vehicle_id}/peers",
    SwarmView,
    "Queryable: the node's view of the swarm (its live peers); LAN only.",
    max_bytes=256 * KIB,
)
ZONES = Topic(
    "zones",
    "vehicle/{vehicle_id}/zones/{zone_id}",
    None,
    "Queryable: the no-fly zones and operating areas the node holds (withdrawn ones "
    "too), one NoFlyZone reply per zone on its own key; a (re)started node and the "
    "ground station ask it (`vehicle/*/zones/*`). LAN only.",
    max_bytes=POLYGON_BYTES,  # one NoFlyZone per reply
)
MISSIONS = Topic(
    "missions",
    "vehicle/{vehicle_id}/missions/{mission_id}",
    None,
    "Queryable: the missions the node accepted (the one in force is VehicleInfo's "
    "`mission_id`), one Mission reply per mission on its own key; the ground station's "
    "`gcs save` asks it (`vehicle/*/missions/*`). LAN only.",
    max_bytes=POLYGON_BYTES,  # one Mission per reply
)
DECLARED = Topic(
    "declared",
    "vehicle/{vehicle_id}/declared",
    DeclaredState,
    "Queryable: what the operator declared, as the node holds it (zones, bases, fleets, "
    "missions, each with its stamp; the newest wins). A (re)started node asks each peer "
    "that comes alive and merges; `gcs declared` asks any node. LAN only.",
    max_bytes=4 * KIB * KIB,  # a swarm's zones and missions
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
    max_bytes=64 * KIB,
)

# MAVLink passthrough (`gcs mavlink`, docs/ground-station.md): a session's frames travel
# raw, as the client and the autopilot wrote them, below the swarm's own traffic
MAVLINK_SESSION = Topic(
    "mavlink_session",
    "vehicle/{vehicle_id}/mavlink/{session_id}/session",
    MavlinkSession,
    "A ground station's MAVLink passthrough session with the vehicle's autopilot: "
    "announced every second while its client is there, and when it closes. LAN only.",
    priority=Priority.DATA_LOW,
)
MAVLINK_UP = Topic(
    "mavlink_up",
    "vehicle/{vehicle_id}/mavlink/{session_id}/up",
    None,
    "Raw MAVLink frames from the session's client (QGroundControl, MAVProxy) to the "
    "vehicle's node, which relays them to its autopilot or rules on them first "
    "(docs/autopilot-link.md, Passthrough). LAN only.",
    priority=Priority.DATA_LOW,
)
MAVLINK_DOWN = Topic(
    "mavlink_down",
    "vehicle/{vehicle_id}/mavlink/{session_id}/down",
    None,
    "Raw MAVLink frames from the vehicle's autopilot (and the node's answers on its "
    "behalf) to the session's client. LAN only.",
    priority=Priority.DATA_LOW,
    congestion=Congestion.DROP,
)

# ... and on the 900 MHz radio, a budgeted mode: a HIGH_LATENCY2 summary every 5 s and
# commands only, in the room the swarm's own traffic leaves (docs/radio.md)
MAVLINK_SUMMARY = Topic(
    "mavlink_summary",
    "vehicle/{vehicle_id}/mavlink/summary",
    MavlinkSummary,
    "The vehicle's HIGH_LATENCY2 every 5 s while a radio passthrough session asks for it.",
    priority=Priority.DATA_LOW,
    radio=RadioPolicy(True, RadioClass.PASSTHROUGH, max_rate_hz=0.2, latest_only=True),
    **_TELEMETRY,  # type: ignore[arg-type]
)
MAVLINK_COMMAND = Topic(
    "mavlink_command",
    "vehicle/{target_id}/mavlink/command/{issuer_id}",
    MavlinkCommand,
    "A radio passthrough session's command to the vehicle's autopilot (or, empty, its keep-alive).",
    priority=Priority.DATA_LOW,
    radio=RadioPolicy(True, RadioClass.PASSTHROUGH, acked=True),
)
MAVLINK_ANSWER = Topic(
    "mavlink_answer",
    "vehicle/{vehicle_id}/mavlink/answer/{issuer_id}",
    MavlinkAnswer,
    "The vehicle's answer to a radio passthrough session's command.",
    priority=Priority.DATA_LOW,
    radio=RadioPolicy(True, RadioClass.PASSTHROUGH, acked=True),
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
    HOLDER,
    PEERS,
    ZONES,
    MISSIONS,
    DECLARED,
    DATABASE,
    RADIO_STATS,
    MAVLINK_SESSION,
    MAVLINK_UP,
    MAVLINK_DOWN,
    MAVLINK_SUMMARY,
    MAVLINK_COMMAND,
    MAVLINK_ANSWER,
    INTENT,
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
