"""A broadcast radio channel of XTend-like modules (pure: bytes and `now` in).

Each module has a host side (serial bytes in and out, AT command mode, packetization by
the RO idle timeout) and an RF side on one shared channel:

- a packet occupies the air for a sync preamble plus its bytes at the sender's RF rate;
- every other module on the same RF rate, hopping channel and network id receives it,
  unless it was transmitting meanwhile (half duplex), the packet overlapped another one
  (both are lost: a collision), or random loss or bit errors hit it;
- a module does not start a packet while it is receiving: once another packet's preamble
  has been on air for `detect_s` it waits for that packet to end (a *deferral*). Two
  packets that start within `detect_s` of each other collide;
- the receiving host gets the bytes `latency_s` after the packet ends, at its serial rate;
- a module needs `tx_setup_s` (plus up to `tx_setup_jitter_s`) after the RO timeout to set
  up a transmission and cannot receive while setting up or transmitting (half-duplex
  turnaround);
- capture: a receiver hearing two overlapping packets keeps the one that started first
  with probability `capture` (a stronger, earlier signal); the overlap still counts as a
  collision (a TDM must have none);
- a packet the host wrote late (`from_host(..., late=True)`: after the last moment its
  schedule allowed) is counted apart: a collision involving one is a `collisions_late`
  (the host's fault), one between on-time packets a `collisions_tdm` (the schedule's).

`XTEND_DATASHEET` holds the figures from the XTend datasheet (Digi 9XTend product manual:
6.5 ms RF initializer per packet at 115.2 kbps, ~0.8 ms transmit setup after the RO
timeout with 100-200 us of uncertainty): emulations that check a schedule use them,
independently of the `LinkTiming` the gateway sizes its slots with, so the check can
disagree with the design.

Bit errors are delivered as flipped bits (a real XTend drops packets failing its own CRC;
passing them on tests the gateway's framing). A host whose serial rate differs from the
module's BD sees garbage, both ways.

Times are modelled: a packet starts when its serial bytes have arrived (at the module's
baud) plus RO idle character times, even if the caller is a little late to look.
"""

from __future__ import annotations

import heapq
import itertools
import math
import random
from collections import Counter
from dataclasses import dataclass, field
from enum import Enum

from radio_gateway.core.airtime import RF_RATES, SERIAL_RATES
from radio_gateway.core.xtend import PARAMS


@dataclass(frozen=True)
class ChannelParams:
    sync_s: float = 0.006
    detect_s: float = 0.006  # preamble time before a receiver knows the channel is busy
    latency_s: float = 0.0005
    loss: float = 0.0  # probability a receiver misses a packet
    ber: float = 0.0  # bit error rate of delivered packets
    seed: int = 0
    tx_setup_s: float = 0.0  # after the RO timeout, before the preamble starts
    tx_setup_jitter_s: float = 0.0  # uniform extra setup time
    capture: float = 0.0  # probability a receiver keeps the earlier of two overlapping

    def __post_init__(self) -> None:
        if not (0 <= self.loss <= 1 and 0 <= self.ber <= 1 and 0 <= self.capture <= 1):
            raise ValueError("loss, ber and capture are probabilities")
        if self.tx_setup_s < 0 or self.tx_setup_jitter_s < 0:
            raise ValueError("setup times are >= 0")


# the XTend at 115.2 kbps RF, from its datasheet (see the module docstring)
XTEND_DATASHEET = ChannelParams(
    sync_s=0.0065,
    detect_s=0.0065,
    latency_s=0.0005,
    tx_setup_s=0.0008,
    tx_setup_jitter_s=0.0002,
)


class Mode(Enum):
    DATA = "data"
    COMMAND = "command"


@dataclass
class Transmission:
    src: int
    start: float
    end: float
    data: bytes
    rf_bps: int
    hp: int
    vid: int
    dt: int
    collided: bool = False
    delivered: bool = False
    late: bool = False
    setup: float = 0.0  # when the module stopped listening to set up this packet
    first: bool = True  # started before every packet it overlaps (capture)


