"""MAVLink bytes <-> messages, without I/O: pymavlink's ardupilotmega dialect decodes and
packs, this module finds the frames.

pymavlink's own stream parser trusts a corrupted length byte and then drops the good
packets swallowed by it; `MavFramer` resynchronises byte by byte instead: a frame whose
CRC fails, whose header is impossible or whose message id is unknown (so its CRC cannot
be checked) costs one byte, and scanning resumes at the next start marker. Every run of
bytes that did not decode is reported as one `BadFrame`, never raised.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from . import mavcodec

STX_V1 = 0xFE
STX_V2 = 0xFD
_SIGNED = 0x01
_MAX_BUFFER = 1 << 16  # never hold more than this undecoded

MAVLinkMessage = Any  # pymavlink.dialects.v20.ardupilotmega.MAVLink_message (untyped)


@dataclass(frozen=True, slots=True)
class BadFrame:
    """A run of `n_bytes` that were not a valid MAVLink frame."""

    n_bytes: int
    reason: str


class MavFramer:
    """Feed bytes in any chunking; get decoded messages and BadFrame runs out, in order."""

    def __init__(self) -> None:
        self._parser = mavlink.MAVLink(None)
        self._buf = bytearray()
        self.frames = 0
        self.garbage_bytes = 0

    def feed(self, data: bytes) -> list[MAVLinkMessage | BadFrame]:
        buf = self._buf
        buf += data
        out: list[MAVLinkMessage | BadFrame] = []
        junk = 0
        reason = ""
        i = 0
        n = len(buf)
        while i < n:
            # a frame where the last one ended (the usual case): no search
            j = i if buf[i] == STX_V2 or buf[i] == STX_V1 else _next_stx(buf, i)
            if j < 0:
                junk += n - i
                reason = reason or "no start marker"
                i = n
                break
            if j > i:
                junk += j - i
                reason = reason or "no start marker"
                i = j
            if n - i < 3:
                break
            length = buf[i + 1]
            if buf[i] == STX_V2:
                flags = buf[i + 2]
                if flags & ~_SIGNED:
                    junk, i, reason = junk + 1, i + 1, "bad incompat flags"
                    continue
                total = 12 + length + (13 if flags & _SIGNED else 0)
            else:
                total = 8 + length
            if n - i < total:
                break
            try:
                # the usual frame without pymavlink's bookkeeping (the same message)
                msg = mavcodec.unpack(buf, i, total) or self._parser.decode(
                    bytearray(buf[i : i + total])
                )
            except Exception as exc:  # pymavlink raises MAVError, struct.error, ...
                junk, i = junk + 1, i + 1
                reason = _short(exc)
                continue
            if isinstance(msg, mavlink.MAVLink_unknown):
                junk, i, reason = junk + 1, i + 1, "unknown message id"
                continue
            if junk:
                out.append(BadFrame(junk, reason))
                self.garbage_bytes += junk
                junk, reason = 0, ""
            out.append(msg)
            self.frames += 1
            i += total
        del buf[:i]
        if len(buf) > _MAX_BUFFER:  # cannot happen with valid lengths; belt and braces
            junk += len(buf)
            buf.clear()
        if junk:
            out.append(BadFrame(junk, reason))
            self.garbage_bytes += junk
        return out


def _next_stx(buf: bytearray, start: int) -> int:
    a = buf.find(STX_V2, start)
    b = buf.find(STX_V1, start)
    if a < 0:
        return b
    if b < 0:
        return a
    return min(a, b)


def _short(exc: Exception) -> str:
    text = getattr(exc, "message", None) or str(exc) or type(exc).__name__
    return text.split(",")[0][:60]


class MavEncoder:
    """Packs messages as MAVLink 2 from (`sysid`, `compid`), numbering them."""

    def __init__(self, sysid: int, compid: int) -> None:
        if not (1 <= sysid <= 255 and 0 <= compid <= 255):
            raise ValueError(f"bad MAVLink source {sysid}/{compid}")
        self._mav = mavlink.MAVLink(None, srcSystem=sysid, srcComponent=compid)
        self.sysid = sysid
        self.compid = compid

    def encode(self, msg: MAVLinkMessage) -> bytes:
        mav = self._mav
        data = (
            None
            if mav.signing.sign_outgoing
            else mavcodec.pack(msg, mav.seq, self.sysid, self.compid)
        )
        data = data or bytes(msg.pack(mav))
        mav.seq = (mav.seq + 1) % 256
        return data
