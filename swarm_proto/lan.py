"""The LAN encoding: MessagePack maps (msgspec), field names as keys.

Self-describing: anyone with msgspec (or any MessagePack library) can decode a payload
into a dict without bandada. `decode` validates every constraint and raises only
`swarm_proto.DecodeError`.
"""

from __future__ import annotations

from functools import cache
from typing import TypeVar

import msgspec

from .errors import DecodeError, EncodeError

T = TypeVar("T", bound=msgspec.Struct)

_encoder = msgspec.msgpack.Encoder()


def encode(msg: msgspec.Struct) -> bytes:
    try:
        return _encoder.encode(msg)
    except (TypeError, ValueError, OverflowError) as exc:
        raise EncodeError(f"{type(msg).__name__}: {exc}") from exc


@cache
def _decoder(cls: type[T]) -> msgspec.msgpack.Decoder[T]:
    return msgspec.msgpack.Decoder(cls)


def decoder(cls: type[T]) -> msgspec.msgpack.Decoder[T]:
    """The (cached) decoder of `cls` (`warm.warm_decoders` builds them all up front)."""
    return _decoder(cls)


def decode(data: bytes | bytearray | memoryview, cls: type[T]) -> T:
    try:
        return _decoder(cls).decode(data)
    except (msgspec.MsgspecError, ValueError, TypeError, OverflowError, RecursionError) as exc:
        raise DecodeError(f"invalid {cls.__name__}: {exc}") from exc
