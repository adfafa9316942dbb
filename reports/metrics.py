"""Error metrics of a predicted distance map against ground truth (pure numpy + OpenCV, no Blender).

Scoring rules (used by :func:`summary` and :func:`breakdown` alike):

* Only pixels whose **ground truth** is finite and positive are scored ("scored pixels"); pixels whose
  ray hits nothing (ground truth ``+inf``) are ignored.
* A **prediction** that is NaN, +/-inf or ``<= 0`` at a scored pixel is *invalid*.  It is **not dropped**:
  it is scored as if the prediction were 0, i.e. with absolute error ``|err| = gt``, relative error 1, and
  it fails ``delta1`` and counts as an outlier.  Every variant is therefore scored on exactly the same
  pixel set, and a method cannot improve its numbers by refusing to answer on hard pixels.
* ``valid_px`` is the number of scored pixels (finite ground truth), i.e. the denominator of every
  share and mean below; it is the same for every variant of one frame.

Distances are metres, angles degrees (bin edges only), images ``(H, W, 3)`` uint8 RGB.
"""

from __future__ import annotations

import cv2
import numpy as np

from reconstruction.camera.equirect import bearing_grid

__all__ = [
    "ANGLE_EDGES_DEG",
    "DISTANCE_EDGES_M",
    "TEXTURE_EDGES",
    "DELTA1_RATIO",
    "OUTLIER_FRACTION",
    "score_pixels",
    "summary",
    "breakdown",
    "angle_to_baseline_deg",
    "texture_magnitude",
    "binned_errors",
]

#: 10-degree bins of the angle between a pixel's bearing and a baseline direction, degrees, 0..180.
ANGLE_EDGES_DEG = np.arange(0.0, 181.0, 10.0)
#: bins of the true distance, metres; the last bin is open (8 m and beyond).
DISTANCE_EDGES_M = np.array([0.0, 1.0, 2.0, 3.0, 5.0, 8.0, np.inf])
#: fixed, roughly logarithmic bins of the Sobel gradient magnitude of C's grey image, in 8-bit grey levels
#: per pixel (see :func:`texture_magnitude`); fixed (not per-frame quantiles) so frames can be pooled.
TEXTURE_EDGES = np.array([0.0, 1.0, 2.0, 4.0, 8.0, 16.0, 32.0, np.inf])
#: ``delta1`` threshold on ``max(pred/gt, gt/pred)`` (strictly below counts as good).
DELTA1_RATIO = 1.25
#: a pixel is an outlier if ``|pred - gt| > OUTLIER_FRACTION * gt``.
OUTLIER_FRACTION = 0.10


def score_pixels(pred, gt):
    """Per-pixel absolute error under the scoring rules of this module.

    Args:
        pred: (H, W) predicted distance, metres (NaN / inf / <= 0 = invalid).
        gt: (H, W) true distance, metres (+inf = no surface, not scored).
    Returns:
        ``(mask, abs_err, valid_pred)``: ``mask`` (H, W) bool, scored pixels (finite positive ``gt``);
        ``abs_err`` (N,) float64 metres for the ``N = mask.sum()`` scored pixels in row-major order, equal
        to ``gt`` where the prediction is invalid; ``valid_pred`` (N,) bool, prediction valid.
    Raises:
        ValueError: if the shapes differ or are not 2-D.
    """
    pred = np.asarray(pred, dtype=np.float64)
    gt = np.asarray(gt, dtype=np.float64)
    if pred.ndim != 2 or pred.shape != gt.shape:
        raise ValueError(f"pred and gt must be 2-D arrays of the same shape, got {pred.shape} and {gt.shape}")
    mask = np.isfinite(gt) & (gt > 0)
    p, g = pred[mask], gt[mask]
    valid = np.isfinite(p) & (p > 0)
    abs_err = np.where(valid, np.abs(np.where(valid, p, 0.0) - g), g)
    return mask, abs_err, valid


