"""Who speaks in a vehicle's name (pure): the sources of the vehicles' telemetry and of
the holder tokens, checked at the node's input boundary before any logic sees them.

A source (swarm_proto.intake.Source) is what a sample's attachment says: a Zenoh
session (its id, and the MAVLink system id of its autopilot), the radio (a gateway
relaying from the air), or a foreign publisher (no bandada attachment). Each vehicle
node also holds the liveliness token `id/<its id>/<its session id>` (HOLDER).

**This vehicle.** Anything in its own name heard from another session (the shell
subscribes to its own status and info keys for remote samples only, so its own
publications are never among them), and any holder token of its id from another
session, is a conflict: `IdentityNews.conflict` names the other source, and the
node's monitoring raises a CRITICAL IDENTITY_CONFLICT and refuses missions while it
lasts. A radio relay of its own telemetry is not a conflict, unless the relayed
VehicleInfo names another MAVLink system id. The conflict ends `clear_after_s` after
the other source was last heard (and its token is gone): stopping the other node, or
giving it its own id, resolves it.

**Other vehicles.** A vehicle heard from two sessions (or a session and a foreign
publisher), from two MAVLink system ids, held by two sessions, or reporting a conflict
itself (the IDENTITY_CONFLICT bit of its status) is untrusted until none of that has
been true for `clear_after_s`: `IdentityNews.untrusted` (the roster keeps it out of
voting and planning; the peers queryable and `gcs status` show it). While it is
untrusted only the source first heard (the incumbent) is passed on, so the node keeps
one consistent track of it; the others are dropped (counted as `identity`). Radio
relays are one source, compatible with any session (a ground gateway relays vehicles
that are on the LAN too). Ground stations (VehicleInfo of type GCS) are exempt: every
`gcs` command is a process of its own with the same id.

**Liveliness.** A holder token alone makes nobody alive: `HolderAlive(id, True)` is
said once a session holding the id has been heard by its telemetry too, and
`HolderAlive(id, False)` when no such session holds it any more. Foreign `alive/<id>`
tokens are not read by nodes at all (Zenoh 1.10 merges the tokens on one key, so a
duplicate one cannot be seen; docs/security.md).

    book.heard(vehicle_id, source, now, ...) -> (keep, outputs)
    book.heard_own(source, now, sysid=...)   -> outputs
    book.holder(node_id, zid, alive, now)    -> outputs
    book.on_timer(now) -> outputs;  book.next_deadline() -> float | None
"""

from __future__ import annotations

from dataclasses import dataclass, field

from swarm_proto.intake import Source

CLEAR_AFTER_S = 10.0  # a conflict ends when its other source has been silent this long
MAX_SOURCES = 8  # sources remembered per vehicle (the oldest is forgotten)
CHECK_PERIOD_S = 1.0  # how often conflicts are checked for clearing


@dataclass(frozen=True)
class IdentityNews:
    """For the node core: this vehicle's conflict ("": none) and the untrusted peers."""

    conflict: str
    untrusted: frozenset[int]


@dataclass(frozen=True)
class HolderAlive:
    """A vehicle held by a session it was heard from appeared (or the last went)."""

    node_id: int
    alive: bool


Output = IdentityNews | HolderAlive


@dataclass
class _Seen:
    last_s: float
    what: str  # Source.describe()
    sysids: dict[int, float] = field(default_factory=dict)  # MAVLink system id: last heard


@dataclass
class _Track:
    sources: dict[str, _Seen] = field(default_factory=dict)  # by Source.key
    incumbent: str = ""
    holders: set[str] = field(default_factory=set)  # session ids holding the id now
    alive_said: bool = False
    reports_conflict_s: float = float("-inf")  # it last said it has a conflict
    ground: bool = False
    why: str = ""  # untrusted: why ("" trusted)


