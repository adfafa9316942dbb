"""The colour residual of the LM (``color``, ``color-rgb``, ``color-patch``): its numba kernel against the plain
numpy formula, its Jacobian against finite differences, and the per-pixel sums the LM uses against the residuals."""

import numpy as np
import pytest

from reconstruction.camera.equirect import project_rays_camera
from reconstruction.camera.resample import bilinear_with_gradient
from reconstruction.refine.lm import ColorTerm, RefineProblem, patch_offsets
from reconstruction.refine.triangulate import pair_geometry

W, H = 64, 32


def _problem(channels: int, patch: int, seed: int = 0):
    """A two-pair problem with colour terms over 200 random bearings, including rows near both poles and pixels
    whose projection crosses the seam (u wraps) or leaves the image vertically (v clamps)."""
    rng = np.random.default_rng(seed)
    a = rng.normal(size=(200, 3))
    a[:20, 2] = np.sign(a[:20, 2]) * 40.0  # near the poles: patch rows leave the image
    a[20:40, 0], a[20:40, 1] = -1e-3, -1.0  # longitude pi: the seam
    a /= np.linalg.norm(a, axis=1, keepdims=True)
    d_true = rng.uniform(1.0, 5.0, size=len(a))
    starts = {"U": np.array([0.0, 0.0, -0.4]), "R": np.array([-0.4, 0.0, 0.0])}
    offsets = patch_offsets(patch)
    pairs, terms = [], []
    for start in starts.values():
        x = d_true[:, None] * a + start
        pairs.append(pair_geometry(a, -start, x / np.linalg.norm(x, axis=1, keepdims=True)))
        terms.append(ColorTerm(image=rng.uniform(0.0, 1.0, size=(H, W, channels)),
                               ref=rng.uniform(0.0, 1.0, size=(len(a), len(offsets) * channels)),
                               start=start, direction=a, offsets=offsets if patch > 1 else None))
    weights = [np.sin(g.alpha) ** 2 for g in pairs]
    problem = RefineProblem(np.zeros(3), a, pairs, weights, H, W, color=terms, color_weight=30.0 / len(offsets),
                            color_saturation=0.1)
    return problem, d_true


def _numpy_colour(problem: RefineProblem, d, idx):
    """The colour residuals and derivatives written out with numpy: (M, sum of P c) each."""
    s, lam = problem.color_saturation, np.sqrt(problem.color_weight)
    rs, js = [], []
    for term in problem.color:
        u, v, du, dv = project_rays_camera(term.start, term.direction[idx], d, problem.width, problem.height)
        offsets = np.zeros((1, 2)) if term.offsets is None else term.offsets
        c = term.image.shape[2]
        for k, (ou, ov) in enumerate(offsets):
            val, gu, gv = bilinear_with_gradient(term.image, u + ou, v + ov)
            th = np.tanh((val - term.ref[idx][:, k * c:(k + 1) * c]) / s)
            rs.append(lam * s * th)
            js.append(lam * (1.0 - th * th) * (gu * du[:, None] + gv * dv[:, None]))
    return np.concatenate(rs, axis=1), np.concatenate(js, axis=1)


@pytest.mark.parametrize("channels,patch", [(1, 1), (3, 1), (1, 3), (3, 3)])
def test_colour_residuals_match_the_numpy_formula_and_the_sums(channels, patch):
    problem, d_true = _problem(channels, patch)
    idx = np.arange(5, 200, 3)
    d = d_true[idx] * 1.1
    r, j = problem.residuals(d, idx)
    n_geo = len(problem.pairs)
    assert r.shape == j.shape == (idx.size, n_geo + 2 * patch * patch * channels)
    r_np, j_np = _numpy_colour(problem, d, idx)
    # same arithmetic in another order: agreement to a few ulps of the O(1) values (pixel equivalents)
    np.testing.assert_allclose(r[:, n_geo:], r_np, rtol=0, atol=1e-12)
    np.testing.assert_allclose(j[:, n_geo:], j_np, rtol=0, atol=1e-9)  # per metre; values up to ~1e2
    cost, grad, hess = problem.normal_terms(d, idx)
    np.testing.assert_allclose(cost, (r * r).sum(axis=1), rtol=1e-12)
    np.testing.assert_allclose(grad, (j * r).sum(axis=1), rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(hess, (j * j).sum(axis=1), rtol=1e-12)


def test_colour_jacobian_matches_finite_differences():
    """Away from the kinks of bilinear interpolation (pixel borders) the derivative is that of the residual."""
    problem, d_true = _problem(3, 3, seed=1)
    d = d_true * 0.9
    h = 1e-7  # metres
    _, j = problem.residuals(d)
    r_plus, _ = problem.residuals(d + h)
    r_minus, _ = problem.residuals(d - h)
    fd = (r_plus - r_minus) / (2 * h)
    # a central difference that straddles a pixel border (kink of the interpolant) differs; they are rare
    close = np.isclose(fd, j, rtol=1e-4, atol=1e-4)
    assert close.mean() > 0.99


def test_all_pixels_and_an_index_give_the_same_rows():
    """The rows of an indexed call are those of the call over all pixels, to a few ulps: numpy's vectorised
    trigonometry (the projection) may take another SIMD path for 4 elements than for 200, so the last bits may
    differ (by 1.5e-15 on an Intel Xeon); a wrong or shifted row differs by O(0.1) or more."""
    problem, d_true = _problem(1, 3, seed=2)
    r_all, j_all = problem.residuals(d_true)
    idx = np.array([7, 3, 150, 21])
    r_idx, j_idx = problem.residuals(d_true[idx], idx)
    np.testing.assert_allclose(r_idx, r_all[idx], rtol=0, atol=1e-12)  # pixel equivalents, values O(1)
    np.testing.assert_allclose(j_idx, j_all[idx], rtol=1e-12, atol=1e-9)  # per metre, values up to ~1e2


def test_a_nan_distance_gives_nan_residuals_not_a_crash():
    """The kernel never indexes the image with a NaN projection: the pixel's residuals and sums are NaN, the
    others unchanged."""
    problem, d_true = _problem(1, 3, seed=3)
    d = d_true.copy()
    d[4] = np.nan
    r, j = problem.residuals(d)
    r_ok, _ = problem.residuals(d_true)
    n_geo = len(problem.pairs)
    assert np.isnan(r[4, n_geo:]).all() and np.isnan(j[4, n_geo:]).all()
    # the others to a few ulps (pixel equivalents, values O(1)): a NaN may send its SIMD block of numpy's
    # trigonometry down another path; a pixel corrupted by the NaN would be NaN or off by O(0.1)
    np.testing.assert_allclose(np.delete(r, 4, axis=0), np.delete(r_ok, 4, axis=0), rtol=0, atol=1e-12)
    cost, _, _ = problem.normal_terms(d)
    assert np.isnan(cost[4]) and np.isfinite(np.delete(cost, 4)).all()
