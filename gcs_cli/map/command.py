"""`gcs map`: the operator's live map in a browser (docs/ground-station.md, "The live
map"). Registered on the `gcs` app by app.py."""

from __future__ import annotations

import asyncio
import contextlib
import re
import secrets
import signal
import sys
from pathlib import Path

import typer

from ..common import console
from ..options import finite


def parse_listen(text: str) -> tuple[str, int]:
    """HOST:PORT (an IPv6 host in brackets); port 0: one the kernel picks."""
    m = re.fullmatch(r"\[([0-9A-Fa-f:.]+)\]:(\d{1,5})|([A-Za-z0-9.\-]+):(\d{1,5})", text.strip())
    if m is None:
        raise typer.BadParameter(
            f"expected HOST:PORT (e.g. 127.0.0.1:8765), got {text!r}", param_hint="--listen"
        )
    host = m.group(1) or m.group(3)
    port = int(m.group(2) or m.group(4))
    if port > 65535:
        raise typer.BadParameter(f"port {port} is out of range 0..65535", param_hint="--listen")
    return host, port


def check_tiles(url: str) -> str:
    """A tile server's URL template: http(s), with {z}, {x} and {y}."""
    if not re.match(r"^https?://[^\s/]+/", url) or not all(
        f"{{{k}}}" in url for k in ("z", "x", "y")
    ):
        raise typer.BadParameter(
            f"{url!r}: a tile URL is http(s)://HOST/.../{{z}}/{{x}}/{{y}}.png", param_hint="--tiles"
        )
    return url


def map_command(
    ctx: typer.Context,
    listen: str = typer.Option(
        "127.0.0.1:8765",
        "--listen",
        help="HOST:PORT the page is served on; any address but a loopback one needs "
        "the token printed in the URL to see the map at all",
    ),
    tiles: str | None = typer.Option(
        None,
        "--tiles",
        help="a tile server, e.g. http://tiles.local/{z}/{x}/{y}.png (default: none, a "
        "metric grid: the map works with no network)",
    ),
    replay: Path | None = typer.Option(
        None,
        "--replay",
        dir_okay=False,
        help="play a flight recorder CSV (gcs record, the demo's flight.csv) with a time "
        "slider, instead of the live swarm; no commands",
    ),
    trail: float = typer.Option(5.0, "--trail", help="trails: the last this many minutes"),
    token: str | None = typer.Option(
        None,
        "--token",
        help="the token the page's requests must carry (default: a fresh random one)",
        hidden=True,
    ),
) -> None:
    """The operator's live map, served to a browser: every vehicle as a heading icon
    (its type, coloured by fleet, bordered by its worst active alert), trails, homes,
    the base, zones, missions and each vehicle's share, the vehicle list with packets
    per second, the flight display, alerts, the last vote, and commands with a
    confirmation naming the vehicles and every answer shown. Prints its URL (with the
    token every command carries) and serves until Ctrl-C.

    Example: gcs --connect tcp/10.0.0.1:7447 map --tiles http://tiles.local/{z}/{x}/{y}.png
    """
    from .server import Config, Hub, is_loopback, replay_infos

    host, port = parse_listen(listen)
    if tiles is not None:
        check_tiles(tiles)
    finite(trail, "--trail", 0.1, 24 * 60.0)
    if token is not None and not re.fullmatch(r"[A-Za-z0-9_\-]{16,64}", token):
        raise typer.BadParameter("16-64 letters, digits, '-' or '_'", param_hint="--token")
    link = ctx.obj
    config = Config(
        host,
        port,
        token or secrets.token_urlsafe(18),
        tiles,
        link.swarm,
        link.gcs_id,
        trail * 60.0,
    )
    player = None
    if replay is not None:
        from swarm_proto.trajectory import TrajectoryError

        from .replay import Player, read_flight

        try:
            player = Player(read_flight(replay))
        except TrajectoryError as exc:
            raise typer.BadParameter(str(exc), param_hint="--replay") from None
    if not is_loopback(host):
        console.print(
            f"[yellow]gcs map: listening on {host}: the page and every command need the "
            "token in the URL; anyone with the URL can command the swarm[/]"
        )
    gs = None if player is not None else link.open()
    try:
        hub = Hub(config, gs, player)
        if player is not None:
            hub.use_infos(replay_infos(sorted({s.vehicle_id for s in player.samples}), None))
        else:
            hub.attach()
        _run(hub)
    finally:
        if gs is not None:
            gs.close()


def _run(hub: object) -> None:
    from .server import Hub, serve

    assert isinstance(hub, Hub)

    async def main() -> None:
        stopped = asyncio.Event()
        loop = asyncio.get_running_loop()
        for sig in (signal.SIGINT, signal.SIGTERM):
            with contextlib.suppress(NotImplementedError, RuntimeError):
                loop.add_signal_handler(sig, stopped.set)

        def ready(url: str) -> None:
            what = "replay" if hub.player is not None else f"swarm {hub.config.swarm}"
            print(f"gcs map ({what}): {url}", flush=True)
            print("Ctrl-C stops", file=sys.stderr, flush=True)

        try:
            await serve(hub, ready, stopped)
        except OSError as exc:
            raise typer.BadParameter(
                f"cannot listen on {hub.config.host}:{hub.config.port}: {exc.strerror or exc}",
                param_hint="--listen",
            ) from None

    try:
        asyncio.run(main())
    finally:
        hub.close()
