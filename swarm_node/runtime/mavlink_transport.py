"""Byte transports for MAVLink connection strings, as MAVProxy and pymavlink write them.

| connection string             | meaning (same as pymavlink.mavutil)                         |
|-------------------------------|-------------------------------------------------------------|
| `udp:HOST:PORT`, `udpin:...`  | listen for UDP on HOST:PORT; answer the last sender         |
| `HOST:PORT`                   | same as `udp:` (mavutil's default)                          |
| `udpout:HOST:PORT`            | send UDP to HOST:PORT; read the answers                     |
| `udpbcast:HOST:PORT`          | broadcast to HOST:PORT until a peer answers, then unicast   |
| `tcp:HOST:PORT`               | TCP client (ArduPilot SITL listens on tcp:127.0.0.1:5760)   |
| `tcpin:HOST:PORT`             | TCP server; the latest client wins                          |
| `/dev/ttyUSB0[,BAUD]`, `COM3` | serial device, baud from `,BAUD` or the `baud` argument     |

Why not mavutil's own connection classes: they print, block in `time.sleep` while
reconnecting, busy-loop on a closed TCP socket and hide the parser. These are
non-blocking, select()-able, raise `OSError` when the link breaks, and leave parsing
to the pure core (`swarm_node.core.autopilot.framing`). Reopening is the caller's job.
"""

from __future__ import annotations

import contextlib
import errno
import ipaddress
import os
import socket
from dataclasses import dataclass
from typing import Protocol

UDP_MAX = 65535
_MAX_PENDING = 1 << 16


class Transport(Protocol):
    description: str

    def open(self) -> None: ...  # raises OSError when it cannot (yet)

    def filenos(self) -> list[int]: ...  # for select(); [] while closed

    def read(self) -> bytes: ...  # non-blocking: b"" when nothing; OSError when broken

    def write(self, data: bytes) -> None: ...  # OSError when broken

    def close(self) -> None: ...

    @property
    def is_open(self) -> bool: ...


@dataclass(frozen=True)
class Endpoint:
    kind: str  # "udpin", "udpout", "udpbcast", "tcp", "tcpin", "serial"
    host: str = ""
    port: int = 0
    device: str = ""
    baud: int = 57600


def parse_url(url: str, baud: int = 57600) -> Endpoint:
    """Parse a MAVProxy/pymavlink connection string; ValueError if malformed."""
    text = url.strip()
    if not text:
        raise ValueError("empty connection string")
    prefixes = {
        "udp:": "udpin",
        "udpin:": "udpin",
        "udpout:": "udpout",
        "udpbcast:": "udpbcast",
        "tcp:": "tcp",
        "tcpin:": "tcpin",
    }
    for prefix, kind in prefixes.items():
        if text.startswith(prefix):
            host, port = _host_port(text[len(prefix) :], url)
            return Endpoint(kind, host, port)
    device, sep, b = text.partition(",")
    if sep:
        return Endpoint("serial", device=device, baud=_baud(b, url))
    if (
        ":" in text
        and not os.path.exists(text)
        and not text.upper().startswith("COM")
        and "/" not in text
    ):
        host, port = _host_port(text, url)  # mavutil treats HOST:PORT as udp input
        return Endpoint("udpin", host, port)
    return Endpoint("serial", device=text, baud=baud)


def check_address(url: str, baud: int = 57600) -> Endpoint:
    """`parse_url`, and what can be known before opening: a serial device that exists,
    a host that is an address or a name that resolves. ValueError in one line
    otherwise (a node refuses to start rather than retry for ever what cannot work).
    An address that passes may still not answer: the link retries it."""
    endpoint = parse_url(url, baud)
    if endpoint.kind == "serial":
        device = endpoint.device
        if not device.upper().startswith("COM") and not os.path.exists(device):
            raise ValueError(
                f"autopilot {url!r}: no such device {device!r} (a serial device, or "
                "tcp:HOST:PORT, udpin:HOST:PORT, udpout:HOST:PORT)"
            )
        return endpoint
    host = endpoint.host
    if host.replace(".", "").isdigit():  # looks like an IPv4 address: it must be one
        try:
            ipaddress.ip_address(host)
        except ValueError:
            raise ValueError(f"autopilot {url!r}: {host!r} is not an IP address") from None
        return endpoint
    try:
        socket.getaddrinfo(host, endpoint.port)
    except (OSError, UnicodeError) as exc:
        raise ValueError(f"autopilot {url!r}: cannot resolve host {host!r}") from exc
    return endpoint


