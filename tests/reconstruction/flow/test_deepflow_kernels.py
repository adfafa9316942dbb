"""DeepFlow's numba kernels against straightforward numpy versions of the same maths, on small random inputs."""

from __future__ import annotations

import numpy as np
import pytest

from reconstruction.flow.deepflow import (
    _N_SUMS,
    _N_TERMS,
    _SOR_WAVE,
    DATANORM,
    EPS2,
    _data_terms,
    _dx5,
    _dy5,
    _image_terms,
    _smoothness,
    _sor,
)


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

    # with wrapping and an odd width the last column has the first's colour and neighbour: it is updated after
    # the colour's other pixels
    last = (jj == w - 1) if wrap and w % 2 == 1 else np.zeros((h, w), bool)
    for _ in range(iters):
        for colour in range(2):
            for sel in (((ii + jj) % 2 == colour) & ~last, ((ii + jj) % 2 == colour) & last):
                nu = (1 - omega) * du + omega * (b1 + nb(du) - a12 * dv) / (a11 + sh + 1e-12)
                du = np.where(sel, nu, du)
                nv = (1 - omega) * dv + omega * (b2 + nb(dv) - a12 * du) / (a22 + sh + 1e-12)
                dv = np.where(sel, nv, dv)
    return du, dv


def image_terms_numpy(im1, im2w, wrap):
    """The per-channel derivatives (float32, with the module's numpy _dx5 / _dy5), and the normalisations and the
    summed system coefficients in float64, as (11, c, h, w) and (10, h, w) arrays."""
    mean, iz = 0.5 * (im1 + im2w), im2w - im1
    ix, iy = _dx5(mean, wrap), _dy5(mean)
    ixx, ixy, iyy, ixz, iyz = _dx5(ix, wrap), _dy5(ix), _dy5(iy), _dx5(iz, wrap), _dy5(iz)
    d = [x.astype(np.float64) for x in (iz, ix, iy, ixx, ixy, iyy, ixz, iyz)]
    iz, ix, iy, ixx, ixy, iyy, ixz, iyz = d
    nd = 1.0 / (ix ** 2 + iy ** 2 + DATANORM)
    nx = 1.0 / (ixx ** 2 + ixy ** 2 + DATANORM)
    ny = 1.0 / (iyy ** 2 + ixy ** 2 + DATANORM)
    terms = np.stack([x.transpose(2, 0, 1) for x in d + [nd, nx, ny]])
    sums = np.stack([(nd * ix * ix).sum(2), (nd * ix * iy).sum(2), (nd * iy * iy).sum(2), (nd * iz * ix).sum(2),
                     (nd * iz * iy).sum(2), (nx * ixx * ixx + ny * ixy * ixy).sum(2),
                     (nx * ixx * ixy + ny * ixy * iyy).sum(2), (nx * ixy * ixy + ny * iyy * iyy).sum(2),
                     (nx * ixx * ixz + ny * ixy * iyz).sum(2), (nx * ixy * ixz + ny * iyy * iyz).sum(2)])
    return terms, sums


def data_terms_numpy(terms, du, dv, mask, w_u, w_v, mu, mv, mw, hd, hg, half_beta):
    """The linearised data and matching terms, channel by channel as in the paper, in float64."""
    iz, ix, iy, ixx, ixy, iyy, ixz, iyz, nd, nx, ny = terms.astype(np.float64)
    du, dv, mask, w_u, w_v, mu, mv, mw = (x.astype(np.float64) for x in (du, dv, mask, w_u, w_v, mu, mv, mw))
    psi = mask * hd / np.sqrt((nd * (iz + ix * du + iy * dv) ** 2).sum(0) + EPS2)
    q = psi * nd
    a11, a12, a22 = (q * ix * ix).sum(0), (q * ix * iy).sum(0), (q * iy * iy).sum(0)
    b1, b2 = -(q * iz * ix).sum(0), -(q * iz * iy).sum(0)
    tx, ty = ixz + ixx * du + ixy * dv, iyz + ixy * du + iyy * dv
    psi = mask * hg / np.sqrt((nx * tx ** 2 + ny * ty ** 2).sum(0) + EPS2)
    qx, qy = psi * nx, psi * ny
    a11 += (qx * ixx * ixx + qy * ixy * ixy).sum(0)
    a12 += (qx * ixx * ixy + qy * ixy * iyy).sum(0)
    a22 += (qx * ixy * ixy + qy * iyy * iyy).sum(0)
    b1 -= (qx * ixx * ixz + qy * ixy * iyz).sum(0)
    b2 -= (qx * ixy * ixz + qy * iyy * iyz).sum(0)
    psi = np.where(mw > 0, half_beta * mw / np.sqrt((w_u + du - mu) ** 2 + (w_v + dv - mv) ** 2 + EPS2), 0.0)
    return a11 + psi, a12, a22 + psi, b1 - psi * (w_u - mu), b2 - psi * (w_v - mv)


def _images(h, w, seed):
    """Two smooth-ish random (h, w, 3) float32 images, 0..255."""
    rng = np.random.default_rng(seed)
    base = rng.uniform(0, 255, (h, w, 3)).astype(np.float32)
    im1 = (0.5 * base + 0.5 * np.roll(base, 1, axis=1)).astype(np.float32)
    im2w = (im1 + rng.normal(0, 5, (h, w, 3))).astype(np.float32)
    return im1, im2w


