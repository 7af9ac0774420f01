"""The live map's server: transport only. The view model (model.py) decides what the
page shows; this module feeds it and carries its frames and the page's requests.

    Zenoh callbacks (GroundStation's session) ──> a thread-safe queue ──┐
    replay (a flight CSV, replay.py) ───────────────────────────────────┤
                                                 the aiohttp loop: every FRAME_S the
                                                 queue is folded into the model, and
                                                 each page gets what changed since its
                                                 last frame over its WebSocket
    the page's requests (WebSocket or POST /api/check, /api/send) ──> commands.py:
    checked as `gcs` checks them, confirmed on the page, sent through the exchange core
    in a worker thread; the answers come back through the model

Safety: the server binds 127.0.0.1 unless told otherwise. Every request that changes
anything (a command, a zone, a mission, the replay's controls) carries the token
`gcs map` generated and printed in the page's URL, or is refused; on any address other
than a loopback one the page and its WebSocket need the token too. A WebSocket opened
from another site's page (its Origin not this server) is refused.
"""

from __future__ import annotations

import asyncio
import contextlib
import hmac
import ipaddress
import itertools
import logging
import queue
import threading
import time
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit

import msgspec
from aiohttp import WSMsgType, web

from swarm_proto import VehicleInfo, VehicleType
from swarm_proto.topics import ACK, ALERT, INFO, MISSION, VOTE, ZONE

from ..answers import outcome_json, summary
from ..core.exchange import Exchange
from ..core.lost import NotLostError
from .commands import (
    PageError,
    Prepared,
    dismissal,
    geometry_preview,
    prepare,
    question,
    send,
)
from .model import (
    Alive,
    CommandDone,
    CommandFailed,
    CommandRef,
    CommandSent,
    MapModel,
    PlanDone,
    PlanJob,
)
from .replay import Player

log = logging.getLogger(__name__)

FRAME_S = 0.2  # frames at most 5 per second to each page
RESYNC_S = 30.0  # the zones and missions the vehicles hold, asked again this often
STATIC = Path(__file__).resolve().parent / "static"
MAX_REQUEST_BYTES = 4 * 1024 * 1024  # a mission file read on the page, base64


def leaflet_dir() -> Path:
    """Leaflet's files, as the xstatic-leaflet package ships them (served locally)."""
    import xstatic.pkg.leaflet as leaflet  # type: ignore[import-untyped]

    return Path(leaflet.BASE_DIR)


def is_loopback(host: str) -> bool:
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host.strip("[]")).is_loopback
    except ValueError:
        return False


@dataclass
class Config:
    host: str
    port: int
    token: str
    tiles: str | None = None
    swarm: str = "default"
    gcs_id: int = 900
    trail_s: float = 300.0
    db_path: Path | None = None


