"""Endpoints as operators write them. Zenoh writes `tcp/127.0.0.1:7447`, MAVLink tools
(pymavlink, MAVProxy) write `tcp:127.0.0.1:5760`; operators mix them up. Each reader
here accepts the other's spelling and a bare `HOST:PORT`, and refuses anything else
with a one-line message that shows the right form."""

from __future__ import annotations

import re

ZENOH_PROTOCOLS = ("tcp", "udp", "tls", "quic", "ws", "unixsock-stream", "serial")
_HOST_PORT = re.compile(r"^(\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9_.-]+):(\d{1,5})$")


def _port_ok(port: str) -> bool:
    return 0 <= int(port) <= 65535  # 0: any free port (to listen on)


def zenoh_endpoint(text: str) -> str:
    """`tcp/HOST:PORT` (and Zenoh's other protocols) as is; `tcp:HOST:PORT` (MAVLink's
    spelling) and `HOST:PORT` become `tcp/HOST:PORT`. ValueError otherwise."""
    t = text.strip()
    hint = f"{text!r} is not a Zenoh endpoint: write PROTOCOL/HOST:PORT, e.g. tcp/127.0.0.1:7447"
    proto, sep, rest = t.partition("/")
    if sep and proto in ZENOH_PROTOCOLS:
        locator = rest.split("#", 1)[0]
        if proto in ("unixsock-stream", "serial"):
            return t if locator else _raise(hint)
        m = _HOST_PORT.match(locator)
        if m is None or not _port_ok(m.group(2)):
            raise ValueError(hint)
        return t
    for p in ("tcp", "udp", "tls", "quic"):
        if t.startswith(p + ":"):
            m = _HOST_PORT.match(t[len(p) + 1 :])
            if m and _port_ok(m.group(2)):
                return f"{p}/{t[len(p) + 1 :]}"
            raise ValueError(hint)
    m = _HOST_PORT.match(t)
    if m and _port_ok(m.group(2)):
        return f"tcp/{t}"
    raise ValueError(hint)


def _raise(message: str) -> str:
    raise ValueError(message)


def mavlink_endpoint(text: str) -> str:
    """A MAVLink connection string as pymavlink takes it (`tcp:HOST:PORT`, `udpin:`,
    `udpout:`, a serial device `/dev/ttyACM0[,BAUD]`); Zenoh's `tcp/HOST:PORT`
    becomes `tcp:HOST:PORT`. ValueError (with the forms) otherwise."""
    t = text.strip()
    hint = (
        f"{text!r} is not a MAVLink connection: write tcp:HOST:PORT, udpin:HOST:PORT, "
        "udpout:HOST:PORT or a serial device such as /dev/ttyACM0,115200"
    )
    if t.startswith("tcp/"):
        t = "tcp:" + t[4:]
    for p in ("tcp:", "tcpin:", "udp:", "udpin:", "udpout:", "udpbcast:"):
        if t.startswith(p):
            m = _HOST_PORT.match(t[len(p) :])
            if m and _port_ok(m.group(2)):
                return t
            raise ValueError(hint)
    if t.startswith(("/dev/", "COM")) or (t and t[0] in "/." and "," in t):
        return t
    raise ValueError(hint)
