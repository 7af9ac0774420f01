"""Radio at swarm scale: 14, 25 and 50 vehicles flying the demo's mission on
one 115.2 kbps XTend channel, the gateway as shipped (send on error, adaptive schedule,
peers predicted) against the fixed 5 Hz TDM, at 0 % and 10 % loss; and the framing
efficiency of the gateway's real frames.

Everything runs in fast time: whole gateways (`Bridge` + `RadioNode`, as `radio-gateway
run` composes them) on the channel model (`swarm_sim.radio_channel`), with 0.5 ms of
random serial write and read latency. The channel uses the XTend datasheet's timing
(`XTEND_DATASHEET`: 6.5 ms RF initializer per packet, 0.8-1.0 ms transmit setup,
half-duplex), independently of the timing the gateways size their slots with
(`DESIGN`, configured with the datasheet's 6.5 ms like `radio-gateway --sync-ms 6.5`):
a schedule that is wrong shows as collisions. With loss, the channel also flips bits
(BER 1e-5: about one 60-byte frame in 200 arrives corrupt and is dropped by the CRC) and
a receiver keeps the earlier of two overlapping packets half of the time (capture).

Vehicles fly the demo's survey (`_radio_tracks.demo_flight`: FastFleet, the real node
cores on simulated ArduPilot VTOLs and quadcopters, take-off to landing): vehicle i flies
demo vehicle i mod 5's track from its own moment of the flight, so the swarm has
vehicles climbing out, on lanes, turning, returning and landing at once. Each node
publishes its VehicleStatus at 5 Hz on its LAN. A ground station publishes a command
to every vehicle every 5 s; every vehicle answers with an Ack (at 50 vehicles a command
each second would be 50 answers a second for the ground station to acknowledge, more
than its share of the air carries).

Per n and loss, for `tdm5` (the gateway with `status_mode = "every"`, fixed slots: each
status queued, latest only, one per slot: 5 Hz up to the limit, slower past it; a node
believes the last status heard, as nodes do without prediction) and `gateway` (as
shipped: send on error at 5 m / 1 s heartbeat, slots of 88 record bytes, adaptive slot
shares: parked vehicles level 0, flying 1, control backlog 2; a node believes its
gateway's prediction at `now`); at n = 50 also `gateway_fixed` (the same without the
adaptive schedule: what the shares cost or buy):

- `position_error_p99_m`, `position_error_max_m`: every receiver's belief of every other
  vehicle against the truth, every 100 ms of the window;
- `bound_exceeded`: (gateway) the fraction of those samples where the truth was outside
  the prediction's error bound (`position_error_m`);
- `airtime_used`: the fraction of the channel's time under a packet, initializers
  included; `collisions` (`collisions_tdm` between on-time packets; `collisions_late`
  involving a packet its host wrote late);
- `cmd_latency_p99_ms`: command published by the ground station to its delivery on each
  vehicle's LAN; `ack_latency_p99_ms`: a vehicle's Ack to the ground station's LAN;
- `status_packets_per_s` (statuses put on air), `slot_rate_hz` (the fixed table's).

`dr_position_error_*` (tdm5) is the same run with each status heard dead-reckoned the way the
gateway predicts (what prediction alone buys).

Limits (the issue's "bare-message limit"): `bare_limit` vehicles a 200 ms cycle carries
with one bare 40-byte status per packet (5 ms guard + 6.5 ms initializer + 40 bytes);
`achieved_*`: measured, vehicles whose every status reaches every other at >= 95 % of
5 Hz with 0 collisions, with the gateway's real frames (real VehicleStatus bytes through
the bridge, `status_mode = "every"`): one frame per vehicle per 200 ms, and the
gateway's batched setting (`cycle_s = 0.4`, `min_payload = 84`, `latest_keep = 2`: two
statuses per authenticated frame). `bare_limit_ratio` = achieved_batched / bare_limit.
"""

from __future__ import annotations

import math
import time
from collections import defaultdict
from typing import Any

import msgspec

from radio_gateway.core.airtime import LinkTiming
from radio_gateway.core.bridge import Bridge
from radio_gateway.core.deadreckon import predict
from radio_gateway.core.slots import SlotLayout, TdmConfig, physical_limit
from radio_gateway.core.telemetry import (
    PeerPredictor,
    PredictConfig,
    SendOnErrorConfig,
    kinematics,
)
from swarm_proto import Ack, AckRef, Command, CommandKind, VehicleStatus
from swarm_sim.radio_channel.harness import Fleet
from swarm_sim.radio_channel.model import XTEND_DATASHEET, ChannelParams