def _host_port(text: str, url: str) -> tuple[str, int]:
    host, sep, port = text.rpartition(":")
    if not sep or not port.isdigit() or not 0 <= int(port) <= 65535:
        raise ValueError(f"bad connection string {url!r}: expected HOST:PORT")
    return host or "0.0.0.0", int(port)


def _baud(text: str, url: str) -> int:
    if not text.strip().isdigit():
        raise ValueError(f"bad baud rate in {url!r}")
    return int(text)


def make_transport(endpoint: Endpoint) -> Transport:
    if endpoint.kind in ("udpin", "udpout", "udpbcast"):
        return UdpTransport(endpoint)
    if endpoint.kind == "tcp":
        return TcpClientTransport(endpoint)
    if endpoint.kind == "tcpin":
        return TcpServerTransport(endpoint)
    return SerialTransport(endpoint)


class UdpTransport:
    def __init__(self, endpoint: Endpoint) -> None:
        self.endpoint = endpoint
        self.description = f"{endpoint.kind}:{endpoint.host}:{endpoint.port}"
        self._sock: socket.socket | None = None
        self._peer: tuple[str, int] | None = None

    @property
    def is_open(self) -> bool:
        return self._sock is not None

    def open(self) -> None:
        e = self.endpoint
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            sock.setblocking(False)
            if e.kind == "udpin":
                sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
                sock.bind((e.host, e.port))
            else:
                if e.kind == "udpbcast":
                    sock.setsockopt(socket.SOL_SOCKET, socket.SO_BROADCAST, 1)
                self._peer = (socket.gethostbyname(e.host), e.port)
        except OSError:
            sock.close()
            raise
        self._sock = sock

    def filenos(self) -> list[int]:
        return [self._sock.fileno()] if self._sock is not None else []

    def read(self) -> bytes:
        if self._sock is None:
            return b""
        try:
            data, addr = self._sock.recvfrom(UDP_MAX)
        except (BlockingIOError, InterruptedError):
            return b""
        except ConnectionRefusedError:  # ICMP port unreachable from an earlier send
            return b""
        if self.endpoint.kind != "udpout":
            self._peer = addr  # answer whoever spoke last (udpbcast: lock onto it)
        return data

    def write(self, data: bytes) -> None:
        if self._sock is None or self._peer is None:
            return  # udpin: nobody has spoken yet
        # a full buffer or nobody listening yet: UDP may drop
        with contextlib.suppress(BlockingIOError, ConnectionRefusedError):
            self._sock.sendto(data, self._peer)

    def close(self) -> None:
        if self._sock is not None:
            self._sock.close()
            self._sock = None


class TcpClientTransport:
    def __init__(self, endpoint: Endpoint, connect_timeout_s: float = 1.0) -> None:
        self.endpoint = endpoint
        self.description = f"tcp:{endpoint.host}:{endpoint.port}"
        self.connect_timeout_s = connect_timeout_s
        self._sock: socket.socket | None = None
        self._out = bytearray()  # what the kernel did not take yet
        self.dropped_bytes = 0

    @property
    def is_open(self) -> bool:
        return self._sock is not None

    def open(self) -> None:
        sock = socket.create_connection(
            (self.endpoint.host, self.endpoint.port), timeout=self.connect_timeout_s
        )
        sock.setblocking(False)
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self._sock = sock
        self._out = bytearray()

    def filenos(self) -> list[int]:
        return [self._sock.fileno()] if self._sock is not None else []

    def read(self) -> bytes:
        if self._sock is None:
            return b""
        self._flush()
        try:
            data = self._sock.recv(65536)
        except (BlockingIOError, InterruptedError):
            return b""
        if not data:
            raise ConnectionResetError(errno.ECONNRESET, "closed by the autopilot")
        return data

    def write(self, data: bytes) -> None:
        if self._sock is None:
            return
        if len(self._out) + len(data) > _MAX_PENDING:
            self.dropped_bytes += len(data)  # the peer stopped reading: drop whole frames
            return
        self._out += data
        self._flush()

    def _flush(self) -> None:
        if self._sock is None or not self._out:
            return
        try:
            sent = self._sock.send(self._out)
        except (BlockingIOError, InterruptedError):
            return
        del self._out[:sent]

    def close(self) -> None:
        self._out.clear()
        if self._sock is not None:
            self._sock.close()
            self._sock = None