class Hub:
    """The loop's side: the model, the pages, the requests. Everything here runs on the
    event loop's thread except what is handed to the executors (sending, planning)."""

    def __init__(self, config: Config, gs: Any | None = None, player: Player | None = None) -> None:
        if (gs is None) == (player is None):
            raise ValueError("a hub is live (a ground station) or a replay (a player)")
        self.config = config
        self.gs = gs
        self.player = player
        self.inbox: queue.SimpleQueue[tuple[Any, float]] = queue.SimpleQueue()
        self.pages: dict[web.WebSocketResponse, _Page] = {}
        self.epoch = 1
        self.cids = itertools.count(1)
        self.sending = ThreadPoolExecutor(4, thread_name_prefix="map-send")
        self.planning = ThreadPoolExecutor(1, thread_name_prefix="map-plan")
        self.stop = threading.Event()
        self.infos: list[VehicleInfo] = []
        self.model = self._new_model()
        self._statuses: Any = None
        self.frames_sent = 0

    # ------------------------------------------------------------------ time
    def now(self) -> float:
        return self.player.t if self.player is not None else time.monotonic()

    def use_infos(self, infos: list[VehicleInfo]) -> None:
        """The vehicles a replay shows (from its CSV): the map starts again with them."""
        self.infos = infos
        self.model = self._new_model()

    def _new_model(self) -> MapModel:
        if self.player is None:
            return MapModel(
                time.monotonic(), trail_s=self.config.trail_s, gcs_id=self.config.gcs_id
            )
        model = MapModel(
            self.player.t0, trail_s=self.config.trail_s, gcs_id=self.config.gcs_id, mode="replay"
        )
        for info in self.infos:
            model.handle(info, self.player.t0)
        return model

    # ------------------------------------------------------------------ inputs (any thread)
    def put(self, msg: Any, t: float | None = None) -> None:
        self.inbox.put((msg, time.monotonic() if t is None else t))

    def attach(self) -> None:
        """Subscribe to what the page shows (live): statuses through the ground station's
        own feed (decoded once), the rest on its session, each stamped as it arrives."""
        gs = self.gs
        assert gs is not None
        self._statuses = gs.status_feed()
        for topic in (INFO, ALERT, ACK, VOTE, ZONE, MISSION):
            gs.bus.subscribe(topic, lambda m, k: self.put(m))
        gs.bus.watch_alive(lambda node, alive: self.put(Alive(node, alive)))
        threading.Thread(target=self._resync, name="map-resync", daemon=True).start()

    def _resync(self) -> None:
        """The zones and missions the vehicles hold (declared before the map started):
        their queryables, now and every RESYNC_S."""
        gs = self.gs
        assert gs is not None
        while not self.stop.is_set():
            try:
                for zones in gs.all_zones(2.0).values():
                    for z in zones.values():
                        self.put(z)
                for missions in gs.missions_held(2.0).values():
                    for m in missions.values():
                        self.put(m)
            except Exception as exc:  # a closed session at exit
                log.debug("resync: %s", exc)
            if self.stop.wait(RESYNC_S):
                return

    # ------------------------------------------------------------------ the pump
    def fold(self) -> None:
        """Everything heard since the last tick into the model, and the plans it asks."""
        now = self.now()
        if self.player is not None:
            for s in self.player.advance(time.monotonic()):
                self.model.handle(s, s.time_unix_s)
        if self._statuses is not None:
            t = time.monotonic()
            while True:
                try:
                    s = self._statuses.get_nowait()
                except queue.Empty:
                    break
                self._plan(self.model.handle(s, t))
        while True:
            try:
                msg, t = self.inbox.get_nowait()
            except queue.Empty:
                break
            self._plan(self.model.handle(msg, t if self.player is None else now))
        self._plan(self.model.on_timer(now))

    def _plan(self, jobs: list[PlanJob]) -> None:
        for job in jobs:
            self.planning.submit(self._run_plan, job)

    def _run_plan(self, job: PlanJob) -> None:
        try:
            shares = plan_shares(job, self.config.db_path)
            self.put(PlanDone(job.mission.mission_id, job.members, shares))
        except Exception as exc:  # planning or the database: the map goes on without
            text = " ".join(str(exc).split()) or type(exc).__name__
            self.put(PlanDone(job.mission.mission_id, job.members, error=f"no shares: {text}"))

    async def pump(self) -> None:
        while not self.stop.is_set():
            try:
                self.fold()
            except Exception:  # a bug in the fold must not freeze every page
                log.exception("map: folding what was heard failed")
            for page in list(self.pages.values()):
                page.wake.set()
            await asyncio.sleep(FRAME_S)

    def frame_for(self, cursor: int) -> tuple[bytes, int]:
        frame, cursor = self.model.frame(cursor, self.now())
        frame["epoch"] = self.epoch
        if self.player is not None:
            frame["replay"] = self.player.state()
        return msgspec.json.encode(frame), cursor

    # ------------------------------------------------------------------ requests
    def token_ok(self, token: Any) -> bool:
        return isinstance(token, str) and hmac.compare_digest(
            token.encode(), self.config.token.encode()
        )

    def view_ok(self, request: web.Request) -> bool:
        return is_loopback(self.config.host) or self.token_ok(request.query.get("token"))

    async def answer(self, body: Any) -> dict[str, Any]:
        """A request from the page: {op, token, req}; the answer to show."""
        if not isinstance(body, dict):
            return {"ok": False, "error": "a request is a JSON object"}
        op = body.get("op")
        if not self.token_ok(body.get("token")):
            return {"ok": False, "error": "refused: no token, or not this map's (see its URL)"}
        if op == "replay":
            return self._replay(body.get("req"))
        if op == "dismiss":  # the ground station's own list: nothing sent
            try:
                vid = self.model.dismiss(dismissal(body.get("req")), self.now())
            except (PageError, NotLostError) as exc:
                return {"ok": False, "error": str(exc)}
            return {"ok": True, "dismissed": vid}
        if op not in ("check", "send"):
            return {"ok": False, "error": f"unknown op {op!r}: check, send, replay, dismiss"}
        if self.gs is None:
            return {"ok": False, "error": "a replay sends no commands"}
        loop = asyncio.get_running_loop()
        known = set(self.model.known_ids()) | set(self.gs.database_ids or ())
        zone_ids = set(self.model.zones)
        try:
            p: Prepared = await loop.run_in_executor(
                self.sending,
                lambda: prepare(
                    body.get("req"),
                    gcs_id=self.config.gcs_id,
                    known=known,
                    zone_ids=zone_ids,
                    db_path=self.config.db_path,
                ),
            )
        except PageError as exc:
            return {"ok": False, "error": str(exc)}
        alive = {k.vehicle_id: k.fleet_id or 0 for k in self.gs.known() if k.alive}
        q = question(p, alive)
        if op == "check":  # the ids chosen here go with the request as it is confirmed
            return {
                "ok": True,
                "question": q,
                "what": p.what,
                "geometry": geometry_preview(p),
                "fixed": p.fixed,
            }
        cid = next(self.cids)
        self.put(CommandSent(cid, p.what, q))
        loop.run_in_executor(self.sending, self._send, cid, p)
        return {"ok": True, "cid": cid, "question": q}

    def _send(self, cid: int, p: Prepared) -> None:
        told = False

        def progress(ex: Exchange, now: float) -> None:
            nonlocal told
            if not told:
                r = ex.request
                self.put(CommandRef(cid, r.ref, r.ref_id, r.issuer_id))
                told = True

        assert self.gs is not None
        try:
            out = send(self.gs, p, progress)
        except Exception as exc:  # a closed session, a message the wire refuses
            self.put(CommandFailed(cid, " ".join(str(exc).split()) or type(exc).__name__))
            return
        self.put(CommandDone(cid, outcome_json(out), summary(out)))

    def _replay(self, req: Any) -> dict[str, Any]:
        player = self.player
        if player is None:
            return {"ok": False, "error": "not a replay"}
        if not isinstance(req, dict):
            return {"ok": False, "error": "a replay control is {action, ...}"}
        action = req.get("action")
        try:
            match action:
                case "play":
                    if player.t >= player.t1:
                        self._seek(player.t0)
                    player.playing = True
                case "pause":
                    player.playing = False
                case "speed":
                    player.set_speed(float(req.get("speed", "")))
                case "seek":
                    t = float(req.get("t", ""))
                    if t != t:  # NaN
                        raise ValueError("t is not a number")
                    self._seek(t)
                case _:
                    return {"ok": False, "error": f"unknown action {action!r}"}
        except (TypeError, ValueError) as exc:
            return {"ok": False, "error": f"replay {action}: {exc}"}
        return {"ok": True, "replay": player.state()}

    def _seek(self, t: float) -> None:
        """A new map from the samples of the trail window before `t`."""
        assert self.player is not None
        samples = self.player.seek(t, self.config.trail_s)
        self.model = self._new_model()
        for s in samples:
            self.model.handle(s, s.time_unix_s)
        self.epoch += 1
        for page in self.pages.values():
            page.cursor = 0
            page.wake.set()

    def close(self) -> None:
        self.stop.set()
        self.sending.shutdown(wait=False, cancel_futures=True)
        self.planning.shutdown(wait=False, cancel_futures=True)