@pytest.mark.parametrize("wrap", [True, False])
@pytest.mark.parametrize("shape", [(9, 12), (6, 5)])
def test_image_terms_kernel_equals_numpy(wrap, shape):
    """The derivatives are numpy's float32 operations (equal to 1e-6 relative); the normalisations and the sums,
    float64 in the kernel, to 1e-6 relative of their largest value."""
    h, w = shape
    im1, im2w = _images(h, w, 3)
    terms = np.empty((_N_TERMS, 3, h, w), np.float32)
    sums = np.empty((_N_SUMS, h, w), np.float32)
    _image_terms(im1, im2w, wrap, terms, sums)
    rt, rs = image_terms_numpy(im1, im2w, wrap)
    for q in range(_N_TERMS):
        np.testing.assert_allclose(terms[q], rt[q], rtol=1e-6, atol=1e-6 * np.abs(rt[q]).max())
    for q in range(_N_SUMS):
        np.testing.assert_allclose(sums[q], rs[q], rtol=1e-5, atol=1e-6 * np.abs(rs[q]).max())


def test_data_terms_kernel_equals_numpy():
    """The kernel (energies in float32, the system from the per-level sums) against the channel-by-channel
    formulas in float64: 1e-5 relative of each output's largest value; pixels without a match, with a match, and
    outside the warp (mask 0) all occur."""
    h, w = 8, 13
    rng = np.random.default_rng(4)
    im1, im2w = _images(h, w, 5)
    terms = np.empty((_N_TERMS, 3, h, w), np.float32)
    sums = np.empty((_N_SUMS, h, w), np.float32)
    _image_terms(im1, im2w, True, terms, sums)
    du, dv, w_u, w_v, mu, mv = (rng.normal(0, 1, (h, w)).astype(np.float32) for _ in range(6))
    mw = np.where(rng.random((h, w)) < 0.3, rng.uniform(0.1, 3, (h, w)), 0.0).astype(np.float32)
    mask = (rng.random((h, w)) < 0.8).astype(np.float32)
    out = [np.full((h, w), np.nan, np.float32) for _ in range(5)]
    _data_terms(terms, sums, mask, du, dv, w_u, w_v, mu, mv, mw, 0.5 / 6, 5.0 / 6, 95.0, *out)
    ref = data_terms_numpy(terms, du, dv, mask, w_u, w_v, mu, mv, mw, 0.5 / 6, 5.0 / 6, 95.0)
    for got, want in zip(out, ref, strict=True):
        np.testing.assert_allclose(got, want, rtol=1e-5, atol=1e-5 * np.abs(want).max())


@pytest.mark.parametrize("wrap", [True, False])
@pytest.mark.parametrize("shape", [(9, 12), (4, 7)])
def test_smoothness_kernel_equals_numpy(wrap, shape):
    rng = np.random.default_rng(1)
    h, w = shape
    w_u, w_v, du, dv = (rng.normal(0, 2, (h, w)).astype(np.float32) for _ in range(4))
    b1, b2 = (rng.normal(0, 1, (h, w)).astype(np.float32) for _ in range(2))
    b1_0, b2_0 = b1.copy(), b2.copy()
    hx, hy, su, sv = (np.full((h, w), np.nan, np.float32) for _ in range(4))
    _smoothness(w_u, w_v, du, dv, 1.5, wrap, b1, b2, hx, hy, su, sv)
    rx, ry, r1, r2 = smoothness_numpy(w_u, w_v, du, dv, 1.5, wrap)
    for got, want in ((hx, rx), (hy, ry), (b1 - b1_0, r1), (b2 - b2_0, r2)):
        np.testing.assert_allclose(got, want, rtol=1e-5, atol=1e-5)


@pytest.mark.parametrize("wrap", [True, False])
@pytest.mark.parametrize("shape", [(7, 10), (8, 11), (3, 9), (12, 4)])
@pytest.mark.parametrize("iters", [1, _SOR_WAVE, 2 * _SOR_WAVE + 1])
def test_sor_kernel_equals_numpy(wrap, shape, iters):
    """Odd and even heights and widths (with wrapping and an odd width the first and last columns have the same
    colour); sweep counts below, at and above the wavefront's group; the scratch starts as NaN."""
    rng = np.random.default_rng(2)
    h, w = shape
    a11, a22 = (rng.uniform(0.1, 2, (h, w)).astype(np.float32) for _ in range(2))
    a12 = (0.3 * rng.uniform(-1, 1, (h, w)) * np.sqrt(a11 * a22)).astype(np.float32)
    b1, b2 = (rng.normal(0, 1, (h, w)).astype(np.float32) for _ in range(2))
    hx, hy = (rng.uniform(0, 1, (h, w)).astype(np.float32) for _ in range(2))
    hy[-1] = 0.0
    if not wrap:
        hx[:, -1] = 0.0
    du0, dv0 = (rng.normal(0, 0.5, (h, w)).astype(np.float32) for _ in range(2))
    du, dv = du0.copy(), dv0.copy()
    split = np.full((9, 2 * h * ((w + 1) // 2) + 3), np.nan, np.float32)
    _sor(du, dv, a11, a12, a22, b1, b2, hx, hy, iters, 1.6, wrap, split)
    ru, rv = sor_numpy(du0, dv0, a11, a12, a22, b1, b2, hx, hy, iters, 1.6, wrap)
    np.testing.assert_allclose(du, ru, rtol=1e-5, atol=1e-5)
    np.testing.assert_allclose(dv, rv, rtol=1e-5, atol=1e-5)
