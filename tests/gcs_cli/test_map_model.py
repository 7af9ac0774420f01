"""The live map's view model (gcs_cli/map/model.py), pure: messages and times in, the
page's frames out, no browser, no Zenoh."""

from __future__ import annotations

import msgspec
from hypothesis import given
from hypothesis import strategies as st

from gcs_cli.map.model import (
    SETTLE_S,
    Alive,
    CommandDone,
    CommandRef,
    CommandSent,
    MapModel,
    PlanDone,
    PlanJob,
)
from swarm_proto import (
    Ack,
    AckReason,
    AckRef,
    Alert,
    AlertCode,
    AlertFlag,
    FsmState,
    Geometry,
    GeoPoint,
    Mission,
    MissionType,
    NoFlyZone,
    Selector,
    SelectorKind,
    Severity,
    VehicleInfo,
    VehicleStatus,
    VehicleType,
    Vote,
    VoteScore,
)
from tests.conftest import REPO
from tests.test_architecture import violations

LAT, LON = 37.4112, -5.9889


def status(vid: int, t: float, north_m: float = 0.0, **kw: object) -> VehicleStatus:
    return VehicleStatus(vid, 1.7e9 + t, LAT + north_m / 111_320.0, LON, 110.0, 100.0, **kw)  # type: ignore[arg-type]


def info(vid: int, **kw: object) -> VehicleInfo:
    kw.setdefault("home", GeoPoint(LAT, LON + vid * 1e-4, 10.0))
    return VehicleInfo(vid, VehicleType.VTOL, "Albatross 250 VTOL", f"ALB-{vid:02d}", **kw)  # type: ignore[arg-type]


def test_the_model_does_no_io() -> None:
    path = REPO / "gcs_cli" / "map" / "model.py"
    assert not violations(path)


def test_a_vehicle_as_the_page_shows_it() -> None:
    m = MapModel(0.0)
    m.handle(info(1, fleet_id=2, roll_deg=5.0, sensors_present=0b11, sensors_health=0b01), 0.0)
    m.handle(status(1, 0.0, heading_deg=90.0, battery_pct=77, fleet_id=2, armed=True), 0.1)
    frame, cursor = m.frame(0, 0.2)
    (v,) = frame["vehicles"]
    assert v["id"] == 1 and v["type"] == "VTOL" and v["user_id"] == "ALB-01"
    assert v["heading_deg"] == 90.0 and v["battery_pct"] == 77 and v["fleet"] == 2
    assert v["lat"] == LAT and v["has_position"] and v["home"] == [LAT, LON + 1e-4, 10.0]
    assert v["sensors"] == {
        "gyro": "ok",
        "accel": "NOT HEALTHY",
        "compass": "absent",
        "baro": "absent",
        "airspeed": "absent",
        "gps": "absent",
    }
    assert frame["full"] and cursor == m.seq
    msgspec.json.encode(frame)  # JSON as it is


def test_link_age_packets_per_second_and_lost_on_injected_time() -> None:
    m = MapModel(0.0)
    for k in range(10):  # 5 Hz for 2 s
        m.handle(status(1, k * 0.2), k * 0.2)
    frame, _ = m.frame(0, 1.9)
    assert frame["links"]["1"] == {"age_s": 0.1, "pps": 5.0, "alive": False, "lost": False}
    frame, _ = m.frame(0, 7.0)  # not heard for 5.2 s
    link = frame["links"]["1"]
    assert link["lost"] and link["pps"] == 0.0 and link["age_s"] == 5.2
    assert frame["summary"]["by_state"]["LOST"] == [1]
    m.handle(Alive(1, True), 7.0)
    assert m.frame(0, 7.0)[0]["links"]["1"]["alive"]


def test_trails_one_point_a_second_kept_for_the_window_and_sent_once() -> None:
    m = MapModel(0.0, trail_s=10.0)
    for k in range(25):  # 5 s at 5 Hz, moving north 1 m per sample
        m.handle(status(1, k * 0.2, north_m=k), k * 0.2)
    frame, cursor = m.frame(0, 5.0)
    assert len(frame["trails"]["1"]) == 5  # one a second
    m.handle(status(1, 5.0, north_m=25), 5.0)
    frame, cursor = m.frame(cursor, 5.0)
    assert len(frame["trails"]["1"]) == 1  # only the new point
    assert [v["id"] for v in frame["vehicles"]] == [1]
    frame, _ = m.frame(cursor, 5.1)
    assert frame["trails"] == {} and frame["vehicles"] == []  # nothing new
    for k in range(26, 100):
        m.handle(status(1, k * 0.2, north_m=k), k * 0.2)
    full, _ = m.frame(0, 19.8)
    times = [p[0] for p in full["trails"]["1"]]
    assert min(times) >= 19.8 - 10.0 - 1e-9  # older points dropped


