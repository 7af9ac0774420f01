"""The radio frame: one per TDM slot, one radio packet, one serial write.

Before COBS (all integers little-endian):

| offset | bytes | field |
|---|---|---|
| 0 | 1 | bits 7-5 protocol version (1); bit 0 JOIN request; bits 1-2 time stratum; bits 3-4 the sender's need level (adaptive schedule) |
| 1 | 2 | source node id |
| 3 | 2 | cycle counter, low 16 bits (cycle = floor(GPS time / cycle length)) |
| 5 | 2 | slot-table version: 16-bit hash of the sender's membership |
| 7 | 1 | members in the sender's table (n) |
| 8 | ceil(n/8) | heard bitmap: bit i = member of rank i heard in the last period |
| .. | .. | records: type (1), length (1), value |
| -8 | 6 | tag: BLAKE2s-48 over the full cycle counter and every byte before it |
| -2 | 2 | CRC-16/CCITT-FALSE over every byte before it |

then COBS-encoded and followed by one 0x00 delimiter. Records (unknown types skipped):

| type | value |
|---|---|
| 1 MSG | a radio-encoded message (swarm_proto.radio) |
| 2 FRAG, 3 FRAG_ACKED | seq (2), total chunks (1), first chunk (1), data: chunks of a message |
| 4 ACK | source (2), seq (2), bitmap of chunks held (empty: complete) |
| 5 JOIN, 6 LEAVE | node (2), activation cycle low 16 bits (2) |
| 7 RELAY | a peer's latest telemetry, repeated for nodes that missed it |
| 8 LEVEL | node (2), activation cycle low 16 bits (2), need level (1): a scheduled change of a member's slot share |
| 9 FRAG_ACKED_BY | seq (2), total chunks (1), first chunk (1), node (2), data: chunks of a message only `node` acknowledges (an Ack answers its issuer) |

Decoding never raises anything but `FrameError`, whose `reason` says which check failed.
"""

from __future__ import annotations

import binascii
import struct
from dataclasses import dataclass, field
from enum import IntEnum

from . import auth, cobs

PROTOCOL_VERSION = 1
HEADER = struct.Struct("<BHHHB")
HEADER_BYTES = HEADER.size
CRC_BYTES = 2
TRAILER_BYTES = auth.TAG_BYTES + CRC_BYTES
RECORD_HEADER_BYTES = 2
MAX_RECORD_VALUE = 255
CHUNK_BYTES = 16  # fragments are whole chunks, except a message's last
MAX_CHUNKS = 255
MAX_MESSAGE_BYTES = CHUNK_BYTES * MAX_CHUNKS
FRAG_FIXED = 4  # seq, total, first
ACK_FIXED = 4  # src, seq
CHANGE_VALUE = 4
LEVEL_VALUE = 5


class RecordType(IntEnum):
    MSG = 1
    FRAG = 2
    FRAG_ACKED = 3
    ACK = 4
    JOIN = 5
    LEAVE = 6
    RELAY = 7
    LEVEL = 8
    FRAG_ACKED_BY = 9


class FrameError(ValueError):
    """A frame that failed a check; `reason` is one of: cobs, short, crc, version, mac,
    malformed."""

    def __init__(self, reason: str, message: str = "") -> None:
        super().__init__(message or reason)
        self.reason = reason


@dataclass(frozen=True)
class Msg:
    data: bytes


@dataclass(frozen=True)
class Relay:
    data: bytes


