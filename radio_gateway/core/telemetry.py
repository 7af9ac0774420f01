"""Send on error in the gateway (pure): a vehicle's gateway runs, of its own vehicle, the
dead reckoning every peer's gateway runs of it, puts a status on air only when the
peers' prediction would be off, and every peer's gateway republishes the prediction on
its LAN so the nodes above see radio peers as they see LAN peers, at 5 Hz.

    own = OwnTelemetry(SendOnErrorConfig())                    # sender (the vehicle's gateway)
    own.update(status, now)                                    # every VehicleStatus of its node
    c = own.candidate(now, horizon_s)                          # at frame build: due?
    if c is not None and <it went into the frame>: own.sent(c, now)

    peers = PeerPredictor(PredictConfig())                     # receiver (every gateway)
    peers.on_status(status, turn_rate, now)                    # a status heard on air
    for s in peers.due(now, alive): publish(s)                 # predictions, 5 Hz per peer

**The model** (`deadreckon.predict`): position, velocity, a constant turn rate about the
vertical and a constant climb rate: a coordinated turn. It is exact on a straight leg
and on a fixed-wing orbit (the two things a plane does for long), and the turn rate is
what makes an orbit predictable at all: a straight-line model of a 60 m orbit is 20 m
off after a second. The turn rate is estimated by the sender from its own statuses (the
rotation of the velocity over the last ~0.4 s) and travels in two bytes after the 40-byte
status (`TURN_TRAILER`: int16, 1e-4 rad/s, counter-clockwise from above positive), which
every radio decoder ignores (docs/radio-encoding.md).

**When the sender transmits** (`OwnTelemetry.candidate`), at each transmit opportunity:
the first status; a change of a discrete field (armed, FSM state, mission state, mode,
fleet, alerts); the peers' prediction from the last status sent being, or going to be
before the next opportunity (`horizon_s`: the next own slot plus delivery), more than
`threshold_m` from the vehicle's own state carried forward by the same model; once
more at the next opportunity after such an error-triggered send (`repeat`: one lost
frame does not leave a peer on the old manoeuvre); or `heartbeat_s` since the last send.

**What a receiver publishes**: the status heard, as heard, at once; then every
`1 / republish_hz` the status predicted to `now`: `time_unix_s = now`, position, velocity
and heading carried forward, `predicted_s` the horizon, `position_error_m` the bound

    bound = min(max_accel * age^2, (max_speed + speed) * age)

(truth and prediction leave the same state at `t`; each accelerates within `max_accel`,
so they part by at most `max_accel * age^2`, whatever was lost; neither can be further
apart than both their travels). It stops predicting a peer `predict_max_s` after its
last status, or as soon as the radio has not heard the peer for `silent_s` (`alive`):
then the node's own membership sees it go stale as it would on the LAN. A status heard
again unchanged (a vehicle whose autopilot link is down repeats its last one) keeps the
peer predicted, its bound growing with the age of the data.
"""

from __future__ import annotations

import math
import struct
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field

import msgspec

from swarm_proto import AlertFlag, VehicleStatus

from .deadreckon import Kinematics, predict

TURN_TRAILER = struct.Struct("<h")
TURN_RES = 1e-4  # rad/s per unit: +-3.27 rad/s
TURN_MAX = 32767 * TURN_RES
AVOIDING = AlertFlag.COLLISION_RISK

_A = 6_378_137.0  # WGS84
_E2 = 6.694_379_990_14e-3


def metres_per_rad(lat_deg: float, alt_m: float = 0.0) -> tuple[float, float]:
    """Metres per radian of latitude (north) and of longitude (east) at `lat_deg`, on
    the WGS84 ellipsoid (meridian and prime-vertical radii of curvature)."""
    s = math.sin(math.radians(lat_deg))
    w = 1.0 - _E2 * s * s
    m = _A * (1.0 - _E2) / (w * math.sqrt(w)) + alt_m
    n = _A / math.sqrt(w) + alt_m
    return m, n * math.cos(math.radians(lat_deg))


def kinematics(s: VehicleStatus, turn_rate: float, origin: tuple[float, float]) -> Kinematics:
    """A status as a dead-reckoning state in the local east-north-up plane tangent at
    `origin` (lat, lon degrees): exact to ~1e-6 of the distance within a few km."""
    mn, me = metres_per_rad(origin[0], s.alt_msl_m)
    return Kinematics(
        s.time_unix_s,
        math.radians(s.lon_deg - origin[1]) * me,
        math.radians(s.lat_deg - origin[0]) * mn,
        s.alt_msl_m,
        s.vel_east_m_s,
        s.vel_north_m_s,
        -s.vel_down_m_s,
        turn_rate,
    )


