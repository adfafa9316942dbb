"""DeepMatching's numba kernels against straightforward numpy versions of the same maths, on small random inputs."""

from __future__ import annotations

import numpy as np
import pytest

from reconstruction.flow.deepmatching import _level1


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
