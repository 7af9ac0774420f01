"""What every `gcs` command shares: the console, the link to the swarm (`Link`, made
from the root options by `link_options`), the checks of the common options, whom a
command addresses and the confirmation of a request that moves vehicles. The commands
import this module; `app.py` assembles them."""

from __future__ import annotations

import contextlib
import os
import signal
import sys
import threading
from collections.abc import Iterator
from dataclasses import dataclass

import msgspec
import typer
from rich.console import Console

from swarm_proto import Geometry, Selector, SelectorKind
from swarm_proto.endpoints import zenoh_endpoint
from swarm_proto.session import ZenohSettings
from swarm_proto.session import zenoh_config as zenoh_config_of

from . import _clickx
from .ground import DEFAULT_GCS_ID, GroundStation
from .options import confirm, describe, finite, selection
from .options import geometry_from as _geometry_from
from .options import parse_latlon as _parse_latlon
from .options import parse_points as _parse_points


def _width() -> int | None:
    """A terminal's own width; 100 columns (or $COLUMNS if wider) for a file or a pipe,
    where rich would take 80 and squeeze the tables."""
    if sys.stdout.isatty():
        return None
    try:
        return max(100, int(os.environ.get("COLUMNS", "100")))
    except ValueError:
        return 100


console = Console(width=_width())
REACH_S = 3.0  # how long a fresh session may take to reach the router or a peer


@dataclass
class Link:
    settings: ZenohSettings
    swarm: str
    gcs_id: int

    def open(self, *, check: bool = True) -> GroundStation:
        """A ground station session; exit 2 (one line) when Zenoh cannot be opened
        (a taken --listen port, a certificate), exit 1 when, with `check`, nothing at
        --connect answers
        (an unreachable router looked like an empty swarm, exit 0)."""
        try:
            gs = GroundStation(self.settings, self.swarm, self.gcs_id, database_ids=database_ids())
        except Exception as exc:
            from swarm_proto.session import zenoh_reason as _zenoh_reason

            err = _clickx.ClickException(f"cannot open Zenoh: {_zenoh_reason(exc)}")
            err.exit_code = 2  # type: ignore[attr-defined]  # a taken port, a bad certificate: the setup
            raise err from None
        if check and self.settings.connect and not gs.reachable(REACH_S):
            gs.close()
            where = ", ".join(self.settings.connect)
            raise _clickx.ClickException(
                f"nothing answers at {where} within {REACH_S:g} s: is the router running "
                "(`swarm-node router`), and is the endpoint right?"
            )
        return gs


def database_ids() -> list[int] | None:
    """The vehicles of the swarm database ($BANDADA_DB, else the per-user file), or
    None when it cannot be read: whom `--all` may miss, and ids it does not know."""
    from swarm_node.database import SwarmDatabase
    from swarm_node.database.errors import SwarmDbError
    from swarm_node.database.paths import resolve_db_path
    from swarm_proto import VehicleType

    try:
        with SwarmDatabase.open(resolve_db_path(None)) as db:
            return [p.vehicle_id for p in db.profiles() if p.vehicle_type != VehicleType.GCS]
    except (SwarmDbError, OSError):
        return None


def _endpoints(values: list[str], name: str) -> list[str]:
    out = []
    for v in values:
        try:
            out.append(zenoh_endpoint(v))
        except ValueError as exc:
            raise typer.BadParameter(str(exc), param_hint=name) from None
    return out