from ._radio_tracks import Swarm, Track, demo_flight, position_error_m

KEY = bytes(range(32))
DESIGN = LinkTiming(sync_s=XTEND_DATASHEET.sync_s)
STATUS_BYTES = 40
GUARD_S = 0.005
CYCLE_S = 0.2
GCS = 900
WINDOW_S = 40.0
WARMUP_S = 3.0
LIMIT_SIM_S = 10.0
NS = (14, 25, 50)
LOSSES = (0.0, 0.1)
BER = 1e-5
CAPTURE = 0.5
CMD_EVERY_S = 5.0  # a command to every vehicle, each answering with an Ack


def _pctl(values: list[float], q: float) -> float:
    if not values:
        return math.nan
    s = sorted(values)
    return s[min(len(s) - 1, math.ceil(q * len(s)) - 1)]


def _channel(n: int, loss: float) -> ChannelParams:
    extra = {"ber": BER, "capture": CAPTURE} if loss else {}
    return ChannelParams(**{**XTEND_DATASHEET.__dict__, "loss": loss, "seed": n, **extra})


# ---------------------------------------------------------------------------- limits
def _fits(n: int, tdm: TdmConfig, batched: bool, track: Track) -> tuple[bool, int]:
    f = Fleet(
        XTEND_DATASHEET,
        DESIGN,
        tdm,
        KEY,
        max_nodes=n,
        seed=n,
        write_jitter_s=5e-4,
        read_jitter_s=5e-4,
        latest_keep=2 if batched else 1,
    )
    members = tuple(range(1, n + 1))
    t0 = f.t

    def lan(v: int) -> Any:
        def publish(t: float) -> list[msgspec.Struct]:
            s = track.at(20.0 + (t - t0) + v)
            return [msgspec.structs.replace(s, vehicle_id=v, time_unix_s=t)]

        return publish

    for v in members:
        f.add(
            v,
            lan=lan(v),
            produce_every_s=CYCLE_S,
            initial_members=members,
            bridge=Bridge("default", v, frozenset({v})),
        )
    f.run(t0 + 1.0)
    base = f.model.counts["collisions"]
    f.run(t0 + 1.0 + LIMIT_SIM_S)
    seen: set[tuple[int, int, float]] = set()
    per: defaultdict[tuple[int, int], int] = defaultdict(int)
    lo, hi = t0 + 1.5, t0 + 1.0 + LIMIT_SIM_S
    for t, dst, msg in f.published:
        if lo < t <= hi and isinstance(msg, VehicleStatus):
            k = (dst, msg.vehicle_id, msg.time_unix_s)
            if k not in seen:
                seen.add(k)
                per[(dst, msg.vehicle_id)] += 1
    rate = min(per[(d, s)] for d in members for s in members if d != s) / (hi - lo)
    coll = f.model.counts["collisions"] - base
    return coll == 0 and rate >= 0.95 * 5.0, coll


def _achieved(tdm: TdmConfig, batched: bool, track: Track) -> tuple[int, int]:
    limit = physical_limit(DESIGN, tdm)
    for n in range(limit, 1, -1):
        ok, _ = _fits(n, tdm, batched, track)
        if ok:
            return n, limit
    return 0, limit


