"""The timing model of an XTend-like broadcast radio, shared by the gateway (to size and
place its slots) and the channel emulator (to decide what collides).

A host writes a frame to the module over the serial line; the module starts the RF
packet once the serial bytes are in and the line has been idle for RO character times;
the packet occupies the air for a sync preamble plus its bytes at the RF data rate; the
receiving module hands the bytes to its host after a short processing latency, at the
serial rate.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

# XTend parameter values (BD, BR) and the rates they select
SERIAL_RATES = {
    0: 1200,
    1: 2400,
    2: 4800,
    3: 9600,
    4: 19200,
    5: 38400,
    6: 57600,
    7: 115200,
    8: 230400,
}
RF_RATES = {0: 9600, 1: 115200}


@dataclass(frozen=True)
class LinkTiming:
    rf_bps: int = 115_200  # over-the-air data rate
    serial_baud: int = 230_400  # host <-> module UART
    sync_s: float = 0.006  # preamble and sync every RF packet pays
    ro_chars: int = 3  # packetization timeout, in character times
    latency_s: float = 0.0005  # receiving module: end of packet -> first byte out
    max_packet: int = 2048  # PK: the largest RF packet (bytes)

    def __post_init__(self) -> None:
        if self.rf_bps <= 0 or self.serial_baud <= 0 or self.sync_s < 0 or self.max_packet <= 0:
            raise ValueError(f"invalid link timing {self}")

    @property
    def char_s(self) -> float:
        return 10.0 / self.serial_baud  # 8N1

    def serial_s(self, n: int) -> float:
        return n * self.char_s

    def airtime_s(self, n: int) -> float:
        """How long an n-byte packet occupies the channel (sync preamble included)."""
        return self.sync_s + n * 8.0 / self.rf_bps

    def tx_delay_s(self, n: int) -> float:
        """From the start of the host's write to the start of the RF packet."""
        return self.serial_s(n) + self.ro_chars * self.char_s

    def rx_delay_s(self, n: int) -> float:
        """From the start of the RF packet to its last byte at the receiving host."""
        return self.airtime_s(n) + self.latency_s + self.serial_s(n)

    def bytes_in(self, seconds: float) -> int:
        """The largest packet whose airtime fits in `seconds`."""
        return max(0, math.floor((seconds - self.sync_s) * self.rf_bps / 8.0 + 1e-9))
