"""Shared by the radio tests: status producers, telemetry age, fleets in simulated time."""

from __future__ import annotations

import itertools
from collections import defaultdict
from collections.abc import Callable, Iterable

from radio_gateway.core.airtime import LinkTiming
from radio_gateway.core.outbox import OutMessage
from radio_gateway.core.slots import TdmConfig
from swarm_proto import VehicleStatus, radio
from swarm_proto.topics import STATUS, key_of
from swarm_sim.radio_channel.harness import Fleet
from swarm_sim.radio_channel.model import ChannelParams

KEY = bytes(range(32))
TIMING = LinkTiming()  # XTend at 115.2 kbps RF, 230,400 baud, 6 ms sync
TDM = TdmConfig(guard_s=0.002)  # 14 nodes x 62-byte status frames fit 200 ms with 2 ms guards


def status(vid: int, t: float) -> VehicleStatus:
    return VehicleStatus(
        vehicle_id=vid,
        time_unix_s=t,
        lat_deg=37.4112,
        lon_deg=-5.9889,
        alt_msl_m=110.0,
        alt_rel_m=100.0,
        battery_pct=80,
    )


def status_out(vid: int, t: float) -> OutMessage:
    p = STATUS.radio
    return OutMessage(
        key_of("default", status(vid, t)),
        radio.encode(status(vid, t)),
        int(p.klass),
        p.latest_only,
        p.acked,
        p.max_rate_hz,
    )


def status_producer(vid: int) -> Callable[[float], list[OutMessage]]:
    return lambda t: [status_out(vid, t)]


def fleet(
    n: int,
    *,
    loss: float = 0.0,
    tdm: TdmConfig = TDM,
    timing: LinkTiming = TIMING,
    seed: int = 1,
    initial: bool = True,
    max_nodes: int | None = None,
    jitter_s: float = 0.0,
) -> Fleet:
    f = Fleet(
        ChannelParams(loss=loss, seed=seed),
        timing,
        tdm,
        KEY,
        max_nodes=max_nodes or n + 2,
        seed=seed,
        write_jitter_s=jitter_s,
        read_jitter_s=jitter_s,
    )
    for vid in range(1, n + 1):
        f.add(
            vid,
            producer=status_producer(vid),
            initial_members=tuple(range(1, n + 1)) if initial else (),
        )
    return f


def status_arrivals(
    deliveries: Iterable[tuple[float, int, int, bytes]],
) -> dict[tuple[int, int], list[tuple[float, float]]]:
    """(receiver, vehicle) -> [(arrival, status time)] of every new status (in order)."""
    fresh: dict[tuple[int, int], float] = {}
    out: dict[tuple[int, int], list[tuple[float, float]]] = defaultdict(list)
    for t, dst, _src, data in deliveries:
        if data[:2] != b"\x01\x01":
            continue
        s = radio.decode(data, now_unix_s=t)
        assert isinstance(s, VehicleStatus)
        k = (dst, s.vehicle_id)
        if dst == s.vehicle_id or s.time_unix_s <= fresh.get(k, -1.0):
            continue
        fresh[k] = s.time_unix_s
        out[k].append((t, s.time_unix_s))
    return out


def worst_ages(
    arrivals: dict[tuple[int, int], list[tuple[float, float]]], after: float
) -> list[float]:
    """For every update after `after`: how old the receiver's telemetry was just before it."""
    ages = []
    for series in arrivals.values():
        for (_, t_prev), (t_new, _) in itertools.pairwise(series):
            if t_new > after:
                ages.append(t_new - t_prev)
    return sorted(ages)
