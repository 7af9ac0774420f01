"""Exact Dubins paths: agreement with OMPL, continuity, radius, batch form."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from swarm_node.core.planning import (
    InvalidParameterError,
    Pose,
    Word,
    batch_lengths,
    path_length,
    shortest_path,
)
from swarm_node.core.planning.checks import dubins_problems
from swarm_node.core.planning.dubins import all_paths

coord = st.floats(-500, 500, allow_nan=False)
yaw = st.floats(-math.pi, math.pi, allow_nan=False)
poses = st.builds(Pose, coord, coord, yaw)
radii = st.floats(1.0, 200.0)


def _random_pairs(n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    s = np.column_stack(
        [rng.uniform(-400, 400, n), rng.uniform(-400, 400, n), rng.uniform(-math.pi, math.pi, n)]
    )
    g = np.column_stack(
        [rng.uniform(-400, 400, n), rng.uniform(-400, 400, n), rng.uniform(-math.pi, math.pi, n)]
    )
    return s, g


def ompl_lengths(s: np.ndarray, g: np.ndarray, radius: float) -> np.ndarray:
    ob = pytest.importorskip("ompl.base")
    space = ob.DubinsStateSpace(radius)
    a, b = space.allocState(), space.allocState()
    out = np.empty(len(s))
    for i in range(len(s)):
        a.setX(s[i, 0])
        a.setY(s[i, 1])
        a.setYaw(s[i, 2])
        b.setX(g[i, 0])
        b.setY(g[i, 1])
        b.setYaw(g[i, 2])
        out[i] = space.distance(a, b)
    return out


def _agree(n: int, seed: int) -> None:
    for radius in (30.0, 68.9):
        s, g = _random_pairs(n, seed)
        ref = ompl_lengths(s, g, radius)
        got = batch_lengths(s, g, radius)
        assert isinstance(got, np.ndarray)
        assert np.abs(got - ref).max() <= 1e-9
        one = np.array(
            [shortest_path(Pose(*s[i]), Pose(*g[i]), radius).length_m for i in range(min(n, 2000))]
        )
        assert np.abs(one - ref[: len(one)]).max() <= 1e-9


def test_agrees_with_ompl_on_100k_random_pairs() -> None:
    # fast enough (about a second) to run in `make test`
    _agree(100_000, seed=7)


@given(poses, poses, radii)
def test_path_is_continuous_respects_radius_and_reaches_goal(a: Pose, b: Pose, r: float) -> None:
    path = shortest_path(a, b, r)
    assert dubins_problems(path, step_m=max(path.length_m / 200, 0.01)) == []
    end = path.end
    # poses closer than 1e-6 R count as equal (as in OMPL): the path is then a point
    assert math.hypot(end.x - b.x, end.y - b.y) < 1e-6 * max(1.0, path.length_m) + 2e-6 * r
    assert abs(math.remainder(end.yaw - b.yaw, 2 * math.pi)) < 1e-6
    assert path.length_m >= math.hypot(b.x - a.x, b.y - a.y) - 1e-9


@given(poses, poses, radii)
def test_batch_matches_single(a: Pose, b: Pose, r: float) -> None:
    lengths, words = batch_lengths([[a.x, a.y, a.yaw]], [[b.x, b.y, b.yaw]], r, words=True)
    p = shortest_path(a, b, r)
    assert lengths[0] == pytest.approx(p.length_m, abs=1e-9)
    # the word may differ where two words tie for the shortest (e.g. RLR and LRL
    # turning round on the spot): it must be one of the shortest; poses closer than
    # 1e-6 R count as equal (as in OMPL), and the path between them is not one of the six
    shortest = {
        q.word for q in all_paths(a, b, r) if q.length_m == pytest.approx(p.length_m, abs=1e-9)
    }
    same_pose = (
        math.hypot(b.x - a.x, b.y - a.y) <= 1e-6 * r
        and abs(math.remainder(b.yaw - a.yaw, 2 * math.pi)) <= 1e-6
    )
    assert Word(int(words[0])) in shortest or same_pose


def test_all_six_words_occur() -> None:
    s, g = _random_pairs(20_000, seed=3)
    _l, words = batch_lengths(s, g, 100.0, words=True)
    assert set(np.unique(words).tolist()) == {w.value for w in Word}


def test_known_paths() -> None:
    r = 30.0
    # straight ahead
    assert path_length(Pose(0, 0, 0), Pose(100, 0, 0), r) == pytest.approx(100.0)
    # U-turn at exactly 2R: a half circle
    assert path_length(Pose(0, 0, 0), Pose(0, 2 * r, math.pi), r) == pytest.approx(math.pi * r)
    # adjacent lanes closer than 2R need a longer CCC turn
    assert path_length(Pose(0, 0, 0), Pose(0, r, math.pi), r) > math.pi * r
    assert shortest_path(Pose(0, 0, 0), Pose(0, r, math.pi), r).word in (Word.LRL, Word.RLR)


def test_cost_matrix_broadcasts() -> None:
    s, g = _random_pairs(5, seed=1)
    m = batch_lengths(s[:, None, :], g[None, :, :], 30.0)
    assert isinstance(m, np.ndarray) and m.shape == (5, 5)
    assert m[2, 3] == pytest.approx(path_length(Pose(*s[2]), Pose(*g[3]), 30.0))


@pytest.mark.parametrize("r", [0.0, -1.0, math.nan, math.inf])
def test_bad_radius_raises(r: float) -> None:
    with pytest.raises(InvalidParameterError):
        shortest_path(Pose(0, 0, 0), Pose(1, 1, 0), r)
    with pytest.raises(InvalidParameterError):
        batch_lengths([[0, 0, 0]], [[1, 1, 0]], r)


def test_nan_pose_raises() -> None:
    with pytest.raises(InvalidParameterError):
        shortest_path(Pose(math.nan, 0, 0), Pose(1, 1, 0), 10.0)


@given(poses, poses, radii, st.floats(0.5, 20.0))
def test_vectorized_samples_are_the_sampled_poses(a: Pose, b: Pose, r: float, step: float) -> None:
    path = shortest_path(a, b, r)
    ref = np.array([(p.x, p.y) for p in path.sample(step)])
    assert np.abs(path.sample_xy(step) - ref).max() < 1e-9
    # waypoint_s gives the distances of the waypoints along the path
    for s, p in zip(path.waypoint_s(), path.waypoints(), strict=True):
        q = path.pose_at(s)
        assert (q.x, q.y, q.yaw) == (p.x, p.y, p.yaw)
