"""Swarm manager, membership half (paper section 2.3.3): who is in the swarm.

A peer joins when its liveliness token appears or when its first telemetry arrives
(peers behind the radio have no liveliness, only telemetry relayed by the gateway).
It leaves when its liveliness token is withdrawn, or when nothing has been heard from
it for `stale_after_s` (a frozen process loses its token only after the Zenoh lease;
a radio peer only goes silent). A peer that sends no VehicleStatus, only its 1 Hz
VehicleInfo (a ground station), is given `info_stale_after_s` instead: over the radio
info is the lowest class, so two seconds would be two missed updates. Pure: events and
`now` in, PeerJoined/PeerLeft out.

**Behind the radio** (once a peer's status comes as a gateway's prediction:
`predicted_s` or `position_error_m` set) a status peer goes stale after
`radio_stale_after_s` (4 s), not 2 s: its gateway republishes it at 5 Hz, predicted,
as long as the radio hears it (3 s at most unheard, 5 s at most without a status: then
it stops), so a gap here is one of the gateway's own (descheduled, or a status path
hiccup: a `--radio` run at load 17 lost vehicle 5 at every node at once for 0.4 s
while every slot table kept it, and the replan that followed broke the fleet up).

**Our feed's silence is no evidence** (`feed_quiet_s`, `feed_outage_s`): when every
peer known by telemetry (two or more; each is heard at 5 Hz, radio peers as their
gateway's predictions) has been silent for over `feed_quiet_s`, what stopped is our own
feed (our radio gateway descheduled on a loaded host, the channel down), not all of
them at once: none goes stale until the silence reaches `feed_outage_s`, and when one
is heard again every one gets a fresh `stale_after_s`. A `swarm-sim demo --radio` at
load 10-20 replanned three times at launch, "the fleet changed", for such gaps. A single
telemetry peer's silence is taken at its word, as a LAN peer's withdrawn token is.

Cost per event does not grow with the swarm: the peers that can go stale
(present, no liveliness token) are kept in two lists, one per staleness rule, least
recently heard first. Hearing a peer moves it to the end of its list; the next deadline
is the first peer of each list; the timer looks only at peers whose time has come
(`visits` counts the peers examined, for the scaling test).
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Sequence
from dataclasses import dataclass, field

from swarm_proto import FsmState, GeoPoint, VehicleInfo, VehicleStatus, VehicleType


@dataclass(frozen=True)
class PeerJoined:
    node_id: int
    how: str  # "liveliness" | "telemetry"


@dataclass(frozen=True)
class PeerLeft:
    node_id: int
    why: str  # "liveliness" | "stale"


PeerEvent = PeerJoined | PeerLeft


@dataclass
class Peer:
    node_id: int
    present: bool = False
    alive_token: bool = False
    last_heard_s: float = float("-inf")
    status: VehicleStatus | None = None
    info: VehicleInfo | None = None

    @property
    def vehicle_type(self) -> VehicleType:
        return self.info.vehicle_type if self.info else VehicleType.OTHER

    @property
    def is_ground_station(self) -> bool:
        return self.vehicle_type == VehicleType.GCS

    @property
    def fleet_id(self) -> int:
        if self.status is not None:
            return self.status.fleet_id
        return self.info.fleet_id if self.info else 0

    @property
    def fsm_state(self) -> FsmState:
        if self.status is not None:
            return self.status.fsm_state
        return self.info.fsm_state if self.info else FsmState.INACTIVE

    @property
    def mission_id(self) -> int:
        return self.info.mission_id if self.info else 0


@dataclass
class SwarmMembership:
    self_id: int
    stale_after_s: float = 2.0  # a peer that sends VehicleStatus (5 Hz)
    info_stale_after_s: float = 5.0  # a peer that sends only VehicleInfo (1 Hz)
    peers: dict[int, Peer] = field(default_factory=dict)
    # peers that may go stale, least recently heard first: those that send VehicleStatus,
    # and those heard only by their VehicleInfo (the longer rule)
    _watch: OrderedDict[int, Peer] = field(default_factory=OrderedDict, repr=False)
    _watch_info: OrderedDict[int, Peer] = field(default_factory=OrderedDict, repr=False)
    visits: int = 0  # peers examined by the timer and the deadline (not by their own event)
    # behind a radio gateway (a peer's status came as its prediction) a peer that sends
    # VehicleStatus goes stale after this, if longer than `stale_after_s`
    radio_stale_after_s: float = 4.0
    behind_radio: bool = False
    feed_quiet_s: float = 1.0  # every telemetry peer silent this long: our feed stopped
    feed_outage_s: float = 5.0  # ... and is held for up to this long (then they go stale)
    _latest_s: float = field(default=float("-inf"), repr=False)  # latest time any peer was heard
    _since_s: float = field(default=float("-inf"), repr=False)  # our feed came back then

    def _stale_after(self, peer: Peer) -> float:
        status_s = self.stale_after_s
        if self.behind_radio:
            status_s = max(status_s, self.radio_stale_after_s)
        if peer.status is None:
            return max(status_s, self.info_stale_after_s)
        return status_s

    # ------------------------------------------------------------------ inputs
    def on_alive(self, node_id: int, alive: bool, now: float) -> list[PeerEvent]:
        if node_id == self.self_id:
            return []
        peer = self.peers.get(node_id)
        if peer is None:
            peer = self.peers[node_id] = Peer(node_id)
        peer.alive_token = alive
        if alive:
            peer.last_heard_s = now
            out = self._join(peer, "liveliness")
        else:
            out = self._leave(peer, "liveliness")
        self._rewatch(peer)
        return out

    def on_status(self, msg: VehicleStatus, now: float) -> list[PeerEvent]:
        if self.heard_again((msg,), now):
            return []
        return self._heard(msg.vehicle_id, now, status=msg)

    def heard_again(self, msgs: Sequence[VehicleStatus | VehicleInfo], now: float) -> int:
        """The usual event (5 Hz per peer), what `on_status` and `on_info` do for it, for
        a run of statuses and infos at once: each from a known peer heard again, kept by
        its liveliness token (a LAN: never stale, not watched), or by telemetry, last in
        the staleness list. Returns how many of `msgs` (from the first) were such; the
        first that is not is left to `on_status` or `on_info` (what both do first for
        every message, noting our feed heard and a gateway's prediction, is idempotent)."""
        peers = self.peers
        for k, msg in enumerate(msgs):
            vid = msg.vehicle_id
            peer = peers.get(vid)
            if peer is None or not peer.alive_token:
                self._feed_heard(now)
            if (
                isinstance(msg, VehicleStatus)
                and not self.behind_radio
                and (msg.predicted_s > 0.0 or msg.position_error_m > 0.0)
            ):
                self.behind_radio = True  # a gateway's prediction: our peers are radio peers
            if peer is None or not peer.present:
                return k
            if isinstance(msg, VehicleStatus):
                if peer.status is None:
                    return k
                if not peer.alive_token:
                    watch = self._watch
                    if not (now >= self._latest_s and vid in watch):
                        return k
                    self._latest_s = now
                    watch.move_to_end(vid)  # the most recently heard of all
                if now > peer.last_heard_s:
                    peer.last_heard_s = now
                peer.status = msg
                continue
            if not peer.alive_token:
                watch = self._watch if peer.status is not None else self._watch_info
                if not (now >= self._latest_s and vid in watch):
                    return k
                self._latest_s = now
                watch.move_to_end(vid)
            if now > peer.last_heard_s:
                peer.last_heard_s = now
            peer.info = msg
        return len(msgs)

    def on_info(self, msg: VehicleInfo, now: float) -> list[PeerEvent]:
        peer = self.peers.get(msg.vehicle_id)
        if peer is None or not peer.alive_token:
            self._feed_heard(now)
        return self._heard(msg.vehicle_id, now, info=msg)

    def on_timer(self, now: float) -> list[PeerEvent]:
        out: list[PeerEvent] = []
        if self._feed_out(now):
            return out  # our feed stopped: no evidence against anyone (module docstring)
        for watch in (self._watch, self._watch_info):
            while watch:
                peer = next(iter(watch.values()))
                self.visits += 1
                if now - max(peer.last_heard_s, self._since_s) < self._stale_after(peer):
                    break  # the least recently heard is not stale: nor is anyone after it
                out += self._leave(peer, "stale")
                self._rewatch(peer)
        return out

    def next_deadline(self) -> float | None:
        if not self._watch and not self._watch_info:
            return None  # (a LAN swarm: every peer kept by its token)
        times = []
        for watch in (self._watch, self._watch_info):
            if watch:
                peer = next(iter(watch.values()))
                self.visits += 1
                times.append(max(peer.last_heard_s, self._since_s) + self._stale_after(peer))
        if not times:
            return None
        first = min(times)
        newest = self._newest()
        if newest is not None and newest + self.feed_quiet_s < first < newest + self.feed_outage_s:
            return newest + self.feed_outage_s  # held until then, unless one is heard
        return first

    # ------------------------------------------------------------------ our feed
    def _newest(self) -> float | None:
        """When the most recently heard telemetry peer was heard (None: fewer than two)."""
        if len(self._watch) < 2:
            return None
        return next(reversed(self._watch.values())).last_heard_s

    def _feed_out(self, now: float) -> bool:
        """Every telemetry peer (two or more) silent for over `feed_quiet_s`, not yet
        `feed_outage_s`: our feed stopped, their silence tells nothing."""
        newest = self._newest()
        return newest is not None and self.feed_quiet_s < now - newest < self.feed_outage_s

    def _feed_heard(self, now: float) -> None:
        """A telemetry peer heard: if every one had gone quiet, each gets a fresh
        `stale_after_s` from now (the others may follow a moment later)."""
        newest = self._newest()
        if newest is not None and now - newest > self.feed_quiet_s:
            self._since_s = max(self._since_s, now)

    # ------------------------------------------------------------------ views
    def live(self) -> list[Peer]:
        return sorted((p for p in self.peers.values() if p.present), key=lambda p: p.node_id)

    def live_ids(self) -> list[int]:
        return [p.node_id for p in self.live()]

    def vehicles(self) -> list[Peer]:
        return [p for p in self.live() if not p.is_ground_station]

    def fleet(self, fleet_id: int) -> list[Peer]:
        return [p for p in self.vehicles() if fleet_id and p.fleet_id == fleet_id]

    def statuses_and_homes(self) -> list[tuple[VehicleStatus, GeoPoint | None]]:
        """The live peers' latest statuses with their homes (the pad rules')."""
        return [
            (p.status, p.info.home if p.info else None)
            for p in self.peers.values()
            if p.present and p.status is not None
        ]

    def homes(self) -> dict[int, GeoPoint]:
        """Every known peer's home (VehicleInfo): their pads."""
        return {v: p.info.home for v, p in self.peers.items() if p.info and p.info.home}

    def types(self) -> dict[int, VehicleType]:
        """Every known peer's vehicle type (VehicleInfo)."""
        return {v: p.info.vehicle_type for v, p in self.peers.items() if p.info}

    # ------------------------------------------------------------------ internals
    def _heard(
        self,
        node_id: int,
        now: float,
        *,
        status: VehicleStatus | None = None,
        info: VehicleInfo | None = None,
    ) -> list[PeerEvent]:
        peer = self.peers.get(node_id)
        if peer is None:
            if node_id == self.self_id:
                return []
            peer = self.peers[node_id] = Peer(node_id)
        if now > peer.last_heard_s:
            peer.last_heard_s = now
        had_status = peer.status is not None
        if status is not None:
            peer.status = status
        elif info is not None:
            peer.info = info
        if peer.present:  # the usual event, O(1): a peer we know, heard again
            if peer.alive_token:
                return []  # its liveliness token keeps it: never stale, not watched
            watch = self._watch if had_status else self._watch_info
            if (had_status or status is None) and now >= self._latest_s and node_id in watch:
                self._latest_s = now
                watch.move_to_end(node_id)  # the most recently heard of all
                return []
        out = self._join(peer, "telemetry")
        self._rewatch(peer)
        return out

    def _rewatch(self, peer: Peer) -> None:
        """Put the peer at its place in the staleness lists (or out of them): O(1) when
        it was heard last, which is every event in time order."""
        nid = peer.node_id
        self._watch.pop(nid, None)
        self._watch_info.pop(nid, None)
        if not peer.present or peer.alive_token:
            return
        watch = self._watch_info if peer.status is None else self._watch
        self._latest_s = max(self._latest_s, peer.last_heard_s)
        if watch and peer.last_heard_s < next(reversed(watch.values())).last_heard_s:
            # heard earlier than the last one in the list (time went backwards): sorted
            # in, O(n)
            items = sorted([*watch.values(), peer], key=lambda p: p.last_heard_s)
            watch.clear()
            watch.update((p.node_id, p) for p in items)
            return
        watch[nid] = peer

    def _join(self, peer: Peer, how: str) -> list[PeerEvent]:
        if peer.present:
            return []
        peer.present = True
        return [PeerJoined(peer.node_id, how)]

    def _leave(self, peer: Peer, why: str) -> list[PeerEvent]:
        if not peer.present:
            return []
        peer.present = False
        peer.alive_token = False
        return [PeerLeft(peer.node_id, why)]
