"""`VehicleEndpoint`: a `SimAutopilot` behind the MAVLink wire format. Bytes in, bytes
out, time passed in; no sockets. The runtime feeds it what a TCP client sent and writes
back what it returns; the fast-time harness does the same without sockets.

Garbage bytes, truncated and corrupted frames are counted (`counters`) and dropped;
they never reach the autopilot and never raise.
"""

from __future__ import annotations

import struct
from collections import Counter
from collections.abc import Hashable
from dataclasses import replace
from typing import Any

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from swarm_node.core.autopilot import mavcodec

from .airframes import AirframeParams, VehicleModel, default_airframe
from .autopilot import Home, SimAutopilot, SimOptions

SITL_BASE_PORT = 5760


def sitl_port(instance: int) -> int:
    """ArduPilot SITL's TCP port for an instance: 5760 + 10 * instance."""
    if instance < 0:
        raise ValueError("instance must be >= 0")
    return SITL_BASE_PORT + 10 * instance


class _NullFile:
    def write(self, data: bytes) -> None:  # pymavlink's encoder wants a file; we pack ourselves
        pass


class VehicleEndpoint:
    """MAVLink framing around one simulated autopilot."""

    def __init__(self, autopilot: SimAutopilot) -> None:
        self.autopilot = autopilot
        self._encoder = mavlink.MAVLink(
            _NullFile(), srcSystem=autopilot.sysid, srcComponent=autopilot.compid
        )
        self._parsers: dict[Hashable, Any] = {}
        self.counters: Counter[str] = Counter()

    @classmethod
    def create(
        cls,
        model: VehicleModel | str,
        *,
        home: Home,
        now: float,
        sysid: int | None = None,
        airframe: AirframeParams | None = None,
        options: SimOptions | None = None,
    ) -> VehicleEndpoint:
        """A vehicle of `model` with its default airframe (or `airframe`); `sysid`
        overrides `options.sysid`."""
        af = airframe if airframe is not None else default_airframe(model)
        opts = options if options is not None else SimOptions()
        if sysid is not None and opts.sysid != sysid:
            opts = replace(opts, sysid=sysid)
        return cls(SimAutopilot(af, home, now, opts))

    def reboot(self, now: float, *, keep_stores: bool = False) -> None:
        """Power-cycle the autopilot (`SimAutopilot.rebooted`): partial frames of the
        clients are forgotten, as by a real reboot that drops the link."""
        self.autopilot = self.autopilot.rebooted(now, keep_stores=keep_stores)
        self._parsers.clear()
        self.counters["reboots"] += 1

    @staticmethod
    def _new_parser() -> Any:
        parser = mavlink.MAVLink(_NullFile(), srcSystem=0, srcComponent=0)
        parser.robust_parsing = True
        return parser

    def drop_channel(self, channel: Hashable) -> None:
        """Forget a client's partial frame (it disconnected)."""
        self._parsers.pop(channel, None)

    def receive(self, data: bytes, now: float, channel: Hashable = 0) -> bytes:
        """Bytes from a client (each client its own `channel`, so that interleaved
        partial frames of two clients never mix) -> bytes to send to all clients."""
        out: list[Any] = []
        for msg in self._parse(data, channel):
            out.extend(self.autopilot.handle(msg, now))
        out.extend(self.autopilot.on_timer(now))
        return self.encode(out)

    def on_timer(self, now: float) -> bytes:
        return self.encode(self.autopilot.on_timer(now))

    def next_deadline(self) -> float | None:
        return self.autopilot.next_deadline()

    def encode(self, messages: list[Any]) -> bytes:
        enc = self._encoder
        sysid, compid = enc.srcSystem, enc.srcComponent
        fast = not enc.signing.sign_outgoing
        pack = mavcodec.pack
        chunks = []
        seq = enc.seq
        for msg in messages:
            try:
                # the usual message without pymavlink's bookkeeping (the same bytes)
                data = pack(msg, seq, sysid, compid) if fast else None
                if data is None:
                    enc.seq = seq
                    data = msg.pack(enc)
            except (struct.error, ValueError, TypeError, OverflowError):
                # a field out of range for its wire type: drop the message, keep serving
                self.counters["encode_errors"] += 1
                continue
            chunks.append(data)
            seq = (seq + 1) % 256
        enc.seq = seq
        self.counters["tx_messages"] += len(messages)
        return b"".join(chunks)

    def _parse(self, data: bytes, channel: Hashable) -> list[Any]:
        if not data:
            return []
        self.counters["rx_bytes"] += len(data)
        parser = self._parsers.get(channel)
        if parser is None:
            parser = self._parsers[channel] = self._new_parser()
        try:
            msgs = parser.parse_buffer(data) or []
        except Exception:  # pymavlink raises assorted errors on hostile input
            self.counters["parser_errors"] += 1
            self._parsers.pop(channel, None)
            return []
        good = []
        for msg in msgs:
            mtype = msg.get_type()
            if mtype == "BAD_DATA":
                reason = str(getattr(msg, "reason", ""))
                if "crc" in reason.lower():
                    self.counters["bad_crc"] += 1
                else:
                    self.counters["bad_data"] += 1
                continue
            if mtype == "UNKNOWN":
                self.counters["unknown_message"] += 1
                continue
            good.append(msg)
        self.counters["rx_messages"] += len(good)
        return good
