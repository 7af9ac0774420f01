"""Consistent Overhead Byte Stuffing (Cheshire and Baker, 1999) and a stream deframer.

COBS removes every 0x00 from a frame at a cost of one byte per 254 (one byte for any
frame the radio carries), so 0x00 can delimit frames on the serial stream: a receiver
that joins mid-stream, or loses bytes, resynchronises at the next 0x00.
"""

from __future__ import annotations

from dataclasses import dataclass, field


class CobsError(ValueError):
    """The bytes are not a valid COBS encoding."""


def encode(data: bytes) -> bytes:
    """COBS-encode `data` (the result contains no 0x00; the delimiter is not added)."""
    out = bytearray()
    block = bytearray()
    for b in data:
        if b == 0:
            out.append(len(block) + 1)
            out += block
            block.clear()
        else:
            block.append(b)
            if len(block) == 254:
                out.append(255)
                out += block
                block.clear()
    out.append(len(block) + 1)
    out += block
    return bytes(out)


def decode(data: bytes) -> bytes:
    """Decode one COBS frame (without its delimiter). Raises CobsError."""
    out = bytearray()
    i, n = 0, len(data)
    if n == 0:
        raise CobsError("empty frame")
    while i < n:
        code = data[i]
        if code == 0:
            raise CobsError(f"zero byte at {i}")
        end = i + code
        if end > n:
            raise CobsError("block runs past the end of the frame")
        block = data[i + 1 : end]
        if 0 in block:
            raise CobsError("zero byte inside a block")
        out += block
        i = end
        if code != 255 and i < n:
            out.append(0)
    return bytes(out)


def max_encoded_len(n: int) -> int:
    """Bytes on the wire for an n-byte frame: COBS overhead plus the 0x00 delimiter."""
    return n + n // 254 + 1 + 1


@dataclass
class Deframer:
    """Splits a serial byte stream into frames at 0x00 delimiters (pure, time injected).

    A partial frame older than `gap_s` when new bytes arrive is discarded: the radio
    delivers a packet as one burst and packets are separated by a sync preamble and a
    guard time, so a long gap means the rest of that frame was lost. Frames longer than `max_frame` are discarded. Both are counted.
    """

    max_frame: int = 4096
    gap_s: float = 0.02
    _buf: bytearray = field(default_factory=bytearray)
    _last_s: float | None = None
    truncated: int = 0
    oversized: int = 0

    def feed(self, data: bytes, now: float) -> list[bytes]:
        if self._buf and self._last_s is not None and now - self._last_s > self.gap_s:
            self._buf.clear()
            self.truncated += 1
        self._last_s = now
        frames: list[bytes] = []
        start = 0
        while True:
            j = data.find(0, start)
            if j < 0:
                self._buf += data[start:]
                break
            self._buf += data[start:j]
            if len(self._buf) > self.max_frame:
                self.oversized += 1
            elif self._buf:
                frames.append(bytes(self._buf))
            self._buf.clear()
            start = j + 1
        if len(self._buf) > self.max_frame:
            self._buf.clear()
            self.oversized += 1
        return frames
