"""Radio at swarm scale (issue 19): framing per byte of news, and position knowledge of
14, 25 and 50 vehicles on one 115.2 kbps XTend channel, fixed 5 Hz TDM against
send-on-error, at 0 % and 10 % loss.

Everything runs in fast time: the pure radio node cores (`RadioNode`) on the channel
model (`swarm_sim.radio_channel`), with 0.5 ms of random write and read latency. The
channel uses the XTend datasheet's timing (`XTEND_DATASHEET`: 6.5 ms RF initializer per
packet, 0.8-1.0 ms transmit setup, half-duplex), independently of the timing the
gateways size their slots with (`DESIGN`, configured with the datasheet's 6.5 ms like
`radio-gateway --sync-ms 6.5`): a schedule that is wrong shows as collisions.

- `bare_limit`: vehicles a 200 ms cycle carries with one bare 40-byte status per packet
  (5 ms guard + 6.5 ms initializer + 40 bytes): the ceiling of 5 Hz with no framing.
- `achieved_one_per_packet`: measured, vehicles at 5 Hz (every vehicle's statuses reach
  every other at >= 95 % of 5 Hz) with 0 collisions, one authenticated frame per vehicle
  per 200 ms.
- `achieved_batched`: the same when a vehicle's slot comes every 400 ms and its one
  authenticated frame carries its two latest statuses (the gateway's `latest_keep = 2`,
  `cycle_s = 0.4`, `min_payload = 84`: 5 Hz of statuses, 2.5 Hz of
  packets: the initializer, guard and tag are paid once per two statuses; a status
  waits up to 200 ms more). `bare_limit_ratio` = achieved_batched / bare_limit.
- per n and loss, for `tdm5` (every vehicle queues its status every 200 ms, latest only;
  the table gives it a slot each period: 5 Hz up to the limit, slower past it) and
  `send_on_error` (the same slots; a vehicle queues a status only when its peers'
  dead-reckoning of it would be off by more than 5 m before its next slot, or 1 s has
  passed): `position_error_p99_m` and `position_error_max_m` (every receiver's belief
  of every other vehicle against the truth, every 100 ms after 2 s of warm-up; `tdm5`
  believes the last status heard, `send_on_error` predicts from it; `tdm5_dr` is the
  tdm5 run's statuses predicted the same way), `airtime_used` (fraction of the channel's
  time under a packet, initializers included), `collisions` (TDM faults and late host
  writes apart), `cmd_latency_p99_ms` (a ground station's acknowledged 40-byte command
  every second, submit to delivery at each vehicle), `status_packets_per_s`.

Vehicles fly synthetic fixed-wing missions: 18 m/s, straight legs and 60-120 m orbits of
8-15 s each, some climbing, every acceleration within 5.4 m/s^2.
"""

from __future__ import annotations

import math
import random
import struct
import time
from collections import defaultdict
from typing import Any

from radio_gateway.core.airtime import LinkTiming
from radio_gateway.core.deadreckon import (
    Kinematics,
    PeerView,
    SendOnError,
    decode_kinematics,
    encode_kinematics,
    predict,
)
from radio_gateway.core.outbox import OutMessage
from radio_gateway.core.slots import SlotLayout, TdmConfig, physical_limit
from swarm_sim.radio_channel.harness import Fleet
from swarm_sim.radio_channel.model import XTEND_DATASHEET, ChannelParams

KEY = bytes(range(32))
DESIGN = LinkTiming(sync_s=XTEND_DATASHEET.sync_s)
STATUS_BYTES = 40
GUARD_S = 0.005
CYCLE_S = 0.2
STATUS = b"\x01\x64"  # opaque to the gateway (never relayed)
COMMAND = b"\x01\x65"
GCS = 900
FLIGHT_S = 20.0
WARMUP_S = 2.0
LIMIT_SIM_S = 10.0
NS = (14, 25, 50)
LOSSES = (0.0, 0.1)
SPEED = 18.0


# ---------------------------------------------------------------------------- tracks
def _segments(v: int, t0: float, duration: float) -> list[Kinematics]:
    rng = random.Random(v)
    heading = rng.uniform(0, 2 * math.pi)
    k = Kinematics(
        t0,
        rng.uniform(-2000, 2000),
        rng.uniform(-2000, 2000),
        rng.uniform(60, 150),
        SPEED * math.cos(heading),
        SPEED * math.sin(heading),
        0.0,
        0.0,
    )
    out = []
    t = t0 - rng.uniform(0, 10)
    k = predict(k, t)
    orbit = rng.random() < 0.5
    while t < t0 + duration + 1:
        w = rng.choice((-1, 1)) * SPEED / rng.uniform(60, 120) if orbit else 0.0
        vz = rng.choice((0.0, 0.0, 1.5, -1.5))
        k = Kinematics(k.t, k.x, k.y, k.z, k.vx, k.vy, vz, w)
        out.append(k)
        t += rng.uniform(8, 15)
        k = predict(k, t)
        orbit = not orbit
    return out


