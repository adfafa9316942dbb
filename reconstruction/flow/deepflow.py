"""DeepFlow (Weinzaepfel, Revaud, Harchaoui & Schmid, ICCV 2013): variational flow with a matching term.

The flow ``w = (u, v)`` from image 1 to image 2 minimises

    E(w) = integral of  delta Psi(sum_c |I2_c(x + w) - I1_c(x)|^2 / n_c)                (colour constancy)
                      + gamma Psi(sum_c |grad I2_c(x + w) - grad I1_c(x)|^2 / n'_c)     (gradient constancy)
                      + alpha Psi(|grad u|^2 + |grad v|^2)                               (smoothness)
                      + beta_k phi(x) Psi(|w - w_match|^2)                                (matching term)

with the robust penaliser ``Psi(s^2) = sqrt(s^2 + eps^2)`` (eps = 1e-3), the per-channel normalisations
``n = |grad I|^2 + 0.1^2`` of Zimmer et al. (images in 0..255), and the matching term fed by
:func:`reconstruction.flow.deepmatching.deep_matching`, as in the authors' code: each match is a single point of
weight ``phi`` (:func:`match_weights`: image 0's texture at the match times the agreement of both images at its
ends; DeepMatching's score is not used), bilinearly splatted on each level's grid where the weights add up and
``w_match`` is their weighted mean (:func:`match_field`), so the term is sparse at fine levels and pulls hard
only at coarse ones, where many matches fall on one pixel.  The energy is
minimised coarse to fine (pyramid factor ``eta`` = 0.95 down to ``min_size`` = 25 pixels); at each level, ``n_inner``
fixed-point iterations linearise the data terms around the current flow (the second image warped by it) and
solve the linear system of the increment with ``n_solver`` coupled red-black SOR sweeps (relaxation ``omega``);
the matching weight decays from the coarsest level to the finest as ``beta_k = beta (k / (L - 1))^bk``.

Parameters are the defaults of the authors' code (``optical_flow_params_default`` of DeepFlow 2): alpha 6,
beta 390, gamma 5, delta 0.5, sigma 0.6 (presmoothing, pixels), bk 1, eta 0.95, min_size 25, 5 inner
iterations, 25 SOR sweeps, omega 1.6.

Equirect images wrap in longitude (``wrap=True``): columns are periodic in the warp, the derivatives, the
smoothness term and the solver, so the flow crosses the seam with no padding.

OpenCV pieces: image resizing and blurring only.  ``cv2.optflow.createOptFlow_DeepFlow`` (the variational part
with the same defaults' family) and ``cv2.VariationalRefinement`` have no matching term and no periodic
boundary, so the whole solver is here: numba kernels for the warp, the image derivatives, the data, matching and
smoothness terms and SOR, all single-threaded and releasing the GIL (:func:`deep_flow_both` solves a pair's two
directions on two threads).  Per level, the image terms that do not change over the fixed-point iterations (the
derivatives, their normalisations and the data terms' system before its robust weights) are computed once; the
SOR sweeps run on a colour-split copy of the system (each row's pixels of one colour contiguous, vectorised);
scratch arrays are allocated once per flow, for the finest level, and reused by every level.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from dataclasses import asdict, dataclass, field

import cv2
import numba
import numpy as np

from reconstruction.camera.image_ops import central_differences
from reconstruction.flow.deepmatching import (
    DeepMatchingParams,
    Matches,
    blur_periodic,
    deep_matching,
    deep_matching_both,
)

__all__ = ["DeepFlowParams", "deep_flow", "deep_flow_both", "match_field", "match_weights"]

DATANORM = 0.1 * 0.1  # squared normalisation added to |grad I|^2 (grey levels^2 per pixel^2)
EPS2 = 0.001 * 0.001  # squared epsilon of the robust penaliser


@dataclass(frozen=True)
class DeepFlowParams:
    """DeepFlow's parameters (the authors' code defaults).

    Attributes:
        alpha: smoothness weight (dimensionless; data terms are normalised).
        beta: matching-term weight.
        gamma: gradient-constancy weight.
        delta: colour-constancy weight.
        sigma: Gaussian presmoothing of both images, pixels.
        bk: decay exponent of the matching weight over the levels (0: constant).
        eta: pyramid scale factor between consecutive levels.
        min_size: the coarsest level is the last whose width and height are at least this, pixels.
        n_inner: fixed-point (warping) iterations per level.
        n_solver: SOR sweeps per fixed-point iteration.
        sor_omega: SOR relaxation factor.
        wrap: columns are periodic (equirect longitude).
        matching: DeepMatching's parameters (its ``wrap`` is set to this ``wrap``).
    """

    alpha: float = 6.0
    beta: float = 390.0
    gamma: float = 5.0
    delta: float = 0.5
    sigma: float = 0.6
    bk: float = 1.0
    eta: float = 0.95
    min_size: int = 25
    n_inner: int = 5
    n_solver: int = 25
    sor_omega: float = 1.6
    wrap: bool = True
    matching: DeepMatchingParams = field(default_factory=DeepMatchingParams)

    def config(self) -> dict:
        return asdict(self)


def match_weights(img0: np.ndarray, img1: np.ndarray, m: Matches, wrap: bool = True) -> np.ndarray:
    """Each match's weight phi in the matching term, as the authors' DeepFlow code computes it (its
    ``compute_desc_weight``; DeepMatching's score is not used): high where image 0 is textured in every direction
    and where both images agree at the match's ends,

        phi = 10 sqrt(lambda_min) / (50 sqrt(2 pi)) exp(-s^2 / (2 50^2)),

    with ``lambda_min`` the smaller eigenvalue of image 0's structure tensor (images smoothed by sigma 0.8 px,
    central differences, summed over channels, integrated by a Gaussian of sigma 3 px; grey levels^2 per px^2)
    at the match's start, and ``s`` the sum over channels of the absolute differences of the smoothed colours and
    of their five-point x and y derivatives between the start and the (nearest-pixel) end (grey levels).

    Args:
        img0, img1: (H, W, 3) uint8 RGB or (H, W) grey images, 0..255.
        m: matches from img0 to img1, input pixels.
        wrap: columns are periodic.
    Returns:
        (M,) float64 weights, >= 0 (about 1 for a match in good texture whose ends agree).
    """
    if m.x0.size == 0:
        return np.zeros(0)
    h, w = img0.shape[:2]

    def prep(img):  # a grey image counts as three equal channels, as in the authors' code
        x = img.astype(np.float32)
        return blur_periodic(np.repeat(x[..., None], 3, axis=2) if x.ndim == 2 else x, 0.8, wrap).reshape(h, w, -1)

    s0, s1 = prep(img0), prep(img1)
    cx, cy = central_differences(s0, wrap)
    jxx = blur_periodic(np.ascontiguousarray((cx * cx).sum(2)), 3.0, wrap)
    jxy = blur_periodic(np.ascontiguousarray((cx * cy).sum(2)), 3.0, wrap)
    jyy = blur_periodic(np.ascontiguousarray((cy * cy).sum(2)), 3.0, wrap)
    t = 0.5 * (jxx + jyy)
    lam = t - np.sqrt(np.maximum(t * t + jxy * jxy - jxx * jyy, 0.0))
    i0 = np.clip(np.rint(m.y0).astype(np.int64), 0, h - 1)
    i1 = np.clip(np.rint(m.y1).astype(np.int64), 0, h - 1)
    j0, j1 = np.rint(m.x0).astype(np.int64), np.rint(m.x1).astype(np.int64)
    j0, j1 = (j0 % w, j1 % w) if wrap else (np.clip(j0, 0, w - 1), np.clip(j1, 0, w - 1))
    score = np.abs(s0[i0, j0] - s1[i1, j1]).sum(1)
    for d0, d1 in ((_dx5(s0, wrap), _dx5(s1, wrap)), (_dy5(s0), _dy5(s1))):
        score += np.abs(d0[i0, j0] - d1[i1, j1]).sum(1)
    sig = 50.0  # grey levels
    gauss = np.exp(-score ** 2 / (2 * sig ** 2)) / (sig * np.sqrt(2 * np.pi))
    return np.maximum(10.0 * np.sqrt(np.maximum(lam[i0, j0], 0.0)) * gauss, 0.0).astype(np.float64)


def match_field(m: Matches, phi: np.ndarray, h: int, w: int, wrap: bool = True,
                level_hw: tuple[int, int] | None = None):
    """The matches as dense maps at one pyramid level, as the authors' ``descflow_resize``: each match is one
    point (its image-0 position), bilinearly splatted on the level's pixel grid; the weights *add up* and the
    flow is their weighted mean.

    Args:
        m: matches in input pixels (centres at integers).
        phi: (M,) each match's weight (dimensionless, >= 0; :func:`match_weights`).
        h, w: the input size, pixels.
        wrap: columns are periodic.
        level_hw: (lh, lw) the level's size (default (h, w)); positions map as ``(x + 0.5) lw / w - 0.5`` (the
            centre-aligned mapping of ``cv2.resize``) and the flow is scaled by ``lw / w``, ``lh / h``.
    Returns:
        ``(mu, mv, mw)``, each (lh, lw) float32: the matches' flow (level pixels) and the summed weights (0 where
        no match).
    """
    lh, lw = level_hw if level_hw is not None else (h, w)
    if m.x0.size == 0:
        return tuple(np.zeros((lh, lw), np.float32) for _ in range(3))
    phi = np.asarray(phi, np.float64)
    sx, sy = lw / w, lh / h
    fu, fv = (m.x1 - m.x0) * sx, (m.y1 - m.y0) * sy
    xs = (m.x0 + 0.5) * sx - 0.5
    ys = np.clip((m.y0 + 0.5) * sy - 0.5, 0.0, lh - 1.0)
    if wrap:
        xs = xs % lw
    else:
        xs = np.clip(xs, 0.0, lw - 1.0)
    x0f, y0f = np.floor(xs), np.floor(ys)
    ax, ay = xs - x0f, ys - y0f
    x0i, y0i = x0f.astype(np.int64), y0f.astype(np.int64)
    cells, wts = [], []
    for dy, wy in ((0, 1.0 - ay), (1, ay)):
        yi = np.minimum(y0i + dy, lh - 1)
        for dx, wx in ((0, 1.0 - ax), (1, ax)):
            xi = (x0i + dx) % lw if wrap else np.minimum(x0i + dx, lw - 1)
            cells.append(yi * lw + xi)
            wts.append(phi * wx * wy)
    # the four corners' splats added one after the other into zeroed maps (bincount adds in input order)
    cell, wt = np.concatenate(cells), np.concatenate(wts)
    mw = np.bincount(cell, wt, lh * lw).reshape(lh, lw)
    mu = np.bincount(cell, wt * np.tile(fu, 4), lh * lw).reshape(lh, lw)
    mv = np.bincount(cell, wt * np.tile(fv, 4), lh * lw).reshape(lh, lw)
    ok = mw > 1e-10
    mu[ok] /= mw[ok]
    mv[ok] /= mw[ok]
    mw[~ok] = 0.0
    return mu.astype(np.float32), mv.astype(np.float32), mw.astype(np.float32)


@numba.njit(cache=True, nogil=True)
def _warp(img, u, v, wrap):
    """Bilinear sample of (h, w, c) ``img`` at x + u, y + v; mask 0 where the target leaves the rows (or, without
    wrapping, the columns).  Single-threaded, releases the GIL."""
    h, w, c = img.shape
    out = np.empty_like(img)
    mask = np.empty((h, w), np.float32)
    for i in range(h):
        for j in range(w):
            xx = j + u[i, j]
            yy = i + v[i, j]
            inside = yy >= 0 and yy <= h - 1 and (wrap or (xx >= 0 and xx <= w - 1))
            mask[i, j] = 1.0 if inside else 0.0
            x0 = int(np.floor(xx))
            y0 = int(np.floor(yy))
            dx = xx - x0
            dy = yy - y0
            if wrap:
                xa, xb = x0 % w, (x0 + 1) % w
            else:
                xa, xb = min(max(x0, 0), w - 1), min(max(x0 + 1, 0), w - 1)
            ya, yb = min(max(y0, 0), h - 1), min(max(y0 + 1, 0), h - 1)
            for k in range(c):
                out[i, j, k] = ((1 - dx) * (1 - dy) * img[ya, xa, k] + dx * (1 - dy) * img[ya, xb, k]
                                + (1 - dx) * dy * img[yb, xa, k] + dx * dy * img[yb, xb, k])
    return out, mask


# the image terms of a pyramid level (_image_terms): per-channel planes (_N_TERMS, c, h, w) and summed planes
# (_N_SUMS, h, w)
_IZ, _IX, _IY, _IXX, _IXY, _IYY, _IXZ, _IYZ, _ND, _NX, _NY = range(11)
_N_TERMS = 11
_D11, _D12, _D22, _D1, _D2, _G11, _G12, _G22, _G1, _G2 = range(10)
_N_SUMS = 10
_SOR_WAVE = 5  # SOR sweeps done together as a wavefront down the rows (_sor)


@numba.njit(cache=True, nogil=True, inline="always")
def _col(j, w, wrap):
    """Column index j (possibly outside 0..w-1): wrapped if ``wrap``, else clamped to the edge."""
    if wrap:
        return j % w
    return min(max(j, 0), w - 1)


@numba.njit(cache=True, nogil=True)
def _d5x(x, out, wrap):
    """out = five-point derivative (1, -8, 0, 8, -1) / 12 of x along columns, in float32 (the same operations as
    :func:`_dx5`).  x, out: (h, w) float32 planes; columns wrapped or edge-replicated."""
    h, w = x.shape
    e8, d12 = np.float32(8.0), np.float32(12.0)
    for i in range(h):
        for j in range(min(2, w)):
            out[i, j] = (-x[i, _col(j + 2, w, wrap)] + e8 * x[i, _col(j + 1, w, wrap)]
                         - e8 * x[i, _col(j - 1, w, wrap)] + x[i, _col(j - 2, w, wrap)]) / d12
        for j0 in range(w - 4):  # j = j0 + 2, indices from 0 up (no negative-index handling, vectorised)
            out[i, j0 + 2] = (-x[i, j0 + 4] + e8 * x[i, j0 + 3] - e8 * x[i, j0 + 1] + x[i, j0]) / d12
        for j in range(max(w - 2, 2), w):
            out[i, j] = (-x[i, _col(j + 2, w, wrap)] + e8 * x[i, _col(j + 1, w, wrap)]
                         - e8 * x[i, _col(j - 1, w, wrap)] + x[i, _col(j - 2, w, wrap)]) / d12


@numba.njit(cache=True, nogil=True)
def _d5y(x, out):
    """out = five-point derivative of x along rows, edge rows replicated, in float32 (as :func:`_dy5`).
    x, out: (h, w) float32 planes."""
    h, w = x.shape
    e8, d12 = np.float32(8.0), np.float32(12.0)
    for i in range(h):
        r2, r1 = min(i + 2, h - 1), min(i + 1, h - 1)
        m1, m2 = max(i - 1, 0), max(i - 2, 0)
        for j in range(w):
            out[i, j] = (-x[r2, j] + e8 * x[r1, j] - e8 * x[m1, j] + x[m2, j]) / d12


@numba.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _recip_norm(a, b):
    """1 / (a^2 + b^2 + DATANORM) in float64 for float32 a, b (the squares summed in float32)."""
    return 1.0 / (np.float64(a * a + b * b) + DATANORM)


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _image_terms(im1, im2w, wrap, terms, sums):
    """The image terms of one pyramid level, once per warp.

    Per channel k the planes ``terms[q, k]`` (float32; grey levels, per pixel for each derivative) of

        iz = I2w - I1, ix, iy = five-point x and y derivatives of the mean (I1 + I2w) / 2,
        ixx = d/dx ix, ixy = d/dy ix, iyy = d/dy iy, ixz = d/dx iz, iyz = d/dy iz,
        nd = 1 / (ix^2 + iy^2 + DATANORM), nx = 1 / (ixx^2 + ixy^2 + DATANORM), ny = 1 / (iyy^2 + ixy^2 + DATANORM)

    (q = _IZ ... _NY; nd, nx, ny are the per-channel normalisations of the colour and gradient constancy terms),
    and over the channels the sums ``sums[q]`` (float32, q = _D11 ... _G2) that make the data terms' system
    apart from its robust weights:

        D11, D12, D22 = sum nd (ix ix, ix iy, iy iy),  D1, D2 = sum nd iz (ix, iy),
        G11 = sum nx ixx^2 + ny ixy^2,  G12 = sum nx ixx ixy + ny ixy iyy,  G22 = sum nx ixy^2 + ny iyy^2,
        G1 = sum nx ixx ixz + ny ixy iyz,  G2 = sum nx ixy ixz + ny iyy iyz.

    The derivatives are the float32 operations of :func:`_dx5` / :func:`_dy5`; the normalisations and the sums
    are computed in float64.  Single-threaded, releases the GIL.

    Args:
        im1, im2w: (h, w, c) float32 first image and second image warped by the current flow.
        wrap: columns are periodic.
        terms: (11, c, h, w) float32, written.
        sums: (10, h, w) float32, written.
    """
    h, w, c = im1.shape
    half = np.float32(0.5)
    for k in range(c):
        mean = terms[_ND, k]  # scratch until the normalisations are written
        z = terms[_IZ, k]
        for i in range(h):
            for j in range(w):
                mean[i, j] = half * (im1[i, j, k] + im2w[i, j, k])
                z[i, j] = im2w[i, j, k] - im1[i, j, k]
        _d5x(mean, terms[_IX, k], wrap)
        _d5y(mean, terms[_IY, k])
        _d5x(terms[_IX, k], terms[_IXX, k], wrap)
        _d5y(terms[_IX, k], terms[_IXY, k])
        _d5y(terms[_IY, k], terms[_IYY, k])
        _d5x(z, terms[_IXZ, k], wrap)
        _d5y(z, terms[_IYZ, k])
    acc = np.empty((_N_SUMS, w))  # one row's sums, float64
    for i in range(h):
        acc[:] = 0.0
        for k in range(c):  # a few outputs per loop, columns innermost (vectorised)
            ix, iy, iz, nd = terms[_IX, k, i], terms[_IY, k, i], terms[_IZ, k, i], terms[_ND, k, i]
            ixx, ixy, iyy = terms[_IXX, k, i], terms[_IXY, k, i], terms[_IYY, k, i]
            ixz, iyz, nx, ny = terms[_IXZ, k, i], terms[_IYZ, k, i], terms[_NX, k, i], terms[_NY, k, i]
            for j in range(w):
                nd[j] = _recip_norm(ix[j], iy[j])
                nx[j] = _recip_norm(ixx[j], ixy[j])
                ny[j] = _recip_norm(iyy[j], ixy[j])
            for j in range(w):
                q, gx, gy, gz = _recip_norm(ix[j], iy[j]), np.float64(ix[j]), np.float64(iy[j]), np.float64(iz[j])
                acc[_D11, j] += q * gx * gx
                acc[_D12, j] += q * gx * gy
                acc[_D22, j] += q * gy * gy
                acc[_D1, j] += q * gz * gx
                acc[_D2, j] += q * gz * gy
            for j in range(w):
                qx, qy = _recip_norm(ixx[j], ixy[j]), _recip_norm(iyy[j], ixy[j])
                gxx, gxy, gyy = np.float64(ixx[j]), np.float64(ixy[j]), np.float64(iyy[j])
                acc[_G11, j] += qx * gxx * gxx + qy * gxy * gxy
                acc[_G12, j] += qx * gxx * gxy + qy * gxy * gyy
                acc[_G22, j] += qx * gxy * gxy + qy * gyy * gyy
            for j in range(w):
                qx, qy = _recip_norm(ixx[j], ixy[j]), _recip_norm(iyy[j], ixy[j])
                gxx, gxy, gyy = np.float64(ixx[j]), np.float64(ixy[j]), np.float64(iyy[j])
                gxz, gyz = np.float64(ixz[j]), np.float64(iyz[j])
                acc[_G1, j] += qx * gxx * gxz + qy * gxy * gyz
                acc[_G2, j] += qx * gxy * gxz + qy * gyy * gyz
        for q in range(_N_SUMS):
            for j in range(w):
                sums[q, i, j] = acc[q, j]


@numba.njit(cache=True, nogil=True, fastmath=True, error_model="numpy")
def _data_terms(terms, sums, mask, du, dv, w_u, w_v, mu, mv, mw, hd, hg, half_beta, a11, a12, a22, b1, b2):
    """The linearised data and matching terms of one fixed-point iteration: per pixel the 2 x 2 system
    ``[[a11, a12], [a12, a22]] (du, dv) = (b1, b2)`` (before smoothness), the robust weights taken at the current
    increment (du, dv):

        colour:   psi_d = mask hd / sqrt(sum_k nd (iz + ix du + iy dv)^2 + eps^2)
        gradient: psi_g = mask hg / sqrt(sum_k nx (ixz + ixx du + ixy dv)^2 + ny (iyz + ixy du + iyy dv)^2 + eps^2)
        matching: psi_m = half_beta mw / sqrt(|w + d - m|^2 + eps^2)
        a11 = psi_d D11 + psi_g G11 + psi_m,  a12 = psi_d D12 + psi_g G12,  a22 = psi_d D22 + psi_g G22 + psi_m,
        b1 = -(psi_d D1 + psi_g G1) - psi_m (w_u - mu),  b2 = -(psi_d D2 + psi_g G2) - psi_m (w_v - mv)

    (the sums D, G of :func:`_image_terms`).  Each row's energies are summed channel by channel with the columns
    innermost (vectorised).  Single-threaded, releases the GIL.

    Args:
        terms, sums: (11, c, h, w) and (10, h, w) float32 image terms of :func:`_image_terms`.
        mask: (h, w) float32, 1 where the warp stays inside the image, else 0.
        du, dv: (h, w) float32 increment, pixels; w_u, w_v: (h, w) float32 flow, pixels.
        mu, mv, mw: (h, w) float32 matches' flow (pixels) and weights (:func:`match_field`).
        hd, hg: colour and gradient constancy weights (delta / 6, gamma / 6); half_beta: matching weight / 2.
        a11, a12, a22, b1, b2: (h, w) float32, written.
    """
    c, h, w = terms.shape[1:]
    ed = np.zeros(w, np.float32)
    eg = np.zeros(w, np.float32)
    for i in range(h):
        if hd > 0:
            ed[:] = 0.0
            for k in range(c):
                for j in range(w):
                    t = terms[_IZ, k, i, j] + terms[_IX, k, i, j] * du[i, j] + terms[_IY, k, i, j] * dv[i, j]
                    ed[j] += t * t * terms[_ND, k, i, j]
        if hg > 0:
            eg[:] = 0.0
            for k in range(c):
                for j in range(w):
                    gxy = terms[_IXY, k, i, j]
                    tx = terms[_IXZ, k, i, j] + terms[_IXX, k, i, j] * du[i, j] + gxy * dv[i, j]
                    ty = terms[_IYZ, k, i, j] + gxy * du[i, j] + terms[_IYY, k, i, j] * dv[i, j]
                    eg[j] += tx * tx * terms[_NX, k, i, j] + ty * ty * terms[_NY, k, i, j]
        for j in range(w):
            pd = mask[i, j] * hd / np.sqrt(ed[j] + EPS2) if hd > 0 else 0.0
            pg = mask[i, j] * hg / np.sqrt(eg[j] + EPS2) if hg > 0 else 0.0
            eu = w_u[i, j] + du[i, j] - mu[i, j]
            ev = w_v[i, j] + dv[i, j] - mv[i, j]
            pm = half_beta * mw[i, j] / np.sqrt(eu * eu + ev * ev + EPS2)  # 0 where no match
            a11[i, j] = pd * sums[_D11, i, j] + pg * sums[_G11, i, j] + pm
            a12[i, j] = pd * sums[_D12, i, j] + pg * sums[_G12, i, j]
            a22[i, j] = pd * sums[_D22, i, j] + pg * sums[_G22, i, j] + pm
            b1[i, j] = -(pd * sums[_D1, i, j] + pg * sums[_G1, i, j]) - pm * (w_u[i, j] - mu[i, j])
            b2[i, j] = -(pd * sums[_D2, i, j] + pg * sums[_G2, i, j]) - pm * (w_v[i, j] - mv[i, j])


def _dx5(x: np.ndarray, wrap: bool) -> np.ndarray:
    """Five-point derivative (1, -8, 0, 8, -1) / 12 along columns (axis 1)."""
    if wrap:
        r = lambda k: np.roll(x, -k, axis=1)  # noqa: E731 -- x[j + k]
    else:
        xp = np.concatenate([x[:, :1], x[:, :1], x, x[:, -1:], x[:, -1:]], axis=1)
        r = lambda k: xp[:, 2 + k: xp.shape[1] - 2 + k]  # noqa: E731
    return (-r(2) + 8.0 * r(1) - 8.0 * r(-1) + r(-2)) / 12.0


def _dy5(x: np.ndarray) -> np.ndarray:
    """Five-point derivative along rows (axis 0), edge rows replicated."""
    xp = np.concatenate([x[:1], x[:1], x, x[-1:], x[-1:]], axis=0)
    r = lambda k: xp[2 + k: xp.shape[0] - 2 + k]  # noqa: E731
    return (-r(2) + 8.0 * r(1) - 8.0 * r(-1) + r(-2)) / 12.0


@numba.njit(cache=True, nogil=True, fastmath=True, error_model="numpy", inline="always")
def _hx_pixel(u, v, quarter_alpha, i, j, jr, iu, idn):
    """hx between (i, j) and (i, jr) (see :func:`_smoothness`)."""
    half = np.float32(0.5)
    a = u[i, jr] - u[i, j]
    b = 0.5 * (half * (u[idn, j] - u[iu, j]) + half * (u[idn, jr] - u[iu, jr]))
    c = v[i, jr] - v[i, j]
    d = 0.5 * (half * (v[idn, j] - v[iu, j]) + half * (v[idn, jr] - v[iu, jr]))
    return quarter_alpha / np.sqrt(a * a + b * b + c * c + d * d + EPS2)


@numba.njit(cache=True, nogil=True, fastmath=True, error_model="numpy", inline="always")
def _hy_pixel(u, v, quarter_alpha, i, j, jl, jr):
    """hy between (i, j) and (i + 1, j) (see :func:`_smoothness`)."""
    half = np.float32(0.5)
    a = u[i + 1, j] - u[i, j]
    b = 0.5 * (half * (u[i, jr] - u[i, jl]) + half * (u[i + 1, jr] - u[i + 1, jl]))
    c = v[i + 1, j] - v[i, j]
    d = 0.5 * (half * (v[i, jr] - v[i, jl]) + half * (v[i + 1, jr] - v[i + 1, jl]))
    return quarter_alpha / np.sqrt(a * a + b * b + c * c + d * d + EPS2)


@numba.njit(cache=True, nogil=True, fastmath=True, inline="always")
def _rhs_pixel(f, hx, hy, wl, i, j, jl, jr, iu, idn):
    """sum over the neighbours of (i, j) of h (f_nb - f) (see :func:`_smoothness`), wl the left link's weight."""
    s = hx[i, j] * (f[i, jr] - f[i, j])
    s -= wl * (f[i, j] - f[i, jl])
    s += hy[i, j] * (f[idn, j] - f[i, j])
    s -= hy[iu, j] * (f[i, j] - f[iu, j])
    return s