class TcpServerTransport:
    def __init__(self, endpoint: Endpoint) -> None:
        self.endpoint = endpoint
        self.description = f"tcpin:{endpoint.host}:{endpoint.port}"
        self._listen: socket.socket | None = None
        self._client: socket.socket | None = None

    @property
    def is_open(self) -> bool:
        return self._listen is not None

    def open(self) -> None:
        sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        try:
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            sock.bind((self.endpoint.host, self.endpoint.port))
            sock.listen(1)
            sock.setblocking(False)
        except OSError:
            sock.close()
            raise
        self._listen = sock

    def filenos(self) -> list[int]:
        """The listening socket (a new client replaces a dead one) and the client."""
        return [s.fileno() for s in (self._listen, self._client) if s is not None]

    def read(self) -> bytes:
        if self._listen is None:
            return b""
        try:
            client, _ = self._listen.accept()
        except (BlockingIOError, InterruptedError):
            pass
        else:
            if self._client is not None:
                self._client.close()
            client.setblocking(False)
            self._client = client
        if self._client is None:
            return b""
        try:
            data = self._client.recv(65536)
        except (BlockingIOError, InterruptedError):
            return b""
        except OSError:
            data = b""
        if not data:
            self._client.close()
            self._client = None
        return data

    def write(self, data: bytes) -> None:
        if self._client is None:
            return
        try:
            self._client.send(data)  # a partial send only costs the peer a resync
        except (BlockingIOError, InterruptedError):
            pass
        except OSError:
            self._client.close()
            self._client = None

    def close(self) -> None:
        for s in (self._client, self._listen):
            if s is not None:
                s.close()
        self._client = self._listen = None


class SerialTransport:
    def __init__(self, endpoint: Endpoint) -> None:
        self.endpoint = endpoint
        self.description = f"{endpoint.device},{endpoint.baud}"
        self._port: object | None = None

    @property
    def is_open(self) -> bool:
        return self._port is not None

    def open(self) -> None:
        import serial

        try:
            self._port = serial.Serial(
                self.endpoint.device,
                self.endpoint.baud,
                timeout=0,
                write_timeout=0,
                rtscts=False,
                dsrdtr=False,
                xonxoff=False,
            )
        except (serial.SerialException, ValueError) as exc:
            raise OSError(errno.ENODEV, f"{self.endpoint.device}: {exc}") from exc

    def filenos(self) -> list[int]:
        port = self._port
        if port is None:
            return []
        try:
            return [int(port.fileno())]  # type: ignore[attr-defined]
        except Exception:
            return []

    def read(self) -> bytes:
        import serial

        port = self._port
        if port is None:
            return b""
        try:
            waiting = port.in_waiting  # type: ignore[attr-defined]
            data = port.read(max(1, waiting))  # type: ignore[attr-defined]
        except (serial.SerialException, OSError, TypeError) as exc:
            raise OSError(errno.EIO, f"{self.endpoint.device}: {exc}") from exc
        return bytes(data)

    def write(self, data: bytes) -> None:
        import serial

        port = self._port
        if port is None:
            return
        try:
            port.write(data)  # type: ignore[attr-defined]
        except serial.SerialTimeoutException:
            pass  # output buffer full: drop, as a radio would
        except (serial.SerialException, OSError) as exc:
            raise OSError(errno.EIO, f"{self.endpoint.device}: {exc}") from exc

    def close(self) -> None:
        port = self._port
        self._port = None
        if port is not None:
            with contextlib.suppress(Exception):
                port.close()  # type: ignore[attr-defined]
