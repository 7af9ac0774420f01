"""Errors raised by swarm_proto.

Errors by blame (as in h11): bad bytes from a peer, the radio or a user are a
`DecodeError`; misuse of the API by our own code (encoding a message that breaks its
own constraints, an unregistered type) is an `EncodeError`. Decoders never raise
anything else, whatever the input.
"""

from __future__ import annotations


class ProtoError(Exception):
    """Base class of every error raised by swarm_proto."""


class DecodeError(ProtoError):
    """The bytes are not a valid message of the expected kind.

    `reason` is a short machine-readable cause ("malformed", "invalid", "version",
    "unknown-type", "truncated"); the message says what and where.
    """

    def __init__(self, message: str, *, reason: str = "invalid") -> None:
        super().__init__(message)
        self.reason = reason


class EncodeError(ProtoError):
    """A message could not be encoded (out-of-range value, unregistered type)."""