@numba.njit(cache=True, nogil=True, fastmath=True, error_model="numpy")
def _smoothness(w_u, w_v, du, dv, quarter_alpha, wrap, b1, b2, hx, hy, u, v):
    """The smoothness term of one fixed-point iteration.

    Diffusivities of the flow ``(u, v) = (w_u + du, w_v + dv)`` (pixels): ``hx[i, j] = quarter_alpha / sqrt(
    ux^2 + uy^2 + vx^2 + vy^2 + eps^2)`` between (i, j) and (i, j + 1), with the x derivatives the forward
    differences across that link and the y derivatives the mean of both ends' central differences; ``hy[i, j]``
    alike between rows i and i + 1.  Without wrapping the last column's hx is 0, and hy of the last row is always
    0; central differences replicate the edge pixel.  The current flow's smoothness is moved to the right-hand
    side: ``b1 += sum over neighbours of h (w_u_nb - w_u)`` and ``b2`` alike for ``w_v`` (in place).  One pass
    over the rows (hx, hy and the right-hand side of row i together); the first and last columns apart, so that
    the other columns are loops without index wrapping (vectorised).

    Args:
        w_u, w_v, du, dv: (h, w) float32 flow and its increment, pixels.
        quarter_alpha: alpha / 4.
        wrap: columns are periodic.
        b1, b2: (h, w) float32 right-hand sides, updated in place.
        hx, hy: (h, w) float32, written.
        u, v: (h, w) float32 scratch (written with the flow w + d).
    """
    h, w = w_u.shape
    for i in range(h):
        for j in range(w):
            u[i, j] = w_u[i, j] + du[i, j]
            v[i, j] = w_v[i, j] + dv[i, j]
    wl_last = w - 1 if wrap else 0  # the left neighbour of column 0
    wr_first = 0 if wrap else w - 1  # the right neighbour of column w - 1
    for i in range(h):
        iu, idn = max(i - 1, 0), min(i + 1, h - 1)
        for j in range(w - 1):
            hx[i, j] = _hx_pixel(u, v, quarter_alpha, i, j, j + 1, iu, idn)
        hx[i, w - 1] = _hx_pixel(u, v, quarter_alpha, i, w - 1, 0, iu, idn) if wrap else np.float32(0.0)
        if i < h - 1:
            hy[i, 0] = _hy_pixel(u, v, quarter_alpha, i, 0, wl_last, min(1, w - 1))
            for j in range(1, w - 1):
                hy[i, j] = _hy_pixel(u, v, quarter_alpha, i, j, j - 1, j + 1)
            if w > 1:
                hy[i, w - 1] = _hy_pixel(u, v, quarter_alpha, i, w - 1, w - 2, wr_first)
        else:
            hy[i, :] = 0.0
        # right-hand side of row i (hy of the last row is 0, and the first row's upper link is itself: both weigh
        # nothing); the columns without index wrapping in a loop of their own
        wl0 = hx[i, w - 1] if wrap else np.float32(0.0)
        jr0 = 1 if w > 1 else 0
        b1[i, 0] += _rhs_pixel(w_u, hx, hy, wl0, i, 0, w - 1, jr0, iu, idn)
        b2[i, 0] += _rhs_pixel(w_v, hx, hy, wl0, i, 0, w - 1, jr0, iu, idn)
        for j in range(1, w - 1):
            b1[i, j] += _rhs_pixel(w_u, hx, hy, hx[i, j - 1], i, j, j - 1, j + 1, iu, idn)
            b2[i, j] += _rhs_pixel(w_v, hx, hy, hx[i, j - 1], i, j, j - 1, j + 1, iu, idn)
        if w > 1:  # hx[i, w - 1] = 0 without wrapping
            b1[i, w - 1] += _rhs_pixel(w_u, hx, hy, hx[i, w - 2], i, w - 1, w - 2, 0, iu, idn)
            b2[i, w - 1] += _rhs_pixel(w_v, hx, hy, hx[i, w - 2], i, w - 1, w - 2, 0, iu, idn)


