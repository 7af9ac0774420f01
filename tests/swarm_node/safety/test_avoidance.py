"""CollisionAvoider: the paper's cases one by one, priority as a property, and the
eight-aircraft head-on stress case in a point-mass fast-time simulation."""

from __future__ import annotations

import itertools
from collections.abc import Sequence

import msgspec
import numpy as np
import pymap3d
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from swarm_node.core.autopilot.requests import ChangeAltitude, Goto, SetMode
from swarm_node.core.safety.avoidance import (
    AvoidanceConfig,
    Ceiling,
    CollisionAvoider,
    Forget,
    Manoeuvre,
    ManoeuvreKind,
    OwnRoute,
    PlannedAltitude,
    Traffic,
)
from swarm_proto import Alert, AlertCode, Severity, VehicleInfo, VehicleStatus, VehicleType
from swarm_sim.core.pointmass import Start, run, stress_eight_headon
from tests.conftest import examples

LAT0, LON0, HOME = 40.4168, -3.7038, 650.0
T = 1_700_000_000.0


def status(
    vid: int,
    e: float,
    n: float,
    up: float,
    ve: float = 0.0,
    vn: float = 0.0,
    vu: float = 0.0,
    t: float = T,
    armed: bool = True,
) -> VehicleStatus:
    lat, lon, _h = pymap3d.enu2geodetic(e, n, up, LAT0, LON0, HOME)
    return VehicleStatus(
        vehicle_id=vid,
        time_unix_s=t,
        lat_deg=float(lat),
        lon_deg=float(lon),
        alt_msl_m=HOME + up,
        alt_rel_m=up,
        vel_north_m_s=vn,
        vel_east_m_s=ve,
        vel_down_m_s=-vu,
        armed=armed,
    )


def avoider(vid: int, vtype: VehicleType = VehicleType.PLANE, **kw: float) -> CollisionAvoider:
    return CollisionAvoider(AvoidanceConfig(vid, vtype, **kw))


def feed(av: CollisionAvoider, statuses: Sequence[VehicleStatus], now: float = T) -> list:
    for s in statuses:
        av.handle(s, now)
    return av.on_timer(now)


def manoeuvres(out: list) -> list[Manoeuvre]:
    return [o for o in out if isinstance(o, Manoeuvre)]


def head_on(alt_a: float = 100.0, alt_b: float = 100.0) -> list[VehicleStatus]:
    return [status(1, 0, 0, alt_a, ve=20), status(2, 800, 0, alt_b, ve=-20)]


def test_head_on_only_the_higher_id_climbs_at_one_altitude() -> None:
    pair = head_on()
    out1 = feed(avoider(1), pair)
    out2 = feed(avoider(2), pair)
    assert manoeuvres(out1) == []
    (m,) = manoeuvres(out2)
    assert m.kind is ManoeuvreKind.CLIMB and m.against == (1,)
    assert m.requests == (ChangeAltitude(alt_rel_m=pytest.approx(115.0, abs=0.01)),)
    (alert,) = [o for o in out2 if isinstance(o, Alert)]
    assert alert.code is AlertCode.COLLISION_RISK and alert.severity is Severity.WARNING
    assert "climb to 115 m for 1" in alert.text


def test_head_on_the_higher_vehicle_climbs_whatever_its_id() -> None:
    pair = head_on(alt_a=110.0, alt_b=100.0)  # 1 is 10 m higher than 2
    assert manoeuvres(feed(avoider(2), pair)) == []
    (m,) = manoeuvres(feed(avoider(1), pair))
    assert m.target_alt_rel_m == pytest.approx(115.0, abs=0.01)


def test_crossing_at_right_angles() -> None:
    pair = [status(1, -500, 0, 100, ve=25), status(2, 0, -500, 102, vn=25)]
    assert manoeuvres(feed(avoider(1), pair)) == []
    (m,) = manoeuvres(feed(avoider(2), pair))
    assert m.kind is ManoeuvreKind.CLIMB


def test_crossing_that_misses_by_far_is_no_conflict() -> None:
    pair = [status(1, -500, 0, 100, ve=25), status(2, 0, -800, 100, vn=25)]  # 300 m apart
    assert feed(avoider(2), pair) == []


def test_overtaking_on_one_track() -> None:
    pair = [status(1, 0, 0, 100, vn=15), status(2, 0, -300, 100, vn=30)]
    (m,) = manoeuvres(feed(avoider(2), pair))
    assert m.kind is ManoeuvreKind.CLIMB
    assert manoeuvres(feed(avoider(1), pair)) == []


def test_vertical_convergence_the_lower_one_levels_off() -> None:
    """1 climbs towards 2 flying 30 m above it on the same track: 2 is already above
    what 1 needs, so 2 keeps its altitude and 1 stops climbing."""
    pair = [status(1, 0, 0, 100, vn=20, vu=5), status(2, 0, 0, 130, vn=20)]
    (m,) = manoeuvres(feed(avoider(1), pair))
    assert m.kind is ManoeuvreKind.LEVEL and m.requests == (ChangeAltitude(alt_rel_m=100.0),)
    assert manoeuvres(feed(avoider(2), pair)) == []