def carried(s: VehicleStatus, turn_rate: float, t: float) -> tuple[VehicleStatus, float]:
    """The status carried forward to `t` by the model (position, altitudes, velocity,
    heading; everything else as it was), and the distance it moved."""
    k0 = kinematics(s, turn_rate, (s.lat_deg, s.lon_deg))
    k = predict(k0, t)
    mn, me = metres_per_rad(s.lat_deg, s.alt_msl_m)
    dz = k.z - k0.z
    lat = min(90.0, max(-90.0, s.lat_deg + math.degrees(k.y / mn)))
    lon = (s.lon_deg + math.degrees(k.x / me) + 180.0) % 360.0 - 180.0
    rotated = math.degrees(turn_rate * (t - s.time_unix_s))
    out = msgspec.structs.replace(
        s,
        time_unix_s=max(0.0, t),
        lat_deg=lat,
        lon_deg=lon,
        alt_msl_m=_clamp(s.alt_msl_m + dz, -1000.0, 8000.0),
        alt_rel_m=_clamp(s.alt_rel_m + dz, -1000.0, 8000.0),
        vel_north_m_s=_clamp(k.vy, -300.0, 300.0),
        vel_east_m_s=_clamp(k.vx, -300.0, 300.0),
        heading_deg=(s.heading_deg - rotated) % 360.0 % 360.0,
    )
    return out, math.hypot(k.x, k.y, dz)


def _clamp(x: float, lo: float, hi: float) -> float:
    return lo if x < lo else hi if x > hi else x


def encode_turn(turn_rate: float) -> bytes:
    return TURN_TRAILER.pack(round(_clamp(turn_rate, -TURN_MAX, TURN_MAX) / TURN_RES))


def decode_turn(radio_status: bytes, status_bytes: int = 40) -> float:
    """The turn rate after a radio status (0 if the sender appended none)."""
    if len(radio_status) < status_bytes + TURN_TRAILER.size:
        return 0.0
    return float(TURN_TRAILER.unpack_from(radio_status, status_bytes)[0]) * TURN_RES


def _discrete(s: VehicleStatus) -> tuple[object, ...]:
    return (s.armed, s.fsm_state, s.mission_state, s.ap_mode, s.fleet_id, s.alerts)


# ---------------------------------------------------------------------------- sender


@dataclass(frozen=True)
class SendOnErrorConfig:
    threshold_m: float = 5.0
    heartbeat_s: float = 1.0
    repeat: int = 1  # error-triggered sends repeated at the next opportunity
    turn_window_s: float = 0.4  # the turn rate is the velocity's rotation over this
    min_turn_speed_m_s: float = 2.0  # below this the course is noise: no turn rate
    calm_s: float = 10.0  # (manoeuvre_share) level 2 this long after an error outran our slots
    # raise our share when a manoeuvre outran our slots (measured: at the demo's mix the
    # share arrives too late to pay for what it takes from the others; off by default)
    manoeuvre_share: bool = False

    def __post_init__(self) -> None:
        if not (self.threshold_m > 0 and self.heartbeat_s > 0 and self.repeat >= 0):
            raise ValueError("threshold_m and heartbeat_s are > 0, repeat >= 0")


@dataclass(frozen=True)
class Candidate:
    status: VehicleStatus
    turn_rate: float
    data: bytes  # the radio status + turn trailer
    reason: str  # first | changed | error | repeat | heartbeat