@numba.njit(cache=True, nogil=True, fastmath=True, inline="always")
def _sor_pixel(U, V, HX, HY, Q1, Q2, C12, C1, C2, keep, i, j, w, wrap):
    """One SOR update of pixel (i, j) (see :func:`_sor`; arrays in its colour-split layout), the column
    neighbours wrapped (without wrapping, the missing link's weight is 0)."""
    h = U.shape[1]
    c = (i + j) & 1
    cn = 1 - c
    t = j >> 1
    jl = j - 1 if j > 0 else w - 1
    jr = j + 1 if j < w - 1 else 0
    cl, cr = (i + jl) & 1, (i + jr) & 1  # the other colour, or with wrapping and an odd width this one
    wl = HX[cl, i, jl >> 1] if (j > 0 or wrap) else np.float32(0.0)
    wr = HX[c, i, t]
    wu = HY[cn, i - 1, t] if i > 0 else np.float32(0.0)
    wd = HY[c, i, t]  # 0 in the last row
    iu = i - 1 if i > 0 else 0
    idn = i + 1 if i < h - 1 else h - 1
    su = wl * U[cl, i, jl >> 1] + wr * U[cr, i, jr >> 1] + wu * U[cn, iu, t] + wd * U[cn, idn, t]
    sv = wl * V[cl, i, jl >> 1] + wr * V[cr, i, jr >> 1] + wu * V[cn, iu, t] + wd * V[cn, idn, t]
    nu = keep * U[c, i, t] + Q1[c, i, t] * (C1[c, i, t] + su - C12[c, i, t] * V[c, i, t])
    U[c, i, t] = nu
    V[c, i, t] = keep * V[c, i, t] + Q2[c, i, t] * (C2[c, i, t] + sv - C12[c, i, t] * nu)