class Track:
    def __init__(self, v: int, t0: float, duration: float) -> None:
        self.segs = _segments(v, t0, duration)

    def at(self, t: float) -> Kinematics:
        seg = self.segs[0]
        for s in self.segs:
            if s.t > t:
                break
            seg = s
        return predict(seg, t)


def _status(v: int, k: Kinematics) -> bytes:
    return STATUS + struct.pack("<H", v) + encode_kinematics(k)


def _pctl(values: list[float], q: float) -> float:
    if not values:
        return math.nan
    s = sorted(values)
    return s[min(len(s) - 1, math.ceil(q * len(s)) - 1)]


# ---------------------------------------------------------------------------- limits
def _latest_producer(v: int) -> Any:
    seq = [0]

    def produce(t: float) -> list[OutMessage]:
        seq[0] += 1
        data = STATUS + struct.pack("<HI", v, seq[0])
        data += bytes(STATUS_BYTES - len(data))
        return [OutMessage(f"s{v}", data, 2, True, False, 5.0)]

    return produce


def _fits(n: int, tdm: TdmConfig, batched: bool) -> tuple[bool, int]:
    f = Fleet(
        XTEND_DATASHEET, DESIGN, tdm, KEY, max_nodes=n, seed=n, write_jitter_s=5e-4,
        read_jitter_s=5e-4, latest_keep=2 if batched else 1,
    )  # fmt: skip
    members = tuple(range(1, n + 1))
    for v in members:
        f.add(v, producer=_latest_producer(v), produce_every_s=CYCLE_S, initial_members=members)
    t0 = f.t
    f.run(t0 + 1.0)
    base = f.model.counts["collisions"]
    f.run(t0 + 1.0 + LIMIT_SIM_S)
    seen: set[tuple[int, bytes]] = set()
    per: defaultdict[tuple[int, int], int] = defaultdict(int)
    lo, hi = t0 + 1.5, t0 + 1.0 + LIMIT_SIM_S
    for t, dst, _, data in f.deliveries:
        if lo < t <= hi and (dst, data) not in seen:
            seen.add((dst, data))
            per[(dst, struct.unpack_from("<H", data, 2)[0])] += 1
    rate = min(per[(d, s)] for d in members for s in members if d != s) / (hi - lo)
    coll = f.model.counts["collisions"] - base
    return coll == 0 and rate >= 0.95 * 5.0, coll


def _achieved(tdm: TdmConfig, batched: bool) -> tuple[int, int]:
    limit = physical_limit(DESIGN, tdm)
    for n in range(limit, 1, -1):
        ok, _ = _fits(n, tdm, batched)
        if ok:
            return n, limit
    return 0, limit