@dataclass
class OwnTelemetry:
    """The sender's side: its own vehicle's latest state, and whether to send it."""

    config: SendOnErrorConfig = field(default_factory=SendOnErrorConfig)
    encode: Callable[[VehicleStatus], bytes] | None = None  # swarm_proto.radio.encode
    latest: VehicleStatus | None = None
    turn_rate: float = 0.0
    last_sent: Candidate | None = None
    last_sent_at: float = -math.inf
    last_error_send: float = -math.inf
    last_late: float = -math.inf  # the peers' error was past the threshold when we could send
    repeats_left: int = 0
    counts: dict[str, int] = field(default_factory=dict)
    _history: deque[VehicleStatus] = field(default_factory=lambda: deque(maxlen=32))

    def update(self, s: VehicleStatus, now: float) -> None:
        """The node's own status (from the LAN). Older or repeated samples are ignored."""
        if self.latest is not None and s.time_unix_s < self.latest.time_unix_s:
            return
        self.latest = s
        self._history.append(s)
        self.turn_rate = self._turn_rate(s)

    def _turn_rate(self, s: VehicleStatus) -> float:
        c = self.config
        if s.groundspeed_m_s < c.min_turn_speed_m_s:
            return 0.0
        old = None
        for h in reversed(self._history):
            if s.time_unix_s - h.time_unix_s >= c.turn_window_s:
                old = h
                break
        if old is None or old.groundspeed_m_s < c.min_turn_speed_m_s:
            return 0.0
        dt = s.time_unix_s - old.time_unix_s
        if dt > 4 * c.turn_window_s:
            return 0.0
        a0 = math.atan2(old.vel_north_m_s, old.vel_east_m_s)
        a1 = math.atan2(s.vel_north_m_s, s.vel_east_m_s)
        d = (a1 - a0 + math.pi) % (2 * math.pi) - math.pi
        return _clamp(d / dt, -TURN_MAX, TURN_MAX)

    def error_m(self, t: float) -> float:
        """How far the peers' prediction (from the last status sent) is from our own
        state, both carried forward to `t` (inf before anything was sent)."""
        if self.last_sent is None or self.latest is None:
            return math.inf
        origin = (self.latest.lat_deg, self.latest.lon_deg)
        a = kinematics(self.last_sent.status, self.last_sent.turn_rate, origin)
        b = kinematics(self.latest, self.turn_rate, origin)
        pa, pb = predict(a, t), predict(b, t)
        return math.dist((pa.x, pa.y, pa.z), (pb.x, pb.y, pb.z))

    def candidate(self, now: float, horizon_s: float) -> Candidate | None:
        """The status to put in the frame being built, if one is due (see the module
        docstring); `horizon_s`: from now until a status sent at the next opportunity
        would reach the peers."""
        s = self.latest
        if s is None:
            return None
        c = self.config
        last = self.last_sent
        if last is None:
            reason = "first"
        elif _discrete(s) != _discrete(last.status):
            reason = "changed"
        elif self._off(now, horizon_s):
            reason = "error"
            if self.error_m(now) > c.threshold_m:
                self.last_late = now  # our slots come too seldom for this manoeuvre
        elif self.repeats_left > 0:
            reason = "repeat"
        elif now - self.last_sent_at >= c.heartbeat_s - 1e-9:
            reason = "heartbeat"
        else:
            return None
        if last is not None and last.status == s and reason not in ("repeat", "heartbeat"):
            # nothing new from the node: only the heartbeat (an autopilot link loss stops
            # its status; the heartbeat still says the vehicle is there)
            return None
        data = (self.encode(s) if self.encode else b"") + encode_turn(self.turn_rate)
        return Candidate(s, self.turn_rate, data, reason)

    def _off(self, now: float, horizon_s: float) -> bool:
        if self.last_sent is None or self.latest is None:
            return True
        origin = (self.latest.lat_deg, self.latest.lon_deg)
        a = kinematics(self.last_sent.status, self.last_sent.turn_rate, origin)
        b = kinematics(self.latest, self.turn_rate, origin)
        steps = max(1, math.ceil(horizon_s / 0.1))
        lim = self.config.threshold_m
        for i in range(steps + 1):
            t = now + horizon_s * i / steps
            pa, pb = predict(a, t), predict(b, t)
            if math.dist((pa.x, pa.y, pa.z), (pb.x, pb.y, pb.z)) > lim:
                return True
        return False

    def sent(self, c: Candidate, now: float) -> None:
        """`c` went out in a frame: the peers now predict from it."""
        self.counts[c.reason] = self.counts.get(c.reason, 0) + 1
        if c.reason == "error":
            self.last_error_send = now
            self.repeats_left = self.config.repeat
        elif c.reason == "repeat":
            self.repeats_left -= 1
        self.last_sent, self.last_sent_at = c, now

    def need_level(self, now: float) -> int:
        """How much air this vehicle needs (the adaptive schedule's level): 2 while it
        avoids a conflict (COLLISION_RISK; with `manoeuvre_share`, also for `calm_s`
        after a manoeuvre outran its slots: when it could send, its peers' prediction
        was already past the threshold); 0 parked (disarmed, or on the ground and still:
        nothing to predict); 1 flying."""
        s = self.latest
        if s is None:
            return 1
        if AVOIDING in s.alerts or (
            self.config.manoeuvre_share and now - self.last_late < self.config.calm_s
        ):
            return 2
        parked = not s.armed or (s.alt_rel_m < 2.0 and s.groundspeed_m_s < 1.0)
        return 0 if parked else 1


# ---------------------------------------------------------------------------- receiver


@dataclass(frozen=True)
class PredictConfig:
    republish_hz: float = 5.0
    max_accel_mps2: float = 6.0  # a fixed-wing at 30 degrees of bank: g tan 30
    max_speed_m_s: float = 35.0  # the fastest a peer could fly
    predict_max_s: float = 5.0  # no status for this long: stop predicting
    silent_s: float = 3.0  # the radio heard nothing of the peer for this long: stop

    def __post_init__(self) -> None:
        if not (self.republish_hz > 0 and self.max_accel_mps2 >= 0 and self.predict_max_s > 0):
            raise ValueError("republish_hz, predict_max_s > 0; max_accel_mps2 >= 0")


