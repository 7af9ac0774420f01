"""Take-off and landing deconfliction at neighbouring pads: a pure rule every node
applies to the same reported numbers (its peers' VehicleStatus and the homes in their
VehicleInfo), so no messages are exchanged and no leader decides.

A vehicle's pad is its home (where it took off). Pads closer than `near_m` are
neighbours. Vertical moves near the ground (a take-off climb, the descent onto the pad)
are sequenced among neighbours:

    may_move(own, pad, peers, taking_off) -> the blockers (empty: go)

    a peer u blocks vehicle v (pad P) if
      (a) u is airborne (above `airborne_m`) within `near_m` of P horizontally (plus
          `circle_m` while it flies faster than `hover_speed_m_s`: a circling fixed-wing;
          landing, plus `circle_m` again when v itself circles down: its own loiter
          circle sweeps that far around P), and u is low (under `stagger_m`), or
          (landing only) v's descent would go through it: u is below v, or level with
          it (within `level_band_m`) with a lower id; landing, u counts at its own pad
          as well while within `approach_m` of it (on its way down there: a VTOL's
          transition and slow approach begin far out); or
      (b) taking off only: u stands on a neighbouring pad with a lower id and is about
          to take off for a mission too (its sortie PLANNING or PREMISSION).

So a simultaneous take-off from pads 8 m apart goes in id order, each vehicle starting
its climb when the one before is `stagger_m` up (vertical climbs at the same rate keep
that gap) or has flown off; a landing waits while a neighbour is low over or near the
pad (taking off, landing) or below it there (the holding layers below land first). The
relation is acyclic (altitude, then id) or waits on a vehicle that is moving (a low one
is taking off or landing), so it cannot deadlock. A peer that is silent (lost) does not
block.

`hold_layer` gives every vehicle returning to neighbouring pads its own holding
altitude (its rank in the cluster of pads joined by steps shorter than their holds
need, `holds_apart_m`: `hold_near_m` for holding circles that could overlap,
`hover_near_m` for two multirotors hovering still over their pads; multirotors low,
fixed-wing above, each by id), so vehicles waiting for their turn to land are stacked
`layer_m` apart, and multirotors on pads far enough apart all hold at the lowest layer.

Pure: no I/O, no clock.
"""

from __future__ import annotations

import math
from collections.abc import Collection, Iterable, Mapping
from dataclasses import dataclass

from swarm_proto import GeoPoint, MissionState, VehicleStatus, VehicleType
from swarm_proto.geodesy import distance_m

ABOUT_TO_TAKE_OFF = frozenset({MissionState.PLANNING, MissionState.PREMISSION})
HOVER_SPEED_M_S = 8.0  # a VTOL slower than this is hovering (it manoeuvres as a multirotor)


def hovering(vehicle_type: VehicleType, mode_name: str, groundspeed_m_s: float) -> bool:
    """A multirotor, or a VTOL hovering outside its mission (a take-off climb, QLOITER):
    in AUTO a VTOL counts as the fixed-wing it flies as (slow only in a transition)."""
    if vehicle_type == VehicleType.COPTER:
        return True
    return (
        vehicle_type == VehicleType.VTOL
        and mode_name != "AUTO"
        and groundspeed_m_s < HOVER_SPEED_M_S
    )