# ---------------------------------------------------------------------------- scale
def _scale(n: int, loss: float, scheme: str, tracks: dict[int, Track]) -> dict[str, Any]:
    gateway = scheme in ("gateway", "gateway_fixed", "gateway_manoeuvre")
    adaptive = scheme in ("gateway", "gateway_manoeuvre")
    # a slot carries a status (+ its turn rate and record header) and as much again for
    # acks, answers and schedule changes (the gateway's on_error default)
    min_payload = 2 * (STATUS_BYTES + 4) if gateway else STATUS_BYTES + 2
    tdm = TdmConfig(cycle_s=CYCLE_S, guard_s=GUARD_S, min_payload=min_payload)
    f = Fleet(
        _channel(n, loss),
        DESIGN,
        tdm,
        KEY,
        max_nodes=n + 1,
        seed=n,
        write_jitter_s=5e-4,
        read_jitter_s=5e-4,
        keep_predictions=False,
    )
    t0 = f.t
    vehicles = tuple(range(1, n + 1))
    members = (*vehicles, GCS)
    layout = SlotLayout.build(members, DESIGN, tdm)
    swarm = Swarm(tracks, n, t0, WINDOW_S)
    predict_cfg = PredictConfig()
    soe = SendOnErrorConfig(manoeuvre_share=scheme == "gateway_manoeuvre") if gateway else None
    commands: dict[int, float] = {}  # seq -> published
    acks: dict[tuple[int, int], float] = {}  # (vehicle, seq) -> published
    answered: dict[int, int] = dict.fromkeys(vehicles, 0)  # commands a vehicle answered

    def vehicle_lan(v: int) -> Any:
        def publish(t: float) -> list[msgspec.Struct]:
            out: list[msgspec.Struct] = [swarm.vehicle(v, t)]
            for seq in sorted(heard_cmds[v] - set(range(answered[v] + 1))):
                out.append(Ack(v, GCS, AckRef.COMMAND, seq, True))
                acks[(v, seq)] = t
                answered[v] = max(answered[v], seq)
            return out

        return publish

    seq = [0]

    def gcs_lan(t: float) -> list[msgspec.Struct]:
        seq[0] += 1
        commands[seq[0]] = t
        return [Command(GCS, seq[0], CommandKind.SET_SPEED, time_unix_s=t)]

    bridges: dict[int, Bridge] = {}
    heard_cmds: dict[int, set[int]] = {v: set() for v in vehicles}
    for v in vehicles:
        bridges[v] = Bridge(
            "default",
            v,
            frozenset({v}),
            predictor=PeerPredictor(predict_cfg) if gateway else None,
        )
        f.add(
            v,
            lan=vehicle_lan(v),
            produce_every_s=0.2,
            initial_members=members,
            send_on_error=soe,
            adaptive=adaptive,
            bridge=bridges[v],
        )
    bridges[GCS] = Bridge("default", GCS, frozenset({GCS}))
    f.add(
        GCS,
        lan=gcs_lan,
        produce_every_s=CMD_EVERY_S,
        initial_members=members,
        adaptive=adaptive,
        bridge=bridges[GCS],
    )

    # run in 100 ms steps; sample every receiver's belief of every other vehicle
    err: list[float] = []
    err_dr: list[float] = []
    exceeded = 0
    unheard = 0
    last: dict[tuple[int, int], VehicleStatus] = {}
    seen_pub = 0
    cmd_ms: list[float] = []
    ack_ms: list[float] = []
    steps = int(WINDOW_S / 0.1)
    for i in range(1, steps + 1):
        t = t0 + 0.1 * i
        f.run(t)
        for tp, dst, msg in f.published[seen_pub:]:
            if isinstance(msg, VehicleStatus):
                if msg.predicted_s == 0.0:
                    k = (dst, msg.vehicle_id)
                    old = last.get(k)
                    if old is None or msg.time_unix_s > old.time_unix_s:
                        last[k] = msg
            elif isinstance(msg, Command) and dst != GCS:
                if msg.seq not in heard_cmds[dst]:
                    heard_cmds[dst].add(msg.seq)
                    cmd_ms.append((tp - commands[msg.seq]) * 1000)
            elif isinstance(msg, Ack) and dst == GCS:
                sent = acks.get((msg.vehicle_id, msg.ref_id))
                if sent is not None:
                    ack_ms.append((tp - sent) * 1000)
                    del acks[(msg.vehicle_id, msg.ref_id)]
        seen_pub = len(f.published)
        if t < t0 + WARMUP_S:
            continue
        truth = {v: swarm.vehicle(v, t) for v in vehicles}
        for dst in vehicles:
            pred = bridges[dst].predictor
            for src in vehicles:
                if src == dst:
                    continue
                tr = truth[src]
                if gateway:
                    assert pred is not None
                    pos = pred.position(src, t)
                    if pos is None:
                        unheard += 1
                        continue
                    e = position_error_m(
                        tr,
                        msgspec.structs.replace(
                            tr, lat_deg=pos[0], lon_deg=pos[1], alt_msl_m=pos[2]
                        ),
                    )
                    err.append(e)
                    if e > pos[3] + 0.5:  # + the radio's quantization (cm) and the chord
                        exceeded += 1
                    continue
                s = last.get((dst, src))
                if s is None:
                    unheard += 1
                    continue
                err.append(position_error_m(tr, s))
                kin = predict(kinematics(s, 0.0, (s.lat_deg, s.lon_deg)), t)
                mlat, mlon = 111_132.0, 111_320.0 * math.cos(math.radians(s.lat_deg))
                p = msgspec.structs.replace(
                    s,
                    lat_deg=s.lat_deg + kin.y / mlat,
                    lon_deg=s.lon_deg + kin.x / mlon,
                    alt_msl_m=kin.z,
                )
                err_dr.append(position_error_m(tr, p))
    air = sum(XTEND_DATASHEET.sync_s + len(a.data) * 8 / DESIGN.rf_bps for _, _, a in f.transmits)
    c = f.model.counts
    status_sent = sum(
        v
        for m in f.members.values()
        for k, v in m.node.counts.items()
        if k.startswith("own_status_")
    )
    if not gateway:  # every vehicle frame carries its latest status (5 Hz >= slot rate)
        status_sent = sum(f.node(v).counts["tx_frames"] for v in vehicles)
    levels = {v: f.node(v).membership.level_of(v) for v in members}
    row: dict[str, Any] = {
        "position_error_p99_m": round(_pctl(err, 0.99), 2),
        "position_error_max_m": round(max(err), 2) if err else math.nan,
        "position_error_p50_m": round(_pctl(err, 0.5), 2),
        "airtime_used": round(air / (f.t - t0), 3),
        "collisions": c["collisions"],
        "collisions_tdm": c["collisions_tdm"],
        "collisions_late": c["collisions_late"],
        "late_writes": c["late_writes"],
        "cmd_latency_p99_ms": round(_pctl(cmd_ms, 0.99), 1),
        "ack_latency_p99_ms": round(_pctl(ack_ms, 0.99), 1),
        "commands_delivered": f"{len(cmd_ms)}/{len(commands) * n}",
        "status_packets_per_s": round(status_sent / (f.t - t0), 1),
        "slot_rate_hz": round(layout.rate_hz, 2),
        "unheard_samples": unheard,
        "lost": c["lost"],
        "corrupted": c["corrupted"],
        "captured": sum(pm["captured"] for pm in f.model.per_module),
    }
    if gateway:
        row["bound_exceeded"] = round(exceeded / max(1, len(err)), 5)
        row["levels_at_end"] = dict(
            sorted(
                defaultdict(
                    int,
                    {lv: sum(1 for x in levels.values() if x == lv) for lv in set(levels.values())},
                ).items()
            )
        )
        row["level_changes"] = sum(f.node(v).membership.changes_applied for v in (1,))
        reasons: defaultdict[str, int] = defaultdict(int)
        for m in f.members.values():
            for name, v in m.node.counts.items():
                if name.startswith("own_status_"):
                    reasons[name.removeprefix("own_status_")] += v
        row["status_reasons"] = dict(reasons)
    else:
        row["dr_position_error_p99_m"] = round(_pctl(err_dr, 0.99), 2)
        row["dr_position_error_max_m"] = round(max(err_dr), 2) if err_dr else math.nan
    return row