class _Page:
    """One page's WebSocket: its cursor and a sender that never queues frames (a slow
    page skips ticks; the next frame carries everything since its cursor)."""

    def __init__(self, ws: web.WebSocketResponse) -> None:
        self.ws = ws
        self.cursor = 0
        self.wake = asyncio.Event()

    async def run(self, hub: Hub) -> None:
        while not self.ws.closed:
            await self.wake.wait()
            self.wake.clear()
            data, cursor = hub.frame_for(self.cursor)
            try:
                await self.ws.send_bytes(data)
            except (ConnectionError, RuntimeError):
                return
            self.cursor = cursor
            hub.frames_sent += 1


def plan_shares(job: PlanJob, db_path: Path | None) -> dict[int, list[tuple[float, float]]]:
    """Each member's share of a mission, planned as the members plan it (the nodes'
    planner, their database profiles, homes and plan batteries, the zones)."""
    from swarm_node.core.mission.share import Member, plan_fleet
    from swarm_node.database import SwarmDatabase
    from swarm_node.database.paths import resolve_db_path

    with SwarmDatabase.open(resolve_db_path(db_path)) as db:
        members = [
            Member(db.vehicle_profile(v), job.homes.get(v), job.battery_pct.get(v))
            for v in job.members
        ]
    first = next(iter(job.homes.values()), None)
    plan = plan_fleet(
        job.mission,
        members,
        list(job.zones),
        job.mission.time_unix_s or time.time(),
        first.alt_msl_m if first else 0.0,
    )
    return {
        vid: [(w.lat_deg, w.lon_deg) for w in share.waypoints if w.lat_deg or w.lon_deg]
        for vid, share in plan.shares.items()
    }