def test_the_worst_active_alert_borders_the_icon() -> None:
    m = MapModel(0.0)
    flags = AlertFlag.BATTERY_LOW | AlertFlag.GPS_LOSS
    m.handle(status(1, 0.0, alerts=flags, armed=True), 0.0)
    (v,) = m.frame(0, 0.0)[0]["vehicles"]
    assert v["worst"] == "CRITICAL"  # GPS lost while armed (the node's own rule)
    assert v["alerts"] == ["BATTERY_LOW", "GPS_LOSS"]
    m.handle(Alert(1, 1.7e9, Severity.EMERGENCY, AlertCode.BATTERY_LOW, "9%"), 0.1)
    (v,) = m.frame(0, 0.1)[0]["vehicles"]
    assert v["worst"] == "EMERGENCY"  # what the vehicle said
    m.handle(status(1, 0.2), 0.2)
    (v,) = m.frame(0, 0.2)[0]["vehicles"]
    assert v["worst"] is None and v["alerts"] == []


def test_alerts_are_sent_once_with_their_meaning() -> None:
    m = MapModel(0.0)
    m.handle(Alert(3, 1.7e9, Severity.WARNING, AlertCode.BATTERY_LOW, "battery 20%"), 0.0)
    frame, cursor = m.frame(0, 0.0)
    assert frame["alerts"] == [
        {
            "vehicle": 3,
            "time_unix_s": 1.7e9,
            "severity": "WARNING",
            "code": "BATTERY_LOW",
            "text": "battery low: battery 20%",
        }
    ]
    assert m.frame(cursor, 0.1)[0]["alerts"] == []


def test_a_radio_prediction_carries_its_error_circle() -> None:
    m = MapModel(0.0)
    m.handle(status(5, 0.0, position_error_m=24.0, predicted_s=2.0), 0.0)
    (v,) = m.frame(0, 0.0)[0]["vehicles"]
    assert v["position_error_m"] == 24.0 and v["predicted_s"] == 2.0


def test_zones_newest_declaration_wins_and_a_withdrawn_one_goes() -> None:
    m = MapModel(0.0)
    z = NoFlyZone(3, Geometry.circle(LAT, LON, 50.0), time_unix_s=100.0, name="tower")
    m.handle(z, 0.0)
    frame, cursor = m.frame(0, 0.0)
    assert [
        (z["id"], z["geometry"]["kind"], z["geometry"]["radius_m"]) for z in frame["zones"]
    ] == [(3, "circle", 50.0)]
    assert "zones" not in m.frame(cursor, 0.1)[0]  # unchanged: not sent again
    m.handle(msgspec.structs.replace(z, active=False, time_unix_s=50.0), 0.2)  # older
    assert [z["id"] for z in m.frame(0, 0.2)[0]["zones"]] == [3]
    m.handle(msgspec.structs.replace(z, active=False, time_unix_s=200.0), 0.3)
    assert m.frame(0, 0.3)[0]["zones"] == []


def area_mission(mid: int = 12, quantity: int = 0) -> Mission:
    sel = Selector(SelectorKind.QUANTITY, quantity=quantity) if quantity else Selector()
    square = [(LAT, LON), (LAT + 0.002, LON), (LAT + 0.002, LON + 0.002), (LAT, LON + 0.002)]
    return Mission(mid, 900, MissionType.AREA, Geometry.polygon(square), selection=sel)


def test_a_settled_roster_is_planned_once_and_a_lost_member_keeps_its_share() -> None:
    m = MapModel(0.0)
    m.handle(area_mission(), 0.0)
    for vid in (1, 2):
        m.handle(info(vid, mission_id=12, fsm_state=FsmState.PLAN, battery_pct=90), 0.0)
    assert m.on_timer(SETTLE_S - 0.1) == []
    assert m.next_deadline() == SETTLE_S
    (job,) = m.on_timer(SETTLE_S)
    assert isinstance(job, PlanJob) and job.members == (1, 2)
    assert job.homes[2] == GeoPoint(LAT, LON + 2e-4, 10.0) and job.battery_pct == {1: 90.0, 2: 90.0}
    assert m.on_timer(SETTLE_S + 5) == []  # asked once
    shares = {1: [(LAT, LON), (LAT + 0.001, LON)], 2: [(LAT, LON + 0.001)]}
    m.handle(PlanDone(12, (1, 2), shares), 3.0)
    (mission,) = m.frame(0, 3.0)[0]["missions"]
    assert mission["plan"] == "planned" and mission["flying"] == [1, 2]
    assert mission["shares"]["1"] == [(LAT, LON), (LAT + 0.001, LON)]
    m.handle(info(2, mission_id=0, fsm_state=FsmState.EMERGENCY), 4.0)  # lost
    assert m.on_timer(10.0) == []  # a smaller roster keeps the plan
    (mission,) = m.frame(0, 10.0)[0]["missions"]
    assert mission["flying"] == [1] and mission["members"] == [1, 2]
    assert set(mission["shares"]) == {"1", "2"}
    m.handle(info(3, mission_id=12, fsm_state=FsmState.PLAN), 11.0)  # joins: planned again
    (job,) = m.on_timer(11.0 + SETTLE_S)
    assert job.members == (1, 3)


