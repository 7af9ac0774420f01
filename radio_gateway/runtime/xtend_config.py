"""Device configuration (the paper's Device Configuration module): set up an XTend
through its AT command mode, and verify it before running.

    report = configure("/dev/ttyUSB0", RadioSettings(address=7), write=True)
    problems = verify("/dev/ttyUSB0", RadioSettings(address=7))   # [] when all is well

Entering command mode takes the module's guard times (1 s of silence before and after
"+++" by default); `clock` is the clock those seconds are counted on (a ScaledClock in a
simulation). A module at an unknown serial rate is found by trying the common rates.
"""

from __future__ import annotations

import contextlib
import logging
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field

import serial

from swarm_proto.clock import Clock, SystemClock

from ..core import xtend
from ..core.airtime import SERIAL_RATES

log = logging.getLogger(__name__)

SCAN_RATES = (230_400, 9_600, 115_200, 57_600, 38_400, 19_200)


class XTendError(RuntimeError):
    """The module did not answer, or refused a setting."""


class CommandMode:
    """An open command-mode session on a serial port."""

    def __init__(
        self, ser: serial.Serial, clock: Clock, guard_s: float = 1.1, reply_s: float = 1.0
    ) -> None:
        self.ser = ser
        self.clock = clock
        self.guard_s = guard_s
        self.reply_s = reply_s

    def _read_until(self, token: bytes, seconds: float) -> bytes | None:
        buf = b""
        deadline = self.clock.now() + seconds
        while self.clock.now() < deadline:
            self.ser.timeout = max(
                0.005, min(0.05, self.clock.to_wall(deadline - self.clock.now()))
            )
            chunk = self.ser.read(max(1, self.ser.in_waiting))
            buf += chunk
            if token in buf:
                return buf
        return None

    def enter(self) -> bool:
        self.ser.reset_input_buffer()
        self.clock.sleep(self.guard_s)
        self.ser.write(b"+++")
        self.ser.flush()
        got = self._read_until(b"OK\r", self.guard_s + self.reply_s)
        return got is not None

    def command(self, name: str, value: int | None = None) -> str:
        self.ser.reset_input_buffer()
        self.ser.write(xtend.command(name, value))
        self.ser.flush()
        got = self._read_until(b"\r", self.reply_s)
        if got is None:
            raise XTendError(f"no answer to AT{name}")
        return got.split(b"\r")[0].decode("ascii", "replace").strip()

    def query(self, name: str) -> int | None:
        return xtend.parse_value(self.command(name).encode())

    def set(self, name: str, value: int) -> None:
        answer = self.command(name, value)
        if answer != "OK":
            raise XTendError(f"AT{name} {value:X} refused: {answer!r}")

    def exit(self) -> None:
        with contextlib.suppress(XTendError):
            self.command("CN")


@contextlib.contextmanager
def command_mode(
    port: str, baud: int, clock: Clock | None = None, guard_s: float = 1.1
) -> Iterator[CommandMode]:
    with serial.Serial(port, baud, timeout=0.05) as ser:
        cm = CommandMode(ser, clock or SystemClock(), guard_s)
        if not cm.enter():
            raise XTendError(f"{port} at {baud} baud: no OK after +++")
        try:
            yield cm
        finally:
            cm.exit()


def find_rate(
    port: str, rates: Iterable[int], clock: Clock | None = None, guard_s: float = 1.1
) -> int:
    """The serial rate the module answers at."""
    tried = []
    for baud in dict.fromkeys(rates):
        tried.append(baud)
        try:
            with command_mode(port, baud, clock, guard_s):
                return baud
        except XTendError:
            continue
    raise XTendError(f"{port}: no XTend answered at {', '.join(map(str, tried))} baud")


def read_registers(cm: CommandMode, names: Iterable[str]) -> dict[str, int | None]:
    return {n: cm.query(n) for n in names}


@dataclass
class ConfigReport:
    port: str
    found_baud: int
    changed: dict[str, tuple[int | None, int]] = field(default_factory=dict)
    written: bool = False


def configure(
    port: str,
    settings: xtend.RadioSettings,
    *,
    write: bool = True,
    clock: Clock | None = None,
    guard_s: float = 1.1,
) -> ConfigReport:
    """Apply `settings` (finding the module's current serial rate first); with `write`,
    save them to flash (ATWR) so they survive a power cycle."""
    wanted = settings.registers()
    baud = find_rate(port, (settings.serial_baud, *SCAN_RATES), clock, guard_s)
    report = ConfigReport(port, baud)
    with command_mode(port, baud, clock, guard_s) as cm:
        current = read_registers(cm, wanted)
        # BR before PK/RB: lowering BR lowers PK; BD last (it applies when we leave)
        order = ["BR", *[n for n in wanted if n not in ("BR", "BD")], "BD"]
        for name in order:
            if current.get(name) != wanted[name]:
                cm.set(name, wanted[name])
                report.changed[name] = (current.get(name), wanted[name])
        if write:
            answer = cm.command("WR")
            if answer != "OK":
                raise XTendError(f"ATWR refused: {answer!r}")
            report.written = True
    log.info("configured %s: %s", port, report)
    return report


def verify(
    port: str, settings: xtend.RadioSettings, *, clock: Clock | None = None, guard_s: float = 1.1
) -> list[str]:
    """Differences between the module and `settings` (talking at settings.serial_baud);
    empty when the module is ready."""
    wanted = settings.registers()
    try:
        with command_mode(port, settings.serial_baud, clock, guard_s) as cm:
            actual = read_registers(cm, wanted)
    except XTendError as exc:
        return [f"{exc} (is the serial rate {settings.serial_baud}? run `radio-gateway configure`)"]
    return xtend.mismatches(wanted, actual)


def baud_name(baud: int) -> str:
    code = {v: k for k, v in SERIAL_RATES.items()}.get(baud)
    return f"{baud} (ATBD {code})" if code is not None else str(baud)