def run() -> dict[str, Any]:
    t_start = time.perf_counter()
    tracks = demo_flight()
    flight_s = round(min(t.duration_s for t in tracks.values()), 1)
    print(f"demo flight: {len(tracks)} vehicles, {flight_s} s each", flush=True)
    bare = int(CYCLE_S // (GUARD_S + DESIGN.airtime_s(STATUS_BYTES)))
    one = TdmConfig(cycle_s=CYCLE_S, guard_s=GUARD_S, min_payload=STATUS_BYTES + 2)
    two = TdmConfig(cycle_s=2 * CYCLE_S, guard_s=GUARD_S, min_payload=2 * (STATUS_BYTES + 2))
    track = tracks[min(tracks)]
    achieved_one, limit_one = _achieved(one, batched=False, track=track)
    print(f"one per packet: {achieved_one} of {limit_one}", flush=True)
    achieved_two, limit_two = _achieved(two, batched=True, track=track)
    print(f"batched: {achieved_two} of {limit_two}", flush=True)
    scale: dict[str, Any] = {}
    for n in NS:
        for loss in LOSSES:
            for scheme in ("tdm5", "gateway", *(("gateway_fixed",) if n == max(NS) else ())):
                t1 = time.perf_counter()
                row = _scale(n, loss, scheme, tracks)
                row["wall_s"] = round(time.perf_counter() - t1, 1)
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
        "lossy_channel_extra": {"ber": BER, "capture": CAPTURE},
        "design_sync_ms": DESIGN.sync_s * 1000,
        "window_s": WINDOW_S,
        "command_every_s": CMD_EVERY_S,
        "demo_flight_s": flight_s,
        "sweep_wall_s": round(time.perf_counter() - t_start, 1),
    }
