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
boundary, so the whole solver is here: numba kernels for the warp, the data, matching and smoothness terms and
SOR, all single-threaded and releasing the GIL (:func:`deep_flow_both` solves a pair's two directions on two
threads), numpy for the derivatives.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from dataclasses import asdict, dataclass, field

import cv2
import numba
import numpy as np

from reconstruction.flow.deepmatching import (
    DeepMatchingParams,
    Matches,
    blur_periodic,
    central_differences,
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
    mu = np.zeros((lh, lw), np.float64)
    mv = np.zeros((lh, lw), np.float64)
    mw = np.zeros((lh, lw), np.float64)
    if m.x0.size == 0:
        return mu.astype(np.float32), mv.astype(np.float32), mw.astype(np.float32)
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
    for dy, wy in ((0, 1.0 - ay), (1, ay)):
        yi = np.minimum(y0i + dy, lh - 1)
        for dx, wx in ((0, 1.0 - ax), (1, ax)):
            xi = (x0i + dx) % lw if wrap else np.minimum(x0i + dx, lw - 1)
            wt = phi * wx * wy
            np.add.at(mw, (yi, xi), wt)
            np.add.at(mu, (yi, xi), wt * fu)
            np.add.at(mv, (yi, xi), wt * fv)
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


@numba.njit(cache=True, nogil=True, fastmath=True, inline="always")
def _sor_pixel(du, dv, a12, b1, b2, hx, hy, left, r11, r22, keep, i, j, iu, idn, fu):
    """One SOR update of pixel (i, j) (see :func:`_sor`), the column neighbours wrapped."""
    w = du.shape[1]
    jl = j - 1 if j > 0 else w - 1
    jr = j + 1 if j < w - 1 else 0
    wl, wr, wu, wd = left[i, j], hx[i, j], fu * hy[iu, j], hy[i, j]
    su = wl * du[i, jl] + wr * du[i, jr] + wu * du[iu, j] + wd * du[idn, j]
    sv = wl * dv[i, jl] + wr * dv[i, jr] + wu * dv[iu, j] + wd * dv[idn, j]
    nu = keep * du[i, j] + r11[i, j] * (b1[i, j] + su - a12[i, j] * dv[i, j])
    du[i, j] = nu
    dv[i, j] = keep * dv[i, j] + r22[i, j] * (b2[i, j] + sv - a12[i, j] * nu)


@numba.njit(cache=True, nogil=True, fastmath=True)
def _sor(du, dv, a11, a12, a22, b1, b2, hx, hy, iters, omega, wrap):
    """Coupled red-black SOR for the increment (du, dv) of one fixed-point iteration (in place).

    The system per pixel: (a + sum h) d - sum_nb h d_nb = b, with hx[i, j] the weight between (i, j) and
    (i, j + 1) (the last column links to the first when wrapping, else hx[:, -1] must be 0) and hy[i, j] between
    rows i and i + 1 (hy[-1] must be 0).  All arrays (h, w) float32; ``iters`` sweeps, each the pixels with
    i + j even then those with i + j odd, each row's pixels of a colour in column order (with wrapping and an odd
    width the first and last columns have the same colour: the last then sees the first's new value).  The
    diagonal's reciprocals are computed once per call; the first and last columns are updated apart so that the
    row's other pixels are a loop without index wrapping (vectorised).  Single-threaded (releases the GIL): a
    sweep of a pyramid level is too little work for a parallel loop's barriers to pay off.
    """
    h, w = du.shape
    left = np.empty((h, w), np.float32)  # weight of the left neighbour (0 in the first column without wrapping)
    r11 = np.empty((h, w), np.float32)  # omega / (a11 + sum of the neighbour weights)
    r22 = np.empty((h, w), np.float32)
    for i in range(h):
        for j in range(w):
            wl = hx[i, j - 1] if j > 0 else (hx[i, w - 1] if wrap else 0.0)
            wu = hy[i - 1, j] if i > 0 else 0.0
            sh = wl + hx[i, j] + wu + hy[i, j]
            left[i, j] = wl
            r11[i, j] = omega / (a11[i, j] + sh + 1e-12)
            r22[i, j] = omega / (a22[i, j] + sh + 1e-12)
    keep = np.float32(1.0 - omega)
    for _ in range(iters):
        for colour in range(2):
            for i in range(h):
                iu = i - 1 if i > 0 else 0
                idn = i + 1 if i < h - 1 else h - 1  # hy[h - 1] = 0
                fu = np.float32(1.0) if i > 0 else np.float32(0.0)  # the first row has no upper neighbour
                j0 = (i + colour) % 2
                if j0 == 0:
                    _sor_pixel(du, dv, a12, b1, b2, hx, hy, left, r11, r22, keep, i, 0, iu, idn, fu)
                    j0 = 2
                u0, uu, ud, v0, vu, vd = du[i], du[iu], du[idn], dv[i], dv[iu], dv[idn]
                wlr, wrr, wur, wdr = left[i], hx[i], hy[iu], hy[i]
                q1, q2, c12, c1, c2 = r11[i], r22[i], a12[i], b1[i], b2[i]
                n_in = max((w - j0) // 2, 0)  # columns j0, j0 + 2, ..., at most w - 2
                for t in range(n_in):
                    j = j0 + 2 * t
                    wl, wr, wu, wd = wlr[j], wrr[j], fu * wur[j], wdr[j]
                    su = wl * u0[j - 1] + wr * u0[j + 1] + wu * uu[j] + wd * ud[j]
                    sv = wl * v0[j - 1] + wr * v0[j + 1] + wu * vu[j] + wd * vd[j]
                    nu = keep * u0[j] + q1[j] * (c1[j] + su - c12[j] * v0[j])
                    u0[j] = nu
                    v0[j] = keep * v0[j] + q2[j] * (c2[j] + sv - c12[j] * nu)
                if j0 + 2 * n_in == w - 1:
                    _sor_pixel(du, dv, a12, b1, b2, hx, hy, left, r11, r22, keep, i, w - 1, iu, idn, fu)


@numba.njit(cache=True, nogil=True, fastmath=True)
def _data_terms(ix, iy, iz, ixx, ixy, iyy, ixz, iyz, du, dv, mask, w_u, w_v, mu, mv, mw, hd, hg, half_beta):
    """The linearised data and matching terms of one fixed-point iteration: per pixel the 2 x 2 system
    ``[[a11, a12], [a12, a22]] (du, dv) = (b1, b2)`` (before smoothness), robust weights from the current
    increment (du, dv).  Derivative arrays are (h, w, c); the others (h, w).  Single-threaded, releases the GIL."""
    h, w, c = ix.shape
    a11 = np.zeros((h, w), np.float32)
    a12 = np.zeros((h, w), np.float32)
    a22 = np.zeros((h, w), np.float32)
    b1 = np.zeros((h, w), np.float32)
    b2 = np.zeros((h, w), np.float32)
    for i in range(h):
        for j in range(w):
            x11 = 0.0
            x12 = 0.0
            x22 = 0.0
            y1 = 0.0
            y2 = 0.0
            u = du[i, j]
            v = dv[i, j]
            if hd > 0:
                e = 0.0
                for k in range(c):
                    t = iz[i, j, k] + ix[i, j, k] * u + iy[i, j, k] * v
                    e += t * t / (ix[i, j, k] ** 2 + iy[i, j, k] ** 2 + DATANORM)
                psi = mask[i, j] * hd / np.sqrt(e + EPS2)
                for k in range(c):
                    q = psi / (ix[i, j, k] ** 2 + iy[i, j, k] ** 2 + DATANORM)
                    x11 += q * ix[i, j, k] * ix[i, j, k]
                    x12 += q * ix[i, j, k] * iy[i, j, k]
                    x22 += q * iy[i, j, k] * iy[i, j, k]
                    y1 -= q * iz[i, j, k] * ix[i, j, k]
                    y2 -= q * iz[i, j, k] * iy[i, j, k]
            if hg > 0:
                e = 0.0
                for k in range(c):
                    nx = ixx[i, j, k] ** 2 + ixy[i, j, k] ** 2 + DATANORM
                    ny = iyy[i, j, k] ** 2 + ixy[i, j, k] ** 2 + DATANORM
                    tx = ixz[i, j, k] + ixx[i, j, k] * u + ixy[i, j, k] * v
                    ty = iyz[i, j, k] + ixy[i, j, k] * u + iyy[i, j, k] * v
                    e += tx * tx / nx + ty * ty / ny
                psi = mask[i, j] * hg / np.sqrt(e + EPS2)
                for k in range(c):
                    qx = psi / (ixx[i, j, k] ** 2 + ixy[i, j, k] ** 2 + DATANORM)
                    qy = psi / (iyy[i, j, k] ** 2 + ixy[i, j, k] ** 2 + DATANORM)
                    gxx, gxy, gyy = ixx[i, j, k], ixy[i, j, k], iyy[i, j, k]
                    x11 += qx * gxx * gxx + qy * gxy * gxy
                    x12 += qx * gxx * gxy + qy * gxy * gyy
                    x22 += qx * gxy * gxy + qy * gyy * gyy
                    y1 -= qx * gxx * ixz[i, j, k] + qy * gxy * iyz[i, j, k]
                    y2 -= qx * gxy * ixz[i, j, k] + qy * gyy * iyz[i, j, k]
            if half_beta > 0 and mw[i, j] > 0:
                eu = w_u[i, j] + u - mu[i, j]
                ev = w_v[i, j] + v - mv[i, j]
                psi = half_beta * mw[i, j] / np.sqrt(eu * eu + ev * ev + EPS2)
                x11 += psi
                x22 += psi
                y1 -= psi * (w_u[i, j] - mu[i, j])
                y2 -= psi * (w_v[i, j] - mv[i, j])
            a11[i, j] = x11
            a12[i, j] = x12
            a22[i, j] = x22
            b1[i, j] = y1
            b2[i, j] = y2
    return a11, a12, a22, b1, b2


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


@numba.njit(cache=True, nogil=True, fastmath=True)
def _smoothness(w_u, w_v, du, dv, quarter_alpha, wrap, b1, b2):
    """The smoothness term of one fixed-point iteration.

    Diffusivities of the flow ``(u, v) = (w_u + du, w_v + dv)`` (pixels): ``hx[i, j] = quarter_alpha / sqrt(
    ux^2 + uy^2 + vx^2 + vy^2 + eps^2)`` between (i, j) and (i, j + 1), with the x derivatives the forward
    differences across that link and the y derivatives the mean of both ends' central differences; ``hy[i, j]``
    alike between rows i and i + 1.  Without wrapping the last column's hx is 0, and hy of the last row is always
    0; central differences replicate the edge pixel.  The current flow's smoothness is moved to the right-hand
    side: ``b1 += sum over neighbours of h (w_u_nb - w_u)`` and ``b2`` alike for ``w_v`` (in place).

    Args:
        w_u, w_v, du, dv: (h, w) float32 flow and its increment, pixels.
        quarter_alpha: alpha / 4.
        wrap: columns are periodic.
        b1, b2: (h, w) float32 right-hand sides, updated in place.
    Returns:
        ``(hx, hy)``, each (h, w) float32.
    """
    h, w = w_u.shape
    u = np.empty((h, w), np.float32)
    v = np.empty((h, w), np.float32)
    for i in range(h):
        for j in range(w):
            u[i, j] = w_u[i, j] + du[i, j]
            v[i, j] = w_v[i, j] + dv[i, j]
    ux = np.empty((h, w), np.float32)  # central differences, edge pixel replicated (or columns wrapped)
    vx = np.empty((h, w), np.float32)
    uy = np.empty((h, w), np.float32)
    vy = np.empty((h, w), np.float32)
    for i in range(h):
        iu, idn = max(i - 1, 0), min(i + 1, h - 1)
        for j in range(w):
            if wrap:
                jl, jr = (j - 1) % w, (j + 1) % w
            else:
                jl, jr = max(j - 1, 0), min(j + 1, w - 1)
            ux[i, j] = 0.5 * (u[i, jr] - u[i, jl])
            vx[i, j] = 0.5 * (v[i, jr] - v[i, jl])
            uy[i, j] = 0.5 * (u[idn, j] - u[iu, j])
            vy[i, j] = 0.5 * (v[idn, j] - v[iu, j])
    hx = np.zeros((h, w), np.float32)
    hy = np.zeros((h, w), np.float32)
    for i in range(h):
        for j in range(w):
            if wrap or j < w - 1:
                jr = (j + 1) % w
                a = u[i, jr] - u[i, j]
                b = 0.5 * (uy[i, j] + uy[i, jr])
                c = v[i, jr] - v[i, j]
                d = 0.5 * (vy[i, j] + vy[i, jr])
                hx[i, j] = quarter_alpha / np.sqrt(a * a + b * b + c * c + d * d + EPS2)
            if i < h - 1:
                a = u[i + 1, j] - u[i, j]
                b = 0.5 * (ux[i, j] + ux[i + 1, j])
                c = v[i + 1, j] - v[i, j]
                d = 0.5 * (vx[i, j] + vx[i + 1, j])
                hy[i, j] = quarter_alpha / np.sqrt(a * a + b * b + c * c + d * d + EPS2)
    for i in range(h):
        for j in range(w):
            jr = (j + 1) % w  # hx[i, w - 1] = 0 without wrapping
            jl = (j - 1) % w
            fu = hx[i, j] * (w_u[i, jr] - w_u[i, j])
            fv = hx[i, j] * (w_v[i, jr] - w_v[i, j])
            if j > 0 or wrap:
                fu -= hx[i, jl] * (w_u[i, j] - w_u[i, jl])
                fv -= hx[i, jl] * (w_v[i, j] - w_v[i, jl])
            if i < h - 1:
                fu += hy[i, j] * (w_u[i + 1, j] - w_u[i, j])
                fv += hy[i, j] * (w_v[i + 1, j] - w_v[i, j])
            if i > 0:
                fu -= hy[i - 1, j] * (w_u[i, j] - w_u[i - 1, j])
                fv -= hy[i - 1, j] * (w_v[i, j] - w_v[i - 1, j])
            b1[i, j] += fu
            b2[i, j] += fv
    return hx, hy


def _one_level(w_u, w_v, im1, im2, mu, mv, mw, half_beta, p: DeepFlowParams):
    """Fixed-point iterations at one pyramid level; returns the refined flow (u, v)."""
    wrap = p.wrap
    im2w, mask = _warp(im2, w_u, w_v, wrap)
    mean = 0.5 * (im1 + im2w)
    iz = im2w - im1
    ix = _dx5(mean, wrap)
    iy = _dy5(mean)
    ixx, ixy, iyy = _dx5(ix, wrap), _dy5(ix), _dy5(iy)
    ixz, iyz = _dx5(iz, wrap), _dy5(iz)
    hd, hg, qa = p.delta * 0.5 / 3.0, p.gamma * 0.5 / 3.0, 0.25 * p.alpha
    f32 = lambda a: np.ascontiguousarray(a, np.float32)  # noqa: E731
    ix, iy, iz, ixx, ixy, iyy, ixz, iyz = (f32(a) for a in (ix, iy, iz, ixx, ixy, iyy, ixz, iyz))
    mask = f32(mask)
    du = np.zeros_like(w_u)
    dv = np.zeros_like(w_v)
    for _ in range(int(p.n_inner)):
        a11, a12, a22, b1, b2 = _data_terms(ix, iy, iz, ixx, ixy, iyy, ixz, iyz, du, dv, mask, w_u, w_v, mu, mv,
                                            mw, hd, hg, float(half_beta))
        hx, hy = _smoothness(w_u, w_v, du, dv, qa, wrap, b1, b2)
        _sor(du, dv, a11, a12, a22, b1, b2, hx, hy, int(p.n_solver), float(p.sor_omega), wrap)
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
                          lmv.astype(np.float32), lmw.astype(np.float32), half_beta, p)
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
