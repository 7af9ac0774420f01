"""No-fly zones become the autopilot's fence (the backstop if the companion computer
fails): which zones, how they fit the autopilot's storage, and the keeper that uploads
them, pure; then inside NodeCore (zone declared, withdrawn, expired)."""

from __future__ import annotations

import math
from collections.abc import Sequence

import pytest
from hypothesis import given
from hypothesis import strategies as st
from shapely.geometry import Polygon

from swarm_node.core.autopilot.requests import ApRequest, ApResult, SetParam, UploadFence
from swarm_node.core.fences import (
    FENCE_FULL_HEIGHT_REL_M,
    FenceKeeper,
    approximate,
    plan_fence,
)
from swarm_node.core.node import (
    AutopilotResult,
    AutopilotUpdate,
    NodeCore,
    NodeSettings,
    Output,
    Publish,
    Received,
    Submit,
)
from swarm_node.database import seed_profiles
from swarm_proto import (
    Alert,
    AlertCode,
    Command,
    CommandArgs,
    CommandKind,
    Geometry,
    GeoPoint,
    Mission,
    MissionParams,
    MissionType,
    NoFlyZone,
    Selector,
    Severity,
)
from tests.swarm_node.test_node_core import flying

HOME = GeoPoint(37.4112, -5.9889, 10.0)
T0 = 1.8e9


def offset(n_m: float, e_m: float) -> tuple[float, float]:
    return (
        HOME.lat_deg + n_m / 111_320.0,
        HOME.lon_deg + e_m / (111_320.0 * math.cos(math.radians(HOME.lat_deg))),
    )


def circle_zone(zid: int, n_m: float, e_m: float, r_m: float = 40.0, **kw: object) -> NoFlyZone:
    lat, lon = offset(n_m, e_m)
    return NoFlyZone(zid, Geometry.circle(lat, lon, r_m), **kw)  # type: ignore[arg-type]


def ring(n: int, n_m: float, e_m: float, r_m: float) -> list[tuple[float, float]]:
    """An n-gon around (n_m, e_m) metres from home."""
    return [
        offset(n_m + r_m * math.cos(2 * math.pi * k / n), e_m + r_m * math.sin(2 * math.pi * k / n))
        for k in range(n)
    ]


def local(points: Sequence[tuple[float, float]]) -> Polygon:
    """(lat, lon) points as a polygon in metres east/north of home."""
    k = 111_320.0 * math.cos(math.radians(HOME.lat_deg))
    return Polygon(
        [((lon - HOME.lon_deg) * k, (lat - HOME.lat_deg) * 111_320.0) for lat, lon in points]
    )


def latlon(zone: NoFlyZone) -> list[tuple[float, float]]:
    return [(p.lat_deg, p.lon_deg) for p in zone.geometry.points]


# ----------------------------------------------------------------------- what is fenced


def test_ground_to_sky_zones_are_fenced_others_stay_companion_only() -> None:
    zones = [
        circle_zone(1, 300, 0),  # default floor/ceiling: -1000..8000 m MSL
        NoFlyZone(2, Geometry.polygon(ring(5, 600, 0, 50))),
        circle_zone(3, 200, 200, floor_alt_msl_m=-100.0, ceiling_alt_msl_m=60.0),  # overflown
        circle_zone(4, 200, -200, floor_alt_msl_m=50.0, ceiling_alt_msl_m=8000.0),  # flown under
        circle_zone(5, 100, 0, active=False),  # withdrawn
        circle_zone(6, 100, 0, valid_from_unix_s=T0 + 60),  # not yet
        circle_zone(7, 100, 0, valid_until_unix_s=T0 - 1),  # expired
    ]
    plan = plan_fence(zones, T0, home=HOME)
    assert plan.fenced == (1, 2) and plan.overflown == (3, 4) and plan.left_out == ()
    req = plan.request
    assert req.enable is True and len(req.exclusion_circles) == 1
    assert req.exclusion_circles[0][2] == 40.0 and len(req.exclusion_polygons[0]) == 5
    # a mission above FENCE_FULL_HEIGHT_REL_M: a zone below that altitude is overflown too
    high = circle_zone(8, 300, 0, ceiling_alt_msl_m=HOME.alt_msl_m + 150.0)
    assert plan_fence([high], T0, home=HOME).fenced == (8,)
    assert plan_fence([high], T0, home=HOME, fly_ceiling_rel_m=200.0).overflown == (8,)
    # nothing in force: an empty fence, disabled
    empty = plan_fence(zones[2:], T0, home=HOME).request
    assert empty == UploadFence(enable=False)