def test_three_way_targets_stack_by_rank() -> None:
    three = [
        status(1, -600, 0, 100, ve=20),
        status(2, 600, 0, 101, ve=-20),
        status(3, 0, -600, 99, vn=20),
    ]
    targets = {}
    for vid in (1, 2, 3):
        ms = manoeuvres(feed(avoider(vid), three))
        targets[vid] = ms[0].target_alt_rel_m if ms else None
    assert targets[1] is None
    assert targets[2] == pytest.approx(115.0, abs=0.01)
    assert targets[3] == pytest.approx(130.0, abs=0.01)


def test_stale_telemetry_widens_the_protection_volume() -> None:
    """A report that reaches us 4 s later than this sender's reports usually do is 4 s
    old (measured on our clock: its send time to our reception, over the least seen)."""
    fresh = [status(1, 0, 0, 100, ve=20), status(2, 800, 60, 100, ve=-20)]  # 60 m abeam
    assert feed(avoider(2), fresh) == []
    av = avoider(2)
    far = status(2, 880, 60, 100, ve=-20, t=T - 4.0)
    feed(av, [far, status(1, -80, 0, 100, ve=20, t=T - 4.0)], T - 4.0)  # on time: the usual
    av.handle(status(1, 0, 0, 100, ve=20, t=T - 4.0), T)  # its next report, 4 s late
    (m,) = manoeuvres(feed(av, [fresh[1]]))
    assert m.kind is ManoeuvreKind.CLIMB  # 60 m < 20 m + 0.5 * 10 m/s^2 * (4 s)^2


def test_a_skewed_clock_is_not_stale_data() -> None:
    """Every report of a peer whose clock runs 10 s behind ours (SITL's GPS time ran
    9.4-10.5 s behind its host's) is fresh: the skew is constant, it cancels out."""
    for skew in (0.0, 10.0, -10.0):
        av = avoider(2)
        for k in range(10):
            t = T + k * 0.2
            own = status(2, 800 - 20 * k * 0.2, 60, 100, ve=-20, t=t - skew)
            peer = status(1, 20 * k * 0.2, 0, 100, ve=20, t=t - skew)
            assert not manoeuvres(feed(av, [own, peer], t)), skew  # 60 m abeam, fresh


def test_a_report_is_at_least_as_old_as_when_it_was_heard() -> None:
    av = avoider(2)
    av.handle(status(1, 0, 0, 100, ve=20), T)  # heard at T, says T
    av.handle(status(2, 800, 60, 100, ve=-20, t=T + 4.0), T + 4.0)
    assert manoeuvres(av.on_timer(T + 4.0))  # not heard for 4 s: widened by 80 m


def test_a_rover_and_a_plane() -> None:
    """A plane low over a rover's road: the plane climbs, the rover stops."""
    plane = status(1, -400, 0, 12, ve=20)  # 12 m over the rover in 20 s
    rover = status(2, 0, -60, 0, vn=3)
    infos = [
        VehicleInfo(vehicle_id=1, vehicle_type=VehicleType.PLANE, model="", user_id=""),
        VehicleInfo(vehicle_id=2, vehicle_type=VehicleType.ROVER, model="", user_id=""),
    ]
    av_plane, av_rover = avoider(1), avoider(2, VehicleType.ROVER)
    for av in (av_plane, av_rover):
        for i in infos:
            av.handle(i, T)
    (m,) = manoeuvres(feed(av_plane, [plane, rover]))
    assert m.kind is ManoeuvreKind.CLIMB and m.target_alt_rel_m == pytest.approx(15.0, abs=0.1)
    (r,) = manoeuvres(feed(av_rover, [plane, rover]))
    assert r.kind is ManoeuvreKind.STOP and r.requests == (SetMode(mode="HOLD"),)


def test_two_rovers_the_higher_id_stops() -> None:
    a = status(1, 0, 0, 0, ve=4)
    b = status(2, 100, -100, 0, vn=4)
    rover = VehicleType.ROVER
    infos = [VehicleInfo(vehicle_id=i, vehicle_type=rover, model="", user_id="") for i in (1, 2)]
    av1, av2 = avoider(1, rover), avoider(2, rover)
    for av in (av1, av2):
        for i in infos:
            av.handle(i, T)
    assert manoeuvres(feed(av1, [a, b])) == []
    (m,) = manoeuvres(feed(av2, [a, b]))
    assert m.kind is ManoeuvreKind.STOP


