"""The emulated radio channel on pseudo-terminals: N endpoints that a gateway opens with
pyserial like /dev/ttyUSB0 (the I/O shell around `model.RadioChannelModel`).

    with PtyRadioChannel(4, ChannelParams(loss=0.1), clock) as channel:
        channel.ports   # ["/dev/pts/7", ...]

The serial rate a host set on its end (termios) is compared with the module's BD: a
mismatch garbles the bytes both ways, as on a real UART.
"""

from __future__ import annotations

import contextlib
import errno
import logging
import os
import select
import termios
import threading
import time
import tty
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from swarm_proto.clock import Clock, SystemClock

from .model import ChannelParams, RadioChannelModel, garble

log = logging.getLogger(__name__)

_BAUDS: dict[int, int] = {
    getattr(termios, f"B{b}"): b
    for b in (1200, 2400, 4800, 9600, 19200, 38400, 57600, 115200, 230400)
    if hasattr(termios, f"B{b}")
}


class PtyRadioChannel:
    def __init__(
        self,
        n: int,
        params: ChannelParams | None = None,
        clock: Clock | None = None,
        *,
        registers: Mapping[str, int] | None = None,
        link_dir: Path | None = None,
    ) -> None:
        """`registers` presets (and saves) AT registers on every module, e.g. the settings
        `radio-gateway configure` would write; `link_dir` gets symlinks radio0..radioN-1."""
        if n < 1:
            raise ValueError("need at least one endpoint")
        self.clock = clock or SystemClock()
        self.model = RadioChannelModel(n, params or ChannelParams())
        self._masters: list[int] = []
        self._slaves: list[int] = []
        self.ports: list[str] = []
        for i in range(n):
            master, slave = os.openpty()
            tty.setraw(slave)
            os.set_blocking(master, False)
            self._masters.append(master)
            self._slaves.append(slave)
            self.ports.append(os.ttyname(slave))
            if registers:
                self.model.preset(i, **dict(registers))
        self.links: list[Path] = []
        if link_dir is not None:
            link_dir.mkdir(parents=True, exist_ok=True)
            for i, port in enumerate(self.ports):
                link = link_dir / f"radio{i}"
                with contextlib.suppress(FileNotFoundError):
                    link.unlink()
                link.symlink_to(port)
                self.links.append(link)
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self.overflow = 0
        # the longest the emulator sleeps without looking, and how much later than asked
        # it may wake before what it reads counts as late: together under half a 5 ms
        # guard, so a read it does not flag is never late enough to overlap a neighbour
        self.poll_s = 0.002
        self.late_tolerance_s = 0.0005
        self.late_reads = 0

    # ------------------------------------------------------------------ lifecycle
    def start(self) -> PtyRadioChannel:
        self._thread = threading.Thread(target=self.run, name="radio-channel", daemon=True)
        self._thread.start()
        return self

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=5)
            self._thread = None

    def close(self) -> None:
        self.stop()
        for fd in self._masters + self._slaves:
            with contextlib.suppress(OSError):
                os.close(fd)
        for link in self.links:
            with contextlib.suppress(OSError):
                link.unlink()
        self._masters, self._slaves = [], []

    def __enter__(self) -> PtyRadioChannel:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.close()

    # ------------------------------------------------------------------ state
    def host_baud(self, i: int) -> int | None:
        try:
            return _BAUDS.get(termios.tcgetattr(self._slaves[i])[4])
        except (termios.error, OSError, IndexError):
            return None

    def stats(self) -> dict[str, Any]:
        with self._lock:
            return {
                "channel": dict(self.model.counts),
                "modules": [dict(c) for c in self.model.per_module],
                "overflow": self.overflow,
                "late_reads": self.late_reads,
            }

    def reset_stats(self) -> None:
        with self._lock:
            self.model.counts.clear()
            for c in self.model.per_module:
                c.clear()

    def power_cycle(self, i: int) -> None:
        with self._lock:
            self.model.power_cycle(i)

    def set_loss(self, loss: float) -> None:
        from dataclasses import replace

        with self._lock:
            self.model.params = replace(self.model.params, loss=loss)

    # ------------------------------------------------------------------ loop
    def run(self, stop: threading.Event | None = None) -> None:
        """The emulator reads what hosts write when it gets to run: on a busy machine it
        may itself be late, and bytes it reads late start their packet late, into the
        next slot. It waits at most `poll_s` at a time; an iteration that took more than
        that plus `late_tolerance_s` was descheduled, and what it reads is flagged late
        (the emulator's host, not the schedule: `collisions_late`, apart from TDM
        faults)."""
        stop = stop or self._stop
        index = {fd: i for i, fd in enumerate(self._masters)}
        last = time.monotonic()  # when we last looked (the previous select returned)
        while not stop.is_set() and not self._stop.is_set():
            now = self.clock.now()
            with self._lock:
                deadline = self.model.next_deadline()
            wait = self.poll_s if deadline is None else self.clock.to_wall(deadline - now)
            wait = min(max(wait, 0.0), self.poll_s)
            try:
                ready, _, _ = select.select(list(index), [], [], wait)
            except (OSError, ValueError):
                return  # closed underneath us
            # since we last looked: the wait asked and the tolerance (a host's write may
            # have sat unread as long; descheduled anywhere in the loop shows here)
            looked = time.monotonic()
            late = looked - last > wait + self.late_tolerance_s
            last = looked
            if late and ready:
                self.late_reads += 1
            now = self.clock.now()
            with self._lock:
                for fd in ready:
                    try:
                        data = os.read(fd, 65536)
                    except BlockingIOError:
                        continue
                    except OSError as exc:
                        if exc.errno in (errno.EIO, errno.EBADF):
                            continue
                        raise
                    if data:
                        i = index[fd]
                        self.model.from_host(i, data, now, self.host_baud(i), late=late)
                out = self.model.on_timer(self.clock.now())
            for i, data in out:
                self._write(i, data)

    def _write(self, i: int, data: bytes) -> None:
        m = self.model.modules[i]
        host = self.host_baud(i)
        if host is not None and host != m.baud:
            data = garble(data)
        try:
            os.write(self._masters[i], data)
        except (BlockingIOError, OSError):
            self.overflow += 1  # nobody reads that port: the module's buffer overflows


