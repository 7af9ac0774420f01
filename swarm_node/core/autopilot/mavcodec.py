"""MAVLink 2 frames packed and unpacked without pymavlink's per-frame bookkeeping, for
the common case: an unsigned frame of a message with no arrays and no strings (the
telemetry: positions, attitude, HUD, GPS, heartbeats, system status...). The bytes out
and the message objects in are exactly pymavlink's (`tests/swarm_node/autopilot/
test_mavcodec.py` compares them); anything else (MAVLink 1, a signed frame, a message
with arrays or strings, an unknown id, a bad CRC) returns None and the caller takes
pymavlink's path, which also gives pymavlink's errors.

What pymavlink does per frame and this does not: build and pack a header object, copy
the buffer three times and run a CRC object (pack); check the signing and length again,
and reorder the fields through a generic loop (unpack). A fleet in fast time packs and
parses about 21 of these per vehicle and simulated second.
"""

from __future__ import annotations

import operator
import struct
from collections.abc import Callable
from typing import Any

from pymavlink.dialects.v20 import ardupilotmega as mavlink

_mcrf4xx: Callable[..., int] | None
try:
    from fastcrc.crc16 import mcrf4xx as _mcrf4xx  # pymavlink's own fast CRC
except ImportError:  # pragma: no cover - pymavlink uses it when it is installed
    _mcrf4xx = None

_HEADER = struct.Struct("<BBBBBBBHB")  # MAVLink 2: STX, len, flags x2, seq, sys, comp, id
_CRC = struct.Struct("<H")
_V2_MARKER = 0xFD
_V2_HEADER_LEN = 10


def _crc(data: bytes | bytearray, extra: bytes) -> int:
    assert _mcrf4xx is not None
    return int(_mcrf4xx(extra, _mcrf4xx(data, 0xFFFF)))


class _Layout:
    """What packing and unpacking one message type needs, computed once."""

    __slots__ = ("cls", "extra", "getter", "msg_id", "orders", "size", "unpacker")

    def __init__(self, cls: Any) -> None:
        self.cls = cls
        self.msg_id: int = cls.id
        self.extra = bytes([cls.crc_extra])
        self.unpacker: struct.Struct = cls.unpacker
        self.size: int = cls.unpacker.size
        # the declared fields' places in the wire order (None: the same order)
        orders = list(cls.orders)
        self.orders: list[int] | None = None if orders == list(range(len(orders))) else orders
        names = list(cls.ordered_fieldnames)
        g = operator.attrgetter(*names)
        self.getter: Callable[[Any], tuple[Any, ...]] = (
            g if len(names) > 1 else (lambda m, _g=g: (_g(m),))  # type: ignore[misc]
        )


def _plain(cls: Any) -> bool:
    """A message of scalars only (no arrays, no strings): the fast path's."""
    fmt = cls.unpacker.format
    fmt = fmt.decode() if isinstance(fmt, bytes) else fmt
    return (
        bool(cls.ordered_fieldnames)
        and sum(cls.lengths) == len(cls.lengths)
        and not any(c in fmt for c in "sc")
        and not any(n for n in cls.array_lengths)
    )


_LAYOUTS: dict[int, _Layout] = (
    {}
    if _mcrf4xx is None
    else {mid: _Layout(cls) for mid, cls in mavlink.mavlink_map.items() if _plain(cls)}
)
_BY_CLASS = {lay.cls: lay for lay in _LAYOUTS.values()}  # (a field may be called `id`)


def pack(msg: Any, seq: int, sysid: int, compid: int) -> bytes | None:
    """`msg` as pymavlink packs it (MAVLink 2, unsigned) from (`sysid`, `compid`) with
    sequence number `seq`; None: not a plain message, pack it with pymavlink. A field out
    of range for its wire type raises struct.error, as pymavlink does."""
    lay = _BY_CLASS.get(type(msg))
    if lay is None:
        return None
    payload = lay.unpacker.pack(*lay.getter(msg))
    body = payload.rstrip(b"\x00") or payload[:1]  # MAVLink 2 trims trailing zeros
    mid = lay.msg_id
    header = _HEADER.pack(_V2_MARKER, len(body), 0, 0, seq, sysid, compid, mid & 0xFFFF, mid >> 16)
    frame = header[1:] + body
    return header[:1] + frame + _CRC.pack(_crc(frame, lay.extra))


def unpack(buf: bytearray, start: int, total: int) -> Any | None:
    """The frame `buf[start : start + total]` (its length taken from its header) as
    pymavlink's decode gives it; None: not an unsigned MAVLink 2 frame of a plain
    message with a good CRC (let pymavlink decode it, or raise)."""
    if buf[start] != _V2_MARKER or total < 12:
        return None
    _stx, mlen, incompat, compat, seq, sysid, compid, lo, hi = _HEADER.unpack_from(buf, start)
    if incompat:
        return None
    msg_id = lo | (hi << 16)
    lay = _LAYOUTS.get(msg_id)
    if lay is None:
        return None
    msgbuf = buf[start : start + total]
    crc = _CRC.unpack_from(msgbuf, total - 2)[0]
    if _crc(msgbuf[1:-2], lay.extra) != crc:
        return None
    payload = msgbuf[_V2_HEADER_LEN:-2]
    size = lay.size
    if len(payload) < size:
        payload += bytes(size - len(payload))  # MAVLink 2 trimmed trailing zeros
    t = lay.unpacker.unpack(payload[:size] if len(payload) > size else payload)
    orders = lay.orders
    m = lay.cls(*(t if orders is None else [t[o] for o in orders]))
    m._signed = False
    m._msgbuf = msgbuf
    m._payload = msgbuf[6:-2]  # as pymavlink sets it (cut at the MAVLink 1 header's length)
    m._crc = crc
    m._header = mavlink.MAVLink_header(msg_id, 0, compat, mlen, seq, sysid, compid)
    return m