def test_a_multirotor_holds_over_itself_while_it_climbs() -> None:
    pair = [status(1, 0, 0, 100, ve=20), status(2, 200, 0, 100, ve=-20)]  # 4.5 s to the loss
    (m,) = manoeuvres(feed(avoider(2, VehicleType.COPTER), pair))
    (goto,) = m.requests
    assert isinstance(goto, Goto)
    assert (goto.lat_deg, goto.lon_deg) == (pair[1].lat_deg, pair[1].lon_deg)
    assert goto.alt_rel_m == pytest.approx(115.0, abs=0.01)


def test_a_non_cooperative_intruder_is_given_way_to_by_every_id() -> None:
    own = status(1, 0, 0, 100, ve=20)  # the lowest id: against a peer it would not climb
    lat, lon, h = pymap3d.enu2geodetic(1500, 0, 100, LAT0, LON0, HOME)
    intruder = Traffic(0xABCDEF, float(lat), float(lon), float(h), vel_east_m_s=-40.0, time_s=T)
    av = avoider(1)
    av.handle(intruder, T)
    (m,) = manoeuvres(feed(av, [own]))
    assert m.kind is ManoeuvreKind.CLIMB and m.against == (-1 - 0xABCDEF,)
    assert m.target_alt_rel_m is not None and m.target_alt_rel_m >= 115.0


def test_an_intruder_well_above_is_not_climbed_into() -> None:
    own = status(1, 0, 0, 100, ve=20, vu=3)
    lat, lon, h = pymap3d.enu2geodetic(800, 0, 112, LAT0, LON0, HOME)
    intruder = Traffic(0x123456, float(lat), float(lon), float(h), vel_east_m_s=-20.0, time_s=T)
    av = avoider(1)
    av.handle(intruder, T)
    (m,) = manoeuvres(feed(av, [own]))
    assert m.kind is ManoeuvreKind.LEVEL


def test_traffic_from_an_adsb_report() -> None:
    report = {
        "ICAO_address": 0x4CA123,
        "lat": 404168000,
        "lon": -37038000,
        "altitude": 950_000,
        "heading": 9000,
        "hor_velocity": 5000,
        "ver_velocity": -200,
        "flags": 1 | 2 | 4 | 8,
        "tslc": 1,
    }
    tr = Traffic.from_adsb(report, received_s=T)
    assert tr.contact_id == -1 - 0x4CA123
    assert (tr.lat_deg, tr.lon_deg, tr.alt_msl_m) == (40.4168, -3.7038, 950.0)
    assert tr.vel_east_m_s == pytest.approx(50.0) and tr.vel_north_m_s == pytest.approx(
        0.0, abs=1e-9
    )
    assert tr.vel_down_m_s == pytest.approx(2.0) and tr.time_s == T - 1
    for bad in (
        {**report, "flags": 8},
        {**report, "lat": None},
        {**report, "altitude": float("nan")},
    ):
        with pytest.raises(ValueError):
            Traffic.from_adsb(bad, received_s=T)


def test_ceiling_caps_the_climb_and_says_so() -> None:
    av = avoider(2)
    av.handle(Ceiling(alt_rel_m=108.0), T)
    out = feed(av, head_on())
    (m,) = manoeuvres(out)
    assert m.target_alt_rel_m == 108.0
    (alert,) = [o for o in out if isinstance(o, Alert)]
    assert alert.severity is Severity.CRITICAL and "ceiling" in alert.text


def test_a_climb_too_slow_for_the_conflict_is_critical() -> None:
    pair = [status(1, 0, 0, 100, ve=20), status(2, 200, 0, 100, ve=-20)]  # 5 s away
    out = feed(avoider(2, climb_rate_m_s=1.0), pair)
    (alert,) = [o for o in out if isinstance(o, Alert)]
    assert alert.severity is Severity.CRITICAL and "to climb" in alert.text


def test_not_flying_means_no_manoeuvre() -> None:
    low = [status(1, 0, 0, 5, ve=20), status(2, 800, 0, 5, ve=-20)]
    assert feed(avoider(2), low) == []
    disarmed = [status(1, 0, 0, 100, ve=20), status(2, 800, 0, 100, ve=-20, armed=False)]
    assert feed(avoider(2), disarmed) == []


def test_a_disarmed_or_landing_peer_will_not_manoeuvre_so_we_do() -> None:
    pair = [status(1, 0, 0, 5, ve=20), status(2, 800, 0, 12, ve=-20)]  # 1 below 10 m
    (m,) = manoeuvres(feed(avoider(2), pair))
    assert m.kind is ManoeuvreKind.CLIMB