def _serve(conn: Any, n: int, params: ChannelParams, clock_spec: str, registers: Any) -> None:
    from swarm_proto.clock import clock_from_spec

    channel = PtyRadioChannel(n, params, clock_from_spec(clock_spec), registers=registers)
    channel.start()
    conn.send(channel.ports)
    try:
        while True:
            cmd, arg = conn.recv()
            if cmd == "close":
                break
            if cmd == "stats":
                conn.send(channel.stats())
            elif cmd == "reset":
                channel.reset_stats()
                conn.send(None)
            elif cmd == "power_cycle":
                channel.power_cycle(arg)
                conn.send(None)
            elif cmd == "loss":
                channel.set_loss(arg)
                conn.send(None)
    except (EOFError, OSError):
        pass
    finally:
        channel.close()


class ChannelProcess:
    """A PtyRadioChannel in a process of its own (spawned), so that the timing of the
    emulated air does not share an interpreter with the gateways under test. Same calls
    as PtyRadioChannel: ports, stats(), reset_stats(), power_cycle(i), set_loss(p)."""

    def __init__(
        self,
        n: int,
        params: ChannelParams | None = None,
        clock: Clock | None = None,
        *,
        registers: Mapping[str, int] | None = None,
    ) -> None:
        import multiprocessing

        ctx = multiprocessing.get_context("spawn")
        self._conn, child = ctx.Pipe()
        spec = (clock or SystemClock()).spec()
        regs = dict(registers) if registers else None
        self._proc = ctx.Process(
            target=_serve, args=(child, n, params or ChannelParams(), spec, regs), daemon=True
        )
        self._proc.start()
        if not self._conn.poll(30):
            self._proc.kill()
            raise RuntimeError("the radio channel process did not start")
        self.ports: list[str] = self._conn.recv()

    def _call(self, cmd: str, arg: Any = None) -> Any:
        self._conn.send((cmd, arg))
        return self._conn.recv()

    def stats(self) -> dict[str, Any]:
        result: dict[str, Any] = self._call("stats")
        return result

    def reset_stats(self) -> None:
        self._call("reset")

    def power_cycle(self, i: int) -> None:
        self._call("power_cycle", i)

    def set_loss(self, loss: float) -> None:
        self._call("loss", loss)

    def close(self) -> None:
        with contextlib.suppress(OSError, BrokenPipeError):
            self._conn.send(("close", None))
        self._proc.join(timeout=10)
        if self._proc.is_alive():
            self._proc.kill()
        self._conn.close()

    def __enter__(self) -> ChannelProcess:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
