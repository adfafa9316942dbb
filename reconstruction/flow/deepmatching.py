"""DeepMatching (Revaud, Weinzaepfel, Harchaoui & Schmid, IJCV 2016; Weinzaepfel et al., ICCV 2013) in numpy/numba.

Quasi-dense correspondences between two images from a hierarchical, correlational architecture:

1. **Pixel descriptors** (HOG-like): the grey image (0..255) is smoothed (``presmooth_sigma``), its gradient is
   projected on 8 orientations (k * 45 degrees) keeping the positive part, each orientation map is smoothed
   (``mid_smoothing``), squashed by the sigmoid ``2 / (1 + exp(-hog_sigmoid * x)) - 1``, a constant ninth
   dimension ``ninth_dim`` is appended (so that flat areas still have a descriptor), the 8 maps are smoothed
   again (``post_smoothing``) and every pixel's 9-vector is L2-normalised.
2. **Atomic patches**: 4 x 4 cells of ``cell_px`` = 4 pixels, i.e. 16 x 16 working pixels, on a grid of step 8
   (half a patch).  A patch's descriptor is its 16 cells' descriptors (144 dimensions, unit norm); its response
   map is the correlation with the same 4 x 4 cell layout at every displacement of the second image within the
   search range (level 1, values in [0, 1]).
3. **Bottom-up pyramid**: a patch of size 2N is made of 4 children of size N at offsets (+-N/2, +-N/2).  Its
   response at a displacement is ``(mean over the children of maxpool3x3(child response))^nlpow`` after
   subsampling by 2: the max-pool lets every child move by one cell of its level (the deformable part).
   Responses are kept *in displacement coordinates*, where the children's shifts by their offsets cancel
   (a child at ``p + o`` whose parent moves by ``delta`` is expected at ``p + o + delta``: the same
   displacement), so the aggregation is pool, subsample, average, power.  Every level keeps the atomic grid
   (step 8), so every patch of a level is a child of up to four parents of the next one; levels are built while
   the parent patch (32, 64, 128, ... working pixels) fits in the image.  Every level's responses are stored
   displacement-major, (dy, dx, patch), so pooling and averaging are loops over contiguous patch vectors.
4. **Top-down backtracking**: from every local maximum (3 x 3) of every patch's response map at every level >= 2
   the argmax of each child's pooling window (recorded while pooling) is followed down to level 1; an atomic
   patch reached along a path scores the sum of the responses on that path and keeps its best-scoring match
   (the first in a fixed order on equal scores, whatever the threads).
5. **Reciprocal verification**: matching is run both ways (image 0 -> 1 and 1 -> 0); a match p -> q is kept if
   the backward match of the atomic patch of image 1 nearest to q leads back to within ``reciprocal_px`` of p.

Equirectangular images wrap in longitude (``wrap=True``): columns are periodic everywhere (smoothing,
gradients, cells, the displacement axis), so matches cross the left/right seam with no padding.

Units: sizes and radii are *working* pixels, i.e. pixels of the image after ``downscale`` (the image is resized
to about ``1 / 2**downscale`` of its size, rounded to a multiple of 64 pixels per side so every level's grid
tiles the period exactly); returned coordinates are pixels of the input image.

Parameters are the authors' defaults (their code's ``desc_params`` and ``dm_params``): presmoothing 1.0,
mid and post smoothing 1.0, sigmoid 0.2, ninth dimension 0.3, non-linearity 1.4, image downscaled by 2 (the
default of their DeepFlow set-up).  The authors' unlimited search (``ngh_rad = 0``) costs O(N^2) in memory
and time; here ``ngh_rad_y`` limits the vertical displacement (default a quarter of the working height) while
``ngh_rad_x = 0`` searches every column (the whole longitude circle when wrapping).  Per-pixel rather than
per-patch normalisation of the descriptor is a simplification: with the ninth dimension every pixel has a
non-zero descriptor, and per-pixel unit vectors make every patch exactly unit-norm.

Measured on this 2-core shared machine (numba, both cores), one 1000 x 500 equirect pair, both directions
plus the verification: see ``docs/deepflow.md`` (``tools/bench/flow.py`` measures it).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import cv2
import numba
import numpy as np
from numba.core import types as nbtypes
from numba.extending import intrinsic

from reconstruction.camera.image_ops import central_differences, grey, periodic_gaussian_blur

__all__ = ["DeepMatchingParams", "Matches", "deep_matching", "deep_matching_both", "pixel_descriptors",
           "blur_periodic"]

PATCH_CELLS = 4  # an atomic patch is 4 x 4 cells
N_ORIENT = 8


@dataclass(frozen=True)
class DeepMatchingParams:
    """DeepMatching parameters (the authors' defaults unless stated).

    Attributes:
        downscale: the images are resized by about ``1 / 2**downscale`` before matching (1: half resolution, the
            authors' DeepFlow set-up; 0: full resolution, about 4x the memory and 8x the time).
        presmooth_sigma: Gaussian sigma, working pixels, before the gradient.
        mid_smoothing: Gaussian sigma, working pixels, of each orientation map before the sigmoid.
        post_smoothing: Gaussian sigma, working pixels, of each orientation map after the sigmoid.
        hog_sigmoid: slope of the sigmoid, per grey level (images in 0..255).
        ninth_dim: the constant ninth descriptor dimension (relative to the sigmoid's range [0, 1)).
        cell_px: spacing of an atomic patch's 4 x 4 cells, working pixels (atomic patch = 4 cell_px wide).
        nlpow: power non-linearity applied to every aggregated response.
        ngh_rad_x: largest horizontal displacement searched, working pixels (0: every column).
        ngh_rad_y: largest vertical displacement searched, working pixels (0: a quarter of the working height).
        reciprocal_px: tolerance of the forward-backward check, working pixels.
        wrap: columns are periodic (equirect longitude).
    """

    downscale: int = 1
    presmooth_sigma: float = 1.0
    mid_smoothing: float = 1.0
    post_smoothing: float = 1.0
    hog_sigmoid: float = 0.2
    ninth_dim: float = 0.3
    cell_px: int = 4
    nlpow: float = 1.4
    ngh_rad_x: int = 0
    ngh_rad_y: int = 0
    reciprocal_px: float = 4.0
    wrap: bool = True

    def config(self) -> dict:
        return asdict(self)


@dataclass
class Matches:
    """Verified correspondences, in input-image pixels (centres at integers).

    Attributes:
        x0, y0: (M,) positions in image 0 (atomic patch centres).
        x1, y1: (M,) matched positions in image 1; with wrapping ``x1`` is ``x0`` plus the shortest horizontal
            displacement, so it may lie outside [0, W) (the caller wraps it).
        score: (M,) sum of the pyramid responses along the backtracking path (dimensionless, >= 0).
        cell: spacing of the atomic patch grid, input pixels (the area each match stands for).
    """

    x0: np.ndarray
    y0: np.ndarray
    x1: np.ndarray
    y1: np.ndarray
    score: np.ndarray
    cell: float


def blur_periodic(x: np.ndarray, sigma: float, wrap: bool) -> np.ndarray:
    """DeepMatching's and DeepFlow's smoothing: Gaussian blur (``sigma`` pixels) of an (H, W) or (H, W, C) float32
    array, periodic in columns if ``wrap`` (``ceil(3 sigma) + 1`` columns wrapped, at most W), the edge replicated
    beyond (:func:`reconstruction.camera.image_ops.periodic_gaussian_blur`); ``x`` itself for ``sigma`` <= 0."""
    cols = min(int(np.ceil(3 * sigma)) + 1, x.shape[1]) if wrap else 0
    return periodic_gaussian_blur(x, sigma, cols=cols, border=cv2.BORDER_REPLICATE)


def pixel_descriptors(gray: np.ndarray, p: DeepMatchingParams) -> np.ndarray:
    """Per-pixel 9-dimensional descriptors.

    Args:
        gray: (H, W) float32 grey image, 0..255.
        p: parameters.
    Returns:
        (H, W, 9) float32, each pixel's vector of unit L2 norm.
    """
    g = blur_periodic(gray.astype(np.float32), p.presmooth_sigma, p.wrap)
    gx, gy = central_differences(g, p.wrap)
    ang = np.arange(N_ORIENT) * (2 * np.pi / N_ORIENT)
    hog = np.maximum(0.0, gx[..., None] * np.cos(ang) + gy[..., None] * np.sin(ang)).astype(np.float32)
    hog = blur_periodic(hog, p.mid_smoothing, p.wrap)
    hog = (2.0 / (1.0 + np.exp(-p.hog_sigmoid * hog)) - 1.0).astype(np.float32)
    hog = blur_periodic(hog, p.post_smoothing, p.wrap)
    desc = np.concatenate([hog, np.full(g.shape + (1,), p.ninth_dim, np.float32)], axis=2)
    desc /= np.linalg.norm(desc, axis=2, keepdims=True)
    return np.ascontiguousarray(desc.astype(np.float32))


@numba.njit(parallel=True, cache=True, fastmath=True)
def _level1(d0, d1, cell, step, ndy, ndx, ky, kx, circ, wrapc):
    """Atomic-patch response maps (level 1) at every displacement of the search window.

    Args:
        d0, d1: (H, W, 9) float32 pixel descriptors of both images (H and W multiples of ``cell``).
        cell: cell spacing, pixels; the patch grid step is 2 * cell, a patch's cells sit at offsets
            cell * (k - 1.5), k = 0..3, from its centre (centres at multiples of ``step``).
        ndy, ndx: size of the displacement window; displacement index a <-> dy = a - ky, b <-> dx = b - kx
            (``circ``: dx = b - kx taken modulo W, the window covering every column).
        wrapc: columns are periodic (cells and displacements wrap); else cells are clamped to the image and a
            cell displaced out of image 1 correlates 0.
    Returns:
        (ndy, ndx, n_patches) float32 responses in [0, 1], displacement-major (each displacement's responses of
        all patches are contiguous), patches in row-major grid order.

    Image 0's cell descriptors are gathered channel-major, (9, H / cell, W / cell), and image 1 is split by
    column phase: plane ``r`` holds the pixels of columns ``cell * t + r``, so the cells displaced by dx read a
    contiguous run of a plane's columns and the cell correlations of one row are a vectorisable loop.  The plane
    has a band of W / cell columns either side (wrapped, or 0 without wrapping) so no index is wrapped in the
    loop.  Parallel over the vertical displacements.
    """
    h, w, c = d0.shape
    ph, pw = h // step, w // step
    ch, cw = h // cell, w // cell
    out = np.empty((ndy, ndx, ph * pw), np.float32)
    half = cell // 2
    scale = np.float32(1.0 / (PATCH_CELLS * PATCH_CELLS))
    # the cell rows / columns of every patch (centre row j * step: cells 2j - 2 .. 2j + 1, clamped or wrapped)
    crow = np.empty((ph, PATCH_CELLS), np.int64)
    for j in range(ph):
        for u in range(PATCH_CELLS):
            crow[j, u] = min(max(2 * j - 2 + u, 0), ch - 1)
    ccol = np.empty((pw, PATCH_CELLS), np.int64)
    for i in range(pw):
        for v in range(PATCH_CELLS):
            n = 2 * i - 2 + v
            ccol[i, v] = n % cw if wrapc else min(max(n, 0), cw - 1)
    a0 = np.empty((c, ch, cw), np.float32)  # image 0's cell descriptors
    for k in range(c):
        for m in range(ch):
            for n in range(cw):
                a0[k, m, n] = d0[m * cell + half, n * cell + half, k]
    planes = np.zeros((cell, c, h, 3 * cw), np.float32)  # planes[r, k, y, t + cw] = d1[y, cell * t + r, k]
    for r in range(cell):
        for k in range(c):
            for y in range(h):
                for t in range(-cw, 2 * cw):
                    if wrapc or 0 <= t < cw:
                        planes[r, k, y, t + cw] = d1[y, (cell * t + r) % w, k]
    for a in numba.prange(ndy):
        dy = a - ky
        s = np.zeros((ch, cw), np.float32)  # cell correlations at one displacement
        vs = np.zeros((ph, cw), np.float32)  # their sums over each patch row's 4 cell rows
        for b in range(ndx):
            e = half + b - kx  # image-1 column of cell n: n * cell + e
            if circ:
                e = e % w
            r = e % cell
            o = e // cell + cw  # plane column of cell 0 (0 <= o <= 2 cw)
            for m in range(ch):
                srow = s[m]
                y1 = m * cell + half + dy
                if y1 < 0 or y1 >= h:
                    for n in range(cw):
                        srow[n] = 0.0
                    continue
                if c == 9:  # the descriptors' size: the 9 products accumulated in registers
                    q0, q1, q2, q3, q4 = a0[0, m], a0[1, m], a0[2, m], a0[3, m], a0[4, m]
                    q5, q6, q7, q8 = a0[5, m], a0[6, m], a0[7, m], a0[8, m]
                    pl = planes[r]
                    p0, p1, p2 = pl[0, y1, o:o + cw], pl[1, y1, o:o + cw], pl[2, y1, o:o + cw]
                    p3, p4, p5 = pl[3, y1, o:o + cw], pl[4, y1, o:o + cw], pl[5, y1, o:o + cw]
                    p6, p7, p8 = pl[6, y1, o:o + cw], pl[7, y1, o:o + cw], pl[8, y1, o:o + cw]
                    for n in range(cw):
                        acc = q0[n] * p0[n]
                        acc += q1[n] * p1[n]
                        acc += q2[n] * p2[n]
                        acc += q3[n] * p3[n]
                        acc += q4[n] * p4[n]
                        acc += q5[n] * p5[n]
                        acc += q6[n] * p6[n]
                        acc += q7[n] * p7[n]
                        acc += q8[n] * p8[n]
                        srow[n] = acc
                else:
                    for n in range(cw):
                        srow[n] = 0.0
                    for k in range(c):
                        arow = a0[k, m]
                        prow = planes[r, k, y1, o:o + cw]
                        for n in range(cw):
                            srow[n] += arow[n] * prow[n]
            for j in range(ph):  # separable 4 x 4 cell sums: the 4 cell rows, then the 4 cell columns
                s0, s1, s2, s3, vrow = s[crow[j, 0]], s[crow[j, 1]], s[crow[j, 2]], s[crow[j, 3]], vs[j]
                for n in range(cw):
                    vrow[n] = s0[n] + s1[n] + s2[n] + s3[n]
            orow = out[a, b]
            for j in range(ph):  # patch column i covers cell columns 2i - 2 .. 2i + 1: only i = 0 wraps / clamps
                vrow = vs[j]
                base = j * pw
                orow[base] = (vrow[ccol[0, 0]] + vrow[ccol[0, 1]] + vrow[ccol[0, 2]] + vrow[ccol[0, 3]]) * scale
                for i in range(1, pw):
                    orow[base + i] = (vrow[2 * i - 2] + vrow[2 * i - 1] + vrow[2 * i] + vrow[2 * i + 1]) * scale
    return out


_LN2_HI = 6.93147180369123816490e-01  # ln 2 split (fdlibm): k * _LN2_HI is exact for |k| < 2**20
_LN2_LO = 1.90821492927058770002e-10
_INV_LN2 = 1.44269504088896338700e+00
_SQRT2 = 1.4142135623730951
_ROUND = 6755399441055744.0  # 1.5 * 2**52: x + _ROUND holds round(x) in its low mantissa bits
_ROUND_BITS = 0x4338000000000000  # the bit pattern of _ROUND
_TWO52 = 4503599627370496.0
_HARD_ULPS = 1 << 16  # results this close (float64 ulps) to a float32 rounding midpoint are redone with libm
_F32_MIN = 1.1754943508222875e-38  # smallest normal float32
_F32_MAX = 3.4e38


@intrinsic
def _f64_bits(typingctx, x):
    """The bit pattern of a float64, as int64."""
    def codegen(context, builder, signature, args):
        return builder.bitcast(args[0], context.get_value_type(nbtypes.int64))
    return nbtypes.int64(nbtypes.float64), codegen


@intrinsic
def _bits_f64(typingctx, i):
    """The float64 of an int64 bit pattern."""
    def codegen(context, builder, signature, args):
        return builder.bitcast(args[0], context.get_value_type(nbtypes.float64))
    return nbtypes.float64(nbtypes.int64), codegen


@numba.njit(cache=True, error_model="numpy", fastmath={"contract"})
def _pow_f32(x, e, out, redo):
    """``out[q] = float32(x[q] ** e)`` for (n,) float64 ``x >= 0``, the same float32 as libm's ``pow``.

    ``x ** e = exp(e log x)`` in float64 by range reduction and polynomials, a loop that vectorises (relative
    error below 1e-12), rounded to float32; the few results within ``_HARD_ULPS`` float64 ulps (about 7e-12
    relative) of a float32 rounding midpoint, and out-of-range ones, are recomputed with libm's ``pow``, so the
    float32 result is libm's.  ``redo`` is an (n,) bool scratch buffer.
    """
    n = x.size
    if e <= 0.0:  # 0^e is not 0: libm throughout (not a pyramid's case)
        for q in range(n):
            out[q] = np.float32(x[q] ** e)
        return
    nredo = 0
    for q in range(n):
        xq = x[q]
        bits = _f64_bits(xq)  # x = 2^k m: m in [1, 2) and the biased exponent (as 2^52 + k + 1023)
        m = _bits_f64((bits & 0x000FFFFFFFFFFFFF) | 0x3FF0000000000000)
        kd = _bits_f64((bits >> 52) | 0x4330000000000000) - (_TWO52 + 1023.0)
        big = m > _SQRT2  # m in [sqrt(1/2), sqrt(2))
        m = m * 0.5 if big else m
        kd = kd + 1.0 if big else kd
        s = (m - 1.0) / (m + 1.0)  # log m = 2 atanh(s) = 2 (s + s^3 / 3 + ... + s^15 / 15), |s| < 0.172
        z = s * s
        z2 = z * z
        pz = ((1.0 / 3.0 + z * (1.0 / 5.0)) + z2 * (1.0 / 7.0 + z * (1.0 / 9.0))
              + z2 * z2 * ((1.0 / 11.0 + z * (1.0 / 13.0)) + z2 * (1.0 / 15.0)))
        s2 = 2.0 * s
        y = e * (kd * _LN2_HI + (kd * _LN2_LO + (s2 + s2 * z * pz)))  # e log x
        y = min(max(y, -700.0), 700.0)
        nr = y * _INV_LN2 + _ROUND
        nd = nr - _ROUND  # exp(y) = 2^nd exp(r), |r| <= ln(2) / 2, exp(r) to the r^11 term
        r = (y - nd * _LN2_HI) - nd * _LN2_LO
        r2 = r * r
        r4 = r2 * r2
        p = (((1.0 + r) + r2 * (0.5 + r * (1.0 / 6.0)))
             + r4 * ((1.0 / 24.0 + r * (1.0 / 120.0)) + r2 * (1.0 / 720.0 + r * (1.0 / 5040.0)))
             + r4 * r4 * ((1.0 / 40320.0 + r * (1.0 / 362880.0)) + r2 * (1.0 / 3628800.0 + r * (1.0 / 39916800.0))))
        vb = _f64_bits(p) + ((_f64_bits(nr) - _ROUND_BITS) << 52)  # p * 2^nd
        v = _bits_f64(vb)
        d = (vb & 0x1FFFFFFF) - 0x10000000  # the 29 bits float32 drops, from the rounding midpoint
        bad = ((d <= _HARD_ULPS) & (d >= -_HARD_ULPS)) | (v < _F32_MIN) | (v > _F32_MAX)
        pos = xq > 0.0
        out[q] = np.float32(v) if pos else np.float32(0.0)
        redo[q] = bad & pos
        nredo += bad & pos
    if nredo > 0:
        for q in range(n):
            if redo[q]:
                out[q] = np.float32(x[q] ** e)


@numba.njit(cache=True, inline="always")
def _window_col(bb, ndx, circ):
    """Displacement column ``bb`` of a 3 x 3 window (at most one period outside ``[0, ndx)``): wrapped when
    ``circ``, else -1 when it lies outside."""
    if circ:
        if bb < 0:
            return bb + ndx
        if bb >= ndx:
            return bb - ndx
        return bb
    return bb if 0 <= bb < ndx else -1


@numba.njit(parallel=True, cache=True, error_model="numpy")
def _pool_combine(child, ky_c, kx_c, circ, gh, gw, off, wrapc, nlpow):
    """One pyramid step: max-pool 3 x 3 and subsample by 2 every child's responses, then each parent's
    ``(mean of its children's pooled responses)^nlpow``.

    Args:
        child: (2 ky_c + 1, ndx_c, n) float32 responses of the child level, displacement-major: entry (k, l, q)
            is patch q at dy = k - ky_c and dx = l - kx_c (columns circular of period ndx_c if ``circ``, dx = l),
            in the level's displacement steps.
        gh, gw: the patch grid (n = gh * gw, row-major), shared by all levels.
        off: the parent at grid (j, i) has its children at (j +- off, i +- off) (a quarter of the parent's size,
            in grid steps); columns wrap if ``wrapc``, else children off the grid are left out.
        nlpow: the power non-linearity.
    Returns:
        ``(pooled, arg, parent)``, each (2 ky_p + 1, ndx_p, n) with ky_p = ky_c // 2 and ndx_p = ndx_c // 2
        (circular) or 2 (kx_c // 2) + 1, displacement-major.  ``pooled[a, b, q]`` (float32): the maximum of
        ``child[ca + da, cb + db, q]`` over da, db in -1..1 (entries off the map left out, columns wrapped if
        ``circ``), the window centred on the parent displacement, ca = ky_c + 2 (a - ky_p) and cb = 2 b
        (circular) or kx_c + 2 (b - kx_p).  ``arg[a, b, q]`` (uint8): where it lies, 3 (da + 1) + (db + 1), the
        first such entry in that order on ties.  ``parent[a, b, q]`` (float32): the mean of ``pooled[a, b]``
        over q's children (summed in float64 in the order (-off, -off), (-off, +off), (+off, -off),
        (+off, +off)) to the power ``nlpow`` (:func:`_pow_f32`: libm's ``pow`` rounded to float32; 0 for a
        parent without children).  In displacement coordinates the children's offsets cancel, so no shift is
        needed.  Parallel over the parent displacements, each a vectorisable loop over the n patches.
    """
    ndy_c, ndx_c, n = child.shape
    ky_p, kx_p = ky_c // 2, kx_c // 2
    ndy_p = 2 * ky_p + 1
    ndx_p = ndx_c // 2 if circ else 2 * kx_p + 1
    pooled = np.empty((ndy_p, ndx_p, n), np.float32)
    arg = np.empty((ndy_p, ndx_p, n), np.uint8)
    out = np.empty((ndy_p, ndx_p, n), np.float32)
    inv = np.zeros(n)  # 1 / number of children (0: none)
    for j in range(gh):
        nj = (1 if j - off >= 0 else 0) + (1 if j + off < gh else 0)
        for i in range(gw):
            ni = 2 if wrapc else (1 if i - off >= 0 else 0) + (1 if i + off < gw else 0)
            if nj * ni > 0:
                inv[j * gw + i] = 1.0 / (nj * ni)
    for t in numba.prange(ndy_p * ndx_p):
        a, b = t // ndx_p, t % ndx_p
        ca = ky_c + 2 * (a - ky_p)
        cb = 2 * b if circ else kx_c + 2 * (b - kx_p)
        pr, ag = pooled[a, b], arg[a, b]
        where = np.empty(n, np.int32)  # (same width as the values: the selects vectorise)
        first = True
        for da in range(-1, 2):
            aa = ca + da
            if aa < 0 or aa >= ndy_c:
                continue
            for db in range(-1, 2):
                bb = _window_col(cb + db, ndx_c, circ)
                if bb < 0:
                    continue
                src = child[aa, bb]
                k = np.int32(3 * (da + 1) + db + 1)
                if first:
                    for q in range(n):
                        pr[q] = src[q]
                        where[q] = k
                    first = False
                else:  # strictly greater: the first maximum in window order is kept
                    for q in range(n):
                        up = src[q] > pr[q]
                        pr[q] = src[q] if up else pr[q]
                        where[q] = k if up else where[q]
        for q in range(n):
            ag[q] = np.uint8(where[q])
        tot = np.zeros(n)
        for sj in (-1, 1):
            for si in (-1, 1):
                sh = si * off
                lo, hi = max(0, -sh), min(gw, gw - sh)  # columns whose child column i + sh needs no wrap
                for j in range(gh):
                    cj = j + sj * off
                    if cj < 0 or cj >= gh:
                        continue
                    dst, srcr = j * gw, cj * gw + sh
                    for i in range(lo, hi):
                        tot[dst + i] += pr[srcr + i]
                    if wrapc:
                        for i in range(0, min(lo, gw)):
                            tot[dst + i] += pr[cj * gw + (i + sh) % gw]
                        for i in range(max(hi, 0), gw):
                            tot[dst + i] += pr[cj * gw + (i + sh) % gw]
        for q in range(n):
            tot[q] *= inv[q]
        _pow_f32(tot, nlpow, out[a, b], np.empty(n, np.bool_))
        for q in range(n):
            if inv[q] == 0.0:
                out[a, b, q] = 0.0
    return pooled, arg, out


@numba.njit(cache=True)
def _backtrack_row(maps, pooled, args, gh, gw, kys, kxs, circ, wrapc, lev, a, best_s, best_a, best_b, best_r):
    """:func:`_backtrack` from the starts of level ``lev`` (0-based) in displacement row ``a``.

    Updates ``best_s, best_a, best_b, best_r`` ((n,) float64, int64, int64, int64: each atomic patch's best path
    score, 0 if none yet, its level-1 displacement indices and the rank of that path) where a path scores more,
    or as much with a lower rank.
    """
    m = maps[lev]
    ndy, ndx, n = m.shape
    leaves = np.int64(1) << (2 * lev)  # at most 4^lev atomic patches per start
    flag = np.empty(n, np.bool_)
    stack_lev = np.empty(256, np.int64)
    stack_p = np.empty(256, np.int64)
    stack_a = np.empty(256, np.int64)
    stack_b = np.empty(256, np.int64)
    stack_s = np.empty(256, np.float64)
    for b in range(ndx):
        row = m[a, b]
        for q in range(n):  # the local maxima at (a, b): > 0 and no neighbour above
            flag[q] = row[q] > 0.0
        for da in range(-1, 2):
            aa = a + da
            if aa < 0 or aa >= ndy:
                continue
            for db in range(-1, 2):
                if da == 0 and db == 0:
                    continue
                bb = _window_col(b + db, ndx, circ)
                if bb < 0:
                    continue
                nrow = m[aa, bb]
                for q in range(n):
                    flag[q] = flag[q] & (nrow[q] <= row[q])
        for p in range(n):
            if not flag[p]:
                continue
            rank = ((p * ndy + a) * ndx + b) * leaves  # the start's place in (p, a, b) order, then the leaf's
            stack_lev[0], stack_p[0], stack_a[0], stack_b[0], stack_s[0] = lev, p, a, b, row[p]
            top = 1
            while top > 0:
                top -= 1
                lv, pp, pa, pb, sc = stack_lev[top], stack_p[top], stack_a[top], stack_b[top], stack_s[top]
                if lv == 0:
                    if sc > best_s[pp] or (sc == best_s[pp] and rank < best_r[pp]):
                        best_s[pp] = sc
                        best_a[pp] = pa
                        best_b[pp] = pb
                        best_r[pp] = rank
                    rank += 1
                    continue
                pm = pooled[lv - 1]
                pg = args[lv - 1]
                cndx = maps[lv - 1].shape[1]
                off = 1 << (lv - 1)
                j, i = pp // gw, pp % gw
                ca = kys[lv - 1] + 2 * (pa - kys[lv])
                cb = 2 * pb if circ else kxs[lv - 1] + 2 * (pb - kxs[lv])
                for sj in (-1, 1):
                    cj = j + sj * off
                    if cj < 0 or cj >= gh:
                        continue
                    for si in (-1, 1):
                        ci = i + si * off
                        if wrapc:
                            ci = ci % gw
                        elif ci < 0 or ci >= gw:
                            continue
                        cidx = cj * gw + ci
                        k = np.int64(pg[pa, pb, cidx])  # where the child's pooled maximum lies in its window
                        ba = ca + k // 3 - 1
                        bb2 = cb + k % 3 - 1
                        if circ:
                            if bb2 < 0:
                                bb2 += cndx
                            elif bb2 >= cndx:
                                bb2 -= cndx
                        stack_lev[top], stack_p[top], stack_a[top], stack_b[top] = lv - 1, cidx, ba, bb2
                        stack_s[top] = sc + pm[pa, pb, cidx]
                        top += 1


@numba.njit(parallel=True, cache=True)
def _backtrack(maps, pooled, args, gh, gw, kys, kxs, circ, wrapc):
    """Top-down: from every local maximum at every level >= 2 down to the atomic patches.

    A start is a displacement (a, b) of a patch p at level >= 2 whose response is > 0 and not below any of its
    8 neighbours' (columns circular if ``circ``).  Each step down takes, for each child, the maximum of its
    pooling window (the one the parent's response pooled, recorded by :func:`_pool_combine`) and goes on from
    where it lies; an atomic patch reached scores the sum of the responses along the path.

    Args:
        maps: list of (ndy, ndx, n) float32 response arrays per level (level 1 first), displacement-major.
        pooled, args: per level but the last, the pooled responses and where they lie (:func:`_pool_combine`).
        gh, gw: the patch grid (n = gh * gw, shared by all levels).
        kys, kxs: (L,) displacement window half-sizes per level (``kxs`` unused when circular).
    Returns:
        ``(score, a, b)``: (L, n) float64 and int64: per starting level, each atomic patch's best path score (0:
        none) and its level-1 displacement indices.  On equal scores the path met first wins, in the order:
        start patch, then its displacement (a, b) row-major, then depth-first (children in the order
        (-off, -off), (-off, +off), (+off, -off), (+off, +off), the last pushed explored first).  Every
        path carries its rank in that order, so the parallel tasks (one per level and displacement row) are
        reduced to the same result whatever the threads.
    """
    nlev = len(maps)
    n = gh * gw
    ntask = 0
    for lev in range(1, nlev):
        ntask += maps[lev].shape[0]
    task_lev = np.empty(ntask, np.int64)
    task_a = np.empty(ntask, np.int64)
    t = 0
    for lev in range(nlev - 1, 0, -1):  # the top levels (long paths) first
        for a in range(maps[lev].shape[0]):
            task_lev[t], task_a[t] = lev, a
            t += 1
    ts = np.zeros((ntask, n))
    ta = np.zeros((ntask, n), np.int64)
    tb = np.zeros((ntask, n), np.int64)
    tr = np.full((ntask, n), np.iinfo(np.int64).max)
    for t in numba.prange(ntask):
        _backtrack_row(maps, pooled, args, gh, gw, kys, kxs, circ, wrapc, task_lev[t], task_a[t], ts[t], ta[t],
                       tb[t], tr[t])
    score = np.zeros((nlev, n))
    best_a = np.zeros((nlev, n), np.int64)
    best_b = np.zeros((nlev, n), np.int64)
    best_r = np.full((nlev, n), np.iinfo(np.int64).max)
    for t in range(ntask):
        lev = task_lev[t]
        for x in range(n):
            if ts[t, x] > score[lev, x] or (ts[t, x] == score[lev, x] and tr[t, x] < best_r[lev, x]):
                score[lev, x] = ts[t, x]
                best_a[lev, x] = ta[t, x]
                best_b[lev, x] = tb[t, x]
                best_r[lev, x] = tr[t, x]
    return score, best_a, best_b


def _working_size(h: int, w: int, downscale: int) -> tuple[int, int]:
    """Working (height, width): about 1 / 2**downscale of the input, each a multiple of 64 (at least 64)."""
    f = 2.0 ** -downscale
    return max(64, int(round(h * f / 64.0)) * 64), max(64, int(round(w * f / 64.0)) * 64)


def _one_way(d0: np.ndarray, d1: np.ndarray, p: DeepMatchingParams):
    """Match image 0's atomic patches in image 1.

    Returns:
        ``(dy, dx, score, grid)``: (n,) displacements of every atomic patch (working pixels; dx the shortest
        periodic one when wrapping), (n,) path scores (0 = no match) and the (rows, columns) patch grid.
    """
    h, w = d0.shape[:2]
    cell = int(p.cell_px)
    step = 2 * cell
    ky = int(p.ngh_rad_y) if p.ngh_rad_y > 0 else h // 4
    circ = bool(p.wrap and (p.ngh_rad_x <= 0 or p.ngh_rad_x >= w // 2))
    if circ:
        kx, ndx = 0, w
    else:
        kx = int(p.ngh_rad_x) if p.ngh_rad_x > 0 else w - 1
        ndx = 2 * kx + 1
    wrapc = bool(p.wrap)
    maps = [_level1(d0, d1, cell, step, 2 * ky + 1, ndx, ky, kx, circ, wrapc)]
    gh, gw = h // step, w // step
    kys, kxs = [ky], [kx]
    psize = PATCH_CELLS * cell
    # build levels while the patch (16, 32, 64, ... working pixels) fits in the image
    pooled, args = [], []
    while 2 * psize <= min(h, w) and maps[-1].shape[1] >= 3:
        off = (psize // 2) // step  # children at +- a quarter of the parent's size, in grid steps
        pm, pa, parent = _pool_combine(maps[-1], kys[-1], kxs[-1], circ, gh, gw, off, wrapc, float(p.nlpow))
        pooled.append(pm)
        args.append(pa)
        maps.append(parent)
        kys.append(kys[-1] // 2)
        kxs.append(kxs[-1] // 2)
        psize *= 2
    n = gh * gw
    nlev = len(maps)
    if nlev > 1:
        with numba.parallel_chunksize(1):  # tasks of uneven cost: hand them out one at a time
            all_s, all_a, all_b = _backtrack(numba.typed.List(maps), numba.typed.List(pooled),
                                             numba.typed.List(args), gh, gw, np.asarray(kys, np.int64),
                                             np.asarray(kxs, np.int64), circ, wrapc)
    else:  # a single level: each atomic patch's own best response (the first in (a, b) order on ties)
        flat = maps[0].reshape(-1, n)
        arg = np.argmax(flat, axis=0)
        all_s = flat[arg, np.arange(n)][None].astype(np.float64)
        a1, b1 = np.divmod(arg, maps[0].shape[1])
        all_a, all_b = a1[None], b1[None]
    top = np.argmax(all_s, axis=0)  # the best path over starting levels (first level on ties: deterministic)
    idx = np.arange(n)
    best_s, best_a, best_b = all_s[top, idx], all_a[top, idx], all_b[top, idx]
    dy = (best_a - ky).astype(np.float64)
    if circ:
        dx = ((best_b + w // 2) % w - w // 2).astype(np.float64)
    else:
        dx = (best_b - kx).astype(np.float64)
    return dy, dx, best_s, (gh, gw)


def _verified(fwd, bwd, p: DeepMatchingParams, wh: int, ww: int, h: int, w: int) -> Matches:
    """Matches of ``fwd`` (image a -> b) that ``bwd`` (b -> a) confirms, in input pixels."""
    dy_f, dx_f, s_f, (gh, gw) = fwd
    dy_b, dx_b, s_b, _ = bwd
    step = 2 * int(p.cell_px)
    jj, ii = np.divmod(np.arange(gh * gw), gw)
    y0, x0 = (jj * step).astype(np.float64), (ii * step).astype(np.float64)
    y1, x1 = y0 + dy_f, x0 + dx_f
    # the backward patch nearest to the forward target, and where its own match leads back to
    bj = np.clip(np.rint(y1 / step).astype(np.int64), 0, gh - 1)
    bi = np.rint(x1 / step).astype(np.int64)
    bi = bi % gw if p.wrap else np.clip(bi, 0, gw - 1)
    b = bj * gw + bi
    back_y, back_x = y1 + dy_b[b], x1 + dx_b[b]
    ex = back_x - x0
    if p.wrap:
        ex = (ex + ww / 2) % ww - ww / 2
    ok = (s_f > 0) & (s_b[b] > 0) & (np.hypot(ex, back_y - y0) <= p.reciprocal_px)
    sx, sy = w / ww, h / wh

    def to_input(x, scale):
        return (x + 0.5) * scale - 0.5

    return Matches(x0=to_input(x0[ok], sx), y0=to_input(y0[ok], sy), x1=to_input(x1[ok], sx),
                   y1=to_input(y1[ok], sy), score=s_f[ok], cell=step * 0.5 * (sx + sy))


def deep_matching_both(img0: np.ndarray, img1: np.ndarray,
                       params: DeepMatchingParams | None = None) -> tuple[Matches, Matches]:
    """DeepMatching both ways, each verified by the other: ``(matches 0 -> 1, matches 1 -> 0)``.

    Args:
        img0, img1: (H, W, 3) uint8 RGB or (H, W) uint8 grey images of the same size.
        params: :class:`DeepMatchingParams` (default: the authors' defaults, equirect wrapping).
    """
    p = params or DeepMatchingParams()
    if img0.shape != img1.shape:
        raise ValueError(f"deep_matching: images differ in size ({img0.shape} vs {img1.shape})")
    h, w = img0.shape[:2]
    wh, ww = _working_size(h, w, int(p.downscale))

    def prep(img):
        g = grey(img)
        g = cv2.resize(g.astype(np.float32), (ww, wh), interpolation=cv2.INTER_AREA)
        return pixel_descriptors(g, p)

    d0, d1 = prep(img0), prep(img1)
    fwd = _one_way(d0, d1, p)
    bwd = _one_way(d1, d0, p)
    return _verified(fwd, bwd, p, wh, ww, h, w), _verified(bwd, fwd, p, wh, ww, h, w)


def deep_matching(img0: np.ndarray, img1: np.ndarray, params: DeepMatchingParams | None = None) -> Matches:
    """DeepMatching from ``img0`` to ``img1``, verified by the reverse matching (see :func:`deep_matching_both`).

    Returns:
        :class:`Matches` in input pixels: one per atomic patch of image 0 that passed the reciprocal check.
    """
    return deep_matching_both(img0, img1, params)[0]
