"""The mission layer over real node processes on loopback Zenoh, each flying a
simulated vehicle over MAVLink: planning runs off the control loop."""

from __future__ import annotations

import math
import os
import queue
import time
from collections.abc import Iterator
from pathlib import Path

import msgspec
import pytest

from swarm_proto import (
    Ack,
    AckReason,
    AckRef,
    Command,
    CommandArgs,
    CommandKind,
    DetailCode,
    FsmState,
    Geometry,
    GeoPoint,
    Mission,
    MissionParams,
    MissionState,
    MissionType,
    Selector,
    VehicleStatus,
)
from swarm_sim.core import SITL_HOME
from swarm_sim.runtime import VehicleSpec, spread_homes
from tests.swarm_node.processes import nodes, peers_of, plain_session, served, wait_until

pytestmark = pytest.mark.network
GCS = 900


def wavy_area(n: int, lat0: float, lon0: float, radius_m: float = 150.0) -> Geometry:
    """A valid polygon of `n` vertices (a wavy circle)."""
    pts = []
    for i in range(n):
        a = 2 * math.pi * i / n
        r = radius_m + 0.13 * radius_m * math.sin(7 * a)
        pts.append(
            (
                lat0 + r * math.sin(a) / 111_320.0,
                lon0 + r * math.cos(a) / (111_320.0 * math.cos(math.radians(lat0))),
            )
        )
    return Geometry.polygon(pts)


@pytest.fixture
def swarm(request: pytest.FixtureRequest) -> str:
    return f"m{os.getpid()}{abs(hash(request.node.name)) % 10000}"


@pytest.fixture
def vehicles(request: pytest.FixtureRequest) -> Iterator[dict[int, str]]:
    models: dict[int, str] = request.param
    homes = spread_homes(SITL_HOME, len(models), 30.0)
    specs = {
        vid: VehicleSpec(model, instance=i, port=0, home=homes[i], sysid=vid)
        for i, (vid, model) in enumerate(models.items())
    }
    with served(specs) as ports:
        yield {vid: f"tcp:127.0.0.1:{port}" for vid, port in ports.items()}


class Watch:
    """Every status and ack of the swarm, as they arrive (with their arrival time)."""

    def __init__(self, session: object, swarm: str) -> None:
        self.statuses: queue.Queue[tuple[float, VehicleStatus]] = queue.Queue()
        self.acks: queue.Queue[Ack] = queue.Queue()
        self.subs = [
            session.declare_subscriber(  # type: ignore[attr-defined]
                f"bandada/{swarm}/vehicle/*/status",
                lambda s: self.statuses.put(
                    (
                        time.monotonic(),
                        msgspec.msgpack.decode(s.payload.to_bytes(), type=VehicleStatus),
                    )
                ),
            ),
            session.declare_subscriber(  # type: ignore[attr-defined]
                f"bandada/{swarm}/vehicle/*/ack",
                lambda s: self.acks.put(msgspec.msgpack.decode(s.payload.to_bytes(), type=Ack)),
            ),
        ]

    def close(self) -> None:
        for s in self.subs:
            s.undeclare()


def send(client: object, swarm: str, msg: Command | Mission) -> None:
    key = f"cmd/{GCS}" if isinstance(msg, Command) else f"mission/{msg.mission_id}"
    client.put(f"bandada/{swarm}/{key}", msgspec.msgpack.encode(msg))  # type: ignore[attr-defined]


def activate(client: object, swarm: str, watch: Watch, ids: list[int]) -> None:
    base = GeoPoint(SITL_HOME.lat_deg, SITL_HOME.lon_deg, SITL_HOME.alt_m)
    for i in ids:
        assert wait_until(lambda i=i: peers_of(client, swarm, i) is not None, timeout=60)
    send(client, swarm, Command(GCS, 1, CommandKind.SET_BASE, args=CommandArgs(point=base)))
    ready: set[int] = set()
    t_end = time.monotonic() + 90
    while ready != set(ids) and time.monotonic() < t_end:
        try:
            _, st = watch.statuses.get(timeout=1)
        except queue.Empty:
            continue
        if st.fsm_state == FsmState.GO_MISSION:
            ready.add(st.vehicle_id)
    assert ready == set(ids)


