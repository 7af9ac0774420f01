"""The PREMISSION meet and the MISSION speed rule as the mission manager runs them
(`mission/fleet_sync.py`): who meets, the meet time every node agrees on, the leg from
where the vehicle is, the airspeed it commands."""

from __future__ import annotations

import math
import random

import msgspec
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from swarm_node.core.autopilot.items import ItemKind
from swarm_node.core.autopilot.state import AutopilotState
from swarm_node.core.mission import fleet_sync
from swarm_node.core.mission.fleet_sync import FleetSync, sync_group
from swarm_node.core.planning import PlanVehicle, VehiclePose
from swarm_node.core.planning.fleet_plan import FleetPlan, plan_fleet
from swarm_node.core.profile import VehicleProfile
from swarm_proto import Geometry, GeoPoint, Mission, MissionParams, MissionType, VehicleType
from tests.conftest import examples

LA, LO = 40.4168, -3.7038
AREA = Geometry.polygon(
    [
        (LA + 0.004, LO - 0.003),
        (LA + 0.004, LO + 0.003),
        (LA + 0.008, LO + 0.003),
        (LA + 0.008, LO - 0.003),
    ]
)


def _profile(vid: int) -> VehicleProfile:
    return VehicleProfile(vid, str(vid), "Albatross 250 VTOL", VehicleType.VTOL)


def fleet_of(profiles: dict[int, VehicleProfile], ids: list[int]) -> list[PlanVehicle]:
    return [PlanVehicle(profiles[v], VehiclePose(LA, LO + 0.0007 * i)) for i, v in enumerate(ids)]


def plan(
    profiles: dict[int, VehicleProfile], ids: list[int], kind: MissionType = MissionType.AREA
) -> FleetPlan:
    geometry = AREA if kind == MissionType.AREA else Geometry.point(LA + 0.006, LO)
    params = MissionParams(altitude_rel_m=80.0, side_overlap=0.2, altitude_step_m=10.0)
    mission = Mission(5, 900, kind, geometry, params)
    return plan_fleet(
        mission, fleet_of(profiles, ids), zones=[], now_unix_s=0.0, home_alt_msl_m=0.0
    )


def on_ground(lat: float, lon: float, heading: float = 0.0) -> AutopilotState:
    return AutopilotState(
        lat_deg=lat, lon_deg=lon, alt_rel_m=0.0, heading_deg=heading, home=GeoPoint(lat, lon, 600.0)
    )


def test_the_sync_group_is_the_fixed_wing_members_of_two_or_more(fleet_profiles: dict) -> None:
    """The paper: no PREMISSION for vehicles that are not fixed-wing, nor for one
    vehicle alone."""
    assert sync_group(plan(fleet_profiles, [1, 2, 7])) == (1, 2)
    assert sync_group(plan(fleet_profiles, [1, 7, 8])) == ()  # one fixed-wing
    assert sync_group(plan(fleet_profiles, [7, 8], MissionType.TARGET)) == ()
    assert sync_group(plan(fleet_profiles, [1, 2, 3], MissionType.TARGET)) == (1, 2, 3)


