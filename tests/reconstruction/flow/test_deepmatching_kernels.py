"""DeepMatching's numba kernels against straightforward numpy / Python versions of the same maths, on small random
inputs."""

from __future__ import annotations

import math

import numpy as np
import pytest

from reconstruction.flow.deepmatching import _backtrack, _level1, _pool_combine, _pow_f32


def level1_numpy(d0, d1, cell, ky, kx, ndx, circ, wrapc):
    """Atomic-patch responses by definition, (n_patches, ndy, ndx): for patch (j, i) (centre (j, i) * 2 cell)
    and displacement (dy, dx) = (a - ky, b - kx) (``circ``: dx modulo W), the mean over its 4 x 4 cells of the
    dot product of image 0's descriptor at the cell centre and image 1's at the displaced centre (0 outside
    image 1; cells clamped to image 0's cell grid, or wrapped with ``wrapc``)."""
    h, w, _ = d0.shape
    ch, cw = h // cell, w // cell
    ph, pw = h // (2 * cell), w // (2 * cell)
    half = cell // 2
    out = np.zeros((ph * pw, 2 * ky + 1, ndx))
    for j in range(ph):
        for i in range(pw):
            for a in range(2 * ky + 1):
                for b in range(ndx):
                    tot = 0.0
                    for u in range(4):
                        for v in range(4):
                            m = min(max(2 * j - 2 + u, 0), ch - 1)
                            n = (2 * i - 2 + v) % cw if wrapc else min(max(2 * i - 2 + v, 0), cw - 1)
                            y0, x0 = m * cell + half, n * cell + half
                            y1, x1 = y0 + a - ky, x0 + b - kx
                            if circ or wrapc:
                                x1 %= w
                            if 0 <= y1 < h and 0 <= x1 < w:
                                tot += float(d0[y0, x0] @ d1[y1, x1])
                    out[j * pw + i, a, b] = tot / 16
    return out


@pytest.mark.parametrize("circ, wrapc, kx, c", [(True, True, 0, 9), (False, True, 5, 9), (False, False, 7, 9),
                                                (True, True, 0, 5), (False, False, 7, 5)])
def test_level1_equals_numpy(circ, wrapc, kx, c):
    """Displacement-major output (ndy, ndx, n_patches) equal to the definition within float32 rounding; c = 9 is
    the descriptors' size (unrolled loop), c = 5 the general loop."""
    rng = np.random.default_rng(3)
    h, w, cell = 16, 24, 4
    d0, d1 = (rng.random((h, w, c)).astype(np.float32) for _ in range(2))
    ky = 3
    ndx = w if circ else 2 * kx + 1
    got = _level1(d0, d1, cell, 2 * cell, 2 * ky + 1, ndx, ky, kx, circ, wrapc)
    want = level1_numpy(d0, d1, cell, ky, kx, ndx, circ, wrapc).transpose(1, 2, 0)
    assert got.shape == want.shape
    np.testing.assert_allclose(got, want, rtol=1e-5, atol=1e-5)


def test_pow_f32_is_libm_pow_rounded_to_float32():
    """Exactly ``float32(math.pow(x, e))`` (libm), including zeros, tiny and large values, and float32 rounding
    midpoints (e = 1: x ** 1 = x exactly, so every result is a tie that the fast path must hand to libm)."""
    rng = np.random.default_rng(5)
    x = np.concatenate([rng.random(3000), rng.random(500) ** 8, 10.0 ** rng.uniform(-40, 30, 500),
                        [0.0, 1.0, 0.25, 1e-300, 2.0 ** -126]])
    f32 = rng.random(2000).astype(np.float32)
    mid = (f32.astype(np.float64) + np.nextafter(f32, np.float32(2)).astype(np.float64)) / 2  # float32 midpoints
    for e, xs in ((1.4, x), (1.0, x), (2.5, x), (0.5, x), (1.0, mid), (-1.0, x[x > 0])):
        out = np.empty(xs.size, np.float32)
        _pow_f32(np.ascontiguousarray(xs), e, out, np.empty(xs.size, np.bool_))
        with np.errstate(over="ignore"):
            want = np.array([math.pow(v, e) for v in xs]).astype(np.float32)
        np.testing.assert_array_equal(out, want, err_msg=f"e = {e}")


def pool_combine_reference(child, ky_c, kx_c, circ, gh, gw, off, wrapc, nlpow):
    """Per parent displacement and patch, in plain Python: the window maximum and its first position, then the
    children's mean (float64, children in the order (-off, -off), (-off, +off), (+off, -off), (+off, +off)) to
    the power nlpow (math.pow), as float32."""
    ndy_c, ndx_c, n = child.shape
    ky_p, kx_p = ky_c // 2, kx_c // 2
    ndx_p = ndx_c // 2 if circ else 2 * kx_p + 1
    pooled = np.zeros((2 * ky_p + 1, ndx_p, n), np.float32)
    arg = np.zeros(pooled.shape, np.uint8)
    parent = np.zeros(pooled.shape, np.float32)
    for a in range(2 * ky_p + 1):
        for b in range(ndx_p):
            ca = ky_c + 2 * (a - ky_p)
            cb = 2 * b if circ else kx_c + 2 * (b - kx_p)
            for q in range(n):
                win = [(child[ca + da, (cb + db) % ndx_c if circ else cb + db, q], 3 * (da + 1) + db + 1)
                       for da in (-1, 0, 1) for db in (-1, 0, 1)
                       if 0 <= ca + da < ndy_c and (circ or 0 <= cb + db < ndx_c)]
                best = max(v for v, _ in win)
                pooled[a, b, q] = best
                arg[a, b, q] = next(k for v, k in win if v == best)
            for q in range(n):
                j, i = divmod(q, gw)
                kids = [(j + sj * off) * gw + (i + si * off) % gw if wrapc else (j + sj * off) * gw + i + si * off
                        for sj in (-1, 1) for si in (-1, 1)
                        if 0 <= j + sj * off < gh and (wrapc or 0 <= i + si * off < gw)]
                tot = 0.0
                for k in kids:
                    tot += float(pooled[a, b, k])
                parent[a, b, q] = math.pow(tot * (1.0 / len(kids)), nlpow) if kids else 0.0
    return pooled, arg, parent


