"""8-path semi-global matching on the equirect grid over joint label families (numba).

Labels are split into contiguous families (e.g. sphere distances, then horizontal planes).  Along each path
``r`` the aggregated cost is (Hirschmueller 2008, with families)::

    L_r(p, l) = C(p, l) + min( L_r(p-r, l),
                               L_r(p-r, l +- 1) + P1                    (l +- 1 in l's family),
                               min_{k in fam(l)} L_r(p-r, k) + P2e,
                               min_k L_r(p-r, k) + P2e + P3e )  -  min_k L_r(p-r, k)

with ``P2e = max(P1, P2 / (1 + |I(p) - I(p-r)| / edge))`` and ``P3e = P3 / (1 + |I(p) - I(p-r)| / edge)``:
large jumps, and switching families, are cheap only at image edges.  The 8 paths are left/right (wrapping
around the full circle of longitude: they start half a turn early), up/down and the four diagonals (whose
column neighbours wrap too).  Every ``L_r`` lies in ``[0, max C + P2 + P3]``, so the sum over 8 paths is kept
in uint16 when ``8 * (max C + P2 + P3) <= 65535`` (checked).
"""

from __future__ import annotations

import numba
import numpy as np

__all__ = ["aggregate", "winner_take_all", "check_penalties"]

_BIG = np.int32(1 << 30)


@numba.njit(inline="always", fastmath=True, cache=True)
def _family_minima(prev, bounds, nfam, fmin):
    # fmin[f] = min of prev over family f's labels; returns the minimum over all labels
    g = np.float32(_BIG)
    for f in range(nfam):
        m = np.float32(_BIG)
        for i in range(bounds[f], bounds[f + 1]):
            m = min(m, prev[i])
        fmin[f] = m
        g = min(g, m)
    return g


@numba.njit(inline="always", fastmath=True, cache=True)
def _step(prev, c, out, acc, bounds, nfam, fmin, g, fnext, p1, p2e, p3e):
    # prev/out: (L,) float32 path costs (integer-valued, exact); c: (L,) uint16; bounds: (nfam + 1,) label
    # ranges of the families (each at least 2 labels); fmin/g: prev's family minima and minimum.  Writes out,
    # adds it to acc ((L,) uint16), fills fnext with out's family minima and returns out's minimum: one pass over
    # the labels per step.  Branch-free inner loop (SIMD).
    gn = np.float32(_BIG)
    for f in range(nfam):
        a, b = bounds[f], bounds[f + 1]
        base = min(fmin[f] + p2e, g + p2e + p3e)
        v = np.float32(c[a]) + min(min(prev[a], prev[a + 1] + p1), base) - g
        out[a] = v
        acc[a] += np.uint16(np.int32(v))
        m = v
        for i in range(a + 1, b - 1):
            v = np.float32(c[i]) + min(min(prev[i], min(prev[i - 1], prev[i + 1]) + p1), base) - g
            out[i] = v
            acc[i] += np.uint16(np.int32(v))
            m = min(m, v)
        v = np.float32(c[b - 1]) + min(min(prev[b - 1], prev[b - 2] + p1), base) - g
        out[b - 1] = v
        acc[b - 1] += np.uint16(np.int32(v))
        fnext[f] = min(m, v)
        gn = min(gn, fnext[f])
    return gn


@numba.njit(inline="always", cache=True)
def _penalties(gray_a, gray_b, p1, p2, p3, edge):
    s = 1.0 + abs(gray_a - gray_b) / edge
    p2e = np.float32(np.floor(p2 / s + 0.5))
    if p2e < p1:
        p2e = p1
    return p2e, np.float32(np.floor(p3 / s + 0.5))


@numba.njit(parallel=True, cache=True)
def _horizontal(cost, gray, bounds, nfam, p1, p2, p3, edge, out):
    h, w, n = cost.shape
    warm = w // 2
    for y in numba.prange(h):
        prev = np.empty(n, np.float32)
        cur = np.empty(n, np.float32)
        fmin = np.empty(nfam, np.float32)
        fnext = np.empty(nfam, np.float32)
        scratch = np.zeros(n, np.uint16)  # where the warm-up steps add (discarded): the step stays branch-free
        for direction in (1, -1):
            x0 = (-warm) % w if direction == 1 else (w - 1 + warm) % w
            for i in range(n):
                prev[i] = cost[y, x0, i]
            g = _family_minima(prev, bounds, nfam, fmin)
            xp = x0
            for k in range(1, w + warm):
                x = (xp + direction) % w
                p2e, p3e = _penalties(gray[y, x], gray[y, xp], p1, p2, p3, edge)
                acc = out[y, x] if k >= warm else scratch
                g = _step(prev, cost[y, x], cur, acc, bounds, nfam, fmin, g, fnext, p1, p2e, p3e)
                prev, cur = cur, prev
                fmin, fnext = fnext, fmin
                xp = x


