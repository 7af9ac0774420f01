"""Take-off and landing deconfliction at neighbouring pads: a pure rule every node
applies to the same reported numbers (its peers' VehicleStatus and the homes in their
VehicleInfo), so no messages are exchanged and no leader decides.

A vehicle's pad is its home (where it took off). Pads closer than `near_m` are
neighbours. Vertical moves near the ground (a take-off climb, the descent onto the pad)
are sequenced among neighbours:

    may_move(own, pad, peers, taking_off) -> the blockers (empty: go)

    a peer u blocks vehicle v (pad P) if
      (a) u is airborne (above `airborne_m`) within `near_m` of P horizontally, and
          u is low (under `stagger_m`), or (landing only) u has priority (a lower id); or
      (b) taking off only: u stands on a neighbouring pad with a lower id and is about
          to take off for a mission too (its sortie PLANNING or PREMISSION).

So a simultaneous take-off from pads 8 m apart goes in id order, each vehicle starting
its climb when the one before is `stagger_m` up (vertical climbs at the same rate keep
that gap) or has flown off; a landing waits while a neighbour is low over or near the
pad (taking off, landing) or while a neighbour with priority is airborne near it. The
relation is acyclic (ids) or waits on a vehicle that is moving (a low one is taking
off or landing), so it cannot deadlock. A peer that is silent (lost) does not block.

`hold_layer` gives every vehicle returning to neighbouring pads its own holding
altitude (its rank by id in the cluster of pads joined by steps under `hold_near_m`:
holding circles that could overlap), so vehicles waiting for their turn to land are
stacked `layer_m` apart.

Pure: no I/O, no clock.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass

from swarm_proto import GeoPoint, MissionState, VehicleStatus
from swarm_proto.geodesy import distance_m

ABOUT_TO_TAKE_OFF = frozenset({MissionState.PLANNING, MissionState.PREMISSION})


@dataclass(frozen=True, slots=True)
class PadConfig:
    near_m: float = 25.0  # pads (or a vehicle and a pad) closer than this are sequenced
    stagger_m: float = 30.0  # a neighbour above this height over the ground has climbed clear
    airborne_m: float = 1.0  # above this height above its home a vehicle is airborne
    hold_alt_rel_m: float = 30.0  # the lowest holding layer over a pad
    layer_m: float = 30.0  # between holding layers (over the avoider's 20 m and its margins)
    hold_near_m: float = 150.0  # pads this close share the holding layers (loiter circles)

    def __post_init__(self) -> None:
        if min(self.near_m, self.stagger_m, self.layer_m) <= 0:
            raise ValueError("near_m, stagger_m and layer_m must be positive")


@dataclass(frozen=True, slots=True)
class Blocker:
    vehicle_id: int
    why: str


def may_move(
    own_id: int,
    pad: GeoPoint,
    peers: Iterable[tuple[VehicleStatus, GeoPoint | None]],
    *,
    taking_off: bool,
    config: PadConfig = PadConfig(),
) -> list[Blocker]:
    """Who keeps vehicle `own_id` from climbing off / descending onto `pad` now:
    `peers` are the peers' latest statuses with their pads (homes), None if unknown."""
    cfg = config
    out: list[Blocker] = []
    for st, their_pad in peers:
        u = st.vehicle_id
        if u == own_id:
            continue
        d = distance_m(pad.lat_deg, pad.lon_deg, st.lat_deg, st.lon_deg)
        airborne = st.armed and st.alt_rel_m > cfg.airborne_m
        if airborne:
            low = st.alt_rel_m < cfg.stagger_m
            if d < cfg.near_m and (low or (u < own_id and not taking_off)):
                out.append(Blocker(u, f"{u} {'low' if low else 'airborne'} {d:.0f} m from the pad"))
            continue
        if (
            taking_off
            and u < own_id
            and st.mission_state in ABOUT_TO_TAKE_OFF
            and their_pad is not None
            and distance_m(pad.lat_deg, pad.lon_deg, their_pad.lat_deg, their_pad.lon_deg)
            < cfg.near_m
        ):
            out.append(Blocker(u, f"{u} takes off first"))
    return out


def hold_layer(
    own_id: int, pad: GeoPoint, pads: Mapping[int, GeoPoint], config: PadConfig = PadConfig()
) -> float:
    """The holding altitude above home of `own_id` over its pad: `hold_alt_rel_m` plus
    `layer_m` times its rank by id in its cluster, the vehicles whose pads are joined by
    steps shorter than `hold_near_m` (holding circles that could overlap). Every member
    of a cluster computes the same cluster from the same pads, so layers never repeat."""
    every = dict(pads)
    every[own_id] = pad
    cluster = {own_id}
    todo = [own_id]
    while todo:
        a = every[todo.pop()]
        for vid, p in every.items():
            if (
                vid not in cluster
                and distance_m(a.lat_deg, a.lon_deg, p.lat_deg, p.lon_deg) < config.hold_near_m
            ):
                cluster.add(vid)
                todo.append(vid)
    rank = sorted(cluster).index(own_id)
    return config.hold_alt_rel_m + rank * config.layer_m