def test_hysteresis_resume_only_after_clear_for_the_hold_time() -> None:
    av = avoider(2, clear_hold_s=3.0)
    av.handle(PlannedAltitude(alt_rel_m=100.0), T)
    assert manoeuvres(feed(av, head_on()))
    # a tick later the peer is gone (lost): clear from the planned altitude
    av.handle(Forget(vehicle_id=1), T + 0.2)
    now, resumed_at = T + 0.2, None
    while now < T + 6:
        ms = manoeuvres(feed(av, [status(2, 0, 0, 110, ve=-20, t=now)], now))
        if ms:
            assert [m.kind for m in ms] == [ManoeuvreKind.RESUME]
            assert ms[0].requests == (ChangeAltitude(alt_rel_m=100.0),)
            resumed_at = now
            break
        now += 0.2
    assert resumed_at is not None and resumed_at - (T + 0.2) >= 3.0 - 1e-6
    assert av.manoeuvring is None


def test_the_deadline_is_the_next_5hz_tick() -> None:
    av = avoider(2)
    assert av.next_deadline() is None
    av.handle(head_on()[0], T)
    assert av.next_deadline() == T
    av.on_timer(T)
    assert av.next_deadline() == pytest.approx(T + 0.2)
    assert av.on_timer(T + 0.1) == []  # early: nothing
    av.on_timer(T + 5.0)  # called late: the next tick is a period later, not now again
    assert av.next_deadline() == pytest.approx(T + 5.2)
    ticks = av.counters["ticks"]
    assert av.on_timer(T + 5.0) == [] and av.counters["ticks"] == ticks


def test_bad_input_is_counted_not_raised() -> None:
    av = avoider(2)
    av.handle(Traffic(1, float("nan"), 0.0, 100.0, time_s=T), T)
    assert av.counters["bad_track"] == 1
    assert feed(av, head_on()[1:]) == []


@settings(max_examples=examples(150), deadline=None)
@given(
    st.floats(-800, 800),
    st.floats(-800, 800),
    st.floats(20, 300),
    st.floats(20, 300),
    st.floats(0, 359),
    st.floats(0, 359),
    st.integers(1, 250),
    st.integers(1, 250),
)
def test_two_aircraft_never_both_climb_and_the_lower_never_does(
    e: float, n: float, za: float, zb: float, ca: float, cb: float, ida: int, idb: int
) -> None:
    if ida == idb:
        idb = ida % 250 + 1
    rad_a, rad_b = np.radians(ca), np.radians(cb)
    a = status(ida, 0, 0, za, ve=20 * np.sin(rad_a), vn=20 * np.cos(rad_a))
    b = status(idb, e, n, zb, ve=20 * np.sin(rad_b), vn=20 * np.cos(rad_b))
    climbs = {}
    for s in (a, b):
        ms = manoeuvres(feed(avoider(s.vehicle_id), [a, b]))
        climbs[s.vehicle_id] = bool(ms) and ms[0].kind is ManoeuvreKind.CLIMB
    assert not (climbs[ida] and climbs[idb])
    if abs(za - zb) > 5.0:
        lower = ida if za < zb else idb
        assert not climbs[lower]


# --------------------------------------------------------------------------- fast time


def separations(samples: list[tuple[float, int, float, float, float]]) -> list[float]:
    """Pairwise 3-D distances at every time step, by an independent ECEF sum."""
    by_t: dict[float, dict[int, np.ndarray]] = {}
    for t, v, lat, lon, h in samples:
        by_t.setdefault(t, {})[v] = np.array(pymap3d.geodetic2ecef(lat, lon, h))
    return [
        float(np.linalg.norm(pts[i] - pts[j]))
        for pts in by_t.values()
        for i, j in itertools.combinations(sorted(pts), 2)
    ]


def test_eight_fixed_wing_head_on_keep_apart_with_avoidance_and_collide_without() -> None:
    on = run(stress_eight_headon(), duration_s=70.0, avoid=True)
    off = run(stress_eight_headon(), duration_s=70.0, avoid=False)
    d_on, d_off = separations(on.samples), separations(off.samples)
    assert min(d_off) < 5.0 and sum(d < 5.0 for d in d_off) > 0  # the test can fail
    assert min(d_on) > 10.0  # no danger (5-10 m), no near-collision (< 5 m)
    for vid, ms in on.manoeuvres.items():
        kinds = [m.kind for m in ms]
        if vid == 1:
            assert kinds == []  # the lowest rank keeps its altitude
        else:  # no oscillation: one climb, one resume
            assert kinds == [ManoeuvreKind.CLIMB, ManoeuvreKind.RESUME]


def test_a_copter_a_plane_and_a_rover_cross_in_fast_time() -> None:
    starts = [
        Start(1, VehicleType.PLANE, -600, 0, 20, 20, 0),
        Start(2, VehicleType.COPTER, 0, -300, 22, 0, 10),
        Start(3, VehicleType.ROVER, 150, -150, 0, -5, 5, climb_rate_m_s=0.0),
    ]
    on = run(starts, duration_s=60.0, avoid=True)
    assert min(separations(on.samples)) > 10.0
    off = run(starts, duration_s=60.0, avoid=False)
    assert min(separations(off.samples)) < 5.0