@dataclass(frozen=True)
class Frag:
    seq: int
    total: int  # chunks in the whole message
    first: int  # index of the first chunk carried
    data: bytes
    acked: bool
    ack_by: int = 0  # acked: only this node acknowledges (0: every member)

    @property
    def fixed(self) -> int:
        return FRAG_FIXED + (2 if self.ack_by else 0)

    @property
    def chunks(self) -> range:
        return range(self.first, self.first + -(-len(self.data) // CHUNK_BYTES))


@dataclass(frozen=True)
class Ack:
    src: int  # whose message is acknowledged
    seq: int
    mask: bytes = b""  # chunks held, bit i of byte i // 8; empty = complete


@dataclass(frozen=True)
class Change:
    join: bool  # True: JOIN, False: LEAVE
    node: int
    at_cycle: int


@dataclass(frozen=True)
class LevelChange:
    """A member's need level (slot share) from `at_cycle` on (the adaptive schedule)."""

    node: int
    level: int
    at_cycle: int


Record = Msg | Relay | Frag | Ack | Change | LevelChange


@dataclass(frozen=True)
class Frame:
    src: int
    cycle: int
    table_hash: int
    n_members: int
    heard: bytes = b""
    join: bool = False
    stratum: int = 3
    records: tuple[Record, ...] = ()
    level: int = 1  # the sender's need level in force (adaptive schedule; 1 the default)
    unknown_records: int = field(default=0, compare=False)


def heard_bytes(n_members: int) -> int:
    return (n_members + 7) // 8


def frame_overhead(n_members: int, payload: int = 0) -> int:
    """Bytes on the wire, at most, for a frame whose records take `payload` bytes."""
    return cobs.max_encoded_len(HEADER_BYTES + heard_bytes(n_members) + payload + TRAILER_BYTES)


def record_size(r: Record) -> int:
    if isinstance(r, Msg | Relay):
        return RECORD_HEADER_BYTES + len(r.data)
    if isinstance(r, Frag):
        return RECORD_HEADER_BYTES + r.fixed + len(r.data)
    if isinstance(r, Ack):
        return RECORD_HEADER_BYTES + ACK_FIXED + len(r.mask)
    if isinstance(r, LevelChange):
        return RECORD_HEADER_BYTES + LEVEL_VALUE
    return RECORD_HEADER_BYTES + CHANGE_VALUE


def _encode_record(r: Record) -> bytes:
    if isinstance(r, Msg):
        t, v = RecordType.MSG, r.data
    elif isinstance(r, Relay):
        t, v = RecordType.RELAY, r.data
    elif isinstance(r, Frag):
        if r.ack_by and r.acked:
            t = RecordType.FRAG_ACKED_BY
            v = struct.pack("<HBBH", r.seq, r.total, r.first, r.ack_by) + r.data
        else:
            t = RecordType.FRAG_ACKED if r.acked else RecordType.FRAG
            v = struct.pack("<HBB", r.seq, r.total, r.first) + r.data
    elif isinstance(r, Ack):
        t, v = RecordType.ACK, struct.pack("<HH", r.src, r.seq) + r.mask
    elif isinstance(r, LevelChange):
        t, v = RecordType.LEVEL, struct.pack("<HHB", r.node, r.at_cycle & 0xFFFF, r.level)
    else:
        t = RecordType.JOIN if r.join else RecordType.LEAVE
        v = struct.pack("<HH", r.node, r.at_cycle & 0xFFFF)
    if len(v) > MAX_RECORD_VALUE:
        raise ValueError(f"record value of {len(v)} bytes exceeds {MAX_RECORD_VALUE}")
    return bytes((t, len(v))) + v


def encode_body(frame: Frame) -> bytes:
    """The frame before its tag, CRC and COBS (what the tag covers)."""
    if not 0 <= frame.stratum <= 3:
        raise ValueError("stratum is 0..3")
    if not 0 <= frame.level <= 3:
        raise ValueError("level is 0..3")
    if len(frame.heard) != heard_bytes(frame.n_members):
        raise ValueError("heard bitmap length does not match n_members")
    flags = (
        (PROTOCOL_VERSION << 5)
        | (frame.level << 3)
        | (frame.stratum << 1)
        | (1 if frame.join else 0)
    )
    out = bytearray(
        HEADER.pack(flags, frame.src, frame.cycle & 0xFFFF, frame.table_hash, frame.n_members)
    )
    out += frame.heard
    for r in frame.records:
        out += _encode_record(r)
    return bytes(out)


def encode(frame: Frame, key: bytes) -> bytes:
    """The bytes to write to the radio: COBS(body + tag + CRC) + 0x00."""
    body = encode_body(frame)
    body += auth.tag(key, frame.cycle, body)
    body += binascii.crc_hqx(body, 0xFFFF).to_bytes(2, "little")
    return cobs.encode(body) + b"\x00"


def max_wire_size(frame: Frame) -> int:
    """Bytes on the wire at most (COBS adds fewer when the frame holds zero bytes): what
    slot budgets count, so a frame never overruns its slot."""
    return frame_overhead(frame.n_members, sum(record_size(r) for r in frame.records))


@dataclass(frozen=True)
class Unverified:
    """A frame whose CRC and header passed, before its tag is checked."""

    body: bytes
    tag: bytes
    src: int
    cycle_lo: int


def open_frame(raw: bytes) -> Unverified:
    """COBS, length, CRC and version checks (raw excludes the 0x00 delimiter)."""
    try:
        data = cobs.decode(raw)
    except cobs.CobsError as exc:
        raise FrameError("cobs", str(exc)) from None
    if len(data) < HEADER_BYTES + TRAILER_BYTES:
        raise FrameError("short", f"{len(data)} bytes")
    if binascii.crc_hqx(data[:-CRC_BYTES], 0xFFFF) != int.from_bytes(data[-CRC_BYTES:], "little"):
        raise FrameError("crc")
    flags, src, cycle_lo, _, _ = HEADER.unpack_from(data)
    if flags >> 5 != PROTOCOL_VERSION:
        raise FrameError("version", f"protocol version {flags >> 5}")
    return Unverified(
        body=data[:-TRAILER_BYTES],
        tag=data[-TRAILER_BYTES:-CRC_BYTES],
        src=src,
        cycle_lo=cycle_lo,
    )


def verify(u: Unverified, key: bytes, near_cycle: int) -> Frame:
    """Check the tag with the full cycle nearest to `near_cycle`, then parse."""
    cycle = auth.unwrap16(u.cycle_lo, near_cycle)
    if not auth.verify(key, cycle, u.body, u.tag):
        raise FrameError("mac")
    return parse_body(u.body, cycle)


def parse_body(body: bytes, cycle: int) -> Frame:
    flags, src, _, table_hash, n = HEADER.unpack_from(body)
    pos = HEADER_BYTES + heard_bytes(n)
    if pos > len(body):
        raise FrameError("malformed", "heard bitmap runs past the end")
    heard = body[HEADER_BYTES:pos]
    records: list[Record] = []
    unknown = 0
    while pos < len(body):
        if pos + RECORD_HEADER_BYTES > len(body):
            raise FrameError("malformed", "truncated record header")
        t, length = body[pos], body[pos + 1]
        value = body[pos + 2 : pos + 2 + length]
        if len(value) != length:
            raise FrameError("malformed", "record runs past the end")
        pos += 2 + length
        if t in (RecordType.MSG, RecordType.RELAY):
            if not value:
                raise FrameError("malformed", "empty MSG")
            records.append(Msg(value) if t == RecordType.MSG else Relay(value))
        elif t in (RecordType.FRAG, RecordType.FRAG_ACKED, RecordType.FRAG_ACKED_BY):
            by = t == RecordType.FRAG_ACKED_BY
            fixed = FRAG_FIXED + (2 if by else 0)
            if length <= fixed:
                raise FrameError("malformed", "FRAG without data")
            seq, total, first = struct.unpack_from("<HBB", value)
            ack_by = struct.unpack_from("<H", value, FRAG_FIXED)[0] if by else 0
            if by and not ack_by:
                raise FrameError("malformed", "FRAG_ACKED_BY node 0")
            frag = Frag(seq, total, first, value[fixed:], t != RecordType.FRAG, ack_by)
            if total == 0 or frag.chunks.stop > total:
                raise FrameError("malformed", "FRAG chunks outside the message")
            if frag.chunks.stop < total and len(frag.data) % CHUNK_BYTES:
                raise FrameError("malformed", "FRAG not ending a message must hold whole chunks")
            records.append(frag)
        elif t == RecordType.ACK:
            if length < ACK_FIXED:
                raise FrameError("malformed", "short ACK")
            a_src, a_seq = struct.unpack_from("<HH", value)
            records.append(Ack(a_src, a_seq, value[ACK_FIXED:]))
        elif t in (RecordType.JOIN, RecordType.LEAVE):
            if length < CHANGE_VALUE:
                raise FrameError("malformed", "short membership change")
            node, at_lo = struct.unpack_from("<HH", value)
            records.append(Change(t == RecordType.JOIN, node, auth.unwrap16(at_lo, cycle)))
        elif t == RecordType.LEVEL:
            if length < LEVEL_VALUE:
                raise FrameError("malformed", "short level change")
            node, at_lo, lvl = struct.unpack_from("<HHB", value)
            if lvl > 3:
                raise FrameError("malformed", f"need level {lvl}")
            records.append(LevelChange(node, lvl, auth.unwrap16(at_lo, cycle)))
        else:
            unknown += 1
    return Frame(
        src=src,
        cycle=cycle,
        table_hash=table_hash,
        n_members=n,
        heard=heard,
        join=bool(flags & 1),
        stratum=(flags >> 1) & 3,
        records=tuple(records),
        level=(flags >> 3) & 3,
        unknown_records=unknown,
    )


def decode(raw: bytes, key: bytes, near_cycle: int) -> Frame:
    """open_frame + verify. Raises FrameError only."""
    return verify(open_frame(raw), key, near_cycle)
