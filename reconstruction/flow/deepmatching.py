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
   the parent patch (32, 64, 128, ... working pixels) fits in the image.
4. **Top-down backtracking**: from every local maximum (3 x 3) of every patch's response map at every level >= 2
   the argmax of each child's pooling window is followed down to level 1; an atomic patch reached along a path
   scores the sum of the responses on that path and keeps its best-scoring match.
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

__all__ = ["DeepMatchingParams", "Matches", "deep_matching", "deep_matching_both", "pixel_descriptors", "blur_periodic",
           "central_differences"]

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
    """Gaussian blur (``sigma`` pixels) of an (H, W) or (H, W, C) float32 array, periodic in columns if ``wrap``
    (rows: the edge replicated)."""
    if sigma <= 0:
        return x
    pad = int(np.ceil(3 * sigma)) + 1
    if wrap:
        w = x.shape[1]
        pad = min(pad, w)
        xp = np.concatenate([x[:, w - pad:], x, x[:, :pad]], axis=1)
        out = cv2.GaussianBlur(xp, (0, 0), sigma, borderType=cv2.BORDER_REPLICATE)
        return np.ascontiguousarray(out[:, pad:pad + w])
    return cv2.GaussianBlur(x, (0, 0), sigma, borderType=cv2.BORDER_REPLICATE)


