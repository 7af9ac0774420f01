"""Digi XTend (9XTend) AT command set: the parameters bandada sets, and the pure parts of
talking to a module in command mode (what to send, what the answers mean).

Command mode: no serial data for BT x 100 ms, the command sequence character (CC, '+')
three times, no data for AT x 100 ms; the module answers "OK\\r". Commands are
"AT<2 letters>[<hex value>]\\r", several may share a line separated by commas; values
are hexadecimal (CF = 1, the default). A query answers the value, a setting "OK", a bad
command or value "ERROR". WR writes the settings to flash, CN leaves command mode
(a new BD takes effect then).

bandada's settings: DT = 0xFFFF (broadcast), MT = 0 and RR = 0 (one RF packet per slot,
no module-level retries or repeats: the TDM owns the channel), PK = the largest packet
the RF rate allows and RB = PK (packets end only on the RO idle timeout, so one serial
write is one RF packet).
"""

from __future__ import annotations

from dataclasses import dataclass

import msgspec

from .airtime import RF_RATES, SERIAL_RATES, LinkTiming


@dataclass(frozen=True)
class Param:
    name: str
    default: int
    lo: int
    hi: int
    doc: str
    read_only: bool = False


PARAMS: dict[str, Param] = {
    p.name: p
    for p in (
        Param("BD", 3, 0, 8, "interface (serial) data rate: 3 = 9600, 7 = 115200, 8 = 230400"),
        Param("BR", 1, 0, 1, "RF data rate: 0 = 9600, 1 = 115200"),
        Param("PL", 4, 0, 4, "power level: 0 = 1 mW, 1 = 10 mW, 2 = 100 mW, 3 = 500 mW, 4 = 1 W"),
        Param("HP", 0, 0, 9, "hopping channel"),
        Param("ID", 0x3332, 0, 0x7FFF, "modem VID (network id)"),
        Param("DT", 0, 0, 0xFFFF, "destination address (0xFFFF: broadcast)"),
        Param("MY", 0xFFFF, 0, 0xFFFF, "source address"),
        Param("MK", 0xFFFF, 0, 0xFFFF, "address mask"),
        Param("MT", 0, 0, 0xFF, "multi-transmit: extra copies of each broadcast packet"),
        Param("RR", 0x0A, 0, 0xFF, "retries (addressed packets only)"),
        Param("PK", 0x800, 1, 0x800, "maximum RF packet size, bytes (0x100 at BR = 0)"),
        Param("RB", 0x800, 1, 0x800, "packetization threshold, bytes"),
        Param("RO", 3, 0, 0xFFFF, "packetization timeout, character times"),
        Param("BT", 0x0A, 0, 0xFFFF, "guard time before the command sequence, x 100 ms"),
        Param("AT", 0x0A, 2, 0x7FFC, "guard time after the command sequence, x 100 ms"),
        Param("CT", 0xC8, 2, 0xFFFF, "command mode timeout, x 100 ms"),
        Param("CC", 0x2B, 0x20, 0x7F, "command sequence character"),
        Param("VR", 0x2070, 0, 0xFFFF, "firmware version", read_only=True),
    )
}


class RadioSettings(msgspec.Struct, frozen=True, forbid_unknown_fields=True):
    """What bandada needs from the module (and verifies at start)."""

    serial_baud: int = 230_400
    rf_bps: int = 115_200
    power_level: int = 4
    channel: int = 0  # HP
    network_id: int = 0x3332  # ID (modem VID)
    address: int = 0xFFFF  # MY; `radio-gateway` uses the node id
    ro_chars: int = 3

    def registers(self) -> dict[str, int]:
        bd = {v: k for k, v in SERIAL_RATES.items()}.get(self.serial_baud)
        br = {v: k for k, v in RF_RATES.items()}.get(self.rf_bps)
        if bd is None:
            raise ValueError(
                f"serial_baud {self.serial_baud}: one of {sorted(SERIAL_RATES.values())}"
            )
        if br is None:
            raise ValueError(f"rf_bps {self.rf_bps}: one of {sorted(RF_RATES.values())}")
        pk = 0x800 if br == 1 else 0x100
        regs = {
            "BD": bd,
            "BR": br,
            "PL": self.power_level,
            "HP": self.channel,
            "ID": self.network_id,
            "DT": 0xFFFF,
            "MY": self.address,
            "MK": 0xFFFF,
            "MT": 0,
            "RR": 0,
            "PK": pk,
            "RB": pk,
            "RO": self.ro_chars,
        }
        for name, value in regs.items():
            p = PARAMS[name]
            if not p.lo <= value <= p.hi:
                raise ValueError(f"AT{name} = {value:#x} outside {p.lo:#x}..{p.hi:#x} ({p.doc})")
        return regs

    def timing(self, sync_s: float = 0.006, latency_s: float = 0.0005) -> LinkTiming:
        regs = self.registers()
        return LinkTiming(
            rf_bps=self.rf_bps,
            serial_baud=self.serial_baud,
            sync_s=sync_s,
            ro_chars=self.ro_chars,
            latency_s=latency_s,
            max_packet=regs["PK"],
        )


def command(name: str, value: int | None = None) -> bytes:
    """One AT command line."""
    if name not in PARAMS and name not in ("WR", "CN", "RE", ""):
        raise ValueError(f"unknown AT command {name!r}")
    return f"AT{name}{'' if value is None else f' {value:X}'}\r".encode("ascii")


def parse_value(line: bytes) -> int | None:
    """A query's answer (hex), or None if it is not one."""
    text = line.strip().decode("ascii", "replace")
    try:
        return int(text, 16)
    except ValueError:
        return None


def mismatches(wanted: dict[str, int], actual: dict[str, int | None]) -> list[str]:
    """Human-readable differences, empty if the module is set up as wanted."""
    out = []
    for name, value in wanted.items():
        got = actual.get(name)
        if got != value:
            shown = "no answer" if got is None else f"{got:X}"
            out.append(f"AT{name} is {shown}, want {value:X} ({PARAMS[name].doc})")
    return out