def test_the_switch_turns_the_meet_off(
    fleet_profiles: dict, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(fleet_sync, "PREMISSION", False)
    assert sync_group(plan(fleet_profiles, [1, 2])) == ()


@settings(max_examples=examples(50), deadline=None)
@given(
    st.dictionaries(st.integers(1, 6), st.floats(1.0e9, 1.0e9 + 500.0), min_size=5, max_size=5),
    st.randoms(use_true_random=False),
)
def test_every_node_meets_at_the_latest_eta_whatever_the_order(
    etas: dict, rnd: random.Random
) -> None:
    """The meet time is the latest ETA of the group's members still in the mission: the
    same on every node that heard the same ETAs, in any order; nothing until all are in."""
    group = tuple(sorted({*etas, 9}))
    times = []
    for me in [*etas][:3]:
        s = FleetSync(me, _profile(me))
        s.group, s.eta_unix_s = group, etas[me]
        heard = [(v, t) for v, t in etas.items() if v != me]
        rnd.shuffle(heard)
        assert s.meet_time(dict(heard), gone=()) is None  # 9 has not published yet
        times.append(s.meet_time({**dict(heard), 9: 1.0e9}, gone=()))
        assert s.meet_time(dict(heard), gone={9}) == max(etas.values())  # 9 was lost
    assert len(set(times)) == 1 and times[0] == max(etas.values())


def test_a_vehicle_waits_for_the_etas_then_goes_with_what_it_heard() -> None:
    s = FleetSync(1, _profile(1))
    s.group, s.eta_unix_s = (1, 2, 3), 100.0
    assert s.ready({2: 90.0}, (), now=50.0) is None
    assert s.ready({2: 90.0}, (), now=50.0 + fleet_sync.META_WAIT_S - 0.1) is None
    assert s.ready({2: 120.0}, (), now=50.0 + fleet_sync.META_WAIT_S) == 120.0


def test_a_hovering_vtol_waits_on_the_spot_and_flies_its_leg_at_mission_speed(
    fleet_profiles: dict,
) -> None:
    """The first ETA counts the climb; climbed, the leg to a later meet time leaves when
    the mission speed brings it to the entry on time; one that cannot make the meet
    time flies at its top speed and publishes a later ETA."""
    fp = plan(fleet_profiles, [1, 2])
    s = FleetSync(1, fleet_profiles[1])
    ground = on_ground(LA, LO)
    assert s.begin(fp, ground, [], 1000.0, 600.0, launch_s=30.0)
    first = s.eta_unix_s
    assert first > 1030.0 and s.info_due
    air = msgspec.structs.replace(ground, armed=True, alt_rel_m=80.0)
    late = first + 60.0
    wps = s.plan_leg(air, [], 1030.0, 600.0, late)
    leg = s.leg
    assert leg is not None and s.depart_unix_s > 1030.0  # waits in hover
    assert leg.speed_m_s == pytest.approx(26.0, abs=0.3)  # the mission speed
    assert s.meet_unix_s == pytest.approx(late)
    assert wps[: len(leg.waypoints)] == leg.waypoints
    assert s.entry_seq - 1 == max(
        k for k, w in enumerate(leg.waypoints) if w.kind == ItemKind.WAYPOINT
    )
    s2 = FleetSync(1, fleet_profiles[1])
    assert s2.begin(fp, ground, [], 1000.0, 600.0, launch_s=30.0)
    s2.info_due = False
    s2.plan_leg(air, [], 1030.0, 600.0, 1031.0)  # too soon for anyone
    assert s2.depart_unix_s == 1030.0 and s2.info_due and s2.eta_unix_s > 1031.0
    assert s2.leg is not None and s2.leg.speed_m_s > 29.0  # its top speed on its turns


def test_the_airspeed_brings_it_to_the_entry_on_time_and_then_keeps_the_fleet_together(
    fleet_profiles: dict,
) -> None:
    fp = plan(fleet_profiles, [1, 2])
    s = FleetSync(1, fleet_profiles[1])
    ground = on_ground(LA, LO)
    assert s.begin(fp, ground, [], 0.0, 600.0, launch_s=30.0)
    air = msgspec.structs.replace(
        ground, armed=True, alt_rel_m=80.0, airspeed_m_s=26.0, groundspeed_m_s=26.0
    )
    s.plan_leg(air, [], 30.0, 600.0, 100.0)
    assert s.leg is not None
    t = s.depart_unix_s + 5.0
    # on the leg, little left and plenty of time: slow; much left, little time: fast
    slow = s.control(air, t, 2, 0.0, t + 100.0, {}, ())
    assert slow is not None and slow < 20.0
    fast = s.control(air, t + 1.0, 2, 0.0, t + 2.0, {}, ())
    assert fast is not None and fast > 29.0
    # past the entry: behind the other member -> faster, ahead -> slower, in the band: mission speed
    entry = s.entry_along_m[1]
    s.control(air, t + 2.0, s.entry_seq, entry, t, {}, ())
    assert s.arrived_at == t + 2.0
    other_entry = s.entry_along_m[2]
    at = t + 100.0
    on_time = entry + 100.0 * 26.0  # 100 s after the meet at the mission speed
    peers_ahead = {2: (other_entry + 100.0 * 26.0 + 400.0, 0.0)}
    peers_behind = {2: (other_entry + 100.0 * 26.0 - 400.0, 0.0)}
    up = s.control(air, at, s.entry_seq + 3, on_time, t, peers_ahead, ())
    assert up is not None and up > 26.5
    down = s.control(air, at + 1.0, s.entry_seq + 3, on_time, t, peers_behind, ())
    assert down is not None and down < 25.5
    nominal = s.control(
        air, at + 2.0, s.entry_seq + 3, on_time, t, {2: (other_entry + 100.0 * 26.0, 0.0)}, ()
    )
    assert nominal == pytest.approx(26.0)
    # a member lost is not waited for
    assert s.control(air, at + 3.0, s.entry_seq + 3, on_time, t, peers_behind, {2}) is None


def test_an_airspeed_the_autopilot_does_not_fly_is_sent_again(fleet_profiles: dict) -> None:
    """A VTOL's transition or the mission's CHANGE_SPEED item took over: the command is
    repeated after RESEND_S, not only when it changes."""
    fp = plan(fleet_profiles, [1, 2])
    s = FleetSync(1, fleet_profiles[1])
    ground = on_ground(LA, LO)
    assert s.begin(fp, ground, [], 0.0, 600.0, launch_s=0.0)
    air = msgspec.structs.replace(
        ground, armed=True, alt_rel_m=80.0, airspeed_m_s=26.0, groundspeed_m_s=26.0
    )
    s.plan_leg(air, [], 0.0, 600.0, 200.0)
    t = s.depart_unix_s + 1.0
    v = s.control(air, t, 2, 0.0, t + 100.0, {}, ())
    assert v is not None
    assert s.control(air, t + 1.0, 2, 0.0, t + 100.0, {}, ()) is None  # the same: not again
    again = s.control(air, t + 1.0 + fleet_sync.RESEND_S, 2, 0.0, t + 100.0, {}, ())
    assert again is not None and math.isclose(again, v, abs_tol=fleet_sync.SPEED_STEP_M_S)
    flown = msgspec.structs.replace(air, airspeed_m_s=again)
    assert s.control(flown, t + 2.0 + 2 * fleet_sync.RESEND_S, 2, 0.0, t + 100.0, {}, ()) is None