def central_differences(x: np.ndarray, wrap: bool) -> tuple[np.ndarray, np.ndarray]:
    """``(d/dx, d/dy)`` of an (H, W) or (H, W, C) array by central differences (per pixel); columns periodic if
    ``wrap`` (else 0 in the first and last column), 0 in the first and last row."""
    if wrap:
        gx = 0.5 * (np.roll(x, -1, axis=1) - np.roll(x, 1, axis=1))
    else:
        gx = np.zeros_like(x)
        gx[:, 1:-1] = 0.5 * (x[:, 2:] - x[:, :-2])
    gy = np.zeros_like(x)
    gy[1:-1] = 0.5 * (x[2:] - x[:-2])
    return gx, gy


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
        (n_patches, ndy, ndx) float32 responses in [0, 1], patches in row-major grid order.

    Image 0's cell descriptors are gathered channel-major, (9, H / cell, W / cell), and image 1 is split by
    column phase: plane ``r`` holds the pixels of columns ``cell * t + r``, so the cells displaced by dx read a
    contiguous run of a plane's columns and the cell correlations of one row are a vectorisable loop.  The plane
    has a band of W / cell columns either side (wrapped, or 0 without wrapping) so no index is wrapped in the
    loop.  Parallel over the vertical displacements.
    """
    h, w, c = d0.shape
    ph, pw = h // step, w // step
    ch, cw = h // cell, w // cell
    out = np.zeros((ph * pw, ndy, ndx), np.float32)
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
    npatch = ph * pw
    for a in numba.prange(ndy):
        dy = a - ky
        s = np.zeros((ch, cw), np.float32)  # cell correlations at one displacement
        vs = np.zeros((ph, cw), np.float32)  # their sums over each patch row's 4 cell rows
        row = np.empty((ndx, npatch), np.float32)  # this displacement row's responses, displacement-major
        for b in range(ndx):
            e = half + b - kx  # image-1 column of cell n: n * cell + e
            if circ:
                e = e % w
            r = e % cell
            o = e // cell + cw  # plane column of cell 0 (0 <= o <= 2 cw)
            for m in range(ch):
                srow = s[m]
                for n in range(cw):
                    srow[n] = 0.0
                y1 = m * cell + half + dy
                if y1 < 0 or y1 >= h:
                    continue
                for k in range(c):
                    arow = a0[k, m]
                    prow = planes[r, k, y1, o:o + cw]
                    for n in range(cw):
                        srow[n] += arow[n] * prow[n]
            for j in range(ph):  # separable 4 x 4 cell sums: the 4 cell rows, then the 4 cell columns
                s0, s1, s2, s3, vrow = s[crow[j, 0]], s[crow[j, 1]], s[crow[j, 2]], s[crow[j, 3]], vs[j]
                for n in range(cw):
                    vrow[n] = s0[n] + s1[n] + s2[n] + s3[n]
            for j in range(ph):
                for i in range(pw):
                    row[b, j * pw + i] = (vs[j, ccol[i, 0]] + vs[j, ccol[i, 1]] + vs[j, ccol[i, 2]]
                                          + vs[j, ccol[i, 3]]) * scale
        for q in range(npatch):
            for b in range(ndx):
                out[q, a, b] = row[b, q]
    return out


@numba.njit(parallel=True, cache=True, fastmath=True)
def _pool(child, ky_c, kx_c, circ):
    """Max-pool 3 x 3 and subsample by 2 every patch's response map (displacement coordinates).

    Args:
        child: (n, 2 ky_c + 1, ndx_c) responses (row index k <-> k - ky_c steps; columns circular of period
            ndx_c if ``circ``, else index k <-> k - kx_c).
    Returns:
        ``(pooled, arg)``: (n, 2 (ky_c // 2) + 1, ndx_p) float32 maxima, with ndx_p = ndx_c // 2 (circular) or
        2 (kx_c // 2) + 1, and (same shape) uint8 where each maximum lies in its window, 3 (da + 1) + (db + 1)
        for the child entry (2 a + da, 2 b + db) around the window's centre (the first such entry in that order
        on ties).
    """
    n, ndy_c, ndx_c = child.shape
    ky_p, kx_p = ky_c // 2, kx_c // 2
    ndy_p = 2 * ky_p + 1
    ndx_p = ndx_c // 2 if circ else 2 * kx_p + 1
    out = np.zeros((n, ndy_p, ndx_p), np.float32)
    arg = np.zeros((n, ndy_p, ndx_p), np.uint8)
    for q in numba.prange(n):
        for a in range(ndy_p):
            ca = ky_c + 2 * (a - ky_p)
            for b in range(ndx_p):
                cb = 2 * b if circ else kx_c + 2 * (b - kx_p)
                best = -1.0
                where = 4
                for da in range(-1, 2):
                    aa = ca + da
                    if aa < 0 or aa >= ndy_c:
                        continue
                    for db in range(-1, 2):
                        bb = cb + db
                        if circ:
                            bb = bb % ndx_c
                        elif bb < 0 or bb >= ndx_c:
                            continue
                        val = child[q, aa, bb]
                        if val > best:
                            best = val
                            where = 3 * (da + 1) + db + 1
                out[q, a, b] = best
                arg[q, a, b] = where
    return out, arg


@numba.njit(parallel=True, cache=True, fastmath=True)
def _combine(pooled, gh, gw, off, wrapc, nlpow):
    """Parents' responses: ``(mean of the 4 children's pooled responses)^nlpow``.

    Every level uses the same patch grid (gh x gw, one patch per atomic grid position); the parent at (j, i)
    has its children at (j +- off, i +- off) (``off`` = a quarter of the parent's size, in grid steps).  In
    displacement coordinates the children's offsets cancel, so no shift is needed.
    """
    n, ndy, ndx = pooled.shape
    out = np.zeros((n, ndy, ndx), np.float32)
    for q in numba.prange(n):
        j, i = q // gw, q % gw
        kids = np.empty(4, np.int64)
        nk = 0
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
                kids[nk] = cj * gw + ci
                nk += 1
        if nk == 0:
            continue
        inv = 1.0 / nk
        for a in range(ndy):
            for b in range(ndx):
                tot = 0.0
                for k in range(nk):
                    tot += pooled[kids[k], a, b]
                out[q, a, b] = (tot * inv) ** nlpow
    return out


@numba.njit(parallel=True, cache=True)
def _backtrack(maps, pooled, args, gh, gw, kys, kxs, circ, wrapc, best_score, best_a, best_b):
    """Top-down: from every local maximum at every level >= 2 down to the atomic patches.

    Each step down takes, for each child, the maximum of its pooling window (the one the parent's response
    pooled) and goes on from where it lies.

    Args:
        maps: list of (n, ndy, ndx) response arrays per level (level 1 first).
        pooled, args: per level but the last, :func:`_pool` of its map (the maxima and where they lie).
        gh, gw: the patch grid (shared by all levels).
        kys, kxs: (L,) displacement window half-sizes per level (``kxs`` unused when circular).
        best_score, best_a, best_b: (L, n) output: per starting level, each atomic patch's best path score
            and its level-1 displacement indices (levels are filled in parallel, then reduced by the caller).
    """
    nlev = len(maps)
    for lev in numba.prange(1, nlev):
        stack_lev = np.empty(256, np.int64)
        stack_p = np.empty(256, np.int64)
        stack_a = np.empty(256, np.int64)
        stack_b = np.empty(256, np.int64)
        stack_s = np.empty(256, np.float64)
        m = maps[lev]
        ndy, ndx = m.shape[1], m.shape[2]
        for p in range(m.shape[0]):
            for a in range(ndy):
                for b in range(ndx):
                    v = m[p, a, b]
                    if v <= 0.0:
                        continue
                    is_max = True
                    for da in range(-1, 2):
                        aa = a + da
                        if aa < 0 or aa >= ndy:
                            continue
                        for db in range(-1, 2):
                            if da == 0 and db == 0:
                                continue
                            bb = b + db
                            if circ:
                                bb = bb % ndx
                            elif bb < 0 or bb >= ndx:
                                continue
                            if m[p, aa, bb] > v:
                                is_max = False
                    if not is_max:
                        continue
                    stack_lev[0], stack_p[0], stack_a[0], stack_b[0], stack_s[0] = lev, p, a, b, v
                    top = 1
                    while top > 0:
                        top -= 1
                        lv, pp, pa, pb, sc = stack_lev[top], stack_p[top], stack_a[top], stack_b[top], stack_s[top]
                        if lv == 0:
                            if sc > best_score[lev, pp]:
                                best_score[lev, pp] = sc
                                best_a[lev, pp] = pa
                                best_b[lev, pp] = pb
                            continue
                        pm = pooled[lv - 1]
                        pg = args[lv - 1]
                        off = 1 << (lv - 1)
                        j, i = pp // gw, pp % gw
                        ca = kys[lv - 1] + 2 * (pa - kys[lv])
                        cb = 2 * pb if circ else kxs[lv - 1] + 2 * (pb - kxs[lv])
                        cndx = maps[lv - 1].shape[2]
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
                                bv = pm[cidx, pa, pb]  # the child's best in its pooling window, and where
                                k = np.int64(pg[cidx, pa, pb])
                                ba = ca + k // 3 - 1
                                bb2 = cb + k % 3 - 1
                                if circ:
                                    bb2 = bb2 % cndx
                                stack_lev[top], stack_p[top], stack_a[top], stack_b[top] = lv - 1, cidx, ba, bb2
                                stack_s[top] = sc + bv
                                top += 1


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
    while 2 * psize <= min(h, w) and maps[-1].shape[2] >= 3:
        pm, pa = _pool(maps[-1], kys[-1], kxs[-1], circ)
        pooled.append(pm)
        args.append(pa)
        off = (psize // 2) // step  # children at +- a quarter of the parent's size, in grid steps
        maps.append(_combine(pm, gh, gw, off, wrapc, float(p.nlpow)))
        kys.append(kys[-1] // 2)
        kxs.append(kxs[-1] // 2)
        psize *= 2
    n = gh * gw
    nlev = len(maps)
    all_s = np.zeros((nlev, n))
    all_a = np.zeros((nlev, n), np.int64)
    all_b = np.zeros((nlev, n), np.int64)
    if nlev > 1:
        _backtrack(numba.typed.List(maps), numba.typed.List(pooled), numba.typed.List(args), gh, gw,
                   np.asarray(kys, np.int64), np.asarray(kxs, np.int64), circ, wrapc, all_s, all_a, all_b)
    else:  # a single level: each atomic patch's own best response
        flat = maps[0].reshape(n, -1)
        arg = np.argmax(flat, axis=1)
        all_s[0] = flat[np.arange(n), arg]
        all_a[0], all_b[0] = np.divmod(arg, maps[0].shape[2])
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
        g = img if img.ndim == 2 else cv2.cvtColor(np.ascontiguousarray(img), cv2.COLOR_RGB2GRAY)
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
