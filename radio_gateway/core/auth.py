"""Frame authentication: a truncated keyed BLAKE2s MAC bound to the GPS-time cycle counter,
and replay protection.

Every node of a swarm shares one 32-byte key (a file; see `parse_key`). A frame's tag is
BLAKE2s-48 keyed with it, over the full 64-bit cycle counter of the slot the frame was sent
in followed by the frame's bytes. Only the counter's low 16 bits travel; the receiver
supplies the rest from its own GPS time, so a frame replayed in another cycle, or
recorded 3.6 hours (65,536 cycles) earlier, fails the tag. `ReplayGuard` rejects a frame
whose counter is not newer than the last one accepted from its source, or too far from
the receiver's own cycle.

Overhead on air: 6 bytes of tag plus 2 bytes of counter (which the TDM needs anyway).
"""

from __future__ import annotations

import hashlib
import hmac
from dataclasses import dataclass, field

KEY_BYTES = 32
TAG_BYTES = 6
COUNTER_BYTES = 2
AUTH_OVERHEAD_BYTES = TAG_BYTES + COUNTER_BYTES
_PERSON = b"bandada1"


class SwarmKeyError(ValueError):
    """A swarm key file that is not 32 bytes (raw) or 64 hex digits."""


def parse_key(content: bytes) -> bytes:
    """The 32-byte swarm key from a key file's content: 64 hex digits (whitespace
    ignored) or exactly 32 raw bytes."""
    text = content.strip()
    if len(text) == 2 * KEY_BYTES:
        try:
            return bytes.fromhex(text.decode("ascii"))
        except (UnicodeDecodeError, ValueError):
            pass
    if len(content) == KEY_BYTES:
        return bytes(content)
    raise SwarmKeyError(
        f"a swarm key is {KEY_BYTES} raw bytes or {2 * KEY_BYTES} hex digits, got {len(content)} bytes"
    )


def tag(key: bytes, cycle: int, data: bytes) -> bytes:
    """The 6-byte tag of `data` sent in `cycle`."""
    h = hashlib.blake2s(key=key, digest_size=TAG_BYTES, person=_PERSON)
    h.update((cycle & 0xFFFF_FFFF_FFFF_FFFF).to_bytes(8, "little"))
    h.update(data)
    return h.digest()


def verify(key: bytes, cycle: int, data: bytes, received: bytes) -> bool:
    return hmac.compare_digest(tag(key, cycle, data), received)


def unwrap16(lo: int, near: int) -> int:
    """The integer nearest to `near` whose low 16 bits are `lo`."""
    base = near - ((near - lo) & 0xFFFF)
    return base + 0x10000 if near - base > 0x8000 else base


@dataclass
class ReplayGuard:
    """Accepts a (source, cycle) at most once, in increasing order, near our own cycle."""

    window_cycles: int = 2
    _last: dict[int, int] = field(default_factory=dict)

    def check(self, src: int, cycle: int, my_cycle: int) -> str | None:
        """None if fresh (and remembers it), else the reason: "stale" or "replay"."""
        if abs(cycle - my_cycle) > self.window_cycles:
            return "stale"
        last = self._last.get(src)
        if last is not None and cycle <= last:
            return "replay"
        self._last[src] = cycle
        return None
