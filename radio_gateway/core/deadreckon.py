"""Send on error (pure): every node runs, of itself, the same dead-reckoning model its peers
run of it, and transmits a status only when their prediction would be off by more than a
threshold (default 5 m), or when a heartbeat floor has passed.

The model is a coordinated turn: position, velocity and a constant turn rate about the
vertical (a fixed-wing orbit is a constant turn; a straight leg a zero one), with a
constant climb rate. The peers' prediction of a vehicle is exact while it holds a leg or
an orbit, and drifts only when it changes manoeuvre, which is when it speaks again.

    sender = SendOnError()                       # on the vehicle
    if sender.due(state, now, horizon_s=0.4):    # before each transmit opportunity
        send(encode_kinematics(state)); sender.sent(state)
    view = PeerView()                            # on every peer, one per vehicle
    view.on_state(decode_kinematics(data))
    p = view.predicted(now)                      # p.x, p.y, p.z, p.bound_m, p.age_s

`bound_m` is sound when the vehicle's acceleration stays within `max_accel_mps2` (and
the prediction's, a turn of the reported rate, too): the truth and the prediction leave
the same state at the same time, so they part by at most `max_accel_mps2 * age**2` (their
relative acceleration is at most twice the bound), lost messages or not; when nothing
was lost the sender keeps the error within `threshold_m` besides.

Times are the same clock on every node (GPS time); states carry the time they describe.

The gateway runs this model on VehicleStatus (`telemetry.py`: `OwnTelemetry` is the
sender, `PeerPredictor` the receivers); `SendOnError` and `PeerView` here are the same
rules on bare states, kept for their property tests.
"""

from __future__ import annotations

import math
import struct
from dataclasses import dataclass

KINEMATICS = struct.Struct("<dfffffff")
KINEMATICS_BYTES = KINEMATICS.size  # 36
_EPS_W = 1e-6  # rad/s: below this, a straight line


@dataclass(frozen=True)
class Kinematics:
    t: float  # the time the state describes (s)
    x: float  # east of a shared origin (m)
    y: float  # north (m)
    z: float  # up (m)
    vx: float  # m/s
    vy: float
    vz: float
    turn_rate: float = 0.0  # rad/s, positive counter-clockwise seen from above

    def __post_init__(self) -> None:
        values = (self.t, self.x, self.y, self.z, self.vx, self.vy, self.vz, self.turn_rate)
        if not all(math.isfinite(v) for v in values):
            raise ValueError(f"non-finite kinematics {self}")

    @property
    def speed(self) -> float:
        return math.hypot(self.vx, self.vy)


def predict(k: Kinematics, t: float) -> Kinematics:
    """The state at `t` if the vehicle holds its turn rate and climb rate from `k.t`."""
    dt = t - k.t
    w = k.turn_rate
    if abs(w) < _EPS_W:
        x, y = k.x + k.vx * dt, k.y + k.vy * dt
        vx, vy = k.vx, k.vy
    else:
        s, c = math.sin(w * dt), math.cos(w * dt)
        x = k.x + (k.vx * s - k.vy * (1.0 - c)) / w
        y = k.y + (k.vy * s + k.vx * (1.0 - c)) / w
        vx, vy = k.vx * c - k.vy * s, k.vx * s + k.vy * c
    return Kinematics(t, x, y, k.z + k.vz * dt, vx, vy, k.vz, w)


def distance(a: Kinematics, b: Kinematics) -> float:
    return math.sqrt((a.x - b.x) ** 2 + (a.y - b.y) ** 2 + (a.z - b.z) ** 2)


def encode_kinematics(k: Kinematics) -> bytes:
    """36 bytes: time (float64), then position, velocity, turn rate (float32)."""
    return KINEMATICS.pack(k.t, k.x, k.y, k.z, k.vx, k.vy, k.vz, k.turn_rate)


def decode_kinematics(data: bytes) -> Kinematics:
    """Raises ValueError (never anything else) on a short or non-finite record."""
    if len(data) < KINEMATICS_BYTES:
        raise ValueError(f"kinematics need {KINEMATICS_BYTES} bytes, got {len(data)}")
    return Kinematics(*KINEMATICS.unpack_from(data))


@dataclass
class SendOnError:
    """The sender's side: when to transmit its own state."""

    threshold_m: float = 5.0
    heartbeat_s: float = 1.0
    last_sent: Kinematics | None = None
    sends: int = 0
    heartbeats: int = 0

    def __post_init__(self) -> None:
        if self.threshold_m <= 0 or self.heartbeat_s <= 0:
            raise ValueError("threshold_m and heartbeat_s are > 0")

    def error(self, truth: Kinematics, t: float) -> float:
        """How far the peers' prediction is from the truth (held to its own model) at t."""
        if self.last_sent is None:
            return math.inf
        return distance(predict(self.last_sent, t), predict(truth, t))

    def due(self, truth: Kinematics, now: float, horizon_s: float = 0.0) -> bool:
        """True if a status must go out now: the peers' prediction is, or will be within
        `horizon_s` (the next chance to speak after this one, plus latency), off by more
        than the threshold, or the heartbeat floor has passed."""
        if self.last_sent is None:
            return True
        if now - self.last_sent.t >= self.heartbeat_s - 1e-9:
            return True
        steps = max(1, math.ceil(horizon_s / 0.1))
        return any(
            self.error(truth, now + horizon_s * i / steps) > self.threshold_m
            for i in range(steps + 1)
        )

    def sent(self, truth: Kinematics, now: float | None = None) -> None:
        """Record what went out (the peers now predict from it)."""
        last = self.last_sent
        if last is not None and now is not None and now - last.t >= self.heartbeat_s - 1e-9:
            self.heartbeats += 1
        self.last_sent = truth
        self.sends += 1


@dataclass(frozen=True)
class Predicted:
    x: float
    y: float
    z: float
    bound_m: float  # the truth is within this distance (accelerations within the bound)
    age_s: float  # since the state the prediction starts from


@dataclass
class PeerView:
    """A receiver's view of one peer: the latest state heard, predicted forward."""

    max_accel_mps2: float = 6.0  # a fixed-wing at 30 degrees of bank: g tan 30
    accuracy_m: float = 0.0  # the position error of a reported state
    last: Kinematics | None = None
    stale: int = 0

    def on_state(self, k: Kinematics) -> bool:
        """Take a heard state; False (ignored) if not newer than the one held."""
        if self.last is not None and k.t <= self.last.t:
            self.stale += 1
            return False
        self.last = k
        return True

    def predicted(self, now: float) -> Predicted | None:
        if self.last is None:
            return None
        p = predict(self.last, now)
        age = max(0.0, now - self.last.t)
        return Predicted(p.x, p.y, p.z, self.accuracy_m + self.max_accel_mps2 * age * age, age)
