"""A small lab network on one machine, made of network namespaces this process creates:
one "hub" namespace holding a bridge per subnet, and one namespace per host with a veth
into the hub for each subnet it is on. Addresses (10.77.x.y) exist only inside the
namespaces; nothing touches the host's interfaces. Used by tests/test_netns.py and
`python -m bench deploy`.

Without IP forwarding (a new namespace's default) hosts on different subnets cannot
reach each other except through a process on a host in both: the Zenoh router.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import signal
import subprocess
import time
from pathlib import Path
from typing import IO

PREFIX = "bndl"


def unavailable() -> str | None:
    """Why namespaces cannot be made here (None: they can)."""
    if shutil.which("ip") is None:
        return "no `ip` command (iproute2)"
    if os.geteuid() != 0:
        return "network namespaces need root (CI runs as root)"
    name = f"{PREFIX}{os.getpid()}probe"
    r = subprocess.run(["ip", "netns", "add", name], capture_output=True, text=True)
    if r.returncode != 0:
        return f"cannot create a network namespace: {r.stderr.strip()}"
    subprocess.run(["ip", "netns", "del", name], capture_output=True)
    return None


def _ip(*args: str) -> None:
    r = subprocess.run(["ip", *args], capture_output=True, text=True)
    if r.returncode != 0:
        raise RuntimeError(f"ip {' '.join(args)}: {r.stderr.strip()}")


def clean_stale() -> None:
    """Delete namespaces left by a lab whose process is gone (a killed test run)."""
    r = subprocess.run(["ip", "netns", "list"], capture_output=True, text=True)
    for line in r.stdout.splitlines():
        name = line.split()[0] if line.split() else ""
        if not name.startswith(PREFIX):
            continue
        pid = name[len(PREFIX) :].split("-")[0]
        if pid.isdigit() and not Path(f"/proc/{pid}").exists():
            subprocess.run(["ip", "netns", "del", name], capture_output=True)


class NetLab:
    def __init__(self, logdir: Path) -> None:
        self.tag = f"{PREFIX}{os.getpid()}-{int(time.monotonic() * 1000) % 100000}"
        self.logdir = logdir
        self.namespaces: list[str] = []
        self.procs: list[subprocess.Popen[bytes]] = []
        self._logs: list[IO[bytes]] = []
        self._veth = 0
        clean_stale()
        self.hub = self._netns("hub")

    def _netns(self, name: str) -> str:
        ns = f"{self.tag}-{name}"
        _ip("netns", "add", ns)
        self.namespaces.append(ns)
        _ip("-n", ns, "link", "set", "lo", "up")
        return ns

    def subnet(self, name: str) -> None:
        _ip("-n", self.hub, "link", "add", f"br-{name}", "type", "bridge")
        _ip("-n", self.hub, "link", "set", f"br-{name}", "up")

    def host(self, name: str, addrs: dict[str, str]) -> str:
        """A host namespace with one interface per subnet: {"a": "10.77.1.5/24"};
        interfaces are eth0, eth1, ... in the order given. Returns the namespace."""
        ns = self._netns(name)
        for i, (subnet, addr) in enumerate(addrs.items()):
            self._veth += 1
            hub_end = f"v{self._veth}"
            _ip(
                "-n",
                self.hub,
                "link",
                "add",
                hub_end,
                "type",
                "veth",
                "peer",
                "name",
                f"eth{i}",
                "netns",
                ns,
            )
            _ip("-n", self.hub, "link", "set", hub_end, "master", f"br-{subnet}")
            _ip("-n", self.hub, "link", "set", hub_end, "up")
            _ip("-n", ns, "addr", "add", addr, "dev", f"eth{i}")
            _ip("-n", ns, "link", "set", f"eth{i}", "up")
        return ns

    def popen(
        self, ns: str, argv: list[str], log: str, env: dict[str, str] | None = None
    ) -> subprocess.Popen[bytes]:
        out = (self.logdir / log).open("wb")
        self._logs.append(out)
        proc = subprocess.Popen(
            ["ip", "netns", "exec", ns, *argv],
            stdout=out,
            stderr=subprocess.STDOUT,
            env=env,
            start_new_session=True,
        )
        self.procs.append(proc)
        return proc

    def run(
        self, ns: str, argv: list[str], env: dict[str, str] | None = None, timeout: float = 60.0
    ) -> subprocess.CompletedProcess[str]:
        return subprocess.run(
            ["ip", "netns", "exec", ns, *argv],
            capture_output=True,
            text=True,
            env=env,
            timeout=timeout,
        )

    def stop(self, proc: subprocess.Popen[bytes], timeout: float = 10.0) -> None:
        if proc.poll() is None:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(proc.pid, signal.SIGINT)
            try:
                proc.wait(timeout)
            except subprocess.TimeoutExpired:
                with contextlib.suppress(ProcessLookupError):
                    os.killpg(proc.pid, signal.SIGKILL)
                proc.wait(5)

    def close(self) -> None:
        for proc in reversed(self.procs):
            with contextlib.suppress(Exception):  # keep cleaning
                self.stop(proc, timeout=5.0)
        for f in self._logs:
            f.close()
        for ns in reversed(self.namespaces):
            subprocess.run(["ip", "netns", "del", ns], capture_output=True)
        self.namespaces.clear()

    def __enter__(self) -> NetLab:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


# --------------------------------------------------------------------------- the swarm lab

REPO = Path(__file__).resolve().parents[1]
ZENOH = REPO / "deploy" / "zenoh"
VEHICLES = (1, 2, 3)
GCS_ID = 900
ROUTER_A, ROUTER_B = "10.77.1.1", "10.77.2.1"


class SwarmLab:
    """Router, vehicles (a simulated vehicle and a `swarm-node run` each) and a ground
    station host, each in its own namespace, in one of the documented topologies:

    - "a": one subnet 10.77.1.0/24, the router started with deploy/zenoh/router.json5
      (multicast scouting on), every node with deploy/zenoh/scouting-peer.json5: no
      address configured anywhere;
    - "b": the ground station on 10.77.1.0/24, the vehicles on 10.77.2.0/24, the router on
      both (no IP forwarding: only Zenoh crosses), nodes with deploy/zenoh/client.json5
      and --connect to the router's address on their own subnet;
    - "tls": as "b", with the mutual-TLS and access-control configs of
      `swarm-node certs make` (certs in `certs_dir`).
    """

    def __init__(self, lab: NetLab, topology: str, env: dict[str, str]) -> None:
        import sys

        self.lab, self.topology, self.env = lab, topology, env
        self.py = sys.executable
        self.bin = Path(sys.executable).parent  # the console scripts, as a user runs them
        lab.subnet("a")
        two = topology in ("b", "tls")
        if two:
            lab.subnet("b")
            self.router = lab.host("router", {"a": f"{ROUTER_A}/24", "b": f"{ROUTER_B}/24"})
        else:
            self.router = lab.host("router", {"a": f"{ROUTER_A}/24"})
        self.gcs = lab.host("gcs", {"a": "10.77.1.100/24"})
        self.vehicles = {
            v: lab.host(f"v{v}", {"b" if two else "a": f"10.77.{2 if two else 1}.{10 + v}/24"})
            for v in VEHICLES
        }
        self.certs = lab.logdir / "certs"
        if topology == "tls":
            from swarm_node.certs import make_swarm_certs

            make_swarm_certs(self.certs, "default", list(VEHICLES), [GCS_ID], [ROUTER_B, ROUTER_A])

    # the command lines, as docs/deploy.md gives them
    def router_argv(self, log_denied: bool = False) -> list[str]:
        conf = self.certs / "router.json5" if self.topology == "tls" else ZENOH / "router.json5"
        argv = [str(self.bin / "swarm-node"), "router", "--config", str(conf)]
        return [*argv, "--log-denied"] if log_denied else argv

    def zenoh_args(self, who: str, subnet_router: str) -> list[str]:
        if self.topology == "a":
            return ["--zenoh-config", str(ZENOH / "scouting-peer.json5")]
        if self.topology == "b":
            return [
                "--zenoh-config",
                str(ZENOH / "client.json5"),
                "--connect",
                f"tcp/{subnet_router}:7447",
            ]
        return [
            "--zenoh-config",
            str(self.certs / f"{who}.json5"),
            "--connect",
            f"tls/{subnet_router}:7447",
        ]

    def vehicle_router(self) -> str:
        return ROUTER_B if self.topology in ("b", "tls") else ROUTER_A

    def start_router(
        self, log_denied: bool = False, timeout: float = 60.0
    ) -> subprocess.Popen[bytes]:
        """Start the router and wait until it listens (it prints "zenoh router ...")."""
        proc = self.lab.popen(self.router, self.router_argv(log_denied), "router.log", self.env)
        log = self.lab.logdir / "router.log"
        deadline = time.monotonic() + timeout
        while "zenoh router" not in log.read_text(errors="replace"):
            if proc.poll() is not None or time.monotonic() > deadline:
                raise RuntimeError(f"the router did not start: {log.read_text()[-2000:]}")
            time.sleep(0.1)
        return proc

    def start_vehicle(self, v: int) -> None:
        ns = self.vehicles[v]
        self.lab.popen(
            ns,
            [str(self.bin / "swarm-sim"), "vehicle", "--model", "vtol", "--sysid", str(v)],
            f"sim-{v}.log",
            self.env,
        )
        env = {**self.env, "BANDADA_DB": str(self.lab.logdir / f"swarm-{v}.db")}
        self.lab.popen(
            ns,
            [
                str(self.bin / "swarm-node"),
                "run",
                "--id",
                str(v),
                "--autopilot",
                "tcp:127.0.0.1:5760",
                *self.zenoh_args(f"vehicle-{v}", self.vehicle_router()),
            ],
            f"node-{v}.log",
            env,
        )

    def gcs_argv(self, *args: str, who: str = f"gcs-{GCS_ID}") -> list[str]:
        return [str(self.bin / "gcs"), *self.zenoh_args(who, ROUTER_A), *args]