@dataclass
class Module:
    index: int
    registers: dict[str, int] = field(
        default_factory=lambda: {k: p.default for k, p in PARAMS.items()}
    )
    saved: dict[str, int] = field(default_factory=dict)
    mode: Mode = Mode.DATA
    active_bd: int = 3  # BD in force (a new BD applies when command mode ends)
    buf: bytearray = field(default_factory=bytearray)
    serial_end: float = 0.0
    last_rx: float = -1e18
    plus: bytes = b""
    plus_t: float = 0.0
    line: bytearray = field(default_factory=bytearray)
    cmd_last: float = 0.0
    tx_free: float = -1e18  # its own previous packet ends
    late: bool = False  # the buffered bytes include a late write

    def __post_init__(self) -> None:
        self.saved = dict(self.registers)
        self.active_bd = self.registers["BD"]

    @property
    def baud(self) -> int:
        return SERIAL_RATES[self.active_bd]

    @property
    def rf_bps(self) -> int:
        return RF_RATES[self.registers["BR"]]

    @property
    def char_s(self) -> float:
        return 10.0 / self.baud

    def reg_s(self, name: str) -> float:
        return self.registers[name] * 0.1


def garble(data: bytes) -> bytes:
    """What bytes look like through a UART at the wrong baud rate (never 0x00)."""
    return bytes(((b * 7 + 0x5B) & 0xFF) | 0x80 for b in data)