@numba.njit(parallel=True, cache=True)
def _lines(cost, gray, bounds, nfam, p1, p2, p3, edge, out, dx, down):
    # One path direction (dy = +1 if down else -1, column step dx in {-1, 0, 1}): the predecessor of (y, x) is
    # (y - dy, (x + dx) % w), so every path is one independent line (a column, or a diagonal wrapping in
    # longitude) and all lines run in ONE parallel region (no per-row barrier: robust on a loaded machine).
    h, w, n = cost.shape
    for x0 in numba.prange(w):
        prev = np.empty(n, np.float32)
        cur = np.empty(n, np.float32)
        fmin = np.empty(nfam, np.float32)
        fnext = np.empty(nfam, np.float32)
        y = np.int64(0) if down else np.int64(h - 1)
        x = np.int64(x0)
        for i in range(n):
            prev[i] = cost[y, x, i]
            out[y, x, i] += cost[y, x, i]
        g = _family_minima(prev, bounds, nfam, fmin)
        for s in range(1, h):
            yp, xp = y, x
            y = s if down else h - 1 - s
            x = np.int64((xp - dx) % w)
            p2e, p3e = _penalties(gray[y, x], gray[yp, xp], p1, p2, p3, edge)
            g = _step(prev, cost[y, x], cur, out[y, x], bounds, nfam, fmin, g, fnext, p1, p2e, p3e)
            prev, cur = cur, prev
            fmin, fnext = fnext, fmin


def check_penalties(max_cost: int, p1: int, p2: int, p3: int) -> None:
    """Raise ValueError unless the 8-path sum of aggregated costs fits uint16 (see the module docstring)."""
    if not 0 < p1 <= p2 or p3 < 0 or p1 != int(p1):
        raise ValueError(f"SGM penalties must satisfy 0 < P1 <= P2 and P3 >= 0 (got {p1}, {p2}, {p3})")
    if 8 * (max_cost + p2 + p3) > 65535:
        raise ValueError(f"8 * (max cost {max_cost} + P2 {p2} + P3 {p3}) exceeds uint16: lower the cost scale "
                         "or the penalties")


def aggregate(cost: np.ndarray, family: np.ndarray, gray: np.ndarray, p1: int, p2: int, p3: int,
              edge: float, max_cost: int, paths: int = 8) -> np.ndarray:
    """Sum of the path-wise aggregated costs over 8 (or 4) paths.

    Args:
        cost: (H, W, L) uint16 matching costs (every value <= ``max_cost``).
        family: (L,) int family id of each label (0, 1, ...; each family a contiguous range).
        gray: (H, W) float32 guide image (gray levels) for the edge-adaptive penalties.
        p1, p2, p3: penalties for a +-1 step within a family, a larger jump, a family switch (cost units).
        edge: gray-level difference that halves P2 and P3, gray levels.
        max_cost: the largest value in ``cost``.
        paths: 8 (all) or 4 (left, right, up, down: ablation).
    Returns:
        (H, W, L) uint16 aggregated costs.
    """
    check_penalties(max_cost, p1, p2, p3)
    fam = np.asarray(family, np.int64)
    nfam = int(fam.max()) + 1
    if np.any(np.diff(fam) < 0) or fam[0] != 0:
        raise ValueError("label families must be contiguous and numbered 0, 1, ... in label order")
    fam = np.searchsorted(fam, np.arange(nfam + 1)).astype(np.int64)  # family bounds
    if np.any(np.diff(fam) < 2):
        raise ValueError("every label family needs at least 2 labels")
    out = np.zeros(cost.shape, np.uint16)
    g = np.ascontiguousarray(gray, np.float32)
    _horizontal(cost, g, fam, nfam, np.float32(p1), float(p2), float(p3), float(edge), out)
    for down in (True, False):
        for dx in ((-1, 0, 1) if paths == 8 else (0,)):
            _lines(cost, g, fam, nfam, np.float32(p1), float(p2), float(p3), float(edge), out, dx, down)
    return out


@numba.njit(parallel=True, cache=True)
def _wta(agg, fam, label, conf):
    h, w, n = agg.shape
    for y in numba.prange(h):
        for x in range(w):
            s = agg[y, x]
            best = 0
            for i in range(1, n):
                if s[i] < s[best]:
                    best = i
            f = fam[best]
            s1 = np.float64(s[best])
            s2 = 1e18
            for i in range(n):
                if fam[i] == f and abs(i - best) <= 1:
                    continue
                if s[i] < s2:
                    s2 = s[i]
            delta = 0.0
            if best > 0 and best < n - 1 and fam[best - 1] == f and fam[best + 1] == f:
                a = np.float64(s[best - 1])
                c = np.float64(s[best + 1])
                den = a - 2.0 * s1 + c
                if den > 0:
                    delta = 0.5 * (a - c) / den
                    if delta > 0.5:
                        delta = 0.5
                    elif delta < -0.5:
                        delta = -0.5
            label[y, x] = best + delta
            conf[y, x] = (s2 - s1) / s2 if s2 > 0 else 0.0


def winner_take_all(agg: np.ndarray, family: np.ndarray):
    """Best label per pixel with parabolic sub-level refinement, and a confidence.

    Args:
        agg: (H, W, L) uint16 aggregated costs; family: (L,) family id per label.
    Returns:
        ``(label, confidence)``: (H, W) float64 fractional label (the winner plus a parabola offset in
        [-0.5, 0.5] between its same-family neighbours) and (H, W) float32 ``1 - S1 / S2`` in [0, 1], where
        S1 is the winner's aggregated cost and S2 the best one outside the winner and its same-family
        neighbours.
    """
    h, w, _ = agg.shape
    label = np.empty((h, w), np.float64)
    conf = np.empty((h, w), np.float32)
    _wta(agg, np.ascontiguousarray(family, np.int64), label, conf)
    return label, conf