def test_a_full_fence_keeps_the_nearest_zones_and_approximates_on_the_safe_side() -> None:
    near = NoFlyZone(1, Geometry.polygon(ring(40, 300, 0, 60)))
    far = NoFlyZone(2, Geometry.polygon(ring(40, 3000, 0, 60)))
    circle = circle_zone(3, 1500, 0)
    plan = plan_fence([far, near, circle], T0, home=HOME, max_items=30)
    assert plan.fenced == (1, 2, 3) and set(plan.approximated) == {1, 2} and not plan.left_out
    items = sum(len(p) for p in plan.request.exclusion_polygons) + 1
    assert items <= 30
    # the nearest zone first, each approximation inside its zone (never stricter)
    first, second = plan.request.exclusion_polygons
    assert local(latlon(near)).covers(local(first))
    assert local(latlon(far)).covers(local(second))
    # no room at all: reported, never half a zone
    tight = plan_fence([near, circle], T0, home=HOME, max_items=2)
    assert tight.fenced == (3,) and tight.left_out == (1,)


def test_operating_areas_are_inclusion_fences_and_come_first() -> None:
    field = NoFlyZone(
        1, Geometry.polygon(ring(100, 0, 0, 2000)), ceiling_alt_msl_m=20.0, operating_area=True
    )
    disc = NoFlyZone(2, Geometry.circle(HOME.lat_deg, HOME.lon_deg, 3000.0), operating_area=True)
    zone = circle_zone(3, 300, 0)
    plan = plan_fence([zone, field, disc], T0, home=HOME, max_items=40)
    assert plan.fenced == (1, 2, 3) and plan.approximated == (1,) and plan.overflown == ()
    req = plan.request
    assert req.inclusion_circles == ((HOME.lat_deg, HOME.lon_deg, 3000.0),)
    assert req.exclusion_circles and len(req.inclusion_polygons[0]) <= 38
    # the approximation lies around the area: the fence never fires inside it
    assert local(req.inclusion_polygons[0]).covers(local(latlon(field)))


@given(
    n=st.integers(5, 60),
    radius=st.floats(20.0, 2000.0),
    wobble=st.lists(st.floats(0.6, 1.0), min_size=60, max_size=60),
    budget=st.integers(3, 40),
)
def test_approximations_stay_on_the_permissive_side(
    n: int, radius: float, wobble: list[float], budget: int
) -> None:
    pts = [
        offset(
            radius * wobble[k] * math.cos(2 * math.pi * k / n),
            radius * wobble[k] * math.sin(2 * math.pi * k / n),
        )
        for k in range(n)
    ]
    shape = local(pts)
    for inner in (True, False):
        got = approximate(pts, budget, inner=inner)
        if got is None:
            continue
        assert 3 <= len(got) <= budget
        approx = local(got)
        assert approx.is_valid
        if inner:  # an exclusion fence inside the zone (allow float noise: 1 cm)
            assert shape.buffer(0.01).covers(approx)
        else:  # an inclusion fence around the area
            assert approx.buffer(0.01).covers(shape)


# ----------------------------------------------------------------------- the keeper


def test_the_keeper_sets_the_fence_type_uploads_and_retries() -> None:
    keeper = FenceKeeper()
    want = UploadFence(exclusion_circles=((37.0, -6.0, 50.0),), enable=True)
    (first,) = keeper.update(want, 0.0)
    assert isinstance(first, SetParam) and (first.name, first.value) == ("FENCE_TYPE", 4.0)
    assert keeper.update(want, 0.1) == []  # one request at a time
    (upload,) = keeper.on_result(ApResult(first.request_id, True), 0.2)[0]
    assert isinstance(upload, UploadFence) and upload.exclusion_circles == want.exclusion_circles
    nothing, problem = keeper.on_result(ApResult(upload.request_id, False, "link down"), 0.3)
    assert nothing == [] and problem is not None and "link down" in problem
    assert keeper.next_deadline() == pytest.approx(5.3)
    assert keeper.on_timer(1.0) == []
    (again,) = keeper.on_timer(5.3)
    assert isinstance(again, UploadFence)  # FENCE_TYPE was set already
    changed = UploadFence(enable=False)
    assert keeper.update(changed, 5.4) == []  # still busy with `again`
    (follow,) = keeper.on_result(ApResult(again.request_id, True), 5.5)[0]
    assert keeper.held is not None and keeper.held.enable is True
    assert isinstance(follow, UploadFence) and follow.enable is False
    assert keeper.on_result(ApResult(follow.request_id, True), 5.6) == ([], None)
    assert keeper.update(changed, 6.0) == []  # the autopilot holds it already


# ----------------------------------------------------------------------- in the node


def quad_node(settings: NodeSettings | None = None) -> NodeCore:
    """A seed quadcopter's node whose autopilot is up, with home set."""
    node = NodeCore(seed_profiles()["Generic Quadcopter"], settings or NodeSettings(), now=T0)
    node.handle(AutopilotUpdate(flying(home=HOME)), T0)
    return node


def submitted(outputs: list[Output]) -> list[ApRequest]:
    return [o.request for o in outputs if isinstance(o, Submit)]


def alerts(outputs: list[Output]) -> list[Alert]:
    return [o.msg for o in outputs if isinstance(o, Publish) and isinstance(o.msg, Alert)]