@pytest.mark.parametrize("circ, wrapc", [(True, True), (False, True), (False, False)])
def test_pool_combine_equals_reference(circ, wrapc):
    """Pooled maxima, their positions (first in window order: values quantised so that ties occur) and the
    parents' responses equal the plain reference exactly (tolerance 0: same float64 sums, libm's pow)."""
    rng = np.random.default_rng(4)
    ky_c, kx_c, gh, gw, off = 4, 5, 4, 6, 1
    ndx_c = 12 if circ else 2 * kx_c + 1
    child = (rng.integers(0, 4, (2 * ky_c + 1, ndx_c, gh * gw)) / 4).astype(np.float32)
    got = _pool_combine(child, ky_c, kx_c, circ, gh, gw, off, wrapc, 1.4)
    want = pool_combine_reference(child, ky_c, kx_c, circ, gh, gw, off, wrapc, 1.4)
    for g, w_, name in zip(got, want, ("pooled", "arg", "parent"), strict=True):
        assert g.shape == w_.shape, name
        np.testing.assert_array_equal(g, w_, err_msg=name)


def backtrack_reference(maps, pooled, args, gh, gw, kys, kxs, circ, wrapc):
    """The backtracking in plain Python, serially: per starting level, starts in (patch, a, b) order, each path
    depth-first with a stack; an atomic patch keeps the first strictly best score."""
    nlev, n = len(maps), gh * gw
    score = np.zeros((nlev, n))
    best_a = np.zeros((nlev, n), np.int64)
    best_b = np.zeros((nlev, n), np.int64)
    for lev in range(1, nlev):
        m = maps[lev]
        ndy, ndx = m.shape[:2]
        for p in range(n):
            for a in range(ndy):
                for b in range(ndx):
                    v = m[a, b, p]
                    nbrs = [m[a + da, (b + db) % ndx if circ else b + db, p]
                            for da in (-1, 0, 1) for db in (-1, 0, 1) if (da, db) != (0, 0)
                            and 0 <= a + da < ndy and (circ or 0 <= b + db < ndx)]
                    if v <= 0 or any(u > v for u in nbrs):
                        continue
                    stack = [(lev, p, a, b, float(v))]
                    while stack:
                        lv, pp, pa, pb, sc = stack.pop()
                        if lv == 0:
                            if sc > score[lev, pp]:
                                score[lev, pp], best_a[lev, pp], best_b[lev, pp] = sc, pa, pb
                            continue
                        off = 1 << (lv - 1)
                        j, i = divmod(pp, gw)
                        ca = kys[lv - 1] + 2 * (pa - kys[lv])
                        cb = 2 * pb if circ else kxs[lv - 1] + 2 * (pb - kxs[lv])
                        for sj in (-1, 1):
                            for si in (-1, 1):
                                cj, ci = j + sj * off, i + si * off
                                if not 0 <= cj < gh or not (wrapc or 0 <= ci < gw):
                                    continue
                                cidx = cj * gw + ci % gw
                                k = int(args[lv - 1][pa, pb, cidx])
                                bb = cb + k % 3 - 1
                                if circ:
                                    bb %= maps[lv - 1].shape[1]
                                stack.append((lv - 1, cidx, ca + k // 3 - 1, bb,
                                              sc + float(pooled[lv - 1][pa, pb, cidx])))
    return score, best_a, best_b


@pytest.mark.parametrize("circ, wrapc", [(True, True), (False, False)])
def test_backtrack_equals_serial_reference(circ, wrapc):
    """Three levels from a quantised level-1 map (so that scores tie): the parallel backtracking picks the same
    score and displacement as the serial reference for every starting level and atomic patch."""
    import numba

    rng = np.random.default_rng(6)
    gh, gw, ky, kx = 8, 8, 8, 6
    ndx = 16 if circ else 2 * kx + 1
    maps = [(rng.integers(0, 3, (2 * ky + 1, ndx, gh * gw)) / 2).astype(np.float32)]
    kys, kxs, pooled, args = [ky], [kx], [], []
    for off in (1, 2):
        pm, pa, parent = _pool_combine(maps[-1], kys[-1], kxs[-1], circ, gh, gw, off, wrapc, 1.4)
        pooled.append(pm)
        args.append(pa)
        maps.append(parent)
        kys.append(kys[-1] // 2)
        kxs.append(kxs[-1] // 2)
    kys, kxs = np.asarray(kys, np.int64), np.asarray(kxs, np.int64)
    got = _backtrack(numba.typed.List(maps), numba.typed.List(pooled), numba.typed.List(args), gh, gw, kys, kxs,
                     circ, wrapc)
    want = backtrack_reference(maps, pooled, args, gh, gw, kys, kxs, circ, wrapc)
    assert np.count_nonzero(want[0]) > 0.5 * want[0][1:].size  # most atomic patches reached from each level
    for g, w_ in zip(got, want, strict=True):
        np.testing.assert_array_equal(g, w_)