def test_release_needs_the_release_distance_not_just_the_protection_one() -> None:
    """Clear means every miss from the planned altitude above 30 m: a peer parked
    25 m from where we would fly keeps the manoeuvre on (no resume, no oscillation)."""
    av = avoider(2, clear_hold_s=0.0)
    av.handle(PlannedAltitude(alt_rel_m=100.0), T)
    assert manoeuvres(feed(av, head_on()))
    now = T + 0.2
    # the peer now hovers 25 m east of our path, our own climb done (115 m)
    near = [status(1, 0, 25, 100, t=now), status(2, -300, 0, 115, ve=20, t=now)]
    for _ in range(10):
        assert manoeuvres(feed(av, near, now)) == []
        now += 0.2
    far = [status(1, 0, 45, 100, t=now), status(2, -300, 0, 115, ve=20, t=now)]
    (m,) = manoeuvres(feed(av, far, now))
    assert m.kind is ManoeuvreKind.RESUME


def test_altitudes_are_compared_above_mean_sea_level_not_home() -> None:
    """Same height above their homes, but 1's home is 10 m higher: 1 is the higher
    aircraft and climbs, although 2 has the higher id."""
    a = status(1, 0, 0, 100, ve=20)
    a = msgspec.structs.replace(a, alt_msl_m=a.alt_msl_m + 10.0)
    b = status(2, 800, 0, 100, ve=-20)
    assert manoeuvres(feed(avoider(2), [a, b])) == []
    (m,) = manoeuvres(feed(avoider(1), [a, b]))
    assert m.kind is ManoeuvreKind.CLIMB
    assert m.target_alt_rel_m == pytest.approx(105.0, abs=0.01)  # 15 m over 2, in 1's terms


def test_a_band_cycle_falls_back_to_altitude_then_id() -> None:
    """3 over 2 by id, 2 over 1 by id, 1 over 3 by 8 m: a cycle; ranked by altitude
    alone instead, the lowest keeps its altitude and each other climbs 15 m above the
    one below it."""
    three = [
        status(3, -600, 0, 100, ve=20),
        status(2, 600, 0, 104, ve=-20),
        status(1, 0, -600, 108, vn=20),
    ]
    targets = {}
    for vid in (1, 2, 3):
        ms = manoeuvres(feed(avoider(vid), three))
        targets[vid] = ms[0].target_alt_rel_m if ms else None
    assert targets[3] is None  # the lowest
    assert targets[2] == pytest.approx(115.0, abs=0.01)
    assert targets[1] == pytest.approx(130.0, abs=0.01)


@settings(max_examples=examples(60), deadline=None)
@given(
    st.lists(
        st.tuples(st.integers(1, 60), st.floats(95, 112), st.floats(300, 700)),
        min_size=3,
        max_size=6,
        unique_by=lambda v: v[0],
    ),
    st.floats(0, 360),
)
def test_many_converging_aircraft_end_up_in_layers_every_vehicle_agrees_on(
    fleet: list[tuple[int, float, float]], phase_deg: float
) -> None:
    """N aircraft converging on one point at random altitudes (ties, bands and cycles
    included), each deciding alone from the same reports: the altitudes they will fly
    (their targets, or their own altitude when they keep it) are all at least the
    vertical separation apart (less the 0.5 m a vehicle does not climb for)."""
    statuses = []
    for k, (vid, alt, radius) in enumerate(fleet):
        ang = np.radians(phase_deg + 360.0 * k / len(fleet))
        e, n = radius * np.cos(ang), radius * np.sin(ang)
        speed = radius / 25.0  # all at the centre in 25 s
        statuses.append(status(vid, e, n, alt, ve=-speed * np.cos(ang), vn=-speed * np.sin(ang)))
    final = []
    for s in statuses:
        ms = manoeuvres(feed(avoider(s.vehicle_id), statuses))
        assert all(m.kind is ManoeuvreKind.CLIMB for m in ms)
        final.append(ms[0].target_alt_rel_m if ms else s.alt_rel_m)
    final.sort()
    assert all(b - a >= 15.0 - 0.5 - 1e-6 for a, b in itertools.pairwise(final)), final


def test_a_non_cooperative_intruder_in_fast_time() -> None:
    """A manned aircraft (ADS-B at 1 Hz, no avoider) flies through two crossing drones
    at their altitude: the drones climb over it, it never changes anything."""
    starts = [
        Start(1, VehicleType.PLANE, -500, 0, 100, 20, 0),
        Start(2, VehicleType.PLANE, 0, -500, 100, 0, 20),
        Start(9, VehicleType.MANNED, 700, 700, 100, -28, -28, cooperative=False),
    ]
    on = run(starts, duration_s=60.0, avoid=True)
    assert on.manoeuvres[9] == []
    intruder_alts = [s[4] for s in on.samples if s[1] == 9]
    assert max(intruder_alts) - min(intruder_alts) < 0.5  # it never climbed (curvature: 0.15 m)
    assert min(separations(on.samples)) > 10.0
    off = run(starts, duration_s=60.0, avoid=False)
    assert min(separations(off.samples)) < 5.0


