"""DeepMatching's numba kernels against straightforward numpy versions of the same maths, on small random inputs."""

from __future__ import annotations

import numpy as np
import pytest

from reconstruction.flow.deepmatching import _level1, _pool


def level1_numpy(d0, d1, cell, ky, kx, ndx, circ, wrapc):
    """Atomic-patch responses by definition: for patch (j, i) (centre (j, i) * 2 cell) and displacement
    (dy, dx) = (a - ky, b - kx) (``circ``: dx modulo W), the mean over its 4 x 4 cells of the dot product of
    image 0's descriptor at the cell centre and image 1's at the displaced centre (0 outside image 1; cells
    clamped to image 0's cell grid, or wrapped with ``wrapc``)."""
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


@pytest.mark.parametrize("circ, wrapc, kx", [(True, True, 0), (False, True, 5), (False, False, 7)])
def test_level1_equals_numpy(circ, wrapc, kx):
    rng = np.random.default_rng(3)
    h, w, cell = 16, 24, 4
    d0, d1 = (rng.random((h, w, 9)).astype(np.float32) for _ in range(2))
    ky = 3
    ndx = w if circ else 2 * kx + 1
    got = _level1(d0, d1, cell, 2 * cell, 2 * ky + 1, ndx, ky, kx, circ, wrapc)
    np.testing.assert_allclose(got, level1_numpy(d0, d1, cell, ky, kx, ndx, circ, wrapc), rtol=1e-5, atol=1e-5)


@pytest.mark.parametrize("circ", [True, False])
def test_pool_equals_numpy_and_points_at_its_maximum(circ):
    """The 3 x 3 max-pool subsampled by 2 equals numpy's; the recorded position holds that maximum and is the
    first such entry in row-major window order (values quantised so that ties occur)."""
    rng = np.random.default_rng(4)
    ky_c, kx_c, n = 4, 5, 3
    ndx_c = 12 if circ else 2 * kx_c + 1
    child = (rng.integers(0, 4, (n, 2 * ky_c + 1, ndx_c)) / 4).astype(np.float32)
    out, arg = _pool(child, ky_c, kx_c, circ)
    ky_p, kx_p = ky_c // 2, kx_c // 2
    ndx_p = ndx_c // 2 if circ else 2 * kx_p + 1
    assert out.shape == arg.shape == (n, 2 * ky_p + 1, ndx_p)
    for q in range(n):
        for a in range(2 * ky_p + 1):
            for b in range(ndx_p):
                ca = ky_c + 2 * (a - ky_p)
                cb = 2 * b if circ else kx_c + 2 * (b - kx_p)
                win = [(child[q, ca + da, (cb + db) % ndx_c if circ else cb + db], 3 * (da + 1) + db + 1)
                       for da in (-1, 0, 1) for db in (-1, 0, 1)
                       if 0 <= ca + da < child.shape[1] and (circ or 0 <= cb + db < ndx_c)]
                best = max(v for v, _ in win)
                assert out[q, a, b] == best
                assert arg[q, a, b] == next(k for v, k in win if v == best)