def link_options(
    ctx: typer.Context,
    connect: list[str] = typer.Option(
        [],
        help="Zenoh endpoints to connect to, e.g. tcp/10.0.0.1:7447 (tcp:HOST:PORT and "
        "HOST:PORT are read the same); default tcp/127.0.0.1:7447, or the file's",
    ),
    listen: list[str] = typer.Option([], help="Zenoh endpoints to listen on"),
    mode: str = typer.Option("peer", help="Zenoh mode: peer or client"),
    zenoh_config: str | None = typer.Option(
        None,
        "--zenoh-config",
        help="a Zenoh JSON5 config (deploy/zenoh/peer.json5, or gcs-<id>.json5 from "
        "`swarm-node certs make`); --connect/--listen/--mode override it",
    ),
    swarm: str = typer.Option("default", help="swarm name"),
    gcs_id: int = typer.Option(
        DEFAULT_GCS_ID, min=1, max=65534, help="this ground station's node id"
    ),
) -> None:
    """bandada ground station.

    Example: gcs --connect tcp/10.0.0.1:7447 status
    """
    if mode not in ("peer", "client", "router"):
        raise typer.BadParameter("mode is peer, client or router", param_hint="--mode")
    connect = _endpoints(connect, "--connect")
    listen = _endpoints(listen, "--listen")
    if not connect and not zenoh_config and mode != "router":
        connect = ["tcp/127.0.0.1:7447"]
    settings = msgspec.convert(
        {"mode": mode, "connect": connect, "listen": listen, "config_file": zenoh_config},
        ZenohSettings,
    )
    if zenoh_config:
        try:
            zenoh_config_of(settings)
        except ValueError as exc:
            raise typer.BadParameter(str(exc), param_hint="--zenoh-config") from exc
    ctx.obj = Link(settings, swarm, gcs_id)


def parse_point(text: str) -> tuple[float, float]:
    return _parse_latlon(text)


def parse_points(text: str) -> list[tuple[float, float]]:
    return _parse_points(text, "--points")


def geometry_from(
    polygon: str | None, point: str | None, circle: str | None, line: str | None, points: str | None
) -> Geometry:
    return _geometry_from(polygon, point, circle, line, points)


def selector_from(
    ids: list[int],
    fleet: int | None,
    quantity: int,
    payload: str,
    all_: bool = False,
    *,
    required: bool = False,
) -> Selector:
    if not 0 <= quantity <= 255:
        raise typer.BadParameter(f"--count must be 1..255, got {quantity}")
    if payload and not quantity:
        raise typer.BadParameter("--payload needs --count: voting picks a payload's vehicles")
    if quantity and ids:
        raise typer.BadParameter("--count and --id exclude each other: voting picks the ids")
    if quantity and all_:
        raise typer.BadParameter("--count and --all exclude each other")
    try:
        if quantity:
            return Selector(
                SelectorKind.QUANTITY, fleet_id=fleet or 0, quantity=quantity, payload_model=payload
            )
        return selection(ids, fleet, all_, required=required)
    except ValueError as exc:
        raise typer.BadParameter(str(exc)) from exc


def wait_option(wait: float) -> float:
    finite(wait, "--wait", 0.0, 3600.0)
    return wait


def timeout_option(timeout: float) -> float:
    finite(timeout, "--timeout", 0.0, 3600.0)
    return timeout


def read_filter(ids: list[int], fleet: int | None, all_: bool = False) -> Selector:
    """A read command's filter: --id / --fleet, else (or --all) every vehicle."""
    return selection(ids, fleet, all_, required=False)


def ask(gs: GroundStation, what: str, sel: Selector, yes: bool) -> None:
    """Confirm a request that moves or arms vehicles, naming whom it reaches now."""
    if yes:
        return
    alive = None
    if sel.kind != SelectorKind.IDS:
        gs.discover()
        alive = sorted(
            k.vehicle_id
            for k in gs.known()
            if k.alive and sel.addresses(k.vehicle_id, k.fleet_id or 0)
        )
    confirm(f"{what} to {describe(sel, alive)}?", yes)


@contextlib.contextmanager
def quit_on_signal() -> Iterator[threading.Event]:
    """An event set by Ctrl-C (SIGINT) or SIGTERM while a long-running command loops:
    the loop waits on it instead of relying on KeyboardInterrupt, which a native library
    checking signals inside its own call (Zenoh's bindings) can take and drop; then a
    Ctrl-C was lost and `gcs watch` ran on. Outside the main thread (a test's runner)
    nothing is installed and the event is never set by a signal."""
    quit_ = threading.Event()
    if threading.current_thread() is not threading.main_thread():
        yield quit_
        return

    def _set(signum: int, frame: object) -> None:
        quit_.set()

    before = {sig: signal.signal(sig, _set) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield quit_
    finally:
        for sig, handler in before.items():
            signal.signal(sig, handler)