def test_in_the_band_a_fixed_wing_climbs_before_a_multirotor_once_types_are_known() -> None:
    """A VTOL (id 1) and a quadcopter (id 7) head-on at one altitude: with both types
    known (VehicleInfo) the VTOL climbs, whatever the ids; each side decides alike. With
    the peer's type unknown the higher id climbs (the rule every report allows)."""

    def info(vid: int, vtype: VehicleType) -> VehicleInfo:
        return VehicleInfo(vehicle_id=vid, vehicle_type=vtype, model="m", user_id=f"U{vid}")

    pair = [status(1, 0, 0, 100, ve=20), status(7, 800, 0, 100, ve=-10)]
    vtol = avoider(1, VehicleType.VTOL)
    copter = avoider(7, VehicleType.COPTER)
    vtol.handle(info(7, VehicleType.COPTER), T)
    copter.handle(info(1, VehicleType.VTOL), T)
    (m,) = manoeuvres(feed(vtol, pair))
    assert m.kind is ManoeuvreKind.CLIMB
    assert manoeuvres(feed(copter, pair)) == []
    # the VTOL has not heard the copter's VehicleInfo: ids decide, the copter (7) climbs
    assert manoeuvres(feed(avoider(1, VehicleType.VTOL), pair)) == []


def test_two_stacked_multirotors_never_hold_each_other_up() -> None:
    """9 climbed to 45 m for 7, 8 climbed to 60 m over 9; 7 has gone. 9 going back to
    30 m brings it no closer to 8 above it, so 9 goes back (then 8 once 9 has flown
    on): neither waits for the other for good (measured in FastFleet before: both
    hovered there until BATTERY_CRITICAL)."""
    av9 = avoider(9, VehicleType.COPTER, clear_hold_s=0.0)
    av8 = avoider(8, VehicleType.COPTER, clear_hold_s=0.0)
    for av in (av8, av9):
        av.handle(PlannedAltitude(alt_rel_m=30.0), T)
    assert manoeuvres(feed(av9, [status(7, 40, 0, 30, ve=-5), status(9, 0, 0, 30)]))
    assert manoeuvres(feed(av8, [status(9, 10, 0, 30), status(8, 0, 0, 36)]))
    av9.handle(Forget(7), T)
    now, resumed9, resumed8 = T, [], []
    here9, here8 = status(9, 0, 0, 45), status(8, 2, 0, 60)  # hovering, 8 over 9
    while now < T + 10 and not resumed9:
        now += 0.2
        # the peer's report as heard: 0.4 s old (its protection volume widened by it)
        here9 = msgspec.structs.replace(here9, time_unix_s=now)
        here8 = msgspec.structs.replace(here8, time_unix_s=now - 0.4)
        resumed9 = [
            m for m in manoeuvres(feed(av9, [here9, here8], now)) if m.kind is ManoeuvreKind.RESUME
        ]
        out8 = manoeuvres(feed(av8, [here9, here8], now))
        assert all(m.kind is not ManoeuvreKind.RESUME for m in out8)  # 8 waits while 9 is under it
    assert resumed9 and resumed9[0].target_alt_rel_m == 30.0
    # 9 back at 30 m flies on; 8 is then clear too
    while now < T + 20 and not resumed8:
        now += 0.2
        gone = T + 10 + 0.0
        here9 = status(9, 0, 80 + 10 * (now - gone), 30, vn=10, t=now)
        here8 = msgspec.structs.replace(here8, time_unix_s=now)
        here9 = msgspec.structs.replace(here9, time_unix_s=now - 0.4)
        resumed8 = [
            m for m in manoeuvres(feed(av8, [here9, here8], now)) if m.kind is ManoeuvreKind.RESUME
        ]
    assert resumed8 and resumed8[0].target_alt_rel_m == 30.0


def copters_head_on(t: float, gap_m: float = 600.0) -> list[VehicleStatus]:
    """Two quadcopters at 30 m flying at each other at 10 m/s, `gap_m` apart at T."""
    d = 10.0 * (t - T)
    return [status(1, gap_m - d, 0, 30, ve=-10, t=t), status(2, d, 0, 30, ve=10, t=t)]