@pytest.mark.parametrize("vehicles", [{1: "vtol"}], indirect=True)
def test_planning_does_not_stall_status_or_commands(
    zenoh_router: str, swarm: str, vehicles: dict[int, str], swarm_db: object, tmp_path: Path
) -> None:
    """A valid 4,000-vertex area mission for a VTOL (its fixed-wing turns made flyable)
    takes a second or more to plan; meanwhile the node keeps publishing its 5 Hz status
    and answers a command (it used to stop for 4.9 s). Since the planner became fast
    a quadcopter's 150 m field plans in 0.1-0.4 s, too short to measure."""
    client = plain_session(zenoh_router)
    watch = Watch(client, swarm)
    try:
        with nodes([1], zenoh_router, swarm, autopilots=vehicles):
            activate(client, swarm, watch, [1])
            area = wavy_area(4000, SITL_HOME.lat_deg + 0.004, SITL_HOME.lon_deg, 300.0)
            planning: list[float] = []  # arrival times of statuses while PLANNING
            mission_acks: list[Ack] = []  # the node's answers to the missions sent
            acked_while_planning = False
            sent_command = False
            # The mission is sent again (under a new id) while the node has neither
            # answered it nor started planning: a put made while the router was still
            # learning the node's subscriptions on a loaded host is lost, and a
            # mission refused for a passing reason (home not yet set) is resent as an
            # operator would. Any other refusal fails the test with its reason.
            mission_id, sent_at = 50, 0.0
            t_end = time.monotonic() + 120
            while time.monotonic() < t_end:
                answered = any(a.accepted for a in mission_acks)
                if not planning and not answered and time.monotonic() - sent_at > 10.0:
                    mission_id += 1
                    params = MissionParams(altitude_rel_m=25.0)
                    send(client, swarm, Mission(mission_id, GCS, MissionType.AREA, area, params))
                    sent_at = time.monotonic()
                try:
                    t, st = watch.statuses.get(timeout=1)
                except queue.Empty:
                    continue
                if st.mission_state == MissionState.PLANNING:
                    planning.append(t)
                    if not sent_command:
                        send(
                            client,
                            swarm,
                            Command(GCS, 60, CommandKind.SET_FLEET, args=CommandArgs(fleet_id=3)),
                        )
                        sent_command = True
                elif st.mission_state in (MissionState.PREMISSION, MissionState.MISSION):
                    assert planning, "the plan was made between two 5 Hz statuses"
                    break
                while not watch.acks.empty():
                    ack = watch.acks.get()
                    if ack.ref == AckRef.MISSION:
                        mission_acks.append(ack)
                        transient = (AckReason.HOME_NOT_SET, AckReason.NOT_READY)
                        replaced = ack.reason == AckReason.BUSY and "replaced by" in ack.text
                        assert ack.accepted or ack.reason in transient or replaced, ack
                        if not ack.accepted:
                            sent_at = time.monotonic() - 9.0  # again in a second
                    if ack.ref_id == 60 and st.mission_state == MissionState.PLANNING:
                        acked_while_planning = True
            assert len(planning) >= 3, (planning, mission_acks)
            window = planning[-1] - planning[0]
            expected = window * 5.0  # status at 5 Hz
            ratio = (len(planning) - 1) / expected if expected else 1.0
            print(f"statuses while planning: {len(planning)} in {window:.1f} s (ratio {ratio:.2f})")
            assert ratio > 0.5
            assert acked_while_planning
    finally:
        watch.close()
        client.close()


# the verdict and its numbers, the same on every member: test_reasons_in_full.py (the
# fleet's plan, pure); a node refusing it over Zenoh: test_gcs_commands.py's
# test_a_mission_the_fleet_cannot_fly_is_refused_with_its_budget
@pytest.mark.soak
@pytest.mark.parametrize("vehicles", [{7: "copter", 8: "copter"}], indirect=True)
def test_a_mission_the_fleet_cannot_fly_is_refused_by_every_member_alike(
    zenoh_router: str, swarm: str, vehicles: dict[int, str], swarm_db: object
) -> None:
    """Two quadcopters sent a field far beyond their batteries: each answers only once
    the fleet's plan is made, both refuse it with the same reason and the endurance
    numbers, and neither takes off."""
    client = plain_session(zenoh_router)
    watch = Watch(client, swarm)
    try:
        with nodes([7, 8], zenoh_router, swarm, autopilots=vehicles):
            activate(client, swarm, watch, [7, 8])
            side = 1500.0
            lat0, lon0 = SITL_HOME.lat_deg + 0.001, SITL_HOME.lon_deg
            d_lat, d_lon = side / 111_320.0, side / (111_320.0 * math.cos(math.radians(lat0)))
            area = Geometry.polygon(
                [
                    (lat0, lon0),
                    (lat0, lon0 + d_lon),
                    (lat0 + d_lat, lon0 + d_lon),
                    (lat0 + d_lat, lon0),
                ]
            )
            m = Mission(
                70,
                GCS,
                MissionType.AREA,
                area,
                MissionParams(altitude_rel_m=40.0),
                Selector.ids(7, 8),
            )
            answers: dict[int, Ack] = {}
            t_end = time.monotonic() + 90  # two planners on a loaded 2-core host
            sent_at = 0.0
            while len(answers) < 2 and time.monotonic() < t_end:
                if not answers and time.monotonic() - sent_at > 15.0:
                    send(client, swarm, m)  # again: a put lost to a router still learning
                    sent_at = time.monotonic()
                try:
                    ack = watch.acks.get(timeout=1)
                except queue.Empty:
                    continue
                if ack.ref == AckRef.MISSION and ack.ref_id == 70:
                    answers[ack.vehicle_id] = ack
            assert set(answers) == {7, 8}, answers
            a7, a8 = answers[7], answers[8]
            assert (a7.accepted, a7.reason) == (False, AckReason.PLAN_FAILED), a7
            assert (a7.text, a7.detail) == (a8.text, a8.detail)
            assert a7.detail is not None and a7.detail.code == DetailCode.ENDURANCE
            assert a7.detail.needed_s > a7.detail.available_s > 0.0
            while not watch.statuses.empty():
                _, st = watch.statuses.get()
                assert not st.armed, st
    finally:
        watch.close()
        client.close()