@numba.njit(cache=True, nogil=True, fastmath=True, inline="always")
def _sor_row(Uf, Vf, HXf, HYf, Q1f, Q2f, C12f, C1f, C2f, U, V, HX, HY, Q1, Q2, C12, C1, C2, keep, i, colour, h, w, wh,
             wrap):
    """The SOR update of row i's pixels of one colour (see :func:`_sor`; ``*f`` the flat views of the split
    arrays)."""
    cn = 1 - colour
    iu = i - 1 if i > 0 else 0
    idn = i + 1 if i < h - 1 else h - 1  # hy[h - 1] = 0
    fu = np.float32(1.0) if i > 0 else np.float32(0.0)  # the first row has no upper neighbour
    j0 = (i + colour) & 1  # the row's first column of this colour
    t0 = 0
    if j0 == 0:
        _sor_pixel(U, V, HX, HY, Q1, Q2, C12, C1, C2, keep, i, 0, w, wrap)
        t0 = 1
    t1 = (w - j0) >> 1  # columns j0 + 2 t < w - 1
    pc = (colour * h + i) * wh  # this row and colour; the left neighbour of t at pl + t, the right at pl + t + 1
    pl = (cn * h + i) * wh + j0 - 1
    pu = (cn * h + iu) * wh
    pd = (cn * h + idn) * wh
    for t in range(t0, t1):  # unsigned offsets: no negative-index handling, vectorised
        kc, kl, ku, kd = np.uint64(pc + t), np.uint64(pl + t), np.uint64(pu + t), np.uint64(pd + t)
        kr = kl + np.uint64(1)
        wl, wr, wu, wd = HXf[kl], HXf[kc], fu * HYf[ku], HYf[kc]
        su = wl * Uf[kl] + wr * Uf[kr] + wu * Uf[ku] + wd * Uf[kd]
        sv = wl * Vf[kl] + wr * Vf[kr] + wu * Vf[ku] + wd * Vf[kd]
        nu = keep * Uf[kc] + Q1f[kc] * (C1f[kc] + su - C12f[kc] * Vf[kc])
        Uf[kc] = nu
        Vf[kc] = keep * Vf[kc] + Q2f[kc] * (C2f[kc] + sv - C12f[kc] * nu)
    if j0 + 2 * t1 == w - 1:
        _sor_pixel(U, V, HX, HY, Q1, Q2, C12, C1, C2, keep, i, w - 1, w, wrap)


