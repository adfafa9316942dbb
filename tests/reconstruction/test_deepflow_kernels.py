"""DeepFlow's numba kernels against straightforward numpy versions of the same maths, on small random inputs."""

from __future__ import annotations

import numpy as np
import pytest

from reconstruction.flow.deepflow import EPS2, _smoothness, _sor


def _nx(x, wrap):
    """x[:, j + 1] (the last column: the first if wrapping, else itself)."""
    return np.roll(x, -1, axis=1) if wrap else np.concatenate([x[:, 1:], x[:, -1:]], axis=1)


def _px(x, wrap):
    """x[:, j - 1] (the first column: the last if wrapping, else itself)."""
    return np.roll(x, 1, axis=1) if wrap else np.concatenate([x[:, :1], x[:, :-1]], axis=1)


def smoothness_numpy(w_u, w_v, du, dv, quarter_alpha, wrap):
    """Diffusivities (hx, hy) and the right-hand-side terms sum_nb h (w_nb - w) for u and v, in float64."""
    u, v = (w_u + du).astype(np.float64), (w_v + dv).astype(np.float64)

    def cdy(a):
        ap = np.concatenate([a[:1], a, a[-1:]], axis=0)
        return 0.5 * (ap[2:] - ap[:-2])

    ux2, vx2 = 0.5 * (_nx(u, wrap) - _px(u, wrap)), 0.5 * (_nx(v, wrap) - _px(v, wrap))
    uy2, vy2 = cdy(u), cdy(v)
    t1, t2 = 0.5 * (uy2 + _nx(uy2, wrap)), 0.5 * (vy2 + _nx(vy2, wrap))
    hx = quarter_alpha / np.sqrt((_nx(u, wrap) - u) ** 2 + t1 ** 2 + (_nx(v, wrap) - v) ** 2 + t2 ** 2 + EPS2)
    if not wrap:
        hx[:, -1] = 0.0
    uy1, vy1, s1, s2 = (np.zeros_like(u) for _ in range(4))
    uy1[:-1], vy1[:-1] = u[1:] - u[:-1], v[1:] - v[:-1]
    s1[:-1], s2[:-1] = 0.5 * (ux2[:-1] + ux2[1:]), 0.5 * (vx2[:-1] + vx2[1:])
    hy = quarter_alpha / np.sqrt(uy1 ** 2 + s1 ** 2 + vy1 ** 2 + s2 ** 2 + EPS2)
    hy[-1] = 0.0

    def rhs(w0):
        w0 = w0.astype(np.float64)
        fx = hx * (_nx(w0, wrap) - w0)
        out = fx - (np.roll(fx, 1, axis=1) if wrap else np.concatenate([np.zeros_like(fx[:, :1]), fx[:, :-1]], 1))
        fy = np.zeros_like(w0)
        fy[:-1] = hy[:-1] * (w0[1:] - w0[:-1])
        out += fy
        out[1:] -= fy[:-1]
        return out

    return hx, hy, rhs(w_u), rhs(w_v)


def sor_numpy(du, dv, a11, a12, a22, b1, b2, hx, hy, iters, omega, wrap):
    """Red-black SOR, each colour's pixels updated at once with numpy (float64)."""
    du, dv = du.astype(np.float64), dv.astype(np.float64)
    h, w = du.shape
    hl = _px(hx.astype(np.float64), True) if wrap else np.concatenate([np.zeros((h, 1)), hx[:, :-1]], axis=1)
    hu = np.concatenate([np.zeros((1, w)), hy[:-1]], axis=0)
    sh = hl + hx + hu + hy
    ii, jj = np.mgrid[0:h, 0:w]

    def nb(x):
        up = np.concatenate([x[:1], x[:-1]], axis=0)
        dn = np.concatenate([x[1:], x[-1:]], axis=0)
        return hl * np.roll(x, 1, axis=1) + hx * np.roll(x, -1, axis=1) + hu * up + hy * dn

    for _ in range(iters):
        for colour in range(2):
            sel = (ii + jj) % 2 == colour
            nu = (1 - omega) * du + omega * (b1 + nb(du) - a12 * dv) / (a11 + sh + 1e-12)
            du = np.where(sel, nu, du)
            nv = (1 - omega) * dv + omega * (b2 + nb(dv) - a12 * du) / (a22 + sh + 1e-12)
            dv = np.where(sel, nv, dv)
    return du, dv


@pytest.mark.parametrize("wrap", [True, False])
def test_smoothness_kernel_equals_numpy(wrap):
    rng = np.random.default_rng(1)
    h, w = 9, 12
    w_u, w_v, du, dv = (rng.normal(0, 2, (h, w)).astype(np.float32) for _ in range(4))
    b1, b2 = (rng.normal(0, 1, (h, w)).astype(np.float32) for _ in range(2))
    b1_0, b2_0 = b1.copy(), b2.copy()
    hx, hy = _smoothness(w_u, w_v, du, dv, 1.5, wrap, b1, b2)
    rx, ry, r1, r2 = smoothness_numpy(w_u, w_v, du, dv, 1.5, wrap)
    for got, want in ((hx, rx), (hy, ry), (b1 - b1_0, r1), (b2 - b2_0, r2)):
        np.testing.assert_allclose(got, want, rtol=1e-5, atol=1e-5)


@pytest.mark.parametrize("wrap", [True, False])
def test_sor_kernel_equals_numpy(wrap):
    rng = np.random.default_rng(2)
    h, w = 7, 10  # odd height, even width: both colours start on either column in some row
    a11, a22 = (rng.uniform(0.1, 2, (h, w)).astype(np.float32) for _ in range(2))
    a12 = (0.3 * rng.uniform(-1, 1, (h, w)) * np.sqrt(a11 * a22)).astype(np.float32)
    b1, b2 = (rng.normal(0, 1, (h, w)).astype(np.float32) for _ in range(2))
    hx, hy = (rng.uniform(0, 1, (h, w)).astype(np.float32) for _ in range(2))
    hy[-1] = 0.0
    if not wrap:
        hx[:, -1] = 0.0
    du0, dv0 = (rng.normal(0, 0.5, (h, w)).astype(np.float32) for _ in range(2))
    du, dv = du0.copy(), dv0.copy()
    _sor(du, dv, a11, a12, a22, b1, b2, hx, hy, 6, 1.6, wrap)
    ru, rv = sor_numpy(du0, dv0, a11, a12, a22, b1, b2, hx, hy, 6, 1.6, wrap)
    np.testing.assert_allclose(du, ru, rtol=1e-5, atol=1e-5)
    np.testing.assert_allclose(dv, rv, rtol=1e-5, atol=1e-5)