def replay_infos(ids: list[int], db_path: Path | None) -> list[VehicleInfo]:
    """The vehicles of a replay as the swarm database describes them (their icons);
    none when the database cannot be read."""
    from swarm_node.database import SwarmDatabase
    from swarm_node.database.errors import SwarmDbError
    from swarm_node.database.paths import resolve_db_path

    try:
        with SwarmDatabase.open(resolve_db_path(db_path)) as db:
            profiles = {p.vehicle_id: p for p in db.profiles()}
    except (SwarmDbError, OSError):
        return []
    return [
        VehicleInfo(v, p.vehicle_type, p.model[:48], p.user_id[:48])
        for v in ids
        if (p := profiles.get(v)) is not None and p.vehicle_type != VehicleType.GCS
    ]


# ----------------------------------------------------------------------------- the app


def csp(tiles: str | None) -> str:
    img = "'self' data:"
    if tiles:
        u = urlsplit(tiles.replace("{s}", "a"))
        host = (u.hostname or "").replace("a.", "*.", 1) if "{s}" in tiles else u.hostname
        img += f" {u.scheme}://{host}" + (f":{u.port}" if u.port else "")
    return (
        "default-src 'self'; "
        f"img-src {img}; "
        "style-src 'self' 'unsafe-inline'; "
        "connect-src 'self'; "
        "frame-ancestors 'none'"
    )


PUMP = web.AppKey("pump", asyncio.Task)


