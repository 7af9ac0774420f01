"""Serves a FakeAutopilot on a real TCP port, UDP port or pseudo-terminal, in a thread,
so the AutopilotLink shell is tested through real sockets and a real tty."""

from __future__ import annotations

import contextlib
import os
import select
import socket
import threading
import tty
from collections.abc import Callable

from swarm_proto import Clock

from .fake_autopilot import FakeAutopilot


class FakeEndpoint:
    """kind: "tcp" (listens; the link connects with tcp:), "tcpout" (connects to the
    link's tcpin: port), "udp" (listens; the link uses udpout:), "udpout" (sends to the
    link's udpin: port), "pty" (a pseudo-terminal; the link opens `device`)."""

    def __init__(self, fake: FakeAutopilot, clock: Clock, kind: str, port: int = 0) -> None:
        self.fake = fake
        self.clock = clock
        self.kind = kind
        self.lock = threading.Lock()
        #: applied to every packet the fake sends (corruption tests); None drops it
        self.tamper: Callable[[bytes], bytes | None] | None = None
        self.paused = False  # True: send nothing, read and discard
        self._stop = threading.Event()
        self._listen: socket.socket | None = None
        self._conn: socket.socket | None = None
        self._peer: tuple[str, int] | None = None
        self._fd: int | None = None
        self.device = ""
        if kind == "tcp":
            self._listen = socket.socket()
            self._listen.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            self._listen.bind(("127.0.0.1", port))
            self._listen.listen(1)
            self.port = self._listen.getsockname()[1]
        elif kind == "tcpout":
            self.port = port
        elif kind in ("udp", "udpout"):
            self._conn = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            if kind == "udp":
                self._conn.bind(("127.0.0.1", port))
                self.port = self._conn.getsockname()[1]
            else:
                self._conn.bind(("127.0.0.1", 0))
                self._peer = ("127.0.0.1", port)
                self.port = port
        elif kind == "pty":
            master, slave = os.openpty()
            tty.setraw(master)
            tty.setraw(slave)
            self._fd = master
            self._slave = slave
            self.device = os.ttyname(slave)
            self.port = 0
        else:
            raise ValueError(kind)
        self._thread = threading.Thread(target=self._run, name=f"fake-{kind}", daemon=True)

    def start(self) -> FakeEndpoint:
        self._thread.start()
        return self

    def close(self) -> None:
        self._stop.set()
        self._thread.join(5)
        for s in (self._conn, self._listen):
            if s is not None:
                s.close()
        if self._fd is not None:
            for fd in (self._fd, self._slave):
                with contextlib.suppress(OSError):
                    os.close(fd)

    def drop_client(self) -> None:
        """TCP: close the current connection (the link must reconnect / accept again)."""
        with self.lock:
            if self.kind in ("tcp", "tcpout") and self._conn is not None:
                self._conn.close()
                self._conn = None

    def send_raw(self, data: bytes) -> None:
        with self.lock:
            self._write(data)

    # ----------------------------------------------------------------- thread

    def _write(self, data: bytes) -> None:
        try:
            if self.kind in ("tcp", "tcpout"):
                if self._conn is not None:
                    self._conn.sendall(data)
            elif self.kind in ("udp", "udpout"):
                if self._conn is not None and self._peer is not None:
                    self._conn.sendto(data, self._peer)
            elif self._fd is not None:
                os.write(self._fd, data)
        except OSError:
            pass

    def _send(self, packets: list[bytes]) -> None:
        if self.paused:
            return
        for p in packets:
            if self.tamper is not None:
                p2 = self.tamper(p)
                if p2 is None:
                    continue
                p = p2
            self._write(p)

    def _run(self) -> None:
        while not self._stop.is_set():
            fds: list = []
            if self.kind == "tcpout" and self._conn is None:
                with contextlib.suppress(OSError), self.lock:
                    self._conn = socket.create_connection(("127.0.0.1", self.port), timeout=0.2)
                if self._conn is None:
                    self._stop.wait(0.05)
                    continue
            if self.kind == "tcp":
                fds.append(self._conn if self._conn is not None else self._listen)
            elif self._conn is not None:
                fds.append(self._conn)
            else:
                fds.append(self._fd)
            with self.lock:
                now = self.clock.now()
                wait = max(0.0, min(self.clock.to_wall(self.fake.next_deadline() - now), 0.05))
            try:
                readable, _, _ = select.select(fds, [], [], wait or 0.002)
            except (OSError, ValueError):
                readable = []
            with self.lock:
                now = self.clock.now()
                for r in readable:
                    data = self._read(r)
                    if data and not self.paused:
                        self._send(self.fake.receive(data, now))
                if now >= self.fake.next_deadline():
                    self._send(self.fake.telemetry(now))

    def _read(self, r: object) -> bytes:
        try:
            if r is self._listen and self._listen is not None:
                conn, _ = self._listen.accept()
                self._conn = conn
                return b""
            if isinstance(r, socket.socket):
                if self.kind in ("tcp", "tcpout"):
                    data = r.recv(65536)
                    if not data:
                        r.close()
                        self._conn = None
                    return data
                data, addr = r.recvfrom(65536)
                if self.kind == "udp":
                    self._peer = addr
                return data
            return os.read(self._fd, 65536) if self._fd is not None else b""
        except OSError:
            return b""