def error_bound(age_s: float, speed_m_s: float, config: PredictConfig) -> float:
    """How far a peer can be from its prediction `age_s` after the state it starts from."""
    age = max(0.0, age_s)
    return min(config.max_accel_mps2 * age * age, (config.max_speed_m_s + speed_m_s) * age)


@dataclass
class _Peer:
    status: VehicleStatus
    turn_rate: float
    next_pub: float
    heard_at: float  # a status of it last heard (the same one repeated counts)


@dataclass
class PeerPredictor:
    """A receiver's view of its radio peers: the latest status heard of each, carried
    forward to `now` with its error bound."""

    config: PredictConfig = field(default_factory=PredictConfig)
    peers: dict[int, _Peer] = field(default_factory=dict)
    counts: dict[str, int] = field(default_factory=dict)
    # (vehicle, why) of each peer `due` stopped predicting, for the shell to log and clear
    dropped: list[tuple[int, str]] = field(default_factory=list)
    _next: float | None = None  # cached next_deadline (None: to recompute)
    _stale_next: bool = True

    def on_status(self, s: VehicleStatus, turn_rate: float, now: float) -> bool:
        """A status heard on air; False (ignored) if not newer than the one held."""
        p = self.peers.get(s.vehicle_id)
        if p is not None and s.time_unix_s <= p.status.time_unix_s:
            self.counts["stale"] = self.counts.get("stale", 0) + 1
            p.heard_at = max(p.heard_at, now)  # repeated: the vehicle is there, its data old
            return False
        nxt = now + 1.0 / self.config.republish_hz
        w = turn_rate if math.isfinite(turn_rate) else 0.0
        self.peers[s.vehicle_id] = _Peer(s, w, nxt, now)
        self._stale_next = True
        return True

    def forget(self, vehicle_id: int) -> None:
        if self.peers.pop(vehicle_id, None) is not None:
            self._stale_next = True

    def predicted(self, vehicle_id: int, now: float) -> VehicleStatus | None:
        """The peer's status carried forward to `now`, with `position_error_m` and
        `predicted_s` set (None: never heard)."""
        p = self.peers.get(vehicle_id)
        if p is None:
            return None
        age = max(0.0, now - p.status.time_unix_s)
        out, _ = carried(p.status, p.turn_rate, max(now, p.status.time_unix_s))
        bound = error_bound(age, p.status.groundspeed_m_s, self.config)
        return msgspec.structs.replace(
            out, position_error_m=min(bound, 1.0e6), predicted_s=min(age, 1.0e7)
        )

    def position(self, vehicle_id: int, now: float) -> tuple[float, float, float, float] | None:
        """The peer's predicted (lat, lon, alt_msl, error bound) at `now`: what
        `predicted` says, without building a status (None: never heard)."""
        p = self.peers.get(vehicle_id)
        if p is None:
            return None
        s = p.status
        k0 = kinematics(s, p.turn_rate, (s.lat_deg, s.lon_deg))
        k = predict(k0, max(now, s.time_unix_s))
        mn, me = metres_per_rad(s.lat_deg, s.alt_msl_m)
        bound = error_bound(now - s.time_unix_s, s.groundspeed_m_s, self.config)
        return (
            s.lat_deg + math.degrees(k.y / mn),
            s.lon_deg + math.degrees(k.x / me),
            k.z,
            bound,
        )

    def due(self, now: float, alive: Callable[[int], bool] | None = None) -> list[VehicleStatus]:
        """Predictions to publish now (each peer every 1 / republish_hz); a peer whose
        last status is older than `predict_max_s`, or that `alive` says the radio no
        longer hears, is dropped."""
        out: list[VehicleStatus] = []
        period = 1.0 / self.config.republish_hz
        if self.next_deadline() is None or now < (self._next or math.inf):
            return out
        self._stale_next = True
        for vid in list(self.peers):
            p = self.peers[vid]
            if now < p.next_pub:
                continue
            old = now - p.heard_at > self.config.predict_max_s
            if old or (alive is not None and not alive(vid)):
                del self.peers[vid]
                self.counts["dropped"] = self.counts.get("dropped", 0) + 1
                why = (
                    f"no status heard for {now - p.heard_at:.1f} s"
                    if old
                    else "the radio no longer hears it"
                )
                self.dropped.append((vid, why))
                del self.dropped[:-16]
                continue
            p.next_pub += period
            if p.next_pub <= now:  # late (a busy host): no burst of catch-up predictions
                p.next_pub = now + period
            s = self.predicted(vid, now)
            if s is not None:
                out.append(s)
                self.counts["published"] = self.counts.get("published", 0) + 1
        return out

    def next_deadline(self) -> float | None:
        if self._stale_next:
            self._next = min((p.next_pub for p in self.peers.values()), default=None)
            self._stale_next = False
        return self._next