# ---------------------------------------------------------------------------- scale
def _scale(n: int, loss: float, scheme: str) -> dict[str, Any]:
    tdm = TdmConfig(cycle_s=CYCLE_S, guard_s=GUARD_S, min_payload=STATUS_BYTES + 2)
    params = ChannelParams(**{**XTEND_DATASHEET.__dict__, "loss": loss, "seed": n})
    f = Fleet(params, DESIGN, tdm, KEY, max_nodes=n + 1, seed=n, write_jitter_s=5e-4,
              read_jitter_s=5e-4)  # fmt: skip
    t0 = f.t
    vehicles = tuple(range(1, n + 1))
    members = (*vehicles, GCS)
    layout = SlotLayout.build(members, DESIGN, tdm)
    tracks = {v: Track(v, t0, FLIGHT_S) for v in vehicles}
    senders = {v: SendOnError(threshold_m=5.0, heartbeat_s=1.0) for v in vehicles}
    sent = [0]

    def producer(v: int) -> Any:
        def produce(t: float) -> list[OutMessage]:
            truth = tracks[v].at(t)
            if scheme == "send_on_error":
                s = senders[v]
                if not s.due(truth, t, horizon_s=layout.period_s + CYCLE_S):
                    return []
                s.sent(truth, t)
            sent[0] += 1
            return [OutMessage(f"s{v}", _status(v, truth), 2, True, False)]

        return produce

    commands: dict[bytes, float] = {}

    def gcs(t: float) -> list[OutMessage]:
        data = COMMAND + struct.pack("<d", t)
        data += bytes(STATUS_BYTES - len(data))
        commands[data] = t
        return [OutMessage(f"cmd{t}", data, 0, False, True)]

    for v in vehicles:
        f.add(v, producer=producer(v), produce_every_s=CYCLE_S / 2, initial_members=members)
    f.add(GCS, producer=gcs, produce_every_s=1.0, initial_members=members)
    f.run(t0 + FLIGHT_S)

    # what each vehicle heard of each other, in order
    heard: defaultdict[tuple[int, int], list[tuple[float, Kinematics]]] = defaultdict(list)
    cmd_ms: list[float] = []
    for t, dst, _, data in f.deliveries:
        if data[:2] == STATUS and dst != GCS:
            src = struct.unpack_from("<H", data, 2)[0]
            heard[(dst, src)].append((t, decode_kinematics(data[4:])))
        elif data[:2] == COMMAND and data in commands:
            cmd_ms.append((t - commands[data]) * 1000)
    err_last: list[float] = []
    err_dr: list[float] = []
    unheard = 0
    steps = [t0 + WARMUP_S + 0.1 * i for i in range(int((FLIGHT_S - WARMUP_S) / 0.1))]
    truth = {v: [tracks[v].at(t) for t in steps] for v in vehicles}
    for dst in vehicles:
        for src in vehicles:
            if src == dst:
                continue
            hs = heard.get((dst, src), [])
            view = PeerView()
            j = 0
            for i, t in enumerate(steps):
                while j < len(hs) and hs[j][0] <= t:
                    view.on_state(hs[j][1])
                    j += 1
                if view.last is None:
                    unheard += 1
                    continue
                tr = truth[src][i]
                last = view.last
                err_last.append(math.dist((last.x, last.y, last.z), (tr.x, tr.y, tr.z)))
                p = predict(last, t)
                err_dr.append(math.dist((p.x, p.y, p.z), (tr.x, tr.y, tr.z)))
    air = sum(XTEND_DATASHEET.sync_s + len(a.data) * 8 / DESIGN.rf_bps for _, _, a in f.transmits)
    believed = err_dr if scheme == "send_on_error" else err_last
    c = f.model.counts
    row: dict[str, Any] = {
        "position_error_p99_m": round(_pctl(believed, 0.99), 2),
        "position_error_max_m": round(max(believed), 2) if believed else math.nan,
        "airtime_used": round(air / FLIGHT_S, 3),
        "collisions": c["collisions"],
        "collisions_tdm": c["collisions_tdm"],
        "collisions_late_write": c["collisions_late"],
        "late_writes": c["late_writes"],
        "cmd_latency_p99_ms": round(_pctl(cmd_ms, 0.99), 1),
        "status_packets_per_s": round(sent[0] / FLIGHT_S, 1),
        "slot_rate_hz": round(layout.rate_hz, 2),
        "unheard_samples": unheard,
    }
    if scheme == "tdm5":
        row["dr_position_error_p99_m"] = round(_pctl(err_dr, 0.99), 2)
        row["dr_position_error_max_m"] = round(max(err_dr), 2) if err_dr else math.nan
    return row


def run() -> dict[str, Any]:
    t_start = time.perf_counter()
    bare = int(CYCLE_S // (GUARD_S + DESIGN.airtime_s(STATUS_BYTES)))
    one = TdmConfig(cycle_s=CYCLE_S, guard_s=GUARD_S, min_payload=STATUS_BYTES + 2)
    two = TdmConfig(cycle_s=2 * CYCLE_S, guard_s=GUARD_S, min_payload=2 * (STATUS_BYTES + 2))
    achieved_one, limit_one = _achieved(one, batched=False)
    print(f"one per packet: {achieved_one} of {limit_one}", flush=True)
    achieved_two, limit_two = _achieved(two, batched=True)
    print(f"batched: {achieved_two} of {limit_two}", flush=True)
    scale: dict[str, Any] = {}
    for n in NS:
        for loss in LOSSES:
            for scheme in ("tdm5", "send_on_error"):
                row = _scale(n, loss, scheme)
                scale.setdefault(f"n_{n}", {}).setdefault(f"loss_{loss:g}", {})[scheme] = row
                print(n, loss, scheme, row, flush=True)
    return {
        "bare_limit": bare,
        "achieved_one_per_packet": achieved_one,
        "limit_one_per_packet": limit_one,
        "achieved_batched": achieved_two,
        "limit_batched": limit_two,
        "bare_limit_ratio": round(achieved_two / bare, 3),
        "bare_limit_ratio_one_per_packet": round(achieved_one / bare, 3),
        "scale": scale,
        "channel": {k: v for k, v in XTEND_DATASHEET.__dict__.items()},
        "design_sync_ms": DESIGN.sync_s * 1000,
        "flight_s": FLIGHT_S,
        "sweep_wall_s": round(time.perf_counter() - t_start, 1),
    }