def summary(pred, gt) -> dict:
    """Summary metrics of one predicted distance map.

    Args:
        pred: (H, W) predicted distance of camera C, metres.
        gt: (H, W) ground-truth distance, metres, +inf where nothing is hit.
    Returns:
        dict with (all over the scored pixels, invalid predictions scored as described in the module doc):

        * ``mae_m``: mean ``|pred - gt|``, metres;
        * ``rmse_m``: root mean squared error, metres;
        * ``median_m``: median ``|pred - gt|``, metres;
        * ``absrel``: mean ``|pred - gt| / gt`` (unitless);
        * ``delta1``: share of pixels with ``max(pred/gt, gt/pred) < 1.25`` (0..1);
        * ``outlier_rate``: share of pixels with ``|pred - gt| > 0.1 * gt`` (0..1);
        * ``valid_px``: number of scored pixels (int).

        With no scored pixel at all every metric is NaN and ``valid_px`` is 0.
    """
    mask, err, valid = score_pixels(pred, gt)
    n = int(err.size)
    if n == 0:
        nan = float("nan")
        return {"mae_m": nan, "rmse_m": nan, "median_m": nan, "absrel": nan, "delta1": nan,
                "outlier_rate": nan, "valid_px": 0}
    g = np.asarray(gt, dtype=np.float64)[mask]
    p = np.where(valid, np.asarray(pred, dtype=np.float64)[mask], 1.0)
    ratio = np.maximum(p / g, g / p)
    good = valid & (ratio < DELTA1_RATIO)
    return {
        "mae_m": float(err.mean()),
        "rmse_m": float(np.sqrt(np.mean(err * err))),
        "median_m": float(np.median(err)),
        "absrel": float(np.mean(err / g)),
        "delta1": float(good.mean()),
        "outlier_rate": float(np.mean(err > OUTLIER_FRACTION * g)),
        "valid_px": n,
    }


# --------------------------------------------------------------------------------------------- breakdown


def angle_to_baseline_deg(frame, other: str) -> np.ndarray:
    """Angle between each pixel's bearing of camera C and the baseline C -> ``other``, degrees.

    Args:
        frame: a :class:`harness.data.frame.Frame`.
        other: "U" or "R"; the baseline direction is ``other.position - C.position`` (world frame).
    Returns:
        (H, W) float64 degrees in [0, 180]; 0 = looking straight at camera ``other`` (its epipole).
    """

    c = frame.cameras["C"]
    t = np.asarray(frame.cameras[other].position, dtype=np.float64) - np.asarray(c.position, dtype=np.float64)
    norm = np.linalg.norm(t)
    if not norm > 0:
        raise ValueError(f"camera {other} coincides with camera C: no baseline direction")
    bearings = bearing_grid(frame.width, frame.height, c.rotation)  # (H, W, 3) unit, world frame
    cosang = np.clip(bearings @ (t / norm), -1.0, 1.0)
    return np.degrees(np.arccos(cosang))


def texture_magnitude(image) -> np.ndarray:
    """Sobel gradient magnitude of an image's grey levels, in 8-bit grey levels per pixel.

    The grey image is OpenCV's RGB->grey (Rec. 601 weights on the sRGB-encoded values, 0..255).  The 3x3
    Sobel responses are divided by 8 so a linear ramp of slope ``s`` grey levels per pixel reads ``s``;
    columns wrap around (the equirect seam is not an edge), rows replicate at the poles.

    Args:
        image: (H, W, 3) uint8 RGB (or (H, W) grey).
    Returns:
        (H, W) float64 gradient magnitude, grey levels per pixel (>= 0).
    """
    img = np.asarray(image)
    grey = cv2.cvtColor(img, cv2.COLOR_RGB2GRAY) if img.ndim == 3 else img
    grey = grey.astype(np.float32)
    padded = np.pad(grey, ((1, 1), (0, 0)), mode="edge")
    padded = np.pad(padded, ((0, 0), (1, 1)), mode="wrap")
    gx = cv2.Sobel(padded, cv2.CV_32F, 1, 0, ksize=3)[1:-1, 1:-1] / 8.0
    gy = cv2.Sobel(padded, cv2.CV_32F, 0, 1, ksize=3)[1:-1, 1:-1] / 8.0
    return np.hypot(gx, gy).astype(np.float64)