def make_app(hub: Hub) -> web.Application:
    app = web.Application(client_max_size=MAX_REQUEST_BYTES)
    policy = csp(hub.config.tiles)

    async def index(request: web.Request) -> web.StreamResponse:
        if not hub.view_ok(request):
            raise web.HTTPForbidden(text="this map needs its token: open the URL `gcs map` printed")
        return web.FileResponse(
            STATIC / "index.html",
            headers={"Cache-Control": "no-store", "Content-Security-Policy": policy},
        )

    async def config(request: web.Request) -> web.Response:
        if not hub.view_ok(request):
            raise web.HTTPForbidden(text="needs the token")
        return web.json_response(
            {
                "mode": "replay" if hub.player else "live",
                "tiles": hub.config.tiles,
                "swarm": hub.config.swarm,
                "gcs_id": hub.config.gcs_id,
                "commands": hub.gs is not None,
                "trail_s": hub.config.trail_s,
            }
        )

    async def websocket(request: web.Request) -> web.StreamResponse:
        if not hub.view_ok(request):
            raise web.HTTPForbidden(text="needs the token")
        origin = request.headers.get("Origin")
        if origin is not None and urlsplit(origin).netloc != request.host:
            raise web.HTTPForbidden(text=f"a page from {origin} may not open this map")
        ws = web.WebSocketResponse(heartbeat=20.0, max_msg_size=MAX_REQUEST_BYTES)
        await ws.prepare(request)
        page = _Page(ws)
        hub.pages[ws] = page
        page.wake.set()
        sender = asyncio.create_task(page.run(hub))
        try:
            async for msg in ws:
                if msg.type != WSMsgType.TEXT:
                    continue
                try:
                    body = msgspec.json.decode(msg.data)
                except msgspec.DecodeError:
                    await ws.send_json({"op": "answer", "ok": False, "error": "not JSON"})
                    continue
                out = await hub.answer(body)
                rid = body.get("rid") if isinstance(body, dict) else None
                await ws.send_json({"op": "answer", "rid": rid, **out})
        finally:
            hub.pages.pop(ws, None)
            page.wake.set()
            sender.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await sender
        return ws

    async def api(request: web.Request) -> web.Response:
        if request.content_type != "application/json":
            raise web.HTTPUnsupportedMediaType(text="send JSON (application/json)")
        try:
            body = msgspec.json.decode(await request.read())
        except msgspec.DecodeError:
            return web.json_response({"ok": False, "error": "not JSON"}, status=400)
        if isinstance(body, dict):
            body.setdefault("op", request.match_info["op"])
            if "token" not in body:
                body["token"] = request.headers.get("X-Bandada-Token")
        out = await hub.answer(body)
        status = 200 if out.get("ok") else (403 if "token" in out.get("error", "") else 400)
        return web.json_response(out, status=status)

    app.router.add_get("/", index)
    app.router.add_get("/config", config)
    app.router.add_get("/ws", websocket)
    app.router.add_post("/api/{op}", api)
    app.router.add_static("/static/", STATIC)
    app.router.add_static("/leaflet/", leaflet_dir())

    async def start_pump(app: web.Application) -> None:
        app[PUMP] = asyncio.create_task(hub.pump())

    async def stop_pump(app: web.Application) -> None:
        hub.stop.set()
        app[PUMP].cancel()
        with contextlib.suppress(asyncio.CancelledError):
            await app[PUMP]
        for ws in list(hub.pages):
            await ws.close()

    app.on_startup.append(start_pump)
    app.on_shutdown.append(stop_pump)
    return app


async def serve(hub: Hub, ready: Callable[[str], None], stopped: asyncio.Event) -> None:
    """Serve until `stopped` is set; `ready(url)` once listening (the port the kernel
    gave when the config asked for 0)."""
    app = make_app(hub)
    runner = web.AppRunner(app, handle_signals=False, access_log=None)
    await runner.setup()
    try:
        site = web.TCPSite(runner, hub.config.host, hub.config.port)
        await site.start()
        bound = [a for a in runner.addresses if isinstance(a, tuple)]
        port = bound[0][1] if bound else hub.config.port
        host = hub.config.host
        shown = f"[{host}]" if ":" in host else host
        ready(f"http://{shown}:{port}/?token={hub.config.token}")
        await stopped.wait()
    finally:
        await runner.cleanup()