def test_the_last_vote_every_score_and_the_winners() -> None:
    m = MapModel(0.0)
    m.handle(area_mission(40, quantity=2), 0.0)
    scores = (VoteScore(1, 0.5), VoteScore(2, 0.9), VoteScore(3, 0.7))
    m.handle(Vote(40, 1, scores[:1]), 0.0)
    m.handle(Vote(40, 2, scores, committed=True), 0.1)
    m.handle(Vote(40, 1, scores[:2]), 0.2)  # an older, undecided vote does not replace
    m.handle(
        Alert(2, 1.7e9, Severity.INFO, AlertCode.GENERIC, "chosen for mission 40, score 0.9"), 0
    )
    vote = m.frame(0, 0.3)[0]["vote"]
    assert vote["mission_id"] == 40 and vote["decided"] and vote["quantity"] == 2
    assert vote["scores"] == [[2, 0.9], [3, 0.7], [1, 0.5]]
    assert vote["winners"] == [2, 3] and vote["said_chosen"] == [2]


def test_every_answer_of_a_command_as_it_arrives_then_the_outcome() -> None:
    m = MapModel(0.0, gcs_id=900)
    m.handle(CommandSent(1, "rtl", "rtl to vehicles 1, 2?"), 0.0)
    early = Ack(1, 900, AckRef.COMMAND, 77, True)
    m.handle(early, 0.1)  # heard before the exchange said which seq it carries
    m.handle(CommandRef(1, AckRef.COMMAND, 77, 900), 0.1)
    m.handle(Ack(2, 900, AckRef.COMMAND, 77, False, AckReason.NOT_READY, "no GPS"), 0.2)
    m.handle(Ack(2, 900, AckRef.COMMAND, 77, True), 0.3)  # a repeat's answer: the first counts
    m.handle(Ack(3, 901, AckRef.COMMAND, 77, True), 0.3)  # another ground station's
    (c,) = m.frame(0, 0.4)[0]["commands"]
    assert c["state"] == "waiting" and c["question"] == "rtl to vehicles 1, 2?"
    assert [(a["id"], a["answer"]) for a in c["answers"]] == [(1, "accepted"), (2, "rejected")]
    assert "not ready" in c["answers"][1]["why"] and "no GPS" in c["answers"][1]["why"]
    outcome = {
        "ok": False,
        "vehicles": [
            {"id": 1, "answer": "accepted", "reason": "OK", "why": "", "notes": []},
            {"id": 2, "answer": "rejected", "reason": "NOT_READY", "why": "x", "notes": []},
        ],
        "not_addressed": [],
        "absent": [],
    }
    m.handle(CommandDone(1, outcome, "rtl: 1 accepted, 1 rejected of 2 addressed"), 1.0)
    (c,) = m.frame(0, 1.0)[0]["commands"]
    assert c["state"] == "failed" and c["summary"].startswith("rtl: 1 accepted")


def test_a_ground_station_is_not_drawn() -> None:
    m = MapModel(0.0)
    m.handle(VehicleInfo(901, VehicleType.GCS, "Ground Station", "GCS-901"), 0.0)
    m.handle(Alive(901, True), 0.0)
    m.handle(Alive(900, True), 0.0)  # this map's own ground station
    assert m.frame(0, 0.0)[0]["vehicles"] == []


@given(
    st.lists(
        st.tuples(st.integers(1, 4), st.floats(0, 50), st.floats(-500, 500), st.booleans()),
        max_size=40,
    )
)
def test_frames_are_json_and_a_cursor_never_misses_a_change(events: list) -> None:
    m = MapModel(0.0)
    seen: dict[int, dict] = {}
    cursor = 0
    t = 0.0
    for vid, dt, north, ask in events:
        t += dt / 10
        m.handle(status(vid, t, north_m=north), t)
        if ask:
            frame, cursor = m.frame(cursor, t)
            msgspec.json.encode(frame)
            seen.update({v["id"]: v for v in frame["vehicles"]})
    frame, cursor = m.frame(cursor, t)
    seen.update({v["id"]: v for v in frame["vehicles"]})
    full = {v["id"]: v for v in m.frame(0, t)[0]["vehicles"]}
    assert seen == full  # the frames since 0 add up to the whole view