def answer_all(node: NodeCore, outputs: list[Output], now: float) -> list[ApRequest]:
    """Answer every autopilot request OK, following up, until none is left: what was sent."""
    sent: list[ApRequest] = []
    todo = submitted(outputs)
    while todo:
        req = todo.pop(0)
        sent.append(req)
        todo += submitted(node.handle(AutopilotResult(ApResult(req.request_id, True)), now))
    return sent


def test_a_zone_reaches_the_autopilot_as_a_fence_and_leaves_it_again() -> None:
    node = quad_node()
    assert submitted(node.on_timer(T0)) == []  # no zone heard: the fence is left alone
    zone = circle_zone(4, 300, 0, valid_until_unix_s=T0 + 100)
    sent = answer_all(node, node.handle(Received(zone), T0), T0)
    assert [type(r).__name__ for r in sent] == ["SetParam", "UploadFence"]
    fence = sent[1]
    assert isinstance(fence, UploadFence)
    assert fence.enable is True and fence.exclusion_circles == (
        (zone.geometry.points[0].lat_deg, zone.geometry.points[0].lon_deg, 40.0),
    )
    assert submitted(node.on_timer(T0 + 1)) == []  # unchanged: nothing sent again
    # expired by its validity: the fence is emptied and disabled
    sent = answer_all(node, node.on_timer(T0 + 100), T0 + 100)
    assert sent == [UploadFence(request_id=sent[0].request_id, enable=False)]
    # declared again, then withdrawn (republished inactive)
    again = circle_zone(4, 300, 0)
    sent = answer_all(node, node.handle(Received(again), T0 + 101), T0 + 101)
    assert [getattr(r, "enable", None) for r in sent] == [True]
    withdrawn = NoFlyZone(4, again.geometry, active=False)
    sent = answer_all(node, node.handle(Received(withdrawn), T0 + 102), T0 + 102)
    assert [getattr(r, "enable", None) for r in sent] == [False]


def test_a_fence_that_does_not_fit_is_reported() -> None:
    node = quad_node(NodeSettings(fence_max_items=2))  # not even a triangle fits
    out = node.handle(Received(NoFlyZone(9, Geometry.polygon(ring(12, 300, 0, 50)))), T0)
    raised = alerts(out)
    assert [(a.code, a.severity) for a in raised] == [(AlertCode.NO_FLY_ZONE, Severity.WARNING)]
    assert "zones 9" in raised[0].text
    assert node.fences.plan is not None and node.fences.plan.left_out == (9,)


def test_a_failed_upload_is_reported_once_and_retried() -> None:
    node = quad_node()
    out = node.handle(Received(circle_zone(4, 300, 0)), T0)
    (param,) = submitted(out)
    failed = ApResult(param.request_id, False, "timeout after 3 tries")
    raised = alerts(node.handle(AutopilotResult(failed), T0))
    assert len(raised) == 1 and "FENCE_TYPE failed" in raised[0].text
    assert node.next_deadline() <= T0 + 5.0
    (retry,) = submitted(node.on_timer(T0 + 5.0))
    assert isinstance(retry, SetParam)


def test_the_fence_ceiling_follows_the_highest_mission() -> None:
    node = quad_node()
    assert node.mission.fly_ceiling_rel_m() == FENCE_FULL_HEIGHT_REL_M
    zone = circle_zone(4, 300, 0, ceiling_alt_msl_m=HOME.alt_msl_m + 140.0)
    sent = answer_all(node, node.handle(Received(zone), T0), T0)
    assert isinstance(sent[-1], UploadFence) and sent[-1].exclusion_circles
    base = Command(900, 1, CommandKind.SET_BASE, args=CommandArgs(point=HOME))
    answer_all(node, node.handle(Received(base), T0), T0)
    node.on_timer(T0 + 0.2)  # activates
    high = Mission(
        5,
        900,
        MissionType.OBJECTIVE,
        Geometry.point(*offset(500, 0)),
        MissionParams(altitude_rel_m=150.0),
        Selector.ids(node.self_id),
    )
    answer_all(node, node.handle(Received(high), T0 + 0.3), T0 + 0.3)
    assert node.mission.fly_ceiling_rel_m() == 150.0
    sent = answer_all(node, node.on_timer(T0 + 0.4), T0 + 0.4)
    assert sent == [UploadFence(request_id=sent[0].request_id, enable=False)]
    assert node.fences.plan is not None and node.fences.plan.overflown == (4,)


def test_inclusion_circles_become_circle_inclusion_items() -> None:
    from swarm_node.core.autopilot.conversion import fence_items

    items = fence_items(
        UploadFence(
            inclusion_circles=((37.0, -6.0, 500.0),), exclusion_circles=((37.0, -6.0, 9.0),)
        )
    )
    assert [(it.command, it.param1) for it in items] == [(5003, 500.0), (5004, 9.0)]