def binned_errors(values, abs_err, edges) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Mean and median of ``abs_err`` per bin of ``values`` (vectorised, no loop over bins).

    Args:
        values: (N,) the quantity binned (degrees, metres, ...); NaN values are dropped.
        abs_err: (N,) absolute errors, metres.
        edges: (K + 1,) increasing bin edges; bin ``k`` is ``[edges[k], edges[k+1])`` and the last bin also
            holds values equal to its upper edge; values outside ``[edges[0], edges[-1]]`` are dropped.
    Returns:
        ``(mae, median, count)``, each (K,): metres, metres, pixels; NaN means where ``count == 0``.
    """
    values = np.asarray(values, dtype=np.float64).ravel()
    abs_err = np.asarray(abs_err, dtype=np.float64).ravel()
    edges = np.asarray(edges, dtype=np.float64)
    k = edges.size - 1
    idx = np.searchsorted(edges, values, side="right") - 1
    idx = np.where(values == edges[-1], k - 1, idx)
    keep = (idx >= 0) & (idx < k) & np.isfinite(abs_err) & ~np.isnan(values)
    idx, err = idx[keep], abs_err[keep]
    count = np.bincount(idx, minlength=k)
    total = np.bincount(idx, weights=err, minlength=k)
    with np.errstate(invalid="ignore", divide="ignore"):
        mae = np.where(count > 0, total / np.maximum(count, 1), np.nan)
    # medians: sort by (bin, error), then read the middle element(s) of each bin's run
    order = np.lexsort((err, idx))
    sorted_err = err[order]
    start = np.cumsum(count) - count
    lo = start + np.maximum(count - 1, 0) // 2
    hi = start + count // 2
    safe = count > 0
    median = np.full(k, np.nan)
    if sorted_err.size:
        median[safe] = 0.5 * (sorted_err[lo[safe]] + sorted_err[np.minimum(hi[safe], sorted_err.size - 1)])
    return mae, median, count


def breakdown(frame, pred) -> list[dict]:
    """Error of camera C's predicted distance broken down by geometry, distance and texture.

    Args:
        frame: a :class:`harness.data.frame.Frame` with ground truth (``frame.distance["C"]``).
        pred: (H, W) predicted distance of camera C, metres (invalid values scored as in the module doc).
    Returns:
        One dict per bin (empty bins included, with ``n_px == 0`` and NaN errors), keys
        ``kind, bin_lo, bin_hi, mae_m, median_m, n_px``, in this order of kinds:

        * ``angle_U`` / ``angle_R``: angle (degrees) between the pixel's bearing (camera C, world frame) and
          the baseline direction ``U.position - C.position`` / ``R.position - C.position``; 18 bins of 10
          degrees over 0..180 (:data:`ANGLE_EDGES_DEG`);
        * ``distance``: true distance, metres, bins :data:`DISTANCE_EDGES_M` (0-1, 1-2, 2-3, 3-5, 5-8, 8+);
        * ``texture``: :func:`texture_magnitude` of C's image, grey levels per pixel, fixed bins
          :data:`TEXTURE_EDGES` (0-1, 1-2, 2-4, 4-8, 8-16, 16-32, 32+).

        ``bin_hi`` of the last distance/texture bin is ``inf``.
    Raises:
        ValueError: if the frame has no ground truth for C or ``pred`` has the wrong shape.
    """
    if "C" not in frame.distance:
        raise ValueError(f"frame {frame.scene}/{frame.viewpoint} has no ground truth for camera C")
    gt = frame.distance["C"]
    pred = np.asarray(pred)
    if pred.shape != gt.shape:
        raise ValueError(f"pred has shape {pred.shape}, frame {frame.scene}/{frame.viewpoint} is {gt.shape}")
    mask, err, _ = score_pixels(pred, gt)
    quantities = (
        ("angle_U", angle_to_baseline_deg(frame, "U")[mask], ANGLE_EDGES_DEG),
        ("angle_R", angle_to_baseline_deg(frame, "R")[mask], ANGLE_EDGES_DEG),
        ("distance", np.asarray(gt, dtype=np.float64)[mask], DISTANCE_EDGES_M),
        ("texture", texture_magnitude(frame.images["C"])[mask], TEXTURE_EDGES),
    )
    rows = []
    for kind, values, edges in quantities:
        mae, median, count = binned_errors(values, err, edges)
        for k in range(edges.size - 1):
            rows.append({"kind": kind, "bin_lo": float(edges[k]), "bin_hi": float(edges[k + 1]),
                         "mae_m": float(mae[k]), "median_m": float(median[k]), "n_px": int(count[k])})
    return rows