def test_a_multirotor_in_level_flight_acts_within_the_time_it_needs_not_30_s_ahead() -> None:
    """The separation is lost 29 s ahead; quadcopter 2 gives way. It needs 6 s to climb
    15 m at 2.5 m/s (and 4 s to stop from 10 m/s, at once): it climbs when the loss is
    11 s ahead (6 s + the 5 s margin), with its climb done 5 s before it; a fixed-wing in
    the same place climbs at once (it cannot stop, its climb on its path costs nothing)."""
    av = avoider(2, VehicleType.COPTER, climb_rate_m_s=2.5)
    now, first = T, None
    while first is None and now < T + 30:
        first = next(iter(manoeuvres(feed(av, copters_head_on(now), now))), None)
        now += 0.2
    assert first is not None and first.kind is ManoeuvreKind.CLIMB
    loss_s = (600.0 - 20.0) / 20.0 - (now - 0.2 - T)
    assert 10.8 <= loss_s <= 11.0 + 1e-6
    assert av.counters["deferred_ticks"] > 80
    assert av.time_to_act_s(copters_head_on(T)[1], HOME + 45.0) == pytest.approx(11.0)
    plane = avoider(2, VehicleType.PLANE, climb_rate_m_s=2.5)
    assert manoeuvres(feed(plane, copters_head_on(T)))


def test_a_multirotor_climbing_or_descending_acts_at_once() -> None:
    """Taking off or landing, its vertical motion is the prediction's weak part: no
    deferral (measured: deferred, three quadcopters taking off under each other met
    in a conflict 1 s ahead that no climb could resolve)."""
    pair = copters_head_on(T)
    pair[1] = msgspec.structs.replace(pair[1], vel_down_m_s=-2.5)
    assert manoeuvres(feed(avoider(2, VehicleType.COPTER, climb_rate_m_s=2.5), pair))


def test_two_multirotors_head_on_in_fast_time_one_climb_not_a_cycle() -> None:
    """Point-mass, two quadcopters head-on from 600 m: the one that gives way climbs once
    and comes back once, 15 m over the other. Acting 30 s ahead, it stopped (a Goto),
    its prediction then cleared (the closing speed halved, the approach beyond the
    horizon) and it flew on into the conflict again: seven climbs and resumes."""
    starts = [
        Start(1, VehicleType.COPTER, 0, 0, 30, 10, 0, climb_rate_m_s=2.5, sink_rate_m_s=1.5),
        Start(2, VehicleType.COPTER, 600, 0, 30, -10, 0, climb_rate_m_s=2.5, sink_rate_m_s=1.5),
    ]
    now = run(starts, duration_s=60.0, avoid=True, config={"climb_rate_m_s": 2.5})
    kinds = [m.kind for m in now.manoeuvres[2]]
    assert kinds == [ManoeuvreKind.CLIMB, ManoeuvreKind.RESUME] and now.manoeuvres[1] == []
    assert min(separations(now.samples)) >= 14.9
    early = run(
        starts, duration_s=60.0, avoid=True, config={"climb_rate_m_s": 2.5, "act_margin_s": 30.0}
    )
    assert len(early.manoeuvres[2]) > 4
    assert min(separations(early.samples)) >= 14.9


def test_a_multirotor_on_its_route_does_not_climb_for_what_its_lane_end_turns_it_from() -> None:
    """Quadcopter 8 flies east at 10 m/s, 7 hovers 60 m ahead at its altitude: straight
    on, the loss is 4 s ahead and 8 climbs. Its mission turns it north at the lane's end
    20 m ahead (its own route, which it knows): 40 m from 7 at the closest, no climb. A
    route that goes on to 7 is a conflict again."""
    pair = [status(7, 60, 0, 30), status(8, 0, 0, 30, ve=10)]
    at = [
        pymap3d.enu2geodetic(e, n, 0.0, LAT0, LON0, HOME)[:2]
        for e, n in ((20, 0), (20, 200), (200, 0))
    ]
    turn = OwnRoute(((*at[0], 30.0), (*at[1], 30.0)), 10.0)
    ahead = OwnRoute(((*at[2], 30.0),), 10.0)
    assert manoeuvres(feed(avoider(8, VehicleType.COPTER, climb_rate_m_s=2.5), pair))
    av = avoider(8, VehicleType.COPTER, climb_rate_m_s=2.5)
    av.handle(turn, T)
    assert feed(av, pair) == []
    av = avoider(8, VehicleType.COPTER, climb_rate_m_s=2.5)
    av.handle(ahead, T)
    assert manoeuvres(feed(av, pair))
    plane = avoider(8, VehicleType.PLANE)  # a fixed-wing's route is not used: it acts
    plane.handle(turn, T)
    assert manoeuvres(feed(plane, pair))


