"""Build every message decoder on the calling thread, before any Zenoh or serial thread
decodes (`open_session` calls `warm_decoders`).

Why: a `swarm-sim demo --radio` start-up crashed twice in msgspec (`mpack_decode`, a
NULL type pointer). msgspec builds a Struct type's decode information lazily, the first
time a decoder or `convert` meets the type, and publishes it on the type while still
filling it in; two threads meeting a type for the first time at once (a Zenoh callback
and the gateway's serial reader) can decode with a half-built one. Our radio codec's
field plans (`radio._plan`) are built the same way. Building all of them up front, on
one thread, leaves no first time for a second thread to race. Idempotent and cheap
after the first call (everything is cached).
"""

from __future__ import annotations

import msgspec

from . import lan, radio
from .messages import MESSAGE_TYPES, DeclaredMission, DeclaredState, SwarmView
from .topics import TOPICS

_done = False


def message_types() -> tuple[type[msgspec.Struct], ...]:
    """Every type a process decodes whole: the messages, each topic's type and the
    query replies (nested structs are built with the type that holds them)."""
    types: list[type[msgspec.Struct]] = [*MESSAGE_TYPES, DeclaredMission, DeclaredState, SwarmView]
    for t in TOPICS:
        if isinstance(t.msg_type, type) and issubclass(t.msg_type, msgspec.Struct):
            types.append(t.msg_type)
    return tuple(dict.fromkeys(types))


def warm_decoders() -> int:
    """Build the LAN decoder and the radio plan of every message type; returns how many
    types (0 when already done)."""
    global _done
    if _done:
        return 0
    types = message_types()
    for cls in types:
        lan.decoder(cls)  # msgspec.msgpack.Decoder(cls): builds cls's and nested types' info
        if cls in radio.TAG_OF:
            radio.plan(cls)
    _done = True
    return len(types)