@dataclass
class RadioChannelModel:
    n: int
    params: ChannelParams = ChannelParams()
    modules: list[Module] = field(init=False)
    counts: Counter[str] = field(default_factory=Counter)
    per_module: list[Counter[str]] = field(init=False)
    air: list[Transmission] = field(default_factory=list)
    _out: list[tuple[float, int, int, bytes]] = field(default_factory=list)  # heap
    _pending: list[tuple[float, int, int, bytes, bool]] = field(
        default_factory=list
    )  # heap: ready packets (late writes flagged)
    _seq: itertools.count[int] = field(default_factory=itertools.count)
    _rng: random.Random = field(init=False)

    def __post_init__(self) -> None:
        self.modules = [Module(i) for i in range(self.n)]
        self.per_module = [Counter() for _ in range(self.n)]
        self._rng = random.Random(self.params.seed)

    def preset(self, i: int, **registers: int) -> None:
        """Set (and save) registers as if configured earlier, e.g. preset(0, BD=8)."""
        m = self.modules[i]
        for k, v in registers.items():
            if k not in PARAMS:
                raise KeyError(k)
            m.registers[k] = v
        m.saved = dict(m.registers)
        m.active_bd = m.registers["BD"]

    # ------------------------------------------------------------------ host side
    def from_host(
        self, i: int, data: bytes, now: float, host_baud: int | None = None, late: bool = False
    ) -> None:
        """Bytes the host of module i wrote (read by the emulator at `now`); `late`: the
        host wrote them after its schedule allowed (counted apart from TDM faults)."""
        m = self.modules[i]
        if late:
            m.late = True
            self.counts["late_writes"] += 1
        if host_baud is not None and host_baud != m.baud:
            data = garble(data)
            self.per_module[i]["baud_mismatch"] += 1
        if m.mode is Mode.COMMAND:
            self._command_bytes(m, data, now)
            m.last_rx = now
            return
        start = max(now, m.serial_end)
        quiet_before = start - m.last_rx >= m.reg_s("BT") and not m.buf
        cc = bytes((m.registers["CC"],))
        if (
            (quiet_before or m.plus)
            and data
            and data == cc * len(data)
            and len(m.plus) + len(data) <= 3
        ):
            m.plus += data
            m.plus_t = start + len(data) * m.char_s
            m.last_rx = m.serial_end = m.plus_t
            return
        if m.plus:
            data, m.plus = m.plus + data, b""
        m.serial_end = start + len(data) * m.char_s
        m.last_rx = m.serial_end
        m.buf += data

    def _to_host(self, i: int, data: bytes, at: float) -> None:
        heapq.heappush(self._out, (at, next(self._seq), i, data))

    def _command_bytes(self, m: Module, data: bytes, now: float) -> None:
        m.cmd_last = now
        for b in data:
            if b in (0x0D, 0x0A):
                if m.line:
                    reply = self._execute(m, bytes(m.line).decode("ascii", "replace"), now)
                    self._to_host(m.index, reply, now + len(reply) * m.char_s)
                    m.line.clear()
            elif len(m.line) < 256:
                m.line.append(b)

    def _execute(self, m: Module, line: str, now: float) -> bytes:
        text = line.strip().upper()
        if not text.startswith("AT"):
            return b"ERROR\r"
        out: list[str] = []
        for part in text[2:].split(","):
            part = part.strip()
            name, arg = part[:2], part[2:].strip()
            if name == "":
                out.append("OK")
            elif name == "CN":
                out.append("OK")
                m.mode = Mode.DATA
                m.active_bd = m.registers["BD"]
                m.last_rx = now
            elif name == "WR":
                m.saved = dict(m.registers)
                out.append("OK")
            elif name == "RE":
                m.registers = {k: p.default for k, p in PARAMS.items()}
                out.append("OK")
            elif name in PARAMS:
                p = PARAMS[name]
                if not arg:
                    out.append(f"{m.registers[name]:X}")
                    continue
                try:
                    value = int(arg, 16)
                except ValueError:
                    out.append("ERROR")
                    continue
                limit = 0x100 if name in ("PK", "RB") and m.registers["BR"] == 0 else p.hi
                if p.read_only or not p.lo <= value <= limit:
                    out.append("ERROR")
                    continue
                m.registers[name] = value
                if name == "BR" and value == 0:
                    m.registers["PK"] = min(m.registers["PK"], 0x100)
                    m.registers["RB"] = min(m.registers["RB"], 0x100)
                if name == "PK":
                    m.registers["RB"] = min(m.registers["RB"], value)
                out.append("OK")
            else:
                out.append("ERROR")
        return ("\r".join(out) + "\r").encode("ascii")

    def power_cycle(self, i: int) -> None:
        """Reset a module: unsaved settings are lost."""
        m = self.modules[i]
        m.registers = dict(m.saved)
        m.active_bd = m.registers["BD"]
        m.mode = Mode.DATA
        m.buf.clear()
        m.plus = b""

    # ------------------------------------------------------------------ timers
    def next_deadline(self) -> float | None:
        times: list[float] = []
        for m in self.modules:
            if m.buf:
                times.append(m.serial_end + m.registers["RO"] * m.char_s)
            if m.plus:
                times.append(m.plus_t + m.reg_s("AT"))
            if m.mode is Mode.COMMAND:
                times.append(m.cmd_last + m.reg_s("CT"))
        if self._out:
            times.append(self._out[0][0])
        if self._pending:
            times.append(self._pending[0][0])
        for t in self.air:
            if not t.delivered:
                times.append(t.end + self.params.latency_s)
        return min(times) if times else None

    def on_timer(self, now: float) -> list[tuple[int, bytes]]:
        """Advance to `now`; returns (module, bytes) for the hosts, in time order."""
        for m in self.modules:
            if m.plus and now >= m.plus_t + m.reg_s("AT"):
                if m.plus == bytes((m.registers["CC"],)) * 3:
                    m.mode = Mode.COMMAND
                    m.cmd_last = now
                    self._to_host(m.index, b"OK\r", m.plus_t + m.reg_s("AT"))
                else:
                    m.buf += m.plus
                m.plus = b""
            if m.mode is Mode.COMMAND and now >= m.cmd_last + m.reg_s("CT"):
                m.mode = Mode.DATA
                m.active_bd = m.registers["BD"]
            ready = m.serial_end + m.registers["RO"] * m.char_s
            if m.buf and now >= ready:
                pk = m.registers["PK"]
                data, m.buf = bytes(m.buf), bytearray()
                late, m.late = m.late, False
                for j in range(0, len(data), pk):
                    heapq.heappush(
                        self._pending,
                        (ready, next(self._seq), m.index, data[j : j + pk], late),
                    )
        while self._pending and self._pending[0][0] <= now:
            t, _, i, data, late = heapq.heappop(self._pending)
            self._start(i, data, t, late)
        self._deliver(now)
        out: list[tuple[int, bytes]] = []
        while self._out and self._out[0][0] <= now:
            _, _, i, data = heapq.heappop(self._out)
            out.append((i, data))
        return out

    # ------------------------------------------------------------------ RF side
    def _start(self, i: int, data: bytes, t: float, late: bool = False) -> None:
        m = self.modules[i]
        r = m.registers
        p = self.params
        setup = p.tx_setup_s
        if p.tx_setup_jitter_s:
            setup += self._rng.uniform(0, p.tx_setup_jitter_s)
        start = max(t + setup, m.tx_free)
        deferred = False
        while True:
            busy = [
                x.end
                for x in self.air
                if x.src != i
                and x.start + self.params.detect_s <= start < x.end
                and self._hears(m, x)
            ]
            if not busy:
                break
            start = max(busy)
            deferred = True
        if deferred:
            self.counts["deferred"] += 1
            self.per_module[i]["deferred"] += 1
        dur = self.params.sync_s + len(data) * 8.0 / m.rf_bps
        tx = Transmission(i, start, start + dur, data, m.rf_bps, r["HP"], r["ID"], r["DT"])
        tx.late = late
        tx.setup = start - setup
        late_overlap = late
        for x in self.air:  # packets on one hopping channel (same HP) interfere
            if x.hp == tx.hp and x.start < tx.end and tx.start < x.end:
                if not x.collided:
                    self.counts["collided_packets"] += 1
                x.collided = True
                tx.collided = True
                late_overlap = late_overlap or x.late
                if x.start >= tx.start:
                    x.first = False
                else:
                    tx.first = False
        if tx.collided:
            self.counts["collided_packets"] += 1
            self.counts["collisions"] += 1  # overlap events
            self.counts["collisions_late" if late_overlap else "collisions_tdm"] += 1
        m.tx_free = tx.end
        self.air.append(tx)
        self.counts["packets"] += 1
        self.per_module[i]["tx"] += 1

    @staticmethod
    def _hears(m: Module, x: Transmission) -> bool:
        r = m.registers
        return x.rf_bps == RF_RATES[r["BR"]] and x.hp == r["HP"] and x.vid == r["ID"]

    def _deliver(self, now: float) -> None:
        lat = self.params.latency_s
        for x in self.air:
            if x.delivered or now < x.end + lat:
                continue
            x.delivered = True
            if x.collided and not (self.params.capture and x.first):
                continue
            for m in self.modules:
                if m.index == x.src:
                    continue
                c = self.per_module[m.index]
                if not self._hears(m, x):
                    c["filtered"] += 1
                    continue
                r = m.registers
                mk = r["MK"]  # XTend address recognition: broadcast, group (DT) or local (MY)
                if x.dt != 0xFFFF and (x.dt & mk) != (r["DT"] & mk) and x.dt != r["MY"]:
                    c["filtered"] += 1
                    continue
                if any(y.src == m.index and y.setup < x.end and x.start < y.end for y in self.air):
                    c["missed_half_duplex"] += 1
                    continue
                if x.collided:  # the earlier of overlapping packets: captured, or not
                    if self._rng.random() >= self.params.capture:
                        c["lost_collision"] += 1
                        continue
                    c["captured"] += 1
                if m.mode is Mode.COMMAND:
                    c["missed_command_mode"] += 1
                    continue
                if self.params.loss and self._rng.random() < self.params.loss:
                    c["lost"] += 1
                    self.counts["lost"] += 1
                    continue
                data = x.data
                if self.params.ber:
                    data = self._flip(data)
                    if data != x.data:
                        c["corrupted"] += 1
                        self.counts["corrupted"] += 1
                c["rx"] += 1
                self.counts["delivered"] += 1
                self._to_host(m.index, data, x.end + lat + len(data) * m.char_s)
        horizon = now - 1.0
        self.air = [x for x in self.air if not x.delivered or x.end > horizon]

    def _flip(self, data: bytes) -> bytes:
        nbits = len(data) * 8
        out = bytearray(data)
        # number of errors ~ binomial(nbits, ber), drawn by geometric gaps
        p = self.params.ber
        i = -1
        while True:
            u = self._rng.random()
            gap = int(math.log(1.0 - u) / math.log(1.0 - p)) if p < 1 else 0
            i += gap + 1
            if i >= nbits:
                break
            out[i // 8] ^= 1 << (i % 8)
        return bytes(out)
