"""Triangulation and the geometric LM residual: hand-computed values, validity, closed-form minimiser."""

import numpy as np
import pytest

from reconstruction.refine.lm import RefineProblem, levenberg_marquardt
from reconstruction.refine.triangulate import (
    TriangulationLimits,
    beta_of_distance,
    pair_geometry,
    triangulate_midpoint,
    triangulate_sines,
)


def _match(a, t, d):
    x = d[:, None] * a - t
    return x / np.linalg.norm(x, axis=1, keepdims=True)


def _random_bearings(n, seed=0):
    a = np.random.default_rng(seed).normal(size=(n, 3))
    return a / np.linalg.norm(a, axis=1, keepdims=True)


def test_hand_computed_right_angle():
    # point 2 m straight ahead (+Y), baseline 0.4 m to the right (+X): alpha = 90 deg, beta = 90 + atan(0.4/2)
    a = np.array([[0.0, 1.0, 0.0]])
    t = np.array([0.4, 0.0, 0.0])
    g = pair_geometry(a, t, _match(a, t, np.array([2.0])))
    assert g.alpha[0] == pytest.approx(np.pi / 2, abs=1e-12)
    assert g.beta_obs[0] == pytest.approx(np.pi / 2 + np.arctan(0.4 / 2.0), abs=1e-12)
    d, valid = triangulate_sines(g)
    assert d[0] == pytest.approx(2.0, abs=1e-12) and valid[0]


@pytest.mark.parametrize("method", ["sines", "midpoint"])
def test_exact_matches_give_exact_distances(method):
    a = _random_bearings(2000)
    t = np.array([0.0, 0.0, 0.4])
    d_true = np.random.default_rng(1).uniform(0.3, 12.0, size=len(a))
    c = _match(a, t, d_true)
    if method == "sines":
        d, valid = triangulate_sines(pair_geometry(a, t, c))
    else:
        d, valid = triangulate_midpoint(a, t, c)
    alpha = np.degrees(np.arccos(np.abs(a @ t / 0.4)))
    # valid everywhere but within 3 degrees of the epipoles (and where d would exceed the clamp)
    assert np.array_equal(valid, alpha >= 3.0)
    np.testing.assert_allclose(d[valid], d_true[valid], rtol=1e-9)  # metres, relative


def test_negative_parallax_and_epipole_are_invalid():
    t = np.array([0.4, 0.0, 0.0])
    a = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0]])
    c = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0]])  # zero parallax; epipole
    c[0] = [-0.01, 1.0, 0.0]
    c[0] /= np.linalg.norm(c[0])  # slightly beyond: beta - alpha > 0 -> valid far point
    c2 = np.array([[0.01, 1.0, 0.0]]) / np.linalg.norm([0.01, 1.0, 0.0])  # beta < alpha: "behind"
    d, valid = triangulate_sines(pair_geometry(a, t, c))
    assert valid[0] and not valid[1]
    assert d[0] == pytest.approx(0.4 / np.tan(0.01), rel=1e-3)
    d2, valid2 = triangulate_sines(pair_geometry(a[:1], t, c2))
    assert not valid2[0] and np.isfinite(d2[0]) and d2[0] <= TriangulationLimits().d_max_m


def test_off_plane_angle():
    a = np.array([[0.0, 1.0, 0.0]])
    t = np.array([0.4, 0.0, 0.0])
    c = np.array([[0.0, np.cos(0.02), np.sin(0.02)]])  # tilted out of the X-Y epipolar plane by 0.02 rad
    assert abs(pair_geometry(a, t, c).off_plane[0]) == pytest.approx(0.02, abs=1e-12)


def test_beta_derivative_matches_finite_difference():
    a = _random_bearings(500, seed=3)
    t = np.array([0.4, 0.0, 0.0])
    g = pair_geometry(a, t, a)
    d = np.random.default_rng(4).uniform(0.5, 10, size=500)
    _, db = beta_of_distance(g, d)
    h = 1e-6
    fd = (beta_of_distance(g, d + h)[0] - beta_of_distance(g, d - h)[0]) / (2 * h)
    np.testing.assert_allclose(db, fd, rtol=1e-6, atol=1e-10)  # radians per metre


def test_lm_two_pairs_reaches_exact_distance_from_poor_start():
    a = _random_bearings(3000, seed=5)
    d_true = np.random.default_rng(6).uniform(0.5, 10.0, size=len(a))
    tu, tr = np.array([0.0, 0.0, 0.4]), np.array([0.4, 0.0, 0.0])
    gu, gr = pair_geometry(a, tu, _match(a, tu, d_true)), pair_geometry(a, tr, _match(a, tr, d_true))
    w = [np.sin(g.alpha) ** 2 for g in (gu, gr)]
    problem = RefineProblem(origin=np.zeros(3), bearings=a, pairs=[gu, gr], weights=w, height=500, width=1000)
    d, iters = levenberg_marquardt(problem, d_true * 1.5)
    np.testing.assert_allclose(d, d_true, atol=1e-6)  # metres
    assert iters < 30


def test_lm_minimises_the_weighted_cost_between_disagreeing_pairs():
    """With one pair at 2 m and the other at 3 m, LM lands between them at the weighted optimum."""
    a = np.array([[0.0, 1.0, 0.0]]).repeat(3, axis=0)
    a[1] = [0.6, 0.8, 0.0]
    a[2] = [0.0, 0.8, 0.6]
    tu, tr = np.array([0.0, 0.0, 0.4]), np.array([0.4, 0.0, 0.0])
    gu, gr = pair_geometry(a, tu, _match(a, tu, np.full(3, 2.0))), pair_geometry(a, tr, _match(a, tr, np.full(3, 3.0)))
    problem = RefineProblem(np.zeros(3), a, [gu, gr], [np.ones(3), np.ones(3)], 500, 1000)
    d, _ = levenberg_marquardt(problem, np.full(3, 2.5))
    grid = np.linspace(1.5, 3.5, 200001)
    for i in range(3):
        cost = sum((beta_of_distance(type(g)(g.baseline_m, g.cos_alpha[[i]].repeat(grid.size),
                                             g.sin_alpha[[i]].repeat(grid.size), g.beta_obs[[i]].repeat(grid.size)),
                                     grid)[0] - g.beta_obs[i]) ** 2 for g in (gu, gr))
        assert 2.0 < d[i] < 3.0
        assert d[i] == pytest.approx(grid[np.argmin(cost)], abs=2e-5)  # metres (grid step 1e-5)
