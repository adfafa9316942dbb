"""Depth edges moved onto camera C's image edges: a joint weighted median of the log distance near the estimate's
own depth edges.

A sweep's depth edge can sit a pixel or two off the object's outline (the foreground's distance spread over the
background beside it, or the reverse). Near every depth edge of the estimate, :func:`snap_depth_edges` gives each
pixel the weighted median of the log distances around it, each neighbour ``q`` of pixel ``p`` weighted by

    exp(-|I(p) - I(q)|^2 / (2 sigma_color^2)) * exp(-|p - q|^2 / (2 sigma_px^2)) * (confidence(q) + 0.01)

(``I`` C's colour, 0-255 per channel; ``|p - q|`` in pixels), so a pixel takes the distance of the neighbours that
look like it and are sure of their distance (the joint weighted median of Ma, Li, Li, Jia, "Constant Time Weighted
Median Filtering for Stereo Matching and Beyond", ICCV 2013, restricted to the pixels near depth edges). A median,
unlike a mean, puts no pixel at a distance between the two sides of an edge. Windows wrap in longitude and continue
across a pole (the row beyond it, half a turn round). Pixels away from depth edges are not touched.
"""

from __future__ import annotations

import cv2
import numba
import numpy as np

from reconstruction.camera.image_ops import dilate_wrapped, periodic_filter

__all__ = ["CONFIDENCE_FLOOR", "edge_pixels", "snap_depth_edges"]

#: added to every neighbour's confidence in its weight, so that a window of unsure pixels still has a median
CONFIDENCE_FLOOR = 0.01


def edge_pixels(log_d: np.ndarray, jump: float, reach_px: int) -> np.ndarray:
    """The pixels within ``reach_px`` (Chebyshev, wrapping in longitude) of a depth edge of the estimate.

    Args:
        log_d: (H, W) natural log of the distance (metres); NaN = no estimate (never an edge).
        jump: a pixel is on a depth edge when the log distances of its 3 x 3 neighbourhood span more than this.
        reach_px: how far from such a pixel the returned mask reaches, pixels (>= 0).
    Returns:
        (H, W) bool.
    """
    x = np.asarray(log_d, np.float32)
    known = np.isfinite(x)
    box = np.ones((3, 3), np.uint8)
    hi = periodic_filter(np.where(known, x, -np.inf).astype(np.float32), 1, lambda a: cv2.dilate(a, box), 1)
    lo = periodic_filter(np.where(known, x, np.inf).astype(np.float32), 1, lambda a: cv2.erode(a, box), 1)
    edge = known & ((hi - lo) > jump)
    return dilate_wrapped(edge, max(int(reach_px), 0))


@numba.njit(parallel=True, cache=True)
def _weighted_median(log_d, weight, image, mask, radius, sigma_color, sigma_px):  # pragma: no cover - numba
    h, w = log_d.shape
    out = log_d.copy()
    side = 2 * radius + 1
    inv_c = 1.0 / (2.0 * sigma_color * sigma_color)
    inv_s = 1.0 / (2.0 * sigma_px * sigma_px)
    spatial = np.empty((side, side))  # the exponent's spatial term, the same product for every pixel
    for dy in range(-radius, radius + 1):
        for dx in range(-radius, radius + 1):
            spatial[dy + radius, dx + radius] = (dx * dx + dy * dy) * inv_s
    channels = image.shape[2]
    for y in numba.prange(h):  # rows are independent: each writes only its own pixels of ``out``
        vals = np.empty(side * side)
        wts = np.empty(side * side)
        for x in range(w):
            if not mask[y, x]:
                continue
            k = 0
            total = 0.0
            for dy in range(-radius, radius + 1):
                yy = y + dy
                shift = 0
                if yy < 0:  # across the north pole: the row -1 - yy, half a turn round
                    yy = -1 - yy
                    shift = w // 2
                elif yy >= h:
                    yy = 2 * h - 1 - yy
                    shift = w // 2
                if yy < 0 or yy >= h:  # a window taller than the image
                    continue
                for dx in range(-radius, radius + 1):
                    xx = (x + dx + shift) % w
                    v = log_d[yy, xx]
                    if not np.isfinite(v):
                        continue
                    dc = 0.0
                    for c in range(channels):
                        t = image[y, x, c] - image[yy, xx, c]
                        dc += t * t
                    wt = np.exp(-dc * inv_c - spatial[dy + radius, dx + radius]) * weight[yy, xx]
                    vals[k] = v
                    wts[k] = wt
                    total += wt
                    k += 1
            if k == 0 or total <= 0.0:
                continue
            order = np.argsort(vals[:k])
            acc = 0.0
            for i in range(k):
                j = order[i]
                acc += wts[j]
                if acc >= 0.5 * total:
                    out[y, x] = vals[j]
                    break
    return out


def snap_depth_edges(distance: np.ndarray, confidence: np.ndarray, image: np.ndarray, radius_px: int,
                     sigma_color: float, sigma_px: float, jump: float, reach_px: int) -> np.ndarray:
    """The joint weighted median of the module doc at the pixels near the estimate's depth edges.

    Args:
        distance: (H, W) C's distance, metres; NaN, inf or <= 0 = no estimate (kept, never a neighbour).
        confidence: (H, W) in [0, 1], the estimate's confidence (higher = surer).
        image: (H, W, 3) or (H, W) C's image, 0-255.
        radius_px: the window's half side, pixels (0 = nothing changes).
        sigma_color: colour scale of the weights, 0-255 units (Euclidean over the channels).
        sigma_px: spatial scale of the weights, pixels.
        jump, reach_px: which pixels are filtered (:func:`edge_pixels`).
    Returns:
        (H, W) float32 distances, metres: ``distance`` away from depth edges, the weighted median near them.
    Raises:
        ValueError: shapes that do not match, or a parameter out of range (named).
    """
    d = np.asarray(distance, np.float64)
    conf = np.asarray(confidence, np.float64)
    img = np.asarray(image, np.float64)
    if img.ndim == 2:
        img = img[:, :, None]
    if d.ndim != 2 or conf.shape != d.shape or img.shape[:2] != d.shape:
        raise ValueError(f"distance (H, W), confidence (H, W) and image (H, W[, C]) must match, got {d.shape}, "
                         f"{conf.shape} and {np.shape(image)}")
    for name, value in (("sigma_color", sigma_color), ("sigma_px", sigma_px), ("jump", jump)):
        if not value > 0:
            raise ValueError(f"{name} must be > 0, got {value}")
    if radius_px < 0 or reach_px < 0:
        raise ValueError(f"radius_px and reach_px must be >= 0, got {radius_px} and {reach_px}")
    ok = np.isfinite(d) & (d > 0)
    if radius_px == 0 or not ok.any():
        return d.astype(np.float32)
    log_d = np.where(ok, np.log(np.where(ok, d, 1.0)), np.nan)
    mask = edge_pixels(log_d, jump, reach_px) & ok
    weight = np.clip(np.nan_to_num(conf, nan=0.0), 0.0, 1.0) + CONFIDENCE_FLOOR
    snapped = _weighted_median(log_d, weight, np.ascontiguousarray(img), mask, int(radius_px), float(sigma_color),
                               float(sigma_px))
    return np.where(ok, np.exp(snapped), d).astype(np.float32)