@dataclass(frozen=True, slots=True)
class PadConfig:
    near_m: float = (
        40.0  # pads (or a vehicle and a pad) closer than this are sequenced (the risk band)
    )
    stagger_m: float = 30.0  # a neighbour above this height over the ground has climbed clear
    airborne_m: float = 1.0  # above this height above its home a vehicle is airborne
    level_band_m: float = 5.0  # landing: a neighbour within this of our level and a lower id first
    hover_speed_m_s: float = 8.0  # faster than this, a neighbour is in fixed-wing flight
    circle_m: float = 80.0  # ... and counts from this much further (its loiter circle)
    # landing: a peer this close to its own pad is on its way down there as well (measured
    # in the demo: a VTOL's transition to hover overshot 170 m from its pad, and it flew
    # the rest at 5 m/s; a fixed-wing circling down 60 m away swept through it)
    approach_m: float = 200.0
    hold_alt_rel_m: float = 30.0  # the lowest holding layer over a pad
    layer_m: float = 30.0  # between holding layers (over the avoider's 20 m and its margins)
    hold_near_m: float = 150.0  # pads this close share the holding layers (loiter circles)
    # two vehicles that hover over their pads (multirotors) share the holding layers only
    # when their pads are this close: hovering still over pads at least the avoider's
    # release distance (30 m) apart, they are never in conflict; a hoverer and a circler
    # share them when the pads are closer than the mean of the two distances (90 m)
    hover_near_m: float = 30.0

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
    own_alt_msl_m: float | None = None,
    own_circles: bool = False,
) -> list[Blocker]:
    """Who keeps vehicle `own_id` from climbing off / descending onto `pad` now:
    `peers` are the peers' latest statuses with their pads (homes), None if unknown;
    `own_alt_msl_m`: where it is (landing); `own_circles`: it flies as a fixed-wing, so
    its descent circles around the pad (landing)."""
    cfg = config
    own_reach = cfg.circle_m if own_circles and not taking_off else 0.0
    out: list[Blocker] = []
    for st, their_pad in peers:
        u = st.vehicle_id
        if u == own_id:
            continue
        d = distance_m(pad.lat_deg, pad.lon_deg, st.lat_deg, st.lon_deg)
        airborne = st.armed and st.alt_rel_m > cfg.airborne_m
        if airborne:
            low = st.alt_rel_m < cfg.stagger_m
            below = False  # landing: our descent would go through it
            if not taking_off and own_alt_msl_m is not None:
                dz = st.alt_msl_m - own_alt_msl_m
                below = dz < -cfg.level_band_m or (abs(dz) <= cfg.level_band_m and u < own_id)
            # a fixed-wing in flight (a VTOL circling its holding layer) sweeps a circle:
            # it counts from further away
            fast = math.hypot(st.vel_north_m_s, st.vel_east_m_s) > cfg.hover_speed_m_s
            reach = cfg.near_m + (cfg.circle_m if fast else 0.0) + own_reach
            how = "m from the pad"
            if not taking_off and their_pad is not None and d >= reach:
                # on its way down to its own pad (a VTOL's slow approach from far out):
                # it will be there
                home = distance_m(their_pad.lat_deg, their_pad.lon_deg, st.lat_deg, st.lon_deg)
                if home < cfg.approach_m:
                    d = distance_m(pad.lat_deg, pad.lon_deg, their_pad.lat_deg, their_pad.lon_deg)
                    how = "m to its own pad, on its way down there"
            if d < reach and (low or below):
                where = "low" if low else "below"
                out.append(Blocker(u, f"{u} {where} {d:.0f} {how}"))
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
    own_id: int,
    pad: GeoPoint,
    pads: Mapping[int, GeoPoint],
    config: PadConfig = PadConfig(),
    fixed_wing: Collection[int] = (),
    hovering: Collection[int] = (),
) -> float:
    """The holding altitude above home of `own_id` over its pad: `hold_alt_rel_m` plus
    `layer_m` times its rank in its cluster, the vehicles whose pads are joined by steps
    shorter than their holding volumes need (`holds_apart_m`: holding circles that could
    overlap, 150 m; two vehicles known to hover over their pads, the `hovering` ones,
    30 m). Rank: vehicles that hover first (the low layers: a multirotor's slow descent
    from high costs battery), then the `fixed_wing` ones (they circle, and fly down
    fast), each by id. Every member of a cluster computes the same cluster from the same
    pads and types, so layers never repeat among vehicles whose holds could conflict."""
    every = dict(pads)
    every[own_id] = pad
    hover = set(hovering)
    cluster = {own_id}
    todo = [own_id]
    while todo:
        u = todo.pop()
        a = every[u]
        for vid, p in every.items():
            if vid not in cluster and distance_m(
                a.lat_deg, a.lon_deg, p.lat_deg, p.lon_deg
            ) < holds_apart_m(u in hover, vid in hover, config):
                cluster.add(vid)
                todo.append(vid)
    wing = set(fixed_wing)
    rank = sorted(cluster, key=lambda v: (v in wing, v)).index(own_id)
    return config.hold_alt_rel_m + rank * config.layer_m


def holds_apart_m(a_hovers: bool, b_hovers: bool, config: PadConfig = PadConfig()) -> float:
    """How far apart two pads must be for their vehicles to hold over them at one layer:
    `hover_near_m` when both hover still over their pads (multirotors), `hold_near_m`
    when both circle (fixed-wing, or a type not known), their mean for one of each."""
    if a_hovers and b_hovers:
        return config.hover_near_m
    if a_hovers or b_hovers:
        return 0.5 * (config.hover_near_m + config.hold_near_m)
    return config.hold_near_m