@numba.njit(cache=True, nogil=True, inline="always")
def _split_row(x, X, i, co, w):
    """Copy row i's columns 1 .. 2 ((w - 1) // 2) of the (h, w) array x into the colour-split (2, h, ceil(w / 2))
    array X (see :func:`_sor`); co is the colour of the row's odd columns."""
    for t in range((w - 1) >> 1):
        X[co, i, t] = x[i, 2 * t + 1]
        X[1 - co, i, t + 1] = x[i, 2 * t + 2]


@numba.njit(cache=True, nogil=True, fastmath=True, error_model="numpy")
def _sor(du, dv, a11, a12, a22, b1, b2, hx, hy, iters, omega, wrap, split):
    """Coupled red-black SOR for the increment (du, dv) of one fixed-point iteration (in place).

    The system per pixel: (a + sum h) d - sum_nb h d_nb = b, with hx[i, j] the weight between (i, j) and
    (i, j + 1) (the last column links to the first when wrapping, else hx[:, -1] must be 0) and hy[i, j] between
    rows i and i + 1 (hy[-1] must be 0).  ``iters`` sweeps, each the pixels with i + j even then those with i + j
    odd, each row's pixels of a colour in column order (with wrapping and an odd width the first and last columns
    have the same colour: the last then sees the first's new value); every update is
    ``d <- (1 - omega) d + omega (b + sum_nb h d_nb - a12 d_other) / (a + sum h)``, du first, dv with the new du.

    Layout: for the sweeps, (du, dv) and the coefficients are copied once per call into ``split``, colour apart:
    pixel (i, j) of colour c = (i + j) % 2 at ``[c, i, j // 2]`` of (2, h, ceil(w / 2)) arrays, so a row's pixels
    of one colour and their left, right, upper and lower neighbours (all of the other colour) are each contiguous;
    the diagonal's reciprocals ``omega / (a + sum h)`` are computed in that copy.  The first and last columns are
    updated apart, the row's other pixels of the colour in a loop without index wrapping (vectorised).

    Order: ``_SOR_WAVE`` sweeps at a time run as a wavefront down the rows (step p updates, for each sweep s of the
    group in turn, the first colour in row p - 2 s, then the second colour in row p - 2 s - 1), so that a band of
    rows stays in cache across those sweeps.  Every update reads exactly the values it would read
    sweep after sweep, so the result is the same, bit for bit.  Single-threaded, releases the GIL: a sweep of a
    pyramid level is too little work for a parallel loop's barriers to pay off.

    Args:
        du, dv: (h, w) float32 increment, pixels; updated in place.
        a11, a12, a22, b1, b2: (h, w) float32 data and matching terms (b with the smoothness moved to it).
        hx, hy: (h, w) float32 smoothness weights.
        iters: sweeps; omega: relaxation factor.
        wrap: columns are periodic.
        split: (9, n) float32 scratch, n >= 2 h ceil(w / 2) (each row's first 2 h ceil(w / 2) elements are used).
    """
    h, w = du.shape
    wh = (w + 1) // 2
    n = 2 * h * wh
    U, V, HX, HY, Q1, Q2, C12, C1, C2 = (split[0, :n].reshape((2, h, wh)), split[1, :n].reshape((2, h, wh)),
                                         split[2, :n].reshape((2, h, wh)), split[3, :n].reshape((2, h, wh)),
                                         split[4, :n].reshape((2, h, wh)), split[5, :n].reshape((2, h, wh)),
                                         split[6, :n].reshape((2, h, wh)), split[7, :n].reshape((2, h, wh)),
                                         split[8, :n].reshape((2, h, wh)))
    if w % 2 == 1:  # the unused last entry of the colour with fewer pixels in each row: finite, weightless
        for q in range(9):
            for c in range(2):
                for i in range(h):
                    if (i + c) & 1 == 1:
                        split[q, (c * h + i) * wh + wh - 1] = 0.0
    for i in range(h):
        fu = 1.0 if i > 0 else 0.0  # the first row has no upper link
        iu = i - 1 if i > 0 else 0
        for e in range(2):  # column 0, and column w - 1 when the pairs below leave it out (w even)
            j = 0 if e == 0 else w - 1
            if e == 1 and (w % 2 == 1 or w == 1):
                continue
            c, t = (i + j) & 1, j >> 1
            wl = hx[i, j - 1] if j > 0 else (hx[i, w - 1] if wrap else 0.0)  # float64, as the sums
            sh = wl + hx[i, j] + fu * hy[iu, j] + hy[i, j]
            Q1[c, i, t] = omega / (a11[i, j] + sh + 1e-12)
            Q2[c, i, t] = omega / (a22[i, j] + sh + 1e-12)
            HX[c, i, t], HY[c, i, t], C12[c, i, t] = hx[i, j], hy[i, j], a12[i, j]
            C1[c, i, t], C2[c, i, t], U[c, i, t], V[c, i, t] = b1[i, j], b2[i, j], du[i, j], dv[i, j]
        co = (i + 1) & 1  # the colour of the odd columns
        for t in range((w - 1) >> 1):  # columns 2 t + 1 and 2 t + 2: stride-2 loads, contiguous stores (vectorised)
            ja, jb = 2 * t + 1, 2 * t + 2
            sha = np.float64(hx[i, ja - 1]) + hx[i, ja] + fu * hy[iu, ja] + hy[i, ja]
            shb = np.float64(hx[i, jb - 1]) + hx[i, jb] + fu * hy[iu, jb] + hy[i, jb]
            Q1[co, i, t] = omega / (a11[i, ja] + sha + 1e-12)
            Q1[1 - co, i, t + 1] = omega / (a11[i, jb] + shb + 1e-12)
            Q2[co, i, t] = omega / (a22[i, ja] + sha + 1e-12)
            Q2[1 - co, i, t + 1] = omega / (a22[i, jb] + shb + 1e-12)
        _split_row(hx, HX, i, co, w)  # one array per loop: few pointers to check for overlap (vectorised)
        _split_row(hy, HY, i, co, w)
        _split_row(a12, C12, i, co, w)
        _split_row(b1, C1, i, co, w)
        _split_row(b2, C2, i, co, w)
        _split_row(du, U, i, co, w)
        _split_row(dv, V, i, co, w)
    # flat views: the sweep loop indexes them with unsigned offsets (no negative-index handling, vectorised)
    Uf, Vf, HXf, HYf, Q1f, Q2f, C12f, C1f, C2f = (split[0], split[1], split[2], split[3], split[4], split[5],
                                                  split[6], split[7], split[8])
    keep = np.float32(1.0 - omega)
    for s0 in range(0, iters, _SOR_WAVE):  # _SOR_WAVE sweeps at a time, as a wavefront down the rows
        ns = min(_SOR_WAVE, iters - s0)
        for p in range(h + 2 * ns - 1):
            for s in range(ns):  # sweep s: the first colour in row p - 2 s, the second in row p - 2 s - 1
                for colour in range(2):
                    i = p - 2 * s - colour
                    if 0 <= i < h:
                        _sor_row(Uf, Vf, HXf, HYf, Q1f, Q2f, C12f, C1f, C2f, U, V, HX, HY, Q1, Q2, C12, C1, C2, keep,
                                 i, colour, h, w, wh, wrap)
    for i in range(h):
        ce = i & 1
        for t in range(w >> 1):
            du[i, 2 * t], du[i, 2 * t + 1] = U[ce, i, t], U[1 - ce, i, t]
            dv[i, 2 * t], dv[i, 2 * t + 1] = V[ce, i, t], V[1 - ce, i, t]
        if w % 2 == 1:
            du[i, w - 1], dv[i, w - 1] = U[ce, i, (w - 1) >> 1], V[ce, i, (w - 1) >> 1]