@dataclass
class IdentityBook:
    self_id: int
    own_zid: str
    clear_after_s: float = CLEAR_AFTER_S
    own_sysid: int = 0  # this node's autopilot's MAVLink system id (0: not known yet)
    tracks: dict[int, _Track] = field(default_factory=dict)
    #: evidence of another source in our own name: source key -> (last heard, describe)
    _own: dict[str, tuple[float, str]] = field(default_factory=dict)
    _own_holders: set[str] = field(default_factory=set)
    conflict: str = ""
    untrusted: frozenset[int] = frozenset()
    _check_at: float | None = None

    # ------------------------------------------------------------------ peers
    def heard(
        self,
        vehicle_id: int,
        source: Source,
        now: float,
        *,
        sysid: int = 0,
        reports_conflict: bool = False,
        ground: bool = False,
    ) -> tuple[bool, list[Output]]:
        """A peer's status or info from `source` (`sysid`: a VehicleInfo's mav_sysid,
        else the attachment's). Returns whether to pass it on, and news."""
        if vehicle_id == self.self_id:
            return True, []  # our own, echoed by our session (the shell checks the rest)
        track = self.tracks.get(vehicle_id)
        if track is None:
            track = self.tracks[vehicle_id] = _Track(incumbent=source.key)
        track.ground |= ground
        key = source.key
        if not track.incumbent:
            track.incumbent = key
        seen = track.sources.get(key)
        sysid = sysid or source.sysid
        if seen is None:
            others = [k for k in track.sources if k != track.incumbent]
            if len(track.sources) >= MAX_SOURCES and others:
                del track.sources[min(others, key=lambda k: track.sources[k].last_s)]
            seen = track.sources[key] = _Seen(now, source.describe())
        else:
            seen.last_s = max(seen.last_s, now)
        if sysid:
            if sysid not in seen.sysids and len(seen.sysids) >= MAX_SOURCES:
                del seen.sysids[min(seen.sysids, key=seen.sysids.__getitem__)]
            seen.sysids[sysid] = now
        if reports_conflict:
            track.reports_conflict_s = now
        out = self._judge(vehicle_id, track, now)
        out += self._alive(vehicle_id, track)
        keep = not track.why or key == track.incumbent
        return keep, out

    def holder(self, node_id: int, zid: str, alive: bool, now: float) -> list[Output]:
        """A holder token `id/<node_id>/<zid>` appeared or went."""
        if node_id == self.self_id:
            if zid == self.own_zid:
                return []
            if alive:
                self._own_holders.add(zid)
            else:
                self._own_holders.discard(zid)
            return self._own_news(now)
        track = self.tracks.get(node_id)
        if track is None:
            if not alive:
                return []
            track = self.tracks[node_id] = _Track()
        if alive:
            if len(track.holders) < MAX_SOURCES:
                track.holders.add(zid)
        else:
            track.holders.discard(zid)
            # its session is gone (stopped, or restarted with a new one): what it said
            # no longer competes with what comes next
            track.sources.pop(zid, None)
            if track.incumbent == zid:
                track.incumbent = ""
        return self._judge(node_id, track, now) + self._alive(node_id, track)

    # ------------------------------------------------------------------ ourselves
    def heard_own(self, source: Source, now: float, *, sysid: int = 0) -> list[Output]:
        """A status or info in our own name from another session."""
        sysid = sysid or source.sysid
        if source.relay and (not sysid or not self.own_sysid or sysid == self.own_sysid):
            return []  # our own telemetry relayed by a radio gateway
        what = source.describe()
        if source.relay and sysid:
            what = f"{what}, MAVLink {sysid}"
        if len(self._own) < MAX_SOURCES or source.key in self._own:
            self._own[source.key] = (now, what)
        return self._own_news(now)

    def set_own_sysid(self, sysid: int) -> None:
        self.own_sysid = sysid

    def _own_news(self, now: float) -> list[Output]:
        recent = [what for last, what in self._own.values() if now - last <= self.clear_after_s]
        holders = sorted(self._own_holders)
        if recent:
            text = f"id {self.self_id} also used by {recent[0]}"
        elif holders:
            text = f"id {self.self_id} also held by session {holders[0][:8]}"
        else:
            text = ""
        if text == self.conflict:
            return []
        self.conflict = text
        self._schedule(now)
        return [IdentityNews(self.conflict, self.untrusted)]

    # ------------------------------------------------------------------ judging
    def _judge(self, vid: int, track: _Track, now: float) -> list[Output]:
        why = "" if track.ground else self._reason(track, now)
        if why == track.why:
            return []
        was = bool(track.why)
        track.why = why
        if bool(why) == was:
            return []  # still untrusted (another reason) or still trusted
        self.untrusted = (self.untrusted | {vid}) if why else (self.untrusted - {vid})
        self._schedule(now)
        return [IdentityNews(self.conflict, self.untrusted)]

    def _reason(self, track: _Track, now: float) -> str:
        recent = {k: s for k, s in track.sources.items() if now - s.last_s <= self.clear_after_s}
        inc = track.sources.get(track.incumbent)
        if (inc is None or now - inc.last_s > self.clear_after_s) and recent:
            # the trusted source went silent: the one heard last is trusted now
            track.incumbent = max(recent, key=lambda k: recent[k].last_s)
        sessions = sorted(k for k in recent if k != "radio")
        if len(sessions) > 1:
            a, b = (recent[k].what for k in sessions[:2])
            return f"heard from {a} and {b}"
        window = now - self.clear_after_s
        sysids = sorted({i for s in recent.values() for i, t in s.sysids.items() if t >= window})
        if len(sysids) > 1:
            return f"MAVLink system ids {sysids[0]} and {sysids[1]}"
        if len(track.holders) > 1:
            return "held by two sessions"
        if now - track.reports_conflict_s <= self.clear_after_s:
            return "it reports an identity conflict"
        return ""

    def _alive(self, vid: int, track: _Track) -> list[Output]:
        alive = any(zid in track.sources for zid in track.holders)  # held, and heard
        if alive == track.alive_said:
            return []
        track.alive_said = alive
        return [HolderAlive(vid, alive)]

    def why(self, vehicle_id: int) -> str:
        """Why a peer is untrusted ("" trusted)."""
        track = self.tracks.get(vehicle_id)
        return track.why if track is not None else ""

    # ------------------------------------------------------------------ time
    def _schedule(self, now: float) -> None:
        if self.conflict or self.untrusted:
            if self._check_at is None:
                self._check_at = now + CHECK_PERIOD_S
        else:
            self._check_at = None

    def next_deadline(self) -> float | None:
        return self._check_at

    def on_timer(self, now: float) -> list[Output]:
        """Conflicts whose other source has been silent long enough end; sources not
        heard for a long while are forgotten."""
        if self._check_at is None or now < self._check_at:
            return []
        self._check_at = None
        out = []
        for key in [k for k, (last, _) in self._own.items() if now - last > self.clear_after_s]:
            del self._own[key]
        out += self._own_news(now)
        for vid in sorted(self.untrusted):
            track = self.tracks[vid]
            out += self._judge(vid, track, now)
            for key in [
                k
                for k, s in track.sources.items()
                if now - s.last_s > 2 * self.clear_after_s and k != track.incumbent
            ]:
                del track.sources[key]
        # one piece of news is enough: the last says where things stand
        news = [o for o in out if isinstance(o, IdentityNews)]
        out = [o for o in out if not isinstance(o, IdentityNews)]
        if news:
            out.append(IdentityNews(self.conflict, self.untrusted))
        self._check_at = None
        self._schedule(now)
        return out
