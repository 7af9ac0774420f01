"""Every message decoder is built on the thread that opens a session (swarm_proto/warm.py:
msgspec builds a type's decode information lazily; two threads meeting a type for the
first time at once crashed a gateway at start-up, `mpack_decode` on a NULL type)."""

from __future__ import annotations

import subprocess
import sys

from swarm_proto import radio
from swarm_proto.messages import MESSAGE_TYPES
from swarm_proto.topics import TOPICS


def test_every_topic_and_radio_type_is_warmed() -> None:
    from swarm_proto.warm import message_types

    types = set(message_types())
    assert set(MESSAGE_TYPES) <= types
    assert {t.msg_type for t in TOPICS if t.msg_type is not None} <= types
    assert set(radio.TAG_OF) <= types


def test_a_bus_builds_every_decoder_before_any_callback() -> None:
    """In a fresh process (nothing cached yet): creating a SwarmBus builds every LAN
    decoder and radio plan first."""
    code = """
from swarm_proto import lan, radio
from swarm_proto.session import SwarmBus
from swarm_proto.warm import message_types
assert lan._decoder.cache_info().currsize == 0 and not radio._PLANS
class S:  # SwarmBus only keeps the session until something is declared
    pass
SwarmBus(S(), "default")
assert lan._decoder.cache_info().currsize == len(message_types())
assert set(radio.TAG_OF) <= set(radio._PLANS)
print("ok")
"""
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert out.stdout.strip() == "ok", out.stderr