def test_two_hovering_vtols_30_m_apart_do_not_hold_each_other_for_good() -> None:
    """`swarm-sim demo --radio`: VTOLs 1 and 2, climbed over their pads 30 m apart,
    hover waiting for their PREMISSION meet. Over the radio a peer is a prediction
    with its error bound (up to 8 m between its 1 s heartbeats): once inside 20 m
    with it, 1 climbed; then, both hovering, the miss from its planned altitude less
    the bound stayed under the 30 m release for good, and the climb (a Goto that holds
    the mission) kept 1 from ever starting its leg. Waiting cannot change a still pair:
    outside the conflict distance (20 m) it does not hold the release."""
    av = avoider(1, VehicleType.VTOL, clear_hold_s=0.0)
    av.handle(PlannedAltitude(alt_rel_m=80.0), T)

    def peer(now: float, error_m: float) -> VehicleStatus:
        s = status(2, 30, 0, 72, t=now)
        return msgspec.structs.replace(s, position_error_m=error_m)

    assert manoeuvres(feed(av, [status(1, 0, 0, 82), peer(T, 12.0)]))  # 30 - 12 < 20
    now, resumed = T, []
    while now < T + 20 and not resumed:
        now += 0.2
        error = 2.0 + 6.0 * ((now - T) % 1.0)  # the bound between heartbeats: 2-8 m
        out = feed(av, [status(1, 0, 0, 83, t=now), peer(now, error)], now)
        resumed = [m for m in manoeuvres(out) if m.kind is ManoeuvreKind.RESUME]
    assert resumed and resumed[0].target_alt_rel_m == 80.0
    # a still pair inside the conflict distance is still held apart
    av = avoider(1, VehicleType.VTOL, clear_hold_s=0.0)
    av.handle(PlannedAltitude(alt_rel_m=80.0), T)
    assert manoeuvres(feed(av, [status(1, 0, 0, 82), status(2, 12, 0, 75)]))
    for i in range(50):
        now = T + 0.2 * (i + 1)
        out = feed(av, [status(1, 0, 0, 95, t=now), status(2, 12, 0, 75, t=now)], now)
        assert not [m for m in manoeuvres(out) if m.kind is ManoeuvreKind.RESUME]


@settings(max_examples=examples(120), deadline=None)
@given(
    n=st.integers(min_value=9, max_value=40),
    spread=st.sampled_from([300.0, 2000.0, 8000.0]),
    seed=st.integers(min_value=0, max_value=10_000),
    planned=st.booleans(),
)
def test_leaving_out_contacts_beyond_reach_changes_no_decision(
    n: int, spread: float, seed: float, planned: bool
) -> None:
    """A flying node's decision looks only at its cluster (the contacts that
    could come within the largest threshold of it, or of one that could, inside the
    horizon): the same decision as over the whole swarm."""
    import random

    rnd = random.Random(seed)
    av = avoider(1)
    own = status(1, 0.0, 0.0, 100.0, ve=22.0)

    def anyone(i: int) -> VehicleStatus:
        e, n_, up = (
            rnd.uniform(-spread, spread),
            rnd.uniform(-spread, spread),
            rnd.uniform(60.0, 140.0),
        )
        v = (rnd.uniform(-25.0, 25.0), rnd.uniform(-25.0, 25.0), rnd.uniform(-2.0, 2.0))
        return status(i, e, n_, up, ve=v[0], vn=v[1], vu=v[2])

    others = [anyone(i) for i in range(2, n + 2)]
    feed(av, [own, *others])
    pruned = av._decide(own, T, planned=planned)
    av._within_reach = lambda k: None  # type: ignore[method-assign]
    whole = av._decide(own, T, planned=planned)
    assert (pruned.kind, pruned.target_msl_m, sorted(pruned.against)) == (
        whole.kind,
        whole.target_msl_m,
        sorted(whole.against),
    )
    if not planned and pruned.against:
        assert pruned.soonest_s == pytest.approx(whole.soonest_s)
        assert pruned.closest_m == pytest.approx(whole.closest_m)


@given(
    st.lists(st.tuples(st.sampled_from(["status", "info", "gcs"]), st.integers(1, 5)), max_size=20),
    st.booleans(),
)
def test_a_run_heard_at_once_is_the_same_as_one_by_one(run: list, statuses_only: bool) -> None:
    """`heard_all` (a node hearing a batch) keeps what `heard` (statuses) and
    `handle` (infos; a ground station's is no traffic) keep, message by message."""
    if statuses_only:
        run = [("status", vid) for _what, vid in run]

    def message(what: str, vid: int) -> VehicleStatus | VehicleInfo:
        if what == "status":
            return status(vid, 10.0 * vid, 0.0, 30.0)
        vtype = VehicleType.GCS if what == "gcs" else VehicleType.COPTER
        return VehicleInfo(vid, vtype, "m", "u")

    one, bulk = avoider(1, VehicleType.COPTER), avoider(1, VehicleType.COPTER)
    for av in (one, bulk):  # known contacts before the run
        for vid in (2, 3):
            av.heard(status(vid, 5.0, 5.0, 30.0), T - 1.0)
        av.on_timer(T - 1.0)
    msgs = [message(what, vid) for what, vid in run]
    for m in msgs:
        one.heard(m, T) if isinstance(m, VehicleStatus) else one.handle(m, T)
    bulk.heard_all(msgs, T, statuses_only=statuses_only)
    for name in ("_heard", "_types", "_contacts", "_own", "_own_received", "_next"):
        assert repr(getattr(bulk, name)) == repr(getattr(one, name)), name