def _work_shapes(h: int, w: int, c: int) -> list[tuple[int, ...]]:
    """The scratch arrays of one pyramid level of size (h, w) with c channels (see :func:`_one_level`)."""
    return [(_N_TERMS, c, h, w), (_N_SUMS, h, w)] + [(h, w)] * 9 + [(9, 2 * h * ((w + 1) // 2))]


def _one_level(w_u, w_v, im1, im2, mu, mv, mw, half_beta, p: DeepFlowParams, work: np.ndarray):
    """Fixed-point iterations at one pyramid level; returns the refined flow (u, v).

    Args:
        w_u, w_v: (h, w) float32 flow from the coarser level, pixels.
        im1, im2: (h, w, c) float32 images.
        mu, mv, mw: (h, w) float32 matching term (:func:`match_field`).
        half_beta: the level's matching weight / 2.
        p: the parameters.
        work: float32 scratch of at least the total size of :func:`_work_shapes` (h, w, c), reused by every
            level so that the kernels allocate nothing large.
    Returns:
        ``(u, v)``, each (h, w) float32, pixels.
    """
    wrap = p.wrap
    h, w, c = im1.shape
    views, o = [], 0
    for shape in _work_shapes(h, w, c):
        n = int(np.prod(shape))
        views.append(work[o:o + n].reshape(shape))
        o += n
    terms, sums, a11, a12, a22, b1, b2, hx, hy, su, sv, split = views
    im2w, mask = _warp(im2, w_u, w_v, wrap)
    _image_terms(im1, im2w, wrap, terms, sums)
    hd, hg, qa = p.delta * 0.5 / 3.0, p.gamma * 0.5 / 3.0, 0.25 * p.alpha
    du = np.zeros_like(w_u)
    dv = np.zeros_like(w_v)
    for _ in range(int(p.n_inner)):
        _data_terms(terms, sums, mask, du, dv, w_u, w_v, mu, mv, mw, hd, hg, float(half_beta), a11, a12, a22, b1, b2)
        _smoothness(w_u, w_v, du, dv, qa, wrap, b1, b2, hx, hy, su, sv)
        _sor(du, dv, a11, a12, a22, b1, b2, hx, hy, int(p.n_solver), float(p.sor_omega), wrap, split)
    return w_u + du, w_v + dv


def _resize(x: np.ndarray, w: int, h: int, interp=cv2.INTER_AREA) -> np.ndarray:
    out = cv2.resize(x, (w, h), interpolation=interp)
    return out if out.ndim == x.ndim else out[..., None]


def deep_flow(img0: np.ndarray, img1: np.ndarray, params: DeepFlowParams | None = None,
              matches: Matches | None = None) -> np.ndarray:
    """DeepFlow from ``img0`` to ``img1``.

    Args:
        img0, img1: (H, W, 3) uint8 RGB (or (H, W) grey) images of the same size.
        params: :class:`DeepFlowParams` (default: the authors' defaults, equirect wrapping).
        matches: DeepMatching's matches from img0 to img1 (computed if None).
    Returns:
        (H, W, 2) float32 flow (du, dv) in pixels.
    """
    p = params or DeepFlowParams()
    if img0.shape != img1.shape:
        raise ValueError(f"deep_flow: images differ in size ({img0.shape} vs {img1.shape})")
    h, w = img0.shape[:2]
    if matches is None:
        matches = deep_matching(img0, img1, _matching_params(p))

    def prep(img):
        x = img.astype(np.float32)
        x = x[..., None] if x.ndim == 2 else x
        if p.sigma > 0:
            x = cv2.GaussianBlur(x, (0, 0), p.sigma, borderType=cv2.BORDER_REPLICATE)
        return x if x.ndim == 3 else x[..., None]

    phi = match_weights(img0, img1, matches, p.wrap)
    s1, s2 = prep(img0), prep(img1)
    sizes = []
    k = 0
    while True:
        f = p.eta ** k
        lw, lh = int(round(w * f)), int(round(h * f))
        if min(lw, lh) < p.min_size and k > 0:
            break
        sizes.append((lw, lh))
        k += 1
        if min(lw, lh) <= p.min_size:
            break
    n_lev = len(sizes)
    work = np.empty(sum(int(np.prod(x)) for x in _work_shapes(h, w, s1.shape[2])), np.float32)
    u = v = None
    for k in range(n_lev - 1, -1, -1):
        lw, lh = sizes[k]
        im1 = np.ascontiguousarray(_resize(s1, lw, lh), np.float32)
        im2 = np.ascontiguousarray(_resize(s2, lw, lh), np.float32)
        if u is None:
            u = np.zeros((lh, lw), np.float32)
            v = np.zeros((lh, lw), np.float32)
        else:
            ph, pw = u.shape
            u = cv2.resize(u, (lw, lh), interpolation=cv2.INTER_LINEAR) * (lw / pw)
            v = cv2.resize(v, (lw, lh), interpolation=cv2.INTER_LINEAR) * (lh / ph)
        lmu, lmv, lmw = match_field(matches, phi, h, w, p.wrap, (lh, lw))
        half_beta = 0.5 * p.beta * ((k / (n_lev - 1)) ** p.bk if (p.bk > 0 and n_lev > 1) else 1.0)
        u, v = _one_level(u.astype(np.float32), v.astype(np.float32), im1, im2, lmu.astype(np.float32),
                          lmv.astype(np.float32), lmw.astype(np.float32), half_beta, p, work)
    return np.ascontiguousarray(np.dstack([u, v]), np.float32)


def _matching_params(p: DeepFlowParams) -> DeepMatchingParams:
    """The DeepMatching parameters of ``p``, with the flow's ``wrap``."""
    return p.matching if p.matching.wrap == p.wrap else DeepMatchingParams(**{**asdict(p.matching), "wrap": p.wrap})


def deep_flow_both(img0: np.ndarray, img1: np.ndarray, params: DeepFlowParams | None = None,
                   matches: tuple[Matches, Matches] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """DeepFlow both ways, ``(flow img0 -> img1, flow img1 -> img0)``, the two solved at once on two threads.

    The solver's kernels are single-threaded and release the GIL, so the two directions of a pair use two cores
    with no synchronisation between them; each result is that of :func:`deep_flow`.

    Args:
        img0, img1: (H, W, 3) uint8 RGB (or (H, W) grey) images of the same size.
        params: :class:`DeepFlowParams` (default: the authors' defaults, equirect wrapping).
        matches: DeepMatching's ``(matches 0 -> 1, matches 1 -> 0)`` (computed by
            :func:`~reconstruction.flow.deepmatching.deep_matching_both` if None).
    Returns:
        Two (H, W, 2) float32 flows, pixels.
    """
    p = params or DeepFlowParams()
    if img0.shape != img1.shape:
        raise ValueError(f"deep_flow: images differ in size ({img0.shape} vs {img1.shape})")
    if matches is None:
        matches = deep_matching_both(img0, img1, _matching_params(p))
    with ThreadPoolExecutor(max_workers=2, thread_name_prefix="deepflow") as pool:
        back = pool.submit(deep_flow, img1, img0, p, matches[1])
        fwd = deep_flow(img0, img1, p, matches[0])
        return fwd, back.result()
